"""Record a world of the Open Dynamics Engine (ODE, through the ``odepy`` ctypes binding) into
the log contract.

Two lines::

    rec = rblog.adapters.ode.OdeRecorder(world, space, dt=DT, mcap="run.mcap")  # table, sample 0
    for _ in range(n): odepy.dSpaceCollide(space, None, near); odepy.dWorldStep(world, DT); rec()
    rec.close()                                   # or `with`; rblog.check(rblog.load("run.mcap"))

(``dJointGroupEmpty(contactgroup)`` after ``rec()`` or before it, as the user's loop has it.)

ODE's conventions and how they become the contract's (docs/log-format.md):

* **bodies**: ODE's API has no list of a world's bodies, so the recorder finds them through the
  geoms of ``space`` (nested spaces included): every body that owns a geom there is one rigid body
  of the table. ODE's spaces put a new geom at the front of their list, so the recorder reads the
  list backwards: before the first ``dSpaceCollide`` (which moves geoms that moved to the front)
  that is the order the geoms were created in. ``bodies=`` gives the list and order explicitly.
  Kinematic bodies are refused (:class:`~rblog.adapters.AdapterError`).
* **joints** (contract v3): hinge, ball, slider and fixed joints between recorded bodies (or to
  the world, ``dJointAttach(j, b, 0)``) become joint rows. ODE's joints form no tree, so the
  recorder makes one: a body jointed to the world is a root (``body_kind`` "joints", parent -1),
  in a group of bodies jointed only to each other the first in table order is a free root, and
  every other body is the child of the body it reaches the root through (``body_parent``); a
  loop of joints is refused. Each row's anchor is ODE's anchor on that body
  (``dJointGetHingeAnchor`` on the joint's first body, ``...Anchor2`` on its second) in the
  child's and the parent's body frames; the axis ``dJointGetHingeAxis`` / ``dJointGetSliderAxis``
  (world) likewise; limits ``dParamLoStop``/``dParamHiStop`` (NaN when infinite). Other joint
  types (hinge2, universal, piston, motors ...) are refused, naming the type.
* **per-interval impulses** (contract v3): every recorded body's ``impulse_contact_*`` (the
  step's contact joints' ``dJointFeedback``) and ``impulse_joint_*`` (the feedback the recorder
  gives each joint above when it is made): ``f1``/``t1`` act on the joint's first non-null body
  (``dJointGetBody`` 0, or 1 when 0 is the world), ``f2``/``t2`` on the second; ``t`` is the
  torque about that body's centre of mass, world frame. Impulse = force x dt summed over the
  steps since the last sample. Joint motors act through their joint's rows and are in
  ``impulse_joint`` (``actuator``: none); damping (``dWorldSetDamping``, ``dBodySetDamping``)
  is ``passive``: none when every body's is 0, else missing; forces the user's loop adds
  (``dBodyAddForce``) are not visible to the recorder: ``applied`` is missing (not judged)
  unless ``applied_forces=False`` says there are none.
* **frames and mass**: an ODE body's position (``dBodyGetPosition``) is its centre of mass (ODE
  requires ``dMass.c = 0``; a body whose ``dBodyGetMass`` says otherwise is refused).
  ``dMass.I`` is the inertia tensor about it in the body frame (3 x 3, rows of 4 reals). The
  contract wants principal moments in its body frame, so each body's contract frame is chosen by
  :func:`rblog.adapters._common.body_frame`: the frame of its one box geom (``dGeomGetOffset*``)
  when the inertia is diagonal there and the box is centred, else the principal frame (a centred
  sphere keeps its shape in any frame); capsules, cylinders, meshes, several geoms: no shape.
* **state**: ``dBodyGetQuaternion`` is (w, x, y, z), body -> world; ``dBodyGetLinearVel`` is
  the world velocity of the centre of mass; ``dBodyGetAngularVel`` is the angular velocity in the
  **world** frame (ODE keeps no body-frame angular velocity). The contract's quaternion is
  ``q ⊗ q_frame``.
* **contacts**: ODE has no list of the contact joints of a step either, so while it is open the
  recorder wraps ``odepy.dJointCreateContact`` (and ``dWorldStep`` / ``dWorldQuickStep``, to
  know which step a contact belongs to): each contact joint the user's near callback creates gets
  a ``dJointFeedback`` of the recorder's, and its ``dContactGeom`` is kept. (A callback that bound
  ``dJointCreateContact`` before the recorder was made is not seen: ``rec.add_contact(joint,
  contact)`` registers a joint by hand.) ``dContactGeom.normal`` points into ``g1`` (moving
  ``g1``'s body along it by ``depth`` separates the pair), ``depth >= 0`` is the penetration from
  the collision at the step's start, ``pos`` the point. The joint is attached as in ODE's demos,
  ``dJointAttach(j, dGeomGetBody(g1), dGeomGetBody(g2))``; ``dJointFeedback.f1`` is the force on
  the joint's first body over the step, and when ``g1`` has no body ODE reverses the joint, so
  ``f1`` acts on ``g2``'s body. Rows: ``body_a`` = the body ``f1`` acts on, ``body_b`` the
  other (-1 for a geom without a body), ``normal`` from ``body_b`` into ``body_a`` (ODE's
  normal, negated when ``g1`` is static), ``separation = -depth`` (before the step), impulse =
  ``f1 x dt`` split into its normal and tangential parts. With ``dWorldStep`` and
  ``dWorldQuickStep`` the velocity update is ``v += dt M^-1 (f_ext + sum f)``, so each body's
  rows sum to its momentum change minus (m g + F) dt to round-off (tests/adapters/test_ode_adapter.py).
* **materials**: ODE has none per geom: the near callback sets each contact's ``dSurfaceParameters``
  (``mu``, ``bounce``). The recorder logs the per-body friction and restitution the caller
  states (``friction=``, ``restitution=``, ``ground_friction=`` ...), NaN (unknown, not judged)
  otherwise, with the combine rules the caller names (``combine_friction``, default ``max``).
* **world**: ``dWorldGetGravity``; the first plane geom without a body is the ground (``dCreatePlane``
  ``a x + b y + c z = d``: normal (a, b, c), offset d), box geoms without a body are static boxes;
  other static geoms are listed in ``engine_settings["static_geoms_not_in_the_table"]`` (their
  contacts are still logged, with ``body_b = -1``). ODE has no time step of its own: ``dt`` is
  the caller's, and a wrapped step with another dt is an error.

Why this module is long: it is the one translation of ODE's conventions (the body table, the joint
tree, the state, contact and joint feedback, and the wrappers that see the user's contact joints
and steps), and they share ODE's pointer bookkeeping; ``rblog run --engine ode``
(rblog/study/engines/ode.py) uses the same pieces.
"""

