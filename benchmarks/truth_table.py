"""Verdicts on real models: every analyzer's verdict against a truth computed from the engine's
own data (issue 37, "Done when" item 2).

The models are the recording issue's, as shipped: dm_control's suite (MuJoCo, its own
integrator: cartpole RK4, the rest Euler) and pybullet_data's worlds (pybullet's default damping,
r2d2 as a multibody and in maximal coordinates), each with zero and random controls (pybullet:
random velocity targets on the motors of r2d2 and kuka; its free-body worlds have no controls),
recorded by the adapters at every step and at every 10th, and audited with ``rblog.check``.

The truth, never from the log or from rblog's code:

* penetration: MuJoCo's ``contact.dist`` after ``mj_forward`` at each logged qpos (a separate
  MjData), pybullet's ``getClosestPoints`` between every two bodies at each sample (links of
  one multibody left out: pybullet does not collide them): the deepest penetration of any
  geom pair. A fault when it exceeds the analyzer's transient tolerance by MARGIN; between the
  resting and the transient tolerance either verdict agrees (a fault only if the pair rests);
  below, clean. A pybullet result whose findings are all creep is held against pybullet's own
  base poses: how far one block's centre moves in its partner's frame over the run.
* energy (MuJoCo): ``mj_energyPos + mj_energyVel`` at each logged state (springs' potential
  included) less the work of every force but gravity and the springs (``qfrc_actuator +
  qfrc_passive - qfrc_spring + qfrc_constraint`` at each step's mean velocity; Euler's
  implicit damping at the step's end velocity), judged by the energy analyzer's definition
  (one definition for the verdict and its truth): a fault where ``|E(t) - E(0)|`` exceeds
  ENERGY_DRIFT_REL of the run's energy scale (its largest kinetic energy or the range of its
  potential) plus the first-order step's bias ENERGY_DT_FACTOR h sum_b m_b |g| (|v_b(t)| +
  |v_b(0)|) / 2 (rblog.analyze.energy; the bodies' centre-of-mass speeds from MuJoCo's cvel).
  An engine's integration error beyond that is a finding, as a free body's drift is (a 1 %
  gain must be caught). Runs with contacts: judged on each stretch of samples in which no
  MuJoCo step had a contact (``ncon`` at its start state), its scale and allowance the
  stretch's own, whole-model energy (the rotors' 0.5 armature qdot^2 included, as the log's
  joint_armature lets the analyzer count them); RK4 runs up to the first step that meets a joint limit (its force across
  RK4's stages does work the step's start does not show: the adapter logs that step's joint
  work NaN). pybullet (PybulletEnergy): each multibody's energy from pybullet's link states
  less the work of Bullet's damping, the URDF joint damping (getJointInfo) and the motors
  (appliedJointMotorTorque), each at the step's mean velocity, on the stretches whose steps
  have no contact pushing the body, no joint starting at a limit and no clamped velocity
  (the adapter takes the joints' forces from the joint sensors' reactions instead); r2d2 in
  maximal coordinates: none (pybullet shows only its base).
* momentum: Newton holds inside either engine: each body's momentum change equals its impulses
  + m g dt, measured from qvel / getBaseVelocity to 1e-9 relative by
  tests/adapters/test_mujoco_models.py and test_pybullet_worlds.py; the truth is clean.
* consistency, drift, joints, tunneling: both engines state poses and velocities from one
  state (unit quaternions; MuJoCo's joints exact in generalized coordinates, pybullet's
  multibody joints too): clean. r2d2 in maximal coordinates: not judged (the adapter logs its
  links as free bodies, without their joint constraints).

Outcomes: agree; false alarm (FAIL on a clean truth); miss (pass on a fault); not judged (the
analyzer's own "not judged"/"skip" where there is something to judge); "not judged (truth)" and
"unverified FAIL" where this truth has no figure.

Run: ``nice .venv/bin/python benchmarks/truth_table.py [--steps N] [--only NAME ...]``; writes
the table to stdout (and ``--md`` to a file).
"""

from __future__ import annotations

import argparse
import re
import sys
import time

import numpy as np

import rblog

