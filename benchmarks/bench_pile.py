"""Loose-pile benchmark: rblog, MuJoCo, Rapier and pybullet interleaved in one run, judged by one
measuring code, with rblog's per-stage profile.

The scene is the performance issue's loose pile (``rblog.study.scenes.loose_pile``): cubes of
0.1 m and 1 kg in layers of 10 x 10 at 0.2 m pitch, layers 0.3 m apart, small random offsets and
tilts up to 0.3 rad, friction 0.5, restitution 0.2, dropped on the ground; dt 1e-3, 2 s. 500
boxes are five layers, 100 one layer, 10 one row. (The dense pile of bench_contact.py, where
MuJoCo's default solver crawls, is measured there.)

Engines, each stepping the same initial state at the same dt on one thread:

* ``rblog``: ContactWorld with default ContactParams (stages chosen, sleeping on); once per
  count in ``--threads`` (the core's task pool, as ``rblog run --threads N``), and with
  ``--exact-motion both`` once more per count with exact_contact_motion on (``rblog-Nt-exact``);
* ``mujoco``: MuJoCo with its defaults (``--mujoco-config``: a setup of
  bench_contact.MUJOCO_CONFIGS);
* ``rapier``: Rapier (``rapier3d``, f32) with its defaults, and ``rapier-stiff`` with the
  issue's stiff contacts: ``length_unit`` 0.1 (the boxes' scale: Rapier's allowed linear error
  and prediction distance are multiples of it), ``normalized_prediction_distance`` 0.1 and a
  contact natural frequency of 480 Hz (``contact_softness``; ``static_contact_softness`` 960 Hz,
  twice it, as Rapier's defaults are 30 and 60 Hz);
* ``pybullet``: maximal coordinates (Bullet's rigid-body pipeline), default solver;
* ``ode``: ODE through ``rblog run --engine ode``'s translation (rblog.study.engines.ode.OdeRun):
  ``dWorldQuickStep`` at ODE's defaults (20 iterations, SOR w 1.3, ERP 0.2, CFM 1e-10), up to 8
  ``dCollide`` points per pair, friction pyramid (dContactApprox1); ``ode-world``: ``dWorldStep``
  (a direct LCP per island, cubic in its rows: small piles only). Its time includes the Python
  near callback of ``dSpaceCollide`` (ctypes; every candidate pair, every contact joint).

The engines advance ``--chunk`` steps each in turn in this one process (interleaved: whatever
else the machine runs slows all alike) and are timed by CPU time (``time.process_time``) around
their stepping calls only; the ratio of rblog's thread counts (``--threads 1,2``) is reported in
wall time, what a second thread buys, beside the process CPU time's (both threads summed, so at
most 1.0x when the work is the same). After every chunk one routine measures every engine's poses:
the deepest box-box overlap (rblog's narrowphase, ``measure.separations``, on a world without
the ground), the deepest ground overlap (each box's lowest corner below the plane), and over the
last ``--settle-window`` seconds the boxes that still move more than ``--moving`` m from their
pose at the window's start. ``--log DIR`` writes each engine's run through ``rblog.Recorder``
(``DIR/<engine>.mcap``, one sample per chunk), so that ``rblog check`` judges them all.

    python benchmarks/bench_pile.py                          # 10, 100, 500 boxes
    python benchmarks/bench_pile.py --boxes 500 --engines rblog,mujoco,rapier-stiff --chunk 1
    python benchmarks/bench_pile.py --boxes 500 --engines rblog --profile --threads 1
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.metadata
import importlib.util
import os
import sys
import time
from collections import namedtuple

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_contact import MUJOCO_CONFIGS, in_scratch_dir, mujoco_model_xml  # noqa: E402

from rblog.engine import _core  # noqa: E402
from rblog.engine import integrators as rot  # noqa: E402
from rblog.engine.contact import ContactParams, ContactWorld  # noqa: E402
from rblog.engine.contact.measure import separations  # noqa: E402
from rblog.engine.profile import Profile  # noqa: E402
from rblog.engine.rotation import quat_to_matrix_np  # noqa: E402
from rblog.study.scenes import loose_pile  # noqa: E402

#: one chunk of an engine's run: steps done, CPU and wall seconds of its stepping calls, and the
#: state after it (world frame): position (N, 3) m, quat_wxyz (N, 4), velocity (N, 3) m/s,
#: angular velocity (N, 3) rad/s
Chunk = namedtuple("Chunk", "steps cpu wall position quat_wxyz velocity omega")

#: Rapier's stiff contacts (the issue's settings)
RAPIER_STIFF = dict(length_unit=0.1, normalized_prediction_distance=0.1, natural_frequency=480.0)


def unit(q):
    return q / np.linalg.norm(q, axis=1, keepdims=True)


# ---- the engines: generators of Chunks; their return value (``yield from``) describes the run --

def chunked(n_steps, chunk, advance, read):
    """An engine's run as Chunks: advance(k) steps it k steps (timed, CPU and wall), read() gives
    its state after them (position, quat_wxyz, velocity, omega; copies)."""
    done = 0
    while done < n_steps:
        k = min(chunk, n_steps - done)
        t0, c0 = time.perf_counter(), time.process_time()
        advance(k)
        cpu, w = time.process_time() - c0, time.perf_counter() - t0
        done += k
        yield Chunk(k, cpu, w, *read())


def rblog_chunks(model, state, dt, n_steps, chunk, threads=1, profile=None, **contact):
    """rblog's ContactWorld; ``contact``: ContactParams fields."""
    world = ContactWorld(model, ContactParams(**contact), rot.METHOD_SPLITTING,
                         rot.ORTHO_NORMALIZE)
    if profile is not None:
        world.profile_ticks = profile.ticks
    s = state.copy()
    n = model.n_bodies
    outs = [np.zeros((1, n, 3)), np.zeros((1, n, 3)), np.zeros((1, n, 4)), np.zeros((1, n, 3, 3)),
            np.zeros((1, n, 3))]
    inv_m = 1.0 / np.asarray(model.body_mass, float)
    inv_i = np.asarray(world._bodies.inv_inertia)

    def advance(k):
        _core.set_threads(threads)
        _, bad, _, _ = world.advance(dt, k, k, False, s.position, s.linear_momentum, s.quat_wxyz,
                                     s.rotation, s.angular_momentum_world, *outs)
        if bad >= 0:
            raise RuntimeError(f"rblog diverged {bad} steps into a chunk")

    def read():
        # w = R I^-1 R^T L
        lb = np.einsum("nji,nj->ni", s.rotation, s.angular_momentum_world)
        omega = np.einsum("nij,nj->ni", s.rotation, inv_i * lb)
        return (s.position.copy(), s.quat_wxyz.copy(), s.linear_momentum * inv_m[:, None],
                omega)

    wall = 0.0
    for c in chunked(n_steps, chunk, advance, read):
        wall += c.wall
        yield c
    if profile is not None:
        profile.wall = wall
    st = world.stats
    return dict(version=f"rblog, {threads} thread{'s' if threads > 1 else ''}, "
                        f"solver kernel {_core.solver_kernel()}"
                        + (", exact motion" if world.params.exact_contact_motion else ""),
                detail=f"{st[3] / max(st[0], 1):.0f} contact points, "
                       f"{st[8] / max(st[0], 1):.1f} sweeps, {st[4] / max(st[0], 1):.0f} awake a "
                       f"step; {world.n_awake} awake at the end",
                settings=dataclasses.asdict(world.params), combine=("geometric", "max"))


