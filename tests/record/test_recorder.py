"""rblog.Recorder, the public writer API: a hand-made run with a known answer goes in, every
derived channel comes out as theory says, both files read back bit for bit, the in-memory audit
equals the file's, v1 logs stay readable, bad input is a one-line error, and the README's
"Record your own engine" example runs."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import rblog
from rblog.analyze import check
from rblog.record import _common as C
from rblog.record import schema as S
from rblog.record.recorder import RecordError, body_table, matrix_to_quat, trajectory_from_arrays
from tests.conftest import REPO

G = np.array([0.0, 0.0, -9.81])
M, HALF = 2.0, 0.1
I_CUBE = M / 3.0 * 2 * HALF**2  # solid cube about any axis through its centre
W, AXIS = 3.0, np.array([1.0, 2.0, 2.0]) / 3.0


def rodrigues(axis, angle):
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def cube_run(T=201, dt=0.01):
    """A cube spinning at W about the fixed axis AXIS while it falls (torque free: every axis of
    a cube is principal). Given to the Recorder as matrices and world velocities only."""
    t = np.arange(T) * dt
    rot = np.array([rodrigues(AXIS, W * tk) for tk in t])[:, None]
    x0, v0 = np.array([0.5, -1.0, 5.0]), np.array([1.0, 0.5, 3.0])
    pos = (x0 + v0 * t[:, None] + 0.5 * G * t[:, None] ** 2)[:, None]
    vel = (v0 + G * t[:, None])[:, None]
    omega = np.tile(W * AXIS, (T, 1, 1))
    model = body_table(name=["cube"], shape=["box"], size=[[HALF] * 3], mass=[M], gravity=G)
    return model, dict(t=t, position=pos, rotation=rot, velocity=vel, angular_velocity=omega)


def test_body_table_inertia_default():
    m = body_table(name=["c", "s"], shape=["box", "sphere"], size=[[HALF] * 3, [0.2, 0, 0]],
                   mass=[M, 3.0])
    np.testing.assert_allclose(m.body_inertia_diag[0], [I_CUBE] * 3, rtol=1e-15)
    np.testing.assert_allclose(m.body_inertia_diag[1], [0.4 * 3.0 * 0.04] * 3, rtol=1e-15)


def test_derived_channels_known_answer():
    model, arrays = cube_run()
    traj = trajectory_from_arrays(model, dt=0.01, **arrays)
    t = arrays["t"]
    v = arrays["velocity"][:, 0]
    np.testing.assert_allclose(traj.linear_momentum[:, 0], M * v, rtol=1e-15)
    np.testing.assert_allclose(traj.energy_translational[:, 0], 0.5 * M * (v**2).sum(1), rtol=1e-14)
    np.testing.assert_allclose(traj.energy_rotational[:, 0], 0.5 * I_CUBE * W**2, rtol=1e-13)
    np.testing.assert_allclose(traj.energy_potential[:, 0], -M * arrays["position"][:, 0] @ G, rtol=1e-14)
    # total energy is conserved in free fall (exact parabola)
    np.testing.assert_allclose(traj.total_energy, traj.total_energy[0], rtol=1e-12)
    np.testing.assert_allclose(traj.angular_momentum[:, 0], np.tile(I_CUBE * W * AXIS, (len(t), 1)),
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(traj.angular_velocity[:, 0], np.tile(W * AXIS, (len(t), 1)), atol=1e-14)
    # quaternion derived from the matrix: the rotation by W t about AXIS, w >= 0
    half = W * t / 2
    q_exact = np.concatenate([np.cos(half)[:, None], np.sin(half)[:, None] * AXIS], axis=1)
    q_exact *= np.sign(q_exact[:, :1])
    np.testing.assert_allclose(traj.quat_wxyz[:, 0], q_exact, atol=1e-14)
    x = arrays["position"][:, 0]
    np.testing.assert_allclose(traj.total_angular_momentum, np.cross(x, M * v) + I_CUBE * W * AXIS,
                               atol=1e-13)
    assert traj.ortho_error.max() < 1e-14 and traj.warnings == []
    assert traj.step.tolist() == list(range(len(t)))


def test_files_round_trip_and_audit_matches_in_memory(tmp_path):
    model, arrays = cube_run()
    rrd, mcap = tmp_path / "c.rrd", tmp_path / "c.mcap"
    with rblog.Recorder(model, rrd=str(rrd), mcap=str(mcap), dt=0.01, writer="hand 1.0",
                        keep=True, combine_friction="max", engine_settings={"k": 1}) as rec:
        for lo in range(0, 201, 50):  # blocks
            rec.write(**{k: v[lo:lo + 50] for k, v in arrays.items()})
    mem = rec.trajectory
    mem_results = check(mem)
    for path in (rrd, mcap):
        got = rblog.load(path)
        assert got.info.writer == "hand 1.0" and got.info.combine_friction == "max"
        assert got.info.engine_settings == {"k": 1} and got.info.log_format == 3
        for name in ("t", "position", "quat_wxyz", "rotation", "velocity", "angular_velocity",
                     "angular_momentum", "total_energy", "total_angular_momentum"):
            np.testing.assert_array_equal(getattr(got, name), getattr(mem, name), err_msg=name)
        file_results = check(got)
        assert [(r.analyzer, r.passed, r.worst_value) for r in file_results] == \
               [(r.analyzer, r.passed, r.worst_value) for r in mem_results]
    assert all(r.passed or r.skipped for r in mem_results), [r.reason for r in mem_results]


def test_contacts_and_cli_check(tmp_path):
    """Contact rows given as arrays are logged and read back; `rblog check` on the file gives the
    library's verdicts."""
    from click.testing import CliRunner

    from rblog_cli.main import main

    model, arrays = cube_run(T=21)
    contacts = dict(step=[5, 5], body_a=[0, 0], body_b=[-1, -1], point=[[0, 0, 0], [0.1, 0, 0]],
                    normal=[[0, 0, 1]] * 2, separation=[-1e-4, -2e-4], normal_impulse=[0.0, 0.0])
    with rblog.Recorder(model, mcap=str(tmp_path / "c.mcap"), dt=0.01) as rec:
        rec.write(**arrays, contacts=contacts)
    got = rblog.load(tmp_path / "c.mcap")
    assert len(got.contacts) == 2 and got.contacts.t.tolist() == [0.05, 0.05]
    np.testing.assert_array_equal(got.contacts.separation, [-1e-4, -2e-4])
    res = CliRunner().invoke(main, ["check", str(tmp_path / "c.mcap"), "--json"])
    import json

    report = json.loads(res.output)
    lib = check(got)
    assert [r["passed"] for r in report["logs"][0]["results"]] == [r.passed for r in lib]


