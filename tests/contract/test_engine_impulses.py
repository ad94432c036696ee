"""rblog's own engine writes contract v3: its geoms and the per-interval contact impulses.

Over each interval between two samples, every body's momentum change is what its contacts gave
it plus gravity and its constant applied load over the interval's steps:

    P[i] - P[i-1] = impulse_contact_linear[i] + impulse_applied_linear[i] + m g (t[i] - t[i-1])
    L[i] - L[i-1] = impulse_contact_angular[i] + impulse_applied_angular[i]

(csrc/engine/impulses.cpp). Independently of that bookkeeping, at every step (log_every 1) the
contact impulse a body received is the sum over its contact rows of that step (the solver's own
impulses: normal_impulse n + friction_impulse on body_a, the negative on body_b)."""

from __future__ import annotations

import numpy as np
import pytest

import rblog
from rblog.contract.model import GEOM_BOX, GEOM_PLANE, GEOM_SPHERE, SUPPLIED_LOGGED, SUPPLIED_NONE
from rblog.engine.scene import parse_scene

# a small pile: 27 boxes and spheres dropped onto the ground and each other, one pushed by a
# constant force and torque; sleep on (the bodies come to rest and sleep within the run)
PILE = """
[sim]
dt = 1e-3
duration = 1.2
seed = 4

[ground]
restitution = 0.2
friction = 0.6

[[static_box]]
position = [0.6, 0.0, 0.2]
half_extents = [0.05, 0.6, 0.2]

[[generator]]
layout = "grid"
grid = [3, 3, 2]
spacing = [0.18, 0.18, 0.25]
origin = [-0.18, -0.18, 0.2]
random_orientation = true
speed = [0.0, 0.3]
spin = [0.0, 2.0]
name_prefix = "box"
[generator.body]
shape = "box"
half_extents = [0.05, 0.05, 0.05]
mass = 0.1
restitution = 0.2
friction = 0.6

[[generator]]
layout = "grid"
grid = [3, 3, 1]
spacing = [0.18, 0.18, 0.2]
origin = [-0.18, -0.18, 0.75]
name_prefix = "ball"
[generator.body]
shape = "sphere"
radius = 0.05
mass = 0.2
restitution = 0.3
friction = 0.5

[[body]]
name = "pushed"
shape = "box"
half_extents = [0.05, 0.05, 0.05]
mass = 0.3
position = [0.3, 0.0, 0.06]
force = [0.4, 0.0, 0.0]
torque = [0.0, 0.0, 0.002]
"""


def _run(log_every: int, solver: str = "pgs", **kw):
    scene = parse_scene(PILE + f'\n[contact]\nsolver = "{solver}"\n', path="pile27.toml")
    traj, summary = rblog.simulate(scene, log_every=log_every, **kw)
    assert summary.status == "ok"
    return traj


def _balance(traj):
    """Per interval and body: the relative residuals of the linear and angular balances: the
    residual over the largest term of the balance; for the angular one, also over r |J_contact|
    (r the body's bounding radius): the contacts' moment about the centre of mass is at most that
    in every step, and steps' moments that cancel over an interval (a resting box rocking) leave
    a rounding of their own size, not of their small sum."""
    m = traj.model
    dt_i = np.diff(traj.t)[:, None, None]
    dp = np.diff(traj.linear_momentum, axis=0)
    dl = np.diff(traj.angular_momentum, axis=0)
    jc, kc = (a[1:] for a in traj.impulse("contact"))
    ja, ka = (a[1:] for a in traj.impulse("applied"))
    grav = m.body_mass[None, :, None] * m.gravity[None, None, :] * dt_i
    res_p = np.abs(dp - (jc + ja + grav)).max(axis=2)
    scale_p = np.maximum.reduce([np.abs(x).max(axis=2) for x in (dp, jc, ja, grav)])
    res_l = np.abs(dl - (kc + ka)).max(axis=2)
    arm = m.body_bounding_radius[None, :] * np.abs(jc).max(axis=2)
    scale_l = np.maximum.reduce([np.abs(x).max(axis=2) for x in (dl, kc, ka)] + [arm])
    return res_p / scale_p, res_l / np.where(scale_l > 0, scale_l, 1.0)


