"""Rotation math for the compiled kernels, and the torque-free rotational drift of each integrator.

Frames: ``q`` (wxyz) and ``R`` map body-frame vectors to the world frame. Angular momentum ``L``
is world frame; ``inv_inertia`` is the diagonal of I_body^-1 (principal axes).

Everything here is ``numba.njit(inline="always")`` over scalars and tuples, so that a kernel
stepping N bodies allocates nothing per step. Drift functions update ``quat_wxyz[i]`` and
``rotation[i]`` of the state arrays in place and keep the two consistent (except under the notes'
own schemes with orthonormalization off, where the integrator's R is the point of interest).

Derivations
-----------
Notes' scheme (``seed``): omega = R I_b^-1 R^T L, R <- R + h [omega]x R, then orthonormalize.
det(I + h[omega]x) = 1 + h^2 |omega|^2, so without orthonormalization det R grows like
exp(h * integral |omega|^2 dt): the body "stretches".

Splitting (``splitting``): the free-body Hamiltonian H = sum_k Lb_k^2 / (2 I_k) (Lb = R^T L) is a
sum of three exactly solvable parts. The flow of part k over time s rotates the body about its own
axis k by theta = s Lb_k / I_k (q <- q (x) (cos theta/2, sin theta/2 e_k)) and rotates Lb by
-theta about e_k, leaving L = R Lb unchanged. Strang composition 1(h/2) 2(h/2) 3(h) 2(h/2) 1(h/2)
is second order, symplectic and time-reversible; |L| (world) is untouched and R stays a product of
exact rotations, so both invariants hold to round-off (McLachlan 1993; Dullweber, Leimkuhler &
McLachlan 1997).

RK4 (``rk4``): classical RK4 on dq/dt = 1/2 (0, omega) (x) q with omega = R(q) I_b^-1 R(q)^T L,
followed by normalization of q.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .constants import POLAR_MAX_ITER, POLAR_TOL

# integrator codes used by the kernels
METHOD_SEED = 0
METHOD_SEED_QUAT = 1
METHOD_SPLITTING = 2
METHOD_RK4 = 3
METHOD_CODES = {"seed": METHOD_SEED, "seed-quat": METHOD_SEED_QUAT, "splitting": METHOD_SPLITTING,
                "rk4": METHOD_RK4}

# orthonormalization codes
ORTHO_NONE = 0
ORTHO_POLAR = 1
ORTHO_GRAM_SCHMIDT = 2
ORTHO_NORMALIZE = 3  # quaternion normalization (seed-quat, splitting, rk4)
ORTHO_CODES = {"none": ORTHO_NONE, "polar": ORTHO_POLAR, "gram-schmidt": ORTHO_GRAM_SCHMIDT,
               "normalize": ORTHO_NORMALIZE}
#: integrator -> (allowed orthonormalize options, default)
ORTHO_ALLOWED = {
    "seed": (("polar", "gram-schmidt", "none"), "polar"),
    "seed-quat": (("normalize", "none"), "normalize"),
    "splitting": (("normalize",), "normalize"),
    "rk4": (("normalize",), "normalize"),
}

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


@jit
def _qdot(w, x, y, z, m_inv, lx, ly, lz):
    """dq/dt = 1/2 (0, omega) (x) q with omega from the normalized q."""
    n = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    m = quat_to_mat(w * n, x * n, y * n, z * n)
    ox, oy, oz = omega_world(m, m_inv[0], m_inv[1], m_inv[2], lx, ly, lz)
    dw, dx, dy, dz = quat_mul(0.0, ox, oy, oz, w, x, y, z)
    return 0.5 * dw, 0.5 * dx, 0.5 * dy, 0.5 * dz


# Exact flows of H_k = Lb_k^2 / (2 I_k) over time s, given s/I_k: rotate the body about its own
# axis k by theta = s Lb_k / I_k and Lb by -theta. Half-angle sine/cosine for the quaternion, the
# full angle's from the double-angle formulas: one sin/cos pair per sub-step.
@jit
def _flow_x(w, x, y, z, b0, b1, b2, s_inv_i):
    th = s_inv_i * b0
    ch, sh = math.cos(0.5 * th), math.sin(0.5 * th)
    c, sn = ch * ch - sh * sh, 2.0 * ch * sh
    return (ch * w - sh * x, ch * x + sh * w, ch * y + sh * z, ch * z - sh * y,
            b0, c * b1 + sn * b2, c * b2 - sn * b1)


@jit
def _flow_y(w, x, y, z, b0, b1, b2, s_inv_i):
    th = s_inv_i * b1
    ch, sh = math.cos(0.5 * th), math.sin(0.5 * th)
    c, sn = ch * ch - sh * sh, 2.0 * ch * sh
    return (ch * w - sh * y, ch * x - sh * z, ch * y + sh * w, ch * z + sh * x,
            c * b0 - sn * b2, b1, c * b2 + sn * b0)


@jit
def _flow_z(w, x, y, z, b0, b1, b2, s_inv_i):
    th = s_inv_i * b2
    ch, sh = math.cos(0.5 * th), math.sin(0.5 * th)
    c, sn = ch * ch - sh * sh, 2.0 * ch * sh
    return (ch * w - sh * z, ch * x + sh * y, ch * y - sh * x, ch * z + sh * w,
            c * b0 + sn * b1, c * b1 - sn * b0, b2)


@jit
def drift_seed(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h):
    """The notes' drift: R += h [omega]x R with omega = R I^-1 R^T L, then orthonormalize."""
    lx = angular_momentum[i, 0]
    ly = angular_momentum[i, 1]
    lz = angular_momentum[i, 2]
    ii = inv_inertia[i]
    m = load_mat(rotation, i)
    ox, oy, oz = omega_world(m, ii[0], ii[1], ii[2], lx, ly, lz)
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    # R <- R + h [omega]x R
    n = (
        m00 + h * (-oz * m10 + oy * m20), m01 + h * (-oz * m11 + oy * m21),
        m02 + h * (-oz * m12 + oy * m22),
        m10 + h * (oz * m00 - ox * m20), m11 + h * (oz * m01 - ox * m21),
        m12 + h * (oz * m02 - ox * m22),
        m20 + h * (-oy * m00 + ox * m10), m21 + h * (-oy * m01 + ox * m11),
        m22 + h * (-oy * m02 + ox * m12),
    )
    if ortho == ORTHO_POLAR:
        n = polar(n)
    elif ortho == ORTHO_GRAM_SCHMIDT:
        n = gram_schmidt(n)
    store_mat(rotation, i, n)
    # the quaternion is derived from R only when logged (see kernels.sync_quat)


