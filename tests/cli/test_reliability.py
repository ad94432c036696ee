"""Every fault and bad input of docs/reliability.md, tried: what rblog says, its exit code, what is
kept. The table in docs/reliability.md is rendered from FAULTS below and compared here, so it stays
true (regenerate it with ``RBLOG_WRITE_DOCS=1 python -m pytest tests/cli/test_reliability.py``).

Each row failed on the code before this change (traceback, silence, or exit 0).
"""

from __future__ import annotations

import os
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
from click.testing import CliRunner

import rblog
from rblog_cli.main import main

from conftest import REPO, SAMPLES_DIR

DOC = REPO / "docs" / "reliability.md"
BEGIN, END = "<!-- faults:begin -->", "<!-- faults:end -->"

FREE = """
[sim]
dt = 1e-3
duration = 0.2
[[body]]
name = "ball"
shape = "sphere"
radius = 0.1
mass = 1.0
"""


@dataclass
class Fault:
    id: str
    what: str          # the fault or bad input, as a user would do it
    files: dict        # name -> text, written to a fresh folder (the cwd of the run)
    argv: list         # the rblog command line
    code: int          # expected exit code
    says: str          # a fragment the one-line message (or warning) must hold
    kept: str          # what is kept (logs, files), for the table


def _scene(extra: str = "", base: str = FREE) -> str:
    return base + extra


