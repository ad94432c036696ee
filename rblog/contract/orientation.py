"""Orientation conversions of the log contract: unit quaternions (scalar first, body -> world),
rotation matrices (``v_world = R v_body``) and rotation vectors, vectorized over leading axes.

Used by the writers (:class:`rblog.record.Recorder` derives the channel a writer did not give) and
by the audit (rblog.analyze.consistency); numpy only.
"""

from __future__ import annotations

import numpy as np


def quat_wxyz_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) quaternions (scalar first, normalized here) -> (..., 3, 3) rotation matrices."""
    q = np.asarray(q, np.float64)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    q = q / np.where(n > 0, n, 1.0)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(q.shape[:-1] + (3, 3))
    out[..., 0, 0] = 1 - 2 * (y * y + z * z)
    out[..., 0, 1] = 2 * (x * y - w * z)
    out[..., 0, 2] = 2 * (x * z + w * y)
    out[..., 1, 0] = 2 * (x * y + w * z)
    out[..., 1, 1] = 1 - 2 * (x * x + z * z)
    out[..., 1, 2] = 2 * (y * z - w * x)
    out[..., 2, 0] = 2 * (x * z - w * y)
    out[..., 2, 1] = 2 * (y * z + w * x)
    out[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def matrix_to_quat(r: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 4) unit quaternions, scalar first, w >= 0
    (Shepperd's method: the largest of 4 w^2, 4 x^2, ... picks the stable branch)."""
    r = np.asarray(r, np.float64)
    tr = np.trace(r, axis1=-2, axis2=-1)
    d = np.stack([tr, r[..., 0, 0], r[..., 1, 1], r[..., 2, 2]], axis=-1)
    k = np.argmax(d, axis=-1)
    q = np.empty(r.shape[:-2] + (4,))
    s0 = np.sqrt(np.maximum(1.0 + tr, 0.0)) * 2  # 4 w
    s1 = np.sqrt(np.maximum(1.0 + r[..., 0, 0] - r[..., 1, 1] - r[..., 2, 2], 0.0)) * 2
    s2 = np.sqrt(np.maximum(1.0 + r[..., 1, 1] - r[..., 0, 0] - r[..., 2, 2], 0.0)) * 2
    s3 = np.sqrt(np.maximum(1.0 + r[..., 2, 2] - r[..., 0, 0] - r[..., 1, 1], 0.0)) * 2
    with np.errstate(divide="ignore", invalid="ignore"):
        c0 = np.stack([0.25 * s0, (r[..., 2, 1] - r[..., 1, 2]) / s0, (r[..., 0, 2] - r[..., 2, 0]) / s0,
                       (r[..., 1, 0] - r[..., 0, 1]) / s0], -1)
        c1 = np.stack([(r[..., 2, 1] - r[..., 1, 2]) / s1, 0.25 * s1, (r[..., 0, 1] + r[..., 1, 0]) / s1,
                       (r[..., 0, 2] + r[..., 2, 0]) / s1], -1)
        c2 = np.stack([(r[..., 0, 2] - r[..., 2, 0]) / s2, (r[..., 0, 1] + r[..., 1, 0]) / s2, 0.25 * s2,
                       (r[..., 1, 2] + r[..., 2, 1]) / s2], -1)
        c3 = np.stack([(r[..., 1, 0] - r[..., 0, 1]) / s3, (r[..., 0, 2] + r[..., 2, 0]) / s3,
                       (r[..., 1, 2] + r[..., 2, 1]) / s3, 0.25 * s3], -1)
    q = np.choose(k[..., None], [c0, c1, c2, c3])
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def rotvec_of_matrix(r: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 3) rotation vectors (axis * angle, angle in
    [0, pi]); accurate for small angles (no arccos near 1)."""
    v = 0.5 * np.stack([r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0],
                        r[..., 1, 0] - r[..., 0, 1]], axis=-1)
    s = np.linalg.norm(v, axis=-1)
    c = 0.5 * (np.trace(r, axis1=-2, axis2=-1) - 1.0)
    ang = np.arctan2(s, c)
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(s > 1e-300, ang / s, 1.0)
    return v * scale[..., None]


__all__ = ["quat_wxyz_to_matrix", "matrix_to_quat", "rotvec_of_matrix"]


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b of (..., 4) scalar-first quaternions (broadcast): the rotation b
    then a (for a body -> world and b geom -> body: geom -> world)."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], axis=-1)