from __future__ import annotations

import ctypes

import numpy as np

from rblog.adapters import AdapterError, require
from rblog.adapters._common import EngineRecorder, SampleStream, body_frame, quat_mul
from rblog.contract.model import IMPULSE_KINDS, BODY_JOINTED, JOINT_BALL, JOINT_FIXED, JOINT_HINGE, JOINT_SLIDE, \
    SHAPE_BOX, SHAPE_SPHERE, SUPPLIED_LOGGED, SUPPLIED_MISSING, SUPPLIED_NONE, Model
from rblog.contract.orientation import matrix_to_quat

#: the contract's value of engine_settings.contact_rows for ODE's contact joints
CONTACT_ROWS = {
    "separation": "before the step (dContactGeom.depth from the collision at its start, negated)",
    "impulse": "dJointFeedback.f1 * dt, on the joint's first body (g2's when g1 has none)",
    "speculative": "none (dCollide reports touching points only)",
}
#: the inertia is diagonal in the body frame when its off-diagonal terms are below this fraction
#: of its trace (then the body frame is kept; else the principal frame is found)
DIAGONAL_REL = 1e-12
#: |dMass.c| above this (m) is a centre of mass off the body origin, which ODE does not support
COM_TOL = 1e-9


_ODEPY = []


def _ode():
    """The odepy module (imported once)."""
    if _ODEPY:
        return _ODEPY[0]
    try:
        _ODEPY.append(require("odepy", extra="ode"))
        return _ODEPY[0]
    except AdapterError:
        raise
    except Exception as e:  # noqa: BLE001 - odepy loads libode on import (OdePyError without it)
        raise AdapterError(f"rblog.adapters.ode: odepy could not load libode ({type(e).__name__}: "
                           f"{e}): apt-get install libode8") from None


def _addr(p) -> int:
    """The address a ctypes pointer (body, geom, joint, world id) holds; 0 for NULL."""
    return ctypes.cast(p, ctypes.c_void_p).value or 0


def _vec(p, n: int = 3) -> np.ndarray:
    return np.array(p[:n], np.float64)


def library() -> tuple[str, str]:
    """(the libode the binding loads, its configuration string: precision, extensions)."""
    _ode()
    import odepy
    from ctypes.util import find_library

    try:
        conf = ctypes.string_at(ctypes.cast(odepy.dGetConfiguration(), ctypes.c_void_p)).decode()
    except Exception:  # noqa: BLE001 - an older libode without dGetConfiguration
        conf = ""
    return find_library("ode") or "libode", conf.strip()


def version() -> str:
    """``ode-python <version> / <libode soname>`` (libode.so.8: ODE 0.16)."""
    from importlib.metadata import PackageNotFoundError, version as pkg_version

    try:
        binding = pkg_version("ode-python")
    except PackageNotFoundError:
        binding = "?"
    return f"ode-python {binding} / {library()[0]}"


def principal(mass) -> tuple[np.ndarray, np.ndarray]:
    """(moments (3,), quaternion (4,) of the principal frame in the body frame) of a dMass."""
    i_body = np.array([[mass.I[4 * r + c] for c in range(3)] for r in range(3)], np.float64)
    i_body = 0.5 * (i_body + i_body.T)
    off = i_body - np.diag(np.diag(i_body))
    if np.max(np.abs(off)) <= DIAGONAL_REL * max(float(np.trace(i_body)), 1e-300):
        return np.diag(i_body).copy(), np.array([1.0, 0.0, 0.0, 0.0])
    moments, axes = np.linalg.eigh(i_body)
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1.0
    return moments, matrix_to_quat(axes)


