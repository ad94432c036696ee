"""`rblog check` on many logs: every log is judged (an unreadable one does not stop the batch),
`--json` holds one entry per log in the order given, the exit code is the worst over the logs, and
directories, glob patterns and list files name the logs. Serial (in this process): the cluster
runs are in tests/study/test_cluster.py."""

from __future__ import annotations

import csv
import json

import pytest
from click.testing import CliRunner

import rblog
from rblog.record import McapRecorder
from rblog_cli.main import main

from conftest import SAMPLES_DIR


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """A clean log (rk4 on the tumbling box: energy drift 1e-13, tol 1e-3), a flagged one (the
    notes' first-order scheme at dt = 1e-2 gains 11.7% energy, tol 0.1%) and a file that is no
    log."""
    d = tmp_path_factory.mktemp("many")
    scene = rblog.load_scene(SAMPLES_DIR / "tumbling_box.toml")
    clean, flagged = d / "clean.mcap", d / "flagged.mcap"
    rblog.run(scene, duration=2.0, recorders=[McapRecorder(str(clean))])
    rblog.run(scene, integrator="seed", dt=1e-2, recorders=[McapRecorder(str(flagged))])
    bad = d / "garbage.mcap"
    bad.write_bytes(b"this is not a log at all")
    return {"clean": str(clean), "flagged": str(flagged), "bad": str(bad), "dir": d}


def run_check(*args):
    return CliRunner().invoke(main, ["check", *map(str, args)])


def test_an_unreadable_log_does_not_stop_the_batch(logs):
    # before: the first unreadable file ended the command (exit 2, nothing on stdout with --json)
    res = run_check("--json", logs["clean"], logs["bad"], logs["flagged"])
    assert res.exit_code == 2  # the worst of clean (0), flagged (1), unreadable (2)
    doc = json.loads(res.stdout)
    assert [e["log"] for e in doc["logs"]] == [logs["clean"], logs["bad"], logs["flagged"]]
    assert [e["status"] for e in doc["logs"]] == ["clean", "unreadable", "flagged"]
    assert logs["bad"] in doc["logs"][1]["error"]
    assert doc["passed"] is False
    flagged = {r["analyzer"] for r in doc["logs"][2]["results"] if not r["passed"] and not r["skipped"]}
    assert flagged == {"energy"}
    # the unreadable file is named on stderr, on one line
    errors = [ln for ln in res.stderr.splitlines() if ln.startswith("rblog: error:")]
    assert len(errors) == 1 and logs["bad"] in errors[0]


def test_missing_file_among_good_ones_is_reported_and_the_rest_checked(logs, tmp_path):
    missing = tmp_path / "nope.rrd"
    res = run_check(logs["clean"], missing)
    assert res.exit_code == 2
    assert f"{logs['clean']}: " in res.stdout  # the good log's report was printed
    assert str(missing) in res.stderr and "no such file" in res.stderr


@pytest.mark.parametrize("names,code", [(("clean",), 0), (("clean", "flagged"), 1),
                                        (("flagged", "bad"), 2), (("bad", "clean"), 2)])
def test_exit_code_is_the_worst_over_the_logs(logs, names, code):
    res = run_check(*[logs[n] for n in names])
    assert res.exit_code == code, res.output


def test_directory_glob_and_list_file_name_the_logs(logs, tmp_path):
    d = logs["dir"]
    expect = sorted(str(p) for p in d.glob("*.mcap"))
    by_dir = json.loads(run_check("--json", d).stdout)
    assert [e["log"] for e in by_dir["logs"]] == expect
    by_glob = json.loads(run_check("--json", d / "*.mcap").stdout)
    assert [e["log"] for e in by_glob["logs"]] == expect
    lst = tmp_path / "logs.txt"
    lst.write_text(f"# two logs\n{logs['flagged']}\n\n{logs['clean']}\n")
    by_list = json.loads(run_check("--json", lst).stdout)
    assert [e["log"] for e in by_list["logs"]] == [logs["flagged"], logs["clean"]]


def test_empty_directory_and_unmatched_pattern_are_one_line_errors(tmp_path):
    for arg in (tmp_path, tmp_path / "*.rrd"):
        res = run_check(arg)
        assert res.exit_code == 2
        assert len(res.stderr.strip().splitlines()) == 1 and str(arg) in res.stderr


def test_summary_and_per_log_table(logs, tmp_path):
    table = tmp_path / "t.csv"
    res = run_check("--table", table, logs["clean"], logs["flagged"], logs["bad"])
    assert res.exit_code == 2
    assert "3 logs: 1 clean, 1 flagged, 1 unreadable" in res.stdout
    rows = list(csv.DictReader(table.open()))
    assert [(r["log"], r["status"]) for r in rows] == [
        (logs["clean"], "clean"), (logs["flagged"], "flagged"), (logs["bad"], "unreadable")]
    assert rows[1]["energy"] == "FAIL" and float(rows[1]["energy_worst"]) > float(rows[1]["energy_tol"])
    assert rows[0]["energy"] == "pass" and float(rows[0]["energy_worst"]) < float(rows[0]["energy_tol"])
    pq = pytest.importorskip("pyarrow.parquet")
    run_check("--table", tmp_path / "t.parquet", logs["clean"], logs["flagged"])
    t = pq.read_table(tmp_path / "t.parquet").to_pylist()
    assert [r["status"] for r in t] == ["clean", "flagged"]


def test_workers_without_dask_names_the_extra(logs, monkeypatch):
    import rblog.study.cluster as cluster

    monkeypatch.setattr(cluster, "dask_available", lambda: False)
    res = run_check("--workers", "2", logs["clean"])
    assert res.exit_code == 2
    assert "--workers" in res.stderr and '".[cluster]"' in res.stderr
    # without workers, the same check runs in this process
    assert run_check(logs["clean"]).exit_code == 0
