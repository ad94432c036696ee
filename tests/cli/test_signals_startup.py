"""A signal at any moment of `rblog run`, start-up included: exit 128 + the signal's number, one
line on stderr, and every log that was written reads.

The moments (0.1, 0.3, 0.6 and 1.5 s after the process starts) fall, on a loaded 2-core machine,
in the interpreter's imports (click, numpy), the Rerun SDK's import (~1 s), the opening of the
logs and the first compiled calls; a moment that falls in CPython's own start-up, before rblog's
first statement, is moved to that statement (CPython answers a signal there itself). Before, a Ctrl-C there printed click's ``Aborted!`` and exited
1, and a SIGTERM exited without a word.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import rblog

from conftest import SAMPLES_DIR

RBLOG = str(Path(sys.executable).with_name("rblog"))
#: a free sample and a contact sample, run long enough that every moment falls inside the run:
#: 1e5 s is ~50 s of stepping for tumbling_box (2.3e6 steps/s unloaded), so 1.5 s is never in
#: the interpreter's teardown after the run (2000 s was 0.87 s of stepping: a SIGINT there met
#: CPython's finalization, which restores SIG_DFL, and killed the process with -2 and no word)
SAMPLES = ("tumbling_box", "bouncing_ball")
DURATION_S = "1e5"
#: 10 samples per simulated second keeps the logs written before the signal small
LOG_RATE = "10"


def _rblog_has_started(pid: int) -> bool:
    """Whether the process runs rblog's code yet: rblog_cli's first statement catches SIGTERM
    (bit 15 of /proc/PID/status's SigCgt), which CPython alone never does. Before that the process
    is CPython starting up (its site import: ~0.1 s at load 12 on 2 cores), where a SIGINT ends in
    CPython's own "Fatal Python error: init_import_site", not a moment rblog can answer."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return True  # no /proc, or the process is gone: the caller's poll() says which
    caught = next(int(ln.split()[1], 16) for ln in status.splitlines() if ln.startswith("SigCgt:"))
    return bool(caught & (1 << (signal.SIGTERM - 1)))


def _interrupt(tmp_path: Path, sample: str, sig: int, after_s: float):
    rrd, mcap = tmp_path / f"{sample}.rrd", tmp_path / f"{sample}.mcap"
    p = subprocess.Popen([RBLOG, "run", str(SAMPLES_DIR / f"{sample}.toml"), "--duration",
                          DURATION_S, "--log-rate", LOG_RATE, "--rrd", str(rrd), "--mcap", str(mcap)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(after_s)
    deadline = time.monotonic() + 30.0
    while not _rblog_has_started(p.pid) and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)  # a loaded machine: the moment is after_s or rblog's first, the later
    running = p.poll() is None
    p.send_signal(sig)
    try:
        out, err = p.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        p.kill()
        out, err = p.communicate()
        pytest.fail(f"still running 60 s after {signal.Signals(sig).name}: {err[-400:]}")
    assert running, f"the run ended before the signal: {err[-400:]}"
    return p.returncode, err, [q for q in (rrd, mcap) if q.exists()]


def _assert_answered(code, err, logs, sig):
    name = signal.Signals(sig).name
    assert code == 128 + sig, (code, err)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert "Aborted" not in err and "Traceback" not in err, err
    assert name in lines[0], lines[0]
    for path in logs:  # a log that was written reads, up to where the run stopped
        traj = rblog.load(path)
        assert traj.n_samples >= 1, path


def test_sigint_during_the_imports_is_one_line(tmp_path):
    """The earliest moment, in the default run (the full grid is below, marked slow)."""
    code, err, logs = _interrupt(tmp_path, "tumbling_box", signal.SIGINT, 0.1)
    _assert_answered(code, err, logs, signal.SIGINT)


@pytest.mark.slow
@pytest.mark.parametrize("after_s", [0.1, 0.3, 0.6, 1.5])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("sample", SAMPLES)
def test_signal_at_any_moment(tmp_path, sample, sig, after_s):
    code, err, logs = _interrupt(tmp_path, sample, sig, after_s)
    _assert_answered(code, err, logs, sig)