def _space_geoms(space) -> list:
    """Every geom of ``space`` and of the spaces nested in it, the list read backwards (ODE adds
    a geom at the front: in the order of creation until a collision pass reorders them)."""
    ode = _ode()
    out = []
    for k in reversed(range(ode.dSpaceGetNumGeoms(space))):
        g = ode.dSpaceGetGeom(space, k)
        if ode.dGeomIsSpace(g):
            out += _space_geoms(ctypes.cast(g, ode.dSpaceID))
        else:
            out.append(g)
    return out


def _body_geoms(body) -> list:
    ode = _ode()
    out, g = [], ode.dBodyGetFirstGeom(body)
    while _addr(g):
        out.append(g)
        g = ode.dGeomGetBodyNext(g)
    return out


def _joint_types(body) -> list[int]:
    ode = _ode()
    return [int(ode.dJointGetType(ode.dBodyGetJoint(body, k))) for k in range(ode.dBodyGetNumJoints(body))]


JOINT_TYPE_NAMES = {1: "ball", 2: "hinge", 3: "slider", 5: "universal", 6: "hinge2", 7: "fixed",
                    8: "null", 9: "amotor", 10: "lmotor", 11: "plane2d", 12: "prismatic-rotoide",
                    13: "prismatic-universal", 14: "piston", 15: "double-ball", 16: "double-hinge",
                    17: "transmission"}
CONTACT_JOINT = 4


def inspect(world, space, *, bodies=None, names=None, friction=np.nan, restitution=np.nan,
            ground_friction=None, ground_restitution=None):
    """The body table of an ODE world: (Model, bodies (list of dBodyID), q_frame (N, 4), notes);
    its joints are :func:`joint_tree`'s.

    ``friction``/``restitution``: scalar or per recorded body (ODE states none per body);
    ``ground_*``: the ground's and the static boxes' (default: the bodies' first value)."""
    ode = _ode()
    geoms = _space_geoms(space)
    if bodies is None:
        bodies, seen = [], set()
        for g in geoms:
            b = ode.dGeomGetBody(g)
            if _addr(b) and _addr(b) not in seen:
                seen.add(_addr(b))
                bodies.append(b)
    n = len(bodies)
    shapes, sizes, inertias, q_frames, masses = [], [], [], [], []
    for i, b in enumerate(bodies):
        if ode.dBodyIsKinematic(b):
            raise AdapterError(f"rblog.adapters.ode: body {i} is kinematic: the contract records "
                               "free rigid bodies and static geometry only")
        other = sorted({JOINT_TYPE_NAMES.get(t, str(t)) for t in _joint_types(b)
                        if t != CONTACT_JOINT and t not in JOINT_CONTRACT})
        if other:
            raise AdapterError(f"rblog.adapters.ode: body {i} is on a {', '.join(other)} joint: the "
                               "contract records hinge, ball, slider and fixed joints")
        m = ode.dMass()
        ode.dBodyGetMass(b, ctypes.byref(m))
        c = np.array(m.c[:3], float)
        if np.linalg.norm(c) > COM_TOL:
            raise AdapterError(f"rblog.adapters.ode: body {i} has dMass.c = {c.tolist()}: ODE needs "
                               "the centre of mass at the body origin (dMassTranslate the geoms instead)")
        moments, q_inertial = principal(m)
        bg = _body_geoms(b)
        geom = None
        if len(bg) == 1:
            g = bg[0]
            cls = int(ode.dGeomGetClass(g))
            q_off = (ode.dQuaternion)()
            ode.dGeomGetOffsetQuaternion(g, q_off)
            centre = _vec(ode.dGeomGetOffsetPosition(g))
            if cls == ode.dSphereClass:
                geom = (SHAPE_SPHERE, np.array([ode.dGeomSphereGetRadius(g), 0.0, 0.0]), centre,
                        _vec(q_off, 4), np.zeros(3))
            elif cls == ode.dBoxClass:
                lengths = (ode.dVector3)()
                ode.dGeomBoxGetLengths(g, lengths)
                geom = (SHAPE_BOX, _vec(lengths) / 2.0, centre, _vec(q_off, 4), np.zeros(3))
        shape, size, inertia_c, q_frame = body_frame(moments, q_inertial, geom)
        shapes.append(shape)
        sizes.append(size)
        inertias.append(inertia_c)
        q_frames.append(q_frame)
        masses.append(float(m.mass))
    ground, g_normal, g_offset = False, np.array([0.0, 0.0, 1.0]), 0.0
    sb_pos, sb_quat, sb_half, other = [], [], [], []
    for g in geoms:
        if _addr(ode.dGeomGetBody(g)):
            continue
        cls = int(ode.dGeomGetClass(g))
        if cls == ode.dPlaneClass and not ground:
            p = (ode.dVector4)()
            ode.dGeomPlaneGetParams(g, p)
            nrm = _vec(p)
            scale = float(np.linalg.norm(nrm))
            ground, g_normal, g_offset = True, nrm / scale, float(p[3]) / scale
        elif cls == ode.dBoxClass:
            lengths, q = (ode.dVector3)(), (ode.dQuaternion)()
            ode.dGeomBoxGetLengths(g, lengths)
            ode.dGeomGetQuaternion(g, q)
            sb_pos.append(_vec(ode.dGeomGetPosition(g)))
            sb_quat.append(_vec(q, 4))
            sb_half.append(_vec(lengths) / 2.0)
        else:
            other.append(f"geom class {cls}")
    mu = np.broadcast_to(np.asarray(friction, float), (n,)).copy()
    e = np.broadcast_to(np.asarray(restitution, float), (n,)).copy()
    g_mu = float(mu[0] if n else np.nan) if ground_friction is None else float(ground_friction)
    g_e = float(e[0] if n else np.nan) if ground_restitution is None else float(ground_restitution)
    grav = (ode.dVector3)()
    ode.dWorldGetGravity(world, grav)
    nsb = len(sb_pos)
    q_frames = np.array(q_frames).reshape(n, 4)
    tree = joint_tree(bodies, q_frames)
    model = Model(
        body_name=list(names) if names is not None else [f"body{i}" for i in range(n)],
        body_shape=np.array(shapes, np.int64).reshape(n), body_size=np.array(sizes).reshape(n, 3),
        body_mass=np.array(masses, float).reshape(n), body_inertia_diag=np.array(inertias).reshape(n, 3),
        body_force_world=np.zeros((n, 3)), body_torque_world=np.zeros((n, 3)),
        body_restitution=e, body_friction=mu, body_group=np.zeros(n, np.int64),
        gravity=_vec(grav), ground=ground, ground_normal=g_normal, ground_offset=g_offset,
        ground_restitution=g_e, ground_friction=g_mu,
        static_box_position=np.array(sb_pos).reshape(nsb, 3),
        static_box_quat_wxyz=np.array(sb_quat).reshape(nsb, 4),
        static_box_half_extents=np.array(sb_half).reshape(nsb, 3),
        static_box_restitution=np.full(nsb, g_e), static_box_friction=np.full(nsb, g_mu),
        **tree.model_fields())
    return model, list(bodies), q_frames, {"static_geoms_not_in_the_table": other}


