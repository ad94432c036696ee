"""Mass properties of the scene's shapes: volume and principal moments, closed forms.

Every shape is in its own frame, centred on its centre of mass with its principal axes along the
frame's (the contract's geom conventions, rblog.contract.model GEOM_*); ``inertia_diag`` returns
the moments (I_xx, I_yy, I_zz) about the centre of mass for a mass ``m`` spread uniformly.

Derivations (uniform density rho, ``r`` radius, ``h`` half length along z, ``e`` half extents):

* sphere: V = 4/3 pi r^3, I = 2/5 m r^2 about every axis.
* box: V = 8 e_x e_y e_z, I_xx = m (e_y^2 + e_z^2) / 3 (and cyclic).
* cylinder (|z| <= h, x^2 + y^2 <= r^2): V = 2 pi r^2 h; I_zz = m r^2 / 2 (discs m r^2 / 2);
  I_xx = m (r^2 / 4 + h^2 / 3) (each disc of mass dm at height z contributes dm (r^2 / 4 + z^2);
  the mean of z^2 over [-h, h] is h^2 / 3).
* capsule (the segment |z| <= h grown by r): a cylinder of mass m_c = rho 2 pi r^2 h and two
  hemispheres, together a sphere of mass m_s = rho 4/3 pi r^3. I_zz = m_c r^2 / 2 + 2/5 m_s r^2.
  About x through the centre: each hemisphere has I = 2/5 (m_s / 2) r^2 about its flat face's
  diameter and its centre of mass at 3 r / 8 from the face; moving that axis to the capsule's
  centre (the face at distance h) by the parallel-axis theorem twice gives, for both,
  m_s (2/5 r^2 + h^2 + 3/4 h r); with the cylinder's m_c (r^2 / 4 + h^2 / 3).
"""

from __future__ import annotations

import math

import numpy as np


# Volumes in m^3, written as products so that a value past 1e308 is inf (the scene's mass check
# names it) instead of an OverflowError.

def sphere_volume(r: float) -> float:
    return 4.0 / 3.0 * math.pi * (r * r * r)


def box_volume(e) -> float:
    return 8.0 * math.prod(float(x) for x in e)  # inf past 1e308


def cylinder_volume(r: float, h: float) -> float:
    return 2.0 * math.pi * r * r * h


def capsule_volume(r: float, h: float) -> float:
    return cylinder_volume(r, h) + sphere_volume(r)


def sphere_inertia(m: float, r: float) -> np.ndarray:
    return np.full(3, 0.4 * m * r ** 2)


def box_inertia(m: float, e) -> np.ndarray:
    a, b, c = np.asarray(e, float) ** 2
    return m / 3.0 * np.array([b + c, a + c, a + b])


def cylinder_inertia(m: float, r: float, h: float) -> np.ndarray:
    ix = m * (r * r / 4.0 + h * h / 3.0)
    return np.array([ix, ix, 0.5 * m * r * r])


def capsule_inertia(m: float, r: float, h: float) -> np.ndarray:
    v_c, v_s = cylinder_volume(r, h), sphere_volume(r)
    m_c = m * v_c / (v_c + v_s)
    m_s = m * v_s / (v_c + v_s)
    ix = m_c * (r * r / 4.0 + h * h / 3.0) + m_s * (0.4 * r * r + h * h + 0.75 * h * r)
    return np.array([ix, ix, 0.5 * m_c * r * r + 0.4 * m_s * r * r])


# ---- convex hulls ---------------------------------------------------------------------------
# A hull is given by its vertices (V, 3) and its boundary as triangles (T, 3) of vertex indices,
# each counter-clockwise seen from outside (outward normal (b - a) x (c - a)).
#
# Derivation (divergence theorem): cut the solid into the tetrahedra (o, a, b, c) of each
# boundary triangle with a common apex o. A tetrahedron with vertices p0 = o, p1, p2, p3 has the
# signed volume V_t = det[p1 - o, p2 - o, p3 - o] / 6 (positive when the triangle faces away from
# o), centroid (p0 + p1 + p2 + p3) / 4 and, with s = sum_k p_k, second moments
# C_t = int x x^T dV = V_t / 20 (sum_k p_k p_k^T + s s^T) (Tonon 2004, J. Math. Stat. 1(1)). The
# signed sums over the triangles are the solid's volume V, first moment V c and second moment C
# (every point outside the solid is counted as often positively as negatively). With o at the
# vertices' mean (round-off), uniform density m / V: the inertia about the centre of mass c is
# I = (m / V) (tr(C_c) 1 - C_c) with C_c = C - V c c^T.

