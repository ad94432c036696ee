"""Contact benchmark: a pile of boxes in rblog and in MuJoCo, side by side, plus stage savings.

Runs the same scene (``rblog.study.scenes.box_pile``: 500 cubes of 0.1 m, 1 kg, random
orientations, dropped from a column of layers up to 2 m onto the ground, friction 0.5) at the
same time step in

* rblog's ContactWorld (default settings: stages chosen for the scene, sleeping on),
* rblog with ``force_all_stages=True`` (every stage runs for every body, no sleeping, no
  isotropic shortcut): the ratio shows what choosing stages saves,
* MuJoCo (``pip install mujoco``), the same boxes as free bodies with box geoms, in one or more
  setups (``--mujoco-config``, default ``both`` = ``tuned`` and ``default``):

  - ``default``: ``<option timestep/>`` only: Newton, pyramidal cones, 100 iterations,
    tolerance 1e-8, solref 0.02, no sleeping. Slow on this pile: the pile's contact graph makes
    the sparse Cholesky factor of Newton's Hessian fill in (at 2.5 s: 2100 contacts couple 676
    box pairs, the factor in MuJoCo's elimination order holds ~15000 of 125000 possible 6x6
    off-diagonal blocks with fronts of up to 119 boxes), so the constraint solver takes 99 % of
    the step, 0.5 s and more per step once the pile has formed.
  - ``tuned``: what MuJoCo's documentation ("Model tuning", "Solver settings", "Sleeping")
    recommends for this case, and the fastest setup we found that is at least as accurate as
    ``default`` on every penetration statistic, stable, and comes to rest:
    ``solver="CG"`` (no factorization; the docs' advice when "Hessian factorization dominates
    step time") capped at ``iterations="40"`` with ``ls_iterations="10"`` (fewer iterations
    leave the stiffer pile creeping or pop boxes out; tolerance-based stopping needs 50-100
    iterations), ``cone="elliptic" impratio="10"`` (recommended defaults; with them the pile
    comes to rest instead of jittering), ``solref="0.005 1"`` on every geom (the recommended
    0.004-0.01 for rigid contacts; MuJoCo's 0.02 lets the boxes sink 40 mm into each other on
    impact), and ``<flag sleep="enable"/>`` with ``sleep_tolerance="0.005"`` (rblog's sleep
    speed; islands at rest drop out of collision and solver, as in rblog).
  - ``soft`` (optional): ``tuned`` with MuJoCo's default contact softness and 20 CG
    iterations: ~1.7x faster than ``tuned``, 4-6x deeper penetration.
  - ``fast`` (optional): CG stopped after 5 iterations, pyramidal cones: ~4x faster than
    ``tuned`` (~500 steps/s), but far from converged: the pile slides out flat (mean height
    0.08 m instead of 0.13 m) and is still moving at the end.

  Tried and not used (cost per step on the formed pile): Newton with ``iterations="4"``
  (hardly faster: the cost is the factorization, not the iteration count), elliptic cones
  under Newton (1.6x slower), bodies declared in x order to cut fill-in (5x faster than
  ``default``, still ~10 steps/s), PGS (20 sweeps cost 2.5x as much as 20 CG iterations),
  ``<flag multiccd>`` (box-box and box-plane have dedicated colliders: no effect), ``<flag
  island="disable">`` (15 % slower), ``integrator="implicitfast"`` (no gain measured for free
  boxes). ``tuned``, ``soft`` and ``fast`` need MuJoCo >= 3.4 (sleeping). MuJoCo runs
  single-threaded, as rblog does.

Reported per engine: steps per second of wall time (compilation excluded; rblog's kernels are
compiled by a short warm-up run first), and penetration measured *the same way for both*: rblog's
narrowphase run on each sampled state (deepest overlap of any pair), sampled every
``--sample-every`` steps, as max / p99 / median over all samples and max over the last quarter
of the run (the settled pile); MuJoCo's own contact distances are shown too.

    python benchmarks/bench_contact.py                       # 500 boxes, 4 s at dt = 2 ms
    python benchmarks/bench_contact.py --boxes 200 --duration 2 --no-mujoco
    python benchmarks/bench_contact.py --mujoco-config all   # default, tuned, soft, fast
    python benchmarks/bench_contact.py --no-pile             # only the stage-selection scenes
    python benchmarks/bench_contact.py --no-forced --interleave --mujoco-config default
                                    # both engines in turn, 10 steps each, wall and CPU time

Stage selection is also shown on three scenes built for it (resting cubes that fall asleep,
spheres that can never touch, bouncing spheres), where the forced run keeps every stage on.
"""

