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

The column constants' documented home is csrc/engine/manifold.hpp (each with its width, frame
and unit); this module reads them from the compiled core, by name. The manifold reduction
(deepest, farthest, largest triangle, largest quad; touching points first) is
``reduce_manifold`` in csrc/engine/manifold.cpp.
"""

from __future__ import annotations

import numpy as np

from rblog.engine import _core

_LAYOUT = _core.collision_layout()


def _columns(*names):
    return tuple(int(_LAYOUT[k]) for k in names)


# per manifold, int64 (mi); per manifold, float64 (mf); per point, float64 (pf): manifold.hpp
(MI_KEY, MI_A, MI_B, MI_REC_A, MI_REC_B, MI_START, MI_COUNT, MI_ACTIVE, MI_COLS) = _columns(
    "MI_KEY", "MI_A", "MI_B", "MI_REC_A", "MI_REC_B", "MI_START", "MI_COUNT", "MI_ACTIVE",
    "MI_COLS")
(MF_N, MF_T1, MF_T2, MF_MU, MF_E, MF_ACC, MF_LU, MF_PIV, MF_LUOK, MF_AR, MF_AT, MF_AOK,
 MF_COLS) = _columns("MF_N", "MF_T1", "MF_T2", "MF_MU", "MF_E", "MF_ACC", "MF_LU", "MF_PIV",
                     "MF_LUOK", "MF_AR", "MF_AT", "MF_AOK", "MF_COLS")
(PF_P, PF_RA, PF_RB, PF_S, PF_NMASS, PF_TK, PF_LN, PF_L1, PF_L2, PF_LP, PF_LWS, PF_W0, PF_F,
 PF_SEND, PF_IMPACT, PF_WT, PF_KN, PF_D, PF_DB, PF_COLS) = _columns(
    "PF_P", "PF_RA", "PF_RB", "PF_S", "PF_NMASS", "PF_TK", "PF_LN", "PF_L1", "PF_L2", "PF_LP",
    "PF_LWS", "PF_W0", "PF_F", "PF_SEND", "PF_IMPACT", "PF_WT", "PF_KN", "PF_D", "PF_DB",
    "PF_COLS")
#: contact log columns (the kernels append rows at sampled steps)
LOG_STEP, LOG_A, LOG_B, LOG_KIND, LOG_I_COLS = _columns(
    "LOG_STEP", "LOG_A", "LOG_B", "LOG_KIND", "LOG_I_COLS")
LOG_P, LOG_N, LOG_S, LOG_LN, LOG_F, LOG_F_COLS = _columns(
    "LOG_P", "LOG_N", "LOG_S", "LOG_LN", "LOG_F", "LOG_F_COLS")


def empty_manifolds(cap_manifolds: int, cap_points: int):
    """Fresh (mi, mf, pf, pid) arrays."""
    return (
        np.zeros((cap_manifolds, MI_COLS), np.int64),
        np.zeros((cap_manifolds, MF_COLS)),
        np.zeros((cap_points, PF_COLS)),
        np.zeros(cap_points, np.int64),
    )


# ---- collider point buffers (manifold.hpp) ----------------------------------------------------
#: rows of the collider's point buffer: a first manifold (rows 0..3 after reduction, up to 8
#: while clipping) and a box pair's second manifold (rows 4.., up to 8 while clipping)
MAX_CLIP_POINTS, MAX_MANIFOLD_POINTS = _columns("MAX_CLIP_POINTS", "MAX_MANIFOLD_POINTS")
#: m^2: triangle areas (about the normal) below this add nothing to a manifold (collinear points)
_AREA_EPS = float(_LAYOUT["_AREA_EPS"])
