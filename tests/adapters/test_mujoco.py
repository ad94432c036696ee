"""rblog.adapters.mujoco on a user's own MJCF models: a box on a plane, a bouncing
ball, two stacked boxes, a tumbling box. Each is recorded in two lines, and rblog.check's verdict
is compared with what numpy computes from qpos/qvel on its own (not through the adapter): the
soft contact's sink, the bounce's restitution, the angular momentum drift of MuJoCo's Euler
integrator. The logged contact impulses must sum to each body's momentum change (minus gravity)
within 1e-9 N s."""

from __future__ import annotations

import numpy as np
import pytest

import rblog

mujoco = pytest.importorskip("mujoco")
from rblog.adapters import AdapterError  # noqa: E402
from rblog.adapters.mujoco import MujocoRecorder, record_rollout  # noqa: E402
from rblog.contract.model import BODY_FREE, BODY_JOINTED, JOINT_FIXED, SHAPE_BOX, SHAPE_NONE, SHAPE_SPHERE  # noqa: E402

DT = 1e-3
G = 9.81
#: impulse balance: the issue's bound. Measured: 3.0e-11 (box), 3.0e-11 (ball), 5.7e-11 N s
#: (stack): the round-off of m dv over ~1e3 steps
BALANCE_NS = 1e-9


def model(bodies: str, *, ground: bool = True, option: str = 'integrator="Euler"') -> "mujoco.MjModel":
    floor = '<geom name="floor" type="plane" size="5 5 0.1"/>' if ground else ""
    return mujoco.MjModel.from_xml_string(
        f'<mujoco><option timestep="{DT}" {option}/><worldbody>{floor}{bodies}</worldbody></mujoco>')


def run(m, n, qvel=None, **rec_options):
    """The user's two lines, plus an independent copy of qpos/qvel after every step."""
    d = mujoco.MjData(m)
    if qvel is not None:
        d.qvel[:] = qvel
    qpos, qv = [d.qpos.copy()], [d.qvel.copy()]
    rec = MujocoRecorder(m, d, **rec_options)            # line 1: the body table, sample 0
    for _ in range(n):
        mujoco.mj_step(m, d)
        rec(d)                                           # line 2: state and contacts
        qpos.append(d.qpos.copy())
        qv.append(d.qvel.copy())
    rec.close()
    return rec.trajectory, np.array(qpos), np.array(qv)


def result(results, name):
    return next(r for r in results if r.analyzer == name)


def balance_residual(traj, m, qvel) -> float:
    """max |m dv - m g dt - sum of the logged impulses| over bodies and steps (N s), with v from
    qvel (the bodies of these models have their centre of mass at the body origin)."""
    c = traj.contacts
    imp = c.normal_impulse[:, None] * c.normal + c.friction_impulse
    worst = 0.0
    for i in range(traj.model.n_bodies):
        mass = float(m.body_mass[i + 1])
        v = qvel[:, 6 * i:6 * i + 3]
        dp = mass * np.diff(v, axis=0) - mass * np.asarray(m.opt.gravity) * DT
        j = np.zeros_like(dp)
        np.add.at(j, c.step[c.body_a == i] - 1, imp[c.body_a == i])
        np.add.at(j, c.step[c.body_b == i] - 1, -imp[c.body_b == i])
        worst = max(worst, float(np.abs(dp - j).max()))
    return worst


def box_bottom(qpos, i, half):
    """Lowest point (m) of box i: z - the box's vertical half-height, from the quaternion."""
    q = qpos[:, 7 * i + 3:7 * i + 7]
    w, x, y, z = q.T
    r2 = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1)
    return qpos[:, 7 * i + 2] - np.abs(r2) @ np.asarray(half)


BOX = '<body name="box" pos="0 0 0.05"><freejoint/><geom type="box" size="0.1 0.1 0.05" mass="1"{}/></body>'


