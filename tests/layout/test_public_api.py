"""The public API: every name in rblog.__all__ imports, and each call works twice in one process
(a submodule once shadowed `rblog.simulate` after its first import)."""

from __future__ import annotations

import numpy as np

import rblog


def test_every_public_name_resolves_twice():
    for name in rblog.__all__:
        assert getattr(rblog, name) is getattr(rblog, name)


def test_simulate_load_check_twice(tmp_path):
    from rblog.record import McapRecorder

    scene = rblog.load_scene(str(rblog_samples() / "tumbling_box.toml"))
    scene2 = rblog.load_scene(str(rblog_samples() / "tumbling_box.toml"))
    t1, s1 = rblog.simulate(scene)
    t2, s2 = rblog.simulate(scene2)
    assert callable(rblog.simulate)
    np.testing.assert_array_equal(t1.position, t2.position)  # deterministic in one process
    path = tmp_path / "run.mcap"
    rblog.run(rblog.load_scene(str(rblog_samples() / "tumbling_box.toml")),
              recorders=[McapRecorder(str(path))])
    a, b = rblog.load(str(path)), rblog.load(str(path))
    assert isinstance(a, rblog.Trajectory) and a.n_samples == b.n_samples == t1.n_samples
    r1, r2 = rblog.check(a), rblog.check(b)
    assert [r.passed for r in r1] == [r.passed for r in r2] and all(r.passed for r in r1)


def test_errors_are_one_family():
    for name in ("SceneError", "LogReadError", "LogWriteError", "SimulationDiverged",
                 "RunInterrupted"):
        assert issubclass(getattr(rblog, name), rblog.RblogError)


def rblog_samples():
    from pathlib import Path

    return Path(__file__).resolve().parents[2] / "samples"
