"""Recording benchmark: what logging costs a run.

    python benchmarks/bench_logging.py [--repeats 5] [--cli] [--default-only]
                                       [--bodies 100] [--steps 4000] [--integrator rk4] [--no-contacts]

First (issue 28): default logging (both logs, Rerun .rrd + MCAP lz4, at 100 Hz) on
samples/spinning_bodies.toml against the same run with --no-log, run A B A B ... in one process
(the machine's load hits both alike), each figure printed beside the other with their ratio
(target <= 1.3x). The wall time is rblog.run's (stepping and writing; the recorders' open is
before the clock), the CPU time the process's (every thread: the Rerun SDK's included). With
--cli, also the whole `rblog run` process (start-up, imports, scene, run, exit), alternating.

Then (issue 4, unless --default-only): logging every step of 100 free bodies to each format, side
by side with the same run without logs, and bytes per body-step of each format. Target: a run
that logs every step to both formats takes at most 2x the run without. Two scenes: free bodies
(no contacts: the cheapest step rblog has, so the worst case for the ratio) and the same number
of boxes dropped onto the ground and onto each other (contacts, and the contacts' records in the
logs).
"""

from __future__ import annotations

import argparse
import copy
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

import rblog  # noqa: E402
from rblog.record import McapRecorder, RerunRecorder  # noqa: E402
from rblog.record.recorder import Recorder  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_SCENE = ROOT / "samples" / "spinning_bodies.toml"
#: issue 28: default logging on DEFAULT_SCENE takes at most this times the --no-log wall time
DEFAULT_RATIO_TARGET = 1.3

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


def _timed(fn):
    """(wall s, process CPU s) of ``fn()``."""
    c0, t0 = time.process_time(), time.perf_counter()
    fn()
    return time.perf_counter() - t0, time.process_time() - c0


def default_logging(tmp, repeats: int, cli: bool):
    """Issue 28's figure: --no-log and default logging (both logs at 100 Hz) on DEFAULT_SCENE,
    alternating, side by side with their ratio."""
    scene = rblog.load_scene(str(DEFAULT_SCENE))
    rrd, mcap = os.path.join(tmp, "d.rrd"), os.path.join(tmp, "d.mcap")

    def logged():
        # as `rblog run` records: one Recorder per writer (cli/rblog_cli/main.py)
        return rblog.run(scene, recorders=[Recorder(writers=[RerunRecorder(rrd)]),
                                           Recorder(writers=[McapRecorder(mcap)])])

    def bare():
        return rblog.run(scene)

    logged(), bare()  # warm: imports, first allocations
    rows = {"no log": [], "both logs": []}
    for _ in range(repeats):
        rows["no log"].append(_timed(bare))
        rows["both logs"].append(_timed(logged))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"{DEFAULT_SCENE.relative_to(ROOT)}: default logging (.rrd + .mcap lz4, 100 Hz) vs "
          f"--no-log, {repeats} alternating repeats in one process (load average {load:.1f}, "
          f"{os.cpu_count()} cores)")
    _side_by_side("rblog.run", rows)
    sizes = os.path.getsize(rrd), os.path.getsize(mcap)
    print(f"  logs: rrd {sizes[0] / 1e6:.1f} MB, mcap {sizes[1] / 1e6:.1f} MB")
    # where the time goes: each writer alone, replaying the run's blocks (as the pipeline joined
    # them), write + close; the Rerun SDK's own threads are the process CPU the calling thread
    # did not spend
    keep = _Keep()
    rblog.run(scene, recorders=[keep])
    parts = {"stepping alone (no-log, main thread)": [], "Rerun writer": [], "MCAP writer": []}
    for _ in range(repeats):
        t0 = time.thread_time()
        bare()
        parts["stepping alone (no-log, main thread)"].append((time.thread_time() - t0, 0.0))
        for name, make in (("Rerun writer", lambda: RerunRecorder(os.path.join(tmp, "w.rrd"))),
                           ("MCAP writer", lambda: McapRecorder(os.path.join(tmp, "w.mcap")))):
            rec = make()
            rec.open(keep.model, keep.info)
            c0, t0 = time.process_time(), time.thread_time()
            for b in keep.blocks:
                rec.write(b)
            rec.close()
            mine = time.thread_time() - t0
            parts[name].append((mine, time.process_time() - c0 - mine))
    print(f"  where the time goes ({len(keep.blocks)} blocks; CPU ms, median of {repeats}; "
          "calling thread + other threads):")
    for name, v in parts.items():
        print(f"    {name:<38} {statistics.median(a for a, _ in v) * 1e3:6.0f} + "
              f"{statistics.median(b for _, b in v) * 1e3:4.0f} ms")
    if cli:
        exe = str(Path(sys.executable).with_name("rblog"))
        base = [exe, "run", str(DEFAULT_SCENE)]
        rows = {"no log": [], "both logs": []}
        for _ in range(repeats):
            for name, argv in (("no log", base + ["--no-log"]),
                               ("both logs", base + ["--rrd", rrd, "--mcap", mcap])):
                t0 = time.perf_counter()
                r0 = os.times()
                subprocess.run(argv, check=True, capture_output=True, cwd=tmp)
                r1 = os.times()
                rows[name].append((time.perf_counter() - t0, (r1.children_user - r0.children_user)
                                   + (r1.children_system - r0.children_system)))
        _side_by_side("whole `rblog run` process", rows)


def _side_by_side(what: str, rows: dict):
    (na, a), (nb, b) = rows.items()
    wa, wb = [w for w, _ in a], [w for w, _ in b]
    print(f"  {what}: wall s (CPU s) per repeat, {na} | {nb}")
    for (x, cx), (y, cy) in zip(a, b):
        print(f"    {x:7.3f} ({cx:6.3f}) | {y:7.3f} ({cy:6.3f})   {y / x:5.2f}x")
    ma, mb = statistics.median(wa), statistics.median(wb)
    ca, cb = statistics.median([c for _, c in a]), statistics.median([c for _, c in b])
    print(f"    median {ma:.3f} s | {mb:.3f} s: {mb / ma:.2f}x (best {min(wb) / min(wa):.2f}x; "
          f"target {DEFAULT_RATIO_TARGET}x); CPU {ca:.3f} s | {cb:.3f} s")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bodies", type=int, default=100)
    ap.add_argument("--steps", type=int, default=4000)
    ap.add_argument("--integrator", default="rk4")
    ap.add_argument("--no-contacts", action="store_true", help="skip the scene with contacts")
    ap.add_argument("--repeats", type=int, default=5, help="alternating repeats of the default run")
    ap.add_argument("--cli", action="store_true", help="also time the whole `rblog run` process")
    ap.add_argument("--default-only", action="store_true",
                    help="only the default-logging figure (issue 28)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:  # ~0.5 GB of logs, removed at the end
        default_logging(tmp, args.repeats, args.cli)
        if not args.default_only:
            print()
            bench(tmp, args)


def bench(tmp, args):
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