@pytest.mark.parametrize("solref", ["", ' solref="0.1 1" solimp="0.5 0.5 0.001"'], ids=["default", "soft"])
def test_box_on_a_plane_sinks_as_numpy_says(solref):
    m = model(BOX.format(solref))
    traj, qpos, qvel = run(m, 1000)
    assert traj.model.body_shape.tolist() == [SHAPE_BOX]
    np.testing.assert_allclose(traj.model.body_size[0], [0.1, 0.1, 0.05])
    assert np.isnan(traj.model.body_restitution[0]) and traj.model.ground
    sink = -box_bottom(qpos, 0, [0.1, 0.1, 0.05]).min()  # numpy, from qpos alone
    res = rblog.check(traj)
    pen = result(res, "penetration")
    # measured: default solref 0.114 mm (passes the 1 mm resting limit); solref 0.1, solimp 0.5: 2.43 mm
    assert (sink > pen.tolerance) == (not pen.passed) == bool(solref)
    assert pen.worst_value == pytest.approx(sink, rel=1e-9)
    assert balance_residual(traj, m, qvel) < BALANCE_NS
    # energy: the box touches the plane in every interval and never strikes it, nothing to judge
    assert all(r.passed or (r.analyzer, r.verdict) == ("energy", "not judged")
               for r in res if r.analyzer != "penetration"), [r.reason for r in res]


BALL = ('<body name="ball" pos="0 0 1"><freejoint/>'
        '<geom type="sphere" size="0.05" mass="1" solref="0.005 0.2"/></body>')


def numpy_bounce(qpos, qvel, r=0.05):
    """(approach speed at the touch z = r, restitution, peak depth) of the first bounce, from z and
    vz alone. A soft contact pushes over many steps: the steps whose dv is not -g dt. Its
    restitution is Newton's, the velocity when the push ends over the velocity when it begins
    (the ball leaves the spring below z = r: from there it flies)."""
    z, vz = qpos[:, 2], qvel[:, 2]
    free = np.abs(np.diff(vz) / DT + G) < 1e-9  # steps without a contact force
    k_in = np.flatnonzero(~free)[0]              # the push acts from sample k_in on
    k_out = k_in + np.flatnonzero(free[k_in:])[0]  # ... until sample k_out
    touch = np.sqrt(vz[k_in] ** 2 + 2 * G * (z[k_in] - r))
    return touch, vz[k_out] / -vz[k_in], r - z[k_in:k_out + 1].min()


def test_bouncing_ball_restitution_as_numpy_says():
    m = model(BALL)
    traj, qpos, qvel = run(m, 800)
    assert traj.model.body_shape.tolist() == [SHAPE_SPHERE]
    speed, e, depth = numpy_bounce(qpos, qvel)
    # semi-implicit Euler arrives at sqrt(2 g h) - g dt / 2 (v_n = g n dt, h = g dt^2 n (n+1) / 2);
    # measured: 4.31240 against that 4.31239
    assert speed == pytest.approx(np.sqrt(2 * G * 0.95) - G * DT / 2, rel=1e-5)
    res = rblog.check(traj)
    mom, pen = result(res, "momentum"), result(res, "penetration")
    first = mom.events[0]
    # measured: e = 0.234099 both ways, equal to round-off (at z = r on the way up the ball has
    # 0.215 of the approach speed: gravity's work between the release and z = r)
    assert first["restitution_effective"] == pytest.approx(e, rel=1e-9)
    assert first["restitution_configured"] is None  # MuJoCo states none: unknown
    assert first["peak_penetration_m"] == pytest.approx(depth, rel=1e-9)
    # the soft contact's peak depth (14.9 mm) exceeds the any-time limit: numpy and rblog agree
    assert (depth > pen.tolerance) == (not pen.passed)
    assert not any("restitution" in f.message for f in mom.findings)
    assert balance_residual(traj, m, qvel) < BALANCE_NS
    # a declared restitution is judged: the measured one passes, one 0.3 off is flagged
    for declared, flagged in ((e, False), (e + 0.3, True)):
        traj2, _, _ = run(m, 800, restitution=declared)
        mom2 = result(rblog.check(traj2, only=["momentum"]), "momentum")
        assert any("restitution" in f.message for f in mom2.findings) == flagged, mom2.reason


