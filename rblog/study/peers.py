"""Optional peers: the reference problems of :mod:`rblog.study.reference` run in MuJoCo, pybullet
and ODE, reduced to the same :class:`~rblog.study.reference.Samples` and scored by the same code
as rblog.

All are optional (``pip install -e ".[engines]"`` in a checkout; ODE: Debian's ``libode8`` and
``pip install -e ".[ode]"``); :func:`available_peers` returns the installed ones. What each
engine is given:

* MuJoCo: one body per rblog body with a free joint and an explicit ``<inertial>`` (mass and
  principal moments, like rblog's ``inertia_diag``); its integrators ``Euler`` (the default,
  semi-implicit), ``RK4`` and ``implicitfast``. Contacts are off (``<flag contact="disable"/>``)
  in problems without contacts. MuJoCo's contacts are soft and have no coefficient of
  restitution: in the impact problems a restitution e is mapped to the damping ratio of a
  spring-damper that lets go when its force vanishes with the same rebound
  (:func:`rblog.study.engines.mujoco.zeta_of_restitution`; ``solref="tc dampratio"``, the
  spring's omega = 1/(tc dampratio) held at 0.2/dt for stability,
  impedance near 0.99 by ``solimp``); resting contact keeps MuJoCo's defaults; frictionless
  contacts use ``condim=1``. Free-joint angular velocity (qvel[3:6]) is body frame; rblog's is turned into it.
  A body's constant applied torque (world frame) goes into ``xfrc_applied``.
* pybullet: ``createMultiBody`` with the same mass and ``localInertiaDiagonal``, its default
  damping (0.04) set to 0. Bullet multiplies the two restitutions (and frictions) of a contact, so
  the static ground gets restitution 1 and the body e. Its one integrator is named ``default``.

* ODE: the problem's scene (``Problem.scene_toml``) translated by ``rblog run --engine ode``'s own
  code (:class:`rblog.study.engines.ode.OdeRun`: masses and principal moments, world-frame angular
  velocity, rblog's combine rules set per contact, dContactApprox1 friction, bounce above rblog's
  restitution threshold, ODE's default ERP 0.2 and CFM 1e-10); its two steppers ``dWorldStep``
  and ``dWorldQuickStep`` (20 iterations). A constant torque is ``dBodyAddTorque`` every step.

Timing (:meth:`time`): MuJoCo runs ``mj_step(nstep=N)`` in one call; pybullet has no multi-step
call, so its time includes one Python call per step (~1 us of its ~10-30 us per step); ODE has
none either and its collision pass calls a Python near callback for every candidate pair, so its
time is per step ``dSpaceCollide`` + the callback + ``dWorldStep`` + ``dJointGroupEmpty``
through ctypes, mostly Python for these one-body problems (2-10 us per step here).
"""

from __future__ import annotations

import math
import time

import numpy as np

from rblog.study.engines.mujoco import zeta_of_restitution
from rblog.study.reference import Problem, Samples, quat_to_matrix

PEER_NAMES = ("mujoco", "pybullet", "ode")
#: problems whose contacts are impacts with a restitution (MuJoCo gets the solref mapping)
IMPACT_KINDS = ("bounce", "two_sphere")
#: omega dt of MuJoCo's contact spring in impact problems (explicit stepping is unstable near 2;
#: 0.2 resolves a contact in ~15 steps)
MUJOCO_OMEGA_DT = 0.2


