"""Free kernel, ns per body-step of each integrator (10,000 bodies x 200 steps, one thread, best of
5): run it once against this tree and once against a checkout without the per-step turn bound
(MAX_ROTATION_PER_STEP_RAD, issue 19) to compare, e.g.

    flock -x LOCK sh -c 'PYTHONPATH=OLD NUMBA_CACHE_DIR=C1 python benchmarks/bench_turn_bound.py;
                         NUMBA_CACHE_DIR=C2 python benchmarks/bench_turn_bound.py'

(each line says which rblog it imported).
"""
import sys, time, numpy as np, rblog
from rblog.engine.free import advance_free
from rblog.engine.integrators import METHOD_CODES, ORTHO_ALLOWED, ORTHO_CODES
from rblog.engine.rotation import quat_to_matrix_np
n, steps = 10_000, 200
rng = np.random.default_rng(0)
inertia = rng.uniform(0.5, 2.0, (n, 3)); q = rng.normal(size=(n, 4)); q /= np.linalg.norm(q, axis=1, keepdims=True)
res = {}
for name in ("seed", "seed-quat", "splitting", "rk4", "exact"):
    best = 1e9
    for rep in range(5):
        st = [rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), q.copy(), quat_to_matrix_np(q), rng.normal(size=(n, 3))]
        out = [np.zeros((2, n, 3)), np.zeros((2, n, 3)), np.zeros((2, n, 4)), np.zeros((2, n, 3, 3)), np.zeros((2, n, 3))]
        t = time.perf_counter()
        advance_free(METHOD_CODES[name], ORTHO_CODES[ORTHO_ALLOWED[name][1]], 1e-3, steps, steps, False,
                     np.ones(n), 1.0 / inertia, np.tile([0, 0, -9.81], (n, 1)), np.zeros((n, 3)), *st, *out, n_threads=1)
        best = min(best, time.perf_counter() - t)
    res[name] = best / (n * steps) * 1e9
print(rblog.__file__, " ".join(f"{k} {v:.1f}" for k, v in res.items()), "ns/body-step (1 thread, best of 5)")