STACK = ('<body name="lower" pos="0 0 0.05"><freejoint/><geom type="box" size="0.1 0.1 0.05" mass="1"/></body>'
         '<body name="upper" pos="0 0 0.15"><freejoint/><geom type="box" size="0.1 0.1 0.05" mass="1"/></body>')


def test_two_stacked_boxes():
    m = model(STACK)
    traj, qpos, qvel = run(m, 1000)
    assert traj.model.body_name == ["lower", "upper"]
    half = [0.1, 0.1, 0.05]
    ground_sink = -box_bottom(qpos, 0, half).min()
    top_of_lower = qpos[:, 2] + (qpos[:, 2] - box_bottom(qpos, 0, half))
    pair_sink = (top_of_lower - box_bottom(qpos, 1, half)).max()
    res = rblog.check(traj)
    pen = result(res, "penetration")
    # measured: 0.207 mm (the lower box carries both), 0.11 mm between the boxes: both pass
    assert max(ground_sink, pair_sink) < pen.tolerance and pen.passed
    assert pen.worst_value == pytest.approx(max(ground_sink, pair_sink), rel=1e-6)
    c = traj.contacts
    assert set(zip(c.body_a.tolist(), c.body_b.tolist())) == {(0, -1), (1, 0)}
    assert balance_residual(traj, m, qvel) < BALANCE_NS
    # energy: both boxes touch in every interval and nothing strikes, nothing to judge
    assert all(r.passed or (r.analyzer, r.verdict) == ("energy", "not judged")
               for r in res), [r.reason for r in res if not r.passed]


TUMBLE = '<body name="tumbler" pos="0 0 1"><freejoint/><geom type="box" size="0.3 0.2 0.1" mass="1"/></body>'
SPIN = [0, 0, 0, 0.05, 2.0, 0.05]  # near the intermediate axis, body frame (rad/s)


def numpy_l_drift(m, qpos, qvel) -> float:
    """max |L(t) - L(0)| / max |L| of the free body, L = R (I w_body), from qpos/qvel."""
    w, x, y, z = qpos[:, 3:7].T
    r = np.empty((len(w), 3, 3))
    r[:, 0] = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], 1)
    r[:, 1] = np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], 1)
    r[:, 2] = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], 1)
    big_l = np.einsum("tij,tj->ti", r, np.asarray(m.body_inertia[1]) * qvel[:, 3:6])
    return float(np.linalg.norm(big_l - big_l[0], axis=1).max() / np.linalg.norm(big_l, axis=1).max())


@pytest.mark.parametrize("integrator, flagged", [("Euler", True), ("RK4", False)])
def test_tumbling_box_angular_momentum(integrator, flagged):
    m = model(TUMBLE, ground=False, option=f'integrator="{integrator}" gravity="0 0 0"')
    traj, qpos, qvel = run(m, 5000, qvel=SPIN)
    drift = numpy_l_drift(m, qpos, qvel)
    mom = result(rblog.check(traj, only=["momentum"]), "momentum")
    # measured: Euler 2.42e-4 over 5 s (its explicit gyroscopic term), RK4 6e-15; limit 1e-6
    assert (drift > mom.tolerance) == flagged == (not mom.passed)
    if flagged:
        assert mom.worst_value == pytest.approx(drift, rel=1e-6)
        assert "angular momentum" in mom.findings[0].message


def test_rollout_records_the_same_states():
    """mujoco.rollout's output recorded in one call equals the stepped recording."""
    from mujoco import rollout

    m = model(TUMBLE, ground=False, option='integrator="Euler" gravity="0 0 0"')
    traj, _, _ = run(m, 200, qvel=SPIN)
    d = mujoco.MjData(m)
    d.qvel[:] = SPIN
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    x0 = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, x0, spec)
    state, _ = rollout.rollout(m, mujoco.MjData(m), x0, nstep=200)
    got = record_rollout(m, x0, state)
    assert got.n_samples == traj.n_samples == 201
    np.testing.assert_array_equal(got.step, traj.step)
    for name in ("position", "quat_wxyz", "velocity", "angular_velocity"):
        np.testing.assert_array_equal(getattr(got, name), getattr(traj, name), err_msg=name)