def mujoco_chunks(model, state, dt, n_steps, chunk, config="default"):
    """MuJoCo from bench_contact's model (a plane and free boxes); w_world = R qvel[3:6] (a free
    joint's angular velocity is in the body frame; the cubes' centres of mass are their origins)."""
    import mujoco

    name, config = config, MUJOCO_CONFIGS[config]
    m = mujoco.MjModel.from_xml_string(mujoco_model_xml(model, state, dt, config))
    d = mujoco.MjData(m)
    n = model.n_bodies

    def read():
        qpos, qvel = d.qpos.reshape(n, 7), d.qvel.reshape(n, 6)
        q = unit(qpos[:, 3:7])
        omega = np.einsum("nij,nj->ni", quat_to_matrix_np(q), qvel[:, 3:6])
        return qpos[:, :3].copy(), q, qvel[:, :3].copy(), omega

    yield from chunked(n_steps, chunk, lambda k: mujoco.mj_step(m, d, nstep=k), read)
    return dict(version=f"MuJoCo {mujoco.__version__} ({name})", detail="",
                settings=dict(xml_option=config.option, xml_flag=config.flag,
                              xml_default=config.default),
                combine=("max", "max"))


def rapier_world(model, state, dt, stiff=False):
    """A Rapier world of the pile: a fixed half-space (the ground) and one dynamic cuboid per box
    (its collider's mass the box's, so its inertia is the solid cuboid's), on one thread."""
    import rapier3d as r

    world = r.PhysicsWorld(gravity=tuple(map(float, model.gravity)))
    world.set_num_threads(1)
    p = world.integration_parameters
    p.dt = float(dt)
    if stiff:
        p.length_unit = RAPIER_STIFF["length_unit"]
        p.normalized_prediction_distance = RAPIER_STIFF["normalized_prediction_distance"]
        f = RAPIER_STIFF["natural_frequency"]
        damping = p.contact_softness.damping_ratio
        # Rapier's defaults: static contacts at twice a dynamic pair's frequency (60 and 30 Hz)
        p.contact_softness = r.SpringCoefficients(f, damping)
        p.static_contact_softness = r.SpringCoefficients(2.0 * f, damping)
    gn = np.asarray(model.ground_normal, float)
    ground = world.add_body(r.RigidBodyBuilder(r.RigidBodyType.FIXED)
                            .translation(tuple(map(float, gn * model.ground_offset))))
    world.add_collider(r.Collider.halfspace(tuple(map(float, gn)))
                       .friction(float(model.ground_friction))
                       .restitution(float(model.ground_restitution)), ground)
    handles = []
    for i in range(model.n_bodies):
        q = state.quat_wxyz[i]
        iso = r.Isometry3(tuple(map(float, state.position[i])),
                          r.Rotation3(float(q[0]), float(q[1]), float(q[2]), float(q[3])))
        h = world.add_body(r.RigidBodyBuilder(r.RigidBodyType.DYNAMIC).position(iso))
        hx, hy, hz = map(float, model.body_size[i])
        world.add_collider(r.Collider.cuboid(hx, hy, hz).mass(float(model.body_mass[i]))
                           .friction(float(model.body_friction[i]))
                           .restitution(float(model.body_restitution[i])), h)
        handles.append(h)
    return world, handles


