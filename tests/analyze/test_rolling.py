"""Rolling and sliding are reported as what they are, with their slip (penetration rule
"rolling_sliding"); resting is judged only where the pair is at rest relative to each other.

* Closed form: a box sliding on a level floor under Coulomb friction, v(t) = v0 - mu g t, is one
  sliding stretch while v > REST_SPEED, with slip v0 at its first sample, v(t_end) at its last,
  a deceleration mu g and a slide v0 T - mu g T^2 / 2 (trapezoid sums are exact for a linear v).
* MuJoCo: a ball rolling without slip at 1.09 m/s is one rolling stretch whose slip equals
  MuJoCo's own at its contact.pos (v + w x (contact.pos - x) from qvel: 1e-5 m/s mean, 1.7e-6
  m/s after 0.1 s); the same log with a steady 0.71 mm/s slip planted reads rolling with slip
  0.71 mm/s, no creep. A ball launched without spin slides, slip v0 - 7/2 mu g t, then rolls at
  5/7 v0 (a solid sphere: dv = -mu g dt, r dw = 5/2 mu g dt).
* The other direction: a box at rest in MuJoCo with a 0.3 mm creep planted is still flagged.
* A body with no contract shape and no geoms, near the ground in a log without contact rows, is
  not taken to touch the ground by its centre: a sideways kick is not judged against the
  ground's friction cone (the same log with a sphere's shape is), and the momentum result says
  its contacts are not judged.
"""

from __future__ import annotations

import numpy as np
import pytest

import rblog
from rblog.analyze import check
from rblog.analyze import tolerances as T
from tests.analyze.test_analyze import GM, results, sliding_box


def _motion(res, kind):
    return [e for e in res.events if e["kind"] == kind]


def test_a_box_sliding_to_a_stop_slides_with_the_closed_form_slip():
    v0, mu = 1.0, 0.5
    traj, ts = sliding_box(v0=v0, mu=mu)
    pen = results(traj)["penetration"]
    assert pen.passed, pen.reason
    (ev,) = _motion(pen, "sliding")
    a = mu * GM
    # the last sample faster than REST_SPEED: v0 - a t > 0.05 m/s
    t_end = np.floor((v0 - T.PENETRATION_REST_SPEED_MPS) / a / 0.01) * 0.01
    assert ev["partner"] == -1 and ev["t_start"] == 0.0
    assert ev["t_end"] == pytest.approx(t_end, abs=1e-12)
    assert ev["slip_start_mps"] == pytest.approx(v0, abs=1e-12)
    assert ev["slip_end_mps"] == pytest.approx(v0 - a * t_end, abs=1e-12)
    assert ev["slip_decel_mps2"] == pytest.approx(a, rel=1e-9)
    assert ev["slid_m"] == pytest.approx(v0 * t_end - 0.5 * a * t_end ** 2, rel=1e-9)
    assert not _motion(pen, "rolling")
    # it then rests: resting is judged after the slide, not during it
    (rest,) = _motion(pen, "rest")
    assert rest["t_start"] > t_end


mujoco = pytest.importorskip("mujoco")
from rblog.adapters.mujoco import MujocoRecorder  # noqa: E402

R = 0.1  # the ball's radius (m)


def _ball_xml(mu=0.5, timestep=0.002, cone="pyramidal"):
    return (f'<mujoco><option timestep="{timestep}" cone="{cone}"/><worldbody>'
            f'<geom name="floor" type="plane" size="50 50 0.1" friction="{mu}"/>'
            f'<body name="ball" pos="0 0 {R}"><freejoint/>'
            f'<geom type="sphere" size="{R}" friction="{mu}"/></body></worldbody></mujoco>')


def _contact_slip(m, d) -> float:
    """MuJoCo's own tangential slip at its contact point (m/s): v + w x (contact.pos - x), w
    in the world frame (qvel[3:6] is in the body frame), less its normal part."""
    mujoco.mj_forward(m, d)
    if not d.ncon:
        return np.nan
    c = d.contact[0]
    w = d.xmat[1].reshape(3, 3) @ d.qvel[3:6]
    u = d.qvel[:3] + np.cross(w, c.pos - d.xpos[1])
    n = c.frame[:3]
    return float(np.linalg.norm(u - (u @ n) * n))


