"""Resting contact of bodies without a v2 shape, judged on their geoms (penetration rule
"geom_pair_support"): supports from the audit's own geom-pair geometry, then the same rest, jitter
and creep rules as for boxes and spheres.

* MuJoCo: a capsule and a cylinder dropped onto a floor (tests/analyze/test_geometry_penetration.py
  builds the log) settle and rest: clean. A creep of 0.3 mm written into the log only (the
  capsule's logged position slid along x by a ramp from t = 0.6 s to the end, velocities left as
  MuJoCo logged them) is flagged on the capsule, on the ground, at the end of its stay, as 0.3 mm.
* Closed form: a capsule (radius r = 0.04 m) on its side rolling without slip, x = r theta,
  omega = theta' about the world y axis: its contact point's slip is 0, so it never creeps; the
  same roll with a slip of 0.3 mm added to x over the run creeps 0.3 mm.
"""

from __future__ import annotations

import numpy as np
import pytest

import rblog
from rblog.analyze import check

pytest.importorskip("mujoco")
from tests.analyze.test_geometry_penetration import mujoco_log  # noqa: E402

CREEP = 3e-4


def _pen(model, arrays):
    rec = rblog.Recorder(model, dt=0.002, writer="mujoco")
    rec.write(**arrays)
    rec.close()
    return next(r for r in check(rec.trajectory, only=["penetration"]))


def test_a_mujoco_capsule_and_cylinder_resting_on_a_floor_are_clean():
    _, model, arrays, _ = mujoco_log()
    res = _pen(model, arrays)
    assert res.judged and res.passed, res.reason
    assert "not judged" not in res.reason
    rests = [e for e in res.events if e["kind"] == "rest"]
    # both bodies rest on the ground (partner -1) by the end of the run (t = 1.2 s)
    for b in (0, 1):
        mine = [e for e in rests if e["body"] == b and e["partner"] == -1]
        assert mine and mine[-1]["t_end"] == pytest.approx(arrays["t"][-1]), (b, rests)
        assert mine[-1]["creep_m"] is not None and mine[-1]["creep_m"] < 1e-5


def test_a_creep_of_03_mm_written_into_the_log_is_flagged_on_the_capsule():
    _, model, arrays, _ = mujoco_log()
    t = arrays["t"]
    k0 = int(np.searchsorted(t, 0.6))
    ramp = np.clip((t - t[k0]) / (t[-1] - t[k0]), 0.0, 1.0) * CREEP
    arrays["position"][:, 0, 0] += ramp
    res = _pen(model, arrays)
    creep = [f for f in res.findings if "creeps" in f.message]
    assert len(creep) == 1 and creep[0].bodies == [0], [f.message for f in res.findings]
    f = creep[0]
    assert "on the ground" in f.message
    assert f.t == pytest.approx(t[-1])
    # the planted 0.3 mm plus what MuJoCo's rest slid (< 1e-5 m, the clean test)
    assert abs(f.value - CREEP) < 1e-5


R, H = 0.04, 0.15  # the capsule's radius and half-length


def _rolling(slip_m=0.0, omega=0.05, seconds=1.0, every=0.01):
    """A capsule on its side (axis along world y) rolling about y without slip at omega (rad/s)
    on the floor z = 0, plus ``slip_m`` slid along x at a steady rate: position (r theta + slip,
    0, r), rotation R_y(theta) R_0 with R_0 the capsule's axis onto y, velocity omega r (+ the
    slip rate) along x, angular velocity (0, omega, 0)."""
    t = np.arange(0.0, seconds + every / 2, every)
    th = omega * t
    c, s = np.cos(th), np.sin(th)
    ry = np.zeros((len(t), 3, 3))
    ry[:, 0, 0], ry[:, 0, 2], ry[:, 1, 1], ry[:, 2, 0], ry[:, 2, 2] = c, s, 1.0, -s, c
    r0 = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # body z (the capsule) -> world y
    rot = ry @ r0
    q = np.empty((len(t), 4))
    from rblog.contract.orientation import matrix_to_quat
    q[:] = matrix_to_quat(rot)
    rate = slip_m / seconds
    pos = np.stack([R * th + rate * t, np.zeros_like(t), np.full_like(t, R)], 1)
    vel = np.stack([np.full_like(t, omega * R + rate), 0 * t, 0 * t], 1)
    w = np.stack([0 * t, np.full_like(t, omega), 0 * t], 1)
    model = rblog.body_table(
        name=["limb"], mass=[1.0], inertia_diag=[[0.01, 0.01, 0.001]],
        geoms=dict(body=[-1, 0], type=["plane", "capsule"], size=[[0, 0, 0], [R, H, 0]],
                   pos_body=[[0, 0, 0]] * 2, quat_wxyz_body=[[1.0, 0, 0, 0]] * 2,
                   name=["floor", "limb"]),
        collide_rule="or", gravity=[0.0, 0.0, -9.81])
    arrays = dict(t=t, step=np.arange(len(t)) * 5, position=pos[:, None], quat_wxyz=q[:, None],
                  velocity=vel[:, None], angular_velocity=w[:, None])
    return model, arrays


def test_a_capsule_rolling_without_slip_does_not_creep():
    # omega 0.05 rad/s: contact speed 0, omega x reach (2 x 0.19 m) 0.019 m/s < the rest speed
    res = _pen(*_rolling())
    assert res.passed, res.reason
    rests = [e for e in res.events if e["kind"] == "rest" and e["body"] == 0]
    assert len(rests) == 1 and rests[0]["partner"] == -1
    # the midpoint rule is exact for a constant roll: slide 0 to round-off (measured 1e-16 m)
    assert rests[0]["creep_m"] < 1e-12


def test_the_same_roll_slipping_03_mm_creeps_03_mm():
    res = _pen(*_rolling(slip_m=CREEP))
    creep = [f for f in res.findings if "creeps" in f.message]
    assert len(creep) == 1 and creep[0].bodies == [0]
    # settled after SETTLE_S = 0.1 s of a steady slip: all of it counts (rule "settling")
    assert creep[0].value == pytest.approx(CREEP, rel=1e-6)


def test_a_capsule_rolling_fast_is_not_resting():
    # omega 2 rad/s: omega x reach 0.76 m/s > the rest speed: rolling, not at rest
    res = _pen(*_rolling(omega=2.0, slip_m=CREEP))
    assert res.passed, res.reason
    assert not [e for e in res.events if e["kind"] == "rest" and e["body"] == 0]