def test_frames_of_offset_and_rotated_bodies():
    """A box whose inertial frame is turned (body_iquat), a capsule, a sphere off its body's
    origin: the logged centre of mass, orientation and velocities equal MuJoCo's own xipos,
    ximat and mj_objectVelocity (world frame, at the centre of mass)."""
    xml = ('<body name="turned" pos="0 0 1" euler="10 20 30"><freejoint/>'
           '<geom type="box" size="0.3 0.2 0.1" euler="0 0 90" mass="2"/></body>'
           '<body name="capsule" pos="1 0 1"><freejoint/><geom type="capsule" size="0.05 0.2" mass="1"/></body>'
           '<body name="offset" pos="2 0 1"><freejoint/><geom type="sphere" size="0.1" pos="0.1 0 0" mass="1"/>'
           '<geom type="sphere" size="0.01" pos="-0.3 0 0" mass="0.1"/></body>')
    m = model(xml, ground=False, option='gravity="0 0 0"')
    d = mujoco.MjData(m)
    d.qvel[:] = np.tile([0.1, -0.2, 0.3, 1.0, 2.0, 3.0], 3)
    rec = MujocoRecorder(m, d)
    for _ in range(50):
        mujoco.mj_step(m, d)
        rec(d)
    mujoco.mj_forward(m, d)  # refresh xipos/ximat for the final qpos
    traj = rec.trajectory
    tm = traj.model
    assert tm.body_shape.tolist() == [SHAPE_BOX, SHAPE_NONE, SHAPE_NONE]
    np.testing.assert_allclose(tm.body_size[0], [0.3, 0.2, 0.1])  # in the box's own frame
    np.testing.assert_allclose(tm.body_mass, [2.0, 1.0, 1.1])
    for i in range(3):
        b = i + 1
        np.testing.assert_allclose(traj.position[-1, i], d.xipos[b], atol=1e-12)
        vel = np.zeros(6)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, b, vel, 0)
        np.testing.assert_allclose(traj.angular_velocity[-1, i], vel[:3], atol=1e-12)
        np.testing.assert_allclose(traj.velocity[-1, i], vel[3:], atol=1e-12)
        # the inertia tensor in the world: the log's R diag(I) R^T equals MuJoCo's
        r = traj.rotation[-1, i]
        ri = d.ximat[b].reshape(3, 3)
        np.testing.assert_allclose(r @ np.diag(tm.body_inertia_diag[i]) @ r.T,
                                   ri @ np.diag(m.body_inertia[b]) @ ri.T, atol=1e-12)
    assert result(rblog.check(traj, only=["consistency"]), "consistency").passed
    # (rblog check's momentum analyzer flags the 'offset' body: MuJoCo's Euler step changes the
    # linear momentum of a body whose centre of mass is off its frame's origin in free flight,
    # 3.6e-4 of m |v| here; the velocities above are MuJoCo's own, so that is MuJoCo's)


def test_refusals_are_one_line():
    with pytest.raises(AdapterError, match="expected a mujoco.MjModel"):
        MujocoRecorder("model.xml")


def test_missing_engine_is_one_line(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "mujoco", None)  # import mujoco now raises ImportError
    with pytest.raises(AdapterError) as err:
        MujocoRecorder(None)
    assert "\n" not in str(err.value) and "pip install mujoco" in str(err.value)


def test_writes_both_logs(tmp_path):
    m = model(BOX.format(""))
    d = mujoco.MjData(m)
    with MujocoRecorder(m, d, mcap=str(tmp_path / "box.mcap"), rrd=str(tmp_path / "box.rrd")) as rec:
        for _ in range(100):
            mujoco.mj_step(m, d)
            rec(d)
    a, b = rblog.load(tmp_path / "box.mcap"), rblog.load(tmp_path / "box.rrd")
    assert a.n_samples == b.n_samples == 101 and not a.truncated
    np.testing.assert_array_equal(a.position, b.position)
    assert a.info.engine_settings["engine"] == "mujoco" and a.info.combine_friction == "max"
    assert a.info.engine_settings["contact_rows"]["separation"].startswith("before the step")


