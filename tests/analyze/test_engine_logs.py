"""`rblog check` on logs of MuJoCo and pybullet runs of rblog's sample scenes, in both directions.

Clean: MuJoCo runs whose behaviour is within the defaults (soft contacts resolved over ~30 steps,
e within 2% of the configured one, an elastic pair keeping its kinetic energy to 0.01%) pass every
analyzer; each impact is one event (not one per step) with its effective restitution.
Faulty: real faults of pybullet runs (a lost restitution at the second bounce, 0.64% of the
kinetic energy lost in an elastic impact, 0.2 mm of creep) and faults planted in MuJoCo logs
(creep, an energy loss in an elastic impact, a mistuned restitution, friction outside the cone)
are flagged with a one-line message naming the body, the time, the value and the limit.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from rblog.analyze import check

from engine_logs import engine_samples, to_trajectory

pytest.importorskip("mujoco")
pytest.importorskip("pybullet")

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
#: MuJoCo impact scenes at dt = 1e-4 (contact spring omega = 1000 rad/s: penetration |v| / omega
#: ~ 4 mm, below the 5 mm transient limit), logged every 1 ms
MJ_IMPACT = dict(dt=1e-4, log_every=10)


def by_name(results):
    return {r.analyzer: r for r in results}


def failing(results):
    return {r.analyzer: r.reason for r in results if not r.passed and not r.skipped}


def one_line_with_numbers(f, body_name):
    """A finding's message: one line that names the body, a time in s, and its limit."""
    assert "\n" not in f.message
    assert body_name in f.message, f.message
    assert re.search(r"t = [0-9.]+", f.message), f.message
    assert "limit" in f.message or "tol" in f.message, f.message


@pytest.fixture(scope="module")
def mj_ball():
    return engine_samples("mujoco", str(SAMPLES / "bouncing_ball.toml"), **MJ_IMPACT)


@pytest.fixture(scope="module")
def mj_pair():
    return engine_samples("mujoco", str(SAMPLES / "newton_pair.toml"), **MJ_IMPACT)


@pytest.fixture(scope="module")
def mj_box():
    return engine_samples("mujoco", str(SAMPLES / "resting_box.toml"), duration=4.0,
                          log_every=1)


# ------------------------------------------------------------------------------ clean: no alarms
def test_mujoco_bouncing_ball_is_clean_and_each_bounce_is_one_event(mj_ball):
    res = check(to_trajectory(mj_ball))
    assert not failing(res), failing(res)
    ev = [e for e in by_name(res)["momentum"].events if e["approach_speed_mps"] > 1.0]
    # theory: impacts at speeds sqrt(2 g) e^n = 4.43, 3.54, 2.83, 2.27, 1.81, 1.45, 1.16 m/s
    # (> 1 m/s), at t = 0.452 + sum of flights 2 e^n sqrt(2 g) / g = 0.452, 1.174, ... 3.117 s:
    # all 7 within the 4 s run
    speeds = np.sqrt(2 * 9.81) * 0.8 ** np.arange(7)
    assert len(ev) == 7, [(e["t"], e["approach_speed_mps"]) for e in ev]
    # the speeds follow e^n to within what a soft contact's own e (measured 0.804..0.809) allows
    got = np.array([e["approach_speed_mps"] for e in ev])
    assert got == pytest.approx(speeds, rel=0.06)
    for e in ev:
        # one event per bounce, spread over many steps, with a positive restitution near 0.8
        assert e["restitution_effective"] == pytest.approx(0.8, abs=0.02)
        assert 1e-3 < e["duration_s"] < 1e-2  # pi / (omega sqrt(1 - z^2)) = 3.1 ms
        assert 0 < e["peak_penetration_m"] < 5e-3
        # impulse m (v+ - v-) + m g D ~ m (1 + e) v-
        assert e["impulse_ns"] == pytest.approx(1.8 * e["approach_speed_mps"], rel=0.05)


def test_mujoco_elastic_pair_and_resting_box_are_clean(mj_pair, mj_box):
    for s in (mj_pair, mj_box):
        res = check(to_trajectory(s))
        assert not failing(res), failing(res)
    ev = by_name(check(to_trajectory(mj_pair)))["momentum"].events
    assert len(ev) == 1 and ev[0]["restitution_effective"] == pytest.approx(1.0, abs=2e-3)


# ------------------------------------------------------------------------------ faults flagged
def test_pybullet_real_faults_are_flagged():
    """pybullet: its second bounce keeps e = 0.21 of a configured 0.8; its head-on elastic pair
    (e = 0.9967) loses 1 - e^2 of the relative kinetic energy, 0.64% of the total; its resting cube
    slips 0.2 mm in 5 s."""
    ball = check(to_trajectory(engine_samples("pybullet", str(SAMPLES / "bouncing_ball.toml"))))
    f = [x for x in by_name(ball)["momentum"].findings if "restitution" in x.message]
    assert f and f[0].value > 0.5, f  # |0.21 - 0.8|
    one_line_with_numbers(f[0], "ball")

    pair = check(to_trajectory(engine_samples("pybullet", str(SAMPLES / "newton_pair.toml"))))
    f = [x for x in by_name(pair)["momentum"].findings if "elastic impact" in x.message]
    # theory: KE loss = (1 - e^2) mu v_rel^2 / 2 / KE = (1 - 0.9967^2) 3.375 / 3.5 = 0.0064
    assert len(f) == 1 and f[0].value == pytest.approx(0.0064, rel=0.05), f
    one_line_with_numbers(f[0], "light")

    box = check(to_trajectory(engine_samples("pybullet", str(SAMPLES / "resting_box.toml")),
                ), only=["penetration"])
    f = [x for x in box[0].findings if "creeps" in x.message]
    assert f and 1e-4 < f[0].value < 1e-3, f
    one_line_with_numbers(f[0], "cube")


