"""Run a scene (TOML) in another engine and record it into rblog's log contract.

``rblog run SCENE --engine mujoco|pybullet|ode`` (optional extras ``engines``: ``pip install -e
".[engines]"``; ``ode``: Debian's ``libode8`` and ``pip install -e ".[ode]"``). Each engine module
translates the scene's :class:`~rblog.contract.model.Model` and initial state into the engine's
model (spheres, boxes, capsules, cylinders and hulls: each body's geoms, :func:`body_parts`, one
for a one-shape body, a compound's parts at their poses in the body frame), ground plane, static boxes, the scene's masses and principal inertias (never the engine's own density
computation), gravity, constant force/torque, collision groups), translates materials with the
engine's own combine rule so that every pair gets the scene's effective restitution ``max(e_a,
e_b)`` and friction ``sqrt(mu_a mu_b)``, steps it at the scene's dt with the engine's integrator,
and records poses, velocities and the engine's contacts through :class:`rblog.record.Recorder`.

A scene feature an engine cannot represent raises :class:`EngineUnsupported` (exit code 2) naming
the feature (a shape by its name). Run metadata (``RunInfo.engine_settings``) names the engine,
its version and every solver setting used.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from rblog.contract.model import GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_MESH, GEOM_NAMES, \
    GEOM_SPHERE, SHAPE_BOX, SHAPE_SPHERE
from rblog.errors import RblogError, EngineUnsupported, EngineMissing

ENGINE_NAMES = ("mujoco", "pybullet", "ode")


def parse_options(engine: str, items, known: dict[str, str]) -> dict[str, str]:
    """``["integrator=RK4", ...]`` -> dict; unknown keys raise EngineUnsupported naming the known
    ones (``known``: name -> help)."""
    out: dict[str, str] = {}
    for item in items or ():
        key, eq, val = str(item).partition("=")
        key = key.strip()
        if not eq or not key:
            raise RblogError(f"--engine-option {item!r}: expected KEY=VALUE")
        if key not in known:
            raise EngineUnsupported(engine, f"option {key!r} (known: {', '.join(sorted(known))})")
        out[key] = val.strip()
    return out


def pair_materials(model):
    """Effective (restitution, friction) by rblog's rules for every pair that can touch.

    Returns (features, e_eff(F, F), mu_eff(F, F), can_touch(F, F)) over features = bodies
    0..N-1, then the ground (if any), then static boxes; static features never touch each other.
    """
    n = model.n_bodies
    e = list(np.asarray(model.body_restitution, float))
    mu = list(np.asarray(model.body_friction, float))
    group = list(np.asarray(model.body_group, int))
    kinds = ["body"] * n
    if model.ground:
        e.append(float(model.ground_restitution))
        mu.append(float(model.ground_friction))
        group.append(0)
        kinds.append("ground")
    for j in range(len(model.static_box_position)):
        e.append(float(model.static_box_restitution[j]))
        mu.append(float(model.static_box_friction[j]))
        group.append(0)
        kinds.append("static")
    e, mu, group = np.array(e), np.array(mu), np.array(group)
    e_eff = np.maximum(e[:, None], e[None, :])
    mu_eff = np.sqrt(mu[:, None] * mu[None, :])
    static = np.array([k != "body" for k in kinds])
    can = ~(static[:, None] & static[None, :])
    can &= (group[:, None] == 0) | (group[None, :] == 0) | (group[:, None] == group[None, :])
    np.fill_diagonal(can, False)
    return kinds, e_eff, mu_eff, can


def body_geoms(model, engine: str, takes=(GEOM_SPHERE, GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER)):
    """Each body's one geom: a list of (GEOM_* code, size (3,) m) over the bodies.

    Sizes as rblog.contract.model's GEOM_* (sphere [r, 0, 0], box half extents, capsule and
    cylinder [r, h, 0] with h the half length along the body's z). A scene puts each body's geom
    at its centre of mass along its principal axes (the body frame); a geom type outside
    ``takes``, or a body with another geom layout, raises EngineUnsupported naming it."""
    n = model.n_bodies
    if model.geom_type is None:  # a sphere-and-box model: the v2 fields say it all
        code = {SHAPE_SPHERE: GEOM_SPHERE, SHAPE_BOX: GEOM_BOX}
        out = [(code.get(int(model.body_shape[i]), -1), np.asarray(model.body_size[i], float))
               for i in range(n)]
    else:
        out = []
        for i in range(n):
            gs = np.flatnonzero(np.asarray(model.geom_body) == i)
            if len(gs) != 1 or np.any(model.geom_pos_body[gs[0]] != 0) \
                    or np.any(model.geom_quat_wxyz_body[gs[0]] != (1.0, 0.0, 0.0, 0.0)):
                raise EngineUnsupported(engine, f"body {model.body_name[i]!r}: {len(gs)} geoms or a "
                                        "geom off the body's centre of mass and principal axes")
            out.append((int(model.geom_type[gs[0]]), np.asarray(model.geom_size[gs[0]], float)))
    for i, (code, _) in enumerate(out):
        if code not in takes:
            raise EngineUnsupported(engine, f"body {model.body_name[i]!r}: shape "
                                    f"{GEOM_NAMES.get(code, f'code {code}')!r}")
    return out


def body_parts(model, engine: str, takes=(GEOM_SPHERE, GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER)):
    """Each body's geoms: a list over the bodies of lists of (GEOM_* code, size (3,) m, position
    (3,) m and quaternion wxyz (4,) geom -> body in the body frame (centre of mass, principal
    axes), geom row or -1), one entry for a one-shape body (at the origin, identity), several for
    a compound. A geom type outside ``takes`` raises EngineUnsupported naming it."""
    n = model.n_bodies
    if model.geom_type is None:
        return [[(code, size, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]), -1)]
                for code, size in body_geoms(model, engine, takes)]
    gb = np.asarray(model.geom_body)
    out = []
    for i in range(n):
        gs = np.flatnonzero(gb == i)
        if not len(gs):
            raise EngineUnsupported(engine, f"body {model.body_name[i]!r}: no geoms")
        rows = []
        for g in gs.tolist():
            code = int(model.geom_type[g])
            if code not in takes:
                raise EngineUnsupported(engine, f"body {model.body_name[i]!r}: shape "
                                        f"{GEOM_NAMES.get(code, f'code {code}')!r}")
            q = np.asarray(model.geom_quat_wxyz_body[g], float)
            rows.append((code, np.asarray(model.geom_size[g], float),
                         np.asarray(model.geom_pos_body[g], float), q / np.linalg.norm(q), g))
        out.append(rows)
    return out


def geom_hull(model, g: int, name: str) -> tuple[np.ndarray, list, np.ndarray, np.ndarray]:
    """body_mesh's (vertices, faces, face normals, face offsets) of mesh geom ``g``, in its geom
    frame (the body ``name`` in the error)."""
    from rblog.engine.hull import hull_boundary

    v = np.asarray(model.geom_vertices(g), float)

    def fail(e):
        raise RblogError(f"body {name!r}: its mesh: {e}")

    used, _, faces, fn, fo = hull_boundary(v, fail)
    return v[used], faces, fn, fo


def geom_mesh(model, g: int, name: str) -> np.ndarray:
    """(V, 3) vertices of mesh geom ``g``'s hull in its geom frame (geom_hull)."""
    return geom_hull(model, g, name)[0]