#: ODE joint types the contract has (dJointType -> JOINT_* code)
JOINT_CONTRACT = {2: JOINT_HINGE, 1: JOINT_BALL, 3: JOINT_SLIDE, 7: JOINT_FIXED}


class JointTree:
    """The recorded bodies' joints as the contract's tree (see the module docstring).

    Attributes: ``joints`` (J,) dJointIDs in row order; ``first``/``second`` (J,) table rows of
    the bodies their feedback's f1/t1 and f2/t2 act on (-1: the world); ``kind``, ``parent`` (N,);
    ``rows``: dict of the joint_* arrays."""

    def __init__(self, joints, first, second, kind, parent, rows):
        self.joints, self.first, self.second = joints, first, second
        self.kind, self.parent, self.rows = kind, parent, rows

    def model_fields(self) -> dict:
        return dict(body_kind=self.kind, body_parent=self.parent, **self.rows)


def _joint_points(j, jtype):
    """(anchor on the joint's body 0, anchor on body 1, axis), world frame, or None each."""
    ode = _ode()
    a1, a2, ax = (ode.dVector3)(), (ode.dVector3)(), (ode.dVector3)()
    if jtype == 2:
        ode.dJointGetHingeAnchor(j, a1)
        ode.dJointGetHingeAnchor2(j, a2)
        ode.dJointGetHingeAxis(j, ax)
        return _vec(a1), _vec(a2), _vec(ax)
    if jtype == 1:
        ode.dJointGetBallAnchor(j, a1)
        ode.dJointGetBallAnchor2(j, a2)
        return _vec(a1), _vec(a2), None
    if jtype == 3:
        ode.dJointGetSliderAxis(j, ax)
        return None, None, _vec(ax)
    return None, None, None


def _limit(j, jtype, param) -> float:
    ode = _ode()
    get = {2: getattr(ode, "dJointGetHingeParam", None), 3: getattr(ode, "dJointGetSliderParam", None)}.get(jtype)
    if get is None:
        return np.nan
    v = float(get(j, param))
    return v if np.isfinite(v) and abs(v) < 1e300 else np.nan