def test_planted_creep_of_a_fraction_of_a_millimetre_is_flagged(mj_box):
    """0.4 mm of slow slide over 3 s (0.13 mm/s, far below any speed a viewer shows)."""
    s = mj_box
    pos = s.position.copy()
    ramp = np.clip(s.t - 1.0, 0, None) * (0.4e-3 / 3.0)
    pos[:, 0, 0] += ramp
    vel = s.velocity.copy()
    vel[:, 0, 0] += np.where(s.t > 1.0, 0.4e-3 / 3.0, 0.0)
    from dataclasses import replace

    res = check(to_trajectory(replace(s, position=pos, velocity=vel)), only=["penetration"])
    f = [x for x in res[0].findings if "creeps" in x.message]
    assert f, res[0].reason
    assert f[0].value == pytest.approx(0.4e-3, rel=0.1)  # planted slide (+ MuJoCo's own ~1e-6 m)
    one_line_with_numbers(f[0], "cube")


def test_planted_one_percent_energy_loss_in_an_elastic_impact_is_flagged(mj_pair):
    """After the impact, the relative velocity is scaled by sqrt(0.99) about the centre of mass:
    momentum is kept, the relative kinetic energy loses 1% (0.96% of the total)."""
    from dataclasses import replace

    s = mj_pair
    m = np.array([1.0, 3.0])
    after = s.t >= 0.6035
    vc = (m[None, :, None] * s.velocity).sum(axis=1) / m.sum()
    vel = s.velocity.copy()
    vel[after] = vc[after, None] + np.sqrt(0.99) * (vel[after] - vc[after, None])
    pos = s.position.copy()
    dtv = np.diff(s.t)[:, None, None]
    for k in np.nonzero(after)[0]:
        pos[k] = pos[k - 1] + vel[k] * dtv[k - 1]
    res = check(to_trajectory(replace(s, position=pos, velocity=vel)))
    f = [x for x in by_name(res)["momentum"].findings if "elastic impact" in x.message]
    # theory: 0.01 x 3.375 / 3.5 = 0.0096 (+ MuJoCo's own -0.01%)
    assert len(f) == 1 and f[0].value == pytest.approx(0.0096, abs=5e-4), f
    one_line_with_numbers(f[0], "light")


def test_mistuned_restitution_is_flagged():
    """MuJoCo given e = 0.8 x 0.95 = 0.76 while the log says 0.8: off by 0.04 > 2% of e."""
    s = engine_samples("mujoco", str(SAMPLES / "bouncing_ball.toml"), duration=1.5,
                       restitution_scale=0.95, **MJ_IMPACT)
    res = by_name(check(to_trajectory(s)))["momentum"]
    f = [x for x in res.findings if "restitution" in x.message]
    assert f and f[0].value == pytest.approx(0.04, abs=0.01), res.reason
    one_line_with_numbers(f[0], "ball")


def test_friction_cone_has_an_absolute_floor(mj_box):
    """A logged friction impulse outside the cone by 1e-8 N s (sub-micro) is no finding; by
    1e-3 N s it is."""
    from dataclasses import replace

    s = mj_box
    for extra, flagged in ((1e-8, False), (1e-3, True)):
        c = s.contacts
        fr = c.friction_impulse.copy()
        k = len(c) // 2
        # mu = 0.5: put the tangential impulse at mu J_n + extra
        t_dir = np.cross(c.normal[k], [1.0, 0.0, 0.0])
        t_dir /= np.linalg.norm(t_dir)
        fr[k] = (0.5 * c.normal_impulse[k] + extra) * t_dir
        res = check(to_trajectory(replace(s, contacts=replace(c, friction_impulse=fr))),
                    only=["momentum"])[0]
        hits = [x for x in res.findings if "friction cone" in x.message]
        assert bool(hits) == flagged, (extra, res.reason)


def test_planted_lost_bounce_is_flagged(mj_ball):
    """The ball stops dead at its first impact (4.43 m/s, e = 0.8: it should leave at 3.54 m/s):
    from the sample after touch-down it rests on the ground (centre at its radius, v = 0)."""
    from dataclasses import replace

    s = mj_ball
    z = s.position[:, 0, 2]
    k_touch = int(np.argmax(z <= 0.1))  # first sample in contact (radius 0.1 m)
    pos, vel = s.position.copy(), s.velocity.copy()
    pos[k_touch:, 0, 2] = 0.1
    pos[k_touch:, 0, :2] = pos[k_touch, 0, :2]
    vel[k_touch:] = 0.0
    res = by_name(check(to_trajectory(replace(s, position=pos, velocity=vel))))["momentum"]
    f = [x for x in res.findings if "bounce lost" in x.message]
    assert len(f) == 1, res.reason
    # e v_n = 0.8 x sqrt(2 g h) = 3.54 m/s expected rebound
    assert f[0].value == pytest.approx(0.8 * np.sqrt(2 * 9.81 * 1.0), rel=0.02)
    one_line_with_numbers(f[0], "ball")
