"""Free-body kernel speed per integrator on one and two threads, side by side with another
version of rblog.

ns per body-step of ``free.advance_free`` (wall time), best of 3 (after a warm-up call), on one
and two threads in alternation, in two sampling regimes: sparse (10,000 bodies, 100 steps, one
sample: the lane kernels, several bodies per vector) and dense (1,000 bodies, 200 steps, every
step sampled: the tiled path). The 1-thread figure is also given in CPU time (the process's),
steadier than wall time on a shared machine; the load average is printed beside the figures.

    python benchmarks/bench_free_kernel.py [--compare PYTHON] [--integrators seed,rk4,...]

``--compare PYTHON`` runs the same measurement with another interpreter, whose ``import rblog``
is another version of rblog (e.g. the .venv of a worktree of main, built), in alternation with
this tree's: other, this tree, other, this tree.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ALL = "seed,seed-quat,splitting,rk4,exact,exact4"
CASES = (("sparse", 10_000, 100, 100), ("dense", 1_000, 200, 1))


def measure(integrators: list[str]) -> dict:
    import numpy as np

    from rblog.engine.free import advance_free
    from rblog.engine.integrators import METHOD_CODES, ORTHO_ALLOWED, ORTHO_CODES
    from rblog.engine.rotation import quat_to_matrix_np

    out = {}
    for integ in integrators:
        for case, n, steps, stride in CASES:
            rng = np.random.default_rng(0)
            inertia = rng.uniform(0.5, 2.0, (n, 3))
            q = rng.normal(size=(n, 4))
            q /= np.linalg.norm(q, axis=1, keepdims=True)
            params = [np.ones(n), 1.0 / inertia, np.zeros((n, 3)) + [0, 0, -9.81], np.zeros((n, 3))]
            state0 = [rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), q, quat_to_matrix_np(q),
                      rng.normal(size=(n, 3)) * 2.0]
            ns = steps // stride + 1
            bufs = [np.empty((ns, n, 3)), np.empty((ns, n, 3)), np.empty((ns, n, 4)),
                    np.empty((ns, n, 3, 3)), np.empty((ns, n, 3))]
            ortho = ORTHO_CODES[ORTHO_ALLOWED[integ][1]]
            best = {1: float("inf"), 2: float("inf"), "cpu": float("inf")}
            for r in range(4):  # the first round loads (or compiles) the kernel
                for threads in (1, 2):
                    st = [a.copy() for a in state0]
                    c0 = time.process_time()
                    t0 = time.perf_counter()
                    advance_free(METHOD_CODES[integ], ortho, 1e-3, steps, stride, False, *params,
                                 *st, *bufs, n_threads=threads)
                    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
                    if r:
                        best[threads] = min(best[threads], wall)
                        if threads == 1:
                            best["cpu"] = min(best["cpu"], cpu)
            for k, v in best.items():
                out[f"{integ}/{case}/{k}"] = v / (n * steps) * 1e9
    out["load"] = os.getloadavg()[0]
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--compare", metavar="REF")
    ap.add_argument("--integrators", default=ALL)
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    integrators = args.integrators.split(",")
    if args.worker:
        print(json.dumps(measure(integrators)))
        return
    with tempfile.TemporaryDirectory() as tmp:
        versions = [("this tree", sys.executable, str(ROOT))]
        if args.compare:
            versions.insert(0, ("other", args.compare, None))
        results = {label: [] for label, *_ in versions}
        for _ in range(2):
            for label, python, pythonpath in versions:
                env = dict(os.environ)
                env.pop("PYTHONPATH", None)
                if pythonpath:
                    env["PYTHONPATH"] = pythonpath
                res = subprocess.run([python, __file__, "--worker", "--integrators",
                                      args.integrators], env=env, check=True, capture_output=True,
                                     text=True, cwd=tmp)
                results[label].append(json.loads(res.stdout))
    loads = [r["load"] for label, *_ in versions for r in results[label]]
    if args.compare:
        print(f"other: {args.compare}")
    print("ns per body-step: 1 thread (wall and CPU time), 2 threads (wall), and the speed-up; "
          "best of 3 per process, best of the 2 processes; load average "
          f"{min(loads):.1f}-{max(loads):.1f} on {os.cpu_count()} CPUs")
    cols = ("1 thr", "1 thr cpu", "2 thr", "speed-up")
    print(f"{'integrator':<12}{'case':<8}" + "".join(
        f"{label[:16] + ' ' + c:>{max(12, len(label[:16]) + len(c) + 2)}}" for label, *_ in versions
        for c in cols))
    for integ in integrators:
        for case, *_ in CASES:
            row = f"{integ:<12}{case:<8}"
            for label, *_ in versions:
                one, cpu, two = (min(r[f"{integ}/{case}/{k}"] for r in results[label])
                                 for k in ("1", "cpu", "2"))
                for c, v in zip(cols, (one, cpu, two, one / two)):
                    w = max(12, len(label[:16]) + len(c) + 2)
                    row += f"{v:>{w}.2f}x" if c == "speed-up" else f"{v:>{w}.1f}"
            print(row)


if __name__ == "__main__":
    main()
