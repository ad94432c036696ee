"""A body against the ground and a tilted static plane at once (dm_control's manipulator: the ball
in the corner of the floor and wall2, a plane at 45 deg): its logged contact rows off the ground's
normal are a second static feature, so its impulse is not judged against the ground's friction
cone alone (MuJoCo holds the ball's momentum: the truth, benchmarks/truth_table.py); a planted kick
on the ball in that corner is still flagged."""

from __future__ import annotations

import numpy as np
import pytest

import rblog

pytest.importorskip("dm_control")
mujoco = pytest.importorskip("mujoco")


def _manipulator(steps=1000):
    from rblog.adapters import mujoco as adapter

    m = adapter.suite_model("manipulator")
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    rec = adapter.recorder(m, d, every=1)
    for _ in range(steps):
        mujoco.mj_step(m, d)
        rec(d)
    rec.close()
    return rec.trajectory


def test_ball_in_the_corner_is_not_judged_against_the_ground_alone():
    traj = _manipulator()
    ball = traj.model.body_name.index("ball")
    c = traj.contacts
    wall = (c.body_a == ball) & (c.body_b == -1) & (c.normal[:, 2] < 0.9)
    assert wall.any()  # the ball touches wall2 (normal (0.707, 0, 0.707)) in this run
    res = {r.analyzer: r for r in rblog.check(traj, only=["momentum"])}
    assert res["momentum"].passed, [f.message for f in res["momentum"].findings][:3]


def test_a_kick_on_the_ball_in_the_corner_is_flagged():
    traj = _manipulator()
    ball = traj.model.body_name.index("ball")
    c = traj.contacts
    t_wall = c.t[(c.body_a == ball) & (c.body_b == -1) & (c.normal[:, 2] < 0.9)][0]
    k = int(np.searchsorted(traj.t, t_wall)) + 5
    m = traj.model.body_mass[ball]
    traj.velocity[k:, ball, 1] += 1.0  # 1 m/s along y, along both planes: no contact gives it
    traj.linear_momentum[k:, ball, 1] += m * 1.0
    traj.position[k:, ball, 1] += 1.0 * (traj.t[k:] - traj.t[k - 1])
    res = {r.analyzer: r for r in rblog.check(traj, only=["momentum"])}
    assert any(ball in f.bodies for f in res["momentum"].findings), res["momentum"].reason
