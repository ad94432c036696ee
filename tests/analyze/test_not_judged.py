"""What the analyzers cannot judge is said, never passed (issue 31): a trajectory from a failed
recording (a ``Recorder.write`` that raised) and a log without samples are "not judged": no
result has ``passed`` (before: every analyzer returned ``passed=True, skipped=True``, and code
that reads ``passed`` saw a clean run)."""

from __future__ import annotations

import numpy as np
import pytest

import rblog

G = 9.81


def _ball_model():
    return rblog.body_table(name=["ball"], shape=["sphere"], size=[[0.1, 0, 0]], mass=[1.0],
                            ground=True, restitution=0.5, ground_restitution=0.5)


def _flight(t):
    """A ball in free flight above the ground (no contact): x = (v t, 0, 5 + 1 t - g t^2 / 2), t <= 1 s."""
    x = np.stack([0.3 * t, 0 * t, 5.0 + 1.0 * t - 0.5 * G * t * t], axis=1)[:, None, :]
    v = np.stack([0.3 + 0 * t, 0 * t, 1.0 - G * t], axis=1)[:, None, :]
    q = np.tile([1.0, 0, 0, 0], (len(t), 1, 1))
    return dict(t=t, position=x, quat_wxyz=q, velocity=v, angular_velocity=np.zeros_like(v))


def test_a_clean_recording_passes():
    """The other direction: the same flight recorded without an error passes every analyzer."""
    rec = rblog.Recorder(_ball_model(), dt=0.01)
    rec.write(**_flight(np.arange(50) * 0.01))
    rec.write(**_flight(np.arange(50, 100) * 0.01))
    traj = rec.trajectory
    assert not traj.failed and not rec.failed
    res = rblog.check(traj)
    assert all(r.passed and r.verdict in ("pass", "skip") and r.judged for r in res), \
        [(r.analyzer, r.reason) for r in res]


def test_failed_first_write_is_not_judged():
    rec = rblog.Recorder(_ball_model(), dt=0.01)
    bad = _flight(np.arange(3) * 0.01)
    bad["position"] = np.zeros((3, 2, 3))  # two bodies' positions for a one-body table
    with pytest.raises(rblog.RecordError):
        rec.write(**bad)
    traj = rec.trajectory
    assert traj.failed.startswith("write of block 1 raised RecordError") and traj.truncated
    res = rblog.check(traj)
    assert len(res) == 7
    for r in res:
        assert not r.passed and not r.judged and r.verdict == "not judged", r
        assert r.reason.startswith("not judged: the recording failed"), r.reason


def test_failed_later_write_is_not_judged_but_its_findings_stand():
    """Samples recorded before the failure are still audited: a real fault in them is a finding
    (FAIL), and the analyzers without findings say "not judged", none passes."""
    rec = rblog.Recorder(_ball_model(), dt=0.01)
    good = _flight(np.arange(50) * 0.01)
    # plant a fault in the recorded part: the velocity jumps by 1 m/s at t = 0.25 s with nothing
    # in reach (5 m above the ground): a momentum change no force explains
    good["velocity"][25:, 0, 0] += 1.0
    good["position"][25:, 0, 0] += 1.0 * (good["t"][25:] - good["t"][24])
    rec.write(**good)
    with pytest.raises(rblog.RecordError):
        rec.write(**{**_flight(np.arange(50, 60) * 0.01), "quat_wxyz": np.ones((10, 1, 3))})
    traj = rec.trajectory
    assert traj.n_samples == 50 and traj.failed.startswith("write of block 2 raised")
    res = {r.analyzer: r for r in rblog.check(traj)}
    assert not any(r.passed for r in res.values())
    assert res["momentum"].verdict == "FAIL" and res["momentum"].findings
    assert "the recording failed" in res["momentum"].not_judged[0]
    clean = [r for r in res.values() if not r.findings]
    assert clean and all(r.verdict == "not judged" for r in clean)


def test_a_failed_recording_is_never_a_clean_log_in_the_cli_report():
    from rblog.study import bulk_check

    rec = rblog.Recorder(_ball_model(), dt=0.01)
    rec.write(**_flight(np.arange(20) * 0.01))
    with pytest.raises(rblog.RecordError):
        rec.write(**{**_flight(np.arange(20, 30) * 0.01), "velocity": np.zeros((10, 1))})
    res = rblog.check(rec.trajectory)
    summary = bulk_check.summarize([{"status": "not judged",
                                     "results": [r.to_dict() for r in res]}])
    assert all(c["not judged"] == 1 and c["pass"] == 0 for c in summary["analyzers"].values())


