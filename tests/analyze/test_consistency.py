"""The consistency checks (rblog.analyze.consistency) on hand-made runs with known answers: a clean
run has no finding; a quaternion in xyzw order, a transposed matrix, a body-frame angular
velocity, p != m v, NaN and time running backwards are each flagged, naming the channel and cause.

The run: a cube (isotropic inertia, so every axis is principal and the motion is torque-free)
spinning at w = 3 rad/s about the fixed world axis a = (1, 2, 2)/3, starting from a tilted
orientation R0, in free fall. Exactly: R(t) = exp(w t [a]x) R0, world angular velocity w a,
body-frame angular velocity R0^T a w (constant, and different from w a because R0 moves a).
"""

from __future__ import annotations

import numpy as np
import pytest

import rblog
from rblog.analyze import check
from rblog.analyze.consistency import ConsistencyAnalyzer, inspect
from rblog.record.recorder import body_table, trajectory_from_arrays

W = 3.0
AXIS = np.array([1.0, 2.0, 2.0]) / 3.0
G = np.array([0.0, 0.0, -9.81])


def rodrigues(axis, angle):
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def to_quat(r):
    """Independent of the code under test: via the axis-angle of r (angle < pi here)."""
    ang = np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1))
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    ax = v / np.linalg.norm(v) if np.linalg.norm(v) > 0 else np.array([1.0, 0, 0])
    return np.concatenate([[np.cos(ang / 2)], np.sin(ang / 2) * ax])


R0 = rodrigues(np.array([0.0, 1.0, 0.0]), 0.7) @ rodrigues(np.array([1.0, 0.0, 0.0]), 0.4)


def spinning_cube(T=101, dt=0.01):
    t = np.arange(T) * dt
    rot = np.array([rodrigues(AXIS, W * tk) @ R0 for tk in t])[:, None]
    quat = np.array([to_quat(r[0]) for r in rot])[:, None]
    v0, x0 = np.array([1.0, 0.0, 3.0]), np.array([0.0, 0.0, 5.0])
    pos = (x0 + v0 * t[:, None] + 0.5 * G * t[:, None] ** 2)[:, None]
    vel = (v0 + G * t[:, None])[:, None]
    omega = np.tile(W * AXIS, (T, 1, 1))
    model = body_table(name=["cube"], shape=["box"], size=[[0.1, 0.1, 0.1]], mass=[2.0], gravity=G)
    return model, dict(t=t, position=pos, rotation=rot, quat_wxyz=quat, velocity=vel,
                       angular_velocity=omega)


def _issues(**override):
    model, arrays = spinning_cube()
    arrays.update(override)
    arrays = {k: v for k, v in arrays.items() if v is not None}
    traj = trajectory_from_arrays(model, dt=0.01, **arrays)
    return traj, inspect(traj)


def test_clean_run_has_no_issue():
    traj, issues = _issues()
    assert issues == []
    res = ConsistencyAnalyzer().run(traj)
    assert res.passed and not res.findings
    assert traj.warnings == []


def test_quat_only_or_matrix_only_clean():
    assert _issues(rotation=None)[1] == []
    assert _issues(quat_wxyz=None)[1] == []


def _one(issues, channel, words):
    assert len(issues) >= 1, "expected a finding"
    hit = [i for i in issues if i.channel == channel]
    assert hit, [i.message for i in issues]
    assert all(w in hit[0].message for w in words), hit[0].message
    return hit[0]


def test_xyzw_quaternion_with_matrix():
    _, arrays = spinning_cube()
    xyzw = arrays["quat_wxyz"][..., [1, 2, 3, 0]]
    _, issues = _issues(quat_wxyz=xyzw)
    _one(issues, "quat_wxyz", ["xyzw"])


def test_xyzw_quaternion_alone():
    """Only a quaternion, in xyzw order: the matrix derived from it is wrong too, so only the
    kinematics can tell; the xyzw hypothesis makes them agree."""
    _, arrays = spinning_cube()
    _, issues = _issues(quat_wxyz=arrays["quat_wxyz"][..., [1, 2, 3, 0]], rotation=None)
    _one(issues, "quat_wxyz", ["xyzw"])


def test_transposed_matrix_with_quat():
    _, arrays = spinning_cube()
    _, issues = _issues(rotation=np.swapaxes(arrays["rotation"], -1, -2))
    _one(issues, "rotation", ["transposed"])


def test_transposed_matrix_alone():
    _, arrays = spinning_cube()
    _, issues = _issues(rotation=np.swapaxes(arrays["rotation"], -1, -2), quat_wxyz=None)
    _one(issues, "rotation", ["transposed"])


