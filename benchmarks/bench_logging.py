"""Recording benchmark: the cost of logging every step of 100 free bodies, side by side with the
same run without logs, and bytes per body-step of each format.

    python benchmarks/bench_logging.py [--bodies 100] [--steps 4000] [--integrator rk4] [--no-contacts]

Target (issue 4): a run that logs every step to both formats takes at most 2x the run without.
Two scenes: free bodies (no contacts: the cheapest step rblog has, so the worst case for the
ratio) and the same number of boxes dropped onto the ground and onto each other (contacts, and
the contacts' records in the logs).
"""

from __future__ import annotations

import argparse
import copy
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

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


CONTACT_SCENE = """
[sim]
dt = 1e-3
duration = {duration}
seed = 1
[ground]
restitution = 0.2
friction = 0.6
[[generator]]
layout = "grid"
grid = [{nx}, {ny}, 2]
spacing = [0.18, 0.18, 0.4]
origin = [-0.81, -0.81, 0.3]
random_orientation = true
speed = [0.0, 0.3]
spin = [0.0, 2.0]
[generator.body]
shape = "box"
half_extents = [0.05, 0.05, 0.05]
mass = 0.1
restitution = 0.2
friction = 0.6
"""


def best_of(fn, repeats=3, clock=time.perf_counter):
    """Least time ``fn()`` takes on ``clock`` (wall time, or ``time.process_time`` for CPU)."""
    best = float("inf")
    for _ in range(repeats):
        t0 = clock()
        fn()
        best = min(best, clock() - t0)
    return best


class _Keep:
    """A recorder that keeps copies of the blocks it is given (to replay them to one writer)."""

    def open(self, model, info):
        self.model, self.info, self.blocks = model, info, []

    def write(self, block):
        self.blocks.append(copy.deepcopy(block))

    def close(self, truncated=False, reason=None):
        pass


def _cpu_per_sample(make, keep, samples):
    """Least process CPU time (us per sample) of a new writer ``make()`` replaying the blocks and
    closing the file (opening it, the static records, is not counted)."""
    best = float("inf")
    for _ in range(3):
        rec = make()
        rec.open(keep.model, keep.info)
        c0 = time.process_time()
        for b in keep.blocks:
            rec.write(b)
        rec.close()
        best = min(best, time.process_time() - c0)
    return best / samples * 1e6


def writers_alone(scene, kw, tmp, steps):
    """Where the time goes: the simulation and each writer on its own, in process CPU time per
    step, and the least wall time any schedule of that CPU work can take on this machine's cores:
    the total spread evenly over the cores, but no less than the simulation's thread or the MCAP
    writer's (one Python thread each); the Rerun SDK encodes on threads of its own."""
    keep = _Keep()
    rblog.run(scene, log_every=1, recorders=[keep], **kw)
    samples = sum(len(b.t) for b in keep.blocks)

    def cpu_of(fn):
        return best_of(fn, clock=time.process_time) / steps * 1e6

    sim = cpu_of(lambda: rblog.run(scene, **kw))
    derived = cpu_of(lambda: rblog.run(scene, log_every=1, **kw))
    rrd = _cpu_per_sample(lambda: RerunRecorder(os.path.join(tmp, "w.rrd")), keep, samples)
    mcap = _cpu_per_sample(lambda: McapRecorder(os.path.join(tmp, "w.mcap")), keep, samples)
    raw = _cpu_per_sample(lambda: McapRecorder(os.path.join(tmp, "w0.mcap"), compression="none"),
                          keep, samples)
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    total = derived + rrd + mcap
    bound = max(total / cores, derived, mcap)
    print("\n  where the time goes (process CPU per step, each writer alone replaying this run's "
          "blocks, best of 3):")
    print(f"    simulation {sim:.1f} us; with every step derived {derived:.1f} us; "
          f"Rerun writer {rrd:.1f} us; MCAP writer {mcap:.1f} us (lz4; no compression {raw:.1f} us)")
    print(f"    least wall time of that CPU on {cores} cores: {bound:.1f} us/step = {bound / sim:.2f}x "
          f"the simulation's CPU (target 2x)")
    no_mcap = max((derived + rrd) / cores, derived)
    print(f"    the same with an MCAP writer that cost nothing: {no_mcap:.1f} us/step = "
          f"{no_mcap / sim:.2f}x")


