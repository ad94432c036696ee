"""`rblog check` analyzers benchmark: body-samples per second, each analyzer and all together.

Builds a synthetic 100-body log of ~10,000 samples (100 s at 100 Hz, dt = 1e-3) from closed-form
motion, so that it needs no simulator and every analyzer has work to do:

* 34 spheres bouncing elastically (e = 1) on the ground at different heights (exact arcs, with
  logged impact contacts): impacts, restitution, contact energy, free-flight energy;
* 33 boxes resting on the ground (turned about z): resting contacts, depth, jitter, creep;
* 33 boxes spinning steadily about a principal axis, floating (a constant applied force cancels
  gravity): drift, energy with an applied-force potential.

Bodies stand on a 10 x 10 grid, 1.5 m apart, as in a typical scene. The log is clean, so the
analyzers run their full paths without building findings.

    python benchmarks/bench_check.py [--samples 10001] [--bodies 100] [--repeat 3] [--threads 2]
    python benchmarks/bench_check.py --against DIR [--require RATIO] [--samples 2001] [--repeat 7]
    python benchmarks/bench_check.py --against DIR --instructions [--require RATIO]

What is timed: ``rblog.analyze.check`` on the trajectory in memory (the shared Context and every
analyzer, up to the Result objects); not reading a log, not formatting the report. Each analyzer
alone is timed with a fresh Context of its own (what ``rblog check --only NAME`` costs); all
analyzers together on one thread and on ``--threads`` threads side by side, best of ``--repeat``.
The analyzers' kernels are C++ (rblog.analyze._audit, built at install): nothing compiles at run
time, so there is no first-run compile figure any more (the numba version printed one).

Targets: >= 1e6 body-samples per second for all analyzers together on one thread (issue 16),
>= 3e6 on two cores (issue 18).

``--against DIR``: this tree side by side with another checkout of rblog (DIR, built, with its
venv at DIR/.venv unless ``--against-python``; e.g. a worktree of the commit that filed issue
37, 258af21). Each tree checks the same log in a process of its own; the two take turns
(ABBA order), ``--repeat`` checks each, all analyzers on one thread, and the best CPU time of
each is compared. ``--require RATIO`` exits 1 when this tree's body-samples per second are
below RATIO times the other's (issue 37: "as fast as today per body-sample").

``--against DIR --instructions``: the same comparison in instructions (valgrind's callgrind)
instead of CPU time, which a shared machine's load does not move: each tree's worker runs under
``valgrind --tool=callgrind`` twice, once with one steady-state check and once with two, and the
difference is that tree's instructions per check. ``--require RATIO`` then exits 1 when the other
tree's instructions per check are below RATIO times this tree's.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if "--worker" in sys.argv:  # a side of --against: the rblog of the tree named after --worker
    ROOT = Path(sys.argv[sys.argv.index("--worker") + 1]).resolve()
sys.path.insert(0, str(ROOT))

from rblog.analyze import ANALYZERS, check  # noqa: E402
from rblog.analyze.base import Context  # noqa: E402
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE, Model  # noqa: E402
from rblog.contract.trajectory import CONTACT_IMPACT, STATIC_BODY, Contacts, RunInfo, derive  # noqa: E402

G = 9.81


def _rot_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    r = np.zeros(np.shape(angle) + (3, 3))
    r[..., 0, 0], r[..., 0, 1], r[..., 1, 0], r[..., 1, 1], r[..., 2, 2] = c, -s, s, c, 1.0
    return r


def synthetic(n_samples: int = 10_001, n_bodies: int = 100, dt: float = 1e-3, log_every: int = 10):
    rng = np.random.default_rng(1)
    t = np.arange(n_samples) * dt * log_every
    step = np.arange(n_samples, dtype=np.int64) * log_every
    kinds = np.arange(n_bodies) % 3  # 0 bouncing sphere, 1 resting box, 2 spinning box
    shape = np.where(kinds == 0, SHAPE_SPHERE, SHAPE_BOX)
    size = np.where((kinds == 0)[:, None], [0.1, 0.0, 0.0], [0.2, 0.15, 0.1])
    mass = np.ones(n_bodies)
    inertia = np.where((kinds == 0)[:, None], 0.4 * 0.01,
                       mass[:, None] / 3 * np.array([0.15 ** 2 + 0.1 ** 2, 0.2 ** 2 + 0.1 ** 2,
                                                     0.2 ** 2 + 0.15 ** 2]))
    force = np.where((kinds == 2)[:, None], [0.0, 0.0, G], 0.0)
    side = int(np.ceil(np.sqrt(n_bodies)))
    gx, gy = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
    xy = 1.5 * np.stack([gx.ravel(), gy.ravel()], 1)[:n_bodies]
    model = Model(
        body_name=[f"b{i}" for i in range(n_bodies)], body_shape=shape, body_size=size,
        body_mass=mass, body_inertia_diag=inertia, body_force_world=force,
        body_torque_world=np.zeros((n_bodies, 3)), body_restitution=np.ones(n_bodies),
        body_friction=np.full(n_bodies, 0.5), body_group=np.zeros(n_bodies, np.int64),
        gravity=np.array([0.0, 0.0, -G]), ground=True, ground_restitution=1.0,
    )
    T, N = n_samples, n_bodies
    pos = np.zeros((T, N, 3))
    vel = np.zeros((T, N, 3))
    rot = np.broadcast_to(np.eye(3), (T, N, 3, 3)).copy()
    lmom = np.zeros((T, N, 3))
    pos[:, :, :2] = xy[None]
    # bouncing spheres: drop height h, period 2 sqrt(2h/g), phase offset
    b = np.nonzero(kinds == 0)[0]
    h = rng.uniform(0.3, 1.5, len(b))
    v0 = np.sqrt(2 * G * h)
    period = 2 * v0 / G
    phase = rng.uniform(0, 1, len(b)) * period
    tau = np.mod(t[:, None] + phase[None], period[None])  # time since the last impact
    pos[:, b, 2] = 0.1 + v0 * tau - 0.5 * G * tau ** 2
    vel[:, b, 2] = v0 - G * tau
    # resting boxes
    r_ = np.nonzero(kinds == 1)[0]
    pos[:, r_, 2] = 0.1
    rot[:, r_] = _rot_z(rng.uniform(0, np.pi, len(r_)))[None]
    # spinning boxes: about body z (principal), floating at 1.5 m
    s = np.nonzero(kinds == 2)[0]
    w = rng.uniform(1, 6, len(s))
    pos[:, s, 2] = 1.5
    rot[:, s] = _rot_z(w[None] * t[:, None])
    lmom[:, s, 2] = inertia[s, 2] * w
    quat = np.zeros((T, N, 4))
    half = 0.5 * np.arctan2(rot[..., 1, 0], rot[..., 0, 0])  # all rotations are about z
    quat[..., 0], quat[..., 3] = np.cos(half), np.sin(half)
    # impact contacts of the spheres, at the first sample after each impact
    wrapped = np.nonzero(np.diff(tau, axis=0) < 0)
    k1, j = wrapped[0] + 1, wrapped[1]
    kk = len(k1)
    contacts = Contacts(
        step=step[k1], t=t[k1], body_a=b[j], body_b=np.full(kk, STATIC_BODY),
        point=np.concatenate([xy[b[j]], np.zeros((kk, 1))], 1),
        normal=np.tile([0, 0, 1.0], (kk, 1)),
        separation=np.zeros(kk), normal_impulse=2 * v0[j], friction_impulse=np.zeros((kk, 3)),
        kind=np.full(kk, CONTACT_IMPACT, np.int8),
    )
    info = RunInfo(integrator="exact", orthonormalize="none", dt=dt, log_every=log_every,
                   duration_s=float(t[-1]), rblog_version="bench", writer="bench_check.py")
    return derive(model, info, step, t, pos, vel * mass[None, :, None], quat, rot, lmom, contacts)


def worker(samples: int, bodies: int, checks: int | None = None):
    """One side of --against: build the log, then one timed check (one thread) per line read;
    prints "cpu_s wall_s" per check. With ``checks``: that many checks after the warm-up, then
    exit (a run under callgrind for --instructions)."""
    traj = synthetic(samples, bodies)
    check(traj.slice(slice(0, 50)), threads=1)
    check(traj, threads=1)  # warm: the timed checks are the steady state
    if checks is not None:
        for _ in range(checks):
            check(traj, threads=1)
        return
    print("ready", flush=True)
    for _ in sys.stdin:
        c0, w0 = time.process_time(), time.perf_counter()
        check(traj, threads=1)
        print(f"{time.process_time() - c0:.6f} {time.perf_counter() - w0:.6f}", flush=True)


def _commit(root: Path) -> str:
    out = subprocess.run(["git", "-C", str(root), "log", "-1", "--format=%h"],
                         capture_output=True, text=True)
    return out.stdout.strip() or "?"


def _callgrind_total(py: str, root: Path, args, checks: int, out: Path) -> int:
    """Instructions of one worker process (``checks`` checks after the warm-up) under callgrind."""
    from _callgrind import total_instructions

    return total_instructions([py, str(Path(__file__).resolve()), "--worker", str(root),
                               "--samples", str(args.samples), "--bodies", str(args.bodies),
                               "--checks", str(checks)], out, f"bench_check: callgrind of {root}",
                              cwd=str(root))


def instructions(args, other: Path, other_py: str) -> int:
    """--against --instructions: instructions per check of both trees; 1 if below --require."""
    import shutil
    import tempfile
    from concurrent.futures import ThreadPoolExecutor

    if shutil.which("valgrind") is None:
        sys.exit("bench_check: --instructions needs valgrind (apt-get install valgrind)")
    sides = (("this tree", sys.executable, ROOT), ("against", other_py, other))
    with tempfile.TemporaryDirectory() as tmp, ThreadPoolExecutor(2) as pool:
        jobs = {(name, k): pool.submit(_callgrind_total, py, root, args, k,
                                       Path(tmp) / f"cg.{i}.{k}")
                for i, (name, py, root) in enumerate(sides) for k in (1, 2)}
        total = {key: job.result() for key, job in jobs.items()}
    print(f"synthetic log: {args.samples} samples x {args.bodies} bodies; all analyzers, one "
          f"thread; instructions of one steady-state check (callgrind, 2 checks less 1)")
    print(f"{'tree':<10} {'commit':<9} {'M instr/check':>13} {'M instr, 1 check':>17}  root")
    per = {}
    for name, _, root in sides:
        per[name] = total[name, 2] - total[name, 1]
        print(f"{name:<10} {_commit(root):<9} {per[name] / 1e6:13.1f} "
              f"{total[name, 1] / 1e6:17.1f}  {root}")
    return _verdict("against / this tree, instructions per check",
                    per["against"] / per["this tree"], args.require)


def _verdict(what: str, ratio: float, require: float | None) -> int:
    """Print ``what: ratio`` (and whether it meets ``require``); 1 if below ``require``."""
    met = require is None or ratio >= require
    note = "" if require is None else f" (required >= {require:.2f}: {'met' if met else 'NOT met'})"
    print(f"{what}: {ratio:.3f}{note}")
    return 0 if met else 1


def against(args) -> int:
    """This tree and ``args.against`` in turns on the same log; 1 if below ``args.require``."""
    other = Path(args.against).resolve()
    other_py = args.against_python or str(other / ".venv" / "bin" / "python")
    if not (other / "rblog").is_dir() or not Path(other_py).exists():
        sys.exit(f"bench_check: --against {other}: no rblog/ there or no {other_py}")
    if args.instructions:
        return instructions(args, other, other_py)
    sides = {}
    for name, py, root in (("this tree", sys.executable, ROOT), ("against", other_py, other)):
        proc = subprocess.Popen(
            [py, str(Path(__file__).resolve()), "--worker", str(root),
             "--samples", str(args.samples), "--bodies", str(args.bodies)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=str(root),
            env={**os.environ, "SKBUILD_EDITABLE_VERBOSE": "0"})
        if proc.stdout.readline().strip() != "ready":
            sys.exit(f"bench_check: the worker of {root} did not start")
        sides[name] = (proc, root, [])
    order = ["this tree", "against"]
    for r in range(args.repeat):
        for name in (order if r % 2 == 0 else order[::-1]):
            proc, _, times = sides[name]
            proc.stdin.write("run\n")
            proc.stdin.flush()
            times.append(tuple(float(x) for x in proc.stdout.readline().split()))
    for proc, _, _ in sides.values():
        proc.stdin.close()
        proc.wait()
    work = args.samples * args.bodies
    print(f"synthetic log: {args.samples} samples x {args.bodies} bodies = {work:,} body-samples; "
          f"all analyzers, one thread, {args.repeat} checks each in turns")
    print(f"{'tree':<10} {'commit':<9} {'best CPU (s)':>12} {'M body-samples/s':>17} "
          f"{'median CPU (s)':>15}  root")
    rate = {}
    for name, (_, root, times) in sides.items():
        cpu = sorted(c for c, _ in times)
        rate[name] = work / cpu[0]
        print(f"{name:<10} {_commit(root):<9} {cpu[0]:12.4f} {rate[name] / 1e6:17.3f} "
              f"{cpu[len(cpu) // 2]:15.4f}  {root}")
    return _verdict("this tree / against, body-samples per second",
                    rate["this tree"] / rate["against"], args.require)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=None,
                    help="samples of the log (10001; 2001 with --against)")
    ap.add_argument("--bodies", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=None, help="timed runs (3; 7 with --against)")
    ap.add_argument("--threads", type=int, default=2, help="the parallel column's thread count")
    ap.add_argument("--against", metavar="DIR", help="another rblog checkout to time side by side")
    ap.add_argument("--against-python", metavar="PY", help="its python (DIR/.venv/bin/python)")
    ap.add_argument("--require", type=float, metavar="RATIO",
                    help="with --against: exit 1 below RATIO x the other tree's body-samples/s")
    ap.add_argument("--instructions", action="store_true",
                    help="with --against: compare callgrind instructions per check, not CPU time")
    ap.add_argument("--worker", metavar="DIR", help=argparse.SUPPRESS)
    ap.add_argument("--checks", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.samples is None:
        args.samples = 2001 if args.against else 10_001
    if args.repeat is None:
        args.repeat = 7 if args.against else 3
    if args.worker:
        return worker(args.samples, args.bodies, args.checks)
    if args.against:
        sys.exit(against(args))
    traj = synthetic(args.samples, args.bodies)
    work = traj.n_samples * traj.n_bodies
    print(f"synthetic log: {traj.n_samples} samples x {traj.n_bodies} bodies = {work:,} "
          f"body-samples, {len(traj.contacts)} contacts")
    counts = (1, args.threads)
    check(traj.slice(slice(0, 50)), threads=args.threads)  # warm up (imports, thread pool)
    first = []
    for th in counts:
        t0 = time.perf_counter()
        check(traj, threads=th)
        first.append(time.perf_counter() - t0)
    print("first call (fresh memory, as in one `rblog check`): "
          + ", ".join(f"{th} thread{'s' if th > 1 else ''} {el:.3f} s ({work / el / 1e6:.2f} M/s)"
                      for th, el in zip(counts, first)))

    def best(fn):
        times = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            out = fn()
            times.append(time.perf_counter() - t0)
        return min(times), out

    print(f"{'analyzer':<14} {'time (s)':>9} {'body-samples/s':>15}  verdict")
    for name, cls in ANALYZERS.items():
        # alone, with its own shared context (what `rblog check --only NAME` costs)
        el, res = best(lambda: cls().run(traj, Context(traj)))
        verdict = "skip" if res.skipped else ("pass" if res.passed else "FAIL")
        print(f"{name:<14} {el:9.3f} {work / el:15,.0f}  {verdict}: {res.reason[:70]}")
    rows = []
    for th in counts:
        el, res = best(lambda: check(traj, threads=th))
        rows.append((th, el, "clean" if all(r.passed for r in res) else "FLAGGED"))
    print(f"\n{'all together':<14} {'time (s)':>9} {'body-samples/s':>15}  {'target':>11}  verdict")
    for (th, el, verdict), target in zip(rows, (1e6, 3e6)):
        met = "met" if work / el >= target else "NOT met"
        print(f"{f'{th} thread' + ('s' if th > 1 else ''):<14} {el:9.3f} {work / el:15,.0f}  "
              f">= {target / 1e6:.0f} M/s {met:>7}  {verdict}")
    print(f"speed-up 1 -> {args.threads} threads: {rows[0][1] / rows[1][1]:.2f}x")


if __name__ == "__main__":
    main()