FAULTS = [
    Fault("dt-tiny", "`dt = 1e-300`", {"s.toml": FREE.replace("dt = 1e-3", "dt = 1e-300")},
          ["run", "s.toml", "--no-log"], 2, "sim.dt: dt = 1e-300 s makes 2e+299 steps",
          "nothing written"),
    Fault("dt-option-tiny", "`--dt 1e-300`", {"s.toml": FREE},
          ["run", "s.toml", "--no-log", "--dt", "1e-300"], 2, "--dt: dt = 1e-300 s makes",
          "nothing written"),
    Fault("dt-gt-duration", "`dt` larger than `duration`",
          {"s.toml": FREE.replace("dt = 1e-3", "dt = 0.5")}, ["validate", "s.toml"], 2,
          "sim.dt: dt = 0.5 s is longer than the duration 0.2 s", "nothing written"),
    Fault("quat-norm", "a quaternion of norm 1.3",
          {"s.toml": _scene('quat_wxyz = [1.3, 0.0, 0.0, 0.0]\n')}, ["validate", "s.toml"], 0,
          "|q| = 1.3, not 1 (off by more than 1e-06); normalised", "runs (warning)"),
    Fault("overlap", "bodies that start overlapping (box sunk 10 mm into the ground, a sphere "
          "90 mm into the box)",
          {"s.toml": "[sim]\ndt = 1e-3\nduration = 0.05\n[ground]\n[[body]]\nname = \"a\"\n"
           "shape = \"box\"\nhalf_extents = [0.5, 0.5, 0.5]\nmass = 1.0\nposition = [0, 0, 0.49]\n"
           "[[body]]\nname = \"b\"\nshape = \"sphere\"\nradius = 0.2\nmass = 1.0\n"
           "position = [0, 0, 1.1]\n"},
          ["run", "s.toml", "--no-log"], 0,
          "2 pair(s) of shapes start overlapping: 'a' and 'b' by 90 mm, 'a' and the ground by 10 mm",
          "runs (warning)"),
    Fault("unknown-key", "a misspelt key (`duraton`)",
          {"s.toml": FREE.replace("duration = 0.2", "duration = 0.2\nduraton = 1")},
          ["validate", "s.toml"], 2, "sim.duraton: unknown key (did you mean 'duration'?",
          "nothing written"),
    Fault("contact-range", "`[contact] over_relaxation = 3`",
          {"s.toml": _scene("[contact]\nover_relaxation = 3.0\n")}, ["validate", "s.toml"], 2,
          "contact.over_relaxation: expected a number in (0, 2), got 3.0", "nothing written"),
    Fault("generator-huge", "a generator asking for 10^8 bodies",
          {"s.toml": FREE.split("[[body]]")[0] + '[[generator]]\nlayout = "random"\n'
           'count = 100000000\nregion_min = [0, 0, 0]\nregion_max = [1, 1, 1]\n'
           'body = { shape = "sphere", radius = 0.1, mass = 1.0 }\n'},
          ["validate", "s.toml"], 2, "generator[0].count: 100,000,000 bodies need about 200 GB",
          "nothing written"),
    Fault("same-path", "`--rrd X --mcap X`", {"s.toml": FREE},
          ["run", "s.toml", "--rrd", "x.log", "--mcap", "x.log"], 2,
          "--rrd and --mcap name the same file 'x.log'", "nothing written"),
    Fault("unwritable-output", "an output in a folder that does not exist", {"s.toml": FREE},
          ["run", "s.toml", "--rrd", "missing/x.rrd"], 2, "missing/x.rrd: cannot write log: folder",
          "nothing written; "
          "checked before the run starts"),
    Fault("dead-port", "`--connect` to a port nobody listens at", {"s.toml": FREE},
          ["run", "s.toml", "--no-log", "--connect", "rerun+http://127.0.0.1:9/proxy"], 2,
          "no Rerun viewer listens at 127.0.0.1:9", "nothing written"),
    Fault("explain", "`--explain`", {"s.toml": FREE}, ["run", "s.toml", "--explain"], 0,
          "integrate", "prints the plan, runs nothing (add `--run` to run)"),
    Fault("run-without-explain", "`--run` without `--explain`", {"s.toml": FREE},
          ["run", "s.toml", "--run"], 2, "--run goes with --explain", "nothing written"),
    Fault("torque-1e40", "a torque of 1e40 N m on a box resting on the ground",
          {"s.toml": "[sim]\ndt = 1e-3\nduration = 1.5\n[ground]\n[[body]]\nshape = \"box\"\n"
           "half_extents = [0.5, 0.5, 0.5]\nmass = 1.0\nposition = [0, 0, 0.5]\n"
           "torque = [1e40, 0, 0]\n"},
          ["run", "s.toml", "--mcap", "x.mcap"], 3,
          "diverged at step 1 (t = 0.001 s): body 0 ('body0') turns",
          "the .mcap up to the step before, its status \"simulation diverged at step N\"; the "
          "contact step applies the same bound (before: ran to the end with an energy drift, "
          "exit 0)"),
    Fault("torque-1e40-free", "a torque of 1e40 N m on a free body (0.1 m sphere, 1 kg)",
          {"s.toml": "[sim]\ndt = 1e-3\nduration = 1.0\ngravity = [0, 0, 0]\n[[body]]\n"
           "shape = \"sphere\"\nradius = 0.1\nmass = 1.0\ntorque = [1e40, 0, 0]\n"},
          ["run", "s.toml", "--mcap", "x.mcap"], 3,
          "diverged at step 1 (t = 0.001 s): body 0 ('body0') turns 2.5e+36 rad in one step",
          "the .mcap up to the step before, its status \"simulation diverged at step N\"; the "
          "bound is MAX_ROTATION_PER_STEP_RAD = 1e6 rad (before: ran on silently, exit 0)"),
    Fault("check-one-sample", "`rblog check` on a log of one sample", {"s.toml": FREE},
          ["check", "one.mcap"], 4, "not judged: 1 sample(s)", "exit 4: never reported clean"),
]