def body_mesh(model, i: int) -> tuple[np.ndarray, list, np.ndarray, np.ndarray]:
    """(vertices (V, 3) m, faces (index loops, counter-clockwise seen from outside), face normals
    (F, 3), face offsets (F,): n . x = offset on the face) of body i's mesh geom, in the body
    frame (a scene's hull: centre of mass, principal axes); its hull's boundary by
    rblog.engine.hull.hull_boundary (qhull)."""
    from rblog.engine.hull import hull_boundary

    g = int(np.flatnonzero(np.asarray(model.geom_body) == i)[0])
    v = np.asarray(model.geom_vertices(g), float)

    def fail(e):
        raise RblogError(f"body {model.body_name[i]!r}: its mesh: {e}")

    used, _, faces, fn, fo = hull_boundary(v, fail)
    return v[used], faces, fn, fo


def initial_world_omega(scene) -> np.ndarray:
    """(N, 3) world angular velocity of the initial state: R diag(1/I) R^T L."""
    st, model = scene.state, scene.model
    r = st.rotation
    lb = np.einsum("nji,nj->ni", r, st.angular_momentum_world) / model.body_inertia_diag
    return np.einsum("nij,nj->ni", r, lb)


def z_to(normal) -> np.ndarray:
    """Unit quaternion (w, x, y, z) rotating +z onto ``normal``."""
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, n)
    s, c = float(np.linalg.norm(axis)), float(np.dot(z, n))
    if s < 1e-12:
        return np.array([1.0, 0, 0, 0]) if c > 0 else np.array([0.0, 1.0, 0, 0])
    ang = math.atan2(s, c)
    return np.concatenate([[math.cos(ang / 2)], math.sin(ang / 2) * axis / s])


