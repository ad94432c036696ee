"""Record the bodies of a pybullet client into the log contract.

Two lines::

    rec = rblog.adapters.pybullet.PybulletRecorder(client, mcap="run.mcap")  # table + sample 0
    for _ in range(n): p.stepSimulation(physicsClientId=client); rec()       # state + contacts
    rec.close()                                     # or `with`; rblog.check(rblog.load(...))

pybullet's conventions and how they become the contract's (docs/log-format.md):

* **bodies**: every body of the client with mass and no joints is a rigid body of the table;
  bodies of mass 0 are static geometry (the first plane is the ground, boxes are static boxes,
  anything else is listed in ``engine_settings["static_shapes_not_in_the_table"]``); bodies with
  joints (multi-link) are refused (:class:`~rblog.adapters.AdapterError`).
* **frames**: a base's position and orientation (``getBasePositionAndOrientation``, xyzw) are
  those of its inertial frame, the centre of mass and the principal axes of
  ``localInertiaDiagonal``; a collision shape sits at ``getCollisionShapeData``'s local frame in
  it. A box keeps its shape when that frame diagonalizes the inertia and is centred on the
  centre of mass (the contract frame is then the box's), a sphere when centred; cylinders,
  capsules, meshes, compounds are recorded without a shape. ``getBaseVelocity`` gives the
  centre of mass's velocity and the angular velocity, both in the world frame.
* **contacts**: ``getContactPoints`` after ``stepSimulation`` lists the manifold points of that
  step (``contactDistance``: the separation from the collision detection at its start;
  ``normalForce`` and the two lateral frictions: the step's applied impulses / timestep, on body A;
  ``contactNormalOnB`` from B into A). Rows: ``body_a`` = A, ``body_b`` = B (a static body
  becomes ``body_b = -1``, signs flipped), impulses = force x timestep. Points with no force and
  positive distance (Bullet's speculative points) are dropped. With ``numSubSteps`` > 1 pybullet
  reports only the last substep's forces, so no rows are logged (the analyzers then infer
  contacts from the motion; ``engine_settings.contact_rows`` says so).
* **materials**: ``lateralFriction`` and ``restitution`` of each body, combined by Bullet's
  ``product`` (both); ``restitutionVelocityThreshold`` and the other engine parameters are in
  ``engine_settings``.
"""

from __future__ import annotations

import numpy as np

from rblog.adapters import AdapterError, require
from rblog.adapters._common import SampleStream, body_frame, quat_mul
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE, Model
from rblog.contract.orientation import quat_wxyz_to_matrix

CONTACT_ROWS = {
    "separation": "before the step (contactDistance: the manifold refreshed at its start)",
    "impulse": "normalForce and lateral frictions * timestep, on body A",
    "speculative": "dropped (no force and positive distance)",
}


def _pb():
    return require("pybullet")


def _wxyz(xyzw) -> np.ndarray:
    x, y, z, w = xyzw
    return np.array([w, x, y, z], np.float64)