#: a truth depth beyond the analyzer's tolerance by more than this fraction of it is a fault the
#: analyzer must find; within the tolerance, a finding is a false alarm; between, either verdict
#: agrees (the engine's contact solve and the audit's geometry differ by ~1e-6 m, issue 37)
MARGIN = 0.1

MJ_MODELS = ["humanoid", "stacker", "manipulator", "cartpole", "walker", "ball_in_cup", "finger",
             "fish"]
PB_WORLDS = ["r2d2", "r2d2_maximal", "kuka_cube", "jenga", "domino", "tray"]
ANALYZERS = ["consistency", "drift", "momentum", "penetration", "energy", "tunneling", "joints"]


def record_mujoco(name, every, ctrl, steps):
    import mujoco

    from rblog.adapters import mujoco as adapter

    m = adapter.suite_model(name)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    rng = np.random.default_rng(7)
    qpos, qvel, work = [d.qpos.copy()], [d.qvel.copy()], [0.0]
    rec = adapter.recorder(m, d, every=every)
    h = m.opt.timestep
    rk4_limit = None  # the first RK4 step with a joint limit, friction loss or equality row
    touching = []  # per step: MuJoCo has a contact at the step's start state (Euler: the step's)
    for k in range(steps):
        if ctrl == "random":
            d.ctrl[:] = rng.uniform(-1.0, 1.0, m.nu)
        mujoco.mj_step(m, d)
        rec(d)
        touching.append(d.ncon > 0)
        if (m.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4 and d.nl + d.nf + d.ne
                and rk4_limit is None):
            rk4_limit = k
        # the work of every force but gravity and the springs over the step (actuators, passive,
        # constraints: MuJoCo's own generalized forces of the step, at its mean velocity); the
        # springs' potential is in mj_energyPos, so their force (qfrc_spring) does no work here
        f = d.qfrc_actuator + d.qfrc_passive - d.qfrc_spring + d.qfrc_constraint
        if m.opt.integrator == mujoco.mjtIntegrator.mjINT_EULER:
            # Euler integrates joint damping implicitly: the step applies -D v(end), not the
            # -D v(start) that qfrc_passive holds
            f = f + m.dof_damping * (qvel[-1] - d.qvel)
        work.append(work[-1] + h * float(f @ (0.5 * (qvel[-1] + d.qvel))))
        qpos.append(d.qpos.copy())
        qvel.append(d.qvel.copy())
    rec.close()
    return (m, rec.trajectory, np.array(qpos), np.array(qvel), np.array(work), rk4_limit,
            np.array(touching, bool))


def stretches(steps, touching):
    """[(first, last)] sample indices of the runs of samples between which no step of MuJoCo's
    had a contact (``touching[s]``: a contact at step ``s``'s start state; the interval of
    samples ``k-1, k`` holds steps ``steps[k-1] .. steps[k] - 1``), each at least two samples."""
    steps = np.asarray(steps)
    free = np.array([not touching[a:b].any() for a, b in zip(steps[:-1], steps[1:])], bool)
    out, k0 = [], None
    for k, f in enumerate(free):
        if f and k0 is None:
            k0 = k
        if not f and k0 is not None:
            out.append((k0, k))
            k0 = None
    if k0 is not None:
        out.append((k0, len(free)))
    return out