#: rows tried by tests/cli/test_signals.py (real processes), listed in the same table
SIGNAL_ROWS = [
    ("SIGINT (Ctrl-C) during a contact run", "`run interrupted at step N (t = ...) by SIGINT`",
     130, "both logs closed, every sample to step N, status \"interrupted\"; answered within 0.5 s"),
    ("SIGTERM during a contact run", "`run interrupted at step N (t = ...) by SIGTERM`", 143,
     "same as SIGINT"),
    ("SIGKILL during the pile", "(none: the process is killed)", -9,
     "both logs readable, samples handed to the writers more than ~1 s before the kill"),
    ("every cache and temporary folder read-only (read-only mounts of /tmp, /var/tmp, the "
     "package folder, HOME and the working folder)", "(none)", 0,
     "`--version` and `run` work and write both logs: nothing is compiled or cached at run time, "
     "the core was compiled when rblog was installed (test_read_only_everywhere_*)"),
    (".rrd cut at 50%", "`log ends early ... read N samples` (warning)", 0,
     "every intact sample (342 of 401 on bouncing_ball)"),
]


#: rows tried by other tests, named in the row
OTHER_ROWS = [
    ("`rblog run SCENE --spawn`", "(none)", 0,
     "a viewer is started (the `rerun` on PATH or beside the Python) on port 9876 and the run "
     "streams to it; if none starts within 5 s: `--spawn: the Rerun viewer did not start`, exit "
     "2 (test_spawn_starts_the_viewer_and_streams_to_it; before: nothing opened, exit 0)"),
    ("`seed-quat` with `orthonormalize = \"none\"`",
     "(no message: the stretch is the point) `max \\|\\|R^T R - I\\|\\|_F` in the summary grows as "
     "sqrt(3) (\\|q\\|^4 - 1)", 0,
     "R = \\|q\\|^2 Q logged (the notes' stretch); omega = (R I_body R^T)^-1 L = \\|q\\|^-4 times "
     "the rigid value, in the engine and the log (before: \\|q\\|^4 times, a runaway that went "
     "non-finite at step 1121 of tests/engine/test_seed_quat_stretch.py's isotropic case)"),
    ("the same scene run with RBLOG_THREADS=1 and =2 (a 3,200-body free scene, a contact "
     "scene), every sample with `--threads 1`, `2` and `4`, and twice in separate processes",
     "(none)", 0,
     "byte-identical .mcap records and bit-identical .rrd samples "
     "(tests/cli/test_thread_determinism.py); the .mcap file bytes may differ only where a chunk "
     "was closed on wall time"),
]


def _invoke(tmp_path, fault: Fault):
    for name, text in fault.files.items():
        (tmp_path / name).write_text(text)
    if fault.id == "check-one-sample":
        from rblog.engine.runner import simulate
        from rblog.engine.scene import parse_scene
        from rblog.record.mcap_writer import McapRecorder

        traj, _ = simulate(parse_scene(FREE, str(tmp_path / "s.toml")))
        rec = McapRecorder(str(tmp_path / "one.mcap"))
        rec.open(traj.model, traj.info)
        rec.write(traj.slice(slice(0, 1)))  # a run stopped right after its first sample
        rec.close(truncated=True, reason="stopped")
    old = os.getcwd()
    os.chdir(tmp_path)
    try:
        return CliRunner().invoke(main, fault.argv)
    finally:
        os.chdir(old)


@pytest.mark.parametrize("fault", FAULTS, ids=[f.id for f in FAULTS])
def test_fault_answered(tmp_path, fault):
    res = _invoke(tmp_path, fault)
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        raise res.exception  # a traceback: the thing this test exists to catch
    assert res.exit_code == fault.code, (res.stdout, res.stderr)
    assert "Traceback" not in res.stderr
    assert fault.says in res.stdout + res.stderr, res.stderr
    if fault.code == 2:
        err = [ln for ln in res.stderr.splitlines() if ln.strip()]
        assert len(err) == 1, err
    if fault.id in ("explain",):
        assert "steps x" not in res.stdout  # did not run
        assert not list(tmp_path.glob("*.rrd")) and not list(tmp_path.glob("*.mcap"))
    if fault.code == 2:
        assert not list(tmp_path.glob("*.rrd")) and not list(tmp_path.glob("*.mcap"))