def inspect(client: int = 0):
    """(Model, ids (N,) of the recorded bodies, q_frame (N, 4), index {body id: row}, notes)."""
    pb = _pb()
    try:
        nb = pb.getNumBodies(physicsClientId=client)
    except pb.error as e:
        raise AdapterError(f"rblog.adapters.pybullet: client {client!r}: {e}") from None
    ids, shapes, sizes, inertias, q_frames, masses, rest, fric, names = [], [], [], [], [], [], [], [], []
    ground, g_normal, g_offset, g_rest, g_fric = False, np.array([0.0, 0.0, 1.0]), 0.0, 0.5, 0.5
    sb_pos, sb_quat, sb_half, sb_rest, sb_fric, other = [], [], [], [], [], []
    for k in range(nb):
        bid = pb.getBodyUniqueId(k, physicsClientId=client)
        label = pb.getBodyInfo(bid, physicsClientId=client)[1].decode() or f"body{bid}"
        info = pb.getDynamicsInfo(bid, -1, physicsClientId=client)
        mass, mu, inertia, e = float(info[0]), float(info[1]), np.array(info[2], float), float(info[5])
        shapes_data = pb.getCollisionShapeData(bid, -1, physicsClientId=client)
        if pb.getNumJoints(bid, physicsClientId=client) > 0:
            raise AdapterError(f"rblog.adapters.pybullet: body {bid} ({label!r}) has joints: the "
                               "contract records free rigid bodies and static geometry only")
        pos, orn = pb.getBasePositionAndOrientation(bid, physicsClientId=client)
        r = quat_wxyz_to_matrix(_wxyz(orn))
        if mass == 0.0:  # static geometry
            for sd in shapes_data:
                gtype, dims = int(sd[2]), np.array(sd[3], float)
                lp, lq = np.array(sd[5], float), _wxyz(sd[6])
                wq = quat_mul(_wxyz(orn), lq)
                wp = np.array(pos) + r @ lp
                if gtype == pb.GEOM_PLANE and not ground:
                    ground, g_rest, g_fric = True, e, mu
                    g_normal = quat_wxyz_to_matrix(wq)[:, 2].copy()
                    g_offset = float(g_normal @ wp)
                elif gtype == pb.GEOM_BOX:
                    sb_pos.append(wp)
                    sb_quat.append(wq)
                    sb_half.append(dims / 2.0)
                    sb_rest.append(e)
                    sb_fric.append(mu)
                else:
                    other.append(f"{label} (geometry type {gtype})")
            continue
        geom = None
        if len(shapes_data) == 1:
            sd = shapes_data[0]
            gtype, dims = int(sd[2]), np.array(sd[3], float)
            code = {pb.GEOM_SPHERE: SHAPE_SPHERE, pb.GEOM_BOX: SHAPE_BOX}.get(gtype)
            if code is not None:
                size = np.array([dims[0], 0.0, 0.0]) if code == SHAPE_SPHERE else dims / 2.0
                geom = (code, size, np.array(sd[5], float), _wxyz(sd[6]), np.zeros(3))
        shape, size, inertia_c, q_frame = body_frame(inertia, [1.0, 0, 0, 0], geom)
        ids.append(bid)
        shapes.append(shape)
        sizes.append(size)
        inertias.append(inertia_c)
        q_frames.append(q_frame)
        masses.append(mass)
        rest.append(e)
        fric.append(mu)
        names.append(label)
    n, nsb = len(ids), len(sb_pos)
    params = pb.getPhysicsEngineParameters(physicsClientId=client)
    gravity = np.array([params.get(f"gravityAcceleration{c}", 0.0) for c in "XYZ"], float)
    model = Model(
        body_name=names, body_shape=np.array(shapes, np.int64).reshape(n),
        body_size=np.array(sizes).reshape(n, 3), body_mass=np.array(masses, float).reshape(n),
        body_inertia_diag=np.array(inertias).reshape(n, 3), body_force_world=np.zeros((n, 3)),
        body_torque_world=np.zeros((n, 3)), body_restitution=np.array(rest, float).reshape(n),
        body_friction=np.array(fric, float).reshape(n), body_group=np.zeros(n, np.int64),
        gravity=gravity, ground=ground, ground_normal=g_normal, ground_offset=g_offset,
        ground_restitution=g_rest, ground_friction=g_fric,
        static_box_position=np.array(sb_pos).reshape(nsb, 3),
        static_box_quat_wxyz=np.array(sb_quat).reshape(nsb, 4),
        static_box_half_extents=np.array(sb_half).reshape(nsb, 3),
        static_box_restitution=np.array(sb_rest, float).reshape(nsb),
        static_box_friction=np.array(sb_fric, float).reshape(nsb))
    index = {bid: i for i, bid in enumerate(ids)}
    return model, np.array(ids, np.int64), np.array(q_frames).reshape(n, 4), index, \
        {"static_shapes_not_in_the_table": other}


def settings(client: int = 0) -> dict:
    pb = _pb()
    from importlib.metadata import PackageNotFoundError, version

    try:
        ver = version("pybullet")
    except PackageNotFoundError:
        ver = str(pb.getAPIVersion())
    params = pb.getPhysicsEngineParameters(physicsClientId=client)
    return {"engine": "pybullet", "version": ver, "api_version": int(pb.getAPIVersion()),
            "integrator": "default",
            **{k: (v if isinstance(v, (int, float, str)) else str(v)) for k, v in params.items()},
            "combine_native": {"friction": "product", "restitution": "product"},
            "contact_rows": dict(CONTACT_ROWS)}


def read_state(client: int, ids, q_frame=None):
    """(position, quat_wxyz, velocity, angular_velocity) of bodies ``ids`` now, world frame, in
    the contract's frames (``q_frame`` (N, 4): each contract frame in the base frame; identity
    when None)."""
    pb = _pb()
    ids = [int(b) for b in ids]
    n = len(ids)
    x, q, v, w = np.empty((n, 3)), np.empty((n, 4)), np.empty((n, 3)), np.empty((n, 3))
    for i, bid in enumerate(ids):
        p, o = pb.getBasePositionAndOrientation(bid, physicsClientId=client)
        lv, av = pb.getBaseVelocity(bid, physicsClientId=client)
        x[i], q[i], v[i], w[i] = p, (o[3], o[0], o[1], o[2]), lv, av
    return x, (q if q_frame is None else quat_mul(q, q_frame)), v, w