def mujoco_truth(m, traj, qpos, qvel, work, ctrl, rk4_limit=None, touching=None):
    """The engine's own numbers at the logged samples: deepest penetration per geom pair, energy."""
    import mujoco

    from rblog.analyze import tolerances as T

    d = mujoco.MjData(m)
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    depth = {}
    energy, kinetic, potential, gravity_speed = [], [], [], []
    g = np.zeros(3) if m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY else m.opt.gravity
    mg = m.body_mass[1:] * float(np.linalg.norm(g))
    ncon = 0
    for k, s in enumerate(traj.step):
        d.qpos[:], d.qvel[:] = qpos[s], qvel[s]
        mujoco.mj_forward(m, d)
        ncon += d.ncon
        for c in d.contact[:d.ncon]:
            pair = tuple(sorted((int(c.geom[0]), int(c.geom[1]))))
            if -c.dist > depth.get(pair, (0.0, 0))[0]:
                depth[pair] = (float(-c.dist), int(s))
        energy.append(d.energy[0] + d.energy[1] - work[s])
        kinetic.append(d.energy[1])
        potential.append(d.energy[0])
        # each body's centre-of-mass speed: cvel (about its subtree's centre) moved to xipos
        arm = d.xipos[1:] - d.subtree_com[m.body_rootid[1:]]
        v = d.cvel[1:, 3:] + np.cross(d.cvel[1:, :3], arm)
        gravity_speed.append(float(mg @ np.linalg.norm(v, axis=1)))
    passive = []
    if ctrl == "random" and m.nu:
        passive.append("actuators driven")
    if np.any(m.dof_damping > 0):
        passive.append("joint damping")
    if np.any(m.dof_frictionloss > 0):
        passive.append("friction loss")
    if m.ntendon:
        passive.append("tendons")
    if ncon or (touching is not None and touching.any()):
        passive.append("contacts")
    if rk4_limit is not None:
        # judged up to the first step that meets a limit (the analyzer ends its stretch there)
        passive.append(f"judged before an RK4 limit at step {rk4_limit}")
        before = np.asarray(traj.step) <= rk4_limit
        energy, kinetic, potential = energy[:before.sum()], kinetic[:before.sum()], \
            potential[:before.sum()]
        gravity_speed = gravity_speed[:before.sum()]
    if np.any(m.body_gravcomp > 0):
        passive.append("gravity compensation")
    name = lambda g: mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
    depth = {f"{name(a)}/{name(b)}": v for (a, b), v in depth.items()}
    energy, kinetic, potential = np.array(energy), np.array(kinetic), np.array(potential)
    gravity_speed = np.array(gravity_speed)
    # the stretches judged: the whole run, or with contacts MuJoCo's own contact-free stretches
    # (its contacts' work then is none: the balance closes on the logged forces' work alone)
    spans = [(0, len(energy) - 1)] if touching is None or not touching.any() else \
        [(a, min(b, len(energy) - 1)) for a, b in stretches(traj.step, touching) if a < len(energy) - 1]
    segs = []
    for a, b in spans:
        sl = slice(a, b + 1)
        scale = max(float(np.max(kinetic[sl])), float(np.ptp(potential[sl])),
                    T.ENERGY_FLOOR_J_PER_KG * float(m.body_mass.sum()))
        allow = T.ENERGY_DRIFT_REL * scale + T.ENERGY_DT_FACTOR * m.opt.timestep * 0.5 * (
            gravity_speed[sl] + gravity_speed[a])
        segs.append((energy[sl], scale, allow, (int(traj.step[a]), int(traj.step[b]))))
    return depth, segs, passive