def test_unwritable_output_is_reported_before_compiling(tmp_path, monkeypatch):
    """The output check runs before the kernels load: the run loop is never entered."""
    import rblog.engine.runner as runner

    def boom(*a, **k):
        raise AssertionError("the run started before the output path was checked")

    monkeypatch.setattr(runner, "run", boom)
    (tmp_path / "s.toml").write_text(FREE)
    res = CliRunner().invoke(main, ["run", str(tmp_path / "s.toml"), "--mcap",
                                    str(tmp_path / "nope" / "x.mcap")])
    assert res.exit_code == 2 and "does not exist" in res.stderr


FAKE_VIEWER = """#!{python}
# stands in for the `rerun` viewer executable: records its argv and the first bytes sent to
# the port it was asked to listen on (a gRPC client opens with the HTTP/2 preface)
import socket, sys, time
a = sys.argv
port = int(next(x.split("=", 1)[1] if "=" in x else a[k + 1]
                for k, x in enumerate(a) if x.startswith("--port")))
srv = socket.socket()
srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
srv.bind(("127.0.0.1", port))
srv.listen(8)
srv.settimeout(1.0)
got = b""
deadline = time.monotonic() + 30
while b"PRI * HTTP/2.0" not in got and time.monotonic() < deadline:
    try:
        conn, _ = srv.accept()
    except OSError:
        continue
    conn.settimeout(5.0)
    try:
        got += conn.recv(64)
    except OSError:
        pass
with open({out!r}, "w") as f:
    f.write(" ".join(sys.argv[1:]) + "\\n" + repr(got[:24]))
"""


def test_spawn_starts_the_viewer_and_streams_to_it(tmp_path, monkeypatch):
    """`--spawn` launches the viewer executable found on PATH with the spawn port and streams the
    run to it (before: rr.spawn() without a global recording was silently ignored and no viewer
    ever started). A stand-in viewer records what it was started with and what it received."""
    import socket
    import time

    import rblog.record.rerun_writer as rw

    with socket.socket() as s:  # a free port, so a real viewer on 9876 cannot answer for it
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    monkeypatch.setattr(rw, "SPAWN_PORT", port)
    bin_dir, out = tmp_path / "bin", tmp_path / "viewer.txt"
    bin_dir.mkdir()
    fake = bin_dir / "rerun"
    fake.write_text(FAKE_VIEWER.format(python=sys.executable, out=str(out)))
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
    (tmp_path / "s.toml").write_text(FREE)
    res = CliRunner().invoke(main, ["run", str(tmp_path / "s.toml"), "--no-log", "--spawn"])
    assert res.exit_code == 0, res.stderr
    deadline = time.monotonic() + 40
    while not out.exists() and time.monotonic() < deadline:
        time.sleep(0.2)
    argv, received = out.read_text().splitlines()
    assert f"--port {port}" in argv or f"--port={port}" in argv, argv
    assert "PRI * HTTP/2.0" in received  # the run's gRPC stream reached the spawned viewer