def read_contacts(client: int, index: dict, dt: float, step: int):
    """The contact rows of the step just taken, in the contract's convention (dict for
    Recorder.write, or None): ``index`` maps pybullet body ids to rows (others: static)."""
    pts = _pb().getContactPoints(physicsClientId=client)
    rows = [c for c in pts if not (c[9] <= 0.0 and c[8] > 0.0)]
    if not rows:
        return None
    cols = list(zip(*rows))
    a = np.array([index.get(x, -1) for x in cols[1]], np.int64)
    b = np.array([index.get(x, -1) for x in cols[2]], np.int64)
    normal = np.array(cols[7], float)  # on B, pointing towards A
    fn = np.array(cols[9], float)
    fric = (np.array(cols[10])[:, None] * np.array(cols[11]) + np.array(cols[12])[:, None] * np.array(cols[13]))
    point = 0.5 * (np.array(cols[5], float) + np.array(cols[6], float))
    flip = a < 0
    a[flip], b[flip] = b[flip], a[flip]
    normal[flip] *= -1.0
    fric[flip] *= -1.0
    keep = a >= 0
    if not keep.any():
        return None
    k = int(keep.sum())
    return dict(step=np.full(k, int(step), np.int64), body_a=a[keep], body_b=b[keep],
                point=point[keep], normal=normal[keep], separation=np.array(cols[8], float)[keep],
                normal_impulse=fn[keep] * dt, friction_impulse=fric[keep] * dt)


class PybulletRecorder:
    """Record the bodies of a pybullet client: ``rec = PybulletRecorder(client, mcap=...)``, then
    ``rec()`` after each ``stepSimulation`` (``rec(steps=k)`` after k of them), ``rec.close()``.

    Args:
        client: the physicsClientId (0 for the first ``connect``).
        rrd, mcap, keep, writer, **recorder_options: as :class:`rblog.adapters.mujoco.MujocoRecorder`.

    The state now is sample 0 (step 0, or ``start_step``)."""

    def __init__(self, client: int = 0, *, rrd=None, mcap=None, writer: str | None = None,
                 keep: bool | None = None, start_step: int = 0, block: int | None = None,
                 **recorder_options):
        from rblog.record.recorder import Recorder

        self.pb, self.client = _pb(), int(client)
        self.model, self.ids, self.q_frame, self.index, notes = inspect(self.client)
        engine = {**settings(self.client), **notes}
        self.dt = float(engine.get("fixedTimeStep", 1.0 / 240.0))
        # with substeps, getContactPoints holds the last substep's forces only: their impulses
        # would not be the step's (measured: 2.7 N s off the momentum change at 4 substeps)
        self.substeps = int(engine.get("numSubSteps", 0) or 0)
        if self.substeps > 1:
            engine["contact_rows"] = {"separation": "before the step (no rows logged: numSubSteps "
                                                    f"{self.substeps} > 1, and pybullet reports the "
                                                    "last substep's forces only)"}
        self.recorder = Recorder(self.model, rrd=rrd, mcap=mcap, dt=self.dt,
                                 writer=writer or f"pybullet {engine['version']} via rblog.adapters",
                                 integrator="default", combine_friction="product",
                                 combine_restitution="product", engine_settings=engine, keep=keep,
                                 **recorder_options)
        self.recorder.open()
        self.stream = SampleStream(self.recorder, **({} if block is None else {"block": block}))
        self.step = int(start_step)
        self.stream.add(self.step, *self.state())

    def state(self):
        """(position, quat_wxyz, velocity, angular_velocity) of the recorded bodies now."""
        return read_state(self.client, self.ids, self.q_frame)

    def contacts(self, step: int):
        """The contact rows of the step just taken (dict for Recorder.write, or None)."""
        return read_contacts(self.client, self.index, self.dt, step)

    def __call__(self, steps: int = 1) -> None:
        """Log the state after ``steps`` more ``stepSimulation`` calls and the last one's contacts."""
        self.step += int(steps)
        rows = None if self.substeps > 1 else self.contacts(self.step)
        self.stream.add(self.step, *self.state(), rows)

    record = __call__

    def close(self, truncated: bool = False, reason: str | None = None) -> None:
        try:
            if not truncated:
                self.stream.flush()
        finally:
            self.recorder.close(truncated=truncated, reason=reason)

    def __enter__(self) -> "PybulletRecorder":
        return self

    def __exit__(self, exc_type, exc, tb):
        self.close(truncated=exc_type is not None, reason=None if exc is None else str(exc))

    @property
    def trajectory(self):
        self.stream.flush()
        return self.recorder.trajectory


__all__ = ["CONTACT_ROWS", "PybulletRecorder", "inspect", "read_contacts", "read_state", "settings"]
