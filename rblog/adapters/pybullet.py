"""Record every body of a pybullet client into the log contract (v3), with per-interval impulses.

Two lines::

    rec = rblog.adapters.pybullet.PybulletRecorder(client, mcap="run.mcap", every=10)
    for _ in range(n): p.stepSimulation(physicsClientId=client); rec()   # or: rec.step()
    rec.close()                                      # or `with`; rblog.check(rblog.load(...))

``rec()`` must follow every ``stepSimulation``: pybullet has no hook into its step, so the
recorder reads the state and the contacts after each step, accumulates that step's impulses and
writes a sample every ``every`` calls (``rec.step(k)`` steps the client and does the same).
Nothing between samples is lost: each sample carries the impulses of every step of its interval.

pybullet's conventions and how they become the contract's (docs/log-format.md):

* **bodies**: one row per dynamic link of every body: the base (``getBasePositionAndOrientation``)
  and each link of a multibody (``getLinkStates``), named ``robot/link`` (``getBodyInfo``'s body
  name, the base's name or ``getJointInfo``'s link name; a robot name used by several bodies gets
  the body id, ``robot#3/link``). The base of a multibody is free (``BODY_FREE``); its links move
  on their joints (``BODY_JOINTED``, ``body_parent`` the parent link). A base of mass 0 (a fixed
  base: pybullet reports mass 0 for ``useFixedBase`` too) is welded to the world: its shapes are
  world geoms (``geom_body = -1``) and its links' parent is the world (-1).
* **frames**: a row's pose is pybullet's inertial frame of the link (the centre of mass and the
  principal axes of ``localInertiaDiagonal``); ``getCollisionShapeData``'s local frames are in it.
  Links are read with ``computeForwardKinematics=1``: the cached link transforms of a floating
  base's links lag its joints (measured on r2d2: 1.9 mm off the base's pose and its joints).
* **joints** (``getJointInfo``): revolute -> hinge, prismatic -> slide, spherical -> ball, planar,
  fixed. The joint frame is the child's URDF link frame; anchor and axis in the child's inertial
  frame from ``localInertialFramePosition/Orientation``; in the parent's from ``parentFramePos``
  and ``parentFrameOrn`` (relative to the parent's inertial frame; the orientation is returned
  inverted). Limits where lower <= upper (pybullet reports a continuous joint's URDF limits as a
  revolute's, which Bullet does not enforce; it cannot tell the two apart).
* **geoms** (``getCollisionShapeData``): sphere ``[r]``; box half extents; capsule and cylinder
  ``[r, length/2]`` (pybullet's length is the cylinder part); mesh: the vertices of
  ``getMeshData`` (Bullet collides with their convex hull); plane: normal ``dims`` turned onto the
  geom's +z; a static box that is a ground slab (GROUND_SLAB_HALF_EXTENT_M, GROUND_SLAB_ASPECT:
  pybullet_data's ``plane.urdf`` collides as a 200 x 200 x 10 m box) is the plane of its upper
  face. Materials per link (``getDynamicsInfo``): lateral friction and restitution, combined by
  Bullet's product. Collision filter: Bullet's defaults (dynamic: group 1, mask all; static:
  group 2, mask all but 2; rule "and"); links of one multibody do not collide unless loaded with
  ``URDF_USE_SELF_COLLISION`` (its geoms share a bit of their own in the group, absent from the
  mask: SELF_FILTER_FIRST_BIT, also where its base is static, part of the world); pybullet
  reports neither a later ``setCollisionFilterGroupMask`` nor self collision (``engine_settings["collision_filter"]`` says so).
* **impulses** per step, summed over each interval (world frame; angular about the row's centre
  of mass at the start of the step, where Bullet's solver applies them):

  - contact: ``getContactPoints`` after the step lists the manifold points the solver used, with
    the accumulated impulses of its last iteration / dt (``normalForce``, ``lateralFriction1/2``
    along ``lateralFrictionDir1/2``) on A at ``positionOnA``; -that on B at ``positionOnB``
    (measured: a free body's momentum change is gravity's, the damping's and these to 1e-14
    relative, so the reported impulses are the ones applied).
  - passive, Bullet's damping (``DAMPING_*``): a multibody link gets, in its ABA, the force
    ``-m v (k + k |v|)`` and torque ``-R I R^T w (k + k |w|)`` (btMultiBody.cpp,
    ``computeAccelerationsArticulatedBodyAlgorithmMultiDof``; ``k`` = linear / angular damping,
    0.04 as a float32 by default), evaluated at the step's initial velocities: impulse = force x dt.
    pybullet cannot report a ``changeDynamics(linearDamping=...)``: pass ``damping={body: (lin,
    ang)}``. A maximal-coordinates body has no damping (measured: v and w unchanged in flight).
  - applied: ``rec.apply_external_force`` / ``rec.apply_external_torque`` call pybullet's and
    log the impulse of the next step; forces given to pybullet directly are invisible (pass
    ``applied=False`` to mark them missing).
  - joint: with ``joint_sensors`` (default) every joint gets ``enableJointForceTorqueSensor``
    (it does not change the motion: same bits measured). ``getJointState``'s reaction is the
    spatial force the parent applies to the child's subtree (``I^A a + p^A`` of the ABA, child
    link frame, about its centre of mass), plus the joint motor's (``appliedJointMotorTorque``:
    Bullet's motor is a constraint, not in the ABA's reaction; a couple along a hinge's axis, a
    force along a slide's at the child's centre of mass and its opposite at the parent's, with no
    moment: Bullet writes a prismatic row's impulse back as link forces at the two centres of mass,
    its angular part zero; measured on r2d2 with random motor targets: the base's angular residual
    was 0.038 N m s a step with the slide motor's 50 N x dt through the anchor (0.2 m from the
    base's centre of mass), and below 1e-2 in every judged step at the centres); a row's net joint impulse is its own minus those of
    its children moved onto it, both in the frames of Bullet's cached link transforms after the
    step. Measured on kuka holding itself up: 2.2e-13 N m s a step with the motor's impulse,
    6.1e-5 without it. Joint limits are constraints pybullet reports nowhere: Bullet makes a
    limit's constraint row only in a step that begins with the joint at or beyond the limit, so
    in such a step the joint impulse of the joint's child and parent rows is NaN (not in the
    log; the analyzers do not judge those rows in that interval). Measured on r2d2
    (falling onto its wheels, motors on): the balance of a link closes to a median 1.7e-7 N s per step, 5.3e-4 N s at most in the steps of the impact (joint
    impulses ~0.4 N s), against ~8 N s without the joint impulses.
    Under ``TORQUE_CONTROL`` pybullet adds the torque in the ABA (``addJointTorque``): the
    reaction carries it and ``appliedJointMotorTorque`` is 0, so it is counted once (measured on
    kuka bent and gravity-compensated, torques up to 0.18 N m s a step: each link's logged
    impulses + m g dt equal m dv from getLinkState to 9.8e-5 N s, dL to 4.3e-6 N m s; URDF joint
    damping, applied the same way, likewise). Bullet clamps every generalized velocity of a
    multibody to +-MAX_COORDINATE_VELOCITY (a joint's, and the world components of a free
    base's w and v): a step that ends with one there has NaN joint impulses on the rows it moves
    (the joint's child and its descendants; every row of the multibody for its base), a
    momentum change reported nowhere (measured: kuka's link 7 at 100 rad/s, 0.0985 N m s a step).
  - integration (every row whose joint impulses are logged: links, and a multibody's base):
    per interval, the row's momentum change ``m v``, ``L = R I R^T w`` between the two samples
    less its other kinds and ``m g dt``, taken per block before it is written. Bullet steps a
    multibody in joint coordinates (``u1 = u0 + h udot``, then ``q1 = q0 + h u1``): this is
    ``K = m [(J(q1) - J(q0)) u1 - h Jdot(q0, u0) u0]`` (docs/log-format.md, "The integration
    kind"; a pendulum's equals its closed form to 4e-15 N s, K up to 1.2e-3 N s a step), plus,
    under damping, a force through the joint that the joint sensor's reaction misses (the
    pendulum: up to 0.49 of the damping impulse; tests/adapters/test_pybullet_integration.py).
    Before it r2d2's and kuka's links under random motor targets left up to 1.2e-3 and
    0.082 N s a step or interval unexplained (truth table's false alarms).
  - ``body_impulse_supplied``: logged as above; none for the actuator (the motors act inside
    the joints), the joint of a body without joints and the damping of a maximal-coordinates body
    (measured: no damping); missing (named in ``engine_settings["missing"]``): contacts and joints
    of a maximal-coordinates body (pybullet exposes only its base and reports the contacts of its
    hidden links on it), joints without ``joint_sensors``, applied loads with ``applied=False``.
* **work** per step, summed over each interval, at the step's mean velocity (a semi-implicit
  step changes the kinetic energy by ``(u0 + u1)/2 . M (u1 - u0)``, and ``M (u1 - u0)`` is the
  sum of its generalized impulses; docs/log-format.md, "Work and the discrete energy"):

  - passive: the multibody damping's impulses above . the row's mean velocities ``(v0 + v1)/2``,
    ``(w0 + w1)/2``; applied likewise, from the loads given through the recorder.
  - joint, on the joint's child row: its generalized force, the reaction's component along the
    joint's dof (``S^T f``, S = (a, a x (centre - anchor)) for a hinge, (0, a) for a slide: the
    torque the ABA applies at the joint, i.e. the URDF joint damping ``-c qdot0`` and any
    TORQUE_CONTROL torque) plus the motor's ``appliedJointMotorTorque``, times dt and the
    joint's mean velocity (``getJointState``). Measured: a free cube's damping work equals its
    kinetic energy's change to 2.5e-15 J over 280 steps, a motor-driven rod's (URDF damping 0.3)
    to 8.4e-16 J (tests/adapters/test_pybullet_energy.py); on kuka under random motor targets
    the energy less this work is the one pybullet's own joint damping and motor torques give,
    0.0281 J both (benchmarks/truth_table.py). NaN where the joint impulses are (a step that
    begins at a limit: the limit's work is unknown; a clamped velocity: the energy it removed),
    and for ball and planar joints (their dofs are not read).
  - ``body_work_supplied``: applied as its impulse; passive logged where a row has damping
    (none on a maximal-coordinates body); joint logged on every row with a joint of its own,
    missing without ``joint_sensors`` or with substeps.
* **sleeping** (``URDF_ENABLE_SLEEPING``, off by default): Bullet zeroes the velocities of a body
  that falls asleep, with no impulse pybullet reports; such a log shows that change unexplained.
* **substeps**: with ``numSubSteps`` > 1 pybullet reports the last substep's contact forces only:
  contacts are marked missing and no rows are logged.

The per-step reading of contacts and damping is compiled (``rblog.adapters._gather``,
csrc/adapters/pybullet/): pybullet returns each contact point as a tuple of tuples, and one pass in C++
reads them without a Python object per number.

Why this module is long: it is the one translation of Bullet's conventions. The model
(:func:`inspect`), the per-step reading (:class:`Stepper`) and the recorder share the row layout
and the rules above; apart, each would restate them.
"""

