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
    assert len(res) == 6
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