@jit
def drift_seed_quat(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h):
    """The notes' drift on the quaternion: q += h/2 (0, omega) (x) q, normalized unless ortho is none."""
    lx = angular_momentum[i, 0]
    ly = angular_momentum[i, 1]
    lz = angular_momentum[i, 2]
    ii = inv_inertia[i]
    w, x, y, z = quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3]
    m = load_mat(rotation, i)
    ox, oy, oz = omega_world(m, ii[0], ii[1], ii[2], lx, ly, lz)
    dw, dx, dy, dz = quat_mul(0.0, ox, oy, oz, w, x, y, z)
    w, x, y, z = w + 0.5 * h * dw, x + 0.5 * h * dx, y + 0.5 * h * dy, z + 0.5 * h * dz
    if ortho != ORTHO_NONE:
        w, x, y, z = normalize4(w, x, y, z)
    quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3] = w, x, y, z
    store_mat(rotation, i, quat_to_mat(w, x, y, z))


@jit
def drift_splitting(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h):
    """Strang splitting 1(h/2) 2(h/2) 3(h) 2(h/2) 1(h/2) of the free rotation into exact axis rotations."""
    lx = angular_momentum[i, 0]
    ly = angular_momentum[i, 1]
    lz = angular_momentum[i, 2]
    ii = inv_inertia[i]
    w, x, y, z = quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3]
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = load_mat(rotation, i)
    # body-frame angular momentum Lb = R^T L
    b0 = m00 * lx + m10 * ly + m20 * lz
    b1 = m01 * lx + m11 * ly + m21 * lz
    b2 = m02 * lx + m12 * ly + m22 * lz
    hh = 0.5 * h
    w, x, y, z, b0, b1, b2 = _flow_x(w, x, y, z, b0, b1, b2, hh * ii[0])
    w, x, y, z, b0, b1, b2 = _flow_y(w, x, y, z, b0, b1, b2, hh * ii[1])
    w, x, y, z, b0, b1, b2 = _flow_z(w, x, y, z, b0, b1, b2, h * ii[2])
    w, x, y, z, b0, b1, b2 = _flow_y(w, x, y, z, b0, b1, b2, hh * ii[1])
    w, x, y, z, b0, b1, b2 = _flow_x(w, x, y, z, b0, b1, b2, hh * ii[0])
    w, x, y, z = normalize4(w, x, y, z)
    quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3] = w, x, y, z
    store_mat(rotation, i, quat_to_mat(w, x, y, z))


