"""The C++ collision core (csrc/engine/{manifold,narrowphase,box_box,broad_phase,collide,island,
measure}.cpp) against its Python homes: the packed columns mirrored in manifold.hpp equal
manifold.py's, the geometry codes and the narrowphase table's keys agree, and the tolerances C++
holds are constants.py's. While the numba kernels still exist (contact/_numba_legacy_collision.py,
until the world step runs on C++), every stage is also checked bitwise against them on the
states of a mixed scene (boxes, spheres, ground, a static box) in flight, at impact, at rest and
asleep."""

from __future__ import annotations

import numpy as np
import pytest

from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE
from rblog.contract.trajectory import STATIC_BODY
from rblog.engine import _core, constants
from rblog.engine import integrators as rot
from rblog.engine.contact import ContactParams, ContactWorld
from rblog.engine.contact import manifold, narrowphase
from rblog.study.scenes import make_model, make_state


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


# ---- bitwise against the numba kernels, while they exist ---------------------------------------

def _legacy():
    return pytest.importorskip("rblog.engine.contact._numba_legacy_collision")


def _same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def _mixed_world(seed=3):
    """12 boxes and 6 spheres dropped in a column over the ground beside a static box."""
    rng = np.random.default_rng(seed)
    n_box, n_sph = 12, 6
    shapes = [SHAPE_BOX] * n_box + [SHAPE_SPHERE] * n_sph
    sizes = [rng.uniform(0.03, 0.08, 3) for _ in range(n_box)] + \
        [rng.uniform(0.03, 0.07) for _ in range(n_sph)]
    model = make_model(shapes, sizes, rng.uniform(0.5, 2.0, len(shapes)),
                       restitution=rng.uniform(0.0, 0.5, len(shapes)),
                       friction=rng.uniform(0.2, 0.8, len(shapes)), ground_friction=0.7,
                       static_box_position=np.array([[0.25, 0.0, 0.1]]),
                       static_box_quat_wxyz=np.array([[np.cos(0.2), 0.0, 0.0, np.sin(0.2)]]),
                       static_box_half_extents=np.array([[0.1, 0.3, 0.1]]),
                       static_box_restitution=np.array([0.1]),
                       static_box_friction=np.array([0.6]))
    n = len(shapes)
    pos = np.zeros((n, 3))
    for i in range(n):
        pos[i] = [rng.uniform(-0.1, 0.3), rng.uniform(-0.1, 0.1), 0.12 + 0.17 * i]
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    state = make_state(model, pos, quat_wxyz=q)
    world = ContactWorld(model, ContactParams(), rot.METHOD_SPLITTING, rot.ORTHO_NORMALIZE)
    return world, state


def _advance(world, state, n_steps, dt=1e-3):
    n = world.n_bodies
    out = [np.zeros((1, n, 3)), np.zeros((1, n, 3)), np.zeros((1, n, 4)), np.zeros((1, n, 3, 3)),
           np.zeros((1, n, 3))]
    world.advance(dt, n_steps, n_steps, False, state.position, state.linear_momentum,
                  state.quat_wxyz, state.rotation, state.angular_momentum_world, *out)


