"""Rotation math shared by the engine: quaternions, matrices, world-frame inertia products.

Frames: ``q`` (wxyz, scalar first) and ``R`` map body-frame vectors to the world frame
(``v_world = R v_body``). Angular momentum ``L`` is world frame; ``inv_inertia`` is the diagonal of
I_body^-1 (principal axes), so omega = R diag(1/I) R^T L, as in the lecture notes.

The compiled helpers are C++ (csrc/engine/rotation.hpp, inline over scalars, where their
derivations are written; the kernels compile them into their loops); the names below call them
through rblog.engine._core (scalars in, tuples out; a matrix is a row-major 9-tuple). The ``*_np``
helpers at the bottom are their numpy twins for scene set-up. The integrators that use these live
in :mod:`rblog.engine.integrators`. (The analyzers keep their own geometry on purpose: an audit
must not share the code it audits.)
"""

from __future__ import annotations

import math

import numpy as np

from rblog.engine import _core

#: Hamilton product a (x) b: quat_mul(aw, ax, ay, az, bw, bx, by, bz) -> (w, x, y, z)
quat_mul = _core.quat_mul
#: rotation matrix (row-major 9-tuple) of q; |q|^2 times a rotation for |q| != 1
quat_to_mat = _core.quat_to_mat
#: unit quaternion (w >= 0) of a row-major 9-tuple (Shepperd's method)
mat_to_quat = _core.mat_to_quat
#: omega = R diag(inv_i) R^T L: omega_world(m, inv_i0, inv_i1, inv_i2, lx, ly, lz)
omega_world = _core.omega_world
#: omega = I_world^-1 L for an R that need not be orthonormal (seed-quat without normalization)
omega_world_stretched = _core.omega_world_stretched
#: nearest rotation (polar factor) by Newton's iteration (constants.POLAR_TOL, POLAR_MAX_ITER)
polar = _core.polar
#: columns orthonormalized in order
gram_schmidt = _core.gram_schmidt
#: q / |q|
normalize4 = _core.normalize4


def load_mat(rotation: np.ndarray, i: int) -> tuple:
    """R[i] of a (N, 3, 3) array as a row-major 9-tuple."""
    return tuple(float(v) for v in rotation[i].reshape(9))


def store_mat(rotation: np.ndarray, i: int, m) -> None:
    """R[i] of a (N, 3, 3) array set from a row-major 9-tuple."""
    rotation[i] = np.asarray(m, float).reshape(3, 3)


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