class PybulletEnergy:
    """pybullet's energy per multibody from its own numbers, for the energy truth.

    At each step's start and end: every dynamic link's and free base's mass, principal inertia
    (``getDynamicsInfo``), centre-of-mass pose and velocities (``getBasePositionAndOrientation``
    / ``getBaseVelocity``, ``getLinkState`` with ``computeLinkVelocity``); E = sum m v.v / 2 +
    w.R I R^T w / 2 - m g.x. The work of every force but gravity over a step, at its mean
    velocity (a semi-implicit step changes the kinetic energy by (u0 + u1)/2 . M (u1 - u0)):
    Bullet's multibody damping, the force -m v k (1 + |v|) and torque -R I R^T w k (1 + |w|) at the
    start velocities (k = 0.04, btMultiBody's default, as pybullet sets it); each joint's URDF
    damping (``getJointInfo``'s jointDamping: the torque -c qdot0 pybullet adds before the step)
    and its motor (``getJointState``'s appliedJointMotorTorque) at the joint's mean velocity.
    A step is left out of the stretches (touching) when a contact point after it pushes the body
    (``getContactPoints``' normal or friction force), a joint begins it at or beyond its limit (a constraint pybullet
    reports nowhere) or a joint velocity reaches Bullet's bound (100)."""

    K_DAMP = float(np.float32(0.04))
    V_MAX = 100.0

    def __init__(self, pb, cid):
        self.pb, self.cid = pb, cid
        self.bodies = []
        for k in range(pb.getNumBodies(physicsClientId=cid)):
            b = pb.getBodyUniqueId(k, physicsClientId=cid)
            info = pb.getDynamicsInfo(b, -1, physicsClientId=cid)
            if info[10] != 2:  # a btRigidBody (maximal coordinates): pybullet shows no links
                continue
            links = [(-1, info)] if info[0] > 0 else []
            joints = []
            for j in range(pb.getNumJoints(b, physicsClientId=cid)):
                ji = pb.getJointInfo(b, j, physicsClientId=cid)
                links.append((j, pb.getDynamicsInfo(b, j, physicsClientId=cid)))
                if ji[2] in (pb.JOINT_REVOLUTE, pb.JOINT_PRISMATIC):
                    joints.append((j, float(ji[6]), float(ji[8]), float(ji[9])))
            if links:
                self.bodies.append((b, links, joints))
        g = pb.getPhysicsEngineParameters(physicsClientId=cid)
        self.g = np.array([g["gravityAccelerationX"], g["gravityAccelerationY"],
                           g["gravityAccelerationZ"]])
        self.h = g["fixedTimeStep"]
        self.prev = self._read()
        self.work = [np.zeros(len(self.bodies))]
        self.bad = []  # per step: (n_bodies,) bool
        self.series = [self._energy(self.prev)]

    def _read(self):
        pb, c = self.pb, self.cid
        out = []
        for b, links, joints in self.bodies:
            rows = []
            for j, info in links:
                if j < 0:
                    x, q = pb.getBasePositionAndOrientation(b, physicsClientId=c)
                    v, w = pb.getBaseVelocity(b, physicsClientId=c)
                else:
                    st = pb.getLinkState(b, j, computeLinkVelocity=1, computeForwardKinematics=1,
                                         physicsClientId=c)
                    x, q, v, w = st[0], st[1], st[6], st[7]
                r = np.array(pb.getMatrixFromQuaternion(q)).reshape(3, 3)
                rows.append((info[0], r @ np.diag(info[2]) @ r.T, np.array(x), np.array(v),
                             np.array(w)))
            js = [pb.getJointState(b, j, physicsClientId=c) for j, *_ in joints]
            out.append((rows, js))
        return out

    def _energy(self, state):
        """(E, kinetic, potential, sum m |g| |v|) per body."""
        e = np.zeros((4, len(self.bodies)))
        gn = float(np.linalg.norm(self.g))
        for i, (rows, _) in enumerate(state):
            for m, inertia, x, v, w in rows:
                ke = 0.5 * m * v @ v + 0.5 * w @ inertia @ w
                e[1, i] += ke
                e[2, i] -= m * self.g @ x
                e[3, i] += m * gn * np.linalg.norm(v)
        e[0] = e[1] + e[2]
        return e

    def after_step(self):
        pb, c, h = self.pb, self.cid, self.h
        now = self._read()
        work = np.zeros(len(self.bodies))
        bad = np.zeros(len(self.bodies), bool)
        for i, ((b, links, joints), (r0, j0), (r1, j1)) in enumerate(zip(self.bodies, self.prev,
                                                                          now)):
            for (m, inertia, _, v0, w0), (_, _, _, v1, w1) in zip(r0, r1):
                f = -m * self.K_DAMP * (1 + np.linalg.norm(v0)) * v0 * h
                t = -self.K_DAMP * (1 + np.linalg.norm(w0)) * (inertia @ w0) * h
                work[i] += f @ (v0 + v1) / 2 + t @ (w0 + w1) / 2
            for (j, damp, lo, hi), s0, s1 in zip(joints, j0, j1):
                tau = (s1[3] - damp * s0[1]) * h
                work[i] += tau * (s0[1] + s1[1]) / 2
                if lo <= hi and (s0[0] <= lo or s0[0] >= hi):
                    bad[i] = True
                if abs(s1[1]) >= self.V_MAX:
                    bad[i] = True
            pts = pb.getContactPoints(bodyA=b, physicsClientId=c)
            if any(p[9] or p[10] or p[12] for p in pts):
                bad[i] = True  # a contact pushed it (normal or friction force)
        self.prev = now
        self.work.append(self.work[-1] + work)
        self.bad.append(bad)
        self.series.append(self._energy(now))

    def segments(self, steps):
        """[(E - W at the stretch's samples, scale, allowance, (first step, last step))] for
        every body's stretches of logged samples with no left-out step between them; the
        analyzer's definition (rblog.analyze.energy's drift check)."""
        from rblog.analyze import tolerances as T

        steps = np.asarray(steps)
        ser, work, bad = np.array(self.series), np.array(self.work), np.array(self.bad)
        segs = []
        for i, (b, links, _) in enumerate(self.bodies):
            mass = sum(info[0] for _, info in links)
            e = ser[steps, 0, i] - work[steps, i]
            ke, pe, gs = ser[steps, 1, i], ser[steps, 2, i], ser[steps, 3, i]
            for a, z in stretches(steps, bad[:, i]):
                sl = slice(a, z + 1)
                scale = max(float(ke[sl].max()), float(np.ptp(pe[sl])),
                            T.ENERGY_FLOOR_J_PER_KG * mass)
                allow = T.ENERGY_DRIFT_REL * scale + T.ENERGY_DT_FACTOR * self.h * 0.5 * (
                    gs[sl] + gs[a])
                segs.append((e[sl], scale, allow, (int(steps[a]), int(steps[z]))))
        return segs


