"""Interrupted runs: Ctrl-C / SIGTERM answered fast with one line, exit 128 + signal and logs closed
"interrupted"; SIGKILL leaves logs readable and loses at most ~1 s of wall time.

Each test starts a real `rblog run` of the 500-box pile (the scene whose compiled blocks used to
run for seconds), so it fails on the code this replaced (88-line traceback, exit 1, status
"failed", up to ~5 s to react; an unreadable .mcap after a kill).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import rblog
from rblog.contract.trajectory import RunInfo
from rblog.engine.runner import run as run_scene
from rblog.engine.scene import load_scene
from rblog.engine import constants as runner_constants
from rblog.record import mcap_writer
from rblog.record.mcap_writer import McapRecorder

from conftest import SAMPLES_DIR

RBLOG = str(Path(sys.executable).with_name("rblog"))
PILE = str(SAMPLES_DIR / "pile.toml")
#: wanted by the issue: a signal is answered (process gone, logs closed) within this (s, wall).
#: Measured 0.05-0.06 s from signal to exit on a shared 2-core machine: the run loop sees the flag
#: within one CALL_WALL_BUDGET_S = 0.03 s call, the message follows 0.02-0.05 s after the signal,
#: and the process then exits without the interpreter's teardown (0.5-0.65 s before, mostly the
#: Rerun SDK's exit hooks).
REACT_MAX_S = 0.5
#: most wall time a SIGKILL may lose (s): a call's samples reach the writers at once, and the
#: writers flush every FLUSH_EVERY_S = 0.5 s
KILL_LOSS_MAX_S = 1.0


def _start_pile(tmp_path, duration=30.0):
    rrd, mcap = tmp_path / "p.rrd", tmp_path / "p.mcap"
    p = subprocess.Popen([RBLOG, "run", PILE, "--duration", str(duration), "--rrd", str(rrd),
                          "--mcap", str(mcap)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True)
    return p, rrd, mcap


def _wait_stepping(p, mcap: Path, tmp_path, timeout=120.0) -> None:
    """Wait until the run has logged samples past t = 0 (kernels compiled, stepping under way)."""
    t0 = time.monotonic()
    snap = tmp_path / "snap.mcap"
    while time.monotonic() - t0 < timeout:
        assert p.poll() is None, p.communicate()
        if mcap.exists() and mcap.stat().st_size > 0:
            shutil.copyfile(mcap, snap)
            try:
                if rblog.load(snap).n_samples >= 2:
                    return
            except rblog.RblogError:
                pass
        time.sleep(0.2)
    p.kill()
    pytest.fail("the pile never started stepping")


@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)],
                         ids=["SIGINT", "SIGTERM"])
def test_signal_during_contact_run(tmp_path, sig, code):
    p, rrd, mcap = _start_pile(tmp_path)
    _wait_stepping(p, mcap, tmp_path)
    time.sleep(0.5)
    t0 = time.perf_counter()
    p.send_signal(sig)
    out, err = p.communicate(timeout=30)
    react = time.perf_counter() - t0
    assert p.returncode == code, err
    lines = [ln for ln in err.splitlines() if ln.strip() and "compiling kernels" not in ln]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert "interrupted at step" in lines[0] and f"by {signal.Signals(sig).name};" in lines[0]
    assert react <= REACT_MAX_S, f"took {react:.3f} s to answer {sig!r}"
    step = int(lines[0].split(" at step ")[1].split()[0])
    for path in (rrd, mcap):
        traj = rblog.load(path)
        assert traj.truncated
        assert any("interrupted" in w for w in traj.warnings), traj.warnings
        # every sample up to the step the message names (log_every = 10 on the pile)
        assert traj.step[-1] == step - step % traj.info.log_every
        assert traj.n_samples == step // traj.info.log_every + 1


def test_sigkill_leaves_readable_logs(tmp_path):
    p, rrd, mcap = _start_pile(tmp_path)
    _wait_stepping(p, mcap, tmp_path)
    time.sleep(2.0)
    p.send_signal(signal.SIGKILL)
    p.communicate(timeout=30)
    for path in (mcap, rrd):
        traj = rblog.load(path)
        assert traj.n_samples >= 2, path
        assert traj.truncated, path


def test_sigkill_during_the_first_seconds_keeps_samples(tmp_path):
    """Killed 2 s after the logs were opened (kernels loaded): the pile's first samples are on
    disk. Before, the first block (~0.65 s simulated, several seconds of wall time) had not been
    written yet and the .mcap held no sample at all ("log ends before its first sample")."""
    p, rrd, mcap = _start_pile(tmp_path)
    t0 = time.monotonic()
    while not (mcap.exists() and mcap.stat().st_size > 0):
        assert p.poll() is None and time.monotonic() - t0 < 120, p.communicate()
        time.sleep(0.05)
    time.sleep(2.0)
    p.send_signal(signal.SIGKILL)
    p.communicate(timeout=30)
    for path in (mcap, rrd):
        assert rblog.load(path).n_samples >= 2, path


class _WriteClock:
    """A recorder that notes the wall time of every block it is handed."""

    def __init__(self):
        self.times: list[float] = []

    def open(self, model, info):
        self.times = [time.perf_counter()]

    def write(self, block):
        self.times.append(time.perf_counter())

    def close(self, truncated=False, reason=None):
        pass


def test_blocks_reach_the_writers_on_a_wall_time_budget():
    """The pile's compiled calls are sized by wall time: the writers get samples at least every
    KILL_LOSS_MAX_S - FLUSH_EVERY_S. Before, one block of the pile was ~0.65 s of simulated time,
    several seconds of wall time."""
    clock = _WriteClock()
    # every step sampled (log_every=1: 400 samples) so that the pipeline's joining of the blocks
    # that arrive within GATHER_HOLD_S (at most GATHER_MAX_BODY_SAMPLES / 500 = 65 samples of
    # the pile a block) still hands the writers several blocks on a fast machine
    run_scene(load_scene(PILE), duration=0.4, log_every=1, recorders=[clock])
    gaps = [b - a for a, b in zip(clock.times[1:], clock.times[2:])]
    assert len(gaps) >= 3
    # measured: largest gap 0.03-0.12 s (CALL_WALL_BUDGET_S = 0.03 s)
    assert max(gaps) <= KILL_LOSS_MAX_S - mcap_writer.FLUSH_EVERY_S, gaps


def test_mcap_on_disk_within_flush_budget(tmp_path, scene_from_text):
    """What was handed to the MCAP writer more than FLUSH_EVERY_S ago is readable from the file
    as it is on disk (a copy taken mid-run stands for a killed process)."""
    from rblog.engine.runner import simulate

    scene = scene_from_text("[sim]\ndt = 1e-3\nduration = 1.0\n[[body]]\nshape = \"sphere\"\n"
                            "radius = 0.1\nmass = 1.0\n")
    traj, _ = simulate(scene)
    path = tmp_path / "live.mcap"
    rec = McapRecorder(str(path))
    rec.open(traj.model, traj.info)
    blocks = _split(traj, 3)
    rec.write(blocks[0])
    time.sleep(mcap_writer.FLUSH_EVERY_S + 0.05)
    # a call's samples reach the writer within CALL_WALL_BUDGET_S, the file within FLUSH_EVERY_S
    assert runner_constants.CALL_WALL_BUDGET_S + mcap_writer.FLUSH_EVERY_S <= KILL_LOSS_MAX_S
    rec.write(blocks[1])  # more than FLUSH_EVERY_S after the last flush: flushes
    snap = tmp_path / "snap.mcap"
    shutil.copyfile(path, snap)
    got = rblog.load(snap)
    assert got.n_samples >= blocks[0].n_samples + blocks[1].n_samples
    rec.close()


def _split(traj, k):
    import numpy as np

    edges = np.linspace(0, traj.n_samples, k + 1).astype(int)
    return [traj.slice(slice(int(a), int(b))) for a, b in zip(edges[:-1], edges[1:])]


def test_sigterm_stops_rblog_stress(tmp_path):
    """``kill`` stops the whole stability suite, not just the run it lands in. Before, the
    interrupted run became a row ("error") and the suite went on for minutes (the full suite:
    over 7 min on the 2-core machine); now the interruption leaves the suite: exit 143 (128 +
    SIGTERM) when it lands in a run, or the default action (-15) between runs."""
    p = subprocess.Popen([RBLOG, "stress", "--no-progress", "--out", str(tmp_path / "out")],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(3.0)  # past start-up (~0.5-1 s), inside the suite's first runs
    assert p.poll() is None, p.communicate()
    t0 = time.monotonic()
    p.send_signal(signal.SIGTERM)
    try:
        out, err = p.communicate(timeout=20)
    except subprocess.TimeoutExpired:
        p.kill()
        out, err = p.communicate()
        raise AssertionError(f"rblog stress still running 20 s after SIGTERM: {err[-500:]}")
    assert p.returncode in (143, -signal.SIGTERM), (p.returncode, err[-500:])
    assert time.monotonic() - t0 < 20
    assert not (tmp_path / "out" / "stress.json").exists()