from __future__ import annotations

import numpy as np

from rblog.adapters import AdapterError, _gather, require
from rblog.adapters._common import EngineRecorder, quat_mul
from rblog.contract.model import (IMPULSE_KINDS, SUPPLIED_LOGGED, SUPPLIED_MISSING, SUPPLIED_NONE,
                                  WORK_KINDS)
from rblog.contract.orientation import quat_wxyz_to_matrix

#: pybullet's default linear and angular damping of a multibody (btMultiBody: 0.04f, a float32)
DAMPING_DEFAULT = float(np.float32(0.04))
#: Bullet's bound on every generalized velocity of a multibody (btMultiBody's
#: m_maxCoordinateVelocity, 100 by default; pybullet's changeDynamics(maxJointVelocity=...)
#: changes it and reports it nowhere): applyDeltaVeeMultiDof clamps each joint velocity and each
#: world component of the base's angular and linear velocity to +-this, a momentum change no
#: force accounts for
MAX_COORDINATE_VELOCITY = 100.0
#: the work kinds the adapter accumulates per row (actuator: none, pybullet's motors act inside
#: the joints, and the joint kind carries their work)
WORK_ACCUMULATED = ("applied", "passive", "joint")
#: pybullet.JOINT_* -> the contract's joint type names
JOINT_TYPES = {0: "hinge", 1: "slide", 2: "ball", 3: "planar", 4: "fixed"}
#: Bullet's default collision filter (btBroadphaseProxy::DefaultFilter / StaticFilter / AllFilter)
FILTER_DYNAMIC = (1, -1)
FILTER_STATIC = (2, -1 ^ 2)
#: the first of the bits that keep the links of one multibody from colliding with each other
#: (Bullet's default without URDF_USE_SELF_COLLISION): multibody k has bit B = 1 << (FIRST + k);
#: its moving links' geoms have group B and mask all but B, its static base's group 2 | B and
#: mask all but 2 and B, so under rule "and" no two of them pass while every other pair passes
#: as under Bullet's defaults; beyond bit 62 multibodies have no bit (their self-pairs then stay
#: in the contract's filter)
SELF_FILTER_FIRST_BIT = 2
#: body_impulse_supplied codes
MISSING, LOGGED, NONE = SUPPLIED_MISSING, SUPPLIED_LOGGED, SUPPLIED_NONE

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