class MujocoPeer:
    name = "mujoco"
    integrators = ("Euler", "RK4", "implicitfast")

    def __init__(self):
        import mujoco

        self.mj = mujoco
        self.version = mujoco.__version__

    def supports(self, problem: Problem) -> str:
        return ""

    def mjcf(self, problem: Problem, integrator: str, dt: float) -> str:
        g = " ".join(repr(float(x)) for x in problem.gravity)
        flag = "" if problem.contacts else '<flag contact="disable"/>'
        parts = [f'<mujoco model="{problem.name}">',
                 f'<option timestep="{dt!r}" gravity="{g}" integrator="{integrator}">{flag}</option>',
                 "<worldbody>"]
        if problem.ground is not None:
            gr = problem.ground
            parts.append(f'<geom name="ground" type="plane" size="0 0 1" pos="0 0 {gr.get("height", 0.0)!r}"'
                         f'{self._contact_attrs(problem, gr.get("restitution", 0.5), gr.get("friction", 0.5), dt)}/>')
        for b in problem.bodies:
            pos = " ".join(repr(float(x)) for x in b.position)
            inertia = " ".join(repr(float(x)) for x in b.inertia_diag)
            if b.shape == "sphere":
                geom = f'type="sphere" size="{float(b.size[0])!r}"'
            else:
                geom = 'type="box" size="' + " ".join(repr(float(x)) for x in b.size) + '"'
            parts.append(
                f'<body name="{b.name}" pos="{pos}"><freejoint/>'
                f'<inertial pos="0 0 0" mass="{float(b.mass)!r}" diaginertia="{inertia}"/>'
                f'<geom {geom}{self._contact_attrs(problem, b.restitution, b.friction, dt)}/></body>')
        parts.append("</worldbody></mujoco>")
        return "".join(parts)

    @staticmethod
    def _contact_attrs(problem: Problem, e: float, mu: float, dt: float) -> str:
        fr = f' friction="{max(mu, 0.0)!r} 0.005 0.0001"' + ("" if mu > 0 else ' condim="1"')
        if problem.params.get("kind") not in IMPACT_KINDS:
            return fr  # resting contact: MuJoCo's default soft contact
        # the force-released spring-damper with damping ratio z rebounds with e; its natural
        # frequency is 1 / (tc z): tc = MUJOCO_OMEGA_DT^-1 dt / z keeps omega dt stable
        z = zeta_of_restitution(e, MUJOCO_OMEGA_DT)
        tc = max(dt / (MUJOCO_OMEGA_DT * max(z, 0.05)), 2.0 * dt, 0.002)
        return f' solref="{tc!r} {z!r}" solimp="0.99 0.99 0.001"' + fr

    def _setup(self, problem: Problem, integrator: str, dt: float):
        mj = self.mj
        m = mj.MjModel.from_xml_string(self.mjcf(problem, integrator, dt))
        d = mj.MjData(m)
        for i, b in enumerate(problem.bodies):
            d.qpos[7 * i:7 * i + 3] = b.position
            d.qpos[7 * i + 3:7 * i + 7] = np.asarray(b.quat_wxyz) / np.linalg.norm(b.quat_wxyz)
            d.qvel[6 * i:6 * i + 3] = b.velocity
            d.qvel[6 * i + 3:6 * i + 6] = b.omega_body
            # a constant world torque at the centre of mass (body i + 1: body 0 is the world);
            # xfrc_applied persists across steps
            d.xfrc_applied[i + 1, 3:6] = b.torque
        mj.mj_forward(m, d)
        return m, d

    def run(self, problem: Problem, integrator: str, dt: float):
        """Run and sample like rblog does; returns (Samples, steps)."""
        m, d = self._setup(problem, integrator, dt)
        n_total = max(1, int(round(problem.duration / dt)))
        stride = problem.log_every(dt)
        nb = len(problem.bodies)
        ts, qp, qv = [0.0], [d.qpos.copy()], [d.qvel.copy()]
        done = 0
        while done < n_total:
            k = min(stride, n_total - done)
            self.mj.mj_step(m, d, nstep=k)
            done += k
            ts.append(done * dt)
            qp.append(d.qpos.copy())
            qv.append(d.qvel.copy())
        qp = np.array(qp).reshape(len(ts), nb, 7)
        qv = np.array(qv).reshape(len(ts), nb, 6)
        quat = qp[..., 3:7]
        r = quat_to_matrix(quat)
        omega_w = np.einsum("tnij,tnj->tni", r, qv[..., 3:6])
        return Samples(np.array(ts), qp[..., :3], quat, qv[..., :3], omega_w), n_total

    def time(self, problem: Problem, integrator: str, dt: float, duration: float):
        """(wall seconds, steps) of stepping ``duration`` in one call."""
        m, d = self._setup(problem, integrator, dt)
        n = max(1, int(round(duration / dt)))
        t0 = time.perf_counter()
        self.mj.mj_step(m, d, nstep=n)
        return time.perf_counter() - t0, n