from __future__ import annotations

import argparse
import importlib.util
import time
from typing import NamedTuple

import numpy as np

from rblog.engine import integrators as rot, rotation
from rblog.engine.contact import ContactParams, ContactWorld
from rblog.engine.contact.measure import separations
from rblog.study.scenes import box_pile, make_model, make_state
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE


def rblog_chunks(model, state, dt, n_steps, sample_every, force_all=False, params=None):
    """Step rblog's ContactWorld ``sample_every`` steps at a time; yields (steps, wall s, CPU s,
    penetration m) per chunk, and returns the world (``yield from``)."""
    world = ContactWorld(model, params or ContactParams(), rot.METHOD_SPLITTING,
                         rot.ORTHO_NORMALIZE, force_all_stages=force_all)
    s = state.copy()
    n = model.n_bodies
    outs = [np.zeros((1, n, 3)), np.zeros((1, n, 3)), np.zeros((1, n, 4)), np.zeros((1, n, 3, 3)),
            np.zeros((1, n, 3))]
    done = 0
    while done < n_steps:
        k = min(sample_every, n_steps - done)
        t0, c0 = time.perf_counter(), time.process_time()
        _, bad, _, _ = world.advance(dt, k, k, False, s.position, s.linear_momentum, s.quat_wxyz,
                                     s.rotation, s.angular_momentum_world, *outs)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        if bad >= 0:
            raise RuntimeError(f"rblog diverged at step {done + bad}")
        done += k
        sep = separations(world, s.position, s.rotation)
        yield k, wall, cpu, (max(0.0, -sep.min()) if len(sep) else 0.0)
    return world


def _drain(gen):
    """Run a chunk generator to its end: (list of its chunks, its return value)."""
    chunks = []
    while True:
        try:
            chunks.append(next(gen))
        except StopIteration as stop:
            return chunks, stop.value


def run_rblog(model, state, dt, n_steps, sample_every, force_all=False, params=None):
    chunks, world = _drain(rblog_chunks(model, state, dt, n_steps, sample_every, force_all,
                                        params))
    wall = sum(c[1] for c in chunks)
    return n_steps / wall, np.array([c[3] for c in chunks]), world


class MujocoConfig(NamedTuple):
    """A MuJoCo setup: ``<option>`` attributes, ``<flag>`` attributes, ``<default>`` children."""
    summary: str
    option: str = ""
    flag: str = ""
    default: str = ""

    def describe(self) -> str:
        parts = [f"<option {self.option}/>" if self.option else "",
                 f"<flag {self.flag}/>" if self.flag else "",
                 f"<default>{self.default}</default>" if self.default else ""]
        return " ".join(p for p in parts if p) or "no options (MuJoCo's defaults)"


#: The MuJoCo setups the pile can run with (``--mujoco-config``); see the module docstring.
MUJOCO_CONFIGS = {
    "default": MujocoConfig("MuJoCo's defaults: Newton, pyramidal cones, 100 iterations, "
                            "tolerance 1e-8, solref 0.02 1, no sleeping"),
    # the others need MuJoCo >= 3.4 (sleeping)
    "tuned": MujocoConfig(
        "expert setup: CG (Newton's sparse Cholesky fills in on the pile), elliptic cones, "
        "impratio 10, stiffer contacts (solref 0.005), sleeping at rblog's 5 mm/s",
        option='solver="CG" iterations="40" ls_iterations="10" cone="elliptic" impratio="10" '
               'sleep_tolerance="0.005"',
        flag='sleep="enable"', default='<geom solref="0.005 1"/>'),
    "soft": MujocoConfig(
        "tuned with MuJoCo's default contact softness (solref 0.02) and 20 CG iterations: "
        "faster, 4-6x deeper penetration",
        option='solver="CG" iterations="20" ls_iterations="10" cone="elliptic" impratio="10" '
               'sleep_tolerance="0.005"',
        flag='sleep="enable"'),
    "fast": MujocoConfig(
        "speed at any price: CG stopped after 5 iterations, far from converged (the pile "
        "slides flat and never comes to rest)",
        option='solver="CG" iterations="5" ls_iterations="10"'),
}


