"""What a scene's values imply together (rblog/engine/scene_checks.py), issue 41's fuzzing
findings: each reproducer is a sample scene with one value changed, and each gave a traceback
(RecursionError, OverflowError, ValueError, a C++ TypeError) or validated "ok" before. Now each is
a SceneError naming the scene, the key and the figure, and `rblog validate` of it exit 2."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from rblog.engine import scene_checks
from rblog.engine.constants import BYTES_PER_BODY_ESTIMATE, BYTES_PER_PAIR_ESTIMATE, MAX_NESTING
from rblog.engine.scene import parse_scene
from rblog.errors import SceneError
from rblog_cli.main import main

from conftest import SAMPLES_DIR

BALL = (SAMPLES_DIR / "bouncing_ball.toml").read_text()
STACK = (SAMPLES_DIR / "box_stack.toml").read_text()


def _sub(text, old, new):
    assert old in text, old
    return text.replace(old, new, 1)


CASES = {
    # name: (scene text, words the one line must hold)
    "nested 1000 deep": (_sub(BALL, "[sim]\n", "x = " + "[" * 1000 + "]" * 1000 + "\n[sim]\n"),
                         ["nested"]),
    "nested 40 deep": (_sub(BALL, "[sim]\n", "x = " + "[" * 40 + "]" * 40 + "\n[sim]\n"),
                       ["nested", str(MAX_NESTING)]),
    "sphere radius 1e308 with a density": (
        _sub(BALL, "radius = 0.1\nmass = 1.0", "radius = 1e308\ndensity = 1000.0"),
        ["body[0].mass", "inf kg"]),
    "sphere radius 1e200 with a mass": (
        _sub(BALL, "radius = 0.1", "radius = 1e200"), ["body[0].inertia_diag", "inf"]),
    "box half extents 1e200": (
        _sub(STACK, "half_extents = [0.2, 0.2, 0.1]", "half_extents = [1e200, 1e200, 1e200]"),
        ["generator[0].body.inertia_diag", "inf"]),
    "box half extents 1e200 with a density": (
        _sub(_sub(STACK, "half_extents = [0.2, 0.2, 0.1]", "half_extents = [1e200, 1e200, 1e200]"),
             "mass = 1.0", "density = 1.0"),
        ["generator[0].body.mass", "inf kg"]),
    "tiny sphere underflows to mass 0": (
        _sub(BALL, "radius = 0.1\nmass = 1.0", "radius = 1e-200\ndensity = 1000.0"),
        ["body[0].mass", "0.0 kg"]),
    "rotvec 1e308": (_sub(BALL, "1.1]\n", "1.1]\nrotvec = [1e308, 1e308, 0.0]\n"),
                     ["body[0].rotvec", "inf rad"]),
    "quaternion 1e308": (_sub(BALL, "1.1]\n", "1.1]\nquat_wxyz = [1e308, 1e308, 0.0, 0.0]\n"),
                         ["'ball'", "unit quaternion"]),
    "velocity whose momentum overflows": (
        _sub(BALL, "mass = 1.0", "mass = 1e300\nvelocity = [1e300, 0.0, 0.0]"),
        ["body[0].velocity", "momentum"]),
    "log_rate 1e-308": (_sub(BALL, "duration = 4.0\n", "duration = 4.0\nlog_rate = 1e-308\n"),
                        ["sim.log_rate", "1e-308 Hz"]),
    "log_rate 1e-30": (_sub(BALL, "duration = 4.0\n", "duration = 4.0\nlog_rate = 1e-30\n"),
                       ["sim.log_rate", "1e+33 steps"]),
    "log_every past the run": (_sub(BALL, "duration = 4.0\n",
                                    "duration = 4.0\nlog_every = 100000000000000000\n"),
                               ["sim.log_every", "4000"]),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_derived_quantity_is_one_line(case, tmp_path):
    text, needles = CASES[case]
    with pytest.raises(SceneError) as err:
        parse_scene(text, "mutated.toml")
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith("mutated.toml"), msg
    for n in needles:
        assert n in msg, msg
    path = tmp_path / "mutated.toml"
    path.write_text(text)
    res = CliRunner().invoke(main, ["validate", str(path)])
    assert res.exit_code == 2, res.output
    assert res.output.count("\n") == 1 and str(path) in res.output, res.output


def test_the_samples_still_validate():
    for p in sorted(SAMPLES_DIR.glob("*.toml")):
        parse_scene(p.read_text(), str(p))


def test_log_rate_of_one_sample_per_run_is_accepted():
    """The lowest rate that still logs a sample after t = 0 (one per duration) is fine."""
    scene = parse_scene(_sub(BALL, "duration = 4.0\n", "duration = 4.0\nlog_rate = 0.25\n"))
    assert scene.sim.log_rate == 0.25


def test_overlapping_pairs_count():
    """Counted against the pairs listed by brute force: a line of 1,000 unit spheres 1 mm apart
    (each overlaps every other: all 499,500 pairs), a lattice of spheres 5 r apart (none touch,
    and no two share a cell or neighbouring cells: 0), and 2 x 2 x 2 touching spheres (spacing
    2 r: each touches 3 and the cell rule counts its 7 others: 28, the bound's excess)."""
    import numpy as np

    line = np.zeros((1000, 3))
    line[:, 0] = np.arange(1000) * 1e-3
    assert scene_checks.overlapping_pairs(line, np.full(1000, 1.0)) == 1000 * 999 // 2
    grid = np.stack(np.meshgrid(*[np.arange(10) * 5.0] * 3, indexing="ij"), -1).reshape(-1, 3)
    assert scene_checks.overlapping_pairs(grid, np.full(len(grid), 1.0)) == 0
    cube = np.stack(np.meshgrid(*[np.arange(2) * 2.0 + 0.5] * 3, indexing="ij"), -1).reshape(-1, 3)
    assert scene_checks.overlapping_pairs(cube, np.full(8, 1.0)) == 28


def test_crowded_scene_refused_with_the_figure(monkeypatch):
    """1,000 boxes 1 mm apart (the issue's 2.66 GB run) on a machine with 1 GB available: refused
    before the run, naming the pairs and the memory."""
    text = _sub(STACK, "grid = [1, 1, 10]", "grid = [1, 1, 1000]")
    text = _sub(text, "spacing = [0.0, 0.0, 0.2]", "spacing = [0.0, 0.0, 0.001]")
    monkeypatch.setattr("rblog.engine.scene._available_memory", lambda: 10**9)
    with pytest.raises(SceneError) as err:
        parse_scene(text, "crowded.toml")
    msg = str(err.value)
    need = 1000 * BYTES_PER_BODY_ESTIMATE + 499_500 * BYTES_PER_PAIR_ESTIMATE
    assert msg.startswith("crowded.toml") and "499,500 overlapping pairs" in msg, msg
    assert f"{need / 1e9:.3g} GB" in msg and "1 GB available" in msg, msg
