"""Bulk work on a local Dask cluster against the same work done serially, in one run.

Measures (issue targets in brackets):

1. ``rblog check`` on N logs of 100 bodies x 1,000 samples (default N = 200): serial in this
   process, then on local clusters of 1 and 2 worker processes [2 workers >= 1.7x serial; the
   result tables identical].
2. ``rblog sweep`` of the tumbling box, 100 random variants (integrator x dt x initial spin),
   logs written: serial, 1 and 2 workers [2 workers >= 1.7x serial; identical tables, timing
   columns aside].
3. Scheduling overhead: 1,000 empty tasks through the executor [<= 5 ms per task].
4. A cost model, T(W) = N c / W + K o: N items of c serial seconds each, sent as K tasks
   (K = len(guided_chunks(N, W)): 24 tasks for 100 items on 2 workers, one per item without
   chunks), o = the empty-task overhead per task on W workers. Its prediction for 1 and 2
   workers is printed beside the measurement, with the per-item cost on the workers that the
   measurement implies ((T - K o) W / N, against c), then its projection for more workers.

Every timing excludes starting the cluster (printed apart: a running cluster is the comparator
the target names, and ``--scheduler`` reuses one) and loading kernels: the serial side checks
one log and runs four short variants first, each worker does the same through ``client.run``
(kernels warmed once per worker before timing). ``--repeat N`` times each sweep N times (serial
and clusters alike) and keeps the fastest; the check (tens of seconds) runs once. The serial
sweep's process CPU time is printed beside its wall time: above 1x, the serial run already uses
part of the second core (the run's writer threads overlap the stepping).

Local workers run with NUMBA_NUM_THREADS = cores // workers (rblog.study.cluster); the serial
side keeps this process's setting.

Run under the exclusive CPU lock (the machine's two cores are shared)::

    flock -x /tmp/rblog-cpu.lock python benchmarks/bench_cluster.py
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

#: distinct runs the bulk-check logs are copied from (different seeds; some flagged)
DISTINCT_LOGS = 8
SWEEP_SETS = ["integrator=seed,seed-quat,splitting,rk4", "dt=1e-3,2e-3,5e-3,1e-2",
              "body[0].angular_velocity_body[0]=0.01:0.5",
              "body[0].angular_velocity_body[2]=0.01:0.5"]


def scene_100_bodies(seed: int) -> str:
    """100 spinning boxes on a 10 x 10 grid, no gravity, nothing touches: 1,000 samples."""
    return f"""[sim]
dt = 1e-3
duration = 0.999
gravity = [0.0, 0.0, 0.0]
seed = {seed}
log_every = 1