class PybulletPeer:
    name = "pybullet"
    integrators = ("default",)

    def __init__(self):
        import pybullet

        self.pb = pybullet
        self.version = str(pybullet.getAPIVersion())

    def supports(self, problem: Problem) -> str:
        if any(any(b.torque) for b in problem.bodies):
            return "applied torque not mapped (pybullet's external torque lasts one step)"
        return ""

    def _setup(self, problem: Problem, dt: float):
        pb = self.pb
        cid = pb.connect(pb.DIRECT)
        pb.setGravity(*problem.gravity, physicsClientId=cid)
        pb.setTimeStep(dt, physicsClientId=cid)
        pb.setPhysicsEngineParameter(numSubSteps=0, physicsClientId=cid)
        ids = []
        for b in problem.bodies:
            if b.shape == "sphere":
                col = pb.createCollisionShape(pb.GEOM_SPHERE, radius=float(b.size[0]), physicsClientId=cid)
            else:
                col = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=list(map(float, b.size)),
                                              physicsClientId=cid)
            q = np.asarray(b.quat_wxyz, float)
            q = q / np.linalg.norm(q)
            bid = pb.createMultiBody(baseMass=float(b.mass), baseCollisionShapeIndex=col,
                                     basePosition=list(map(float, b.position)),
                                     baseOrientation=[q[1], q[2], q[3], q[0]], physicsClientId=cid)
            pb.changeDynamics(bid, -1, localInertiaDiagonal=list(map(float, b.inertia_diag)),
                              linearDamping=0.0, angularDamping=0.0, restitution=float(b.restitution),
                              lateralFriction=float(b.friction), rollingFriction=0.0,
                              spinningFriction=0.0, physicsClientId=cid)
            if not problem.contacts:
                pb.setCollisionFilterGroupMask(bid, -1, 0, 0, physicsClientId=cid)
            pb.resetBaseVelocity(bid, list(map(float, b.velocity)), list(map(float, b.omega_world)),
                                 physicsClientId=cid)
            ids.append(bid)
        if problem.ground is not None:
            gr = problem.ground
            plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=cid)
            gid = pb.createMultiBody(0, plane, basePosition=[0, 0, float(gr.get("height", 0.0))],
                                     physicsClientId=cid)
            # Bullet multiplies the pair's restitutions: the ground carries 1, the body e
            pb.changeDynamics(gid, -1, restitution=1.0, lateralFriction=1.0, physicsClientId=cid)
        if problem.params.get("kind") == "two_sphere":
            # the product of restitutions again: one sphere carries e, the other 1
            pb.changeDynamics(ids[1], -1, restitution=1.0, physicsClientId=cid)
        return cid, ids

    def _state(self, cid, ids):
        pb = self.pb
        pos, quat, vel, om = [], [], [], []
        for bid in ids:
            p, q = pb.getBasePositionAndOrientation(bid, physicsClientId=cid)
            v, w = pb.getBaseVelocity(bid, physicsClientId=cid)
            pos.append(p)
            quat.append((q[3], q[0], q[1], q[2]))
            vel.append(v)
            om.append(w)
        return pos, quat, vel, om

    def run(self, problem: Problem, integrator: str, dt: float):
        pb = self.pb
        cid, ids = self._setup(problem, dt)
        try:
            n_total = max(1, int(round(problem.duration / dt)))
            stride = problem.log_every(dt)
            ts = [0.0]
            st = [self._state(cid, ids)]
            for s in range(1, n_total + 1):
                pb.stepSimulation(physicsClientId=cid)
                if s % stride == 0 or s == n_total:
                    ts.append(s * dt)
                    st.append(self._state(cid, ids))
        finally:
            pb.disconnect(physicsClientId=cid)
        arr = lambda k: np.array([x[k] for x in st], float)
        return Samples(np.array(ts), arr(0), arr(1), arr(2), arr(3)), n_total

    def time(self, problem: Problem, integrator: str, dt: float, duration: float):
        pb = self.pb
        cid, ids = self._setup(problem, dt)
        try:
            n = max(1, int(round(duration / dt)))
            step = pb.stepSimulation
            t0 = time.perf_counter()
            for _ in range(n):
                step(physicsClientId=cid)
            return time.perf_counter() - t0, n
        finally:
            pb.disconnect(physicsClientId=cid)