def test_a_log_without_samples_is_not_judged():
    rec = rblog.Recorder(_ball_model(), dt=0.01)
    res = rblog.check(rec.trajectory)
    assert all(not r.passed and r.verdict == "not judged" for r in res)
    assert all("no samples" in r.reason for r in res)


# ---- bodies without a shape (a MuJoCo capsule) ------------------------------------------------
CAPSULE_XML = """<mujoco><option timestep="0.002"/>
<worldbody><geom name="floor" type="plane" size="5 5 0.1"/>
<body name="capsule" pos="0 0 1.0" euler="0 90 0"><freejoint/>
  <geom type="capsule" size="0.05 0.15" mass="1"/></body>
<body name="ball" pos="0.5 0 1.0"><freejoint/><geom type="sphere" size="0.1" mass="1"/></body>
</worldbody></mujoco>"""


def _capsule_run(rollout: bool):
    """A capsule (no shape in the contract) and a ball dropped 0.95 / 0.9 m onto MuJoCo's floor,
    2 s, recorded by the adapter after each mj_step (contact rows) or from mujoco.rollout (none).
    """
    mujoco = pytest.importorskip("mujoco")
    from rblog.adapters.mujoco import MujocoRecorder, record_rollout

    m = mujoco.MjModel.from_xml_string(CAPSULE_XML)
    d = mujoco.MjData(m)
    if not rollout:
        rec = MujocoRecorder(m, d)
        for _ in range(1000):
            mujoco.mj_step(m, d)
            rec(d)
        rec.close()
        return rec.trajectory
    from mujoco import rollout as mj_rollout

    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    x0 = np.zeros(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, x0, spec)
    state, _ = mj_rollout.rollout(m, d, x0[None], nstep=1000)
    return record_rollout(m, x0, state)


def _mujoco_capsule_depth():
    """The truth, from MuJoCo's own collision: the capsule's deepest contact.dist with the floor
    over the states the adapter logs (each mj_step's end, recomputed on a second MjData)."""
    mujoco = pytest.importorskip("mujoco")
    m = mujoco.MjModel.from_xml_string(CAPSULE_XML)
    d, d2 = mujoco.MjData(m), mujoco.MjData(m)
    cap = [g for g in range(m.ngeom) if m.geom_bodyid[g] == 1]
    deepest, when = 0.0, None
    for _ in range(1000):
        mujoco.mj_step(m, d)
        d2.qpos[:], d2.qvel[:] = d.qpos, d.qvel
        mujoco.mj_forward(m, d2)
        for c in d2.contact[:d2.ncon]:
            if (c.geom1 in cap or c.geom2 in cap) and c.dist < deepest:
                deepest, when = float(c.dist), float(d.time)
    return -deepest, when


@pytest.mark.parametrize("rollout", [False, True], ids=["contact-rows", "rollout"])
def test_a_capsule_is_judged_by_its_geometry(rollout):
    """The capsule has no sphere/box shape; its geom is in the log (contract v3), so penetration
    judges it per geom pair: the deepest depth it reports is MuJoCo's own contact.dist at the
    logged states (MuJoCo's soft floor lets a 4.3 m/s landing dig 28 mm in: a true finding
    against the 5 mm limit). With contact impulses logged, momentum and energy judge it and find
    nothing; from a rollout (no impulses, no contact rows) they say why they do not."""
    traj = _capsule_run(rollout)
    from rblog.contract.model import SHAPE_NONE

    assert traj.model.body_shape[0] == SHAPE_NONE
    # the capsule lands (its centre drops from 1.0 m to its radius, 0.05 m above the floor)
    assert abs(traj.position[-1, 0, 2] - 0.05) < 0.02
    res = {r.analyzer: r for r in rblog.check(traj)}
    depth, when = _mujoco_capsule_depth()
    pen = [f for f in res["penetration"].findings if "'capsule'" in f.message]
    assert pen, res["penetration"].findings
    # measured: equal to 1e-16 m (geometry against contact.dist: tests/analyze/test_geometry_*)
    assert max(f.value for f in pen) == pytest.approx(depth, abs=1e-9)
    for name in ("momentum", "energy", "tunneling", "drift", "consistency"):
        assert all(0 not in f.bodies for f in res[name].findings), (name, res[name].findings[:2])
    if rollout:
        for name in ("momentum", "energy"):
            assert any("'capsule'" in x and "not judged" in x or "not in the log" in x
                       for x in res[name].not_judged), (name, res[name].not_judged)
    else:
        assert res["momentum"].stats["balance_bodies"] == 2