def record_pybullet(name, every, ctrl, steps):
    import pybullet as pb

    from rblog.adapters.pybullet import PybulletRecorder, load_shipped

    cid = pb.connect(pb.DIRECT)
    load_shipped(name, cid)
    rec = PybulletRecorder(cid, keep=True, every=every)
    rng = np.random.default_rng(7)
    motors = []
    for k in range(pb.getNumBodies(physicsClientId=cid)):
        b = pb.getBodyUniqueId(k, physicsClientId=cid)
        for j in range(pb.getNumJoints(b, physicsClientId=cid)):
            kind = pb.getJointInfo(b, j, physicsClientId=cid)[2]
            if kind in (pb.JOINT_REVOLUTE, pb.JOINT_PRISMATIC):
                motors.append((b, j))
    depth = {}
    sample_steps = []

    def closest(step):
        n = pb.getNumBodies(physicsClientId=cid)
        ids = [pb.getBodyUniqueId(k, physicsClientId=cid) for k in range(n)]
        for i, a in enumerate(ids):
            for b in ids[i:]:
                pts = pb.getClosestPoints(a, b, 0.0, physicsClientId=cid)
                for p in pts:
                    if a == b:
                        continue  # links of one multibody: no self collision (pybullet's default)
                    key = f"{a}:{p[3]}/{b}:{p[4]}"
                    if -p[8] > depth.get(key, (0.0, 0))[0]:
                        depth[key] = (float(-p[8]), step)

    poses = []

    def pose():  # pybullet's own base poses of every body: (position, rotation) by body id
        out = {}
        for k in range(pb.getNumBodies(physicsClientId=cid)):
            b = pb.getBodyUniqueId(k, physicsClientId=cid)
            x, q = pb.getBasePositionAndOrientation(b, physicsClientId=cid)
            out[b] = (np.array(x), np.array(pb.getMatrixFromQuaternion(q)).reshape(3, 3))
        poses.append(out)

    closest(0)
    pose()
    energy = PybulletEnergy(pb, cid)
    for k in range(steps):
        if ctrl == "random" and motors:
            for b, j in motors:
                pb.setJointMotorControl2(b, j, pb.VELOCITY_CONTROL,
                                         targetVelocity=rng.uniform(-5, 5),
                                         force=50.0, physicsClientId=cid)
        pb.stepSimulation(physicsClientId=cid)
        rec()
        energy.after_step()
        if (k + 1) % every == 0:
            closest(k + 1)
            pose()
    rec.close()
    traj = rec.trajectory
    rows = list(rec.world.rows)
    pb.disconnect(physicsClientId=cid)
    passive = ["damping", "motors"] + (["motors driven"] if ctrl == "random" else [])
    return traj, depth, (poses, rows), energy.segments(traj.step), passive


