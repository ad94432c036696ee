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
  that is the order the geoms were created in. ``bodies=`` gives the list and order explicitly. Kinematic bodies and bodies on joints other than contacts are refused
  (:class:`~rblog.adapters.AdapterError`, naming the joint type): the contract holds free rigid
  bodies and static geometry only.
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
"""

from __future__ import annotations

import ctypes

import numpy as np

from rblog.adapters import AdapterError, require
from rblog.adapters._common import SampleStream, body_frame, quat_mul
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE, Model
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


def _ode():
    return require("odepy", extra="ode")


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
    """The body table of an ODE world: (Model, bodies (list of dBodyID), q_frame (N, 4), notes).

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
        other = sorted({JOINT_TYPE_NAMES.get(t, str(t)) for t in _joint_types(b) if t != CONTACT_JOINT})
        if other:
            raise AdapterError(f"rblog.adapters.ode: body {i} is on a {', '.join(other)} joint: the "
                               "contract records free rigid bodies and static geometry only")
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
        static_box_restitution=np.full(nsb, g_e), static_box_friction=np.full(nsb, g_mu))
    return model, list(bodies), np.array(q_frames).reshape(n, 4), {"static_geoms_not_in_the_table": other}


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


class OdeRecorder:
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
        rrd, mcap, keep, writer, **recorder_options: as :class:`rblog.record.Recorder`.

    The state now is sample 0 (step 0, or ``start_step``)."""

    def __init__(self, world, space, *, dt: float, rrd=None, mcap=None, bodies=None, names=None,
                 friction=np.nan, restitution=np.nan, ground_friction=None, ground_restitution=None,
                 combine_friction: str = "max", combine_restitution: str = "max",
                 writer: str | None = None, keep: bool | None = None, start_step: int = 0,
                 block: int | None = None, stepper: str = "world", **recorder_options):
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
        engine = {**settings(world, stepper), **notes}
        self.recorder = Recorder(self.model, rrd=rrd, mcap=mcap, dt=self.dt,
                                 writer=writer or f"ode {engine['version']} via rblog.adapters",
                                 integrator=engine["integrator"], combine_friction=combine_friction,
                                 combine_restitution=combine_restitution, engine_settings=engine,
                                 keep=keep, **recorder_options)
        self.recorder.open()
        self.stream = SampleStream(self.recorder, **({} if block is None else {"block": block}))
        self.step = int(start_step)
        self.pending, self.last = ContactFeedback(), ContactFeedback()
        self.steps_seen = 0
        self.stream.add(self.step, *self.state())
        self._wrap = _Wrap(self)

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
        contacts = self.last if self.steps_seen else self.pending
        self.step += int(steps)
        self.stream.add(self.step, *self.state(), contacts.rows(self.dt, self.step))
        self.steps_seen = 0
        self.last = ContactFeedback()
        if contacts is self.pending:
            self.pending = ContactFeedback()

    record = __call__

    def close(self, truncated: bool = False, reason: str | None = None) -> None:
        if self._wrap is not None:
            self._wrap.undo()
            self._wrap = None
        try:
            if not truncated:
                self.stream.flush()
        finally:
            self.recorder.close(truncated=truncated, reason=reason)

    def __enter__(self) -> "OdeRecorder":
        return self

    def __exit__(self, exc_type, exc, tb):
        self.close(truncated=exc_type is not None, reason=None if exc is None else str(exc))

    @property
    def trajectory(self):
        self.stream.flush()
        return self.recorder.trajectory


__all__ = ["CONTACT_ROWS", "ContactFeedback", "OdeRecorder", "inspect", "principal", "read_state",
           "settings", "version"]
