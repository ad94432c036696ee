"""First-run benchmark: `rblog run` as a whole process on an empty kernel cache, then again on the
warm cache; the difference is what a user's first run pays for compilation.

Each scene runs in a fresh process with NUMBA_CACHE_DIR pointing at a new empty directory (the
cold run), then once more with the same directory (warm). Scenes: a free-body scene
(samples/free_fall.toml) and a contact scene (samples/box_stack.toml), each for one step with no
log, so the times are start-up and compilation only. Target (issue 18): cold - warm <= 5 s for
the free-body scene, <= 10 s for the contact scene.

    python benchmarks/bench_firstrun.py
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENES = {"free-body": ROOT / "samples/free_fall.toml", "contact": ROOT / "samples/box_stack.toml"}
TARGET_S = {"free-body": 5.0, "contact": 10.0}


def timed_run(scene: Path, cache: str) -> float:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "rblog_cli.main", "run", str(scene), "--no-log",
                    "--duration", "0.01"], env=env, check=True, capture_output=True)
    return time.perf_counter() - t0


def main():
    print(f"{'scene':<10}{'cold (s)':>10}{'warm (s)':>10}{'compile (s)':>13}{'target':>8}")
    for name, scene in SCENES.items():
        with tempfile.TemporaryDirectory() as tmp:
            cold = timed_run(scene, tmp)
            warm = timed_run(scene, tmp)
        c = cold - warm
        print(f"{name:<10}{cold:>10.1f}{warm:>10.2f}{c:>13.1f}{TARGET_S[name]:>7.0f}s"
              f"  {'met' if c <= TARGET_S[name] else 'NOT met'}")


if __name__ == "__main__":
    main()