[[generator]]
layout = "grid"
grid = [10, 10, 1]
spacing = 1.0
origin = [-4.5, -4.5, 1.0]
spin = [1.0, 6.0]
random_orientation = true
name_prefix = "box"
[generator.body]
shape = "box"
half_extents = [0.3, 0.15, 0.08]
density = 500.0
"""


def make_logs(out: Path, n: int) -> list[str]:
    import rblog
    from rblog.engine.scene import parse_scene
    from rblog.record import McapRecorder

    src = []
    for k in range(DISTINCT_LOGS):
        scene = parse_scene(scene_100_bodies(k + 1), f"bench{k}.toml")
        p = out / f"src{k}.mcap"
        # every fourth: the notes' scheme without orthonormalization (flagged by drift)
        kw = dict(integrator="seed", orthonormalize="none") if k % 4 == 3 else {}
        rblog.run(scene, recorders=[McapRecorder(str(p))], **kw)
        src.append(p)
    paths = []
    for i in range(n):  # hard links: N names, DISTINCT_LOGS files' worth of disk (20 MB each)
        dst = out / f"log{i:04d}.mcap"
        try:
            os.link(src[i % DISTINCT_LOGS], dst)
        except OSError:
            shutil.copyfile(src[i % DISTINCT_LOGS], dst)
        paths.append(str(dst))
    return paths


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--logs", type=int, default=200)
    ap.add_argument("--variants", type=int, default=100)
    ap.add_argument("--overhead-tasks", type=int, default=1000)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeat", type=int, default=1,
                    help="time each sweep this many times and keep the fastest (default 1)")
    args = ap.parse_args()

    from rblog.study.bulk_check import check_log, check_many
    from rblog.study.cluster import Executor, guided_chunks, measure_overhead
    from rblog.study.sweep import comparable_rows, run_sweep, write_outputs

    tmp = Path(tempfile.mkdtemp(prefix="rblog-bench-cluster-"))
    try:
        print(f"machine: {os.cpu_count()} cores; NUMBA_CACHE_DIR={'set' if os.environ.get('NUMBA_CACHE_DIR') else 'unset'}; "
              f"load average at start {os.getloadavg()[0]:.2f} (1 min)")
        (tmp / "logs").mkdir()
        paths, t_make = timed(lambda: make_logs(tmp / "logs", args.logs))
        size = sum(os.path.getsize(p) for p in paths) / len(paths)
        print(f"{len(paths)} logs of 100 bodies x 1,000 samples ({size / 1e6:.2f} MB each) "
              f"written in {t_make:.1f} s")
        scene = str(REPO / "samples" / "tumbling_box.toml")

        def sweep(ex, out):
            return run_sweep(scene, SWEEP_SETS, samples=args.variants, seed=1, executor=ex,
                             out_dir=tmp / out, write_logs=True)

        def best_sweep(ex, out):
            """(report, fastest wall seconds, its process CPU seconds) over --repeat runs."""
            best = None
            for _ in range(max(1, args.repeat)):
                c0 = time.process_time()
                rep, wall = timed(lambda: sweep(ex, out))
                cpu = time.process_time() - c0
                if best is None or wall < best[1]:
                    best = (rep, wall, cpu)
            return best

        # ---- serial ----
        check_log(paths[0])  # kernels loaded
        run_sweep(scene, ["duration=0.5"] + SWEEP_SETS, samples=4, seed=99, write_logs=False)
        ser_check, t_ser_check = timed(lambda: check_many(paths))
        ser_sweep, t_ser_sweep, cpu_ser_sweep = best_sweep(None, "sweep-serial")
        ser_ov = measure_overhead(Executor(), args.overhead_tasks)
        results = {"serial": dict(check_s=t_ser_check, sweep_s=t_ser_sweep,
                                  overhead_ms=ser_ov["per_task_s"] * 1e3)}
        canon = lambda rep: json.dumps(sorted(rep.entries, key=lambda e: e["log"]), sort_keys=True)
        ser_json = canon(ser_check)
        ser_rows = comparable_rows(ser_sweep)

        for w in args.workers:
            ex, t_start = timed(lambda: Executor(workers=w).__enter__())
            try:
                first = paths[0]
                ex.run_on_workers(lambda: check_log(first))
                ex.run_on_workers(lambda: run_sweep(scene, ["duration=0.5"] + SWEEP_SETS, samples=4,
                                                    seed=99, write_logs=False))
                par_check, t_check = timed(lambda: check_many(paths, ex))
                par_sweep, t_sweep, _ = best_sweep(ex, f"sweep-{w}")
                ov = measure_overhead(ex, args.overhead_tasks)
            finally:
                ex.close()
            results[w] = dict(start_s=t_start, check_s=t_check, sweep_s=t_sweep,
                              overhead_ms=ov["per_task_s"] * 1e3,
                              check_same=canon(par_check) == ser_json,
                              sweep_same=comparable_rows(par_sweep) == ser_rows)
            if w == max(args.workers):
                write_outputs(par_sweep, tmp / "sweep-out")

        # ---- report ----
        n_c, n_s = len(paths), args.variants
        print()
        print(f"{'':<22}{'serial':>10}" + "".join(f"{f'{w} worker' + ('s' if w > 1 else ''):>14}"
                                                  for w in args.workers))
        row = lambda label, key, fmt: print(f"{label:<22}{format(results['serial'].get(key, float('nan')), fmt):>10}"
                                            + "".join(f"{format(results[w][key], fmt):>14}" for w in args.workers))
        row(f"check {n_c} logs (s)", "check_s", ".2f")
        print(f"{'  speed-up':<22}{'1.00x':>10}" + "".join(
            f"{results['serial']['check_s'] / results[w]['check_s']:>13.2f}x" for w in args.workers))
        print(f"{'  tables identical':<22}{'':>10}" + "".join(f"{str(results[w]['check_same']):>14}" for w in args.workers))
        row(f"sweep {n_s} variants (s)", "sweep_s", ".2f")
        print(f"{'  speed-up':<22}{'1.00x':>10}" + "".join(
            f"{results['serial']['sweep_s'] / results[w]['sweep_s']:>13.2f}x" for w in args.workers))
        print(f"{'  tables identical':<22}{'':>10}" + "".join(f"{str(results[w]['sweep_same']):>14}" for w in args.workers))
        print(f"{'  serial CPU / wall':<22}{cpu_ser_sweep / t_ser_sweep:>9.2f}x   "
              f"(repeat {args.repeat}, fastest kept)")
        row("empty task (ms/task)", "overhead_ms", ".3f")
        print(f"{'cluster start (s)':<22}{'-':>10}" + "".join(f"{results[w]['start_s']:>14.2f}" for w in args.workers))

        # ---- model ----
        print("\nmodel T(W) = N c / W + K o: c = serial s/item, K = tasks (guided chunks), "
              "o = empty-task overhead per task on W workers")
        o_at = lambda W: results[W if W in results else max(args.workers)]["overhead_ms"] * 1e-3
        for what, key, n in (("check", "check_s", n_c), ("sweep", "sweep_s", n_s)):
            c = results["serial"][key] / n
            k_of = lambda W: len(guided_chunks(n, W))
            pred = lambda W: n * c / (n * c / W + k_of(W) * o_at(W))
            print(f"  {what}: c = {c * 1e3:.1f} ms/item")
            for w in args.workers:
                t = results[w][key]
                per_item = (t - k_of(w) * o_at(w)) * w / n
                print(f"    W={w}: K = {k_of(w)}, o = {o_at(w) * 1e3:.2f} ms; predicted "
                      f"{pred(w):.2f}x, measured {results['serial'][key] / t:.2f}x; per item on "
                      f"the workers {per_item * 1e3:.1f} ms ({per_item / c:.2f} c)")
            proj = ", ".join(f"W={W}: {pred(W):.1f}x" for W in (4, 8, 16, 64))
            print(f"    projected ({n} items, W real cores, o as on {max(args.workers)} workers): "
                  f"{proj}; bound c/o = {c / o_at(max(args.workers)):.0f}x per item-task")
        print(f"load average at end {os.getloadavg()[0]:.2f} (1 min; above ~2 means other "
              "processes shared the two cores during the run)")
        print("\nJSON " + json.dumps({str(k): v for k, v in results.items()}))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
