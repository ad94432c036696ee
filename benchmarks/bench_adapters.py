"""What recording costs through the engine adapters: the bare step loop against the same loop
recording a sample at every step, by CPU time (``time.process_time``), interleaved.

    python benchmarks/bench_adapters.py [--pairs N] [--steps N] [--every K] [--case NAME ...]
        [--mode memory|mcap] [--mcap-compression lz4|zstd|none]
    python benchmarks/bench_adapters.py --instructions [--case NAME ...] [--mode ...]
        [--require-at-most RATIO]

Each case is a row of ``CASES``: a function of the step count and the sample stride (``every``:
a sample every K steps, the impulses of every step summed into it) that builds its world and
returns ``(bare, recorded)``, two callables of the output mode (``"memory"``: the run kept in memory,
no file; ``"mcap"``: an MCAP file written) that each run the step loop once and return nothing.
A pair is one bare run and one recorded run in alternating order (A B, B A, ...), so the load
of a shared machine hits both alike; the table gives each pair's CPU seconds and ratio, then the
median ratio per case and mode. Add a row with ``@case("engine/world")``.

In MCAP mode the table also gives the CPU time spent inside the MCAP writer (``McapRecorder``'s
``open``, ``write`` and ``close``: encoding, compression, CRCs, the file's writes), so a run shows
how much of the recording is the log's bytes and how much is the adapter.

``--instructions``: the same ratio in instructions, which a shared machine's load does not move
(valgrind's callgrind; CI's guard of the recording cost, .ci/run). Each of the bare and the
recorded loop runs in a worker process under callgrind, once with one run after a warm-up run and
once with two; the difference is one steady-state run (setup and ``close()`` counted).
``--require-at-most RATIO`` then exits 1 when a case's recorded / bare ratio is above RATIO.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

MODES = ("memory", "mcap")
#: the MCAP chunk compression of the recorded runs (Recorder's mcap_compression; --mcap-compression)
OPTIONS = {"mcap_compression": "lz4"}
#: name -> builder(steps, every, tmp) -> (bare(mode), recorded(mode))
CASES: dict = {}


def case(name: str):
    """Register a row: ``@case("mujoco/humanoid") def build(steps, every, tmp): ...``."""
    def register(fn):
        CASES[name] = fn
        return fn
    return register


def _mujoco_case(model_name: str):
    def build(steps: int, every: int, tmp: str):
        import mujoco
        import numpy as np

        import rblog.adapters.mujoco as adapter

        m = adapter.suite_model(model_name)
        rng = np.random.default_rng(0)
        ctrl = rng.uniform(-1.0, 1.0, (steps, m.nu))  # the same random controls in both loops

        def start():
            d = mujoco.MjData(m)
            mujoco.mj_forward(m, d)
            return d

        def bare(mode):
            d = start()
            for k in range(steps):
                d.ctrl[:] = ctrl[k]
                mujoco.mj_step(m, d)

        def recorded(mode):
            d = start()
            out = {"mcap": str(Path(tmp) / f"{model_name}.mcap"),
                   "mcap_compression": OPTIONS["mcap_compression"]} if mode == "mcap" else {}
            rec = adapter.recorder(m, d, every=every, keep=mode == "memory", **out)
            for k in range(steps):
                d.ctrl[:] = ctrl[k]
                mujoco.mj_step(m, d)
                rec(d)
            rec.close()

        return bare, recorded
    return build


case("mujoco/humanoid")(_mujoco_case("humanoid"))
case("mujoco/stacker")(_mujoco_case("stacker"))


def _pybullet_case(world: str):
    def build(steps: int, every: int, tmp: str):
        import pybullet as pb

        import rblog.adapters.pybullet as adapter

        def run(rec_options):  # each run loads the world into a fresh client, in both loops
            cid = pb.connect(pb.DIRECT)
            try:
                adapter.load_shipped(world, cid)
                rec = None if rec_options is None else adapter.PybulletRecorder(cid, **rec_options)
                for _ in range(steps):
                    pb.stepSimulation(physicsClientId=cid)
                    if rec is not None:
                        rec()
                if rec is not None:
                    rec.close()
            finally:
                pb.disconnect(physicsClientId=cid)

        def bare(mode):
            run(None)

        def recorded(mode):
            out = {"mcap": str(Path(tmp) / f"{world}.mcap"),
                   "mcap_compression": OPTIONS["mcap_compression"]} if mode == "mcap" else \
                {"keep": True}
            run(dict(every=every, **out))

        return bare, recorded
    return build


case("pybullet/jenga")(_pybullet_case("jenga"))


#: CPU seconds spent inside McapRecorder's open, write and close since the last reset
WRITER_CPU = [0.0]


def _time_mcap_writer() -> None:
    """Wrap McapRecorder's open, write and close so that each adds its CPU time to WRITER_CPU."""
    from rblog.record.mcap_writer import McapRecorder

    def timed(fn):
        def wrapper(*args, **kwargs):
            c0 = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                WRITER_CPU[0] += time.process_time() - c0
        wrapper.__wrapped__ = fn
        return wrapper

    for name in ("open", "write", "close"):
        fn = getattr(McapRecorder, name)
        if not hasattr(fn, "__wrapped__"):
            setattr(McapRecorder, name, timed(fn))