def test_bad_input_one_line_errors():
    model, arrays = cube_run(T=5)
    with pytest.raises(RecordError, match=r"position: shape \(5, 2, 3\), expected \(5, 1, 3\)"):
        trajectory_from_arrays(model, dt=0.01, **{**arrays, "position": np.zeros((5, 2, 3))})
    with pytest.raises(RecordError, match="orientation"):
        trajectory_from_arrays(model, dt=0.01, **{k: v for k, v in arrays.items() if k != "rotation"})
    with pytest.raises(RecordError, match="combine_friction"):
        rblog.Recorder(model, combine_friction="average")
    with pytest.raises(RecordError, match="time order"):
        rec = rblog.Recorder(model, dt=0.01)
        rec.write(**arrays)
        rec.write(**arrays)
    with pytest.raises(RecordError, match="body_b"):
        trajectory_from_arrays(model, dt=0.01, **arrays, contacts=dict(
            step=[1], body_a=[0], body_b=[3], point=[[0, 0, 0]], normal=[[0, 0, 1]],
            separation=[0.0], normal_impulse=[0.0]))


def test_matrix_to_quat_every_branch():
    """Shepperd's branches: angles near 0, pi/2 and pi about each axis round-trip."""
    from rblog.record.recorder import quat_to_matrix

    for axis in np.eye(3):
        for ang in (1e-9, 1.0, np.pi - 1e-6, np.pi):
            r = rodrigues(axis, ang)
            np.testing.assert_allclose(quat_to_matrix(matrix_to_quat(r)), r, atol=1e-12)