#: Rapier's stage timers (its pipeline's counters, wall ms of the last step) summed by --profile
RAPIER_STAGES = (("broad phase", "cd", "broad_phase_time_ms"),
                 ("narrow phase", "cd", "narrow_phase_time_ms"),
                 ("islands", "stages", "island_construction_time_ms"),
                 ("constraints collection", "stages", "island_constraints_collection_time_ms"),
                 ("solver: assembly", "solver", "velocity_assembly_time_ms"),
                 ("solver: resolution", "solver", "velocity_resolution_time_ms"),
                 ("solver: update", "solver", "velocity_update_time_ms"),
                 ("solver (all)", "stages", "solver_time_ms"),
                 ("step", None, "step_time_ms"))


def rapier_chunks(model, state, dt, n_steps, chunk, stiff=False, profile=None):
    """Rapier at its defaults, or with RAPIER_STIFF; the state read back per body (f32 to f64).
    ``profile``: a dict that receives its stage timers summed over the run (s) and its contact
    counts per step (the counters are read after every step, inside the timed loop)."""
    import rapier3d as r

    world, handles = rapier_world(model, state, dt, stiff)
    bodies = world.rigid_bodies
    n = model.n_bodies
    step = world.step

    def advance(k):
        for _ in range(k):
            step()
            if profile is not None:
                cn = world.physics_pipeline.counters
                for name, part, attr in RAPIER_STAGES:
                    src = cn if part is None else getattr(cn, part)
                    profile[name] = profile.get(name, 0.0) + 1e-3 * getattr(src, attr)
                profile["contacts"] = profile.get("contacts", 0) + cn.solver.ncontacts
                profile["steps"] = profile.get("steps", 0) + 1

    def read():
        pos, quat, vel, omega = (np.zeros((n, 3)), np.zeros((n, 4)), np.zeros((n, 3)),
                                 np.zeros((n, 3)))
        for j, h in enumerate(handles):
            b = bodies[h]
            pos[j] = tuple(b.translation)
            rq = b.rotation
            quat[j] = (rq.w, rq.i, rq.j, rq.k)
            vel[j] = tuple(b.linvel)
            omega[j] = tuple(b.angvel)
        return pos, unit(quat), vel, omega

    yield from chunked(n_steps, chunk, advance, read)
    p = world.integration_parameters
    settings = dict(length_unit=p.length_unit,
                    normalized_prediction_distance=p.normalized_prediction_distance,
                    num_solver_iterations=p.num_solver_iterations,
                    num_internal_pgs_iterations=p.num_internal_pgs_iterations,
                    contact_natural_frequency=p.contact_softness.natural_frequency,
                    static_contact_natural_frequency=p.static_contact_softness.natural_frequency,
                    contact_damping_ratio=p.contact_softness.damping_ratio,
                    warmstart_coefficient=p.warmstart_coefficient)
    ver = importlib.metadata.version("rapier3d")
    return dict(version=f"Rapier {ver} ({'stiff' if stiff else 'defaults'})",
                detail=", ".join(f"{k} {v:g}" for k, v in settings.items()), settings=settings,
                combine=("mean", "mean"))


