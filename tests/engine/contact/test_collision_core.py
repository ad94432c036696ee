"""The C++ collision core (csrc/engine/{manifold,narrowphase,box_box,broad_phase,collide,island,
measure}.cpp) against its Python homes: the packed columns mirrored in manifold.hpp equal
manifold.py's, the geometry codes and the narrowphase table's keys agree, and the tolerances C++
holds are constants.py's. (Before the numba kernels were removed, every stage was checked bitwise
equal to them on a mixed scene in flight, at impact, at rest and asleep, and on 3000 random
collider calls: commit 7ae5b2e.)"""

from __future__ import annotations

import numpy as np
import pytest

from rblog.contract.trajectory import STATIC_BODY
from rblog.engine import _core, constants
from rblog.engine.contact import manifold, narrowphase


def test_columns_agree_with_manifold_py():
    layout = _core.collision_layout()
    names = [k for k in layout if k.isupper() and k != "NARROWPHASE_TABLE"]
    names = [k for k in names if not k.startswith("GEOM_")]
    assert len(names) >= 50
    for name in names:
        assert getattr(manifold, name) == layout[name], name
    assert manifold._AREA_EPS == layout["_AREA_EPS"]
    # and every column constant of manifold.py is mirrored
    py_names = {k for k in vars(manifold) if k.split("_")[0] in ("MI", "MF", "PF", "LOG")
                or k.startswith("MAX_")}
    assert py_names <= set(layout), sorted(py_names - set(layout))


def test_geometry_codes_and_table_agree():
    layout = _core.collision_layout()
    for name in ("GEOM_SPHERE", "GEOM_BOX", "GEOM_PLANE"):
        assert getattr(narrowphase, name) == layout[name], name
    assert {tuple(k) for k in layout["NARROWPHASE_TABLE"]} == set(narrowphase.NARROWPHASE_TABLE)


def test_tolerances_come_from_constants_py():
    c = _core.collision_constants()
    assert c["set"]
    for name in ("MANIFOLD_TOUCH_BAND_M", "EDGE_REL_TOL", "FACE_REL_TOL", "AXIS_ABS_TOL",
                 "EDGE_PARALLEL_TOL", "FRICTION_ANCHOR_MAX_DRIFT_M"):
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