@dataclass
class EngineRunSummary:
    """What ``rblog run --engine`` prints: the engine, its settings, and the time split."""

    engine: str
    version: str
    steps: int
    bodies: int
    samples: int
    contacts: int
    dt: float
    log_every: int
    sim_time_s: float
    wall_time_s: float
    step_wall_s: float
    record_wall_s: float
    settings: dict = field(default_factory=dict)
    logs: list = field(default_factory=list)

    def to_dict(self) -> dict:
        from dataclasses import asdict

        return asdict(self)


#: with a live audit, blocks of at most this many samples (0.5 s at the default 100 Hz), so that
#: it can announce a finding before the run ends (rblog's own run loop sizes its blocks by wall
#: time, ~30 ms each)
AUDIT_BLOCK_SAMPLES = 50


def run_engine(scene, engine: str, *, options=(), dt=None, duration=None, log_every=None,
               log_rate=None, rrd=None, mcap=None, keep=False, mcap_compression="lz4",
               audit=None):
    """Run ``scene`` in ``engine`` and record it; returns (EngineRunSummary, Trajectory or None).

    The time split: ``step_wall_s`` is the engine's own stepping, ``record_wall_s`` everything
    else (reading the engine's state and contacts, deriving, encoding, writing). ``audit``: a
    rblog.record.live_audit.LiveAudit that checks the blocks as they are recorded."""
    from rblog.adapters._common import SampleStream
    from rblog.engine.runner import resolve_log_every, samples_per_block
    from rblog.record.recorder import Recorder

    if engine not in ENGINE_NAMES:
        raise RblogError(f"--engine: unknown engine {engine!r} (expected one of: {', '.join(ENGINE_NAMES)})")
    if engine == "mujoco":
        from rblog.study.engines.mujoco import MujocoRun as Run
    elif engine == "ode":
        from rblog.study.engines.ode import OdeRun as Run
    else:
        from rblog.study.engines.pybullet import PybulletRun as Run
    sim = scene.sim
    dt = sim.dt if dt is None else float(dt)
    duration = sim.duration if duration is None else float(duration)
    if not (dt > 0 and math.isfinite(dt)):
        raise RblogError(f"--dt: expected a positive number, got {dt}")
    if log_every is None and log_rate is None:
        log_every, log_rate = sim.log_every, sim.log_rate
    stride = resolve_log_every(dt, log_every, log_rate)
    n_total = max(1, int(round(duration / dt)))
    eng = Run(scene, dt, options)
    # an engine that accounts for every step's impulses (PybulletRun) logs them per interval
    supplied = getattr(eng, "impulse_supplied", None)
    model = scene.model if supplied is None else replace(scene.model, body_impulse_supplied=supplied)
    try:
        rec = Recorder(model, rrd=rrd, mcap=mcap, dt=dt, writer=f"{engine} {eng.version}",
                       integrator=eng.settings.get("integrator", ""), log_every=stride,
                       duration_s=n_total * dt, combine_friction="geometric",
                       combine_restitution="max", engine_settings=eng.settings,
                       scene_path=scene.path, scene_toml=scene.toml_text,
                       scene_resolved=scene.resolved, seed=sim.seed, keep=keep,
                       mcap_compression=mcap_compression,
                       check=audit if audit is not None else False)
        per_block = samples_per_block(scene.model.n_bodies, stride)
        if audit is not None:  # the live audit sees the run a block at a time
            per_block = min(per_block, AUDIT_BLOCK_SAMPLES)
        t_wall = time.perf_counter()
        t_step = 0.0
        n_contacts = 0
        with rec:
            buf = SampleStream(rec, block=per_block)  # writes a block every per_block samples
            buf.add(0, *eng.state(), None, None if supplied is None else eng.impulses())
            done = 0
            while done < n_total:
                k = min(stride, n_total - done)
                t0 = time.perf_counter()
                eng.step(k)
                t_step += time.perf_counter() - t0
                done += k
                c = eng.contacts(done)
                n_contacts += 0 if c is None else len(c["step"])
                buf.add(done, *eng.state(), c, None if supplied is None else eng.impulses())
            buf.flush(dt)
        wall = time.perf_counter() - t_wall
    finally:
        eng.close()
    summary = EngineRunSummary(
        engine=engine, version=eng.version, steps=n_total, bodies=scene.model.n_bodies,
        samples=rec.samples_written, contacts=n_contacts, dt=dt, log_every=stride,
        sim_time_s=n_total * dt, wall_time_s=wall, step_wall_s=t_step,
        record_wall_s=wall - t_step, settings=eng.settings,
        logs=[p for p in (rrd, mcap) if p])
    return summary, (rec.trajectory if keep else None)


__all__ = ["ENGINE_NAMES", "EngineMissing", "EngineUnsupported", "EngineRunSummary", "run_engine"]