def pybullet_chunks(model, state, dt, n_steps, chunk):
    """pybullet, maximal-coordinate rigid bodies, one Python call per step."""
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
        step = pb.stepSimulation

        def advance(k):
            for _ in range(k):
                step(physicsClientId=cid)

        def read():
            pos, quat, vel, omega = (np.zeros((n, 3)), np.zeros((n, 4)), np.zeros((n, 3)),
                                     np.zeros((n, 3)))
            for j, bid in enumerate(ids):
                p, q = pb.getBasePositionAndOrientation(bid, physicsClientId=cid)
                v, om = pb.getBaseVelocity(bid, physicsClientId=cid)
                pos[j], quat[j], vel[j], omega[j] = p, (q[3], q[0], q[1], q[2]), v, om
            return pos, unit(quat), vel, omega

        yield from chunked(n_steps, chunk, advance, read)
        return dict(version=f"pybullet (API {pb.getAPIVersion()}, maximal)", detail="",
                    settings={}, combine=("product", "product"))
    finally:
        pb.disconnect(physicsClientId=cid)


def ode_chunks(model, state, dt, n_steps, chunk, stepper="quick"):
    """ODE by OdeRun (the pile as a scene of its model and state), the state read back per body."""
    from types import SimpleNamespace

    from rblog.study.engines.ode import OdeRun

    scene = SimpleNamespace(model=model, state=state, sim=SimpleNamespace(seed=0), contact=None)
    run = OdeRun(scene, dt, [f"stepper={stepper}"])
    try:
        done = 0
        while done < n_steps:
            k = min(chunk, n_steps - done)
            t0, c0 = time.perf_counter(), time.process_time()
            run.step(k)
            cpu, w = time.process_time() - c0, time.perf_counter() - t0
            done += k
            pos, quat, vel, omega = run.state()
            yield Chunk(k, cpu, w, pos, unit(quat), vel, omega)
        st = run.settings
        keys = ("integrator", "quickstep_iterations", "quickstep_w", "erp", "cfm", "max_contacts")
        return dict(version=f"ODE {run.version} {stepper}", settings={k: st[k] for k in keys if k in st},
                    detail=", ".join(f"{k} {st[k]}" for k in keys if k in st),
                    combine=("geometric", "max"))
    finally:
        run.close()


# ---- one measuring code for every engine --------------------------------------------------------