class OdePeer:
    name = "ode"
    #: ODE's steppers, named by their calls
    integrators = ("dWorldStep", "dWorldQuickStep")
    STEPPER = {"dWorldStep": "world", "dWorldQuickStep": "quick"}

    def __init__(self):
        from rblog.study.engines.ode import OdeRun  # raises EngineMissing without odepy/libode

        import odepy  # noqa: F401
        from rblog.adapters.ode import version

        self.Run = OdeRun
        self.version = version()

    def supports(self, problem: Problem) -> str:
        return ""

    def _setup(self, problem: Problem, integrator: str, dt: float, duration: float | None = None):
        from rblog.engine.scene import parse_scene

        scene = parse_scene(problem.scene_toml(dt, duration), path=f"<{problem.name}>")
        return self.Run(scene, dt, [f"stepper={self.STEPPER[integrator]}"])

    def run(self, problem: Problem, integrator: str, dt: float):
        run = self._setup(problem, integrator, dt)
        try:
            n_total = max(1, int(round(problem.duration / dt)))
            stride = problem.log_every(dt)
            ts, st = [0.0], [run.state()]
            done = 0
            while done < n_total:
                k = min(stride, n_total - done)
                run.step(k)
                done += k
                ts.append(done * dt)
                st.append(run.state())
        finally:
            run.close()
        arr = lambda k: np.array([x[k] for x in st], float)  # noqa: E731
        return Samples(np.array(ts), arr(0), arr(1), arr(2), arr(3)), n_total

    def time(self, problem: Problem, integrator: str, dt: float, duration: float):
        run = self._setup(problem, integrator, dt, duration)
        try:
            n = max(1, int(round(duration / dt)))
            t0 = time.perf_counter()
            run.step(n)
            return time.perf_counter() - t0, n
        finally:
            run.close()


_PEERS = {"mujoco": MujocoPeer, "pybullet": PybulletPeer, "ode": OdePeer}


def unavailable_reason(name: str) -> str:
    if name not in _PEERS:
        return f"unknown peer (expected one of: {', '.join(PEER_NAMES)})"
    try:
        _PEERS[name]()
    except Exception as e:
        extra = "ode" if name == "ode" else "engines"
        return (f"not installed ({type(e).__name__}: {e}); pip install -e \".[{extra}]\" in a "
                f"checkout (or pip install \"rblog[{extra}]\")" + ("; ODE: apt-get install libode8"
                                                                  if name == "ode" else ""))
    return ""


def available_peers(names=None) -> list:
    """Instances of the installed peers among ``names`` (None: all known; () or []: none)."""
    out = []
    for n in (PEER_NAMES if names is None else names):
        if n not in _PEERS:
            continue
        try:
            out.append(_PEERS[n]())
        except Exception:  # not installed, or fails to load: left out (reported by the caller)
            continue
    return out


__all__ = ["MujocoPeer", "OdePeer", "PybulletPeer", "available_peers", "unavailable_reason", "PEER_NAMES"]
