"""Engine recording benchmark: what recording a MuJoCo or pybullet run costs next to the engine's
own stepping, at the default log rate (100 samples per simulated second), on every sample scene;
and what rblog's own run costs when it records through rblog.Recorder instead of the writers.

    python benchmarks/bench_engines.py [--engine mujoco --engine pybullet] [--scene NAME ...]
                                       [--duration S] [--runner-only | --no-runner]
    python benchmarks/bench_engines.py --diff [--engine mujoco] [--scene NAME ...] [--png-dir D]

Per scene and engine (best of --repeats, CPU time of this process):

* ``step``: the engine stepping the scene alone (the same calls, nothing read back);
* ``recorded``: the run as ``rblog run --engine`` does it: stepping, reading state and contacts,
  deriving, writing .rrd and .mcap;
* ``record cost`` = recorded - step, and its ratio to step (target: <= 1, i.e. recording costs at
  most as much as the engine's own stepping).

``--diff``: ``rblog diff`` of rblog's run (its defaults) against each engine's run of every sample
(full duration, default log rate): the largest position and orientation divergence, how many
bodies leave the default tolerances (1 cm, 0.1 rad) and when the first does, the median growth
rate, and the final total energy of both. Not a timing: run it under the shared lock.

Runner section: ``rblog.run`` of bench_logging's 100 free bodies logging every step to both formats,
with the writers handed to the run directly vs each wrapped in an rblog.Recorder (what ``rblog run``
passes); the target is no measurable difference.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

import rblog  # noqa: E402
from rblog.record import McapRecorder, RerunRecorder  # noqa: E402
from rblog.record.recorder import Recorder  # noqa: E402
from rblog.study.engines import run_engine  # noqa: E402

SAMPLES = Path(__file__).resolve().parents[1] / "samples"


def cpu_best(fn, repeats):
    best = float("inf")
    out = None
    for _ in range(repeats):
        t0 = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t0)
    return best, out


def step_only(scene, engine, duration):
    from rblog.study.engines.mujoco import MujocoRun
    from rblog.study.engines.pybullet import PybulletRun

    cls = MujocoRun if engine == "mujoco" else PybulletRun
    run = cls(scene, scene.sim.dt)
    try:
        n = max(1, round(duration / scene.sim.dt))
        stride = max(1, round(1.0 / (100.0 * scene.sim.dt)))  # the same calls as the recorded run
        done = 0
        while done < n:
            k = min(stride, n - done)
            run.step(k)
            done += k
    finally:
        run.close()


def engines_table(engines, scenes, duration, repeats, tmp):
    print(f"{'scene':<16} {'engine':<9} {'bodies':>6} {'steps':>6} {'step s':>8} {'recorded s':>10} "
          f"{'record s':>9} {'record/step':>11}")
    rows = []
    for name in scenes:
        scene = rblog.load_scene(str(SAMPLES / f"{name}.toml"))
        dur = scene.sim.duration if duration is None else min(duration, scene.sim.duration)
        for engine in engines:
            rrd, mcap = os.path.join(tmp, "e.rrd"), os.path.join(tmp, "e.mcap")
            run_engine(scene, engine, duration=min(dur, 0.05), rrd=rrd, mcap=mcap)  # warm
            t_step, _ = cpu_best(lambda: step_only(scene, engine, dur), repeats)
            t_rec, summary = cpu_best(lambda: run_engine(scene, engine, duration=dur, rrd=rrd,
                                                         mcap=mcap)[0], repeats)
            cost = t_rec - t_step
            rows.append((name, engine, t_step, t_rec))
            print(f"{name:<16} {engine:<9} {summary.bodies:>6} {summary.steps:>6} {t_step:>8.3f} "
                  f"{t_rec:>10.3f} {cost:>9.3f} {cost / t_step if t_step > 0 else float('inf'):>11.2f}",
                  flush=True)
    return rows


def runner_table(repeats, tmp):
    text = (Path(__file__).resolve().parent / "bench_logging.py").read_text()
    start = text.index('SCENE = """') + len('SCENE = """')
    scene_text = text[start:text.index('"""', start)].format(duration=2.0, nx=10, ny=10)
    scene = rblog.parse_scene(scene_text, "bench_logging free bodies")
    rrd, mcap = os.path.join(tmp, "r.rrd"), os.path.join(tmp, "r.mcap")

    def direct():
        rblog.run(scene, log_every=1, recorders=[RerunRecorder(rrd), McapRecorder(mcap)])

    def wrapped():
        rblog.run(scene, log_every=1, recorders=[Recorder(writers=[RerunRecorder(rrd)]),
                                                 Recorder(writers=[McapRecorder(mcap)])])

    def none():
        rblog.run(scene, log_every=1)

    direct()
    wrapped()
    t_none, _ = cpu_best(none, repeats)
    res = {}
    for _ in range(2):  # interleave, so that drifting machine load hits both
        for label, fn in (("writers directly", direct), ("through rblog.Recorder", wrapped)):
            t, _ = cpu_best(fn, repeats)
            res[label] = min(res.get(label, float("inf")), t)
    print(f"\nrblog.run, 100 free bodies, 2000 steps, every step logged to .rrd + .mcap (CPU s, best of "
          f"{2 * repeats}); no logs: {t_none:.3f} s")
    for label, t in res.items():
        print(f"  {label:<24} {t:.3f} s  ({t / t_none:.2f}x the run without logs)")
    d, w = res["writers directly"], res["through rblog.Recorder"]
    print(f"  Recorder / direct: {w / d:.3f}")