def test_v1_log_still_readable(tmp_path, monkeypatch):
    """A v1 log (before the combine rules and engine settings existed) loads with rblog's own
    rules and log_format 1."""
    from google.protobuf import descriptor_pb2

    v1_fields = {"combine_friction", "combine_restitution", "engine_settings_json"}
    fd = descriptor_pb2.FileDescriptorProto()
    fd.CopyFrom(S.file_descriptor())
    run = next(m for m in fd.message_type if m.name == "Run")
    keep = [f for f in run.field if f.name not in v1_fields]
    del run.field[:]
    run.field.extend(keep)
    fds = descriptor_pb2.FileDescriptorSet()
    fds.file.append(fd)
    monkeypatch.setattr(S, "file_descriptor_set_bytes", lambda: fds.SerializeToString())
    to_fields = C.info_to_fields
    monkeypatch.setattr(C, "info_to_fields",
                        lambda info: {k: v for k, v in to_fields(info).items() if k not in v1_fields})
    monkeypatch.setattr(C, "LOG_FORMAT_VERSION", 1)
    model, arrays = cube_run(T=11)
    with rblog.Recorder(model, mcap=str(tmp_path / "v1.mcap"), rrd=str(tmp_path / "v1.rrd"),
                        dt=0.01, combine_friction="max") as rec:
        rec.write(**arrays)
    monkeypatch.undo()
    for p in ("v1.mcap", "v1.rrd"):
        got = rblog.load(tmp_path / p)
        assert got.info.log_format == 1, p
        assert got.info.combine_friction == "geometric" and got.info.engine_settings == {}
        assert got.n_samples == 11 and got.warnings == []


def _readme_example() -> str:
    text = (REPO / "docs" / "recording.md").read_text(encoding="utf-8")
    sec = text.split("## Record your own engine", 1)[1]
    return re.search(r"```python\n(.*?)```", sec, re.S).group(1)


def test_readme_example_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    ns: dict = {}
    exec(compile(_readme_example(), "docs/recording.md", "exec"), ns)  # noqa: S102 - the repo's docs
    assert Path("ball.mcap").exists()
    results = ns["results"]
    assert [r.analyzer for r in results][0] == "consistency"
    assert all(r.passed or r.skipped for r in results), [r.reason for r in results if not r.passed]


@pytest.mark.parametrize("rule, flagged", [("geometric", True), ("max", False)])
def test_combine_rule_used_by_the_analyzers(rule, flagged):
    """A box resting on the ground (mu_box 0.2, mu_ground 0.8) with logged rows whose friction is
    0.6 of the normal impulse: inside the cone of MuJoCo's max rule (0.8), outside rblog's
    sqrt(0.2 * 0.8) = 0.4. The log's declared rule decides."""
    T, dt = 21, 0.01
    model = body_table(name=["box"], shape=["box"], size=[[0.1] * 3], mass=[1.0], friction=[0.2],
                       ground=True, ground_friction=0.8)
    t = np.arange(T) * dt
    z = np.zeros((T, 1, 3))
    pos = z + [0.0, 0.0, 0.1]
    jn = 9.81 * dt
    contacts = dict(step=np.arange(1, T), body_a=np.zeros(T - 1), body_b=-np.ones(T - 1),
                    point=np.zeros((T - 1, 3)), normal=np.tile([0.0, 0, 1], (T - 1, 1)),
                    separation=np.zeros(T - 1), normal_impulse=np.full(T - 1, jn),
                    friction_impulse=np.tile([0.6 * jn, 0, 0], (T - 1, 1)))
    traj = trajectory_from_arrays(model, dt=dt, combine_friction=rule, t=t, position=pos,
                                  quat_wxyz=np.tile([1.0, 0, 0, 0], (T, 1, 1)), velocity=z,
                                  angular_velocity=z, contacts=contacts)
    res = check(traj, only=["momentum"])[0]
    cone = [f for f in res.findings if "friction cone" in f.message]
    assert bool(cone) == flagged, res.reason
