"""Recording benchmark: the cost of logging every step of 100 free bodies, side by side with the
same run without logs, and bytes per body-step of each format.

    python benchmarks/bench_logging.py [--bodies 100] [--steps 4000] [--integrator rk4]

Target (issue 4): a run that logs every step to both formats takes at most 2x the run without.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import rblog  # noqa: E402
from rblog.record import McapRecorder, RerunRecorder  # noqa: E402

SCENE = """
[sim]
dt = 1e-3
duration = {duration}
gravity = [0.0, 0.0, -9.81]
[[generator]]
layout = "grid"
grid = [{nx}, {ny}, 1]
spacing = 1.0
spin = [1.0, 5.0]
random_orientation = true
[generator.body]
shape = "box"
half_extents = [0.3, 0.2, 0.1]
mass = 1.0
"""


def best_of(fn, repeats=3):
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bodies", type=int, default=100)
    ap.add_argument("--steps", type=int, default=4000)
    ap.add_argument("--integrator", default="rk4")
    args = ap.parse_args()
    nx = int(round(args.bodies ** 0.5))
    ny = args.bodies // nx
    n = nx * ny
    scene = rblog.parse_scene(SCENE.format(duration=args.steps * 1e-3, nx=nx, ny=ny), "bench")
    tmp = tempfile.mkdtemp()
    rrd, mcap = os.path.join(tmp, "b.rrd"), os.path.join(tmp, "b.mcap")
    kw = dict(integrator=args.integrator)
    rblog.run(scene, log_every=1, recorders=[RerunRecorder(rrd), McapRecorder(mcap)], **kw)  # warm

    rows = [
        ("no log (summary at 100 Hz)", lambda: rblog.run(scene, **kw)),
        ("no log, every step derived", lambda: rblog.run(scene, log_every=1, **kw)),
        ("rrd, every step", lambda: rblog.run(scene, log_every=1, recorders=[RerunRecorder(rrd)], **kw)),
        ("mcap, every step", lambda: rblog.run(scene, log_every=1, recorders=[McapRecorder(mcap)], **kw)),
        ("rrd + mcap, every step", lambda: rblog.run(
            scene, log_every=1, recorders=[RerunRecorder(rrd), McapRecorder(mcap)], **kw)),
        ("rrd + mcap, default 100 Hz", lambda: rblog.run(
            scene, recorders=[RerunRecorder(rrd + "2"), McapRecorder(mcap + "2")], **kw)),
    ]
    print(f"{n} bodies, {args.steps} steps of 1 ms, integrator {args.integrator}; wall time of "
          "rblog.run (kernels loaded), best of 3")
    base = None
    for name, fn in rows:
        t = best_of(fn)
        base = base or t
        print(f"  {name:<30} {t:8.3f} s   {t / base:5.2f}x   {t / args.steps * 1e6:8.1f} us/step")
    body_steps = n * (args.steps + 1)
    print(f"  bytes per body-step: rrd {os.path.getsize(rrd) / body_steps:.0f} B, "
          f"mcap {os.path.getsize(mcap) / body_steps:.0f} B")


if __name__ == "__main__":
    main()