def main():
    with tempfile.TemporaryDirectory() as tmp:  # ~0.5 GB of logs, removed at the end
        bench(tmp)


def bench(tmp):
    ap = argparse.ArgumentParser()
    ap.add_argument("--bodies", type=int, default=100)
    ap.add_argument("--steps", type=int, default=4000)
    ap.add_argument("--integrator", default="rk4")
    ap.add_argument("--no-contacts", action="store_true", help="skip the scene with contacts")
    args = ap.parse_args()
    nx = int(round(args.bodies ** 0.5))
    ny = args.bodies // nx
    n = nx * ny
    scene = rblog.parse_scene(SCENE.format(duration=args.steps * 1e-3, nx=nx, ny=ny), "bench")
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
    sizes = [os.path.getsize(rrd), os.path.getsize(mcap)]
    print(f"  bytes per body-step: rrd {sizes[0] / body_steps:.0f} B, "
          f"mcap {sizes[1] / body_steps:.0f} B")

    # The floor any logger has: writing the content's bytes. Each sample carries 33 float64 per
    # body (docs/log-format.md: position 3, quat 4, rotation 9, velocity 3, momentum 3, omega 3,
    # angular momentum 3, 3 energies, 2 errors) = 264 B per body-step per format.
    raw = np.random.default_rng(0).random(body_steps * 33)
    paths = [os.path.join(tmp, "raw0.bin"), os.path.join(tmp, "raw1.bin")]

    def write_raw(arrays):
        for a, path in zip(arrays, paths):
            with open(path, "wb") as f:
                a.tofile(f)

    content = best_of(lambda: write_raw([raw, raw]))
    files = best_of(lambda: write_raw([raw.view(np.uint8)[:k] for k in sizes]))
    print(f"  floor: write the float64 content twice (2 x {raw.nbytes / 1e6:.0f} MB, no encoding) "
          f"{content:.3f} s = {content / base:.2f}x;  write the two files' bytes "
          f"({sum(sizes) / 1e6:.0f} MB) {files:.3f} s = {files / base:.2f}x")

    writers_alone(scene, kw, tmp, args.steps)

    if args.no_contacts:
        return
    nx2 = max(1, int(round((n / 2) ** 0.5)))
    ny2 = max(1, n // (2 * nx2))
    scene = rblog.parse_scene(CONTACT_SCENE.format(duration=args.steps * 1e-3, nx=nx2, ny=ny2),
                              "bench-contacts")
    n2 = scene.model.n_bodies
    rblog.run(scene, log_every=1, recorders=[RerunRecorder(rrd), McapRecorder(mcap)], **kw)  # warm
    print(f"\n{n2} boxes of 0.1 m dropped onto the ground and each other ({nx2} x {ny2} x 2 grid, "
          f"contacts), {args.steps} steps of 1 ms, integrator {args.integrator}; best of 2")
    base = None
    for name, fn in (
        ("no log (summary at 100 Hz)", lambda: rblog.run(scene, **kw)),
        ("rrd + mcap, every step", lambda: rblog.run(
            scene, log_every=1, recorders=[RerunRecorder(rrd), McapRecorder(mcap)], **kw)),
    ):
        t = best_of(fn, repeats=2)
        base = base or t
        print(f"  {name:<30} {t:8.3f} s   {t / base:5.2f}x   {t / args.steps * 1e6:8.1f} us/step")
    body_steps = n2 * (args.steps + 1)
    print(f"  bytes per body-step (contacts included): rrd {os.path.getsize(rrd) / body_steps:.0f} B, "
          f"mcap {os.path.getsize(mcap) / body_steps:.0f} B")


if __name__ == "__main__":
    main()
