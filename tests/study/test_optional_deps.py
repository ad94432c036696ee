"""Optional dependencies that are not installed. `rblog bench` and `rblog stress` without the
"bench" extra (scipy, matplotlib) say what is missing and how to install it before any run, and
run nothing they cannot score (a plain `pip install -e .` once ran 8 minutes, then reported 4 of
7 problems "unavailable: No module named 'scipy'" and the plot "not written"); `rblog run
--engine` without the engine names the extra as a user of a checkout installs it."""

from __future__ import annotations

import json
import sys

import pytest
from click.testing import CliRunner

from rblog.study.reference import PROBLEMS
from rblog_cli.main import main

EXTRA = 'pip install -e ".[bench]"'


@pytest.fixture
def without_bench_extra(monkeypatch):
    """scipy and matplotlib not importable (a None in sys.modules makes `import` raise
    ImportError), as on an install without the extra."""
    for mod in list(sys.modules):
        if mod.split(".")[0] in ("scipy", "matplotlib"):
            monkeypatch.delitem(sys.modules, mod)
    monkeypatch.setitem(sys.modules, "scipy", None)
    monkeypatch.setitem(sys.modules, "matplotlib", None)


def test_bench_says_what_to_install_before_it_runs(tmp_path, without_bench_extra):
    needs_scipy = [n for n, p in PROBLEMS.items() if "scipy" in p().needs]
    # the problems whose exact answer is computed with scipy's elliptic functions or DOP853
    assert sorted(needs_scipy) == sorted(["torque-free-intermediate", "torque-free-generic",
                                          "torqued-body", "free-fall"])
    res = CliRunner().invoke(main, ["bench", "--quick", "--no-peers", "--integrator", "rk4",
                                    "--dt", "0.02", "--out", str(tmp_path), "--progress"])
    assert res.exit_code == 0, (res.output, res.exception)
    lines = res.output.splitlines()
    note = [i for i, ln in enumerate(lines) if ln.startswith("rblog: note:")]
    runs = [i for i, ln in enumerate(lines) if ln.startswith("  rblog ")]
    assert len(note) == 1 and runs and note[0] < runs[0], res.output  # one line, before any run
    text = lines[note[0]]
    assert EXTRA in text and "scipy" in text and "matplotlib" in text, text
    assert f"{len(needs_scipy)} of {len(PROBLEMS)} problems" in text, text
    # nothing is run that cannot be scored
    for i in runs:
        assert not any(f" {n} " in lines[i] for n in needs_scipy), lines[i]
    report = json.loads((tmp_path / "bench.json").read_text())
    rows = {r["problem"]: r for r in report["runs"]}
    for n in needs_scipy:
        assert rows[n]["status"] == "unavailable" and EXTRA in rows[n]["message"]
    assert rows["bouncing-ball"]["status"] == "ok"


def test_bench_with_everything_installed_prints_no_note(tmp_path):
    pytest.importorskip("scipy")
    pytest.importorskip("matplotlib")
    res = CliRunner().invoke(main, ["bench", "--no-peers", "--problem", "bouncing-ball",
                                    "--integrator", "rk4", "--dt", "0.02", "--out", str(tmp_path)])
    assert res.exit_code == 0, (res.output, res.exception)
    assert "rblog: note:" not in res.output


def test_stress_says_the_plot_needs_the_extra_before_it_runs(tmp_path, without_bench_extra):
    res = CliRunner().invoke(main, ["stress", "--quick", "--case", "spin", "--integrator",
                                    "rk4", "--out", str(tmp_path), "--progress"])
    assert res.exit_code == 0, (res.output, res.exception)
    lines = res.output.splitlines()
    assert lines[0].startswith("rblog: note: matplotlib is not installed") and EXTRA in lines[0]


@pytest.mark.parametrize("engine, module", [("mujoco", "mujoco"), ("pybullet", "pybullet")])
def test_missing_engine_names_the_checkout_install(monkeypatch, engine, module):
    """`rblog run --engine` without the engine: one line, exit 2, the extra as a user of a
    checkout types it (`pip install 'rblog[engines]'` installs rblog from PyPI instead)."""
    for mod in list(sys.modules):
        if mod.split(".")[0] == module:
            monkeypatch.delitem(sys.modules, mod)
    monkeypatch.setitem(sys.modules, module, None)
    from conftest import SAMPLES_DIR

    res = CliRunner().invoke(main, ["run", str(SAMPLES_DIR / "bouncing_ball.toml"), "--engine",
                                    engine, "--no-log"])
    assert res.exit_code == 2, (res.output, res.exception)
    assert len(res.stderr.strip().splitlines()) == 1, res.stderr
    assert 'pip install -e ".[engines]"' in res.stderr, res.stderr
