"""The command line: bad input is one line on stderr and exit code 2, a diverging run exit code 3
naming the step and body, `validate` accepts every sample, `run --json` prints one JSON object."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from rblog.engine.scene import parse_scene
from rblog.engine.runner import simulate
from rblog_cli.main import main

from conftest import FREE_SAMPLES, SAMPLES_DIR, SPINNER

RBLOG = str(Path(sys.executable).with_name("rblog"))

GOOD = """
[sim]
dt = 1e-3
duration = 0.1
gravity = [0.0, 0.0, -9.81]

[[body]]
name = "box"
shape = "box"
half_extents = [0.3, 0.2, 0.1]
mass = 2.0
angular_velocity = [0.1, 0.2, 0.3]
"""

# (id, scene text, key path in the message) -- one scene per class of bad input
BAD_SCENES = [
    ("unknown-top-key", GOOD + "\n[simulation]\nx = 1\n", "simulation"),
    ("unknown-body-key", GOOD + "colour = \"red\"\n", "body[0].colour"),
    ("wrong-type", GOOD.replace("mass = 2.0", 'mass = "heavy"'), "body[0].mass"),
    ("non-positive-mass", GOOD.replace("mass = 2.0", "mass = -2.0"), "body[0].mass"),
    ("non-positive-half-extents", GOOD.replace("[0.3, 0.2, 0.1]", "[0.3, 0.0, 0.1]"),
     "body[0].half_extents[1]"),
    ("non-positive-radius", GOOD.replace('shape = "box"\nhalf_extents = [0.3, 0.2, 0.1]',
                                         'shape = "sphere"\nradius = 0.0'), "body[0].radius"),
    ("nan", GOOD.replace("angular_velocity = [0.1, 0.2, 0.3]", "angular_velocity = [0.1, nan, 0.3]"),
     "body[0].angular_velocity[1]"),
    ("inf", GOOD.replace("dt = 1e-3", "dt = inf"), "sim.dt"),
    ("zero-quaternion", GOOD + "quat_wxyz = [0.0, 0.0, 0.0, 0.0]\n", "body[0].quat_wxyz"),
    ("missing-sim", "[[body]]" + GOOD.split("[[body]]", 1)[1], "sim"),
    ("missing-dt", GOOD.replace("dt = 1e-3\n", ""), "sim.dt"),
    ("mass-and-density", GOOD + "density = 100.0\n", "body[0].mass"),
    ("bad-generator", GOOD + '\n[[generator]]\nlayout = "hex"\n[generator.body]\nshape = "box"\n',
     "generator[0].layout"),
    ("malformed-toml", GOOD + "velocity = [1.0, 2.0\n", ""),
]
BAD_IDS = [b[0] for b in BAD_SCENES]


def one_line_error(stderr: str) -> str:
    """The single line of stderr (asserting there is exactly one, and no traceback)."""
    assert "Traceback" not in stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith("rblog: error: "), stderr
    return lines[0]


@pytest.fixture(scope="module")
def warm_kernels():
    """Compile (or load) the kernels once before CLI runs, so that no one-time "compiling"
    notice lands on stderr in the middle of a test. Every integrator: each has its own free
    kernel (rblog.engine.free.range_kernel)."""
    from rblog.engine.integrators import REGISTRY

    scene = parse_scene(GOOD + "\n[[body]]\nname = \"b\"\nshape = \"sphere\"\nradius = 0.1\n"
                        "mass = 1.0\nposition = [5.0, 0.0, 0.0]\n")
    for integrator in REGISTRY:
        simulate(scene, duration=0.01, integrator=integrator)


@pytest.fixture
def runner():
    return CliRunner()


# ---------------------------------------------------------------------------------------------
# bad input: exit 2, one line


@pytest.mark.parametrize("command", ["validate", "run"])
@pytest.mark.parametrize("text,key", [b[1:] for b in BAD_SCENES], ids=BAD_IDS)
def test_bad_scene_exit_2(runner, scene_file, warm_kernels, command, text, key):
    path = scene_file(text)
    args = [command, path] + (["--no-log", "--json"] if command == "run" else [])
    result = runner.invoke(main, args)
    assert result.exit_code == 2, (result.output, result.exception)
    line = one_line_error(result.stderr)
    assert line.startswith(f"rblog: error: {path}: " + (f"{key}: " if key else "")), line
    assert result.stdout == ""


@pytest.mark.parametrize("command", ["validate", "run"])
def test_missing_file_exit_2(runner, tmp_path, command):
    path = str(tmp_path / "no_such_scene.toml")
    result = runner.invoke(main, [command, path, *(["--no-log"] if command == "run" else [])])
    assert result.exit_code == 2
    assert one_line_error(result.stderr) == f"rblog: error: {path}: no such file"


@pytest.mark.parametrize("options,word", [
    (["--dt", "0"], "--dt"),
    (["--dt", "-0.01"], "--dt"),
    (["--dt", "nan"], "--dt"),
    (["--duration", "0"], "--duration"),
    (["--duration", "inf"], "--duration"),
    (["--integrator", "splitting", "--orthonormalize", "polar"], "--orthonormalize"),
    (["--integrator", "seed", "--orthonormalize", "normalize"], "--orthonormalize"),
    (["--log-every", "5", "--log-rate", "10"], "--log-every"),
], ids=["dt-zero", "dt-negative", "dt-nan", "duration-zero", "duration-inf", "ortho-splitting",
        "ortho-seed", "log-every-and-rate"])
def test_bad_run_options_exit_2(runner, scene_file, warm_kernels, options, word):
    path = scene_file(GOOD)
    result = runner.invoke(main, ["run", path, "--no-log", "--json", *options])
    assert result.exit_code == 2, (result.output, result.exception)
    assert word in one_line_error(result.stderr)
    assert result.stdout == ""


def test_no_log_contradicts_outputs(runner, scene_file, tmp_path, warm_kernels):
    path = scene_file(GOOD)
    result = runner.invoke(main, ["run", path, "--no-log", "--mcap", str(tmp_path / "x.mcap")])
    assert result.exit_code == 2
    one_line_error(result.stderr)
    assert not (tmp_path / "x.mcap").exists()


@pytest.mark.parametrize("choice, stored", [("none", ""), ("zstd", "zstd"), ("lz4", "lz4")])
def test_mcap_compression_option(runner, scene_file, tmp_path, warm_kernels, choice, stored):
    from mcap.reader import make_reader

    import rblog

    out = tmp_path / "x.mcap"
    result = runner.invoke(main, ["run", scene_file(GOOD), "--mcap", str(out),
                                  "--mcap-compression", choice])
    assert result.exit_code == 0, result.output
    with open(out, "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    assert chunks and {c.compression for c in chunks} == {stored}
    assert len(rblog.load(out).t) > 1


@pytest.mark.parametrize("args", [
    ["validate", "{missing}"],
    ["validate", "{bad}"],
    ["run", "{bad}", "--no-log", "--json"],
    ["run", "{good}", "--no-log", "--dt", "-1"],
], ids=["missing", "validate-bad", "run-bad", "run-bad-dt"])
def test_bad_input_real_process(scene_file, tmp_path, warm_kernels, args):
    # the installed entry point, in its own process: exit 2 and one line, no traceback
    paths = {"missing": str(tmp_path / "missing.toml"), "good": scene_file(GOOD),
             "bad": scene_file(GOOD.replace("mass = 2.0", "mass = nan"))}
    argv = [RBLOG, *(a.format(**paths) for a in args)]
    proc = subprocess.run(argv, capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    one_line_error(proc.stderr)
    assert proc.stdout == ""


# ---------------------------------------------------------------------------------------------
# divergence: exit 3 naming the step and the body

# the notes' R += h [w]x R without orthonormalization: R is (1 + 100 i)^n in the xy block,
# |.| = 10001^(n/2), which leaves float64 at step 154 or 155 (see test_free_motion)
SPINNER_STEPS = (154, 155)

TORQUED = """
[sim]
dt = 1.0
duration = 10.0
gravity = [0.0, 0.0, 0.0]

