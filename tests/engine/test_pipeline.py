"""The writer pipeline (rblog.engine.pipeline): joining the run loop's small blocks changes how
many blocks the recorders get, never what they hold; a recorder's error surfaces in the run
loop's thread as the error it raised."""

from __future__ import annotations

import numpy as np
import pytest

import rblog
import rblog.engine.pipeline as pipeline
from rblog.contract.trajectory import BODY_CHANNELS, TOTAL_CHANNELS
from rblog.engine.runner import TrajectoryCollector, samples_per_block

from conftest import SAMPLES_DIR


def _blocks(monkeypatch, hold_s: float, **kw):
    monkeypatch.setattr(pipeline, "GATHER_HOLD_S", hold_s)
    scene = rblog.load_scene(str(SAMPLES_DIR / "spinning_bodies.toml"))
    col = TrajectoryCollector()
    rblog.run(scene, recorders=[col], **kw)
    return scene, col.blocks


def test_joined_blocks_hold_the_same_samples(monkeypatch):
    """Blocks joined for as long as it takes (hold 10 s: every block is joined up to the cap)
    and not at all (hold 0: whatever is already queued, often nothing) carry bit-identical
    samples of every channel, in the same order; joined blocks are fewer and within the cap."""
    scene, apart = _blocks(monkeypatch, 0.0)
    _, joined = _blocks(monkeypatch, 10.0)
    n = scene.model.n_bodies
    cap = max(1, pipeline.GATHER_MAX_BODY_SAMPLES // n)
    # 5 s at 100 Hz: 501 samples; spinning_bodies has 300 bodies, so the cap is 109 samples
    assert cap == 32_768 // 300 == 109
    a = np.concatenate([b.step for b in apart])
    j = np.concatenate([b.step for b in joined])
    assert np.array_equal(a, np.arange(0, 2501, 5)) and np.array_equal(j, a)
    for name in ("t", *BODY_CHANNELS, *TOTAL_CHANNELS):
        got = np.concatenate([getattr(b, name) for b in joined])
        want = np.concatenate([getattr(b, name) for b in apart])
        assert got.tobytes() == want.tobytes(), name
    # the run loop's first calls hold 1 sample each (sized on wall time from 1 step up), so the
    # run is many blocks apart; joined, every block but the last reaches the cap, which a block
    # passes by at most one call's samples
    assert len(joined) < len(apart)
    per_call = samples_per_block(n, 5)
    assert all(cap <= len(b.t) < cap + per_call for b in joined[:-1])


def test_recorder_error_surfaces_in_the_run_loop(monkeypatch):
    """A recorder that raises on its second block (on the pipeline's thread) stops the run with
    that very exception, raised by rblog.run in the caller's thread."""
    from rblog.errors import LogWriteError

    monkeypatch.setattr(pipeline, "GATHER_HOLD_S", 0.0)
    err = LogWriteError("x.log", "disk full")

    class FailsSecond:
        writes = 0
        closed = None

        def open(self, model, info):
            pass

        def write(self, block):
            FailsSecond.writes += 1
            if FailsSecond.writes == 2:
                raise err

        def close(self, truncated=False, reason=None):
            FailsSecond.closed = truncated

    scene = rblog.load_scene(str(SAMPLES_DIR / "spinning_bodies.toml"))
    with pytest.raises(LogWriteError) as info:
        rblog.run(scene, recorders=[FailsSecond()])
    assert info.value is err
    assert FailsSecond.closed is True  # closed as truncated