def mujoco_model_xml(model, state, dt, config=MUJOCO_CONFIGS["default"]):
    half = model.body_size
    lines = [f'<mujoco><option timestep="{dt}" {config.option}>',
             f"<flag {config.flag}/>" if config.flag else "", "</option>",
             f"<default>{config.default}</default>" if config.default else "",
             "<worldbody>",
             f'<geom type="plane" size="0 0 1" friction="{model.ground_friction}"/>']
    for i in range(model.n_bodies):
        x, y, z = state.position[i]
        q = state.quat_wxyz[i]
        lines.append(
            f'<body pos="{x} {y} {z}" quat="{q[0]} {q[1]} {q[2]} {q[3]}"><freejoint/>'
            f'<geom type="box" size="{half[i, 0]} {half[i, 1]} {half[i, 2]}" '
            f'mass="{model.body_mass[i]}" friction="{model.body_friction[i]}"/></body>')
    lines.append("</worldbody></mujoco>")
    return "".join(lines)


def run_mujoco(*args, **kwargs):
    """:func:`_run_mujoco` from a scratch working directory: MuJoCo appends its warnings to
    ``MUJOCO_LOG.TXT`` in the current directory, which must not be left in the user's."""
    return in_scratch_dir(_run_mujoco, *args, **kwargs)


def in_scratch_dir(fn, *args, **kwargs):
    """Call ``fn`` with a temporary current directory (removed after), then restore the cwd."""
    import os
    import tempfile

    old = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="rblog-mujoco-") as tmp:
        os.chdir(tmp)
        try:
            return fn(*args, **kwargs)
        finally:
            os.chdir(old)


def mujoco_chunks(model, state, dt, n_steps, sample_every, world, config=MUJOCO_CONFIGS["default"]):
    """Step MuJoCo ``sample_every`` steps at a time; yields (steps, wall s, CPU s, penetration by
    rblog's narrowphase m, MuJoCo's own deepest contact m, (contacts, solver iterations, awake
    bodies)) per chunk, and returns MuJoCo's version (``yield from``)."""
    import mujoco

    m = mujoco.MjModel.from_xml_string(mujoco_model_xml(model, state, dt, config))
    d = mujoco.MjData(m)
    n = model.n_bodies
    done = 0
    rot_buf = np.zeros((n, 3, 3))
    while done < n_steps:
        k = min(sample_every, n_steps - done)
        t0, c0 = time.perf_counter(), time.process_time()
        mujoco.mj_step(m, d, nstep=k)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        done += k
        qpos = d.qpos.reshape(n, 7)
        rot_buf[:] = rotation.quat_to_matrix_np(qpos[:, 3:7] / np.linalg.norm(qpos[:, 3:7], axis=1,
                                                                        keepdims=True))
        sep = separations(world, np.ascontiguousarray(qpos[:, :3]), rot_buf)
        dist = d.contact.dist[: d.ncon]
        iters = int(d.solver_niter[: max(d.nisland, 1)].max())
        asleep = getattr(d, "tree_asleep", None)
        yield (k, wall, cpu, max(0.0, -sep.min()) if len(sep) else 0.0,
               max(0.0, -dist.min()) if d.ncon else 0.0,
               (d.ncon, iters, n if asleep is None else int((asleep < 0).sum())))
    return mujoco.__version__


