"""Column layout of the packed contact arrays (Box2D's contact constraints, as SoA rows).

Three arrays hold the manifolds of one step; a second set holds the previous step's, for warm
starting and for manifolds of sleeping bodies, which are carried over unchanged.

* ``mi`` (M, MI_COLS) int64 per manifold: pair key, solver body indices, record body indices,
  first point, point count, active flag.
* ``mf`` (M, MF_COLS) float64 per manifold: normal and tangent basis (world), friction,
  restitution, relative normal acceleration from the external forces.
* ``pf`` (K, PF_COLS) float64 per point, ``pid`` (K,) int64 feature ids.

Frames and signs: the normal points from body b into body a; anchors ``ra``/``rb`` are the world
offsets of the contact point from the centres of mass at the narrowphase; a positive normal
impulse pushes a along +normal and b along -normal; the friction impulse ``f`` is the world
vector applied to a (b gets -f). Solver body index ``n_bodies`` is a static dummy (zero inverse
mass, zero velocity) standing for the ground, static boxes and sleeping bodies.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rblog.engine.constants import MANIFOLD_TOUCH_BAND_M

# ---- per manifold, int64 ----
MI_KEY = 0  # 2 (lo * n_shapes + hi) + part; shape ids: bodies, static boxes, ground; part 1 is
#            a box pair's second manifold (face manifold beside an edge contact)
MI_A = 1  # solver index of body a (or the static dummy)
MI_B = 2  # solver index of body b (or the static dummy)
MI_REC_A = 3  # body index of a for the record
MI_REC_B = 4  # body index of b, or STATIC_BODY (-1)
MI_START = 5  # first point
MI_COUNT = 6  # number of points (1..4)
MI_ACTIVE = 7  # 1: solved this step; 0: carried over (both sides asleep or static)
MI_COLS = 8

# ---- per manifold, float64 ----
MF_N = 0  # normal (3), from b into a
MF_T1 = 3  # first tangent (3)
MF_T2 = 6  # second tangent (3) = n x t1
MF_MU = 9  # friction coefficient sqrt(mu_a mu_b)
MF_E = 10  # restitution max(e_a, e_b)
MF_ACC = 11  # gap acceleration from external forces: n . (a_a - a_b) (m/s^2)
MF_LU = 12  # LU factors of the regularised normal block (4 x 4, row-major; prepare_contacts)
MF_PIV = 28  # pivot row of each elimination column (4, as floats)
MF_LUOK = 32  # 1.0: the block factored (non-singular), else 0.0
MF_AR = 33  # friction anchor: pose of a in b's frame when the pair started sticking: R_b^T R_a (9,
#            row-major) ...
MF_AT = 42  # ... and R_b^T (x_a - x_b) (3), m (b's frame: the world for the ground)
MF_AOK = 45  # 1.0: the anchor pose holds (collide sets it, store_impulses drops it), else 0.0
MF_COLS = 46

# ---- per point, float64 ----
PF_P = 0  # contact point (3), world, midpoint of the surfaces
PF_RA = 3  # anchor on a (3): point - x_a
PF_RB = 6  # anchor on b (3): point - x_b (0 for static)
PF_S = 9  # separation at the narrowphase (m), < 0 penetration
PF_NMASS = 10  # 1 / (J M^-1 J^T) along the normal
PF_TK = 11  # 2x2 tangent block of the effective inverse mass K (3: k11, k12, k22)
PF_LN = 14  # accumulated normal impulse (N s)
PF_L1 = 15  # accumulated friction impulse along t1
PF_L2 = 16  # ... along t2
PF_LP = 17  # accumulated pseudo impulse of the position correction
PF_LWS = 18  # normal impulse of the velocity solve (before restitution): next step's warm start
PF_W0 = 19  # normal velocity of the gap at the start of the step, before the force kick (m/s)
PF_F = 20  # friction impulse on a, world (3)
PF_SEND = 23  # separation estimated at the end of the step (m)
PF_IMPACT = 24  # 1.0 if the point was an impact (approach speed above the threshold)
PF_WT = 25  # restitution's target gap velocity (m/s), < 0 when the point does not bounce
PF_KN = 26  # row of the manifold's normal block K_ij (4: one entry per point of the manifold)
PF_D = 30  # friction anchor: slip of a's material point at the contact since the pair started
#            sticking (3), world, m: where it is minus where the anchor pose puts it (collide)
PF_DB = 33  # the anchor's bias, FRICTION_ANCHOR_RATE (D . t1, D . t2) / h (2), m/s (prepare)
PF_COLS = 35

#: contact log columns (the kernels append rows at sampled steps)
LOG_STEP, LOG_A, LOG_B, LOG_KIND = 0, 1, 2, 3
LOG_I_COLS = 4
LOG_P, LOG_N, LOG_S, LOG_LN, LOG_F = 0, 3, 6, 7, 8
LOG_F_COLS = 11


def empty_manifolds(cap_manifolds: int, cap_points: int):
    """Fresh (mi, mf, pf, pid) arrays."""
    return (
        np.zeros((cap_manifolds, MI_COLS), np.int64),
        np.zeros((cap_manifolds, MF_COLS)),
        np.zeros((cap_points, PF_COLS)),
        np.zeros(cap_points, np.int64),
    )


# ---- collider point buffers -------------------------------------------------------------------
#: rows of the collider's point buffer: a first manifold (rows 0..3 after reduction, up to 8
#: while clipping) and a box pair's second manifold (rows 4.., up to 8 while clipping)
MAX_CLIP_POINTS = 12
MAX_MANIFOLD_POINTS = 4
#: m^2: triangle areas (about the normal) below this add nothing to a manifold (collinear points)
_AREA_EPS = 1e-12


@njit(cache=True)
def swap_point(pts, sep, fid, i, j):
    if i == j:
        return
    for k in range(3):
        t = pts[i, k]
        pts[i, k] = pts[j, k]
        pts[j, k] = t
    t = sep[i]
    sep[i] = sep[j]
    sep[j] = t
    f = fid[i]
    fid[i] = fid[j]
    fid[j] = f


@njit(cache=True)
def reduce_manifold(nrm, pts, sep, fid, count):
    """Keep four of ``count`` coplanar-ish points: deepest, farthest from it, the one making the
    largest triangle, the one adding the most area outside that triangle (Gregorius), each chosen
    among the touching points first (within MANIFOLD_TOUCH_BAND_M of the deepest) and among all
    of them only when no touching point is left that adds length or area. Returns 4."""
    if count <= MAX_MANIFOLD_POINTS:
        return count
    nx, ny, nz = nrm[0], nrm[1], nrm[2]
    # 1: deepest
    best = 0
    for j in range(1, count):
        if sep[j] < sep[best]:
            best = j
    swap_point(pts, sep, fid, 0, best)
    touch = sep[0] + MANIFOLD_TOUCH_BAND_M
    # 2: farthest from point 0 (touching first)
    best = -1
    bd = 0.0
    for only_touching in (True, False):
        for j in range(1, count):
            if only_touching and sep[j] > touch:
                continue
            dx, dy, dz = pts[j, 0] - pts[0, 0], pts[j, 1] - pts[0, 1], pts[j, 2] - pts[0, 2]
            d = dx * dx + dy * dy + dz * dz
            if d > bd:
                bd = d
                best = j
        if best >= 0:
            break
    swap_point(pts, sep, fid, 1, max(best, 1))
    # 3: largest |triangle area| with 0, 1 (measured about the normal; touching first)
    ax, ay, az = pts[1, 0] - pts[0, 0], pts[1, 1] - pts[0, 1], pts[1, 2] - pts[0, 2]
    best = -1
    ba = _AREA_EPS
    sgn = 1.0
    for only_touching in (True, False):
        for j in range(2, count):
            if only_touching and sep[j] > touch:
                continue
            bx, by, bz = pts[j, 0] - pts[0, 0], pts[j, 1] - pts[0, 1], pts[j, 2] - pts[0, 2]
            area = nx * (ay * bz - az * by) + ny * (az * bx - ax * bz) + nz * (ax * by - ay * bx)
            if abs(area) > ba:
                ba = abs(area)
                best = j
                sgn = 1.0 if area >= 0.0 else -1.0
        if best >= 0:
            break
    swap_point(pts, sep, fid, 2, max(best, 2))
    # 4: the point farthest outside the triangle (most negative signed area over its edges;
    # touching first)
    best = -1
    ba = -_AREA_EPS
    for only_touching in (True, False):
        for j in range(3, count):
            if only_touching and sep[j] > touch:
                continue
            worst = 0.0
            for e in range(3):
                i0 = e
                i1 = (e + 1) % 3
                ex, ey, ez = pts[i1, 0] - pts[i0, 0], pts[i1, 1] - pts[i0, 1], pts[i1, 2] - pts[i0, 2]
                qx, qy, qz = pts[j, 0] - pts[i0, 0], pts[j, 1] - pts[i0, 1], pts[j, 2] - pts[i0, 2]
                area = sgn * (nx * (ey * qz - ez * qy) + ny * (ez * qx - ex * qz)
                              + nz * (ex * qy - ey * qx))
                if area < worst:
                    worst = area
            if worst < ba:
                ba = worst
                best = j
        if best >= 0:
            break
    swap_point(pts, sep, fid, 3, max(best, 3))
    return MAX_MANIFOLD_POINTS