[[body]]
name = "still"
shape = "box"
half_extents = [0.1, 0.1, 0.1]
mass = 1.0

[[body]]
name = "twisted"
shape = "box"
half_extents = [0.1, 0.1, 0.1]
mass = 1.0
position = [5.0, 0.0, 0.0]
torque = [1e308, 0.0, 0.0]
"""
# L_n = n h tau: 1e308 after step 1 (and w = L / I beyond DBL_MAX already, I = 1/150 kg m^2),
# 2e308 > DBL_MAX at step 2: every integrator must stop at step 1 or 2


def _diverged_line(stderr):
    line = one_line_error(stderr)
    assert "diverged" in line
    return line


def test_divergence_exit_3(runner, scene_file, warm_kernels):
    path = scene_file(SPINNER)
    result = runner.invoke(main, ["run", path, "--no-log", "--json"])
    assert result.exit_code == 3, (result.output, result.exception)
    line = _diverged_line(result.stderr)
    assert any(f"step {n} " in line for n in SPINNER_STEPS), line
    assert "body 1 ('spinner')" in line
    assert result.stdout == ""


@pytest.mark.parametrize("integrator", ["seed", "seed-quat", "splitting", "rk4"])
def test_enormous_torque_exit_3(runner, scene_file, warm_kernels, integrator):
    path = scene_file(TORQUED)
    result = runner.invoke(main, ["run", path, "--no-log", "--integrator", integrator])
    assert result.exit_code == 3, (result.output, result.exception)
    line = _diverged_line(result.stderr)
    assert "step 1 " in line or "step 2 " in line, line
    assert "body 1 ('twisted')" in line


def test_divergence_real_process(scene_file, tmp_path, warm_kernels):
    proc = subprocess.run([RBLOG, "run", scene_file(SPINNER), "--no-log"], capture_output=True,
                          text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 3, proc.stderr
    line = _diverged_line(proc.stderr)
    assert "spinner" in line


# ---------------------------------------------------------------------------------------------
# the samples


def _sample_expectations(name):
    doc = tomllib.loads((SAMPLES_DIR / f"{name}.toml").read_text())
    sim = doc["sim"]
    bodies = len(doc.get("body", []))
    for g in doc.get("generator", []):
        bodies += math.prod(g["grid"]) if g.get("layout", "grid") == "grid" else g["count"]
    steps = max(1, round(sim["duration"] / sim["dt"]))
    return sim, bodies, steps


ALL_SAMPLES = sorted(p.stem for p in SAMPLES_DIR.glob("*.toml"))


def test_free_samples_exist():
    assert set(FREE_SAMPLES) <= set(ALL_SAMPLES)


@pytest.mark.parametrize("name", ALL_SAMPLES)
def test_validate_every_sample(runner, name):
    path = str(SAMPLES_DIR / f"{name}.toml")
    result = runner.invoke(main, ["validate", path])
    assert result.exit_code == 0, result.output
    assert result.stdout.startswith(f"{path}: ok")


@pytest.mark.parametrize("name", FREE_SAMPLES)
def test_validate_reports_body_count(runner, name):
    _, bodies, steps = _sample_expectations(name)
    result = runner.invoke(main, ["validate", str(SAMPLES_DIR / f"{name}.toml")])
    assert result.exit_code == 0
    noun = "body" if bodies == 1 else "bodies"  # English, as the header prints it
    assert f"({bodies} {noun}, {steps} steps" in result.stdout


REQUIRED_KEYS = {"steps", "bodies", "sim_time_s", "wall_time_s", "energy_drift_rel",
                 "angular_momentum_drift_rel", "ortho_error_max"}


@pytest.mark.parametrize("name", FREE_SAMPLES)
def test_run_sample_json(runner, tmp_path, monkeypatch, warm_kernels, name):
    sim, bodies, steps = _sample_expectations(name)
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(main, ["run", str(SAMPLES_DIR / f"{name}.toml"), "--no-log", "--json"])
    assert list(tmp_path.iterdir()) == []  # --no-log writes nothing
    assert result.exit_code == 0, (result.output, result.exception)
    lines = result.stdout.strip().splitlines()
    assert len(lines) == 1, result.stdout
    d = json.loads(lines[0])
    assert isinstance(d, dict)
    assert REQUIRED_KEYS <= set(d)
    assert d["status"] == "ok"
    assert d["steps"] == steps
    assert d["bodies"] == bodies
    assert d["sim_time_s"] == pytest.approx(steps * sim["dt"], rel=1e-12)
    assert d["wall_time_s"] > 0
    for k in ("energy_drift_rel", "angular_momentum_drift_rel", "ortho_error_max"):
        assert isinstance(d[k], float) and math.isfinite(d[k]) and d[k] >= 0
    # free bodies under no torque: L is never kicked, so |L| is exact for every integrator,
    # and every default orthonormalization keeps R a rotation to round-off
    assert d["angular_momentum_drift_rel"] < 1e-12
    assert d["ortho_error_max"] < 1e-12
    assert d["energy_drift_rel"] < 1e-3
    assert d["logs"] == []


def test_run_free_fall_energy_exact_for_splitting(runner, warm_kernels):
    # leapfrog is exact on a parabola and the spin is torque-free: the energy error of the
    # free_fall sample is bounded by the rotational part, which stays far below 1e-6 at dt = 1e-3
    result = runner.invoke(main, ["run", str(SAMPLES_DIR / "free_fall.toml"), "--no-log",
                                  "--json", "--integrator", "splitting"])
    assert result.exit_code == 0
    d = json.loads(result.stdout)
    assert d["integrator"] == "splitting"
    assert d["energy_drift_rel"] < 1e-6


def test_run_options_override_scene(runner, warm_kernels):
    result = runner.invoke(main, ["run", str(SAMPLES_DIR / "tumbling_box.toml"), "--no-log",
                                  "--json", "--dt", "0.01", "--duration", "3", "--integrator",
                                  "seed", "--orthonormalize", "gram-schmidt"])
    assert result.exit_code == 0, result.output
    d = json.loads(result.stdout)
    assert d["steps"] == 300 and d["dt"] == 0.01
    assert d["integrator"] == "seed" and d["orthonormalize"] == "gram-schmidt"
    assert d["sim_time_s"] == pytest.approx(3.0, rel=1e-12)


def test_summary_matches_trajectory_definitions(warm_kernels):
    # the summary's drift figures follow their documented definitions over the logged samples
    scene = parse_scene((SAMPLES_DIR / "tumbling_box.toml").read_text(), "tumbling_box.toml")
    traj, summary = simulate(scene, integrator="seed", orthonormalize="polar", dt=1e-2)
    e = traj.total_energy
    # drift over the run's energy scale (largest kinetic energy + sum m |g| height range), which
    # does not depend on where the potential's zero is; this scene has no gravity
    kinetic = (traj.energy_translational + traj.energy_rotational).sum(axis=1)
    assert np.linalg.norm(scene.model.gravity) == 0
    assert summary.energy_drift_rel == pytest.approx(np.max(np.abs(e - e[0])) / kinetic.max(),
                                                     rel=1e-12)
    assert summary.energy_drift_rel > 0.01  # the notes' scheme gains energy (test_free_motion)
    assert summary.ortho_error_max == pytest.approx(float(traj.ortho_error.max()), rel=1e-12)
