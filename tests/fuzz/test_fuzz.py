"""The fuzz targets (targets.py): every seed of the corpus passes (an RblogError or a result,
nothing else), and in the slow stage a short atheris run of each target finds nothing. The long
run: docs/fuzzing.md; its executions per target: benchmarks/RESULTS.md, "Fuzzing"."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import targets  # noqa: E402

#: executions of each target in the slow stage's short run (about 10-60 s each on this machine)
SHORT_RUNS = 300


def _seeds(target):
    return sorted(p for p in (HERE / "corpus" / target).iterdir() if p.is_file())


@pytest.mark.parametrize("target", sorted(targets.TARGETS))
def test_seed_corpus_passes(target):
    if target == "mujoco":
        pytest.importorskip("mujoco")
    seeds = _seeds(target)
    assert seeds, f"no seeds for {target}"
    for p in seeds:
        targets.TARGETS[target](p.read_bytes())


def test_targets_reach_the_contents():
    """The structured targets are not stopped at the framing: the seed logs read, and a
    mutation of a contact row's body index reaches the reader's contents check."""
    import rblog
    from rblog.errors import LogReadError

    for name in ("ball.mcap", "ball.rrd"):
        assert len(rblog.load(HERE / "corpus" / "seeds" / name).contacts) > 0
    seen = []
    real = rblog.load

    def spy(path):
        try:
            return real(path)
        except LogReadError as e:
            seen.append(str(e))
            raise

    try:
        rblog.load = spy
        # find the first Contacts message (schemas in write order: Run, State, Contacts, ...)
        for idx in range(40):
            seen.clear()
            # message idx, field pick 2 (body_a, the third field), op 4 + 8 k: set entry 0 to
            # k - 2 = 22 (the log has 2 bodies)
            targets.mcap_fields(idx.to_bytes(2, "little") + bytes([2, 4 + 8 * 24]) + bytes(8))
            if any("body_a" in s for s in seen):
                break
        assert any("body_a" in s for s in seen), seen
    finally:
        rblog.load = real


@pytest.mark.slow
@pytest.mark.parametrize("target", sorted(targets.TARGETS))
def test_short_fuzz_run(target, tmp_path):
    pytest.importorskip("atheris")
    if target == "mujoco":
        pytest.importorskip("mujoco")
    proc = subprocess.run([sys.executable, str(HERE / "run.py"), target, f"-runs={SHORT_RUNS}",
                           f"--work={tmp_path}"], capture_output=True, text=True, timeout=1200)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert f"Done {SHORT_RUNS} runs" in proc.stderr, proc.stderr[-1000:]