@pytest.mark.parametrize("solver", ["pgs", "soft_step"])
def test_contact_impulses_close_the_momentum_balance(solver):
    traj = _run(10, solver)  # 1.2 s
    m = traj.model
    assert m.body_impulse_supplied[0].tolist() == [SUPPLIED_LOGGED, SUPPLIED_LOGGED, SUPPLIED_NONE,
                                                   SUPPLIED_NONE, SUPPLIED_NONE, SUPPLIED_NONE]
    rel_p, rel_l = _balance(traj)
    # measured (120 intervals x 28 bodies; pgs / soft_step): linear <= 2.2e-14 / 2.2e-14,
    # angular <= 2.9e-15 / 2.9e-15 of the balance's largest term: the rounding of ten steps' sums
    assert rel_p.max() <= 1e-12, rel_p.max()
    assert rel_l.max() <= 1e-12, rel_l.max()
    # ... sleeping bodies included (pgs: 304 intervals of 9 bodies asleep, P unchanged: their
    # contact impulse is the support -m g dt)
    asleep = np.all(np.diff(traj.linear_momentum, axis=0) == 0, axis=2)
    assert solver != "pgs" or asleep.sum() >= 100, asleep.sum()
    # the balance is not empty: at the end the contacts carry most of the pile, whose net contact
    # impulse is then its weight over the interval, m |g| 10 ms
    jc = traj.impulse_contact_linear
    resting = np.abs(jc[-1, :, 2] + m.body_mass * m.gravity[2] * 0.01) <= 0.01 * m.body_mass * 9.81 * 0.01
    assert resting.sum() >= 20, resting.sum()


def test_contact_impulses_equal_the_contact_rows_at_every_step():
    traj = _run(1, duration=0.6)
    c = traj.contacts
    n = traj.n_bodies
    imp = c.normal_impulse[:, None] * c.normal + c.friction_impulse
    rows = np.zeros((traj.n_samples, n, 3))
    s_idx = np.searchsorted(traj.step, c.step)
    np.add.at(rows, (s_idx, c.body_a), imp)
    dyn_b = c.body_b >= 0
    np.add.at(rows, (s_idx[dyn_b], c.body_b[dyn_b]), -imp[dyn_b])
    jc = traj.impulse_contact_linear
    # bodies awake in the step: their momentum changed (a sleeping body's support is -m g dt by
    # the impulses' rule, its rows carry the impulses stored when it fell asleep)
    moving = np.zeros_like(jc[..., 0], bool)
    moving[1:] = np.any(np.diff(traj.linear_momentum, axis=0) != 0, axis=2)
    err = np.abs(jc - rows).max(axis=2)[moving]
    scale = np.abs(jc).max()
    # measured: 2.8e-16 N s, 4.2e-16 of the largest step impulse (16,800 body-steps, all awake)
    assert moving.sum() > 1000 and err.max() <= 1e-12 * scale, (err.max(), scale)


def test_engine_logs_its_geoms_and_impulses_round_trip(tmp_path):
    scene = parse_scene(PILE, path="pile27.toml")
    path = tmp_path / "pile.mcap"
    from rblog.record import McapRecorder

    rblog.run(scene, recorders=[McapRecorder(str(path))], log_every=10, duration=0.2)
    traj = rblog.load(path)
    m = traj.model
    assert traj.info.log_format == 3
    # geoms: each body's box or sphere at its centre, the ground plane, the static box
    assert m.geom_type.tolist() == [GEOM_BOX] * 19 + [GEOM_SPHERE] * 9 + [GEOM_PLANE, GEOM_BOX]
    assert m.geom_body.tolist() == list(range(28)) + [-1, -1]
    assert np.array_equal(m.geom_size[:19], np.tile([0.05, 0.05, 0.05], (19, 1)))
    assert np.array_equal(m.geom_size[19:28], np.tile([0.05, 0.0, 0.0], (9, 1)))
    assert np.array_equal(m.geom_pos_body[-1], [0.6, 0.0, 0.2])
    assert set(traj.interval_channels) == {"impulse_contact_linear", "impulse_contact_angular",
                                           "impulse_applied_linear", "impulse_applied_angular"}
    # the pushed body's applied impulse: F x 10 steps x 1 ms per interval
    assert np.allclose(traj.impulse_applied_linear[1:, 0], [0.4 * 0.01, 0, 0], rtol=1e-15, atol=0)
    assert np.allclose(traj.impulse_applied_angular[1:, 0], [0, 0, 0.002 * 0.01], rtol=1e-15, atol=0)
    assert (traj.impulse_applied_linear[:, 1:] == 0).all() and (traj.impulse_applied_linear[0] == 0).all()
    rel_p, rel_l = _balance(traj)
    assert rel_p.max() <= 1e-12 and rel_l.max() <= 1e-12


@pytest.mark.parametrize("sample, duration", [
    ("box_stack", None),
    pytest.param("pile", 1.0, marks=pytest.mark.slow),  # 500 boxes: ~4 s of CPU
])
def test_sample_logs_close_the_balance(sample, duration):
    from pathlib import Path

    from rblog.engine.scene import load_scene

    scene = load_scene(Path(__file__).resolve().parents[2] / "samples" / f"{sample}.toml")
    traj, _ = rblog.simulate(scene, log_every=10, duration=duration)
    rel_p, rel_l = _balance(traj)
    # measured: box_stack 1.4e-14 / 1.7e-31, pile (1 s) 2.0e-14 / 6.7e-16 (linear / angular)
    assert rel_p.max() <= 1e-12 and rel_l.max() <= 1e-12, (rel_p.max(), rel_l.max())