def hull_volume_com_second_moment(vertices, triangles) -> tuple[float, np.ndarray, np.ndarray]:
    """(V m^3, centre of mass c (3,), C_c = int (x - c)(x - c)^T dV (3, 3) m^5) of the solid whose
    boundary is ``triangles`` (T, 3) over ``vertices`` (V, 3), in the vertices' frame."""
    v = np.asarray(vertices, np.float64)
    o = v.mean(axis=0)
    p = v[np.asarray(triangles, np.int64)] - o  # (T, 3 corners, 3)
    det = np.einsum("ti,ti->t", p[:, 0], np.cross(p[:, 1], p[:, 2]))
    vol_t = det / 6.0
    vol = float(vol_t.sum())
    s = p.sum(axis=1)  # (T, 3): the apex o is the origin here
    first = (vol_t[:, None] * s).sum(axis=0) / 4.0
    pp = np.einsum("tki,tkj->tij", p, p) + np.einsum("ti,tj->tij", s, s)
    second = (vol_t[:, None, None] * pp).sum(axis=0) / 20.0
    c = first / vol
    second_c = second - vol * np.outer(c, c)
    return vol, c + o, second_c


def hull_inertia_tensor(m: float, volume: float, second_c) -> np.ndarray:
    """(3, 3) inertia about the centre of mass of mass ``m`` spread over the hull (kg m^2)."""
    cc = np.asarray(second_c, np.float64) * (m / volume)
    return np.trace(cc) * np.eye(3) - cc


#: off-diagonal inertia entries at most this times the largest moment are taken as zero: the
#: given axes are then principal (a hull of a box's corners keeps the box's axes exactly)
PRINCIPAL_OFFDIAG_RTOL = 1e-12


def principal_axes(inertia) -> tuple[np.ndarray, np.ndarray]:
    """(moments (3,), Q (3, 3)) with inertia = Q diag(moments) Q^T, Q a rotation (det +1) whose
    columns are the principal axes in the given frame. Q = 1 when the tensor is diagonal to
    PRINCIPAL_OFFDIAG_RTOL; else numpy's eigh, each column's largest component made positive
    (a deterministic choice among the eigenvectors' signs), the third flipped for det +1."""
    j = np.asarray(inertia, np.float64)
    off = np.abs(j - np.diag(np.diag(j))).max()
    if off <= PRINCIPAL_OFFDIAG_RTOL * np.abs(np.diag(j)).max():
        return np.diag(j).copy(), np.eye(3)
    w, q = np.linalg.eigh(0.5 * (j + j.T))
    for k in range(3):
        if q[np.argmax(np.abs(q[:, k])), k] < 0:
            q[:, k] = -q[:, k]
    if np.linalg.det(q) < 0:
        q[:, 2] = -q[:, 2]
    return w, q


# ---- compound bodies ------------------------------------------------------------------------
# A compound body is several parts of one uniform density rho, each a shape with its own pose in
# the body's scene frame: part k has mass m_k = rho V_k, centre of mass c_k and inertia tensor
# J_k = R_k diag(I_k) R_k^T about c_k (I_k its principal moments, R_k its principal axes in the
# scene frame). Overlapping parts count twice (MuJoCo's rule for the geoms of one body). The
# body's mass is M = sum m_k, its centre of mass c = sum m_k c_k / M, and by the parallel-axis
# theorem its inertia about c is
#
#     J = sum_k [J_k + m_k (|d_k|^2 1 - d_k d_k^T)],   d_k = c_k - c,
#
# whose principal axes (principal_axes) are the body frame's.

def compound_inertia_tensor(masses, coms, tensors) -> tuple[float, np.ndarray, np.ndarray]:
    """(M kg, c (3,) m, J (3, 3) kg m^2 about c) of parts of ``masses`` (K,) kg with centres
    ``coms`` (K, 3) and inertia tensors ``tensors`` (K, 3, 3) about their own centres, all in
    one frame (the parallel-axis sum above)."""
    m = np.asarray(masses, np.float64).reshape(-1)
    x = np.asarray(coms, np.float64).reshape(-1, 3)
    j = np.asarray(tensors, np.float64).reshape(-1, 3, 3)
    total = float(m.sum())
    c = (m[:, None] * x).sum(axis=0) / total
    d = x - c
    shift = m[:, None, None] * (np.einsum("ki,ki->k", d, d)[:, None, None] * np.eye(3)
                                - np.einsum("ki,kj->kij", d, d))
    return total, c, (j + shift).sum(axis=0)
