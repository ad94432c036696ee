"""Output that reads at a glance: `rblog check`'s verdict line per log and the quantity and
tolerance of each line, the many-log summary, `rblog findings`, the commands printed after
`rblog run`, and `--json`'s status.

Each test fails on the output these replaced: no verdict line; "worst -0.0941 (tol 1)" for
energy; "worst 0 m (tol 0 m)" for tunneling; a penetration tolerance that changed with the
sub-check without saying which; interrupted logs counted as clean; `rblog findings` printing only
a count; `rerun X.rrd` printed where `rerun` is not on PATH; nothing on stdout for
`--json --fail-fast`.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

import rblog
from rblog.analyze import ANALYZERS
from rblog.engine.runner import simulate
from rblog.engine.scene import load_scene
from rblog.record import McapRecorder
from rblog_cli.main import main

from conftest import REPO, SAMPLES_DIR

RBLOG = str(Path(sys.executable).with_name("rblog"))
#: the notes' scheme without orthonormalization: R stretches from the first step (drift flags it)
STRETCH = ["--integrator", "seed", "--orthonormalize", "none", "--duration", "2"]


def _cli(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """box_stack (clean; every contact takes energy, so the energy gain is negative everywhere),
    the stretching tumbling box (flagged), and bouncing_ball cut short as an interrupted run."""
    d = tmp_path_factory.mktemp("glance")
    out = {}
    r = _cli("run", SAMPLES_DIR / "box_stack.toml", "--mcap", d / "stack.mcap", "--rrd",
             d / "stack.rrd")
    assert r.exit_code == 0, r.output
    out["clean"] = d / "stack.mcap"
    r = _cli("run", SAMPLES_DIR / "tumbling_box.toml", *STRETCH, "--mcap", d / "stretch.mcap",
             "--rrd", d / "stretch.rrd")
    assert r.exit_code == 0, r.output
    out["flagged"] = d / "stretch.mcap"
    traj, _ = simulate(load_scene(str(SAMPLES_DIR / "bouncing_ball.toml")), duration=1.0)
    rec = McapRecorder(str(d / "cut.mcap"))
    rec.open(traj.model, traj.info)
    rec.write(traj)
    rec.close(truncated=True, reason="interrupted (SIGINT) at step 1000")
    out["truncated"] = d / "cut.mcap"
    return out


def _report(path):
    r = _cli("check", path)
    doc = json.loads(_cli("check", path, "--json").output)["logs"][0]
    return r, doc


def _analyzer_lines(output):
    return {m.group(2): m.group(0) for m in
            re.finditer(r"^  (pass|FAIL|skip|----) (\w+) .*$", output, re.M)}


def test_one_verdict_line_per_log(logs):
    r, _ = _report(logs["clean"])
    assert r.exit_code == 0
    assert r.output.splitlines()[-1] == "  verdict: clean"
    r, doc = _report(logs["flagged"])
    assert r.exit_code == 1
    n = sum(int(x["stats"].get("findings", 0)) for x in doc["results"])
    assert n >= 1
    assert r.output.splitlines()[-1].startswith(f"  verdict: flagged: {n} finding")


def test_each_line_shows_its_own_quantity_and_tolerance(logs):
    """The analyzer line names the quantity nearest its tolerance and shows that quantity's own
    tolerance (penetration judges depth at rest, at any time, jitter and creep, each against
    another limit); no negative "worst", no "tol 0"."""
    r, doc = _report(logs["clean"])
    lines = _analyzer_lines(r.output)
    assert set(lines) == set(ANALYZERS)
    for res in doc["results"]:
        line = lines[res["analyzer"]]
        assert not re.search(r"(worst|:) -\d", line), line
        assert "tol 0 " not in line and not line.endswith("tol 0)"), line
        if res["verdict"] == "pass" and res["worst_what"] and res["worst_value"] > 0:
            u = "" if res["unit"] in ("", "1") else f" {res['unit']}"
            assert f"{res['worst_what']} {res['worst_value']:.3g}{u} (tol " \
                   f"{res['tolerance']:.3g}{u})" in line, line
    pen = next(x for x in doc["results"] if x["analyzer"] == "penetration")
    assert pen["worst_what"] and pen["worst_what"] in lines["penetration"]
    # box_stack: contacts only take energy, the largest gain across a contact is below zero
    energy = next(x for x in doc["results"] if x["analyzer"] == "energy")
    assert energy["worst_value"] < 0 and "none above 0" in lines["energy"]


def test_findings_listed_with_their_own_value_and_tolerance(logs):
    r, doc = _report(logs["flagged"])
    findings = [f for x in doc["results"] for f in x["findings"]]
    for f in findings:
        u = "" if f["unit"] in ("", "1") else f" {f['unit']}"
        assert f"t = {f['t']:.4g} s: {f['value']:.3g}{u} (tol {f['tolerance']:.3g}{u}): " \
               f"{f['message']}" in r.output
    out = _cli("findings", logs["flagged"], logs["flagged"].with_name("f.rrd"))
    assert out.exit_code == 1
    for f in findings:  # `rblog findings` lists them too, not only their count
        assert f["message"] in out.output


def test_many_log_summary_does_not_count_a_truncated_log_as_clean(logs):
    r = _cli("check", logs["clean"], logs["truncated"])
    assert r.exit_code == 0, r.output
    summary = [ln for ln in r.output.splitlines() if ln.startswith("2 logs:")][0]
    assert "1 clean" in summary and "1 truncated" in summary, summary
    assert "verdict: clean up to t = 1 s, where the log stops" in r.output


def test_readme_lists_every_analyzer_the_check_prints():
    text = (REPO / "README.md").read_text(encoding="utf-8")
    table = text.split("### What `rblog check` judges", 1)[1].split("\n\n", 2)[1]
    names = re.findall(r"^\| `(\w+)` \|", table, re.M)
    assert names == list(ANALYZERS)


def _path_without_venv():
    bindir = str(Path(sys.executable).parent)
    return os.pathsep.join(p for p in os.environ.get("PATH", "").split(os.pathsep)
                           if Path(p).resolve() != Path(bindir).resolve())


def test_run_prints_the_next_two_commands_that_work_as_printed(tmp_path):
    """With the venv not activated (its bin/ not on PATH), the printed commands name the
    programs by a path that exists, and the first one runs as printed."""
    env = {**os.environ, "PATH": _path_without_venv()}
    p = subprocess.run([RBLOG, "run", str(SAMPLES_DIR / "free_fall.toml")], cwd=tmp_path,
                       env=env, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    lines = p.stdout.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("next:"))
    check = shlex.split(lines[i].removeprefix("next:"))
    view = shlex.split(lines[i + 1])
    assert check[1:] == ["check", "free_fall.rrd"] and view[1:] == ["free_fall.rrd"]
    for prog in (check[0], view[0]):
        exe = Path(prog) if os.sep in prog else None
        assert exe is not None and (tmp_path / exe).exists() and os.access(tmp_path / exe, os.X_OK), prog
    assert Path(view[0]).name == "rerun"
    q = subprocess.run(check, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert q.returncode == 0 and q.stdout.splitlines()[-1] == "  verdict: clean", q.stdout


def test_json_always_prints_its_object_with_the_status(tmp_path):
    ok = _cli("run", SAMPLES_DIR / "free_fall.toml", "--no-log", "--json")
    assert ok.exit_code == 0 and json.loads(ok.stdout)["status"] == "ok"
    flagged = _cli("run", SAMPLES_DIR / "tumbling_box.toml", *STRETCH, "--no-log", "--json",
                   "--check")
    doc = json.loads(flagged.stdout)
    assert flagged.exit_code == 1 and doc["status"] == "flagged" and doc["check"]["flagged"]
    stopped = _cli("run", SAMPLES_DIR / "tumbling_box.toml", *STRETCH, "--mcap",
                   tmp_path / "s.mcap", "--json", "--fail-fast")
    doc = json.loads(stopped.stdout)
    assert stopped.exit_code == 1 and doc["status"] == "stopped" and doc["check"]["flagged"]
    assert doc["logs"] == [str(tmp_path / "s.mcap")]
    assert rblog.load(tmp_path / "s.mcap").truncated


def test_bench_names_the_peers_it_will_not_run(monkeypatch):
    """`rblog bench` says before it starts which peer engines are missing, as it does for scipy
    and matplotlib (before: MuJoCo and pybullet were skipped without a word)."""
    import rblog.study.bench as bench
    from rblog.errors import RblogError

    real = bench.module_missing
    monkeypatch.setattr(bench, "module_missing", lambda m: m == "pybullet" or real(m))

    def stop(**kw):
        raise RblogError("stopped by the test before running")

    monkeypatch.setattr(bench, "run_bench", stop)
    r = CliRunner().invoke(main, ["bench", "--quick"])
    assert "rblog: note: pybullet not installed: no peer runs of pybullet" in r.output, r.output
    assert 'pip install -e ".[engines]"' in r.output