class Judge:
    """Overlaps and settling of one engine's run, from its poses after each chunk.

    Box-box overlap: rblog's narrowphase on a world of the same boxes without the ground
    (deepest penetration of any pair, m). Ground overlap: n . x - sum_k |n . R e_k| h_k below the
    plane's offset (a box's lowest corner). Moving: over the last ``window`` s, the boxes whose
    centre gets farther than ``moving`` m from where it was at the window's start."""

    def __init__(self, model, n_steps, dt, window, moving):
        self.probe = ContactWorld(dataclasses.replace(model, ground=False), ContactParams(),
                                  rot.METHOD_SPLITTING, rot.ORTHO_NORMALIZE)
        self.gn = np.asarray(model.ground_normal, float)
        self.goff = float(model.ground_offset) if model.ground else None
        self.half = np.asarray(model.body_size, float)
        self.window_step = n_steps - int(round(window / dt))
        self.moving = moving
        self.done = 0
        self.box, self.ground = [], []
        self.x_window = None
        self.moved = np.zeros(model.n_bodies)

    def add(self, c: Chunk):
        self.done += c.steps
        R = quat_to_matrix_np(c.quat_wxyz)
        sep = separations(self.probe, np.ascontiguousarray(c.position), np.ascontiguousarray(R))
        self.box.append(max(0.0, -sep.min()) if len(sep) else 0.0)
        if self.goff is not None:
            reach = (np.abs(np.einsum("i,nik->nk", self.gn, R)) * self.half).sum(1)
            low = c.position @ self.gn - reach
            self.ground.append(max(0.0, float(self.goff - low.min())))
        if self.done >= self.window_step:
            if self.x_window is None:
                self.x_window = c.position.copy()
            d = np.linalg.norm(c.position - self.x_window, axis=1)
            self.moved = np.maximum(self.moved, d)

    def summary(self):
        box, ground = np.array(self.box), np.array(self.ground or [0.0])
        return dict(box_max=box.max(), ground_max=ground.max(), box_end=box[-1],
                    ground_end=ground[-1], moving=int((self.moved > self.moving).sum()))


def thread_ratios(runs):
    """rblog's runs at more than one thread against its first count: runs {name: (threads, steps/s
    wall, steps/s CPU)} (CPU: the process's, every thread summed), in order; returns [(name,
    threads, threads of the base, wall ratio, CPU ratio)], a ratio the run's steps/s over the
    base's (> 1: faster)."""
    items = list(runs.items())
    if not items:
        return []
    base_name, (nt0, wall0, cpu0) = items[0]
    return [(name, nt, nt0, wall / wall0, cpu / cpu0)
            for name, (nt, wall, cpu) in items[1:] if nt != nt0]


def recorder_for(path, model, dt, chunk, duration, info):
    from rblog.record import Recorder

    return Recorder(model, mcap=path, dt=dt, writer=info["version"], integrator="",
                    log_every=chunk, duration_s=duration, combine_friction=info["combine"][0],
                    combine_restitution=info["combine"][1],
                    engine_settings={k: v for k, v in info["settings"].items()
                                     if isinstance(v, (int, float, str, bool))})


def run_interleaved(engines, model, dt, n_steps, chunk, args):
    """Each engine's generator advanced a chunk in turn; returns {name: (cpu s, wall s, Judge,
    info, recorded chunks)}."""
    gens = {name: gen for name, gen in engines}
    res = {name: [0.0, 0.0, Judge(model, n_steps, dt, args.settle_window, args.moving), None, []]
           for name in gens}
    live = list(gens)
    while live:
        for name in list(live):
            try:
                c = next(gens[name])
            except StopIteration as stop:
                res[name][3] = stop.value
                live.remove(name)
                continue
            r = res[name]
            r[0] += c.cpu
            r[1] += c.wall
            r[2].add(c)
            if args.log:
                r[4].append(c)
    return res


