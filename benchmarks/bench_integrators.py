"""Engine-core benchmark: ns per body-step of every integrator at 1, 100 and 10,000 free bodies,
side by side with the comparators (the same `seed` step in pure numpy, vectorized over bodies, and
MuJoCo's Euler and RK4 on the same free bodies when MuJoCo is installed), the exact integrator's
error at every step size from 1e-4 to 1 s on both torque-free problems, accuracy for cost on the
tumbling box, and the start-up time of `rblog run` (first and second run; the kernels are C++,
rblog.engine._core, so nothing compiles at run time any more).

    python benchmarks/bench_integrators.py [--quick]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rblog.engine.free import advance_free  # noqa: E402
from rblog.engine.integrators import METHOD_CODES, ORTHO_ALLOWED, ORTHO_CODES  # noqa: E402
from rblog.engine.scene import parse_scene  # noqa: E402
from rblog.engine.runner import simulate  # noqa: E402


def random_bodies(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    inertia = rng.uniform(0.5, 2.0, (n, 3))
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    from rblog.engine.rotation import quat_to_matrix_np

    return dict(
        inv_mass=np.ones(n), inv_inertia=1.0 / inertia, force=np.zeros((n, 3)) + [0, 0, -9.81],
        torque=np.zeros((n, 3)), position=rng.normal(size=(n, 3)), momentum=rng.normal(size=(n, 3)),
        quat=q, rot=quat_to_matrix_np(q), L=rng.normal(size=(n, 3)) * 2.0,
    )


def time_kernel(integrator: str, n: int, steps: int, repeats: int = 3, threads=None, cpu=False):
    """Best-of-repeats ns per body-step of advance_free (one sample at the end), wall time; with
    ``cpu`` also the best process CPU time, as (wall, cpu)."""
    b = random_bodies(n)
    ortho = ORTHO_CODES[ORTHO_ALLOWED[integrator][1]]
    out = [np.empty((1, n, 3)), np.empty((1, n, 3)), np.empty((1, n, 4)), np.empty((1, n, 3, 3)),
           np.empty((1, n, 3))]
    best = best_cpu = np.inf
    for _ in range(repeats):
        st = [b["position"].copy(), b["momentum"].copy(), b["quat"].copy(), b["rot"].copy(), b["L"].copy()]
        c0 = time.process_time()
        t0 = time.perf_counter()
        advance_free(METHOD_CODES[integrator], ortho, 1e-3, steps, steps, False, b["inv_mass"],
                     b["inv_inertia"], b["force"], b["torque"], *st, *out, n_threads=threads)
        best = min(best, time.perf_counter() - t0)
        best_cpu = min(best_cpu, time.process_time() - c0)
    if cpu:
        return best / (n * steps) * 1e9, best_cpu / (n * steps) * 1e9
    return best / (n * steps) * 1e9


def numpy_seed_step_ns(n: int, steps: int) -> float:
    """The notes' step in plain numpy, vectorized over bodies (the comparator)."""
    b = random_bodies(n)
    x, p, r, lw = b["position"].copy(), b["momentum"].copy(), b["rot"].copy(), b["L"].copy()
    f, im, ii, h = b["force"], b["inv_mass"][:, None], b["inv_inertia"], 1e-3
    t0 = time.perf_counter()
    for _ in range(steps):
        p += h * f
        x += h * p * im
        lb = np.einsum("nji,nj->ni", r, lw) * ii
        w = np.einsum("nij,nj->ni", r, lb)
        wx = np.zeros((n, 3, 3))
        wx[:, 0, 1], wx[:, 0, 2], wx[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
        wx[:, 1, 0], wx[:, 2, 0], wx[:, 2, 1] = w[:, 2], -w[:, 1], w[:, 0]
        r = r + h * wx @ r
        u, _, vt = np.linalg.svd(r)
        r = u @ vt
    return (time.perf_counter() - t0) / (n * steps) * 1e9


def mujoco_step_ns(n: int, steps: int, integrator: str, repeats: int = 3) -> float | None:
    """Best-of-repeats ns per body-step of MuJoCo stepping n free boxes (no contacts, gravity on)
    with one mj_step(nstep=steps) call; None when MuJoCo is not installed. (balanceinertia: the
    random moments of random_bodies need not satisfy the triangle inequality MuJoCo checks.)"""
    try:
        import mujoco
    except ImportError:
        return None
    b = random_bodies(n)
    inertia = 1.0 / b["inv_inertia"]
    bodies = "".join(
        f'<body pos="{i} 0 0"><freejoint/><inertial pos="0 0 0" mass="1" '
        f'diaginertia="{float(inertia[i, 0])!r} {float(inertia[i, 1])!r} {float(inertia[i, 2])!r}"/>'
        f'<geom type="box" size="0.1 0.1 0.1"/></body>' for i in range(n))
    xml = (f'<mujoco><compiler balanceinertia="true"/><option timestep="0.001" integrator="{integrator}"><flag contact="disable"/>'
           f'</option><worldbody>{bodies}</worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    best = np.inf
    for _ in range(repeats):
        d = mujoco.MjData(m)
        for i in range(n):
            d.qvel[6 * i + 3:6 * i + 6] = b["inv_inertia"][i] * b["L"][i]
        t0 = time.perf_counter()
        mujoco.mj_step(m, d, nstep=steps)
        best = min(best, time.perf_counter() - t0)
    return best / (n * steps) * 1e9


def exact_dt_sweep(quick: bool):
    """(problem, dt, omega error, attitude error) of the exact integrator against the closed-form
    reference (rblog.study.reference.TorqueFree) on the two torque-free problems of rblog bench."""
    from rblog.study.bench import run_rblog
    from rblog.study.reference import get_problem

    rows = []
    dts = (1.0, 0.1, 1e-2, 1e-3, 1e-4) if not quick else (1.0, 1e-2)
    for name in ("torque-free-generic", "torque-free-intermediate"):
        p = get_problem(name)
        for dt in dts:
            r = run_rblog(p, "exact", dt, timing=False)
            rows.append((name, dt, r["omega_rel"], r["angle_rad"]))
    return rows


TUMBLING = """
[sim]
dt = {dt}
duration = 20.0
gravity = [0, 0, 0]
[[body]]
shape = "box"
half_extents = [0.3, 0.2, 0.1]
mass = 1.0
inertia_diag = [1.0, 2.0, 3.0]
angular_velocity_body = [0.05, 2.0, 0.05]
"""


def exact_omega_y_flips():
    """Sign changes of omega_y in [0, 20] s from the Jacobi-elliptic solution (scipy)."""
    from scipy.special import ellipk

    i1, i2, i3 = 1.0, 2.0, 3.0
    w0 = np.array([0.05, 2.0, 0.05])
    e2 = np.sum(np.array([i1, i2, i3]) * w0**2)   # 2E
    l2 = np.sum((np.array([i1, i2, i3]) * w0) ** 2)
    # L^2 > 2E I2: omega_1 oscillates (dn), omega_2 and omega_3 are sn/cn-like
    lam = np.sqrt((i3 - i2) * (l2 - e2 * i1) / (i1 * i2 * i3))
    k2 = (i2 - i1) * (e2 * i3 - l2) / ((i3 - i2) * (l2 - e2 * i1))
    K = ellipk(k2)
    # omega_2 = w2max * sn(lam t + t0) up to sign; zeros at lam t + t0 = 2 K j
    w2max = np.sqrt((e2 * i3 - l2) / (i2 * (i3 - i2)))
    # phase: sn(t0) = w0[1]/w2max with the right quadrant (omega_2 decreasing? check cn sign)
    from scipy.special import ellipkinc

    u0 = ellipkinc(np.arcsin(np.clip(w0[1] / w2max, -1, 1)), k2)
    # omega_2 is at (near) its maximum: u0 ~ K; zeros at u = 2K, 4K, ...
    zeros = [(2 * K * j - u0) / lam for j in range(1, 10)]
    return [z for z in zeros if 0 < z < 20]


def flip_times(traj):
    wb = np.einsum("tji,tj->ti", traj.rotation[:, 0], traj.angular_velocity[:, 0])
    s = np.sign(wb[:, 1])
    idx = np.nonzero(s[1:] != s[:-1])[0]
    t = traj.t
    # linear interpolation of the zero crossing
    return [t[i] - wb[i, 1] * (t[i + 1] - t[i]) / (wb[i + 1, 1] - wb[i, 1]) for i in idx]


def accuracy_for_cost(quick: bool):
    exact = exact_omega_y_flips()
    rows = []
    dts = [2e-2, 1e-2, 5e-3, 2e-3, 1e-3] if not quick else [1e-2, 2e-3]
    for integ in METHOD_CODES:
        for dt in dts:
            scene = parse_scene(TUMBLING.format(dt=dt), "tumbling")
            traj, summ = simulate(scene, integrator=integ, log_every=1)
            ns = time_kernel(integ, 1, int(round(20 / dt)), repeats=2)
            flips = flip_times(traj)
            if len(flips) == len(exact):
                err = max(abs(a - b) for a, b in zip(flips, exact))
            else:
                err = float("inf")
            rows.append((integ, dt, ns * 20 / dt * 1e-9 * 1e3, err, summ.energy_drift_rel, len(flips)))
    return exact, rows


def thread_scaling(steps: int):
    """ns per body-step on 10,000 free bodies with 1 and 2 threads (wall time, best of 3 calls of
    each, the two thread counts in alternation), the speed-up, and the 1-thread figure in CPU
    time (steadier than wall time on a shared machine); MuJoCo's Euler and RK4 on one thread
    beside them (at 100 bodies: its default arena does not hold 10,000 free bodies). The exact
    integrators carry their flow anchors within each timed call (one call of ``steps`` steps:
    every body-step after the first evaluates the flow from the anchor with its cached
    constants). The partition is static (free.body_ranges: one contiguous BODY_TILE-aligned
    range per thread), so the speed-up measures the machine: with other processes on its
    cores it falls below 2 whatever the kernel does (the load average is printed)."""
    from rblog.engine import _core

    top = _core.hardware_threads()
    print(f"10,000 free bodies, {steps} steps, ns per body-step (best of 3, 1 and 2 threads "
          f"alternating); {top} hardware threads, load average {os.getloadavg()[0]:.1f}, "
          f"{_core.free_lanes()} bodies per vector")
    print("  (cpu: the process's CPU time per body-step; 2-thread cpu / 1-thread cpu near 1 means "
          "the second thread adds no work: no false sharing, no waiting)")
    print(f"{'integrator':<12}{'1 thread':>10}{'1 thr cpu':>11}{'2 threads':>11}{'2 thr cpu':>11}"
          f"{'speed-up':>10}{'cpu ratio':>11}")
    for integ in METHOD_CODES:
        time_kernel(integ, 1, 10)  # load
        one = two = cpu1 = cpu2 = np.inf
        for _ in range(3):
            w, c = time_kernel(integ, 10_000, steps, repeats=1, threads=1, cpu=True)
            one, cpu1 = min(one, w), min(cpu1, c)
            w, c = time_kernel(integ, 10_000, steps, repeats=1, threads=2, cpu=True)
            two, cpu2 = min(two, w), min(cpu2, c)
        print(f"{integ:<12}{one:>10.1f}{cpu1:>11.1f}{two:>11.1f}{cpu2:>11.1f}{one / two:>9.2f}x"
              f"{cpu2 / cpu1:>11.2f}")
    for integ in ("Euler", "RK4"):
        v = mujoco_step_ns(100, 10 * steps, integ)
        if v is None:
            print(f"mujoco {integ}: not installed")
            break
        print(f"{'mujoco ' + integ:<12}{v:>10.1f}{'-':>11}{'-':>11}{'-':>11}{'-':>10}   (100 bodies, "
              "one thread: the comparator)")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--threads-only", action="store_true",
                    help="only the 10,000-body thread scaling (1 vs 2 threads)")
    args = ap.parse_args()
    if args.threads_only:
        thread_scaling(100 if not args.quick else 10)
        return
    steps = {1: 200_000, 100: 5_000, 10_000: 100}
    if args.quick:
        steps = {1: 20_000, 100: 500, 10_000: 10}

    # start-up: a first and a second run in subprocesses (a fresh numba cache dir for what numba
    # still compiles outside the engine's free path)
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, NUMBA_CACHE_DIR=tmp)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "rblog_cli.main", "run", str(ROOT / "samples/free_fall.toml"),
                        "--no-log", "--duration", "0.001"], env=env, check=True, capture_output=True)
        cold = time.perf_counter() - t0
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "rblog_cli.main", "run", str(ROOT / "samples/free_fall.toml"),
                        "--no-log", "--duration", "0.001"], env=env, check=True, capture_output=True)
        warm = time.perf_counter() - t0
    print(f"rblog run start-up: first run {cold:.1f} s, second run {warm:.2f} s")
    print()
    print("ns per body-step (lower is better), free bodies with gravity, one sample per call")
    print(f"{'integrator':<12}" + "".join(f"{n:>12,d}" for n in steps) + "   bodies")
    for integ in METHOD_CODES:
        time_kernel(integ, 1, 10)  # load
        print(f"{integ:<12}" + "".join(f"{time_kernel(integ, n, s):>12.1f}" for n, s in steps.items()))
    print()
    thread_scaling(100 if not args.quick else 10)
    print()
    np_steps = {1: 2000, 100: 200, 10_000: 5} if not args.quick else {1: 200, 100: 20, 10_000: 2}
    print(f"{'numpy seed':<12}" + "".join(f"{numpy_seed_step_ns(n, s):>12.1f}" for n, s in np_steps.items())
          + "   (comparator: the same step in vectorized numpy, SVD polar)")
    # MuJoCo's default arena does not hold 10,000 free bodies: 1 and 100 only
    mj_steps = {1: 20_000, 100: 1_000} if not args.quick else {1: 2_000, 100: 100}
    for integ in ("Euler", "RK4"):
        vals = [mujoco_step_ns(n, s, integ) for n, s in mj_steps.items()]
        if vals[0] is None:
            print(f"mujoco {integ}: not installed")
            break
        print(f"{'mujoco ' + integ:<12}" + "".join(f"{v:>12.1f}" for v in vals) + f"{'-':>12}"
              + "   (comparator: MuJoCo, free joints, one mj_step(nstep) call)")
    print()
    print("exact integrator against the closed-form reference, every step size (omega relative "
          "to |w0|, attitude angle in rad; max over 100 Hz samples)")
    print(f"{'problem':<28}{'dt':>8}{'omega err':>12}{'angle err':>12}")
    for name, dt, we, ae in exact_dt_sweep(args.quick):
        print(f"{name:<28}{dt:>8g}{we:>12.2e}{ae:>12.2e}")
    print()
    exact, rows = accuracy_for_cost(args.quick)
    print("accuracy for cost: tumbling box (I = 1,2,3; omega0 = 0.05,2,0.05), 20 s; exact flips at "
          + ", ".join(f"{t:.6f}" for t in exact) + " s")
    print(f"{'integrator':<12}{'dt':>8}{'ms/run':>10}{'flip time err (s)':>20}{'energy drift':>15}")
    for integ, dt, ms, err, ed, nf in rows:
        e = f"{err:.2e}" if np.isfinite(err) else f"{nf} flips (wrong)"
        print(f"{integ:<12}{dt:>8g}{ms:>10.3f}{e:>20}{ed:>15.2e}")


if __name__ == "__main__":
    main()