def _mat_xyzw(q: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices of (..., 4) scalar-last quaternions (pybullet's order)."""
    x, y, z, w = np.moveaxis(np.asarray(q, np.float64), -1, 0)
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
                     np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
                     np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


#: a static box whose two larger half extents are both at least GROUND_SLAB_HALF_EXTENT_M and
#: GROUND_SLAB_ASPECT times its smallest is a ground slab, logged as the plane of its upper face
#: (pybullet_data's plane.urdf collides as a box of half extents 100, 100, 5 m below z = 0: the
#: plane z = 0, drawn 100 m x 100 m either way; only a body 10 m under it could tell them apart)
GROUND_SLAB_HALF_EXTENT_M = 50.0
GROUND_SLAB_ASPECT = 10.0


def _ground_slab(half, pos, q, up):
    """The plane a static box is logged as when it is a ground slab, else None: the box of half
    extents ``half`` (3,) centred at ``pos`` with orientation ``q`` (wxyz) in its link's frame,
    whose world orientation is ``up`` (3, 3). Returns (size [hx, hy, 0], the centre of the upper
    face (3,), its orientation wxyz (4,)) in the link's frame: +z the face's outward normal (of
    the two faces across the thin axis i, the one facing most along world +z: pybullet's up),
    x, y along the box axes i+1, i+2."""
    i = int(np.argmin(half))
    others = np.delete(half, i)
    if not (others.min() >= GROUND_SLAB_HALF_EXTENT_M and
            others.min() >= GROUND_SLAB_ASPECT * half[i]):
        return None
    from rblog.contract.orientation import matrix_to_quat

    R = quat_wxyz_to_matrix(q)
    s = 1.0 if (up @ R)[2, i] >= 0.0 else -1.0       # the upper face's normal: s e_i (box frame)
    e = np.eye(3)
    j, k = (i + 1) % 3, (i + 2) % 3
    frame = np.stack([e[j], s * e[k], s * e[i]], axis=1)  # the plane's x, y, z in the box frame
    return ([half[j], half[k], 0.0], np.asarray(pos, np.float64) + R @ (s * half[i] * e[i]),
            quat_mul(q, matrix_to_quat(frame)))


def _z_to(n) -> np.ndarray:
    """(4,) wxyz quaternion turning +z onto the unit vector n."""
    n = np.asarray(n, np.float64) / np.linalg.norm(n)
    c = float(n[2])
    if c < -1.0 + 1e-15:
        return np.array([0.0, 1.0, 0.0, 0.0])
    axis = np.cross([0.0, 0.0, 1.0], n)
    q = np.array([1.0 + c, *axis])
    return q / np.linalg.norm(q)


class _Call:
    """pybullet calls that turn ``pybullet.error`` into one AdapterError naming the element."""

    def __init__(self, pb, client: int):
        self.pb, self.client = pb, client

    def __call__(self, fn: str, *args, what: str, **kw):
        try:
            return getattr(self.pb, fn)(*args, physicsClientId=self.client, **kw)
        except self.pb.error as e:
            raise AdapterError(f"rblog.adapters.pybullet: {what}: pybullet.{fn} failed ({e})") from None


class World:
    """The fixed description of a client: rows (bodies), joints, geoms, and what each row's
    impulses can say. Built by :func:`inspect`; arrays N first (N rows), float64."""

    def __init__(self):
        self.rows: list[tuple[int, int]] = []     # (body id, link index; -1 = base)
        self.name: list[str] = []
        self.kind: list[str] = []                  # "free", "joints"
        self.parent: list[int] = []
        self.mass: list[float] = []
        self.inertia: list = []
        self.damping: list[tuple[float, float]] = []
        self.supplied: list[list[int]] = []    # SUPPLIED_* codes in IMPULSE_KINDS order
        self.joints = {k: [] for k in ("name", "body", "type", "anchor_body", "anchor_parent",
                                       "axis_body", "axis_parent", "range")}
        self.geoms = {k: [] for k in ("name", "body", "type", "size", "pos_body", "quat_wxyz_body",
                                      "friction", "restitution", "collide_group", "collide_mask",
                                      "mesh_vert")}
        self.geom_source: list[tuple[int, int, int]] = []   # (body id, link, shape index)
        self.multibodies: list[tuple[int, list[int], list[int]]] = []  # (id, link indices, rows)
        self.missing: dict[str, list[str]] = {}
        self.notes: dict[str, object] = {}
        self.problems: list[str] = []             # elements the contract cannot hold
        self.self_bit: dict[int, int] = {}         # multibody id -> its self-filter bit

    @property
    def n(self) -> int:
        return len(self.rows)


def _names(call, ids):
    """{body id: robot name as logged} (the body id appended where a robot name repeats)."""
    raw = {}
    for bid in ids:
        base, robot = (s.decode() for s in call("getBodyInfo", bid, what=f"body {bid}"))
        # a maximal-coordinates body reports ("", base link name): no robot name
        raw[bid] = (robot, base) if robot and base else (f"body{bid}", robot or base or "base")
    count: dict[str, int] = {}
    for robot, _ in raw.values():
        count[robot] = count.get(robot, 0) + 1
    return {bid: ((r if count[r] == 1 else f"{r}#{bid}"), b) for bid, (r, b) in raw.items()}


def _geoms(call, pb, world: World, bid: int, link: int, row: int, label: str, pose_world=None):
    """Append the collision shapes of (bid, link) as geoms of ``row`` (-1: world, placed by
    ``pose_world`` = (position, wxyz) of the link's inertial frame)."""
    shapes = call("getCollisionShapeData", bid, link, what=f"{label}: collision shapes")
    if not shapes:  # no shape, or one pybullet does not report (a heightfield): its box says
        lo, hi = (np.array(v, np.float64) for v in call("getAABB", bid, link, what=label))
        if np.all(np.isfinite(lo)) and np.all(hi > lo):
            world.problems.append(f"{label}: no collision shape data from pybullet for a shape "
                                  f"spanning {lo.tolist()} .. {hi.tolist()} (a heightfield?)")
    info = call("getDynamicsInfo", bid, link, what=f"{label}: dynamics")
    mu, e = float(info[1]), float(info[5])
    group, mask = FILTER_STATIC if row < 0 else FILTER_DYNAMIC
    if bid not in world.self_bit and call("getNumJoints", bid, what=f"{label}: joints") > 0:
        k_bit = SELF_FILTER_FIRST_BIT + len(world.self_bit)
        world.self_bit[bid] = 1 << k_bit if k_bit <= 62 else 0
    bit = world.self_bit.get(bid, 0)
    if bit:  # a moving link's group is its multibody's bit alone, so "and" keeps the pair out
        group, mask = (group | bit) if row < 0 else bit, mask & ~bit
    for k, sd in enumerate(shapes):
        gtype, dims = int(sd[2]), np.array(sd[3], np.float64)
        pos, q = np.array(sd[5], np.float64), _wxyz(sd[6])
        verts = None
        if gtype == pb.GEOM_SPHERE:
            kind, size = "sphere", [dims[0], 0.0, 0.0]
        elif gtype == pb.GEOM_BOX and row < 0 and (slab := _ground_slab(
                dims / 2.0, pos, q, quat_wxyz_to_matrix(pose_world[1]))) is not None:
            kind, (size, pos, q) = "plane", slab  # plane.urdf: its 200 x 200 x 10 m box's top
        elif gtype == pb.GEOM_BOX:
            kind, size = "box", dims / 2.0
        elif gtype in (pb.GEOM_CAPSULE, pb.GEOM_CYLINDER):
            kind = "capsule" if gtype == pb.GEOM_CAPSULE else "cylinder"
            size = [dims[1], dims[0] / 2.0, 0.0]
        elif gtype == pb.GEOM_PLANE:
            kind, size = "plane", [0.0, 0.0, 0.0]
            q = quat_mul(q, _z_to(dims))
        elif gtype == pb.GEOM_MESH:
            kind, size = "mesh", [0.0, 0.0, 0.0]
            idx = k if len(shapes) > 1 else -1
            _, v = call("getMeshData", bid, link, collisionShapeIndex=idx,
                        what=f"{label}: mesh {sd[4].decode(errors='replace') or k}")
            v = np.array(v, np.float64).reshape(-1, 3)
            if len(v) == 0:
                world.problems.append(f"{label}: mesh {sd[4].decode(errors='replace')!r} "
                                      "without vertices from pybullet")
                continue
            # getMeshData's vertices are in the link's inertial frame (scale and collision
            # frame applied); the geom keeps them in its own frame
            verts = (v - pos) @ quat_wxyz_to_matrix(q)
        else:
            world.problems.append(f"{label}: collision shape {k} of pybullet geometry type "
                                  f"{gtype} (heightfield or other)")
            continue
        if row < 0:
            p0, q0 = pose_world
            pos = p0 + quat_wxyz_to_matrix(q0) @ pos
            q = quat_mul(q0, q)
        g = world.geoms
        g["name"].append(label if len(shapes) == 1 else f"{label}:{k}")
        g["body"].append(row)
        g["type"].append(kind)
        g["size"].append(np.asarray(size, np.float64))
        g["pos_body"].append(pos)
        g["quat_wxyz_body"].append(q / np.linalg.norm(q))
        g["friction"].append(mu)
        g["restitution"].append(e)
        g["collide_group"].append(group)
        g["collide_mask"].append(mask)
        g["mesh_vert"].append(verts)
        world.geom_source.append((bid, link, k))


def inspect(client: int = 0, *, damping=None, joint_sensors: bool = True,
            applied: bool = True) -> World:
    """The :class:`World` of ``client`` now (see the module docstring for the rules).

    Args:
        damping: {body id: (linear, angular)} for bodies whose damping was changed with
            ``changeDynamics`` (pybullet cannot report it); others: DAMPING_DEFAULT.
        joint_sensors: enable pybullet's joint force/torque sensors (joint impulses supplied).
        applied: the user routes applied loads through the recorder (applied impulses supplied).
    """
    pb = _pb()
    call = _Call(pb, int(client))
    try:
        nb = pb.getNumBodies(physicsClientId=client)
    except pb.error as e:
        raise AdapterError(f"rblog.adapters.pybullet: client {client!r}: {e}") from None
    ids = [int(call("getBodyUniqueId", k, what=f"body {k}")) for k in range(nb)]
    names = _names(call, ids)
    damping = {int(k): tuple(map(float, v)) for k, v in (damping or {}).items()}
    unknown = sorted(set(damping) - set(ids))
    if unknown:
        raise AdapterError(f"rblog.adapters.pybullet: damping: body ids {unknown} are not in client "
                           f"{client} (bodies: {ids})")
    w = World()
    maximal = []
    for bid in ids:
        robot, base = names[bid]
        nj = int(call("getNumJoints", bid, what=f"body {bid} ({robot})"))
        info = call("getDynamicsInfo", bid, -1, what=f"{robot}/{base}: dynamics")
        mass, body_type = float(info[0]), int(info[10])
        label = f"{robot}/{base}"
        pos, orn = call("getBasePositionAndOrientation", bid, what=label)
        if body_type != 2:  # a btRigidBody: loaded with useMaximalCoordinates
            maximal.append(label)
            kd = (0.0, 0.0)
        else:
            kd = damping.get(bid, (DAMPING_DEFAULT, DAMPING_DEFAULT))
        base_pose = (np.array(pos, np.float64), _wxyz(orn))
        if mass <= 0.0:  # a fixed base: static geometry of the world, its links hang on it
            if body_type != 2:
                w.missing.setdefault("geoms", []).append(label)
                continue
            _geoms(call, pb, w, bid, -1, -1, label, base_pose)
            base_row = -1
        else:
            base_row = w.n
            w.rows.append((bid, -1))
            w.name.append(label)
            w.kind.append("free")
            w.parent.append(-1)
            w.mass.append(mass)
            w.inertia.append(np.array(info[2], np.float64))
            w.damping.append(kd)
            supplied = {"contact": LOGGED, "applied": LOGGED if applied else MISSING,
                        "passive": LOGGED, "actuator": NONE,
                        "joint": NONE if nj == 0 else LOGGED if joint_sensors else MISSING,
                        "integration": NONE}
            if body_type != 2:  # hidden links: their contacts and joints act on it unseen
                supplied.update(contact=MISSING, joint=MISSING, passive=NONE)
                for k in ("contact", "joint", "geoms"):
                    w.missing.setdefault(k, []).append(label)
            else:
                _geoms(call, pb, w, bid, -1, base_row, label)
            w.supplied.append([supplied[k] for k in IMPULSE_KINDS])
        rows = [base_row]
        for j in range(nj):
            ji = call("getJointInfo", bid, j, what=f"{label}: joint {j}")
            link = f"{robot}/{ji[12].decode()}"
            li = call("getDynamicsInfo", bid, j, what=f"{link}: dynamics")
            jtype = int(ji[2])
            if jtype not in JOINT_TYPES:
                w.problems.append(f"{link}: joint {ji[1].decode()!r} of pybullet type {jtype}")
                jtype = 4  # kept as a row (fixed) so that the rest can be listed
            row = w.n
            parent = rows[int(ji[16]) + 1]
            lmass = float(li[0])
            w.rows.append((bid, j))
            w.name.append(link)
            w.kind.append("joints")
            w.parent.append(parent)
            w.mass.append(lmass)
            w.inertia.append(np.array(li[2], np.float64))
            w.damping.append(kd)
            w.supplied.append([LOGGED, LOGGED if applied else MISSING, LOGGED, NONE,
                               LOGGED if joint_sensors else MISSING, NONE])
            rows.append(row)
            if joint_sensors:
                call("enableJointForceTorqueSensor", bid, j, True, what=f"{link}: joint sensor")
            # the joint frame is the child's URDF link frame: the inertial frame sits at
            # (p_in, r_in) in it, so the anchor is -r_in^T p_in and an axis a is r_in^T a
            r_in = _mat_xyzw(li[4])
            axis = np.array(ji[13], np.float64)
            r_pj = _mat_xyzw(ji[15])
            zero = jtype in (2, 4)
            nrm = np.linalg.norm(axis)
            a = np.zeros(3) if zero or nrm == 0 else axis / nrm
            lo, hi = float(ji[8]), float(ji[9])
            jt = w.joints
            jt["name"].append(ji[1].decode())
            jt["body"].append(row)
            jt["type"].append(JOINT_TYPES[jtype])
            jt["anchor_body"].append(-r_in.T @ np.array(li[3], np.float64))
            # parentFrameOrn is the inverse of the joint frame's orientation in the parent's
            # inertial frame (measured on kuka: r_pj a is off by up to 2, r_pj^T a agrees to 2e-10)
            anchor_p, axis_p = np.array(ji[14], np.float64), r_pj.T @ a
            if parent < 0:  # on the fixed base: the parent frame is the world's
                r_base = quat_wxyz_to_matrix(base_pose[1])
                anchor_p, axis_p = base_pose[0] + r_base @ anchor_p, r_base @ axis_p
            jt["anchor_parent"].append(anchor_p)
            jt["axis_body"].append(r_in.T @ a)
            jt["axis_parent"].append(axis_p)
            jt["range"].append([lo, hi] if lo <= hi and jtype in (0, 1) else [np.nan, np.nan])
            _geoms(call, pb, w, bid, j, row, link)
        w.multibodies.append((bid, list(range(nj)), rows))  # rows[0] = -1: a fixed base
    if w.problems:
        raise AdapterError(f"rblog.adapters.pybullet: the contract has no place for "
                           f"{len(w.problems)} element(s) of client {client}: "
                           + "; ".join(w.problems))
    if maximal:
        w.notes["maximal_coordinates"] = (
            f"{', '.join(maximal)}: loaded with useMaximalCoordinates; pybullet exposes only the "
            "base (no links, no collision shapes, the links' contacts reported on the base)")
    if not joint_sensors:
        w.missing.setdefault("joint", []).extend(n for n, k in zip(w.name, w.kind) if k == "joints")
    if not applied:
        w.missing.setdefault("applied", []).extend(w.name)
    return w


class Stepper:
    """The per-step work: after each ``stepSimulation``, read the rows' state and the step's
    contacts, and add the step's impulses (world frame, (N, 3) each) into ``acc``.

    ``state`` is (x (N, 3), q_xyzw (N, 4), v (N, 3), w (N, 3)) after the last step read: the
    start of the next one, where Bullet evaluates damping and contact lever arms."""

    def __init__(self, world: World, client: int, dt: float, *, contacts: bool = True,
                 joints: bool = True):
        self.pb, self.client, self.world, self.dt = _pb(), int(client), world, float(dt)
        n = world.n
        self.mass = np.array(world.mass, np.float64).reshape(n)
        self.inertia = np.array(world.inertia, np.float64).reshape(n, 3)
        kd = np.array(world.damping, np.float64).reshape(n, 2)
        self.c_lin = self.mass * kd[:, 0] * self.dt  # the damping impulse / (v (1 + |v|))
        self.c_ang = kd[:, 1] * self.dt
        self.parent = np.array(world.parent, np.int64).reshape(n)
        jointed = np.array([k == "joints" for k in world.kind], bool).reshape(n)
        self.jointed = np.flatnonzero(jointed)
        self.jointed_parent = self.parent[self.jointed]
        self._motor_axes(world)
        self.use_contacts, self.use_joints = bool(contacts), bool(joints) and len(self.jointed) > 0
        # (body id, link + 1) -> row, -1 for static geometry and unknown ids
        ids = [b for b, _ in world.rows] + [0]
        width = max([l for _, l in world.rows] + [0]) + 2
        self.row_of = np.full((max(ids) + 1, width), -1, np.int64)
        for r, (b, l) in enumerate(world.rows):
            self.row_of[b, l + 1] = r
        self.calls = [(b, links, rows[0] >= 0) for b, links, rows in world.multibodies]
        self._bases = None  # the body ids when read() is one compiled call, False when not
        kinds = ("contact_linear", "contact_angular", "passive_linear", "passive_angular",
                 "joint_linear", "joint_angular", "applied_linear", "applied_angular")
        # the accumulators, views of one array (zeroed in one call: zero_acc)
        self.acc_all = np.zeros((len(kinds), n, 3))
        self.acc = {k: self.acc_all[i] for i, k in enumerate(kinds)}
        # the work accumulators (J per row), views of one array zeroed with the impulses'
        self.work_all = np.zeros((len(WORK_ACCUMULATED), n))
        self.work = {k: self.work_all[i] for i, k in enumerate(WORK_ACCUMULATED)}
        self.pending = (np.zeros((n, 3)), np.zeros((n, 3)))  # applied before the next step
        self.pending_any = False
        self.rows_out = None  # the last logged step's contact rows (P, 14)
        self.state = self.read()
        if self.use_joints:
            start = [s[:2] for bid, links, _ in self.calls if links
                     for s in self.pb.getJointStates(bid, links, physicsClientId=self.client)]
            start = np.array(start, np.float64).reshape(len(start), 2)
            self.q_start = start[:, 0].copy() if self.limited.any() else None
            self.qd_start = start[:, 1].copy()

    def read(self):
        """The rows' state now; with joints, also ``self.cached``: (x, q_xyzw) of every row as
        Bullet's cached link transforms hold them (the frames of its joint reactions). A world
        of bases alone (no links, no joints) is read in one compiled call
        (``_gather.pybullet_read_bases``: the same pybullet calls, the same numbers)."""
        pb, c = self.pb, self.client
        if self._bases is None:
            self._bases = (np.array([bid for bid, _, base in self.calls if base], np.int64)
                           if not self.use_joints and not any(links for _, links, _ in self.calls)
                           and hasattr(_gather, "pybullet_read_bases") else False)
        if self._bases is not False:
            n = len(self._bases)
            out = (np.empty((n, 3)), np.empty((n, 4)), np.empty((n, 3)), np.empty((n, 3)))
            _gather.pybullet_read_bases(pb.getBasePositionAndOrientation, pb.getBaseVelocity,
                                        self._bases, {"physicsClientId": c}, *out)
            return out
        out, cached = [], []
        for bid, links, base in self.calls:
            if base:
                p, o = pb.getBasePositionAndOrientation(bid, physicsClientId=c)
                lv, av = pb.getBaseVelocity(bid, physicsClientId=c)
                out.append(p + o + lv + av)
                cached.append(p + o)
            if links:
                if self.use_joints:  # before the forward kinematics below refreshes the cache
                    cached += [s[0] + s[1] for s in pb.getLinkStates(bid, links, physicsClientId=c)]
                # forward kinematics leaves the simulation as it is (measured: same bits after
                # 200 steps of r2d2 with and without it)
                out += [s[0] + s[1] + s[6] + s[7] for s in
                        pb.getLinkStates(bid, links, computeLinkVelocity=1,
                                         computeForwardKinematics=1, physicsClientId=c)]
        a = np.array(out, np.float64).reshape(len(out), 13)
        if self.use_joints:
            b = np.array(cached, np.float64).reshape(len(cached), 7)
            self.cached = (b[:, 0:3], b[:, 3:7])
        return tuple(np.ascontiguousarray(a[:, k:k + m]) for k, m in ((0, 3), (3, 4), (7, 3), (10, 3)))

    def after_step(self, rows: bool = True) -> None:
        """Account for the step just taken (call once after every stepSimulation); ``rows``:
        keep its contact rows for :meth:`contact_rows`."""
        try:
            self._after_step(rows)
        except self.pb.error as e:
            raise AdapterError(f"rblog.adapters.pybullet: client {self.client} after a step: "
                               f"pybullet: {e} (a body removed, or the client disconnected?)") from None

    def _after_step(self, rows: bool) -> None:
        x0, q0, v0, w0 = self.state
        dt, acc, n = self.dt, self.acc, self.world.n
        self.rows_out = None
        if self.use_contacts:
            self._contacts(x0, n, dt, rows)
        self.state = self.read()
        v1, w1 = self.state[2], self.state[3]
        # passive: Bullet's multibody damping at the step's initial velocities, and its work at
        # the step's mean velocity (compiled)
        _gather.pybullet_damping(q0, v0, w0, v1, w1, self.inertia, self.c_lin, self.c_ang,
                                 acc["passive_linear"], acc["passive_angular"], self.work["passive"])
        if self.pending_any:
            # the loads applied before the step, and their work at its mean velocity (an
            # impulse J at the centre of mass and the angular impulse about it, as the damping's)
            fl, fa = self.pending
            acc["applied_linear"] += fl
            acc["applied_angular"] += fa
            self.work["applied"] += 0.5 * (np.einsum("ij,ij->i", fl, v0 + v1)
                                           + np.einsum("ij,ij->i", fa, w0 + w1))
            fl[:] = 0.0
            fa[:] = 0.0
            self.pending_any = False
        if self.use_joints:
            # the reactions are in the child's frame of Bullet's cached link transforms at the
            # step's end (measured on r2d2: median residual 1.7e-7 N s per step; 2e-5 with the
            # frames at the start, 5.6e-3 N s at most with the forward-kinematics frames)
            x, q = self.cached
            self._joints(x, _mat_xyzw(q), n, dt)

    def _contacts(self, x0, n, dt, rows: bool):
        # compiled: one pass over pybullet's tuples (no Python object per number), the contact
        # rows in the same pass when the step is logged
        pts = self.pb.getContactPoints(physicsClientId=self.client)
        out = np.empty((len(pts), 14)) if rows else None
        k = _gather.pybullet_contacts_accumulate(pts, self.row_of, x0, dt, self.acc["contact_linear"],
                                                 self.acc["contact_angular"], out)
        self.rows_out = out[:k] if rows and k > 0 else None

    def contact_rows(self, step: int):
        """The contact rows of the last step taken with ``after_step(rows=True)``, in the
        contract's convention (dict for Recorder.write, or None): body_b = -1 for static geometry
        (A and B swapped so that body_a is a row, signs flipped); speculative points (no force,
        positive distance) dropped."""
        out = self.rows_out
        if out is None:
            return None
        k = len(out)
        ids = out[:, 0:2].astype(np.int64)
        return dict(step=np.full(k, int(step), np.int64), body_a=ids[:, 0], body_b=ids[:, 1],
                    point=out[:, 2:5], normal=out[:, 5:8], separation=out[:, 8],
                    normal_impulse=out[:, 9], friction_impulse=out[:, 11:14])

    def _lookup(self, body, link):
        ok = (body >= 0) & (body < self.row_of.shape[0]) & (link + 1 < self.row_of.shape[1])
        out = np.full(len(body), -1, np.int64)
        out[ok] = self.row_of[body[ok], link[ok] + 1]
        return out

    def _motor_axes(self, world) -> None:
        """Per jointed row (joint k on row jointed[k]): the joint's axis in the child's inertial
        frame, whether it slides (its motor a force) or turns (a couple), and its limits."""
        jt = world.joints
        k = len(jt["body"])
        self.motor_axis = np.array(jt["axis_body"], np.float64).reshape(k, 3)
        self.motor_slide = np.array([t == "slide" for t in jt["type"]], bool).reshape(k)
        # the dof's motion subspace S about the child's centre of mass, child frame (the frame
        # of the reactions): a hinge turns about its axis a through its anchor c, so S = (a,
        # a x (0 - c)); a slide S = (0, a); a fixed joint none
        anchor = np.array(jt["anchor_body"], np.float64).reshape(k, 3)
        hinge = np.array([t == "hinge" for t in jt["type"]], bool).reshape(k)
        self.dof_ang = np.where(hinge[:, None], self.motor_axis, 0.0)
        self.dof_lin = np.where(hinge[:, None], np.cross(self.motor_axis, -anchor),
                                np.where(self.motor_slide[:, None], self.motor_axis, 0.0))
        self.multi_dof = np.array([t in ("ball", "planar") for t in jt["type"]], bool).reshape(k)
        self.motor_ok = np.array_equal(np.asarray(jt["body"], np.int64).reshape(k), self.jointed)
        # joint limits (NaN: none): Bullet's btMultiBodyJointLimitConstraint makes a limit's
        # row only in a step whose start has the joint at or beyond it (createConstraintRows:
        # ``if (penetration > 0) continue``), and pybullet reports its impulse nowhere
        lim = np.array(jt["range"], np.float64).reshape(k, 2)
        self.limit_lo, self.limit_hi = lim[:, 0], lim[:, 1]
        self.limited = np.isfinite(self.limit_lo) & self.motor_ok
        self.q_start = None  # the limited joints' positions at the next step's start
        # the rows whose velocity a clamped generalized velocity sets (Bullet's velocity bound):
        # joint k's child row and its descendants (subtree[k]), and every row of a multibody
        # whose free base is clamped (free_bases: (base row, its multibody's rows))
        n, parent = world.n, np.array(world.parent, np.int64).reshape(world.n)
        self.subtree = np.zeros((k, n), bool)
        if self.motor_ok:
            for kk, row in enumerate(np.asarray(jt["body"], np.int64).reshape(k)):
                for r in range(n):
                    a = r
                    while a >= 0 and a != row:
                        a = int(parent[a])
                    self.subtree[kk, r] = a == row
        self.free_bases = [(rows[0], [r for r in rows if r >= 0])
                           for _, _, rows in world.multibodies if rows[0] >= 0]

    def _joints(self, x, r, n, dt):
        pb, c = self.pb, self.client
        react, motor, pos, vel = [], [], [], []
        for bid, links, _ in self.calls:
            if links:
                states = pb.getJointStates(bid, links, physicsClientId=c)
                react += [s[2] for s in states]
                motor += [s[3] for s in states]
                pos += [s[0] for s in states]
                vel += [s[1] for s in states]
        rf = np.array(react, np.float64).reshape(len(react), 6)
        j, p = self.jointed, self.jointed_parent
        # the reaction: force and torque (about the child's centre of mass) in the child's frame
        f = np.einsum("nij,nj->ni", r[j], rf[:, :3]) * dt
        t = np.einsum("nij,nj->ni", r[j], rf[:, 3:]) * dt
        fm = np.zeros_like(f)
        if self.motor_ok and len(motor):
            # the joint motor's impulse (appliedJointMotorTorque: Bullet's motor constraint, not
            # in the ABA's reaction): a couple along a hinge's axis on the child; a force along
            # a slide's at the child's centre of mass (fm, no moment); the parent gets the
            # opposite below (the slide's force at its own centre of mass, no moment either)
            tau = np.array(motor, np.float64).reshape(len(motor)) * dt
            axis_w = np.einsum("nij,nj->ni", r[j], self.motor_axis) * tau[:, None]
            sl = self.motor_slide
            fm[sl] = axis_w[sl]
            t[~sl] += axis_w[~sl]
        lin, ang = self.acc["joint_linear"], self.acc["joint_angular"]
        lin[j] += f + fm
        ang[j] += t
        # the joint's work, on its child row: its generalized force over the step (the
        # reaction's component along the joint's dof, S^T f, which is the torque the ABA applies
        # at the joint: URDF joint damping, TORQUE_CONTROL torques; plus the motor's) at the
        # step's mean joint velocity (measured on kuka: S^T f equals -0.5 qdot0, its URDF damping,
        # to 1e-5 N m under velocity control). A ball or planar joint's dofs are not read: NaN
        if self.motor_ok and len(vel):
            qd1 = np.array(vel, np.float64).reshape(len(vel))
            gen = (np.einsum("ij,ij->i", self.dof_ang, rf[:, 3:])
                   + np.einsum("ij,ij->i", self.dof_lin, rf[:, :3]) + np.asarray(motor, np.float64))
            wj = gen * dt * 0.5 * (self.qd_start + qd1)
            wj[self.multi_dof] = np.nan
            self.work["joint"][j] += wj
            self.qd_start = qd1
        else:
            self.work["joint"][j] = np.nan
        has = p >= 0
        pp, ff, tt = p[has], f[has], t[has]
        back_t = tt + np.cross(x[j[has]] - x[pp], ff)
        ff = ff + fm[has]
        for k in range(3):
            lin[:, k] -= np.bincount(pp, ff[:, k], minlength=n)
            ang[:, k] -= np.bincount(pp, back_t[:, k], minlength=n)
        if self.limited.any():
            # a step that began with a joint at or beyond its limit: the limit's impulse (a
            # couple about a hinge's axis, a force along a slide's, between child and parent)
            # is not in the log, so the joint impulse of both rows is NaN for this interval
            # (measured on r2d2: the right gripper resting on its lower limit leaves 2.3e-8
            # N m s a step along its axis on it and its parent, 2e-11 with the joints mid-range)
            q = np.array(pos, np.float64).reshape(len(pos))
            if self.q_start is not None:
                q0 = self.q_start
                hit = self.limited & ((q0 <= self.limit_lo) | (q0 >= self.limit_hi))
                if hit.any():
                    rows = np.concatenate([j[hit], p[hit][p[hit] >= 0]])
                    lin[rows] = np.nan
                    ang[rows] = np.nan
                    self.work["joint"][j[hit]] = np.nan  # the limit's work, likewise
            self.q_start = q
        # a generalized velocity at Bullet's bound after the step was clamped there: the
        # momentum it removed from the rows it moves is reported nowhere, so their joint impulse
        # is NaN for this interval (measured on kuka under TORQUE_CONTROL, gravity compensated:
        # joint 7 at 100 rad/s leaves its link 0.0985 N m s a step unexplained; 1e-5..1e-4 on
        # the other links, which are not clamped)
        if self.motor_ok and len(vel):
            lim = MAX_COORDINATE_VELOCITY
            clamped = self.subtree[np.abs(np.array(vel, np.float64)) >= lim].any(axis=0)
            v_now, w_now = self.state[2], self.state[3]
            for base, rows in self.free_bases:
                if max(np.abs(v_now[base]).max(), np.abs(w_now[base]).max()) >= lim:
                    clamped[rows] = True
            if clamped.any():
                lin[clamped] = np.nan
                ang[clamped] = np.nan
                self.work["joint"][clamped] = np.nan  # the energy the clamp removed

    def take(self):
        """The impulses accumulated since the last take (dict of (N, 3)), zeroing them and the
        works."""
        out = {k: v.copy() for k, v in self.acc.items()}
        self.acc_all[...] = 0.0
        self.work_all[...] = 0.0
        return out


def settings(client: int = 0) -> dict:
    """pybullet's version and engine parameters (``getPhysicsEngineParameters``)."""
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


def work_supplied(world: World, impulses, joints: bool) -> np.ndarray:
    """(N, len(WORK_KINDS)) SUPPLIED_* codes: applied as its impulse; passive logged where a
    row has damping (missing where its impulse is); joint logged on the rows with a joint of
    their own when the joints are read (``joints``), missing when not; the rest none."""
    n = world.n
    sup = np.asarray(impulses, np.int64).reshape(n, len(IMPULSE_KINDS))
    out = np.full((n, len(WORK_KINDS)), NONE, np.int64)
    out[:, WORK_KINDS.index("applied")] = sup[:, IMPULSE_KINDS.index("applied")]
    passive = sup[:, IMPULSE_KINDS.index("passive")]
    damped = (np.array(world.damping, np.float64).reshape(n, 2) > 0).any(axis=1)
    out[:, WORK_KINDS.index("passive")] = np.where(passive == MISSING, MISSING,
                                                   np.where(damped, passive, NONE))
    own = np.array([k == "joints" for k in world.kind], bool).reshape(n)
    out[own, WORK_KINDS.index("joint")] = LOGGED if joints else MISSING
    return out


def body_table(world: World, gravity, impulses=None, work=()):
    """The contract's Model of a :class:`World` (rblog.body_table with geoms and joints)."""
    from rblog.record.recorder import body_table as table

    g = world.geoms
    jt = world.joints
    geoms = dict(body=g["body"], type=g["type"], size=np.array(g["size"]).reshape(-1, 3),
                 pos_body=np.array(g["pos_body"]).reshape(-1, 3),
                 quat_wxyz_body=np.array(g["quat_wxyz_body"]).reshape(-1, 4),
                 friction=g["friction"], restitution=g["restitution"],
                 collide_group=g["collide_group"], collide_mask=g["collide_mask"],
                 name=g["name"], mesh_vert=g["mesh_vert"])
    joints = None
    if jt["name"]:
        joints = dict(body=jt["body"], type=jt["type"], anchor_body=np.array(jt["anchor_body"]),
                      anchor_parent=np.array(jt["anchor_parent"]), axis_body=np.array(jt["axis_body"]),
                      axis_parent=np.array(jt["axis_parent"]), range=np.array(jt["range"]),
                      armature=np.zeros(len(jt["name"])),  # Bullet models no rotor inertia
                      name=jt["name"])
    n = world.n
    supplied = np.array(world.supplied, np.int64).reshape(n, len(IMPULSE_KINDS)) if impulses is None \
        else impulses
    return table(name=list(world.name), mass=np.array(world.mass, float).reshape(n),
                 inertia_diag=np.array(world.inertia, float).reshape(n, 3), kind=list(world.kind),
                 parent=list(world.parent), geoms=geoms, collide_rule="and", joints=joints,
                 impulses=supplied, work=work, gravity=tuple(float(x) for x in gravity))


class PybulletRecorder(EngineRecorder):
    """Record every body of a pybullet client: ``rec = PybulletRecorder(client, mcap=...)``, then
    ``rec()`` after each ``stepSimulation`` (or ``rec.step(k)`` to step and record), ``rec.close()``.

    Args:
        client: the physicsClientId (0 for the first ``connect``).
        rrd, mcap, keep: where the log goes (as :class:`rblog.Recorder`).
        every: write a sample every this many steps (each carries its interval's impulses).
        damping: {body id: (linear, angular)} where ``changeDynamics`` changed them.
        joint_sensors: enable joint force/torque sensors (joint impulses logged).
        applied: True if every applied load goes through :meth:`apply_external_force` /
            :meth:`apply_external_torque`; False marks applied impulses missing.
        block: samples gathered before they go to the writers as one block.

    The state now is sample 0 (step ``start_step``)."""

    def __init__(self, client: int = 0, *, rrd=None, mcap=None, writer: str | None = None,
                 keep: bool | None = None, every: int = 1, start_step: int = 0,
                 damping=None, joint_sensors: bool = True, applied: bool = True,
                 block: int = 256, **recorder_options):
        from rblog.record.recorder import Recorder

        self.pb, self.client = _pb(), int(client)
        if int(every) < 1:
            raise AdapterError(f"rblog.adapters.pybullet: every={every!r}, expected an "
                               "integer >= 1")
        self.every = int(every)
        self.world = world = inspect(self.client, damping=damping, joint_sensors=joint_sensors,
                                     applied=applied)
        if world.n == 0:
            raise AdapterError(f"rblog.adapters.pybullet: client {self.client} has no dynamic body "
                               "to record (only static geometry)")
        engine = settings(self.client)
        self.dt = float(engine.get("fixedTimeStep", 1.0 / 240.0))
        substeps = int(engine.get("numSubSteps", 0) or 0)
        sup = np.array(world.supplied, np.int64).reshape(world.n, len(IMPULSE_KINDS))
        if substeps > 1:
            # pybullet reports the last substep's contact forces and joint reactions only, and
            # damping acts at every substep's velocities, which it does not report
            for k in ("contact", "passive", "joint"):
                col = sup[:, IMPULSE_KINDS.index(k)]
                col[col == LOGGED] = MISSING
                world.missing.setdefault(k, []).extend(world.name)
            engine["contact_rows"] = {**CONTACT_ROWS, "logged": f"none: numSubSteps {substeps} > 1, "
                                      "pybullet reports the last substep's forces only"}
        # the integration kind (docs/log-format.md): every row whose joint impulses are logged
        # (a link, or a multibody's base carrying links: Bullet steps both in joint
        # coordinates, as MuJoCo's adapter logs it for every body with a joint kind); a lone
        # body keeps its step's error in the balance. Taken per block from the samples'
        # momenta (_integration, before each flush)
        joint_col, integ_col = IMPULSE_KINDS.index("joint"), IMPULSE_KINDS.index("integration")
        sup[sup[:, joint_col] == LOGGED, integ_col] = LOGGED
        self.supplied = sup
        engine.update(missing={k: sorted(set(v)) for k, v in world.missing.items()},
                      collision_filter="Bullet's defaults (pybullet reports neither "
                      "setCollisionFilterGroupMask/Pair nor URDF_USE_SELF_COLLISION)",
                      damping={name: list(d) for name, d in zip(world.name, world.damping)},
                      **world.notes)
        params = self.pb.getPhysicsEngineParameters(physicsClientId=self.client)
        gravity = [params.get(f"gravityAcceleration{c}", 0.0) for c in "XYZ"]
        self.model = body_table(world, gravity, sup,
                                work_supplied(world, sup, joint_sensors and substeps <= 1))
        self.recorder = Recorder(self.model, rrd=rrd, mcap=mcap, dt=self.dt,
                                 writer=writer or f"pybullet {engine['version']} via rblog.adapters",
                                 integrator="default", log_every=self.every,
                                 combine_friction="product", combine_restitution="product",
                                 engine_settings=engine, keep=keep, **recorder_options)
        self.recorder.open()
        self.stepper = Stepper(world, self.client, self.dt, contacts=substeps <= 1,
                               joints=joint_sensors and substeps <= 1)
        self.block = self.recorder.sample_block(capacity=int(block))
        # (channel, accumulator) for every channel the body table logs (actuator: none); the
        # integration kind is no accumulator: _integration fills it per block
        self.channels = [(name, name[len("impulse_"):]) for name in vars(self.block)
                         if name.startswith("impulse_") and "_integration_" not in name]
        self.work_channels = [(name, name[len("work_"):]) for name in vars(self.block)
                              if name.startswith("work_")]
        self._integ = np.flatnonzero(sup[:, integ_col] == LOGGED)
        self._prev_momenta = None  # (t, P, L) of the last sample written, for _integration
        if len(self._integ):
            self.block.before_flush = self._integration
        self.step_count = int(start_step)
        self._since = 0
        self._sample(None)

    # -- applied loads -------------------------------------------------------------------------
    def _row(self, body: int, link: int) -> int:
        r = self.stepper._lookup(np.array([int(body)]), np.array([int(link)]))[0]
        if r < 0:
            raise AdapterError(f"rblog.adapters.pybullet: apply: body {body} link {link} is not a "
                               "recorded body (static or unknown)")
        return int(r)

    def apply_external_force(self, body: int, link: int, force, position, flags=None) -> None:
        """``pybullet.applyExternalForce`` (acts on the next step), logged as an applied impulse:
        force x dt, and (position - centre of mass) x force x dt about the centre of mass."""
        pb = self.pb
        flags = pb.WORLD_FRAME if flags is None else int(flags)
        pb.applyExternalForce(int(body), int(link), list(map(float, force)),
                              list(map(float, position)), flags, physicsClientId=self.client)
        r = self._row(body, link)
        x, q = self.stepper.state[0][r], self.stepper.state[1][r]
        f, p = np.asarray(force, float), np.asarray(position, float)
        if flags == pb.LINK_FRAME:  # both in the link's inertial frame
            rm = _mat_xyzw(q)
            f, arm = rm @ f, rm @ p
        else:
            arm = p - x
        fl, fa = self.stepper.pending
        fl[r] += f * self.dt
        fa[r] += np.cross(arm, f) * self.dt
        self.stepper.pending_any = True

    def apply_external_torque(self, body: int, link: int, torque, flags=None) -> None:
        """``pybullet.applyExternalTorque`` (next step), logged as an applied angular impulse."""
        pb = self.pb
        flags = pb.WORLD_FRAME if flags is None else int(flags)
        pb.applyExternalTorque(int(body), int(link), list(map(float, torque)), flags,
                               physicsClientId=self.client)
        r = self._row(body, link)
        t = np.asarray(torque, float)
        if flags == pb.LINK_FRAME:
            t = _mat_xyzw(self.stepper.state[1][r]) @ t
        self.stepper.pending[1][r] += t * self.dt
        self.stepper.pending_any = True

    # -- stepping --------------------------------------------------------------------------------
    def __call__(self) -> None:
        """Account for the ``stepSimulation`` just taken; a sample every ``every`` calls."""
        self._since += 1
        sample = self._since >= self.every
        self.stepper.after_step(rows=sample)
        self.step_count += 1
        if sample:
            self._sample(self.stepper.rows_out)

    record = __call__

    def step(self, k: int = 1) -> None:
        """``stepSimulation`` k times, recording each."""
        for _ in range(int(k)):
            self.pb.stepSimulation(physicsClientId=self.client)
            self()

    def _sample(self, rows) -> None:
        """This step's state, its interval's impulses (then zeroed) and its contact rows
        (Stepper.rows_out, (P, 14) or None) into the next row of the recorder's sample block
        (one Recorder.write per block)."""
        self._since = 0
        blk = self.block
        r = blk.row()
        x, q, v, w = self.stepper.state
        blk.t[r] = self.step_count * self.dt
        blk.step[r] = self.step_count
        blk.position[r] = x
        blk.quat_wxyz[r, :, 0] = q[:, 3]
        blk.quat_wxyz[r, :, 1:] = q[:, :3]
        blk.velocity[r] = v
        blk.angular_velocity[r] = w
        acc = self.stepper.acc
        for name, key in self.channels:
            np.copyto(getattr(blk, name)[r], acc[key])
        work = self.stepper.work
        for name, key in self.work_channels:
            np.copyto(getattr(blk, name)[r], work[key])
        self.stepper.acc_all[...] = 0.0  # every accumulator (acc's arrays are its views)
        self.stepper.work_all[...] = 0.0
        if rows is not None:  # into the block's own contact arrays (views)
            c = blk.contact_rows(len(rows))
            c.body_a[:] = rows[:, 0]
            c.body_b[:] = rows[:, 1]
            c.point[:] = rows[:, 2:5]
            c.normal[:] = rows[:, 5:8]
            c.separation[:] = rows[:, 8]
            c.normal_impulse[:] = rows[:, 9]
            c.friction_impulse[:] = rows[:, 11:14]
        blk.commit()

    def flush(self) -> None:
        """Write the samples gathered so far."""
        self.block.flush()

    def _integration(self, blk, k: int) -> None:
        """The integration kind of the block's k rows (SampleBlock.before_flush): per
        interval, each body's with logged joint impulses momentum change (``P = m v``, ``L = R I R^T w`` of the
        samples, as the log derives them: rblog.contract.derive.state_from_velocities) less its
        other logged kinds and ``m g dt``. Bullet steps a multibody in joint coordinates (its
        velocities ``u`` first, from the forces at the step's start, then ``q += h u1``), and
        a link's centre of mass moves by ``J(q) u``: this is ``K = m [(J(q1) - J(q0)) u1 - h
        Jdot(q0, u0) u0]`` and its angular part (docs/log-format.md, "The integration kind";
        tests/adapters/test_pybullet_integration.py holds it to the closed form of a pendulum).
        An interval whose other kinds are NaN (a joint limit, a clamped velocity) has NaN."""
        from rblog.contract.derive import state_from_velocities

        model, ids = self.model, self._integ
        n = model.n_bodies
        mass = np.ascontiguousarray(model.body_mass, np.float64)
        inertia = np.ascontiguousarray(model.body_inertia_diag, np.float64)
        rot = np.empty((k, n, 3, 3))
        p, L = np.empty((k, n, 3)), np.empty((k, n, 3))
        state_from_velocities(mass, inertia, np.ascontiguousarray(blk.quat_wxyz[:k]),
                              np.ascontiguousarray(blk.velocity[:k]),
                              np.ascontiguousarray(blk.angular_velocity[:k]), rot, p, L)
        t = blk.t[:k]
        prev = self._prev_momenta
        if prev is None:  # the first sample: its interval is empty
            prev = (t[0], p[0], L[0])
        dt = np.diff(np.concatenate([[prev[0]], t]))
        dp = np.diff(np.concatenate([prev[1][None], p]), axis=0)[:, ids]
        dl = np.diff(np.concatenate([prev[2][None], L]), axis=0)[:, ids]
        dp -= mass[ids][None, :, None] * np.asarray(model.gravity, np.float64) * dt[:, None, None]
        for name, _ in self.channels:
            dst = dp if name.endswith("_linear") else dl
            dst -= getattr(blk, name)[:k, ids]
        blk.impulse_integration_linear[:k, ids] = dp
        blk.impulse_integration_angular[:k, ids] = dl
        self._prev_momenta = (t[-1], p[-1].copy(), L[-1].copy())



#: pybullet_data worlds as shipped (the URDFs unchanged, pybullet's default damping left on)
SHIPPED_WORLDS = ("r2d2", "r2d2_maximal", "kuka_cube", "jenga", "domino", "tray")


def load_shipped(name: str, client: int = 0) -> None:
    """Load one of SHIPPED_WORLDS into ``client``: plane.urdf under gravity -9.81 z and

    * ``r2d2``, ``r2d2_maximal``: r2d2.urdf 0.5 m up (a multibody; useMaximalCoordinates=True);
    * ``kuka_cube``: kuka_iiwa/model.urdf (fixed base: its base link has mass 0) and cube.urdf
      dropped 0.7 m from the arm's axis;
    * ``jenga``: 6 layers of 3 jenga/jenga.urdf blocks, crossed layer by layer;
    * ``domino``: 10 domino/domino.urdf 3 cm apart, the first set tipping (3 rad/s about y);
    * ``tray``: tray/traybox.urdf and 5 cube_small.urdf dropped into it.
    """
    pb = _pb()
    import pybullet_data

    if name not in SHIPPED_WORLDS:
        raise AdapterError(f"rblog.adapters.pybullet: world {name!r}, expected one of "
                           f"{', '.join(SHIPPED_WORLDS)}")
    c = int(client)
    pb.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=c)
    pb.setGravity(0.0, 0.0, -9.81, physicsClientId=c)

    def load(f, pos=(0.0, 0.0, 0.0), orn=(0.0, 0.0, 0.0, 1.0), **kw):
        return pb.loadURDF(f, list(pos), list(orn), physicsClientId=c, **kw)

    load("plane.urdf")
    if name in ("r2d2", "r2d2_maximal"):
        load("r2d2.urdf", (0.0, 0.0, 0.5), useMaximalCoordinates=name == "r2d2_maximal")
    elif name == "kuka_cube":
        load("kuka_iiwa/model.urdf")
        load("cube.urdf", (0.7, 0.0, 0.5))
    elif name == "jenga":
        across = pb.getQuaternionFromEuler([0.0, 0.0, np.pi / 2])
        for k in range(6):
            for j in range(3):
                z = 0.015 + 0.03 * k
                if k % 2 == 0:
                    load("jenga/jenga.urdf", (0.0, (j - 1) * 0.05, z))
                else:
                    load("jenga/jenga.urdf", ((j - 1) * 0.05, 0.0, z), across)
    elif name == "domino":
        first = [load("domino/domino.urdf", (0.03 * k, 0.0, 0.0254)) for k in range(10)][0]
        pb.resetBaseVelocity(first, [0.0, 0.0, 0.0], [0.0, 3.0, 0.0], physicsClientId=c)
    else:
        load("tray/traybox.urdf")
        for k in range(5):
            load("cube_small.urdf", (0.05 * (k - 2), 0.02 * k, 0.1 + 0.06 * k))


__all__ = ["CONTACT_ROWS", "DAMPING_DEFAULT", "IMPULSE_KINDS", "MAX_COORDINATE_VELOCITY",
           "PybulletRecorder", "SHIPPED_WORLDS", "Stepper", "World", "body_table", "inspect",
           "load_shipped", "settings"]