def test_cut_rrd_recovers_intact_samples(tmp_path):
    """An .rrd cut at 50% reads back every intact sample and says so (before: 1 of 401)."""
    from rblog.engine.runner import run as run_scene
    from rblog.engine.scene import load_scene
    from rblog.record.rerun_writer import RerunRecorder

    path = tmp_path / "bb.rrd"
    run_scene(load_scene(SAMPLES_DIR / "bouncing_ball.toml"), recorders=[RerunRecorder(str(path))])
    data = path.read_bytes()
    cut = tmp_path / "cut.rrd"
    cut.write_bytes(data[: len(data) // 2])
    traj = rblog.load(cut)
    assert traj.truncated
    # the file's samples are spread about evenly over its bytes: half the file holds ~200 of
    # 401 samples; measured 342 (static data sits at the front)
    assert traj.n_samples >= 150
    assert any(f"read {traj.n_samples} samples" in w for w in traj.warnings), traj.warnings


#: runs argv with every cache and temporary folder unwritable, as root: in a private mount
#: namespace (unshare -m) /tmp, /var/tmp and rblog's package folder are remounted read-only, HOME
#: points into the read-only /tmp, the cwd is read-only (tempfile's last resort); only OUT (bound
#: before /tmp went read-only) stays writable. Mounts end with the namespace.
_NO_CACHE_ANYWHERE = """
mount --bind "$OUT" "$OUT" || exit 90
for d in /tmp /var/tmp; do
    [ -d $d ] || continue
    mount --rbind $d $d && mount -o remount,bind,ro $d || exit 91
done
mount --bind "$PKG" "$PKG" && mount -o remount,bind,ro "$PKG" || exit 92
touch "$PKG/x" 2>/dev/null && exit 93
cd "$RO_CWD" || exit 94
exec env -u XDG_CACHE_HOME -u TMPDIR -u TEMP -u TMP HOME="$RO_CWD/home" "$@"
"""


def _read_only_everywhere(tmp_path, argv):
    import subprocess
    import sys

    if os.geteuid() != 0 or not shutil.which("unshare"):
        pytest.skip("needs root and unshare to make every cache folder read-only")
    out = tmp_path / "out"
    out.mkdir()
    (tmp_path / "s.toml").write_text(FREE)
    env = {**os.environ, "OUT": str(out),
           "PKG": str(Path(rblog.__file__).resolve().parent), "RO_CWD": str(tmp_path)}
    rblog_exe = str(Path(sys.executable).with_name("rblog"))
    p = subprocess.run(["unshare", "-m", "sh", "-c", _NO_CACHE_ANYWHERE, "sh", rblog_exe, *argv],
                       env=env, capture_output=True, text=True, timeout=900)
    if p.returncode in range(90, 95):
        pytest.skip(f"cannot set up read-only mounts here (step {p.returncode}): {p.stderr}")
    return p, out


def _quiet(stderr):
    """Nothing to warn about: no cache is looked for."""
    assert "Traceback" not in stderr and "warning" not in stderr, stderr


def test_read_only_everywhere_version(tmp_path):
    """Every cache and temporary folder read-only: `--version` answers, with no warning."""
    p, _ = _read_only_everywhere(tmp_path, ["--version"])
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith("rblog, version")
    _quiet(p.stderr)


def test_read_only_everywhere_run(tmp_path):
    """As above, `rblog run` runs and writes both logs (OUT stays writable)."""
    import rblog as rb

    out = tmp_path / "out"
    p, out = _read_only_everywhere(tmp_path, ["run", str(tmp_path / "s.toml"), "--mcap",
                                              str(out / "x.mcap"), "--rrd", str(out / "x.rrd")])
    assert p.returncode == 0, p.stderr
    _quiet(p.stderr)
    for name in ("x.mcap", "x.rrd"):
        traj = rb.load(out / name)
        assert traj.n_samples == 21 and not traj.truncated  # 0.2 s logged at 100 Hz


def _table() -> str:
    rows = ["| Fault or bad input | What rblog says | Exit code | What is kept |",
            "|---|---|---|---|"]
    for f in FAULTS:
        says = f.says.replace("|", "\\|")
        rows.append(f"| {f.what} | `{says}` | {f.code} | {f.kept} |")
    for what, says, code, kept in SIGNAL_ROWS + OTHER_ROWS:
        rows.append(f"| {what} | {says} | {code if code >= 0 else 'killed'} | {kept} |")
    return "\n".join(rows)


def test_reliability_doc_table_is_current():
    text = DOC.read_text()
    table = _table()
    if os.environ.get("RBLOG_WRITE_DOCS"):
        head, _, rest = text.partition(BEGIN)
        _, _, tail = rest.partition(END)
        DOC.write_text(f"{head}{BEGIN}\n{table}\n{END}{tail}")
        text = DOC.read_text()
    assert f"{BEGIN}\n{table}\n{END}" in text, (
        "docs/reliability.md is out of date: RBLOG_WRITE_DOCS=1 python -m pytest "
        "tests/cli/test_reliability.py")