def _run_mujoco(model, state, dt, n_steps, sample_every, world, config=MUJOCO_CONFIGS["default"]):
    """Steps/s, penetration samples (rblog's narrowphase), MuJoCo's own deepest contact per
    sample, version, and per-sample (contacts, solver iterations, awake bodies)."""
    chunks, version = _drain(mujoco_chunks(model, state, dt, n_steps, sample_every, world, config))
    wall = sum(c[1] for c in chunks)
    return (n_steps / wall, np.array([c[3] for c in chunks]), np.array([c[4] for c in chunks]),
            version, np.array([c[5] for c in chunks]))


def run_interleaved(model, state, dt, n_steps, sample_every, config):
    """rblog and MuJoCo stepped chunk by chunk in turn (``sample_every`` steps of one, then of the
    other) in this one thread, so that whatever else the machine runs slows both alike; returns
    per engine (steps/s of wall time, steps/s of CPU time, penetrations), MuJoCo's own contact
    depths, its work samples, its version and rblog's world."""
    import mujoco  # noqa: F401  (fail here, not after rblog's first chunk)

    from rblog.engine import _core

    _core.set_threads(1)  # MuJoCo steps on one thread
    rg = rblog_chunks(model, state, dt, n_steps, sample_every)
    # MuJoCo's penetration is measured by rblog's narrowphase: a world of the same bodies
    probe = ContactWorld(model, ContactParams(), rot.METHOD_SPLITTING, rot.ORTHO_NORMALIZE)
    mg = mujoco_chunks(model, state, dt, n_steps, sample_every, probe, config)
    r_chunks, m_chunks = [], []
    world = version = None
    while world is None or version is None:
        if world is None:
            try:
                r_chunks.append(next(rg))
            except StopIteration as stop:
                world = stop.value
        if version is None:
            try:
                m_chunks.append(next(mg))
            except StopIteration as stop:
                version = stop.value

    def rates(chunks):
        steps = sum(c[0] for c in chunks)
        return (steps / sum(c[1] for c in chunks), steps / sum(c[2] for c in chunks),
                np.array([c[3] for c in chunks]))

    return (rates(r_chunks), rates(m_chunks), np.array([c[4] for c in m_chunks]),
            np.array([c[5] for c in m_chunks]), version, world)