def diff_table(engines, scenes, duration, tmp, png_dir=None):
    from rblog.analyze.diff import diff, plot

    print(f"{'scene':<16} {'vs':<9} {'bodies':>6} {'max |dx| m':>10} {'max angle':>9} "
          f"{'leave tol':>9} {'first s':>8} {'growth 1/s':>10} {'E rblog J':>10} {'E engine J':>10}")
    for name in scenes:
        scene = rblog.load_scene(str(SAMPLES / f"{name}.toml"))
        kw = {} if duration is None else {"duration": min(duration, scene.sim.duration)}
        a_path = os.path.join(tmp, f"{name}-rblog.mcap")
        rblog.run(scene, recorders=[McapRecorder(a_path)], **kw)
        a = rblog.load(a_path)
        for engine in engines:
            b_path = os.path.join(tmp, f"{name}-{engine}.mcap")
            run_engine(scene, engine, mcap=b_path, **kw)
            r = diff(a, rblog.load(b_path), label_a=f"{name} rblog", label_b=f"{name} {engine}")
            firsts = [b.first_exceed_t for b in r.bodies if b.first_exceed_t is not None]
            rates = [b.growth_rate_per_s for b in r.bodies if b.growth_rate_per_s is not None]
            e = r.totals["total_energy"]
            print(f"{name:<16} {engine:<9} {len(r.bodies):>6} {r.position.max():>10.3g} "
                  f"{r.angle.max():>9.3g} {r.n_exceed:>9} "
                  f"{min(firsts) if firsts else float('nan'):>8.3g} "
                  f"{float(np.median(rates)) if rates else float('nan'):>10.3g} "
                  f"{e['a_last'][0]:>10.4g} {e['b_last'][0]:>10.4g}", flush=True)
            if png_dir:
                os.makedirs(png_dir, exist_ok=True)
                plot(r, os.path.join(png_dir, f"{name}-rblog-vs-{engine}.png"))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--engine", action="append", choices=["mujoco", "pybullet"])
    ap.add_argument("--scene", action="append")
    ap.add_argument("--duration", type=float, help="cap each scene's duration (s)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--runner-only", action="store_true")
    ap.add_argument("--no-runner", action="store_true")
    ap.add_argument("--diff", action="store_true", help="rblog diff of rblog vs each engine instead")
    ap.add_argument("--png-dir", help="with --diff: write each diff's plot here")
    a = ap.parse_args()
    engines = a.engine or ["mujoco", "pybullet"]
    scenes = a.scene or sorted(p.stem for p in SAMPLES.glob("*.toml"))
    with tempfile.TemporaryDirectory() as tmp:
        if a.diff:
            return diff_table(a.engine or ["mujoco"], scenes, a.duration, tmp, a.png_dir)
        if not a.runner_only:
            engines_table(engines, scenes, a.duration, a.repeats, tmp)
        if not a.no_runner:
            runner_table(a.repeats, tmp)


if __name__ == "__main__":
    main()
