"""Logs of MuJoCo and pybullet runs of rblog's sample scenes, for testing `rblog check` on what
other engines write (a stand-in for the public writer API until it lands).

:func:`engine_samples` steps the engine directly on a scene's bodies (same masses, principal
inertias, materials, ground) and samples every ``log_every`` steps: positions, quaternions,
velocities and world angular velocities, plus the engine's contacts of the sampled steps (point,
normal from body_b into body_a, separation, and the step's impulses on body_a: force x dt).
:func:`to_trajectory` turns them (possibly altered to plant a fault) into a Trajectory through the
writer's own derivation (rblog.contract.trajectory.derive).

MuJoCo's contacts are soft and have no restitution: a restitution e is given as the damping ratio
of the contact's mass-spring-damper with the same rebound (rblog.study.peers' mapping), with the
spring's time constant at ``MUJOCO_TC_S``, so an impact lasts tens of steps (what a compliant
engine does to a per-step check). pybullet multiplies the pair's restitutions and frictions, so the
ground carries 1 and the body its own coefficients.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from rblog.contract.model import SHAPE_SPHERE
from rblog.contract.trajectory import CONTACT_RESTING, STATIC_BODY, Contacts, RunInfo, derive
from rblog.engine.scene import load_scene
from rblog.study.engines.mujoco import zeta_of_restitution
from rblog.study.reference import quat_to_matrix

#: MuJoCo's contact spring in scenes with restitution: omega dt (rblog.study.peers' choice, stable
#: for explicit stepping; an impact lasts ~30 steps): solref = (dt / (omega_dt z), z), omega =
#: 1 / (tc z). The least damping ratio: 0 reads as MuJoCo's "direct" solref format; 3e-4 rebounds
#: with e = exp(-pi z) = 0.999.
MUJOCO_OMEGA_DT = 0.1
MUJOCO_MIN_DAMPRATIO = 3e-4


@dataclass
class EngineSamples:
    model: object
    info: RunInfo
    step: np.ndarray      # (T,)
    t: np.ndarray         # (T,) s
    position: np.ndarray  # (T, N, 3) m
    quat_wxyz: np.ndarray  # (T, N, 4)
    velocity: np.ndarray  # (T, N, 3) m/s
    omega_world: np.ndarray  # (T, N, 3) rad/s
    contacts: Contacts


def to_trajectory(s: EngineSamples):
    m = s.model
    r = quat_to_matrix(s.quat_wxyz)
    inertia = np.asarray(m.body_inertia_diag, float)
    # L = R diag(I) R^T omega (world)
    l_body = np.einsum("tnji,tnj->tni", r, s.omega_world) * inertia[None]
    ang = np.einsum("tnij,tnj->tni", r, l_body)
    p = s.velocity * np.asarray(m.body_mass, float)[None, :, None]
    return derive(m, s.info, s.step, s.t, s.position, p, s.quat_wxyz, r, ang, s.contacts)


def _contacts(rows) -> Contacts:
    if not rows:
        return Contacts.empty()
    col = lambda j, dt=float: np.array([r[j] for r in rows], dt)
    return Contacts(step=col(0, np.int64), t=col(1), body_a=col(2, np.int64),
                    body_b=col(3, np.int64), point=col(4), normal=col(5), separation=col(6),
                    normal_impulse=col(7), friction_impulse=col(8),
                    kind=np.full(len(rows), CONTACT_RESTING, np.int8))


def engine_samples(engine: str, scene: str, *, duration: float | None = None, log_every: int = 1,
                   dt: float | None = None, restitution_scale: float = 1.0) -> EngineSamples:
    """Run ``scene`` (a samples/*.toml path) in ``engine`` ("mujoco" or "pybullet").

    ``restitution_scale`` mistunes the engine: it is given e x scale while the log's model keeps
    the scene's e (a planted restitution fault)."""
    sc = load_scene(scene)
    dt = float(dt or sc.sim.dt)
    duration = float(duration or sc.sim.duration)
    n_steps = int(round(duration / dt))
    run = {"mujoco": _mujoco, "pybullet": _pybullet}[engine]
    info = RunInfo(integrator=engine, orthonormalize="none", dt=dt, log_every=log_every,
                   duration_s=duration, rblog_version="test", scene_path=str(scene),
                   writer=engine)
    return run(sc, dt, n_steps, log_every, info, restitution_scale)


def _initial(sc):
    st, m = sc.state, sc.model
    v0 = st.linear_momentum / np.asarray(m.body_mass, float)[:, None]
    r = st.rotation
    inv_i = np.asarray(m.body_inv_inertia_diag, float)
    w0 = np.einsum("nij,nj->ni", r, np.einsum("nji,nj->ni", r, st.angular_momentum_world) * inv_i)
    return st.position, st.quat_wxyz, v0, w0


def _mujoco(sc, dt, n_steps, every, info, e_scale=1.0):
    mujoco = pytest.importorskip("mujoco")
    m = sc.model
    n = m.n_bodies
    bouncy = bool(np.any(np.asarray(m.body_restitution) > 0))

    def attrs(e, mu):
        fr = f' friction="{mu!r} 0.005 0.0001"'
        if not bouncy:
            return fr
        z = max(zeta_of_restitution(e * e_scale, MUJOCO_OMEGA_DT), MUJOCO_MIN_DAMPRATIO)
        tc = max(dt / (MUJOCO_OMEGA_DT * z), 2.0 * dt)
        return f' solref="{tc!r} {z!r}" solimp="0.99 0.99 0.001"' + fr

    g = " ".join(repr(float(x)) for x in m.gravity)
    xml = [f'<mujoco><option timestep="{dt!r}" gravity="{g}"/><worldbody>']
    if m.ground:
        xml.append(f'<geom name="ground" type="plane" size="0 0 1" pos="0 0 {float(m.ground_offset)!r}"'
                   f'{attrs(float(max(m.body_restitution.max(), m.ground_restitution)), float(m.ground_friction))}/>')
    for i in range(n):
        size = m.body_size[i]
        geom = (f'type="sphere" size="{float(size[0])!r}"' if m.body_shape[i] == SHAPE_SPHERE else
                'type="box" size="' + " ".join(repr(float(x)) for x in size) + '"')
        inert = " ".join(repr(float(x)) for x in m.body_inertia_diag[i])
        xml.append(f'<body name="b{i}"><freejoint/><inertial pos="0 0 0" mass="{float(m.body_mass[i])!r}" '
                   f'diaginertia="{inert}"/><geom {geom}'
                   f'{attrs(float(m.body_restitution[i]), float(m.body_friction[i]))}/></body>')
    xml.append("</worldbody></mujoco>")
    mm = mujoco.MjModel.from_xml_string("".join(xml))
    d = mujoco.MjData(mm)
    x0, q0, v0, w0 = _initial(sc)
    r0 = quat_to_matrix(q0)
    for i in range(n):
        d.qpos[7 * i:7 * i + 3] = x0[i]
        d.qpos[7 * i + 3:7 * i + 7] = q0[i]
        d.qvel[6 * i:6 * i + 3] = v0[i]
        d.qvel[6 * i + 3:6 * i + 6] = r0[i].T @ w0[i]  # free joint: body-frame angular velocity
    mujoco.mj_forward(mm, d)
    body_of_geom = mm.geom_bodyid - 1  # world body 0 -> -1 (static)
    steps, rows_q, rows_v, rows = [0], [d.qpos.copy()], [d.qvel.copy()], []
    f6 = np.zeros(6)
    for s in range(1, n_steps + 1):
        mujoco.mj_step(mm, d)
        if s % every and s != n_steps:
            continue
        steps.append(s)
        rows_q.append(d.qpos.copy())
        rows_v.append(d.qvel.copy())
        for c in range(d.ncon):
            con = d.contact[c]
            mujoco.mj_contactForce(mm, d, c, f6)
            frame = con.frame.reshape(3, 3)
            b1, b2 = int(body_of_geom[con.geom1]), int(body_of_geom[con.geom2])
            # MuJoCo: normal from geom1 to geom2, force on geom2 (contact frame)
            force = frame.T @ f6[:3]
            nrm, a, b = frame[0], b2, b1
            if a < 0:
                nrm, force, a, b = -nrm, -force, b1, b2
            fn = float(force @ nrm)
            rows.append((s, s * dt, a, STATIC_BODY if b < 0 else b, con.pos.copy(), nrm, con.dist,
                         fn * dt, (force - fn * nrm) * dt))
    qp = np.array(rows_q).reshape(len(steps), n, 7)
    qv = np.array(rows_v).reshape(len(steps), n, 6)
    quat = qp[..., 3:7] / np.linalg.norm(qp[..., 3:7], axis=-1, keepdims=True)
    omega_w = np.einsum("tnij,tnj->tni", quat_to_matrix(quat), qv[..., 3:6])
    st = np.array(steps)
    return EngineSamples(m, info, st, st * dt, qp[..., :3], quat, qv[..., :3], omega_w,
                         _contacts(rows))


def _pybullet(sc, dt, n_steps, every, info, e_scale=1.0):
    pb = pytest.importorskip("pybullet")

    m = sc.model
    n = m.n_bodies
    cid = pb.connect(pb.DIRECT)
    try:
        pb.setGravity(*map(float, m.gravity), physicsClientId=cid)
        pb.setTimeStep(dt, physicsClientId=cid)
        pb.setPhysicsEngineParameter(numSubSteps=0, physicsClientId=cid)
        x0, q0, v0, w0 = _initial(sc)
        ids = []
        for i in range(n):
            if m.body_shape[i] == SHAPE_SPHERE:
                col = pb.createCollisionShape(pb.GEOM_SPHERE, radius=float(m.body_size[i, 0]),
                                              physicsClientId=cid)
            else:
                col = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=list(map(float, m.body_size[i])),
                                              physicsClientId=cid)
            q = q0[i]
            bid = pb.createMultiBody(baseMass=float(m.body_mass[i]), baseCollisionShapeIndex=col,
                                     basePosition=list(map(float, x0[i])),
                                     baseOrientation=[q[1], q[2], q[3], q[0]], physicsClientId=cid)
            pb.changeDynamics(bid, -1, localInertiaDiagonal=list(map(float, m.body_inertia_diag[i])),
                              linearDamping=0.0, angularDamping=0.0,
                              restitution=float(m.body_restitution[i] * e_scale),
                              lateralFriction=float(m.body_friction[i]), rollingFriction=0.0,
                              spinningFriction=0.0, physicsClientId=cid)
            pb.resetBaseVelocity(bid, list(map(float, v0[i])), list(map(float, w0[i])),
                                 physicsClientId=cid)
            ids.append(bid)
        if n == 2 and not m.ground:  # the product of restitutions: one carries e, the other 1
            pb.changeDynamics(ids[1], -1, restitution=1.0, physicsClientId=cid)
        if m.ground:
            plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=cid)
            gid = pb.createMultiBody(0, plane, basePosition=[0, 0, float(m.ground_offset)],
                                     physicsClientId=cid)
            pb.changeDynamics(gid, -1, restitution=1.0, lateralFriction=1.0, physicsClientId=cid)
        index = {bid: i for i, bid in enumerate(ids)}

        def state():
            out = []
            for bid in ids:
                p, q = pb.getBasePositionAndOrientation(bid, physicsClientId=cid)
                v, w = pb.getBaseVelocity(bid, physicsClientId=cid)
                out.append((p, (q[3], q[0], q[1], q[2]), v, w))
            return out

        steps, sts, rows = [0], [state()], []
        for s in range(1, n_steps + 1):
            pb.stepSimulation(physicsClientId=cid)
            if s % every and s != n_steps:
                continue
            steps.append(s)
            sts.append(state())
            for c in pb.getContactPoints(physicsClientId=cid):
                a, b = index.get(c[1], -1), index.get(c[2], -1)
                nrm = np.array(c[7])  # on B, pointing towards A
                fric = (c[10] * np.array(c[11]) + c[12] * np.array(c[13])) * dt
                if a < 0:
                    a, b, nrm, fric = b, a, -nrm, -fric
                rows.append((s, s * dt, a, STATIC_BODY if b < 0 else b, np.array(c[5]), nrm,
                             c[8], c[9] * dt, fric))
    finally:
        pb.disconnect(physicsClientId=cid)
    arr = lambda k: np.array([[b[k] for b in st] for st in sts], float)
    quat = arr(1)
    quat /= np.linalg.norm(quat, axis=-1, keepdims=True)
    st = np.array(steps)
    return EngineSamples(m, info, st, st * dt, arr(0), quat, arr(2), arr(3), _contacts(rows))
