"""The C++ collision core (csrc/engine/{manifold,narrowphase,box_box,broad_phase,collide,island,
measure}.cpp) against its Python homes: the fields of manifold.hpp's records tile their rows
(manifold.py builds its dtypes from the core's table), the contact log's records too, the
geometry codes and the narrowphase table's keys agree, and the tolerances C++ holds are
constants.py's."""

from __future__ import annotations

import numpy as np
import pytest

from rblog.contract.trajectory import STATIC_BODY
from rblog.engine import _core, constants
from rblog.engine.contact import manifold, narrowphase


def _tiling_error(at_of, widths, cols):
    """'' when the groups of ``widths`` (name: width) at the offsets ``at_of`` (name: offset)
    cover columns 0..cols-1 once each, in order, else what is wrong."""
    at = 0
    for name, w in sorted(widths.items(), key=lambda kv: at_of[kv[0]]):
        if at_of[name] != at:
            return f"{name} at {at_of[name]}, expected {at}"
        at += w
    return "" if at == cols else f"the groups end at {at}, the array has {cols} columns"


def test_record_fields_tile_the_rows():
    """manifold.hpp's records as the core lists them (contact_fields: name, offset, width from
    offsetof and sizeof): each record's fields cover its row exactly once, no gap, no overlap, so
    a field left out of the table is caught; manifold.py's dtypes are those rows."""
    layout, fields = _core.collision_layout(), _core.contact_fields()
    for record, cols, dtype in (("head", "MI_COLS", manifold.HEAD_DTYPE),
                                ("manifold", "MF_COLS", manifold.MANIFOLD_DTYPE),
                                ("point", "PF_COLS", manifold.POINT_DTYPE),
                                ("log_ids", "LOG_I_COLS", manifold.LOG_IDS_DTYPE),
                                ("log_values", "LOG_F_COLS", manifold.LOG_VALUES_DTYPE)):
        at_of = {f[0]: f[1] for f in fields[record]}
        widths = {f[0]: f[2] for f in fields[record]}
        assert _tiling_error(at_of, widths, layout[cols]) == "", record
        assert dtype.itemsize == 8 * layout[cols] and dtype.names == tuple(at_of)
    # both directions: a field left out of the table is caught
    pts = {f[0]: f for f in fields["point"] if f[0] != "tangent_k"}
    assert "ln" in _tiling_error({k: f[1] for k, f in pts.items()},
                                 {k: f[2] for k, f in pts.items()}, layout["PF_COLS"])
    # a row's fields are the array's columns: point p's ra is pf[p, 3:6]
    pf = np.zeros((2, layout["PF_COLS"]))
    manifold.points(pf)["ra"][1] = (1.0, 2.0, 3.0)
    assert pf[1, 3:6].tolist() == [1.0, 2.0, 3.0] and pf.sum() == 6.0


def test_log_rows_read_the_log_by_name():
    """The contact log's rows as manifold.hpp documents them: ids (step, a, b, kind), values
    (point 3, normal 3, separation, normal_impulse, friction 3)."""
    layout = _core.collision_layout()
    assert (layout["LOG_I_COLS"], layout["LOG_F_COLS"]) == (4, 11)
    li = np.arange(8, dtype=np.int64).reshape(2, 4)
    lf = np.arange(22, dtype=np.float64).reshape(2, 11)
    ids, val = manifold.log_rows(li, lf)
    assert ids["kind"].tolist() == [3, 7] and ids["b"].tolist() == [2, 6]
    assert val["normal"][1].tolist() == [14.0, 15.0, 16.0]
    assert val["separation"].tolist() == [6.0, 17.0] and val["friction"][0].tolist() == [8.0, 9.0, 10.0]
    assert manifold._AREA_EPS == layout["_AREA_EPS"]
    assert (manifold.MAX_CLIP_POINTS, manifold.MAX_MANIFOLD_POINTS) == (12, 4)


def test_geometry_codes_and_table_agree():
    layout = _core.collision_layout()
    for name in ("GEOM_SPHERE", "GEOM_BOX", "GEOM_CAPSULE", "GEOM_CYLINDER", "GEOM_PLANE"):
        assert getattr(narrowphase, name) == layout[name], name
    assert {tuple(k) for k in layout["NARROWPHASE_TABLE"]} == set(narrowphase.NARROWPHASE_TABLE)


def test_tolerances_come_from_constants_py():
    c = _core.collision_constants()
    assert c["set"]
    for name in ("MANIFOLD_TOUCH_BAND_M", "EDGE_REL_TOL", "FACE_REL_TOL", "AXIS_ABS_TOL",
                 "EDGE_PARALLEL_TOL", "FRICTION_ANCHOR_MAX_DRIFT_M", "CONVEX_GJK_TOL_M",
                 "CONVEX_EPA_TOL_M", "CONVEX_MAX_ITER"):
        assert c[name] == getattr(constants, name), name
    assert c["STATIC_BODY"] == STATIC_BODY


def test_tangent_basis_right_handed():
    for n in ([0.0, 0.0, 1.0], [0.3, -0.4, 0.866], [-1.0, 0.0, 0.0]):
        n = np.asarray(n) / np.linalg.norm(n)
        t = np.array(_core.tangent_basis(*n))
        t1, t2 = t[:3], t[3:]
        assert abs(t1 @ n) < 1e-15 and abs(t2 @ n) < 1e-15 and abs(t1 @ t1 - 1) < 1e-15
        assert np.allclose(np.cross(t1, t2), n, atol=1e-15)


def test_sweep_and_prune_pairs_groups_and_growth():
    """Four unit boxes in a row 1.5 m apart along x (neighbours overlap by 0.5 m), bodies 2 and 3
    in groups 1 and 2 (they never pair), body 0 lower than the rest; a static box (item 4) over
    body 0 clears it in z but meets body 1; a pairs array of one row grows to fit; then the ground
    reaches body 0 alone (the only AABB bottom at or below z = 0)."""
    from rblog.engine.contact.broadphase import ground_pairs, sweep_and_prune
    x = np.array([0.0, 1.5, 3.0, 4.5, 0.0])
    lo = np.stack([x - 1.0, -np.ones(5), [-1.0, 0.5, 0.5, 0.5, 1.5]], axis=1)
    hi = np.stack([x + 1.0, np.ones(5), [1.0, 2.5, 2.5, 2.5, 3.5]], axis=1)
    group = np.array([0, 0, 1, 2], np.int64)
    pairs, count = sweep_and_prune(5, 4, lo, hi, group, np.ones(4, np.int64),
                                   np.zeros((1, 2), np.int64))
    assert count == 3 and pairs.shape[0] >= 3
    assert sorted(map(tuple, pairs[:count].tolist())) == [(0, 1), (1, 2), (1, 4)]

    class St:
        gn = np.array([0.0, 0.0, 1.0])
        goff = 0.0
    pairs, count = ground_pairs(4, 1, St, lo, hi, pairs, count)
    assert count == 4 and tuple(pairs[3]) == (0, 5)
