"""The contact constraints' records as numpy sees them (Box2D's contact constraints).

Three arrays hold the manifolds of one step; a second set holds the previous step's, for warm
starting and for manifolds of sleeping bodies, which are carried over unchanged.

* ``mi`` (M, MI_COLS) int64, a manifold's head per row: pair key, solver body indices, record
  body indices, first point, point count, active flag.
* ``mf`` (M, MF_COLS) float64, a manifold per row: normal and tangent basis (world), friction,
  restitution, relative normal acceleration from the external forces, the normal block's
  factors, the friction anchor.
* ``pf`` (K, PF_COLS) float64, a contact point per row; ``pid`` (K,) int64 feature ids.

``heads(mi)``, ``manifolds(mf)`` and ``points(pf)`` view the rows as numpy structured arrays
whose fields are the C++ records' (``points(pf)["ra"][p]``: point p's anchor on a, shape (3,);
writes go to the same memory).

Frames and signs: the normal points from body b into body a; anchors ``ra``/``rb`` are the world
offsets of the contact point from the centres of mass at the narrowphase; a positive normal
impulse pushes a along +normal and b along -normal; the friction impulse ``friction`` is the
world vector applied to a (b gets its negative). Solver body index ``n_bodies`` is a static dummy
(zero inverse mass, zero velocity) standing for the ground, static boxes and sleeping bodies.

The records' documented home is csrc/engine/manifold.hpp (each field with its shape, frame and
unit); this module builds their dtypes from the compiled core's field table
(``_core.contact_fields()``). The manifold reduction (deepest, farthest, largest triangle,
largest quad; touching points first) is ``reduce_manifold`` in csrc/engine/manifold.cpp.
"""

from __future__ import annotations

import numpy as np

from rblog.engine import _core

_LAYOUT = _core.collision_layout()


def _columns(*names):
    return tuple(int(_LAYOUT[k]) for k in names)


def _dtype(fields, kind):
    """A structured dtype of 8-byte values from (name, offset, width) triples."""
    return np.dtype({"names": [f[0] for f in fields],
                     "formats": [kind if f[2] == 1 else (kind, (f[2],)) for f in fields],
                     "offsets": [8 * f[1] for f in fields],
                     "itemsize": 8 * sum(f[2] for f in fields)})


#: the rows' widths: mi (M, MI_COLS) int64, mf (M, MF_COLS) and pf (K, PF_COLS) float64
MI_COLS, MF_COLS, PF_COLS = _columns("MI_COLS", "MF_COLS", "PF_COLS")
_FIELDS = _core.contact_fields()
#: the records' dtypes: a row of mi, of mf, of pf
HEAD_DTYPE = _dtype(_FIELDS["head"], np.int64)
MANIFOLD_DTYPE = _dtype(_FIELDS["manifold"], np.float64)
POINT_DTYPE = _dtype(_FIELDS["point"], np.float64)


def _records(a: np.ndarray, dtype: np.dtype, cols: int) -> np.ndarray:
    if a.ndim != 2 or a.shape[1] != cols or not a.flags.c_contiguous:
        raise ValueError(f"expected a C-contiguous (rows, {cols}) array, got {a.shape}")
    return a.view(dtype)[:, 0]


def heads(mi: np.ndarray) -> np.ndarray:
    """mi (M, MI_COLS) int64 as (M,) records: key, a, b, rec_a, rec_b, start, count, active."""
    return _records(mi, HEAD_DTYPE, MI_COLS)


def manifolds(mf: np.ndarray) -> np.ndarray:
    """mf (M, MF_COLS) as (M,) records: normal, t1, t2, mu, e, acc, lu, piv, lu_ok, anchor_rot,
    anchor_pos, anchor_ok."""
    return _records(mf, MANIFOLD_DTYPE, MF_COLS)


def points(pf: np.ndarray) -> np.ndarray:
    """pf (K, PF_COLS) as (K,) records: point, ra, rb, s, normal_mass, tangent_k, ln, l1, l2, lp,
    lws, w0, friction, s_end, impact, wt, kn, slip, slip_bias."""
    return _records(pf, POINT_DTYPE, PF_COLS)


#: the contact log's rows (the kernels append a row per point at sampled steps): log_i (K,
#: LOG_I_COLS) int64 and log_f (K, LOG_F_COLS) float64
LOG_I_COLS, LOG_F_COLS = _columns("LOG_I_COLS", "LOG_F_COLS")
LOG_IDS_DTYPE = _dtype(_FIELDS["log_ids"], np.int64)
LOG_VALUES_DTYPE = _dtype(_FIELDS["log_values"], np.float64)


def log_rows(log_i: np.ndarray, log_f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The contact log as (K,) records: ids (step, a, b, kind) and values (point, normal,
    separation, normal_impulse, friction)."""
    return _records(log_i, LOG_IDS_DTYPE, LOG_I_COLS), _records(log_f, LOG_VALUES_DTYPE, LOG_F_COLS)


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
