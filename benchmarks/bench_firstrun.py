"""First-run benchmark: `rblog run` as a whole process on an empty kernel cache, then again on the
warm cache; the difference is what a user's first run pays for compilation.

Each scene runs in a fresh process with NUMBA_CACHE_DIR pointing at a new empty directory (the
cold run), then once more with the same directory (warm). Scenes: a free-body scene
(samples/free_fall.toml) and a contact scene (samples/box_stack.toml), each for a few steps with
no log, so the times are start-up and compilation only. Target (issue 18): cold - warm <= 5 s for
the free-body scene, <= 10 s for the contact scene.

    python benchmarks/bench_firstrun.py [--compare REF] [--scenes free-body,contact]

``--compare REF`` (a git commit, e.g. ``main`` or ``HEAD~3``) also times that version of rblog,
side by side in the same run: its source is exported with ``git archive`` into a temporary folder
and put first on PYTHONPATH (same interpreter and packages). The rows alternate between the two
versions, scene by scene, so that load on a shared machine falls on both alike.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENES = {"free-body": ROOT / "samples/free_fall.toml", "contact": ROOT / "samples/box_stack.toml"}
TARGET_S = {"free-body": 5.0, "contact": 10.0}


def timed_run(scene: Path, cache: str, pythonpath: str | None) -> tuple[float, str]:
    """Wall time of one `rblog run` process, and its compile notice (if it printed one)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath + os.pathsep + env.get("PYTHONPATH", "")
    t0 = time.perf_counter()
    res = subprocess.run([sys.executable, "-m", "rblog_cli.main", "run", str(scene), "--no-log",
                          "--duration", "0.01"], env=env, check=True, capture_output=True,
                         text=True, cwd=tempfile.gettempdir())
    wall = time.perf_counter() - t0
    notice = next((ln for ln in res.stderr.splitlines() if "compiling" in ln), "")
    return wall, notice


def export(ref: str, into: Path) -> str:
    """``git archive ref`` of this repository into ``into``; returns a PYTHONPATH that imports
    that version's ``rblog`` and ``rblog_cli``."""
    src = into / "src"
    src.mkdir()
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", ref], check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(src)], input=archive, check=True)
    path = into / "path"
    path.mkdir()
    (path / "rblog").symlink_to(src / "rblog")
    (path / "rblog_cli").symlink_to(src / "cli" / "rblog_cli")
    return str(path)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--compare", metavar="REF", help="git commit to time side by side")
    ap.add_argument("--scenes", default=",".join(SCENES), help="comma-separated: " + ", ".join(SCENES))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        versions = [("this tree", None)]
        if args.compare:
            versions.insert(0, (args.compare, export(args.compare, Path(tmp))))
        print(f"{'scene':<10}{'version':>12}{'cold (s)':>10}{'warm (s)':>10}{'compile (s)':>13}"
              f"{'target':>8}")
        notices = []
        for name in args.scenes.split(","):
            for label, pythonpath in versions:
                with tempfile.TemporaryDirectory() as cache:
                    cold, notice = timed_run(SCENES[name], cache, pythonpath)
                    warm, _ = timed_run(SCENES[name], cache, pythonpath)
                c = cold - warm
                print(f"{name:<10}{label:>12}{cold:>10.1f}{warm:>10.2f}{c:>13.1f}"
                      f"{TARGET_S[name]:>7.0f}s  {'met' if c <= TARGET_S[name] else 'NOT met'}",
                      flush=True)
                notices.append(f"  {name}, {label}: {notice or '(no notice)'}")
        print("compile notices printed by the cold runs:")
        print("\n".join(notices))


if __name__ == "__main__":
    main()