def row_truths(engine, traj, results, depth, energy, passive):
    """{analyzer: (truth verdict, truth figure, why)} for one run."""
    from rblog.analyze import tolerances as T

    out = {}
    tol_rest, tol_tr = T.PENETRATION_DEPTH_M, T.PENETRATION_TRANSIENT_DEPTH_M
    worst = max(depth.items(), key=lambda kv: kv[1][0]) if depth else ("-", (0.0, 0))
    d = worst[1][0]
    if d > tol_tr * (1 + MARGIN):
        out["penetration"] = ("FAIL", f"{d * 1e3:.2f} mm {worst[0]} @{worst[1][1]}",
                              "beyond the transient tolerance")
    elif d > tol_rest * (1 + MARGIN):
        out["penetration"] = ("either", f"{d * 1e3:.2f} mm {worst[0]} @{worst[1][1]}",
                              "beyond the resting tolerance: a fault only if the pair rests")
    else:
        out["penetration"] = ("pass", f"{d * 1e3:.2f} mm {worst[0]}", "")
    if energy is None:
        out["energy"] = ("n/a", "", "pybullet shows only the base of a body in maximal "
                         "coordinates: no energy of the whole body")
    elif not energy:
        out["energy"] = ("n/a", "", "no stretch of two samples whose engine steps are free of contacts"
                         " (and, in pybullet, of joint limits)")
    else:
        # the worst sample of any stretch, by its ratio to the allowance
        worst = None
        for e, scale, allow, span in energy:
            bal = np.abs(e - e[0])
            k = int(np.argmax(bal / allow))
            if worst is None or bal[k] / allow[k] > worst[0]:
                worst = (bal[k] / allow[k], bal[k], scale, allow[k], span)
        _, bal, scale, lim, span = worst
        where = f" (MuJoCo contact-free steps {span[0]}-{span[1]}, {len(energy)} stretches)" \
            if "contacts" in passive else ""
        out["energy"] = ("FAIL" if bal > lim else "pass",
                         f"|E - E0 - W| {bal:.3g} J = {bal / scale:.2g} of the scale {scale:.3g} J, "
                         f"limit {lim / scale:.2g}{where}", ", ".join(passive) or "passive")
    for a in ("consistency", "drift", "momentum", "tunneling", "joints"):
        out[a] = ("pass", "", "engine's own state")
    out["momentum"] = ("pass", "", "Newton holds in the engine: each body's momentum change "
                       "equals its impulses + m g dt, measured from qvel / getBaseVelocity to "
                       "1e-9 relative (tests/adapters/test_mujoco_models.py, "
                       "test_pybullet_worlds.py)")
    return out


def creep_truth(results, truths, traj, poses, rows):
    """A penetration result whose findings are all creep ("creeps resting on"): the truth is
    pybullet's own poses, the largest move of one body's centre in the other's frame, normal
    to the contact (world z between stacked blocks: the tangential part) over the run."""
    pen = next(r for r in results if r.analyzer == "penetration")
    creeps = [f for f in pen.findings if " creeps " in f.message]
    if not creeps or len(creeps) != len(pen.findings) or truths["penetration"][0] != "pass":
        return
    worst = 0.0
    for f in creeps:
        partner = re.search(r"resting on body (\d+)", f.message)
        if partner is None:  # on the ground or a static body: the partner's frame is the world's
            a, b = rows[f.bodies[0]][0], None
        else:
            a, b = rows[f.bodies[0]][0], rows[int(partner.group(1))][0]
        if b is None:
            rel = np.array([pz[a][0] for pz in poses])
        else:
            rel = np.array([pz[b][1].T @ (pz[a][0] - pz[b][0]) for pz in poses])
        tang = rel[:, :2] - rel[0, :2]
        worst = max(worst, float(np.linalg.norm(tang, axis=1).max()))
    tol = creeps[0].tolerance
    truths["penetration"] = ("FAIL" if worst > tol else "pass",
                             f"creep: a centre moves {worst * 1e3:.3g} mm in its partner's frame "
                             f"(pybullet's poses), depth {truths['penetration'][1]}", "creep")