def test_welded_bodies_sum_to_mujocos_subtree():
    """A free body with a welded child (a hammer: handle and head) is two bodies of the log, the
    head on a fixed joint; together their momentum and angular momentum about their common
    centre of mass equal MuJoCo's own subtree_com, subtree_linvel x mass and subtree_angmom
    (mj_subtreeVel)."""
    xml = ('<body name="hammer" pos="0 0 1" euler="10 0 30"><freejoint/>'
           '<geom type="cylinder" size="0.02 0.2" mass="0.5"/>'
           '<body name="head" pos="0 0 0.2" euler="0 90 0"><geom type="box" size="0.03 0.03 0.08" mass="1.5"/>'
           '</body></body>')
    m = model(xml, ground=False, option='gravity="0 0 0"')
    d = mujoco.MjData(m)
    d.qvel[:] = [0.1, 0, 0, 1, 2, 3]
    rec = MujocoRecorder(m, d)
    for _ in range(100):
        mujoco.mj_step(m, d)
        rec(d)
    mujoco.mj_forward(m, d)
    mujoco.mj_subtreeVel(m, d)
    traj = rec.trajectory
    tm = traj.model
    assert tm.body_name == ["hammer", "head"] and tm.body_kind.tolist() == [BODY_FREE, BODY_JOINTED]
    assert tm.joint_type.tolist() == [JOINT_FIXED] and tm.body_parent.tolist() == [-1, 0]
    mass = tm.body_mass.sum()
    assert mass == 2.0
    x, p = traj.position[-1], traj.linear_momentum[-1]
    com = (tm.body_mass[:, None] * x).sum(axis=0) / mass
    np.testing.assert_allclose(com, d.subtree_com[1], atol=1e-12)
    np.testing.assert_allclose(p.sum(axis=0), mass * d.subtree_linvel[1], atol=1e-12)
    angmom = traj.angular_momentum[-1].sum(axis=0) + np.cross(x - com, p).sum(axis=0)
    np.testing.assert_allclose(angmom, d.subtree_angmom[1], atol=1e-12)


def test_a_recording_after_another_logs_the_same_bits():
    """A recorder takes its model's idle MjData (rblog.adapters._mujoco_model.take_scratch,
    reset) for its own kinematics and gives it back on close: a second recording of the same
    model, from the same state, reuses the MjData the first one left at its last sample and logs
    the same bits (the body table at qpos0, every state and impulse); two recorders open at once
    each have their own."""
    xml = ('<body name="arm" pos="0 0 1"><joint name="shoulder" type="hinge" axis="0 1 0"/>'
           '<geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>'
           '<body name="forearm" pos="0.3 0 0" euler="0 20 0"><joint name="elbow" type="hinge" '
           'axis="0 0.6 0.8" range="-1 1"/><geom type="box" size="0.1 0.02 0.02" pos="0.1 0 0"/>'
           '</body></body>'
           '<body name="cube" pos="0.5 0 0.3" euler="10 20 30"><freejoint/>'
           '<geom type="box" size="0.05 0.05 0.05"/></body>')
    m = model(xml)
    logs = []
    for _ in range(2):
        traj, _, _ = run(m, 300, qvel=[2.0, -3.0, 0.5, 0, 0, 1, 2, 3])
        logs.append(traj)
    first, second = logs
    for f in ("joint_anchor_body", "joint_anchor_parent", "joint_axis_body", "joint_axis_parent",
              "geom_pos_body", "geom_quat_wxyz_body"):
        assert getattr(first.model, f).tobytes() == getattr(second.model, f).tobytes(), f
    for f in ("position", "rotation", "quat_wxyz", "velocity", "angular_velocity",
              "impulse_contact_linear", "impulse_joint_angular", "work_joint"):
        assert getattr(first, f).tobytes() == getattr(second, f).tobytes(), f
    d = mujoco.MjData(m)
    a, b = MujocoRecorder(m, d), MujocoRecorder(m, d)
    assert a.kin.d is not b.kin.d
    a.close()
    b.close()