def stage_scenes():
    """Scenes where choosing stages matters, as (name, model, state, dt, n_steps)."""
    rng = np.random.default_rng(1)
    scenes = []
    # 400 cubes resting apart on the ground: they fall asleep after sleep_time
    n = 400
    g = np.arange(n)
    pos = np.stack([(g % 20) * 0.3, (g // 20) * 0.3, np.full(n, 0.05)], 1)
    m = make_model([SHAPE_BOX] * n, [[0.05] * 3] * n, [1.0] * n, restitution=0.0)
    scenes.append(("400 cubes at rest on the ground (sleeping)", m, make_state(m, pos), 2e-3, 1000))
    # 2000 spheres drifting in zero g, each in its own group: nothing can ever touch
    n = 2000
    m = make_model([SHAPE_SPHERE] * n, [0.05] * n, [1.0] * n, gravity=(0, 0, 0), ground=False,
                   groups=np.arange(1, n + 1))
    st = make_state(m, rng.uniform(-5, 5, (n, 3)), rng.normal(size=(n, 3)),
                    omega=rng.normal(size=(n, 3)))
    scenes.append(("2000 spheres, zero g, disjoint groups (free kernel)", m, st, 1e-3, 1000))
    # 300 spheres bouncing on the ground: isotropic shortcut, sleeping once they settle
    n = 300
    g = np.arange(n)
    pos = np.stack([(g % 15) * 0.25, (g // 15) * 0.25, rng.uniform(0.2, 1.0, n)], 1)
    m = make_model([SHAPE_SPHERE] * n, [0.1] * n, [1.0] * n, restitution=0.5)
    scenes.append(("300 spheres bouncing on the ground", m, make_state(m, pos), 1e-3, 3000))
    return scenes


def run_stage_scene(model, state, dt, n_steps, force_all):
    world = ContactWorld(model, ContactParams(), rot.METHOD_SPLITTING, rot.ORTHO_NORMALIZE,
                         force_all_stages=force_all)
    s = state.copy()
    n = model.n_bodies
    outs = [np.zeros((1, n, 3)), np.zeros((1, n, 3)), np.zeros((1, n, 4)), np.zeros((1, n, 3, 3)),
            np.zeros((1, n, 3))]
    world.advance(dt, 1, 1, False, s.position, s.linear_momentum, s.quat_wxyz, s.rotation,
                  s.angular_momentum_world, *outs)  # compile
    t0 = time.perf_counter()
    world.advance(dt, n_steps, n_steps, False, s.position, s.linear_momentum, s.quat_wxyz,
                  s.rotation, s.angular_momentum_world, *outs)
    return n_steps / (time.perf_counter() - t0), world


def stats(pens):
    settled = pens[int(0.75 * len(pens)):]
    return (f"max {1e3 * pens.max():7.3f} mm   p99 {1e3 * np.percentile(pens, 99):7.3f} mm   "
            f"median {1e3 * np.median(pens):7.3f} mm   last 25 %: max {1e3 * settled.max():6.3f} mm")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--boxes", type=int, default=500)
    ap.add_argument("--duration", type=float, default=4.0, help="simulated seconds")
    ap.add_argument("--dt", type=float, default=2e-3)
    ap.add_argument("--sample-every", type=int, default=10, help="steps between penetration samples")
    ap.add_argument("--mujoco-duration", type=float, default=None,
                    help="simulated seconds for MuJoCo (default: --duration)")
    ap.add_argument("--mujoco-config", default="both",
                    help="MuJoCo setups to run (see above): default, tuned, soft, fast, both "
                         "(= tuned,default), all, or a comma-separated list")
    ap.add_argument("--no-mujoco", action="store_true")
    ap.add_argument("--no-forced", action="store_true", help="skip the force_all_stages runs")
    ap.add_argument("--no-pile", action="store_true", help="only the stage-selection scenes")
    ap.add_argument("--interleave", action="store_true",
                    help="step rblog (one thread) and MuJoCo chunk by chunk in turn, over the "
                         "same --duration, and report wall- and CPU-time steps/s of both (one "
                         "MuJoCo setup: --mujoco-config NAME)")
    args = ap.parse_args(argv)
    if args.mujoco_config not in ("both", "all"):
        bad = set(args.mujoco_config.split(",")) - set(MUJOCO_CONFIGS)
        if bad:
            ap.error(f"unknown --mujoco-config {sorted(bad)}; known: {sorted(MUJOCO_CONFIGS)}, "
                     "both, all")

    if not args.no_forced:
        print("stage selection: steps/s with the stages chosen for the scene vs every stage forced")
        for name, m, st, dt, k in stage_scenes():
            chosen, world = run_stage_scene(m, st, dt, k, False)
            forced, _ = run_stage_scene(m, st, dt, k, True)
            picked = ", ".join(stage for stage, _ in world.explain()
                               if "skipped" in stage or "none possible" in stage
                               or "isotropic" in stage or stage == "sleeping")
            print(f"  {name:52s} {chosen:9.0f} vs {forced:9.0f}  = {chosen / forced:6.2f}x"
                  f"   ({picked})")
    if args.no_pile:
        return

    model, state = box_pile(args.boxes)
    n_steps = int(round(args.duration / args.dt))
    print(f"pile: {args.boxes} cubes 0.1 m, dropped from up to 2 m; dt = {args.dt:g} s, "
          f"{n_steps} steps ({args.duration:g} s)")
    # warm-up: first-call costs (imports, allocations) on a small pile
    wm, ws = box_pile(20)
    run_rblog(wm, ws, args.dt, 20, 10)
    if args.interleave:
        name = args.mujoco_config
        if name not in MUJOCO_CONFIGS:
            ap.error(f"--interleave takes one --mujoco-config of {sorted(MUJOCO_CONFIGS)}")
        if importlib.util.find_spec("mujoco") is None:
            ap.error("--interleave needs MuJoCo (pip install mujoco)")
        (r_wall, r_cpu, r_pen), (m_wall, m_cpu, m_pen), own_m, work, ver, world = \
            run_interleaved(model, state, args.dt, n_steps, args.sample_every,
                            MUJOCO_CONFIGS[name])
        st = world.stats
        print(f"interleaved, {args.sample_every} steps of each in turn, one thread each\n")
        print(f"  {'engine':24s} {'wall steps/s':>13s} {'CPU steps/s':>12s}   penetration")
        print(f"  {'rblog':24s} {r_wall:13.1f} {r_cpu:12.1f}   {stats(r_pen)}")
        print(f"  {'MuJoCo ' + ver + ' ' + name:24s} {m_wall:13.1f} {m_cpu:12.1f}   "
              f"{stats(m_pen)}")
        print(f"  rblog per step: {st[3] / max(st[0], 1):.0f} contact points, "
              f"{st[8] / max(st[0], 1):.1f} sweeps; {world.n_awake} awake at the end")
        print(f"  MuJoCo per sample: {work[:, 0].mean():.0f} contacts, {work[:, 1].mean():.1f} "
              f"solver iterations (max {work[:, 1].max()}); own contact distances "
              f"{stats(own_m)}")
        print(f"  {MUJOCO_CONFIGS[name].summary}")
        print(f"  rblog / MuJoCo {name}: {r_wall / m_wall:.2f}x (wall), {r_cpu / m_cpu:.2f}x (CPU)")
        return

    sps, pens, world = run_rblog(model, state, args.dt, n_steps, args.sample_every)
    print("\nstages chosen:")
    for stage, why in world.explain():
        print(f"  {stage:36s} {why}")
    st = world.stats
    print(f"\nrblog                 {sps:8.1f} steps/s   penetration {stats(pens)}")
    print(f"  per step: {st[3] / max(st[0], 1):.0f} contact points, {st[8] / max(st[0], 1):.1f} "
          f"sweeps, {st[4] / max(st[0], 1):.0f} awake bodies; {world.n_awake} awake at the end")
    if not args.no_forced:
        sps_f, pens_f, _ = run_rblog(model, state, args.dt, n_steps, args.sample_every,
                                     force_all=True)
        print(f"rblog, all stages     {sps_f:8.1f} steps/s   penetration {stats(pens_f)}")
        print(f"  stage selection speed-up: {sps / sps_f:.2f}x (the pile is chaotic: round-off "
              "differences between the two runs change its workload by 10-20 %; the scenes "
              "above measure stage selection)")
    if not args.no_mujoco:
        if importlib.util.find_spec("mujoco") is None:
            print("MuJoCo not installed (pip install mujoco): skipped")
            return
        md = args.mujoco_duration or args.duration
        mj_steps = int(round(md / args.dt))
        names = {"both": ["tuned", "default"], "all": list(MUJOCO_CONFIGS)}.get(
            args.mujoco_config, args.mujoco_config.split(","))
        for name in names:
            cfg = MUJOCO_CONFIGS[name]
            sps_m, pens_m, own_m, ver, work = run_mujoco(model, state, args.dt, mj_steps,
                                                         args.sample_every, world, cfg)
            print(f"MuJoCo {ver} {name:8s}{sps_m:8.1f} steps/s   penetration {stats(pens_m)}"
                  f"   ({mj_steps} steps)")
            print(f"  {cfg.summary}")
            print(f"  options: {cfg.describe()}")
            print(f"  per sample: {work[:, 0].mean():.0f} contacts, {work[:, 1].mean():.1f} solver "
                  f"iterations (max {work[:, 1].max()}); {work[-1, 2]} awake at the end")
            print(f"  MuJoCo's own contact distances: {stats(own_m)}")
            print(f"  rblog / MuJoCo {name} speed: {sps / sps_m:.2f}x")


if __name__ == "__main__":
    main()