@jit
def drift_rk4(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h, tx=0.0, ty=0.0, tz=0.0):
    """Classical RK4 on q with L(t) = L + t * torque, then normalization."""
    lx = angular_momentum[i, 0]
    ly = angular_momentum[i, 1]
    lz = angular_momentum[i, 2]
    ii = inv_inertia[i]
    w, x, y, z = quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3]
    a = 0.5 * h
    mx, my, mz = lx + a * tx, ly + a * ty, lz + a * tz
    k1 = _qdot(w, x, y, z, ii, lx, ly, lz)
    k2 = _qdot(w + a * k1[0], x + a * k1[1], y + a * k1[2], z + a * k1[3], ii, mx, my, mz)
    k3 = _qdot(w + a * k2[0], x + a * k2[1], y + a * k2[2], z + a * k2[3], ii, mx, my, mz)
    k4 = _qdot(w + h * k3[0], x + h * k3[1], y + h * k3[2], z + h * k3[3], ii,
               lx + h * tx, ly + h * ty, lz + h * tz)
    g = h / 6.0
    w = w + g * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
    x = x + g * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
    y = y + g * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
    z = z + g * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3])
    w, x, y, z = normalize4(w, x, y, z)
    quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3] = w, x, y, z
    store_mat(rotation, i, quat_to_mat(w, x, y, z))


@njit(cache=True)
def drift_rotation(method, ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h,
                   tx=0.0, ty=0.0, tz=0.0):
    """Advance body i's orientation over h with L (world) held fixed, by the integrator ``method``.

    The applied torque (tx, ty, tz) (world, constant over the step) is used only by RK4, whose
    stages see L(t) = L + t * torque; the other methods take torque as kicks around this drift.

    Args:
        method, ortho: METHOD_* and ORTHO_* codes.
        quat_wxyz: (N, 4), rotation: (N, 3, 3) updated in place for body i.
        angular_momentum: (N, 3) world frame, read only.  inv_inertia: (N, 3) diag(I_body^-1).
    """
    if method == METHOD_SEED:
        drift_seed(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h)
    elif method == METHOD_SEED_QUAT:
        drift_seed_quat(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h)
    elif method == METHOD_SPLITTING:
        drift_splitting(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h)
    else:
        drift_rk4(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h, tx, ty, tz)


@njit(cache=True)
def sync_quat(method, quat_wxyz, rotation, i):
    """Make q[i] describe R[i] for the integrator that advances R (seed); no-op for the others."""
    if method == METHOD_SEED:
        # the rotation part of R (its polar factor): without orthonormalization R = s Q drifts
        # in scale, and Shepperd's formula assumes unit scale. Divide out the largest entry
        # first so that a huge (but finite) R does not overflow in the cofactors.
        m = load_mat(rotation, i)
        big = 0.0
        for v in m:
            big = max(big, abs(v))
        if big > 0.0 and math.isfinite(big):
            inv = 1.0 / big
            m = (m[0] * inv, m[1] * inv, m[2] * inv, m[3] * inv, m[4] * inv, m[5] * inv,
                 m[6] * inv, m[7] * inv, m[8] * inv)
        w, x, y, z = mat_to_quat(polar(m))
        quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3] = w, x, y, z


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