def _check_stages(L, world, state, h=1e-3):
    bd, st, cfg = world.records
    sl = world._sleep
    c = world._cache
    n, ns = world.n_bodies, st.n_static
    x, lm, rot_, am = state.position, state.linear_momentum, state.rotation, \
        state.angular_momentum_world
    # broad phase
    lo_n, hi_n, reach_n = (np.zeros((n + ns, 3)), np.zeros((n + ns, 3)), np.zeros(n + ns))
    lo_n[n:], hi_n[n:] = st.lo, st.hi
    lo_c, hi_c, reach_c = lo_n.copy(), hi_n.copy(), reach_n.copy()
    L.body_aabbs(bd.geom, bd.size, bd.radius, bd.inv_mass, bd.inv_inertia, sl.awake, x, lm, rot_,
                 am, h, cfg.margin, lo_n, hi_n, reach_n)
    _core.body_aabbs(bd.geom, bd.size, bd.radius, bd.inv_mass, bd.inv_inertia, sl.awake, x, lm,
                     rot_, am, h, cfg.margin, lo_c, hi_c, reach_c)
    assert _same(lo_n, lo_c) and _same(hi_n, hi_c) and _same(reach_n, reach_c)
    pn, k_n = L.sweep_and_prune(n + ns, n, lo_n, hi_n, bd.group, sl.awake, np.zeros((4, 2), np.int64))
    pc, k_c = _core.sweep_and_prune(n + ns, n, lo_c, hi_c, bd.group, sl.awake,
                                    np.zeros((4, 2), np.int64))
    assert k_n == k_c and _same(pn[:k_n], pc[:k_c])
    pn, k_n = L.ground_pairs(n, ns, st, lo_n, hi_n, pn, k_n)
    pc, k_c = _core.ground_pairs(n, ns, st.gn, st.goff, lo_c, hi_c, pc, k_c)
    assert k_n == k_c and _same(pn[:k_n], pc[:k_c])
    pairs = np.ascontiguousarray(pn[:max(k_n, 1)])
    # collide
    outs = []
    for impl in ("numba", "cpp"):
        mi, mf, pf, pid = manifold.empty_manifolds(2 * k_n + 2, 8 * k_n + 8)
        args = (pairs, k_n, n, ns, bd.geom, bd.size, sl.awake, x, rot_, reach_n, cfg.margin,
                bd.restitution, bd.friction, bd.accel, st.pos, st.rot, st.ext, st.e, st.mu, st.gn,
                st.goff, st.g_e, st.g_mu, c.mi0, c.mf0, c.pf0, c.pid0, c.keys0, c.idx0, c.n_man0,
                mi, mf, pf, pid, cfg.warm, cfg.anchor)
        if impl == "numba":
            res = L.collide_pairs(*args, *L.collider_buffers())
        else:
            res = _core.collide_pairs(*args)
        outs.append((tuple(res), mi, mf, pf, pid))
    (rn, *an), (rc, *ac) = outs
    assert rn == rc
    for a, b in zip(an, ac):
        assert _same(a, b)
    n_man = rn[0]
    mi, mf, pf = an[0], an[1], an[2]
    keys_n, idx_n = np.zeros(max(n_man, 1), np.int64), np.zeros(max(n_man, 1), np.int64)
    keys_c, idx_c = keys_n.copy(), idx_n.copy()
    L.sort_manifolds(mi, n_man, keys_n, idx_n)
    _core.sort_manifolds(mi, n_man, keys_c, idx_c)
    assert _same(keys_n, keys_c) and _same(idx_n, idx_c)
    # islands: wake_touched, wake_pushed (with the collide output standing in for solved
    # manifolds: the loads are the warm starts), update_sleep, on copies of the sleep state
    force, torque = bd.force, bd.torque
    runs = []
    for impl in ("numba", "cpp"):
        s = [a.copy() for a in (sl.awake, sl.timer, sl.island_of, sl.island_counter, lm, am)]
        awake, timer, island_of, counter, lm_, am_ = s
        if impl == "numba":
            w1 = L.wake_touched(pairs, k_n, n, ns, bd.geom, bd.size, awake, timer, island_of, x,
                                rot_, reach_n, cfg.margin, cfg.slop, st.pos, st.rot, st.ext, st.gn,
                                st.goff, lm_, am_, force, torque, h, cfg.do_kick,
                                *L.collider_buffers(), bd.inv_mass, bd.accel, bd.radius,
                                bd.inv_inertia)
        else:
            w1 = _core.wake_touched(pairs, k_n, n, ns, bd.geom, bd.size, awake, timer, island_of,
                                    x, rot_, reach_n, cfg.margin, cfg.slop, st.pos, st.rot, st.ext,
                                    st.gn, st.goff, lm_, am_, force, torque, h, cfg.do_kick,
                                    bd.inv_mass, bd.accel, bd.radius, bd.inv_inertia)
        f = L.wake_pushed if impl == "numba" else _core.wake_pushed
        w2 = f(mi, mf, pf, n_man, n, awake, timer, island_of, x, lm_, am_, force, torque, h)
        scratch = (np.zeros(n, np.int64), np.zeros(n), np.zeros(n, np.int64))
        f = L.update_sleep if impl == "numba" else _core.update_sleep
        w3 = f(n, mi, pf, n_man, awake, timer, island_of, counter, lm_, am_, bd.inv_mass,
               bd.inv_inertia, bd.radius, h, cfg.sleep_speed, cfg.sleep_time, *scratch)
        runs.append(((w1, w2, w3), s + list(scratch)))
    assert runs[0][0] == runs[1][0]
    for a, b in zip(runs[0][1], runs[1][1]):
        assert _same(a, b)
    return k_n, n_man


