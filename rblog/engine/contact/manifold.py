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

This module is the documented home of the column constants; csrc/engine/manifold.hpp mirrors them
for the C++ core (tests/engine/contact/test_collision_core.py checks that they agree). The
manifold reduction (deepest, farthest, largest triangle, largest quad; touching points first) is
``reduce_manifold`` in csrc/engine/manifold.cpp.
"""

from __future__ import annotations

import numpy as np

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