def _rolling_ball(v=1.09, seconds=2.0, every=5):
    """A MuJoCo ball started rolling without slip (v, w = v / r) on a floor; the log and MuJoCo's
    own slip at each logged step."""
    m = mujoco.MjModel.from_xml_string(_ball_xml())
    d = mujoco.MjData(m)
    d.qvel[0], d.qvel[4] = v, v / R
    rec = MujocoRecorder(m, d, every=every)
    own = [_contact_slip(m, d)]
    for s in range(1, int(round(seconds / m.opt.timestep)) + 1):
        mujoco.mj_step(m, d)
        rec(d)
        if s % every == 0:
            own.append(_contact_slip(m, d))
    rec.close()
    return rec.trajectory, np.array(own)


def _pen(traj):
    return next(r for r in check(traj, only=["penetration"]))


def test_a_mujoco_ball_rolling_without_slip_reads_rolling_with_mujocos_own_slip():
    traj, own = _rolling_ball()
    res = _pen(traj)
    assert res.passed, res.reason
    assert not _motion(res, "rest")  # rolling is not resting: no creep, no resting depth
    (ev,) = _motion(res, "rolling")
    assert ev["partner"] == -1 and ev["t_start"] == 0.0 and ev["t_end"] == pytest.approx(2.0)
    # MuJoCo's own slip at contact.pos, from qvel: mean 1.0e-5 m/s, max 5.8e-4 m/s (the first
    # steps, the ball sinking into the soft floor), 1.7e-6 m/s after 0.1 s
    ok = np.isfinite(own)
    assert ok.all() and own[ok].max() < 1e-3 and own[20:].max() < 1e-5
    # the audit's witness is midway between the surfaces, as MuJoCo's contact.pos: its slip is
    # MuJoCo's (trapezoid mean over the samples)
    t = traj.t
    own_mean = np.trapezoid(own, t) / (t[-1] - t[0])
    assert ev["slip_mps"] == pytest.approx(own_mean, rel=1e-3, abs=1e-9)
    assert ev["slip_max_mps"] == pytest.approx(own.max(), rel=1e-3)
    assert ev["speed_mps"] == pytest.approx(1.09, rel=1e-3)


def test_the_issues_ball_with_a_steady_071_mm_s_slip_reads_rolling_with_that_slip():
    slip = 0.71e-3
    traj, own = _rolling_ball()
    # planted: the centre slides a further 0.71 mm/s along x (position, velocity, momentum)
    traj.position[:, 0, 0] += slip * traj.t
    traj.velocity[:, 0, 0] += slip
    traj.linear_momentum[:, 0, 0] += traj.model.body_mass[0] * slip
    res = _pen(traj)
    assert res.passed, [f.message for f in res.findings]
    assert not any("creep" in f.message for f in res.findings)
    (ev,) = _motion(res, "rolling")
    # the planted slip along the roll plus MuJoCo's own (<= 1e-5 m/s after 0.1 s, the test
    # above; its mean 1.0e-5 m/s over the run)
    assert ev["slip_mps"] == pytest.approx(slip, abs=2e-5)
    assert "slip 0.71" in ev["text"] and "rolls on the ground" in ev["text"]