def joint_tree(bodies, q_frame) -> JointTree:
    """The joints of ``bodies`` (dBodyIDs, the table's order) as rows of the contract's tree;
    ``q_frame`` (N, 4): each body's contract frame in its ODE body frame."""
    ode = _ode()
    from collections import deque

    from rblog.contract.orientation import quat_wxyz_to_matrix

    n = len(bodies)
    row = {_addr(b): i for i, b in enumerate(bodies)}
    found, order = {}, []
    for b in bodies:
        for k in range(ode.dBodyGetNumJoints(b)):
            j = ode.dBodyGetJoint(b, k)
            t = int(ode.dJointGetType(j))
            if t == CONTACT_JOINT or _addr(j) in found:
                continue
            b0, b1 = ode.dJointGetBody(j, 0), ode.dJointGetBody(j, 1)
            r0 = row.get(_addr(b0), -1) if _addr(b0) else -1
            r1 = row.get(_addr(b1), -1) if _addr(b1) else -1
            if (_addr(b0) and r0 < 0) or (_addr(b1) and r1 < 0):
                raise AdapterError("rblog.adapters.ode: a joint attaches a recorded body to a body "
                                   "that is not recorded (give it a geom in the space, or bodies=)")
            found[_addr(j)] = (j, t, r0, r1)
            order.append(_addr(j))
    adj = {i: [] for i in range(n)}
    roots = []
    for key in order:
        j, t, r0, r1 = found[key]
        if r0 >= 0 and r1 >= 0:
            adj[r0].append((r1, key))
            adj[r1].append((r0, key))
        else:
            roots.append((r0 if r0 >= 0 else r1, key))
    kind = np.zeros(n, np.int64)  # BODY_FREE
    parent = np.full(n, -1, np.int64)
    via = {}  # child row -> joint key
    seen = set()
    queue = deque()
    for r, key in roots:
        if r in seen:
            raise AdapterError(f"rblog.adapters.ode: body {r} has two joints to the world: a loop "
                               "of joints, which the contract's tree cannot hold")
        seen.add(r)
        kind[r], via[r] = BODY_JOINTED, key
        queue.append(r)
    for start in range(n):
        if start not in seen and adj[start]:
            seen.add(start)
            queue.append(start)
        used = set()
        while queue:
            p = queue.popleft()
            for c, key in adj[p]:
                if key == via.get(p) or key in used:
                    continue
                used.add(key)
                if c in seen:
                    raise AdapterError("rblog.adapters.ode: a loop of joints (body "
                                       f"{c} is reached twice), which the contract's tree cannot hold")
                seen.add(c)
                kind[c], parent[c], via[c] = BODY_JOINTED, p, key
                queue.append(c)
    pos = np.array([_vec(ode.dBodyGetPosition(b)) for b in bodies]).reshape(n, 3)
    quat = np.array([_vec(ode.dBodyGetQuaternion(b), 4) for b in bodies]).reshape(n, 4)
    rot = quat_wxyz_to_matrix(quat_mul(quat, q_frame)) if n else np.zeros((0, 3, 3))

    def frame(i, v, point=True):
        if i < 0:
            return v
        return rot[i].T @ (v - pos[i] if point else v)

    names, types, child_rows, ab, ap, xb, xp, rng, joints, first, second = ([] for _ in range(11))
    for c in sorted(via):
        key = via[c]
        j, t, r0, r1 = found[key]
        p = int(parent[c])
        a0, a1, ax = _joint_points(j, t)
        if a0 is None:  # slider, fixed: the child's centre of mass
            a_child = a_par = pos[c]
        else:
            a_child, a_par = (a0, a1) if r0 == c else (a1, a0)
        if t == 3:  # at the slider's zero position the child sits pos * axis back
            a_par = a_par - float(ode.dJointGetSliderPosition(j)) * (ax if r0 == c else -ax)
        names.append(f"joint{len(names)}")
        types.append(JOINT_CONTRACT[t])
        child_rows.append(c)
        ab.append(frame(c, a_child))
        ap.append(frame(p, a_par))
        xb.append(np.zeros(3) if ax is None else frame(c, ax, point=False))
        xp.append(np.zeros(3) if ax is None else frame(p, ax, point=False))
        rng.append((_limit(j, t, ode.dParamLoStop), _limit(j, t, ode.dParamHiStop)))
        joints.append(j)
        # dJointFeedback: f1 on the first non-null body, f2 on the second
        first.append(r0 if r0 >= 0 else r1)
        second.append(r1 if r0 >= 0 else -1)
    k = len(names)
    rows = dict(joint_name=names, joint_type=np.array(types, np.int64).reshape(k),
                joint_body=np.array(child_rows, np.int64).reshape(k),
                joint_anchor_body=np.array(ab).reshape(k, 3), joint_anchor_parent=np.array(ap).reshape(k, 3),
                joint_axis_body=np.array(xb).reshape(k, 3), joint_axis_parent=np.array(xp).reshape(k, 3),
                joint_range=np.array(rng, float).reshape(k, 2),
                joint_armature=np.zeros(k))  # ODE models no rotor inertia
    return JointTree(joints, np.array(first, np.int64), np.array(second, np.int64), kind, parent, rows)


def settings(world, stepper: str = "world") -> dict:
    """ODE's world settings (every one that changes a step) in engine_settings' form."""
    ode = _ode()
    out = {"engine": "ode", "version": version(), "library_configuration": library()[1],
           "integrator": "dWorldQuickStep" if stepper == "quick" else "dWorldStep",
           "stepper": stepper, "erp": float(ode.dWorldGetERP(world)), "cfm": float(ode.dWorldGetCFM(world)),
           "contact_max_correcting_vel": float(ode.dWorldGetContactMaxCorrectingVel(world)),
           "contact_surface_layer": float(ode.dWorldGetContactSurfaceLayer(world)),
           "linear_damping": float(ode.dWorldGetLinearDamping(world)),
           "angular_damping": float(ode.dWorldGetAngularDamping(world)),
           "max_angular_speed": float(ode.dWorldGetMaxAngularSpeed(world)),
           "auto_disable": int(ode.dWorldGetAutoDisableFlag(world)),
           "contact_rows": dict(CONTACT_ROWS)}
    if stepper == "quick":
        out["quickstep_iterations"] = int(ode.dWorldGetQuickStepNumIterations(world))
        out["quickstep_w"] = float(ode.dWorldGetQuickStepW(world))
    return out