def test_a_body_without_geoms_is_left_out_of_the_shapeless_notes():
    """A massless marker body with no geom (dm_control's 'pinch site': a site and an inertial)
    on a capsule: in a log with geoms it has no collision geometry, so no analyzer says it is
    not judged "for lack of a shape" (before, penetration and tunneling named it)."""
    mujoco = pytest.importorskip("mujoco")
    from rblog.adapters.mujoco import MujocoRecorder

    xml = CAPSULE_XML.replace(
        '<geom type="capsule" size="0.05 0.15" mass="1"/></body>',
        '<geom type="capsule" size="0.05 0.15" mass="1"/><body name="marker" pos="0 0 0.2">'
        '<site name="tip"/><inertial pos="0 0 0" mass="1e-6" diaginertia="1e-12 1e-12 1e-12"/>'
        '</body></body>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    rec = MujocoRecorder(m, d)
    for _ in range(200):
        mujoco.mj_step(m, d)
        rec(d)
    rec.close()
    traj = rec.trajectory
    names = list(traj.model.body_name)
    assert "marker" in names and traj.model.n_geoms
    notes = [x for r in rblog.check(traj) for x in r.not_judged]
    assert not any("'marker'" in x for x in notes), notes


def test_a_capsule_kicked_in_free_flight_is_still_flagged():
    """The other direction: with contact rows the capsule's free flight is judged; a planted 1 m/s
    horizontal kick at t = 0.1 s (0.9 m above the floor, nothing in reach) is a momentum change no
    force explains."""
    traj = _capsule_run(rollout=False)
    k = int(np.searchsorted(traj.t, 0.1))
    m = traj.model.body_mass[0]
    traj.velocity[k:, 0, 0] += 1.0
    traj.linear_momentum[k:, 0, 0] += m * 1.0
    traj.position[k:, 0, 0] += 1.0 * (traj.t[k:] - traj.t[k - 1])
    res = {r.analyzer: r for r in rblog.check(traj, only=["momentum"])}
    assert any(f.bodies == [0] and "free flight" in f.message for f in res["momentum"].findings)


# ---- restitution the engine does not state ----------------------------------------------------
def test_unknown_restitution_is_not_judged_and_said():
    """An exact bouncing ball (e = 0.8) whose log states no restitution (NaN: MuJoCo's soft
    contacts have none): before, the momentum analyzer passed it silently; now it says the
    restitution of its impacts was not judged (and judges nothing else differently)."""
    from test_analyze import bouncing_ball

    traj, t_imp = bouncing_ball(e=0.8, e_config=float("nan"))
    mom = {r.analyzer: r for r in rblog.check(traj)}["momentum"]
    assert mom.passed and mom.judged
    (line,) = [x for x in mom.not_judged if x.startswith("restitution of")]
    # every bounce of the exact ball is an impact: len(t_imp) of them
    assert line.startswith(f"restitution of {len(t_imp)} impacts ('b0')") and "not judged" in line
    assert mom.stats["restitution_not_judged"] == len(t_imp)
    assert line in mom.reason


def test_stated_restitution_is_judged_both_ways():
    """The other direction: with e stated, the same exact ball is judged (nothing left out) and a
    wrong configured value (0.5 for a ball bouncing at 0.8) is flagged."""
    from test_analyze import bouncing_ball

    traj, _ = bouncing_ball(e=0.8)
    mom = {r.analyzer: r for r in rblog.check(traj)}["momentum"]
    assert mom.passed and not mom.not_judged and mom.stats["restitution_not_judged"] == 0
    traj, _ = bouncing_ball(e=0.8, e_config=0.5)
    mom = {r.analyzer: r for r in rblog.check(traj)}["momentum"]
    assert any("restitution 0.8" in f.message for f in mom.findings), mom.findings[:2]


def test_mujoco_ball_restitution_is_not_judged():
    """The adapter logs MuJoCo's restitution as unknown: its ball's bounce is not judged, and
    the result says so (the ball lands at 4.2 m/s: an impact)."""
    traj = _capsule_run(rollout=False)
    assert np.isnan(traj.model.body_restitution).all()
    mom = {r.analyzer: r for r in rblog.check(traj)}["momentum"]
    assert any(x.startswith("restitution of") and "'ball'" in x for x in mom.not_judged), \
        mom.not_judged