def write_logs(res, model, dt, chunk, duration, log_dir):
    os.makedirs(log_dir, exist_ok=True)
    for name, (_, _, _, info, chunks) in res.items():
        path = os.path.join(log_dir, f"{name}.mcap")
        steps = np.cumsum([c.steps for c in chunks])
        with recorder_for(path, model, dt, chunk, duration, info) as rec:
            rec.write(t=steps * dt, step=steps,
                      position=np.stack([c.position for c in chunks]),
                      quat_wxyz=np.stack([c.quat_wxyz for c in chunks]),
                      velocity=np.stack([c.velocity for c in chunks]),
                      angular_velocity=np.stack([c.omega for c in chunks]))
        print(f"  wrote {path}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--boxes", default="10,100,500", help="comma-separated pile sizes")
    ap.add_argument("--duration", type=float, default=2.0, help="simulated seconds")
    ap.add_argument("--dt", type=float, default=1e-3)
    ap.add_argument("--chunk", "--sample-every", dest="chunk", type=int, default=10,
                    help="steps an engine advances before the next takes its turn; the poses "
                         "are measured after each")
    ap.add_argument("--engines", default="rblog,mujoco,rapier,rapier-stiff,pybullet,ode",
                    help="comma-separated: rblog, mujoco, rapier, rapier-stiff, pybullet, ode, ode-world "
                         "(those not installed are skipped)")
    ap.add_argument("--no-peers", action="store_true", help="rblog only")
    ap.add_argument("--no-pybullet", action="store_true", help="every engine but pybullet")
    ap.add_argument("--mujoco-config", default="default", help=f"one of {sorted(MUJOCO_CONFIGS)}")
    ap.add_argument("--threads", default="1", help="comma-separated rblog thread counts")
    ap.add_argument("--profile", action="store_true", help="print rblog's per-stage profile")
    ap.add_argument("--solver", default="pgs", help="ContactParams.solver: pgs or soft_step")
    ap.add_argument("--substeps", type=int, default=4, help="the soft step's substeps")
    ap.add_argument("--contact-hertz", type=float, default=None,
                    help="the soft step's contact_hertz (default: the substeps' cap)")
    ap.add_argument("--no-anchors", dest="anchors", action="store_false",
                    help="rblog with [contact] static_friction_anchors = false (on by default)")
    ap.add_argument("--exact-motion", default="off", choices=("off", "on", "both"),
                    help="rblog with [contact] exact_contact_motion off (the default), on, or "
                         "both interleaved (engines rblog-Nt and rblog-Nt-exact)")
    ap.add_argument("--settle-window", type=float, default=0.2, help="s at the end of the run")
    ap.add_argument("--moving", type=float, default=1e-4,
                    help="m: a box that moves farther in the settle window is still moving")
    ap.add_argument("--log", default=None, help="directory: write <engine>.mcap per engine")
    args = ap.parse_args(argv)
    if args.log:
        args.log = os.path.abspath(args.log)
    n_steps = int(round(args.duration / args.dt))
    thread_counts = [int(t) for t in args.threads.split(",")]
    wanted = args.engines.split(",")
    if args.no_peers:
        wanted = ["rblog"]
    elif args.no_pybullet:
        wanted = [e for e in wanted if e != "pybullet"]
    have = {"mujoco": importlib.util.find_spec("mujoco") is not None,
            "rapier": importlib.util.find_spec("rapier3d") is not None,
            "pybullet": importlib.util.find_spec("pybullet") is not None,
            "ode": importlib.util.find_spec("odepy") is not None}
    for e in wanted:
        if e.split("-")[0] in have and not have[e.split("-")[0]]:
            print(f"{e}: not installed, skipped")
    print(f"loose pile: dt {args.dt:g} s, {n_steps} steps ({args.duration:g} s), chunks of "
          f"{args.chunk} steps interleaved, CPU time; load {os.getloadavg()[0]:.1f}; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    contact = dict(solver=args.solver, substeps=args.substeps, contact_hertz=args.contact_hertz,
                   static_friction_anchors=args.anchors)
    wm, ws = loose_pile(10)
    for _ in rblog_chunks(wm, ws, args.dt, 20, 10):  # compile / load the kernels
        pass
    for nb in (int(b) for b in args.boxes.split(",")):
        model, state = loose_pile(nb)
        profiles = {}
        engines = []
        for e in wanted:
            if e == "rblog":
                exact = {"off": (False,), "on": (True,), "both": (False, True)}[args.exact_motion]
                for nt in thread_counts:
                    for ex in exact:
                        name = f"rblog-{nt}t" + ("-exact" if ex and len(exact) > 1 else "")
                        profiles[name] = Profile() if args.profile else None
                        engines.append((name, rblog_chunks(model, state, args.dt, n_steps,
                                                           args.chunk, nt, profiles[name],
                                                           exact_contact_motion=ex, **contact)))
            elif e == "mujoco" and have["mujoco"]:
                engines.append(("mujoco", mujoco_chunks(model, state, args.dt, n_steps,
                                                        args.chunk, args.mujoco_config)))
            elif e in ("rapier", "rapier-stiff") and have["rapier"]:
                profiles[e] = {} if args.profile else None
                engines.append((e, rapier_chunks(model, state, args.dt, n_steps, args.chunk,
                                                 stiff=e == "rapier-stiff",
                                                 profile=profiles[e])))
            elif e == "pybullet" and have["pybullet"]:
                engines.append(("pybullet", pybullet_chunks(model, state, args.dt, n_steps,
                                                            args.chunk)))
            elif e in ("ode", "ode-world") and have["ode"]:
                engines.append((e, ode_chunks(model, state, args.dt, n_steps, args.chunk,
                                              "world" if e == "ode-world" else "quick")))
        # from a scratch directory: MuJoCo appends its warnings to MUJOCO_LOG.TXT in the cwd
        res = in_scratch_dir(run_interleaved, engines, model, args.dt, n_steps, args.chunk, args)
        print(f"\n{nb} boxes\n  {'engine':<46} {'steps/s CPU':>11} {'steps/s wall':>12}   deepest "
              "overlap box-box / ground, at the end; boxes moving in the last "
              f"{args.settle_window:g} s")
        cpu_of = {}
        rblog_runs = {}  # {name: (threads, steps/s wall, steps/s CPU)}
        for name, (cpu, wall, judge, info, _) in res.items():
            s = judge.summary()
            cpu_of[name] = n_steps / cpu
            if name.startswith("rblog-") and name.endswith("t"):  # rblog-Nt; not rblog-Nt-exact
                rblog_runs[name] = (int(name[len("rblog-"):-1]), n_steps / wall, n_steps / cpu)
            print(f"  {info['version']:<46} {n_steps / cpu:11.1f} {n_steps / wall:12.1f}   "
                  f"{1e3 * s['box_max']:.3f} / {1e3 * s['ground_max']:.3f} mm, "
                  f"{1e3 * s['box_end']:.3f} / {1e3 * s['ground_end']:.3f} mm; {s['moving']}")
            if info["detail"]:
                print(f"    {info['detail']}")
        for key, prof in profiles.items():
            if prof is None:
                continue
            if isinstance(prof, dict):  # Rapier's counters (wall time)
                total = prof.get("step", 0.0)
                per_step = prof.get("contacts", 0) / max(prof.get("steps", 1), 1)
                print(f"  {key}, per stage (its counters, wall), {per_step:.0f} contacts a step:")
                for name, _, _ in RAPIER_STAGES:
                    print(f"      {name:<36} {prof.get(name, 0.0):8.3f} s  "
                          f"{100 * prof.get(name, 0.0) / max(total, 1e-12):5.1f} %")
                continue
            print(f"  {key}, per stage (wall):")
            for name, sec, share in prof.table():
                print(f"      {name:<36} {sec:8.3f} s  {100 * share:5.1f} %")
        for name, sps in cpu_of.items():
            if name.startswith("rblog") and any(not o.startswith("rblog") for o in cpu_of):
                print(f"  {name}: " + "   ".join(f"/ {o} {sps / v:.2f}x" for o, v in cpu_of.items()
                                               if not o.startswith("rblog")))
            if name.endswith("-exact") and name[:-6] in cpu_of:
                print(f"  {name}: {cpu_of[name[:-6]] / sps:.3f}x the CPU time of {name[:-6]}")
        for name, nt, nt0, r_wall, r_cpu in thread_ratios(rblog_runs):
            print(f"  rblog {nt} threads / {nt0}: {r_wall:.2f}x wall time, {r_cpu:.2f}x process "
                  f"CPU time (the threads' sum)")
        if args.log:
            write_logs(res, model, args.dt, args.chunk, args.duration,
                       os.path.join(args.log, f"{nb}"))


if __name__ == "__main__":
    main()