def test_a_mujoco_ball_launched_without_spin_slides_then_rolls_at_five_sevenths():
    v0, mu = 2.0, 0.3
    m = mujoco.MjModel.from_xml_string(_ball_xml(mu=mu, timestep=0.001, cone="elliptic"))
    d = mujoco.MjData(m)
    for _ in range(300):  # settle into the soft floor
        mujoco.mj_step(m, d)
    d.qvel[:] = 0.0
    d.qvel[0] = v0
    d.time = 0.0
    rec = MujocoRecorder(m, d, every=10)
    for _ in range(1500):
        mujoco.mj_step(m, d)
        rec(d)
    rec.close()
    res = _pen(rec.trajectory)
    assert res.passed, res.reason
    (sl,) = _motion(res, "sliding")
    (ro,) = _motion(res, "rolling")
    # closed form: slip v0 - 7/2 mu g t to 0 at t = 2 v0 / (7 mu g) = 0.194 s, then rolling at
    # 5/7 v0. Measured: deceleration 10.03 against 10.30 m/s^2 (MuJoCo's soft friction, 2.6 %),
    # sliding ends at 0.19 s, rolling at 1.4277 against 1.4286 m/s (6e-4)
    t_stop = 2.0 * v0 / (7.0 * mu * GM)
    assert sl["slip_decel_mps2"] == pytest.approx(3.5 * mu * GM, rel=0.05)
    assert abs(sl["t_end"] - t_stop) <= 0.02 and ro["t_start"] == pytest.approx(sl["t_end"] + 0.01)
    assert ro["speed_mps"] == pytest.approx(5.0 / 7.0 * v0, rel=3e-3)
    assert ro["slip_mps"] < 1e-3
    assert not _motion(res, "rest")


BOX = """<mujoco><option timestep="0.002"/><worldbody>
<geom name="floor" type="plane" size="5 5 0.1"/>
<body name="box" pos="0 0 0.1"><freejoint/><geom type="box" size="0.1 0.1 0.1"/></body>
</worldbody></mujoco>"""


def test_a_resting_mujoco_box_with_a_planted_03_mm_creep_is_still_flagged():
    m = mujoco.MjModel.from_xml_string(BOX)
    d = mujoco.MjData(m)
    rec = MujocoRecorder(m, d, every=5)
    for _ in range(600):
        mujoco.mj_step(m, d)
        rec(d)
    rec.close()
    traj = rec.trajectory
    clean = _pen(traj)
    assert clean.passed and _motion(clean, "rest") and not _motion(clean, "sliding")
    creep = 3e-4
    k0 = int(np.searchsorted(traj.t, 0.6))
    traj.position[:, 0, 0] += np.clip((traj.t - traj.t[k0]) / (traj.t[-1] - traj.t[k0]), 0, 1) \
        * creep
    res = _pen(traj)
    (f,) = [f for f in res.findings if "creeps" in f.message]
    assert f.bodies == [0] and abs(f.value - creep) < 1e-5


def _kicked(shape):
    """A body on the ground (a sphere of r = 0.05 m resting on it, or a body of no contract
    shape and no geoms whose centre is 0.5 mm above it), kicked sideways to 1 m/s at t = 0.25 s
    with no normal impulse: outside the ground's friction cone (1 N s against mu m g dt =
    0.049 N s). No contact rows."""
    t = np.arange(0, 0.5001, 0.01)
    n_t = len(t)
    r = 0.05
    model = rblog.body_table(name=["b"], mass=[1.0], shape=shape,
                             size=[[r if shape == "sphere" else 0.0, 0, 0]],
                             inertia_diag=[[0.01] * 3], ground=True, friction=0.5,
                             ground_friction=0.5, restitution=0.0, ground_restitution=0.0)
    z = r if shape == "sphere" else 5e-4
    moving = t >= 0.25 - 1e-9
    pos = np.stack([np.where(moving, t - 0.25, 0.0), 0 * t, np.full(n_t, z)], 1)[:, None]
    vel = np.stack([moving * 1.0, 0 * t, 0 * t], 1)[:, None]
    rec = rblog.Recorder(model, dt=0.002, writer="test")
    rec.write(t=t, step=np.arange(n_t) * 5, position=pos,
              quat_wxyz=np.tile([1.0, 0, 0, 0], (n_t, 1))[:, None], velocity=vel,
              angular_velocity=np.zeros((n_t, 1, 3)))
    rec.close()
    return next(r for r in check(rec.trajectory, only=["momentum"]))


def test_a_shapeless_body_near_the_ground_is_not_judged_by_its_centre():
    res = _kicked("none")
    assert res.passed and not res.findings
    assert any("without a shape" in w and "contacts" in w for w in res.not_judged), \
        res.not_judged


