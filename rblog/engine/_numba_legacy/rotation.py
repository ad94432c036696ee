"""Rotation math shared by the engine: quaternions, matrices, world-frame inertia products.

Frames: ``q`` (wxyz, scalar first) and ``R`` map body-frame vectors to the world frame
(``v_world = R v_body``). Angular momentum ``L`` is world frame; ``inv_inertia`` is the diagonal of
I_body^-1 (principal axes), so omega = R diag(1/I) R^T L, as in the lecture notes.

The compiled helpers are ``numba.njit(inline="always")`` over scalars and tuples (a matrix is a
row-major 9-tuple), so a kernel stepping N bodies allocates nothing per step. The ``*_np``
helpers at the bottom are their numpy twins for scene set-up. The integrators that use these
live in :mod:`rblog.engine.integrators`. (The analyzers keep their own geometry on purpose: an
audit must not share the code it audits.)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rblog.engine.constants import POLAR_MAX_ITER, POLAR_TOL

jit = njit(inline="always", cache=True)


@jit
def quat_mul(aw, ax, ay, az, bw, bx, by, bz):
    """Hamilton product a (x) b."""
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


@jit
def quat_to_mat(w, x, y, z):
    """Rotation matrix (row-major 9-tuple) of q. For |q| != 1 it returns |q|^2 times a rotation
    (the homogeneous form), so an unnormalized quaternion shows up as a scaled R."""
    return (
        w * w + x * x - y * y - z * z, 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
        2.0 * (x * y + w * z), w * w - x * x + y * y - z * z, 2.0 * (y * z - w * x),
        2.0 * (x * z - w * y), 2.0 * (y * z + w * x), w * w - x * x - y * y + z * z,
    )


@jit
def store_mat(rotation, i, m):
    rotation[i, 0, 0] = m[0]
    rotation[i, 0, 1] = m[1]
    rotation[i, 0, 2] = m[2]
    rotation[i, 1, 0] = m[3]
    rotation[i, 1, 1] = m[4]
    rotation[i, 1, 2] = m[5]
    rotation[i, 2, 0] = m[6]
    rotation[i, 2, 1] = m[7]
    rotation[i, 2, 2] = m[8]


@jit
def load_mat(rotation, i):
    r = rotation[i]
    return (r[0, 0], r[0, 1], r[0, 2], r[1, 0], r[1, 1], r[1, 2], r[2, 0], r[2, 1], r[2, 2])


@jit
def mat_to_quat(m):
    """Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method, w >= 0).

    For a matrix that is not exactly orthonormal it returns the normalized quaternion of the
    nearest-by-construction rotation, which is what a logger can show."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    tr = m00 + m11 + m22
    if tr > 0.0:
        s = math.sqrt(tr + 1.0) * 2.0
        w, x, y, z = 0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s
    elif m00 > m11 and m00 > m22:
        s = math.sqrt(1.0 + m00 - m11 - m22) * 2.0
        w, x, y, z = (m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s
    elif m11 > m22:
        s = math.sqrt(1.0 + m11 - m00 - m22) * 2.0
        w, x, y, z = (m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s
    else:
        s = math.sqrt(1.0 + m22 - m00 - m11) * 2.0
        w, x, y, z = (m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if w < 0.0:
        n = -n
    return w / n, x / n, y / n, z / n


@jit
def omega_world(m, inv_i0, inv_i1, inv_i2, lx, ly, lz):
    """omega = R diag(inv_i) R^T L for R given as a row-major 9-tuple."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    b0 = (m00 * lx + m10 * ly + m20 * lz) * inv_i0
    b1 = (m01 * lx + m11 * ly + m21 * lz) * inv_i1
    b2 = (m02 * lx + m12 * ly + m22 * lz) * inv_i2
    return (
        m00 * b0 + m01 * b1 + m02 * b2,
        m10 * b0 + m11 * b1 + m12 * b2,
        m20 * b0 + m21 * b1 + m22 * b2,
    )


@jit
def omega_world_stretched(m, inv_i0, inv_i1, inv_i2, lx, ly, lz):
    """omega = I_world^-1 L with I_world = R I_body R^T, for an R that need not be orthonormal
    (row-major 9-tuple, invertible): omega = R^-T diag(inv_i) R^-1 L.

    With C the cofactor matrix of R (R^-1 = C^T / det R, R^-T = C / det R):
    omega = C diag(inv_i) C^T L / det(R)^2. For an orthonormal R, C = R and det R = 1, and this
    is :func:`omega_world`; for the scaled rotation R = s Q of an unnormalised quaternion
    (s = |q|^2) it is omega_world(Q) / s^2 (see rblog.engine.integrators, seed-quat)."""
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = m
    c00 = a11 * a22 - a12 * a21
    c01 = a12 * a20 - a10 * a22
    c02 = a10 * a21 - a11 * a20
    c10 = a02 * a21 - a01 * a22
    c11 = a00 * a22 - a02 * a20
    c12 = a01 * a20 - a00 * a21
    c20 = a01 * a12 - a02 * a11
    c21 = a02 * a10 - a00 * a12
    c22 = a00 * a11 - a01 * a10
    det = a00 * c00 + a01 * c01 + a02 * c02
    f = 1.0 / (det * det)
    b0 = (c00 * lx + c10 * ly + c20 * lz) * inv_i0 * f
    b1 = (c01 * lx + c11 * ly + c21 * lz) * inv_i1 * f
    b2 = (c02 * lx + c12 * ly + c22 * lz) * inv_i2 * f
    return (
        c00 * b0 + c01 * b1 + c02 * b2,
        c10 * b0 + c11 * b1 + c12 * b2,
        c20 * b0 + c21 * b1 + c22 * b2,
    )


@jit
def polar(m):
    """Nearest rotation to m (orthogonal polar factor) by Newton's iteration R <- (R + R^-T)/2."""
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = m
    for _ in range(POLAR_MAX_ITER):
        # cofactors: R^-T = cof(R) / det(R)
        c00 = a11 * a22 - a12 * a21
        c01 = a12 * a20 - a10 * a22
        c02 = a10 * a21 - a11 * a20
        c10 = a02 * a21 - a01 * a22
        c11 = a00 * a22 - a02 * a20
        c12 = a01 * a20 - a00 * a21
        c20 = a01 * a12 - a02 * a11
        c21 = a02 * a10 - a00 * a12
        c22 = a00 * a11 - a01 * a10
        det = a00 * c00 + a01 * c01 + a02 * c02
        f = 0.5 / det
        n00 = 0.5 * a00 + f * c00
        n01 = 0.5 * a01 + f * c01
        n02 = 0.5 * a02 + f * c02
        n10 = 0.5 * a10 + f * c10
        n11 = 0.5 * a11 + f * c11
        n12 = 0.5 * a12 + f * c12
        n20 = 0.5 * a20 + f * c20
        n21 = 0.5 * a21 + f * c21
        n22 = 0.5 * a22 + f * c22
        d = max(abs(n00 - a00), abs(n01 - a01), abs(n02 - a02), abs(n10 - a10), abs(n11 - a11),
                abs(n12 - a12), abs(n20 - a20), abs(n21 - a21), abs(n22 - a22))
        a00, a01, a02, a10, a11, a12, a20, a21, a22 = n00, n01, n02, n10, n11, n12, n20, n21, n22
        if d <= POLAR_TOL:  # quadratic convergence: the new iterate is within ~d^2 of the limit
            break
    return (a00, a01, a02, a10, a11, a12, a20, a21, a22)


@jit
def gram_schmidt(m):
    """Orthonormalize the columns of m in order (x axis kept, y made orthogonal, z = x cross y)."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    n = math.sqrt(m00 * m00 + m10 * m10 + m20 * m20)
    x0, x1, x2 = m00 / n, m10 / n, m20 / n
    d = x0 * m01 + x1 * m11 + x2 * m21
    y0, y1, y2 = m01 - d * x0, m11 - d * x1, m21 - d * x2
    n = math.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
    y0, y1, y2 = y0 / n, y1 / n, y2 / n
    z0, z1, z2 = x1 * y2 - x2 * y1, x2 * y0 - x0 * y2, x0 * y1 - x1 * y0
    return (x0, y0, z0, x1, y1, z1, x2, y2, z2)


@jit
def normalize4(w, x, y, z):
    n = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    return w * n, x * n, y * n, z * n


# ---- numpy helpers (scene set-up, tests) -----------------------------------------------------

def quat_to_matrix_np(q_wxyz: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions wxyz -> (..., 3, 3) rotation matrices."""
    w, x, y, z = np.moveaxis(np.asarray(q_wxyz, float), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def axis_angle_to_quat_np(axis, angle_rad: float) -> np.ndarray:
    """Unit quaternion wxyz of a rotation by angle_rad about axis (need not be unit)."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    return np.concatenate([[math.cos(angle_rad / 2)], math.sin(angle_rad / 2) * a])