def read_state(bodies, q_frame=None):
    """(position, quat_wxyz, velocity, angular_velocity) of ``bodies`` now, world frame, (N, 3|4),
    in the contract's frames (``q_frame`` (N, 4): each contract frame in ODE's body frame)."""
    ode = _ode()
    n = len(bodies)
    x, q, v, w = np.empty((n, 3)), np.empty((n, 4)), np.empty((n, 3)), np.empty((n, 3))
    for i, b in enumerate(bodies):
        x[i] = ode.dBodyGetPosition(b)[:3]
        q[i] = ode.dBodyGetQuaternion(b)[:4]
        v[i] = ode.dBodyGetLinearVel(b)[:3]
        w[i] = ode.dBodyGetAngularVel(b)[:3]
    return x, (q if q_frame is None else quat_mul(q, q_frame)), v, w


class ContactFeedback:
    """The contact joints of one step, each with a ``dJointFeedback`` of its own, turned into
    contract rows. ``add(joint, point, normal, depth, row1, row2)``: ODE's normal (into g1),
    depth >= 0, and the table rows of g1's and g2's bodies (-1: no body)."""

    def __init__(self):
        self.clear()

    def clear(self) -> None:
        self.feedback, self.geom = [], []

    def __len__(self):
        return len(self.geom)

    def add(self, joint, point, normal, depth, row1: int, row2: int) -> None:
        ode = _ode()
        fb = ode.dJointFeedback()
        ode.dJointSetFeedback(joint, ctypes.byref(fb))
        self.feedback.append(fb)
        self.geom.append((*point[:3], *normal[:3], float(depth), int(row1), int(row2)))

    def body_impulses(self, n: int, dt: float):
        """((n, 3) linear N s, (n, 3) angular N m s about each body's centre of mass): what the
        step's contacts gave each of the ``n`` bodies (f1/t1 on the first non-null body, f2/t2
        on the second)."""
        lin, ang = np.zeros((n, 3)), np.zeros((n, 3))
        if not self.geom:
            return lin, ang
        fb = _feedback_array(self.feedback)
        r = np.array([g[7:9] for g in self.geom], np.int64)
        _add_feedback(lin, ang, fb, np.where(r[:, 0] >= 0, r[:, 0], r[:, 1]),
                      np.where(r[:, 0] >= 0, r[:, 1], -1), dt)
        return lin, ang

    def rows(self, dt: float, step: int):
        """The rows of the step just taken (dict for Recorder.write), or None."""
        if not self.geom:
            return None
        g = np.array(self.geom, np.float64)
        r1, r2 = g[:, 7].astype(np.int64), g[:, 8].astype(np.int64)
        keep = (r1 >= 0) | (r2 >= 0)
        if not keep.any():
            return None
        f1 = np.array([fb.f1[:3] for fb in self.feedback], np.float64)
        normal = g[:, 3:6].copy()
        flip = r1 < 0  # g1 static: the joint is reversed, f1 acts on g2's body
        a = np.where(flip, r2, r1)
        b = np.where(flip, -1, r2)
        normal[flip] *= -1.0
        imp = f1 * dt
        jn = np.einsum("ij,ij->i", imp, normal)
        fric = imp - jn[:, None] * normal
        k = int(keep.sum())
        return dict(step=np.full(k, int(step), np.int64), body_a=a[keep], body_b=b[keep],
                    point=g[keep, 0:3], normal=normal[keep], separation=-g[keep, 6],
                    normal_impulse=jn[keep], friction_impulse=fric[keep])


def _feedback_array(feedback) -> np.ndarray:
    """(K, 16) the dJointFeedback structs' reals: f1, t1, f2, t2 at columns 0, 4, 8, 12."""
    return np.array([[*f.f1[:4], *f.t1[:4], *f.f2[:4], *f.t2[:4]] for f in feedback],
                    np.float64).reshape(-1, 16)


def _add_feedback(lin, ang, fb, first, second, dt) -> None:
    """Add the impulses of feedback rows ``fb`` (K, 16) to the bodies ``first`` (f1, t1) and
    ``second`` (f2, t2) (K,) rows, -1 = none."""
    for col, rows in ((0, first), (8, second)):
        ok = rows >= 0
        np.add.at(lin, rows[ok], fb[ok, col:col + 3] * dt)
        np.add.at(ang, rows[ok], fb[ok, col + 4:col + 7] * dt)


def _contact_of(arg):
    """The dContact behind what ``dJointCreateContact`` was given (byref, pointer, or the struct)."""
    ode = _ode()
    if isinstance(arg, ode.dContact):
        return arg
    obj = getattr(arg, "_obj", None)  # ctypes.byref(...)
    if isinstance(obj, ode.dContact):
        return obj
    try:
        return ctypes.cast(arg, ctypes.POINTER(ode.dContact)).contents
    except (TypeError, ctypes.ArgumentError):
        raise AdapterError(f"rblog.adapters.ode: dJointCreateContact got a {type(arg).__name__}, "
                           "expected a dContact (or a pointer to one)") from None