def test_the_same_kick_on_a_sphere_resting_on_the_ground_is_flagged():
    res = _kicked("sphere")
    (f,) = res.findings
    assert "friction cone" in f.message and f.bodies == [0]


def test_a_mujoco_box_tipping_over_its_edge_pivots_and_a_ball_rolls():
    """A 0.1 x 0.1 x 0.4 m box stood on its bottom edge 0.35 rad from upright (past its tipping
    angle) falls over about that edge (mu 1: the edge holds) and lies on its side. The contact
    point on the edge hardly slips while the centre moves: a rolling contact of a body with no
    round geom, which the report calls pivoting (a ball rolls: the tests above)."""
    tip = 0.35  # rad from upright about y (the top towards +x), past atan(hx / hz) = 0.245
    hx, hz = 0.05, 0.2
    # the lower edge, x = +hx, z = -hz in the box frame, R_y(tip) of it on the floor at the origin
    c, s = np.cos(tip), np.sin(tip)
    centre = -np.array([c * hx - s * hz, 0.0, -s * hx - c * hz])
    xml = (f'<mujoco><compiler angle="radian"/><option timestep="0.002"/><worldbody>'
           f'<geom name="floor" type="plane" size="5 5 0.1" friction="1"/>'
           f'<body name="box" pos="{centre[0]} 0 {centre[2]}" euler="0 {tip} 0"><freejoint/>'
           f'<geom type="box" size="{hx} 0.05 {hz}" friction="1"/></body></worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    rec = MujocoRecorder(m, d, every=1)
    for _ in range(400):
        mujoco.mj_step(m, d)
        rec(d)
    rec.close()
    # MuJoCo's own end pose: the box's long axis horizontal (it fell over, 4 contacts)
    assert abs(d.xmat[1].reshape(3, 3)[2, 2]) < 1e-3 and d.ncon == 4
    res = _pen(rec.trajectory)
    texts = [e["text"] for e in _motion(res, "rolling")]
    assert texts and all("pivots on the ground" in x for x in texts), texts
    # the fall about the edge: 0.03 .. 0.47 s (measured; MuJoCo's contacts go from 2 to 4 at
    # ~0.5 s)
    assert max(e["duration_s"] for e in _motion(res, "rolling")) > 0.3
    assert not any(" rolls " in e.get("text", "") for e in res.events)


def test_the_rolling_event_is_in_the_checked_rrd_and_mcap(tmp_path):
    """`rblog check --rrd/--mcap` files carry the events beside the findings: the ball's rolling
    stretch as a Rerun TextLog (INFO) on events/penetration and a foxglove.Log (INFO) on
    /rblog/events, at the stretch's start, with the report's text."""
    import warnings

    import rerun as rr
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    from rblog.record.findings import EVENTS_TOPIC, write_checked

    traj, _ = _rolling_ball(seconds=0.5)
    results = check(traj)
    (ev,) = _motion(next(r for r in results if r.analyzer == "penetration"), "rolling")
    write_checked(str(tmp_path / "c.mcap"), traj, results)
    with open(tmp_path / "c.mcap", "rb") as f:
        msgs = [(m.log_time, p) for _, c, m, p in make_reader(
            f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(topics=[EVENTS_TOPIC])]
    assert [(t, p.message, p.level) for t, p in msgs] == [(0, ev["text"], 2)]  # 2: INFO
    write_checked(str(tmp_path / "c.rrd"), traj, results)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = rr.chunk.RrdReader(str(tmp_path / "c.rrd"))
        chunks = [c for c in r.stream(store=r.recordings()[0])
                  if c.entity_path == "/events/penetration"]
    (chunk,) = chunks
    batch = chunk.to_record_batch()
    cols = {n.split(":")[-1]: batch.column(n) for n in batch.schema.names}
    assert cols["text"].to_pylist() == [[ev["text"]]], cols
    assert cols["level"].to_pylist() == [["INFO"]], cols
    assert cols["sim_time"].cast("int64").to_pylist() == [0], cols