def test_body_frame_omega():
    """w logged as R^T w_world = R0^T a w (constant): L = R I R^T w is then derived from it, so
    only the kinematics see it; the body-frame hypothesis makes them agree."""
    _, arrays = spinning_cube()
    w_body = np.einsum("tnji,tnj->tni", arrays["rotation"], arrays["angular_velocity"])
    assert np.abs(w_body - arrays["angular_velocity"]).max() > 1.0  # the fault is visible
    traj, issues = _issues(angular_velocity=w_body)
    hit = _one(issues, "angular_velocity", ["body frame"])
    assert hit.bodies == [0]
    res = check(traj, only=["consistency"])[0]
    assert not res.passed and "body frame" in res.reason


def _corrected_turn(w, c, dt=0.01, T=101):
    """The cube turning at w (rad/s) about AXIS, as logged, while its pose also turns by c (rad)
    per interval about an axis perpendicular to AXIS with no velocity to show for it (an
    engine's position correction): R(t) = exp(c t / dt [p]x) exp(w t [a]x) R0, so the rate over
    an interval is w a + (c / dt) p to first order, d = c / dt from the logged w a."""
    perp = np.array([2.0, -1.0, 0.0]) / np.sqrt(5.0)
    assert abs(perp @ AXIS) < 1e-15
    t = np.arange(T) * dt
    model, arrays = spinning_cube(T, dt)
    arrays["rotation"] = np.array([rodrigues(perp, c * tk / dt) @ rodrigues(AXIS, w * tk) @ R0
                                   for tk in t])[:, None]
    arrays["quat_wxyz"] = np.array([to_quat(r[0]) for r in arrays["rotation"]])[:, None]
    arrays["angular_velocity"] = np.tile(w * AXIS, (T, 1, 1))
    traj = trajectory_from_arrays(model, dt=dt, **arrays)
    return [i for i in inspect(traj) if i.check == "kinematics"]


@pytest.mark.parametrize("w, c, flagged", [
    # samples/pile.toml (exact_contact_motion on, seed 6): box125 lies on the ground under
    # box128, logged w ~0.02 rad/s for 1.3 s while the split-impulse relax turns it back each
    # step (a two-step rock of +-7.5e-6 rad, net ~0): d = 2e-4 rad per 10 ms interval, which
    # the allowance's earlier form, d / (scale + corr / dt), read as a median 0.142 (> 0.1)
    (0.02, -2e-4, False),
    # a body turning 5e-3 rad per interval with a correction of 8e-4 rad on top: within the
    # allowance (the earlier form read 0.08 / 0.6 = 0.13 and flagged it)
    (0.5, 8e-4, False),
    # the same with 2e-3 rad: (0.2 - 0.1) / |0.5 a + 0.2 p| = 0.19 > 0.1, flagged
    (0.5, 2e-3, True),
    # a fast body (3e-2 rad per interval) with 5e-3 rad: (0.5 - 0.1) / 3.04 = 0.13, flagged
    (3.0, 5e-3, True),
])
def test_a_turn_without_velocity_is_allowed_up_to_the_correction_allowance(w, c, flagged):
    """CONSISTENCY_CORRECTION (1e-3 rad per interval) is allowed on top of the relative
    mismatch: rel = max(d dt - corr, 0) / (|w| dt), intervals turning less than corr unusable."""
    from rblog.analyze import tolerances as T

    assert T.CONSISTENCY_CORRECTION == 1e-3  # the brackets above are set about it
    issues = _corrected_turn(w, c)
    assert bool(issues) == flagged, [i.message for i in issues]


def test_a_slow_body_frame_fault_is_still_found():
    """A body-frame w on a cube turning at 0.3 rad/s (3e-3 rad per interval, 3x the allowance):
    |w_body - w_world| = 0.3 |R0^T a - a| (0.19 rad/s here) is past it, and the body-frame
    hypothesis names the cause."""
    model, arrays = spinning_cube()
    t = np.arange(101) * 0.01
    arrays["rotation"] = np.array([rodrigues(AXIS, 0.3 * tk) @ R0 for tk in t])[:, None]
    arrays["quat_wxyz"] = np.array([to_quat(r[0]) for r in arrays["rotation"]])[:, None]
    w_world = np.tile(0.3 * AXIS, (101, 1, 1))
    arrays["angular_velocity"] = np.einsum("tnji,tnj->tni", arrays["rotation"], w_world)
    traj = trajectory_from_arrays(model, dt=0.01, **arrays)
    _one(inspect(traj), "angular_velocity", ["body frame"])


def test_body_frame_omega_with_world_momentum():
    """Both w (body frame, wrong) and L (world, right) logged: L = I_world w fails and names it."""
    model, arrays = spinning_cube()
    inertia = model.body_inertia_diag[0, 0]  # isotropic: L = I w
    lw = inertia * arrays["angular_velocity"]
    w_body = np.einsum("tnji,tnj->tni", arrays["rotation"], arrays["angular_velocity"])
    _, issues = _issues(angular_velocity=w_body, angular_momentum=lw)
    _one(issues, "angular_velocity", ["body frame"])


def test_momentum_not_mass_times_velocity():
    model, arrays = spinning_cube()
    _, issues = _issues(linear_momentum=3.0 * arrays["velocity"])  # mass is 2
    _one(issues, "linear_momentum", ["mass * velocity"])


