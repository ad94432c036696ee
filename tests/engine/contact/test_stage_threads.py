"""The contact step's stages on the task pool give the serial loop's bits (issue 29's threads).

Broadphase (AABBs, the sweep), collide (colliders, then the manifolds at prefix-sum rows),
prepare, the velocity solve's colours, integrate, restitution's gap pass and the project
stage's first pass each cut their loop in blocks that the pool's threads claim in whatever
order the timing gives (csrc/common/task_pool.hpp). A block writes only its own rows, so one,
two and four threads must give the same bytes, and the rows must be in the serial order:

* the sweep's pairs are compared with a numpy re-implementation of the serial sweep (the
  definition in broad_phase.cpp: the axis of largest centre spread, boxes by (low end, id), each
  box against the boxes after it until their low end passes its high end);
* a dense, overlapping cloud of boxes dropped on the ground exercises every threaded stage in
  a few steps (deep points for the project stage, impacts for restitution, hundreds of pairs for
  collide), stepped in one process on one, two and four threads: the states and the contact log
  must be the same bytes.
"""

from __future__ import annotations

import numpy as np
import pytest

from rblog.contract.model import SHAPE_BOX
from rblog.engine import _core
from rblog.engine import integrators as rot
from rblog.engine.contact import ContactParams, ContactWorld
from rblog.engine.contact.step import ST_IMPACTS, ST_PAIRS, ST_PROJECTED, ST_SWEEPS
from rblog.study.scenes import make_model, make_state


@pytest.fixture
def threads():
    """Set the core's threads for a test; back to what they were after. The oversubscribed
    machine's fallback is off meanwhile (on a loaded machine it would put the threaded runs on one
    thread; it changes no result, only which thread solves what)."""
    before = _core.threads()
    _core.set_thread_fallback(False)
    yield _core.set_threads
    _core.set_thread_fallback(True)
    _core.set_threads(before)


def _serial_sweep(lo, hi, n_dyn):
    """broad_phase.cpp's sweep_and_prune, its definition in numpy (no groups: all 0)."""
    c = 0.5 * (lo + hi)
    var = [(c[:, a] ** 2).sum() - c[:, a].sum() ** 2 / len(c) for a in range(3)]
    ax = int(np.argmax(var))  # (first of equal spreads, as the C++ strict >)
    o1, o2 = (ax + 1) % 3, (ax + 2) % 3
    order = np.lexsort((np.arange(len(lo)), lo[:, ax]))
    out = []
    for ii, i in enumerate(order):
        for j in order[ii + 1:]:
            if not lo[j, ax] <= hi[i, ax]:
                break
            if i >= n_dyn and j >= n_dyn:
                continue
            if not (lo[j, o1] <= hi[i, o1] and lo[i, o1] <= hi[j, o1]):
                continue
            if not (lo[j, o2] <= hi[i, o2] and lo[i, o2] <= hi[j, o2]):
                continue
            out.append((min(i, j), max(i, j)))
    return np.array(out, np.int64).reshape(-1, 2)


def test_sweep_gives_the_serial_pairs_in_the_serial_order_on_1_2_and_4_threads(threads):
    rng = np.random.default_rng(7)
    n = 1500  # 12 blocks of 128 boxes: the pool really splits the sweep
    centre = rng.uniform(0.0, 1.5, (n, 3))
    half = rng.uniform(0.02, 0.12, (n, 3))
    lo, hi = centre - half, centre + half
    want = _serial_sweep(lo, hi, n)
    assert len(want) > 2 * n  # a dense cloud: boxes overlap several neighbours (4.3 n measured)
    group, awake = np.zeros(n, np.int64), np.ones(n, np.int64)
    for t in (1, 2, 4):
        threads(t)
        pairs, count = _core.sweep_and_prune(n, n, lo, hi, group, awake, np.zeros((8, 2), np.int64))
        np.testing.assert_array_equal(pairs[:count], want, err_msg=f"{t} threads")


def test_aabbs_are_each_bodys_swept_box_on_1_2_and_4_threads(threads):
    """broad_phase.cpp's body_aabbs for 1,500 tumbling boxes (6 blocks of 256): each body's
    world box (|R| e), grown by the half margin, swept by h v, and for rotation by
    rho = min(h |L| max(1/I) r, r) capped at the bounding sphere r; the same bytes on 1, 2 and
    4 threads."""
    rng = np.random.default_rng(5)
    n, h, margin = 1500, 1e-3, 0.004
    e = rng.uniform(0.02, 0.1, (n, 3))
    radius = np.linalg.norm(e, axis=1)
    q = rng.normal(size=(n, 4))
    state = make_state(make_model([SHAPE_BOX] * n, e, [1.0] * n), rng.uniform(-1, 1, (n, 3)),
                       velocity=rng.normal(0.0, 2.0, (n, 3)), quat_wxyz=q,
                       omega=rng.normal(0.0, 20.0, (n, 3)))
    inv_inertia = rng.uniform(5.0, 50.0, (n, 3))
    awake = (rng.uniform(size=n) < 0.8).astype(np.int64)
    args = (np.full(n, SHAPE_BOX, np.int64), e, radius, np.ones(n), inv_inertia, awake,
            state.position, state.linear_momentum, state.rotation, state.angular_momentum_world,
            h, margin)
    got = {}
    for t in (1, 2, 4):
        threads(t)
        lo, hi, reach = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n)
        _core.body_aabbs(*args, lo, hi, reach)
        got[t] = (lo, hi, reach)
    # the definition, in numpy
    ext = np.abs(state.rotation) @ e[:, :, None]
    ext = ext[:, :, 0]
    d = h * state.linear_momentum
    wmax = np.linalg.norm(state.angular_momentum_world, axis=1) * inv_inertia.max(axis=1)
    rho = np.minimum(h * wmax * radius, radius)
    a = awake[:, None] != 0
    ext = np.where(a, np.minimum(ext + rho[:, None], radius[:, None]), ext)
    d = np.where(a, d, 0.0)
    lo, hi, _ = got[1]
    # (the sums in another order: measured 2.2e-16, one ulp of the positions' ~1 m)
    np.testing.assert_allclose(lo, state.position - ext - margin / 2 + np.minimum(d, 0), rtol=0,
                               atol=1e-15)
    np.testing.assert_allclose(hi, state.position + ext + margin / 2 + np.maximum(d, 0), rtol=0,
                               atol=1e-15)
    for t in (2, 4):
        for x, y in zip(got[1], got[t]):
            assert x.tobytes() == y.tobytes(), t


