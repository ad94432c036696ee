"""What recording a pybullet world costs: the bare ``stepSimulation`` loop against the same loop
with ``rblog.adapters.pybullet.PybulletRecorder`` (``rec()`` after every step).

    python benchmarks/bench_adapters_pybullet.py [--world jenga] [--steps 1000] [--pairs 5]

Each pair runs the world from a fresh client twice, interleaved (bare, recorded, bare, ...) in
one process so that the load of a shared machine hits both alike, and times each by process CPU
(``time.process_time``). Recorded runs: every step (``log_every=1``) and every 10th, each with an
MCAP file written and in memory only (``keep=True``). Prints each pair's ratios and the medians.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time

import pybullet as pb

from rblog.adapters.pybullet import SHIPPED_WORLDS, PybulletRecorder, load_shipped


def bare(world: str, steps: int) -> float:
    cid = pb.connect(pb.DIRECT)
    try:
        load_shipped(world, cid)
        c0 = time.process_time()
        for _ in range(steps):
            pb.stepSimulation(physicsClientId=cid)
        return time.process_time() - c0
    finally:
        pb.disconnect(physicsClientId=cid)


def recorded(world: str, steps: int, every: int, mcap: str | None) -> float:
    cid = pb.connect(pb.DIRECT)
    try:
        load_shipped(world, cid)
        c0 = time.process_time()
        rec = PybulletRecorder(cid, mcap=mcap, keep=mcap is None, log_every=every)
        for _ in range(steps):
            pb.stepSimulation(physicsClientId=cid)
            rec()
        rec.close()
        return time.process_time() - c0
    finally:
        pb.disconnect(physicsClientId=cid)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="jenga", choices=SHIPPED_WORLDS)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--pairs", type=int, default=5)
    a = ap.parse_args(argv)
    cases = [("every step, mcap", 1, True), ("every step, memory", 1, False),
             ("every 10th, mcap", 10, True), ("every 10th, memory", 10, False)]
    ratios = {name: [] for name, *_ in cases}
    with tempfile.TemporaryDirectory() as tmp:
        for p in range(a.pairs):
            for name, every, to_file in cases:
                t_bare = bare(a.world, a.steps)
                t_rec = recorded(a.world, a.steps, every, f"{tmp}/run.mcap" if to_file else None)
                ratios[name].append(t_rec / t_bare)
                print(f"pair {p}: {name:20s} bare {t_bare * 1e6 / a.steps:7.0f} us/step, recorded "
                      f"{t_rec * 1e6 / a.steps:7.0f} us/step, {t_rec / t_bare:.3f}x", flush=True)
    print(f"{a.world}, {a.steps} steps, CPU time, median of {a.pairs} interleaved pairs:")
    for name, r in ratios.items():
        print(f"  {name:20s} {statistics.median(r):.3f}x (min {min(r):.3f}, max {max(r):.3f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