def test_stages_bitwise_equal_to_numba():
    L = _legacy()
    world, state = _mixed_world()
    seen_pairs = seen_man = 0
    for n_steps in (1, 150, 250, 400, 600, 800, 1200):
        _advance(world, state, n_steps)
        k, m = _check_stages(L, world, state)
        seen_pairs += k
        seen_man += m
    assert seen_pairs > 50 and seen_man > 50
    assert world.n_awake < world.n_bodies  # some checks ran with sleepers


def test_colliders_bitwise_equal_to_numba():
    L = _legacy()
    rng = np.random.default_rng(11)
    geoms = (narrowphase.GEOM_SPHERE, narrowphase.GEOM_BOX, narrowphase.GEOM_PLANE)
    n_hits = 0
    for trial in range(3000):
        ga = int(rng.choice(geoms[:2]))
        gb = int(rng.choice(geoms))
        q = rng.normal(size=(2, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        from rblog.engine.rotation import quat_to_matrix_np
        ra, rb = (np.ascontiguousarray(r) for r in quat_to_matrix_np(q))
        if trial % 3 == 0:  # face-aligned poses: clipping and reduction
            ra, rb = np.eye(3), np.ascontiguousarray(quat_to_matrix_np(
                np.array([np.cos(0.4 * rng.uniform()), 0, 0, np.sin(0.4 * rng.uniform())])))
        sa, sb = rng.uniform(0.05, 0.5, 3), rng.uniform(0.05, 0.5, 3)
        ca = np.zeros(3)
        cb = rng.normal(size=3) * 0.5
        pn = rng.normal(size=3)
        pn /= np.linalg.norm(pn)
        poff = float(rng.uniform(-0.5, 0.5))
        spec = float(rng.choice([0.0, 0.01, 0.2, -0.001]))
        key = (min(ga, gb), max(ga, gb))
        code = int(narrowphase.COLLIDE_TABLE[key])
        nrm, pts, sep, fid, work, poly = L.collider_buffers()
        r_n = L.collide(code, ga > gb, ca, ra, sa, cb, rb, sb, pn, poff, spec, nrm, pts, sep, fid,
                        work, poly)
        r_c, nrm_c, pts_c, sep_c, fid_c = _core.collide_np(ga, gb, ca, ra, sa, cb, rb, sb, pn,
                                                           poff, spec)
        assert r_n == r_c, trial
        if r_n <= 0:
            continue
        n_hits += 1
        rows = [q for q in range(8) if (q < 4 and q < r_n % 8) or (q >= 4 and q - 4 < r_n // 8)]
        assert _same(pts[rows], pts_c[rows]) and _same(sep[rows], sep_c[rows]), trial
        assert _same(fid[rows], fid_c[rows]), trial
        assert _same(nrm[:3], nrm_c[:3]) and (r_n < 8 or _same(nrm[3:], nrm_c[3:])), trial
    assert n_hits > 500