def test_velocity_in_another_frame():
    _, arrays = spinning_cube()
    v_body = np.einsum("tnji,tnj->tni", arrays["rotation"], arrays["velocity"])
    _, issues = _issues(velocity=v_body)
    _one(issues, "velocity", ["position"])


def test_nan_and_time_order():
    model, arrays = spinning_cube()
    pos = arrays["position"].copy()
    pos[50, 0, 1] = np.nan
    t = arrays["t"].copy()
    t[30], t[31] = t[31], t[30]
    traj = trajectory_from_arrays(model, dt=0.01, **{**arrays, "position": pos, "t": t},
                                  step=np.arange(len(t)))
    issues = inspect(traj)
    nan = _one(issues, "position", ["not finite"])
    assert nan.step == 50
    back = _one(issues, "t", ["does not increase"])
    assert back.step == 31


def test_findings_reach_the_check_report_and_load(tmp_path):
    model, arrays = spinning_cube()
    with rblog.Recorder(model, mcap=str(tmp_path / "x.mcap"), dt=0.01) as rec:
        rec.write(**{**arrays, "quat_wxyz": arrays["quat_wxyz"][..., [1, 2, 3, 0]]})
    traj = rblog.load(tmp_path / "x.mcap")
    assert any("xyzw" in w for w in traj.warnings)
    assert not rblog.check(traj)[0].passed


@pytest.mark.parametrize("sample", ["tumbling_box", "bouncing_ball", "mixed"])
def test_rblog_runs_are_consistent(sample):
    from rblog.engine.runner import simulate
    from rblog.engine.scene import load_scene
    from tests.conftest import SAMPLES_DIR

    traj, _ = simulate(load_scene(str(SAMPLES_DIR / f"{sample}.toml")), duration=1.0)
    assert inspect(traj) == []


# a two-link arm driven by random motor torques (new every step), and a box tumbling freely high
# above it (it touches nothing)
DRIVEN_XML = """
<mujoco>
  <option timestep="0.005"/>
  <worldbody>
    <body name="upper" pos="0 0 1">
      <joint name="shoulder" type="hinge" axis="0 1 0" damping="0.1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.01"/>
      <body name="lower" pos="0.3 0 0">
        <joint name="elbow" type="hinge" axis="0 1 0" damping="0.1"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.01"/>
      </body>
    </body>
    <body name="box" pos="2 0 50">
      <freejoint/>
      <geom type="box" size="0.1 0.2 0.3"/>
    </body>
  </worldbody>
  <actuator>
    <motor joint="shoulder" gear="2"/>
    <motor joint="elbow" gear="2"/>
  </actuator>
</mujoco>
"""


def _driven(every):
    mujoco = pytest.importorskip("mujoco")
    from rblog.adapters import mujoco as adapter

    m = mujoco.MjModel.from_xml_string(DRIVEN_XML)
    d = mujoco.MjData(m)
    d.qvel[-3:] = [1.0, 2.0, 0.5]
    mujoco.mj_forward(m, d)
    rng = np.random.default_rng(7)
    rec = adapter.recorder(m, d, every=every)
    for _ in range(600):
        d.ctrl[:] = rng.uniform(-1.0, 1.0, m.nu)
        mujoco.mj_step(m, d)
        rec(d)
    rec.close()
    return rec.trajectory


def _w_sign_flipped(traj, body):
    """The log's w and L of ``body`` negated (L = I w still holds; the turn disagrees)."""
    for name in ("angular_velocity", "angular_momentum"):
        a = getattr(traj, name).copy()
        a[:, body] *= -1.0
        setattr(traj, name, a)
    return traj


def test_loads_between_samples_not_judged_faults_still_caught():
    """Sampled every 10th step, the arm's torques change 10 times between two samples: its
    orientation's mean rate over an interval is not the mean of the end rates (median mismatch
    0.55 measured, past 0.1). Those intervals are left out and the arm is named not judged,
    not flagged; the free box in the same log is still judged, and its w with the sign flipped
    in the log is caught; at every step the arm is judged, and the same fault on it caught."""
    traj = _driven(10)
    res = ConsistencyAnalyzer().run(traj)
    assert res.passed, res.reason
    assert any("'upper', 'lower'" in x and "not judged" in x for x in res.not_judged), \
        res.not_judged
    box = traj.model.body_name.index("box")
    bad = ConsistencyAnalyzer().run(_w_sign_flipped(_driven(10), box))
    assert not bad.passed
    assert {b for f in bad.findings for b in f.bodies} == {box}, \
        [f.message for f in bad.findings]
    assert ConsistencyAnalyzer().run(_driven(1)).not_judged == []
    upper = traj.model.body_name.index("upper")
    bad1 = ConsistencyAnalyzer().run(_w_sign_flipped(_driven(1), upper))
    assert {b for f in bad1.findings for b in f.bodies} == {upper}, \
        [f.message for f in bad1.findings]