class _Wrap:
    """odepy.dJointCreateContact, dWorldStep and dWorldQuickStep wrapped for one recorder."""

    NAMES = ("dJointCreateContact", "dWorldStep", "dWorldQuickStep")

    def __init__(self, rec):
        import odepy
        import odepy.objects

        self.rec, self.mods = rec, (odepy, odepy.objects)
        self.orig = {k: getattr(odepy, k) for k in self.NAMES}
        orig = self.orig

        def create(world, group, contact):
            j = orig["dJointCreateContact"](world, group, contact)
            if _addr(world) == rec.world_addr:
                rec.add_contact(j, _contact_of(contact))
            return j

        def stepper(name):
            def step(world, dt):
                r = orig[name](world, dt)
                if _addr(world) == rec.world_addr:
                    rec._stepped(float(dt))
                return r
            return step

        self.new = {"dJointCreateContact": create, "dWorldStep": stepper("dWorldStep"),
                    "dWorldQuickStep": stepper("dWorldQuickStep")}
        for m in self.mods:
            for k, f in self.new.items():
                setattr(m, k, f)

    def undo(self) -> None:
        for m in self.mods:
            for k, f in self.new.items():
                if getattr(m, k, None) is f:  # a later wrapper still in place stays
                    setattr(m, k, self.orig[k])


class _IntervalStream(SampleStream):
    """SampleStream with the per-interval channels of each sample."""

    def _clear(self):
        super()._clear()
        self.chan = {}

    def add(self, step, x, q, v, w, contacts=None, **channels) -> None:
        for k, a in channels.items():
            self.chan.setdefault(k, []).append(np.array(a))
        super().add(step, x, q, v, w, contacts)

    def flush(self, dt: float | None = None) -> None:
        if not self.steps:
            return
        rec = self.recorder
        dt = rec.info.dt if dt is None else dt
        steps = np.array(self.steps, np.int64)
        arrays = dict(t=steps * dt, step=steps, position=np.array(self.x), quat_wxyz=np.array(self.q),
                      velocity=np.array(self.v), angular_velocity=np.array(self.w),
                      **{k: np.array(v) for k, v in self.chan.items()})
        if self.c:
            arrays["contacts"] = {k: np.concatenate([c[k] for c in self.c]) for k in self.c[0]}
        self._clear()
        rec.write(**arrays)


