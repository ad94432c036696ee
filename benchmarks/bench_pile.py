"""Loose-pile benchmark: rblog, MuJoCo and pybullet side by side in one run, with rblog's
per-stage profile.

The scene is the performance issue's loose pile (``rblog.study.scenes.loose_pile``): cubes of
0.1 m and 1 kg in layers of 10 x 10 at 0.2 m pitch, layers 0.3 m apart, small random offsets and
tilts up to 0.3 rad, friction 0.5, dropped on the ground; dt 1e-3, 2 s. 500 boxes are five
layers, 100 one layer, 10 one row. (The dense pile of bench_contact.py, where MuJoCo's default
solver crawls, is measured there.)

Engines, each stepping the same initial state at the same dt:

* rblog's ContactWorld with default ContactParams (stages chosen, sleeping on), timed over its
  advance calls only (compilation excluded: a 20-step warm-up compiles or loads the kernels);
* MuJoCo with its defaults (``--mujoco-config default``; the issue's comparison) or any setup of
  bench_contact.MUJOCO_CONFIGS;
* pybullet in maximal coordinates (``createMultiBody(useMaximalCoordinates=True)``; Bullet's
  rigid-body pipeline, not Featherstone), default solver, one Python call per step.

Penetration is measured the same way for all three: rblog's narrowphase on each sampled state
(every ``--sample-every`` steps), deepest overlap of any pair. Threads: rblog runs once per
count in ``--threads`` (default 1 and 2; the core's task pool, as ``rblog run --threads N`` or
RBLOG_THREADS sets it), and each is printed beside MuJoCo (which steps on one thread). The
velocity solve's kernel (AVX2, SSE2 or scalar; RBLOG_SOLVER_PATH) is printed too.

    python benchmarks/bench_pile.py                          # 10, 100, 500 boxes
    python benchmarks/bench_pile.py --boxes 500 --no-peers --profile --threads 1
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_contact import MUJOCO_CONFIGS, run_mujoco, stats  # noqa: E402

from rblog.engine import _core  # noqa: E402
from rblog.engine import integrators as rot  # noqa: E402
from rblog.engine.contact import ContactParams, ContactWorld  # noqa: E402
from rblog.engine.contact.measure import separations  # noqa: E402
from rblog.engine.profile import Profile  # noqa: E402
from rblog.engine.rotation import quat_to_matrix_np  # noqa: E402
from rblog.study.scenes import loose_pile  # noqa: E402


def run_rblog(model, state, dt, n_steps, sample_every, profile=None, anchors=True, **contact):
    """(steps/s, penetration samples, world, end state); ``anchors``: ContactParams'
    static_friction_anchors; ``contact``: further ContactParams fields (solver, substeps ...)."""
    world = ContactWorld(model, ContactParams(static_friction_anchors=anchors, **contact),
                         rot.METHOD_SPLITTING, rot.ORTHO_NORMALIZE)
    if profile is not None:
        world.profile_ticks = profile.ticks
    s = state.copy()
    n = model.n_bodies
    outs = [np.zeros((1, n, 3)), np.zeros((1, n, 3)), np.zeros((1, n, 4)), np.zeros((1, n, 3, 3)),
            np.zeros((1, n, 3))]
    pens, wall, done = [], 0.0, 0
    while done < n_steps:
        k = min(sample_every, n_steps - done)
        t0 = time.perf_counter()
        _, bad, _, _ = world.advance(dt, k, k, False, s.position, s.linear_momentum, s.quat_wxyz,
                                     s.rotation, s.angular_momentum_world, *outs)
        wall += time.perf_counter() - t0
        if bad >= 0:
            raise RuntimeError(f"rblog diverged at step {done + bad}")
        done += k
        sep = separations(world, s.position, s.rotation)
        pens.append(max(0.0, -sep.min()) if len(sep) else 0.0)
    if profile is not None:
        profile.wall = wall
    return n_steps / wall, np.array(pens), world, s


def run_pybullet(model, state, dt, n_steps, sample_every, world):
    """(steps/s, penetration samples, version): maximal-coordinate rigid bodies."""
    import pybullet as pb

    cid = pb.connect(pb.DIRECT)
    try:
        pb.setGravity(*map(float, model.gravity), physicsClientId=cid)
        pb.setTimeStep(dt, physicsClientId=cid)
        plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=cid)
        gid = pb.createMultiBody(0, plane, physicsClientId=cid)
        pb.changeDynamics(gid, -1, lateralFriction=1.0, restitution=1.0, physicsClientId=cid)
        ids = []
        for i in range(model.n_bodies):
            col = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=list(map(float, model.body_size[i])),
                                          physicsClientId=cid)
            q = state.quat_wxyz[i]
            bid = pb.createMultiBody(float(model.body_mass[i]), col,
                                     basePosition=list(map(float, state.position[i])),
                                     baseOrientation=[float(q[1]), float(q[2]), float(q[3]), float(q[0])],
                                     useMaximalCoordinates=True, physicsClientId=cid)
            pb.changeDynamics(bid, -1, lateralFriction=float(model.body_friction[i]),
                              restitution=float(model.body_restitution[i]), linearDamping=0.0,
                              angularDamping=0.0, physicsClientId=cid)
            ids.append(bid)
        n = model.n_bodies
        pos = np.zeros((n, 3))
        quat = np.zeros((n, 4))
        pens, wall, done = [], 0.0, 0
        step = pb.stepSimulation
        while done < n_steps:
            k = min(sample_every, n_steps - done)
            t0 = time.perf_counter()
            for _ in range(k):
                step(physicsClientId=cid)
            wall += time.perf_counter() - t0
            done += k
            for j, bid in enumerate(ids):
                p, q = pb.getBasePositionAndOrientation(bid, physicsClientId=cid)
                pos[j] = p
                quat[j] = (q[3], q[0], q[1], q[2])
            sep = separations(world, pos, quat_to_matrix_np(quat / np.linalg.norm(quat, axis=1,
                                                                                  keepdims=True)))
            pens.append(max(0.0, -sep.min()) if len(sep) else 0.0)
        return n_steps / wall, np.array(pens), str(pb.getAPIVersion())
    finally:
        pb.disconnect(physicsClientId=cid)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--boxes", default="10,100,500", help="comma-separated pile sizes")
    ap.add_argument("--duration", type=float, default=2.0, help="simulated seconds")
    ap.add_argument("--dt", type=float, default=1e-3)
    ap.add_argument("--sample-every", type=int, default=50, help="steps between penetration samples")
    ap.add_argument("--mujoco-config", default="default", help=f"one of {sorted(MUJOCO_CONFIGS)}")
    ap.add_argument("--no-peers", action="store_true", help="rblog only")
    ap.add_argument("--no-pybullet", action="store_true", help="rblog and MuJoCo only")
    ap.add_argument("--profile", action="store_true", help="print rblog's per-stage profile")
    ap.add_argument("--threads", default="1,2", help="comma-separated rblog thread counts")
    ap.add_argument("--no-anchors", dest="anchors", action="store_false",
                    help="rblog with [contact] static_friction_anchors = false (on by default)")
    ap.add_argument("--solver", default="pgs", help="ContactParams.solver: pgs or soft_step")
    ap.add_argument("--substeps", type=int, default=4, help="the soft step's substeps")
    ap.add_argument("--contact-hertz", type=float, default=None,
                    help="the soft step's contact_hertz (default: the substeps' cap)")
    args = ap.parse_args(argv)
    contact = dict(solver=args.solver, substeps=args.substeps, contact_hertz=args.contact_hertz)
    n_steps = int(round(args.duration / args.dt))
    thread_counts = [int(t) for t in args.threads.split(",")]
    print(f"loose pile: dt {args.dt:g} s, {n_steps} steps ({args.duration:g} s); rblog threads "
          f"{thread_counts}, solver kernel {_core.solver_kernel()}, solver {args.solver}"
          + (f" ({args.substeps} substeps, contact_hertz {args.contact_hertz})"
             if args.solver == "soft_step" else ""))
    wm, ws = loose_pile(10)
    run_rblog(wm, ws, args.dt, 20, 10, anchors=args.anchors)  # compile / load the kernels
    have_mj = importlib.util.find_spec("mujoco") is not None
    have_pb = importlib.util.find_spec("pybullet") is not None and not args.no_pybullet
    for n in (int(b) for b in args.boxes.split(",")):
        model, state = loose_pile(n)
        print(f"\n{n} boxes")
        sps_t = {}
        for nt in thread_counts:
            _core.set_threads(nt)
            prof = Profile() if args.profile else None
            sps, pens, world, _ = run_rblog(model, state, args.dt, n_steps, args.sample_every,
                                            prof, anchors=args.anchors, **contact)
            sps_t[nt] = sps
            st = world.stats
            print(f"  rblog{'' if args.anchors else ' no anchors'} {nt} thread{'s' if nt > 1 else ' '}"
                  f"  {sps:8.1f} steps/s   penetration {stats(pens)}")
            print(f"    per step: {st[3] / max(st[0], 1):.0f} contact points, "
                  f"{st[8] / max(st[0], 1):.1f} sweeps, {st[4] / max(st[0], 1):.0f} awake; "
                  f"{world.n_awake} awake at the end")
            if prof is not None:
                for name, sec, share in prof.table():
                    print(f"      {name:<36} {sec:8.3f} s  {100 * share:5.1f} %")
        if args.no_peers:
            continue
        if have_mj:
            sps_m, pens_m, _, ver, work = run_mujoco(model, state, args.dt, n_steps,
                                                     args.sample_every, world,
                                                     MUJOCO_CONFIGS[args.mujoco_config])
            print(f"  MuJoCo {ver} {args.mujoco_config:8s}{sps_m:8.1f} steps/s   penetration "
                  f"{stats(pens_m)}")
            print(f"    per sample: {work[:, 0].mean():.0f} contacts, {work[:, 1].mean():.1f} "
                  "solver iterations")
        else:
            sps_m = float("nan")
            print("  MuJoCo not installed: skipped")
        if have_pb:
            sps_p, pens_p, ver_p = run_pybullet(model, state, args.dt, n_steps, args.sample_every,
                                                world)
            print(f"  pybullet (API {ver_p}, maximal) {sps_p:8.1f} steps/s   penetration "
                  f"{stats(pens_p)}")
        else:
            sps_p = float("nan")
            print("  pybullet not installed: skipped")
        for nt, sps in sps_t.items():
            print(f"  rblog {nt} thread{'s' if nt > 1 else ' '}: / MuJoCo {sps / sps_m:.2f}x   "
                  f"/ pybullet {sps / sps_p:.2f}x")
        if 1 in sps_t and 2 in sps_t:
            print(f"  rblog 2 threads / 1 thread {sps_t[2] / sps_t[1]:.2f}x")


if __name__ == "__main__":
    main()
