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

What is timed: ``rblog.analyze.check`` on the trajectory in memory (the shared Context and every
analyzer, up to the Result objects); not reading a log, not formatting the report. Each analyzer
alone is timed with a fresh Context of its own (what ``rblog check --only NAME`` costs); all
analyzers together on one thread and on ``--threads`` threads side by side, best of ``--repeat``.
The analyzers' kernels are C++ (rblog.analyze._audit, built at install): nothing compiles at run
time, so there is no first-run compile figure any more (the numba version printed one).

Targets: >= 1e6 body-samples per second for all analyzers together on one thread (issue 16),
>= 3e6 on two cores (issue 18).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=10_001)
    ap.add_argument("--bodies", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2, help="the parallel column's thread count")
    args = ap.parse_args()
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