def judge(verdict, truth):
    t = truth[0]
    if verdict == "skip" and t == "pass":
        return "agree"  # nothing of the kind in the model (no joints)
    if verdict in ("not judged", "skip"):
        return "not judged"
    if t == "n/a":
        return "not judged (truth)" if verdict == "pass" else "unverified FAIL"
    if t == "either":
        return "agree"
    if verdict == t:
        return "agree"
    return "false alarm" if verdict == "FAIL" else "miss"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--only", nargs="*")
    ap.add_argument("--md")
    ap.add_argument("--verbose", action="store_true")
    args = ap.parse_args(argv)
    cases = [("mujoco", n, c, e) for n in MJ_MODELS for c in ("zero", "random") for e in (1, 10)]
    cases += [("pybullet", n, c, e) for n in PB_WORLDS
              for c in (("zero", "random") if n in ("r2d2", "r2d2_maximal", "kuka_cube")
                        else ("zero",))
              for e in (1, 10)]
    if args.only:
        cases = [c for c in cases if c[1] in args.only]
    rows = []
    t0 = time.process_time()
    for engine, name, ctrl, every in cases:
        steps = args.steps
        if engine == "mujoco":
            m, traj, qpos, qvel, work, rk4_limit, touching = record_mujoco(name, every, ctrl,
                                                                           steps)
            depth, energy, passive = mujoco_truth(m, traj, qpos, qvel, work, ctrl, rk4_limit,
                                                  touching)
        else:
            traj, depth, own, energy, passive = record_pybullet(name, every, ctrl, steps)
            if name == "r2d2_maximal":
                energy = None  # pybullet shows only its base: no energy of the whole body
        results = rblog.check(traj, threads=1)
        truths = row_truths(engine, traj, results, depth, energy, passive)
        if engine == "pybullet":
            creep_truth(results, truths, traj, *own)
        if name == "r2d2_maximal":
            truths["joints"] = ("n/a", "", "the adapter logs a maximal-coordinates body's links "
                                "as free bodies, without their joint constraints")
        for r in results:
            truth = truths[r.analyzer]
            rows.append((f"{name} {ctrl} /{every}", r.analyzer, r.verdict, truth[0], truth[1],
                         judge(r.verdict, truth), r.reason if r.verdict != "pass" else ""))
            if args.verbose and r.verdict == "FAIL":
                for f in r.findings[:3]:
                    print("   ", r.analyzer, f.message, file=sys.stderr)
        print(f"{name} {ctrl} /{every}: " + ", ".join(f"{r.analyzer}={r.verdict}" for r in results)
              + f"  [{time.process_time() - t0:.0f} s]", file=sys.stderr)
    counts = {}
    for row in rows:
        counts[row[5]] = counts.get(row[5], 0) + 1
    lines = ["| run | analyzer | verdict | truth | engine's figure | outcome |",
             "|---|---|---|---|---|---|"]
    for row in rows:
        if row[5] != "agree" or row[1] == "penetration":
            lines.append(f"| {row[0]} | {row[1]} | {row[2]} | {row[3]} | {row[4]} | {row[5]} |")
    summary = ", ".join(f"{k}: {v}" for k, v in sorted(counts.items()))
    outcomes = sorted(counts)
    per = ["| analyzer | " + " | ".join(outcomes) + " |", "|---" * (len(outcomes) + 1) + "|"]
    for a in ANALYZERS:
        c = [sum(1 for r in rows if r[1] == a and r[5] == o) for o in outcomes]
        per.append(f"| {a} | " + " | ".join(str(x) for x in c) + " |")
    lines = per + [""] + lines
    print("\n".join(lines))
    print(f"\n{len(rows)} verdicts: {summary}; CPU {time.process_time() - t0:.0f} s")
    if args.verbose:
        for row in rows:
            if row[5] not in ("agree",):
                print(row, file=sys.stderr)
    if args.md:
        with open(args.md, "w") as f:
            f.write("\n".join(lines) + f"\n\n{len(rows)} verdicts: {summary}\n")


if __name__ == "__main__":
    main()
