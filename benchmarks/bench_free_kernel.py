"""Free-body kernel speed per integrator, one thread, side by side with another version of rblog.

ns per body-step of ``free.advance_free`` on one thread, best of 3 (after a warm-up call), in two
sampling regimes: sparse (10,000 bodies, 100 steps, one sample: the one-body-at-a-time path) and
dense (1,000 bodies, 200 steps, every step sampled: the tiled path).

    python benchmarks/bench_free_kernel.py [--compare REF] [--integrators seed,rk4,...]

``--compare REF`` runs the same measurement on that git commit of rblog (exported as in
bench_firstrun.py) in alternation with this tree: REF, this tree, REF, this tree.
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
            best = float("inf")
            for r in range(4):  # the first call loads (or compiles) the kernel
                st = [a.copy() for a in state0]
                t0 = time.perf_counter()
                advance_free(METHOD_CODES[integ], ortho, 1e-3, steps, stride, False, *params, *st,
                             *bufs, n_threads=1)
                if r:
                    best = min(best, time.perf_counter() - t0)
            out[f"{integ}/{case}"] = best / (n * steps) * 1e9
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
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_firstrun import export

    with tempfile.TemporaryDirectory() as tmp:
        versions = [("this tree", None)]
        if args.compare:
            versions.insert(0, (args.compare, export(args.compare, Path(tmp))))
        results = {label: [] for label, _ in versions}
        for _ in range(2):
            for label, pythonpath in versions:
                env = dict(os.environ)
                env["PYTHONPATH"] = pythonpath or str(ROOT)
                res = subprocess.run([sys.executable, __file__, "--worker", "--integrators",
                                      args.integrators], env=env, check=True, capture_output=True,
                                     text=True, cwd=tmp)
                results[label].append(json.loads(res.stdout))
    print("ns per body-step, one thread, best of 3 per process, best of the 2 processes")
    print(f"{'integrator':<12}{'case':<8}" + "".join(f"{label:>14}" for label, _ in versions))
    for integ in integrators:
        for case, *_ in CASES:
            key = f"{integ}/{case}"
            print(f"{integ:<12}{case:<8}" + "".join(
                f"{min(r[key] for r in results[label]):>14.1f}" for label, _ in versions))


if __name__ == "__main__":
    main()