class OdeRecorder(EngineRecorder):
    """Record an ODE world: ``rec = OdeRecorder(world, space, dt=..., mcap=...)``, then ``rec()``
    after each ``dWorldStep`` / ``dWorldQuickStep``, ``rec.close()``.

    Args:
        world, space: the dWorldID and the dSpaceID holding the bodies' geoms.
        dt: the step the user passes to dWorldStep (s).
        bodies, names: the bodies to record (default: every body with a geom in ``space``) and
            their names.
        friction, restitution, ground_friction, ground_restitution: materials to log (ODE's are
            per contact, in the user's near callback); NaN = unknown.
        combine_friction, combine_restitution: how the log says two bodies' values combine.
        applied_forces: False when the user's loop adds no force or torque (dBodyAddForce ...):
            the log then says the applied impulses are none, so the momentum balance is judged.
        rrd, mcap, keep, writer, **recorder_options: as :class:`rblog.record.Recorder`.

    The state now is sample 0 (step 0, or ``start_step``)."""

    def __init__(self, world, space, *, dt: float, rrd=None, mcap=None, bodies=None, names=None,
                 friction=np.nan, restitution=np.nan, ground_friction=None, ground_restitution=None,
                 combine_friction: str = "max", combine_restitution: str = "max",
                 writer: str | None = None, keep: bool | None = None, start_step: int = 0,
                 block: int | None = None, stepper: str = "world", applied_forces: bool = True,
                 **recorder_options):
        from rblog.record.recorder import Recorder

        _ode()
        if not (float(dt) > 0):
            raise AdapterError(f"rblog.adapters.ode: dt = {dt!r}: expected the positive step of dWorldStep")
        self.world, self.space, self.dt = world, space, float(dt)
        self.world_addr = _addr(world)
        self.model, self.bodies, self.q_frame, notes = inspect(
            world, space, bodies=bodies, names=names, friction=friction, restitution=restitution,
            ground_friction=ground_friction, ground_restitution=ground_restitution)
        self.row_of = {_addr(b): i for i, b in enumerate(self.bodies)}
        n = self.model.n_bodies
        # the joints' feedback (the user's own, where set), read after every step
        self.tree = joint_tree(self.bodies, self.q_frame)
        self.joint_feedback = []
        for j in self.tree.joints:
            fb = ode_fb = _ode().dJointGetFeedback(j)
            if not _addr(ode_fb):
                fb = _ode().dJointFeedback()
                _ode().dJointSetFeedback(j, ctypes.byref(fb))
            else:
                fb = ode_fb.contents
            self.joint_feedback.append(fb)
        jointed = np.zeros(n, bool)
        jointed[self.tree.first[self.tree.first >= 0]] = True
        jointed[self.tree.second[self.tree.second >= 0]] = True
        damped = any(_ode().dBodyGetLinearDamping(b) or _ode().dBodyGetAngularDamping(b)
                     for b in self.bodies)
        # IMPULSE_KINDS: contact, applied, passive, actuator, joint, integration (none: ODE's
        # maximal coordinates move each body by its forces)
        sup = np.full((n, len(IMPULSE_KINDS)), SUPPLIED_NONE, np.int64)
        sup[:, 0] = SUPPLIED_LOGGED
        sup[:, 1] = SUPPLIED_MISSING if applied_forces else SUPPLIED_NONE
        sup[:, 2] = SUPPLIED_MISSING if damped else SUPPLIED_NONE
        sup[:, 3] = SUPPLIED_NONE
        sup[:, 4] = np.where(jointed, SUPPLIED_LOGGED, SUPPLIED_NONE)
        self.model.body_impulse_supplied = sup
        self.log_joint = bool(jointed.any())
        self._zero_interval()
        engine = {**settings(world, stepper), **notes}
        engine["joints"] = [f"{self.model.joint_name[k]}: body {int(self.model.joint_body[k])} on "
                            f"{int(self.model.body_parent[self.model.joint_body[k]])}" for k in range(len(self.tree.joints))]
        self.recorder = Recorder(self.model, rrd=rrd, mcap=mcap, dt=self.dt,
                                 writer=writer or f"ode {engine['version']} via rblog.adapters",
                                 integrator=engine["integrator"], combine_friction=combine_friction,
                                 combine_restitution=combine_restitution, engine_settings=engine,
                                 keep=keep, **recorder_options)
        self.recorder.open()
        self.stream = _IntervalStream(self.recorder, **({} if block is None else {"block": block}))
        self.step = int(start_step)
        self.pending, self.last = ContactFeedback(), ContactFeedback()
        self.steps_seen = 0
        self.stream.add(self.step, *self.state(), None, **self._interval())
        self._wrap = _Wrap(self)

    def _zero_interval(self) -> None:
        n = self.model.n_bodies
        self.acc = {k: np.zeros((n, 3)) for k in ("contact_linear", "contact_angular", "joint_linear", "joint_angular")}

    def _accumulate(self, contacts: "ContactFeedback") -> None:
        """Add one step's contact and joint impulses to the interval's sums."""
        n = self.model.n_bodies
        lin, ang = contacts.body_impulses(n, self.dt)
        self.acc["contact_linear"] += lin
        self.acc["contact_angular"] += ang
        if self.joint_feedback:
            _add_feedback(self.acc["joint_linear"], self.acc["joint_angular"],
                          _feedback_array(self.joint_feedback), self.tree.first, self.tree.second, self.dt)

    def _interval(self) -> dict:
        """The interval channels of the sample being logged (then zeroed)."""
        out = {"impulse_contact_linear": self.acc["contact_linear"],
               "impulse_contact_angular": self.acc["contact_angular"]}
        if self.log_joint:
            out["impulse_joint_linear"] = self.acc["joint_linear"]
            out["impulse_joint_angular"] = self.acc["joint_angular"]
        self._zero_interval()
        return out

    def add_contact(self, joint, contact) -> None:
        """Register a contact joint of the coming step (done by the wrapped dJointCreateContact)."""
        ode = _ode()
        g = contact.geom
        r1 = self.row_of.get(_addr(ode.dGeomGetBody(g.g1)), -1)
        r2 = self.row_of.get(_addr(ode.dGeomGetBody(g.g2)), -1)
        self.pending.add(joint, g.pos, g.normal, g.depth, r1, r2)

    def _stepped(self, dt: float) -> None:
        if abs(dt - self.dt) > 1e-12 * self.dt:
            raise AdapterError(f"rblog.adapters.ode: the world was stepped by {dt!r} s, the "
                               f"recorder's dt is {self.dt!r}")
        self._accumulate(self.pending)
        self.last, self.pending = self.pending, ContactFeedback()
        self.steps_seen += 1

    def state(self):
        """(position, quat_wxyz, velocity, angular_velocity) of the recorded bodies now."""
        return read_state(self.bodies, self.q_frame)

    def __call__(self, steps: int | None = None) -> None:
        """Log the state after the steps taken since the last call (``steps``: how many, when the
        world was stepped through a binding the recorder does not see) and the last one's contacts."""
        if steps is None:
            steps = self.steps_seen or 1
        if not self.steps_seen:  # stepped through a binding the recorder does not see
            if int(steps) != 1:
                raise AdapterError(f"rblog.adapters.ode: rec(steps={steps}) without the wrapped "
                                   "dWorldStep: the interval's impulses need every step seen")
            self._accumulate(self.pending)
        contacts = self.last if self.steps_seen else self.pending
        self.step += int(steps)
        self.stream.add(self.step, *self.state(), contacts.rows(self.dt, self.step), **self._interval())
        self.steps_seen = 0
        self.last = ContactFeedback()
        if contacts is self.pending:
            self.pending = ContactFeedback()

    record = __call__

    def flush(self) -> None:
        """Write the samples gathered so far."""
        self.stream.flush()

    def close(self, truncated: bool = False, reason: str | None = None) -> None:
        if self._wrap is not None:  # the world's step no longer records
            self._wrap.undo()
            self._wrap = None
        super().close(truncated=truncated, reason=reason)



__all__ = ["CONTACT_ROWS", "ContactFeedback", "OdeRecorder", "inspect", "principal", "read_state",
           "settings", "version"]