def _dense_cloud(n=400, seed=3):
    """n boxes of 0.1 m in a 1.2 x 1.2 x 0.6 m block above the ground at random orientations
    and velocities, many of them overlapping at the start (deep points: the project stage)."""
    rng = np.random.default_rng(seed)
    model = make_model([SHAPE_BOX] * n, [[0.05, 0.05, 0.05]] * n, [1.0] * n, restitution=0.5,
                       friction=0.5, ground_restitution=0.5)
    pos = rng.uniform([-0.6, -0.6, 0.05], [0.6, 0.6, 0.65], (n, 3))
    vel = rng.normal(0.0, 1.0, (n, 3))
    return model, make_state(model, pos, velocity=vel, quat_wxyz=rng.normal(size=(n, 4)),
                             omega=rng.normal(0.0, 3.0, (n, 3)))


def _step(model, state, steps):
    world = ContactWorld(model, ContactParams(), rot.METHOD_SPLITTING, rot.ORTHO_NORMALIZE)
    s = state.copy()
    n = model.n_bodies
    outs = [np.zeros((1, n, 3)), np.zeros((1, n, 3)), np.zeros((1, n, 4)), np.zeros((1, n, 3, 3)),
            np.zeros((1, n, 3))]
    logs = []
    for _ in range(steps // 5):
        _, bad, _, contacts = world.advance(1e-3, 5, 5, False, s.position, s.linear_momentum,
                                            s.quat_wxyz, s.rotation, s.angular_momentum_world,
                                            *outs)
        assert bad < 0
        logs.append(contacts)
    return s, world.stats.copy(), logs


def test_dense_cloud_steps_to_the_same_bytes_on_1_2_and_4_threads(threads):
    model, state = _dense_cloud()
    threads(1)
    one, stats, logs = _step(model, state, 30)
    # the scene does reach every threaded stage (else the comparison below would be idle)
    assert stats[ST_PAIRS] / stats[0] > 300  # collide: blocks of 64 pairs
    assert stats[ST_IMPACTS] > 0 and stats[ST_PROJECTED] > 0  # restitution, project
    assert stats[ST_SWEEPS] > 0
    for t in (2, 4):
        threads(t)
        _core.thread_stats(reset=True)
        other, stats_t, logs_t = _step(model, state, 30)
        # the threads did take part: solves split in stages, the stages' loops on the pool
        used = _core.thread_stats(reset=True)
        assert used["threaded_solves"] > 0 and used["shared_stages"] > 0, used
        assert used["pool_calls"] >= 30 * 6, used  # collide (2), prepare, relax, integrate ...
        for k in ("position", "linear_momentum", "quat_wxyz", "rotation",
                  "angular_momentum_world"):
            assert getattr(one, k).tobytes() == getattr(other, k).tobytes(), (t, k)
        np.testing.assert_array_equal(stats, stats_t)
        for a, b in zip(logs, logs_t):
            for k in ("step", "body_a", "body_b", "point", "normal", "separation",
                      "normal_impulse", "friction_impulse", "kind"):
                assert getattr(a, k).tobytes() == getattr(b, k).tobytes(), (t, k)


def test_pool_resized_between_chunks_keeps_the_bytes(threads):
    """A resize keeps the pool's threads (task_pool.hpp: a smaller size parks the workers past
    it, a larger one wakes them): the dense cloud stepped in chunks of 5 steps with the pool at
    4, 2, 1, 3, 2, 4 threads gives the one-thread run's bytes, and the woken workers take part
    (a parked worker that claimed a block would index per-worker scratch past threads())."""
    model, state = _dense_cloud()
    threads(1)
    one, stats, logs = _step(model, state, 30)
    world = ContactWorld(model, ContactParams(), rot.METHOD_SPLITTING, rot.ORTHO_NORMALIZE)
    s = state.copy()
    n = model.n_bodies
    outs = [np.zeros((1, n, 3)), np.zeros((1, n, 3)), np.zeros((1, n, 4)), np.zeros((1, n, 3, 3)),
            np.zeros((1, n, 3))]
    _core.thread_stats(reset=True)
    for k, t in enumerate((4, 2, 1, 3, 2, 4)):
        threads(t)
        _, bad, _, contacts = world.advance(1e-3, 5, 5, False, s.position, s.linear_momentum,
                                            s.quat_wxyz, s.rotation, s.angular_momentum_world,
                                            *outs)
        assert bad < 0
        assert contacts.normal_impulse.tobytes() == logs[k].normal_impulse.tobytes(), (k, t)
    assert _core.thread_stats(reset=True)["pool_worker_blocks"] > 0
    for k in ("position", "linear_momentum", "quat_wxyz", "rotation", "angular_momentum_world"):
        assert getattr(one, k).tobytes() == getattr(s, k).tobytes(), k
    np.testing.assert_array_equal(stats, world.stats)