def worker(name: str, mode: str, which: str, runs: int, steps: int, every: int) -> None:
    """One process of --instructions: a warm-up run of the bare or the recorded loop, then
    ``runs`` more."""
    with tempfile.TemporaryDirectory() as tmp:
        bare, recorded = CASES[name](steps, every, tmp)
        fn = recorded if which == "recorded" else bare
        for _ in range(1 + runs):
            fn(mode)


def _callgrind_total(args, name: str, mode: str, which: str, runs: int, out: Path) -> int:
    """Instructions of one worker process under callgrind."""
    from _callgrind import total_instructions

    return total_instructions([sys.executable, str(Path(__file__).resolve()), "--worker", name,
                               mode, which, str(runs), "--steps", str(args.steps), "--every",
                               str(args.every)], out,
                              f"bench_adapters: callgrind of {name} {mode} {which}")


def instructions(args, names, modes) -> int:
    """--instructions: recorded / bare instructions of one steady-state run per case and mode;
    1 if a ratio is above --require-at-most."""
    import shutil
    from concurrent.futures import ThreadPoolExecutor

    if shutil.which("valgrind") is None:
        sys.exit("bench_adapters: --instructions needs valgrind (apt-get install valgrind)")
    print(f"instructions of one run of {args.steps} steps (callgrind, 2 runs less 1 after a "
          f"warm-up; a sample every {args.every} steps)")
    print(f"  {'case':<20} {'mode':<7} {'bare M':>9} {'recorded M':>11} {'ratio':>7}")
    worst = 0.0
    with tempfile.TemporaryDirectory() as tmp, ThreadPoolExecutor(2) as pool:
        for name in names:
            for mode in modes:
                jobs = {(w, k): pool.submit(_callgrind_total, args, name, mode, w, k,
                                            Path(tmp) / f"cg.{w}.{k}")
                        for w in ("bare", "recorded") for k in (1, 2)}
                t = {key: job.result() for key, job in jobs.items()}
                bare = t["bare", 2] - t["bare", 1]
                rec = t["recorded", 2] - t["recorded", 1]
                worst = max(worst, rec / bare)
                print(f"  {name:<20} {mode:<7} {bare / 1e6:9.1f} {rec / 1e6:11.1f} "
                      f"{rec / bare:6.3f}x")
                sys.stdout.flush()
    if args.require_at_most is None:
        return 0
    met = worst <= args.require_at_most
    print(f"worst recorded / bare: {worst:.3f}x (required <= {args.require_at_most:.3f}: "
          f"{'met' if met else 'NOT met'})")
    return 0 if met else 1


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=5)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--every", type=int, default=1, help="a sample every K steps (default 1)")
    ap.add_argument("--case", action="append", choices=sorted(CASES), help="default: every case")
    ap.add_argument("--mode", action="append", choices=MODES, help="default: both")
    ap.add_argument("--mcap-compression", choices=("lz4", "zstd", "none"), default="lz4",
                    help="the MCAP chunk compression (default lz4, the Recorder's)")
    ap.add_argument("--instructions", action="store_true",
                    help="compare callgrind instructions, not CPU time")
    ap.add_argument("--require-at-most", type=float, default=None, metavar="RATIO",
                    help="with --instructions: exit 1 when a recorded / bare ratio is above RATIO")
    ap.add_argument("--worker", nargs=4, metavar=("CASE", "MODE", "WHICH", "RUNS"),
                    help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    OPTIONS["mcap_compression"] = args.mcap_compression
    if args.worker:
        name, mode, which, runs = args.worker
        worker(name, mode, which, int(runs), args.steps, args.every)
        return 0
    names = args.case or list(CASES)
    modes = args.mode or list(MODES)
    if args.instructions:
        return instructions(args, names, modes)
    print(f"CPU seconds of {args.steps} steps, bare loop vs recording (a sample every "
          f"{args.every} steps); {args.pairs} interleaved pairs")
    print(f"  {'case':<20} {'mode':<7} {'pair':>4} {'bare s':>8} {'recorded s':>10} {'ratio':>6}"
          f" {'in MCAP writer s':>17}")
    _time_mcap_writer()
    summary = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            bare, recorded = CASES[name](args.steps, args.every, tmp)
            for mode in modes:
                recorded(mode)  # warm: imports, first-call costs
                bare(mode)
                ratios, shares = [], []
                for k in range(args.pairs):
                    order = (bare, recorded) if k % 2 == 0 else (recorded, bare)
                    cpu = {}
                    for fn in order:
                        WRITER_CPU[0] = 0.0
                        c0 = time.process_time()
                        fn(mode)
                        cpu[fn] = time.process_time() - c0
                        if fn is recorded:
                            writer = WRITER_CPU[0]
                    ratios.append(cpu[recorded] / cpu[bare])
                    shares.append(writer / cpu[bare])
                    print(f"  {name:<20} {mode:<7} {k:>4} {cpu[bare]:>8.3f} {cpu[recorded]:>10.3f} "
                          f"{ratios[-1]:>6.2f}" + (f" {writer:>17.3f}" if mode == "mcap" else ""))
                    sys.stdout.flush()
                summary.append((name, mode, statistics.median(ratios), min(ratios), max(ratios),
                                statistics.median(shares)))
    print("median ratio (recorded / bare CPU), [min, max]; MCAP: the writer's median share of the "
          "bare loop's CPU:")
    for name, mode, med, lo, hi, share in summary:
        print(f"  {name:<20} {mode:<7} {med:.2f}x  [{lo:.2f}, {hi:.2f}]"
              + (f"  writer {share:.2f}x of bare" if mode == "mcap" else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
