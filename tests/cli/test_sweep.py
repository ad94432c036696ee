"""`rblog sweep` from the command line (serial; the cluster runs are in tests/study/test_cluster.py):
the grid is the product of the --set lists, the table holds one row per variant with errors
against the exact motion, and malformed --set values are one-line errors with exit code 2."""

from __future__ import annotations

import csv
import json

import pytest
from click.testing import CliRunner

from rblog_cli.main import main

from conftest import SAMPLES_DIR

TUMBLING = str(SAMPLES_DIR / "tumbling_box.toml")


def sweep(*args):
    return CliRunner().invoke(main, ["sweep", TUMBLING, *map(str, args)])


def test_grid_table_and_plot(tmp_path):
    res = sweep("--set", "integrator=rk4,splitting", "--set", "dt=4e-3,2e-2", "--set", "duration=2",
                "--out", tmp_path, "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    grid = [(r["sim.integrator"], r["sim.dt"]) for r in doc["runs"]]
    assert grid == [("rk4", 4e-3), ("rk4", 2e-2), ("splitting", 4e-3), ("splitting", 2e-2)]
    rows = list(csv.DictReader((tmp_path / "sweep.csv").open()))
    assert len(rows) == 4 and all(r["check"] == "clean" for r in rows)
    err = {(r["integrator"], float(r["dt"])): float(r["angle_rad"]) for r in rows}
    # rk4 is 4th order: 5x the step, 5^4 = 625x the error (measured 595: 8.1e-13 -> 4.8e-10 rad;
    # smaller steps reach the 1e-13 floor of double rounding); splitting is 2nd order: 5^2 = 25x
    # (measured 25.0: 7.4e-7 -> 1.9e-5 rad)
    assert 450 < err[("rk4", 2e-2)] / err[("rk4", 4e-3)] < 800
    assert 22 < err[("splitting", 2e-2)] / err[("splitting", 4e-3)] < 28
    for r in rows:  # logs written by default, one per variant
        assert (tmp_path / "logs").joinpath(r["log"].rsplit("/", 1)[-1]).exists()
    assert (tmp_path / "sweep.png").stat().st_size > 0 and (tmp_path / "sweep.parquet").exists()


def test_random_sample_is_reproducible(tmp_path):
    args = ["--set", "integrator=rk4,splitting", "--set", "duration=0.5",
            "--set", "body[*].angular_velocity_body[0]=0.1:0.3", "--samples", "5", "--seed", "4",
            "--no-logs", "--json"]
    a = json.loads(sweep(*args, "--out", tmp_path / "a").stdout)["runs"]
    b = json.loads(sweep(*args, "--out", tmp_path / "b").stdout)["runs"]
    key = "body[0].angular_velocity_body[0]"
    assert [r[key] for r in a] == [r[key] for r in b]
    assert all(0.1 <= r[key] <= 0.3 for r in a) and len({r[key] for r in a}) == 5
    assert all(r["log"] is None for r in a)


@pytest.mark.parametrize("spec,words", [
    ("dt", ["--set dt", "KEY=V1,V2"]),
    ("dt=1e-3:x", ["LO:HI"]),
    ("body[3].mass=2", ["body[3].mass", "out of range"]),
    ("sim.dt=-1", ["variant 0", "sim.dt"]),
    ("body[0].mass=0.5:2", ["needs --samples"]),
])
def test_bad_set_is_one_line_exit_2(tmp_path, spec, words):
    res = sweep("--set", spec, "--out", tmp_path, "--no-logs")
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and all(w in lines[0] for w in words), lines
