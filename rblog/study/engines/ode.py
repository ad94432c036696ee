"""A scene in the Open Dynamics Engine (ODE, libode through ``odepy``): world, stepping, state and
contacts for the Recorder.

Translation (common part: rblog/study/engines/__init__.py):

* each body: ``dBodyCreate`` with ``dMassSetParameters`` (the scene's mass, centre of mass at the
  body origin as ODE requires, the principal moments on the diagonal: the body frame is the
  contract frame; ODE's ``dMassSetCapsule`` etc. are not used), one ``dCreateSphere``,
  ``dCreateBox``, ``dCreateCapsule``, ``dCreateCylinder`` or ``dCreateConvex`` geom on it with no
  offset, or a compound's parts, each such a geom at its pose in the body frame
  (``dGeomSetOffsetPosition`` / ``dGeomSetOffsetQuaternion``) (capsule and cylinder: ``radius`` and ``length`` = 2 half_length, the capsule's cylinder
  part, along the geom's z = the body's z; a hull: its face planes, vertices and polygons in the
  body frame), position,
  quaternion (w, x, y, z), velocity and the world-frame angular velocity ODE keeps. ODE's
  defaults otherwise: the gyroscopic torque on, taken semi-implicitly (Lacoursiere 2006, ODE's
  step.cpp: ``(I (I - dt [L]x)^-1 - 1) L / dt`` with ``L = I w`` and the inertia at the step's
  start), infinitesimal rotation update (``q += dt/2 (0, w) q``, normalized), no damping, no
  auto-disable. Constant
  force and torque: ``dBodyAddForce`` / ``dBodyAddTorque`` before every step (ODE clears them).
  The ground: ``dCreatePlane(n, offset)``; static boxes: box geoms without a body. All geoms in
  one ``dSimpleSpace`` (every pair's boxes tested, in C): libode 0.16.2's ``dHashSpace`` stops
  reporting a pair whose boxes overlap (samples/shapes.toml: a ball falls 0.11 m into the slope,
  a static box, at t = 0.3 s, while ``dCollide`` on the two geoms gives that depth).
* collisions: ``dSpaceCollide`` calls a near callback (Python) for every pair of geoms whose
  boxes overlap; pairs that cannot touch (two static geoms, different non-zero groups) are
  skipped, the others get up to ``max_contacts`` points from ``dCollide`` and one contact joint
  each, attached as ``dJointAttach(j, body(g1), body(g2))``. ``dCollide`` returns no points for
  a pair of geom classes it has no collider for (cylinder pairs need libode built with libccd):
  every pair of shapes that can touch is probed once (:func:`missing_colliders`) and a missing
  one exits 2 naming the two shapes.
* materials: ODE has no per-geom material: each contact's ``dSurfaceParameters`` are set in the
  near callback, so every pair gets rblog's effective values exactly, friction ``sqrt(mu_a
  mu_b)`` and restitution ``max(e_a, e_b)`` (the combine rule lives in the callback). Mode
  ``dContactApprox1``: the friction limit is ``mu`` times the contact's normal force (a
  coefficient, not ODE's default force bound), applied on two tangent directions each: a
  friction **pyramid** (up to sqrt(2) mu fn along a diagonal). ``dContactBounce`` with
  ``bounce = e`` above ``bounce_vel`` (default: rblog's derived restitution threshold for the
  scene's dt and accelerations, rblog.engine.constants.restitution_threshold).
* stepping: ``dWorldStep`` (the default, ``stepper=world``: a direct LCP solve per island, its
  cost cubic in the island's constraint rows) or ``dWorldQuickStep`` (``stepper=quick``: SOR
  iterations, ``iterations``, ``w``); ``erp`` and ``cfm`` are the world's (ODE's defaults unless
  given); the contact joints are emptied after each step. ``dWorldQuickStep`` shuffles its
  constraint order with ODE's global ``dRand``, seeded with the scene's seed (0 without one) when
  the run starts.
* state and contacts: read by :mod:`rblog.adapters.ode` (``read_state``, ``ContactFeedback``),
  the one translation of ODE's conventions. The logged step's contact joints carry a
  ``dJointFeedback``: ``f1 x dt`` is the impulse on the joint's first body; separation is
  ``-depth`` from ``dCollide`` before the step.
"""

from __future__ import annotations

import ctypes
import math

import numpy as np

from rblog.contract.model import GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_MESH, GEOM_NAMES, \
    GEOM_SPHERE
from rblog.study.engines import EngineMissing, EngineUnsupported, body_mesh, body_parts, geom_hull, \
    initial_world_omega, pair_materials, parse_options

#: contact points per geom pair from dCollide (a box on a face needs 4; 8 leaves room for edges)
DEFAULT_MAX_CONTACTS = 8

OPTIONS = {
    "stepper": "world (dWorldStep, default) or quick (dWorldQuickStep)",
    "iterations": "dWorldQuickStep iterations (ODE's default 20)",
    "w": "dWorldQuickStep SOR over-relaxation (ODE's default 1.3)",
    "erp": "world error reduction parameter (ODE's default 0.2)",
    "cfm": "world constraint force mixing (ODE's default 1e-10 in double precision)",
    "max_contacts": f"contact points per geom pair (default {DEFAULT_MAX_CONTACTS})",
    "surface_layer": "dWorldSetContactSurfaceLayer (m, default 0)",
    "max_correcting_vel": "dWorldSetContactMaxCorrectingVel (m/s, default infinite)",
    "bounce_vel": "no bounce below this approach speed (m/s, default rblog's restitution threshold)",
}
STEPPERS = ("world", "quick")


def _number(key: str, val: str, kind=float):
    try:
        x = kind(val)
    except ValueError:
        raise EngineUnsupported("ode", f"option {key}={val!r} (expected {'an integer' if kind is int else 'a number'})") from None
    if kind is float and not math.isfinite(x) and not (key == "max_correcting_vel" and x == math.inf):
        raise EngineUnsupported("ode", f"option {key}={val!r} (expected a finite number)")
    if x < 0 or (key in ("iterations", "max_contacts") and x < 1):
        raise EngineUnsupported("ode", f"option {key}={val!r} (expected a positive number)")
    return x


#: the probe's geoms (m): each overlaps the other at PROBE_POS_A / PROBE_POS_B
def create_convex(ode, space, vertices, faces, normals, offsets, keep: list):
    """dCreateConvex of a hull (vertices (V, 3), faces as index loops counter-clockwise about
    their outward normals (F, 3), n . x = offset on each): ODE keeps pointers to the three
    arrays, which are appended to ``keep`` (they must outlive the geom)."""
    planes = (ode.dReal * (4 * len(faces)))(*np.column_stack([normals, offsets]).ravel().tolist())
    points = (ode.dReal * (3 * len(vertices)))(*np.asarray(vertices, float).ravel().tolist())
    poly = [x for f in faces for x in (len(f), *map(int, f))]
    polygons = (ctypes.c_uint * len(poly))(*poly)
    keep.extend((planes, points, polygons))
    return ode.dCreateConvex(space, planes, len(faces), points, len(vertices), polygons)


#: a 0.2 m cube as a convex hull, for the probe (vertices, faces, normals, offsets)
_PROBE_HULL = (np.array([[x, y, z] for z in (-0.1, 0.1) for y in (-0.1, 0.1) for x in (-0.1, 0.1)]),
               [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]],
               np.array([[0, 0, -1], [0, 0, 1], [0, -1, 0], [0, 1, 0], [-1, 0, 0], [1, 0, 0]], float),
               np.full(6, 0.1))
_PROBE_KEEP: list = []

_PROBE_GEOMS = {"sphere": lambda ode, sp: ode.dCreateSphere(sp, 0.1),
                "box": lambda ode, sp: ode.dCreateBox(sp, 0.2, 0.2, 0.2),
                "capsule": lambda ode, sp: ode.dCreateCapsule(sp, 0.1, 0.4),
                "cylinder": lambda ode, sp: ode.dCreateCylinder(sp, 0.1, 0.4),
                "plane": lambda ode, sp: ode.dCreatePlane(sp, 0.0, 0.0, 1.0, 0.0),
                "mesh": lambda ode, sp: create_convex(ode, sp, *_PROBE_HULL, _PROBE_KEEP)}
PROBE_POS_A, PROBE_POS_B = (0.0, 0.0, 0.05), (0.05, 0.0, 0.1)


def missing_colliders(ode, pairs) -> list[tuple[str, str]]:
    """The shape pairs (names from _PROBE_GEOMS) dCollide has no collider for: two overlapping
    geoms (at PROBE_POS_A, PROBE_POS_B; a plane stays z = 0) give no point in either order."""
    space = ode.dSimpleSpaceCreate(None)
    buf = (ode.dContactGeom * 8)()
    out = []
    try:
        for a, b in pairs:
            ga, gb = _PROBE_GEOMS[a](ode, space), _PROBE_GEOMS[b](ode, space)
            for g, pos in ((ga, PROBE_POS_A), (gb, PROBE_POS_B)):
                if ode.dGeomGetClass(g) != ode.dPlaneClass:
                    ode.dGeomSetPosition(g, *pos)
            if max(ode.dCollide(ga, gb, 8, buf, ctypes.sizeof(ode.dContactGeom)),
                   ode.dCollide(gb, ga, 8, buf, ctypes.sizeof(ode.dContactGeom))) <= 0:
                out.append((a, b))
            ode.dGeomDestroy(ga)
            ode.dGeomDestroy(gb)
    finally:
        ode.dSpaceDestroy(space)
    return out


class OdeRun:
    """One scene in ODE: ``step(k)``, ``state()``, ``contacts(step)``, ``close()``."""

    #: frame of the angular velocity ``state()`` returns (dBodyGetAngularVel: world)
    OMEGA_FRAME = "world"

    def __init__(self, scene, dt: float, options=()):
        try:
            import odepy as ode
            from odepy.common import loadOde
        except Exception as e:  # noqa: BLE001 - the binding, or libode.so.8 behind it
            raise EngineMissing("ode", e, install='apt-get install libode8 and pip install -e ".[ode]"') from None
        from rblog.adapters.ode import ContactFeedback, settings, version
        from rblog.engine.constants import ContactParams

        self.ode, self.scene, self.dt = ode, scene, float(dt)
        self.version = version()
        opts = parse_options("ode", options, OPTIONS)
        self.stepper = opts.pop("stepper", "world")
        if self.stepper not in STEPPERS:
            raise EngineUnsupported("ode", f"stepper {self.stepper!r} (expected one of: {', '.join(STEPPERS)})")
        if self.stepper != "quick" and ({"iterations", "w"} & set(opts)):
            raise EngineUnsupported("ode", "options iterations/w without stepper=quick (dWorldStep has none)")
        model, st = scene.model, scene.state
        n = model.n_bodies
        parts = body_parts(model, "ode", (GEOM_SPHERE, GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER,
                                          GEOM_MESH))
        self._convex_arrays: list = []  # what ODE's convex geoms point into
        self.max_contacts = int(_number("max_contacts", opts.pop("max_contacts", DEFAULT_MAX_CONTACTS), int))
        accel = float(np.linalg.norm(model.gravity)) + float(np.max(
            np.linalg.norm(model.body_force_world, axis=1) / model.body_mass, initial=0.0))
        self.bounce_vel = (_number("bounce_vel", opts.pop("bounce_vel")) if "bounce_vel" in opts
                           else ContactParams().restitution_threshold_at(self.dt, accel))
        world_opts = {k: _number(k, opts.pop(k)) for k in ("erp", "cfm", "surface_layer",
                                                          "max_correcting_vel", "w") if k in opts}
        if "iterations" in opts:
            world_opts["iterations"] = _number("iterations", opts.pop("iterations"), int)
        ode.dInitODE2(0)
        # dWorldQuickStep reorders its constraints with ODE's one global generator: seeded per run,
        # a scene's run is the same in any process whatever ran before it
        self.rand_seed = int(scene.sim.seed or 0)
        ode.dRandSetSeed(self.rand_seed)
        self.world = ode.dWorldCreate()
        self.space = ode.dSimpleSpaceCreate(None)
        self.group = ode.dJointGroupCreate(0)
        w = self.world
        ode.dWorldSetGravity(w, *map(float, model.gravity))
        setters = {"erp": ode.dWorldSetERP, "cfm": ode.dWorldSetCFM,
                   "surface_layer": ode.dWorldSetContactSurfaceLayer,
                   "max_correcting_vel": ode.dWorldSetContactMaxCorrectingVel,
                   "iterations": ode.dWorldSetQuickStepNumIterations, "w": ode.dWorldSetQuickStepW}
        for k, v in world_opts.items():
            setters[k](w, v)
        # prototypes of the calls made per contact (odepy's dJointAttach builds one per call)
        self._attach = loadOde("dJointAttach", None, ode.dJointID, ode.dBodyID, ode.dBodyID)
        self._collide = ode.dCollide
        self._create = ode.dJointCreateContact
        w_world = initial_world_omega(scene)
        self.bodies, geoms = [], []
        for i in range(n):
            b = ode.dBodyCreate(w)
            m = ode.dMass()
            ode.dMassSetParameters(ctypes.byref(m), float(model.body_mass[i]), 0.0, 0.0, 0.0,
                                   *map(float, model.body_inertia_diag[i]), 0.0, 0.0, 0.0)
            ode.dBodySetMass(b, ctypes.byref(m))
            for code, size, pos, quat, gi in parts[i]:
                if code == GEOM_SPHERE:
                    g = ode.dCreateSphere(self.space, float(size[0]))
                elif code == GEOM_BOX:
                    g = ode.dCreateBox(self.space, *(2.0 * float(x) for x in size))
                elif code == GEOM_CAPSULE:  # length: the cylinder part, 2 h, along the geom's z
                    g = ode.dCreateCapsule(self.space, float(size[0]), 2.0 * float(size[1]))
                elif code == GEOM_MESH:  # dCreateConvex: the hull's planes, points and polygons
                    mesh = body_mesh(model, i) if len(parts[i]) == 1 else \
                        geom_hull(model, gi, model.body_name[i])
                    g = create_convex(ode, self.space, *mesh, self._convex_arrays)
                else:
                    g = ode.dCreateCylinder(self.space, float(size[0]), 2.0 * float(size[1]))
                ode.dGeomSetBody(g, b)
                if len(parts[i]) > 1:  # a compound's part at its pose in the body frame
                    ode.dGeomSetOffsetPosition(g, *map(float, pos))
                    ode.dGeomSetOffsetQuaternion(g, (ode.dQuaternion)(*map(float, quat)))
                geoms.append((g, i))
            ode.dBodySetPosition(b, *map(float, st.position[i]))
            q = st.quat_wxyz[i] / np.linalg.norm(st.quat_wxyz[i])
            ode.dBodySetQuaternion(b, (ode.dQuaternion)(*map(float, q)))
            ode.dBodySetLinearVel(b, *map(float, st.linear_momentum[i] / model.body_mass[i]))
            ode.dBodySetAngularVel(b, *map(float, w_world[i]))
            self.bodies.append(b)
        k = n  # the statics' feature index (pair_materials' items)
        if model.ground:
            nrm = np.asarray(model.ground_normal, float) / np.linalg.norm(model.ground_normal)
            geoms.append((ode.dCreatePlane(self.space, *map(float, nrm), float(model.ground_offset)), k))
            k += 1
        for j in range(len(model.static_box_position)):
            g = ode.dCreateBox(self.space, *(2.0 * float(x) for x in model.static_box_half_extents[j]))
            ode.dGeomSetPosition(g, *map(float, model.static_box_position[j]))
            q = model.static_box_quat_wxyz[j] / np.linalg.norm(model.static_box_quat_wxyz[j])
            ode.dGeomSetQuaternion(g, (ode.dQuaternion)(*map(float, q)))
            geoms.append((g, k))
            k += 1
        kinds, self.e_eff, self.mu_eff, self.can = pair_materials(model)
        self._check_colliders(kinds, [[c for c, *_ in body] for body in parts])
        # each geom's feature index + 1 in its user data (a compound's parts share their
        # body's: pair_materials' can[i, i] is false, so they never collide with each other)
        for g, k in geoms:
            ode.dGeomSetData(g, ctypes.c_void_p(k + 1))
        self._data = ode.dGeomGetData
        self.body_of = [self.bodies[k] if k < n else None for k in range(len(kinds))]
        self.n = n
        self.loaded = [(self.bodies[i], tuple(map(float, model.body_force_world[i])),
                        tuple(map(float, model.body_torque_world[i]))) for i in range(n)
                       if np.any(model.body_force_world[i] != 0) or np.any(model.body_torque_world[i] != 0)]
        self._contact_buf = (ode.dContact * self.max_contacts)()
        self._cptr = [ctypes.byref(c) for c in self._contact_buf]
        self._geom0 = ctypes.byref(self._contact_buf[0].geom)
        self._stride = ctypes.sizeof(ode.dContact)
        self._surface_of = None
        self.feedback = ContactFeedback()
        self.recording = False
        self._near = ode.dNearCallback(self._near_callback)
        self._step = ode.dWorldQuickStep if self.stepper == "quick" else ode.dWorldStep
        self.settings = {
            **settings(w, self.stepper),
            "timestep": self.dt, "max_contacts": self.max_contacts, "bounce_vel": self.bounce_vel,
            "surface_mode": "dContactApprox1 | dContactBounce (friction pyramid on two tangents, "
                            "limit mu * normal force)",
            "gyroscopic": "on (ODE's default: semi-implicit, (I (I - dt [L]x)^-1 - 1) L / dt, "
                          "inertia at the step's start)",
            "rotation_update": "infinitesimal (ODE's default: q += dt/2 (0, w) q, normalized)",
            "space": "dSimpleSpace", "rand_seed": self.rand_seed,
            "combine_native": "none (surface parameters per contact)",
            "material_translation": {"friction": "sqrt(mu_a mu_b) per contact",
                                     "restitution": "max(e_a, e_b) per contact"},
            "ignored_scene_tables": ["contact"] if scene.contact else [],
        }

    def _check_colliders(self, kinds, shapes) -> None:
        """Exit 2 naming the first pair of shapes that can touch and dCollide cannot collide
        (``shapes``: each body's GEOM_* codes, a compound's several)."""
        model = self.scene.model
        shape = [[GEOM_NAMES[c] for c in codes] for codes in shapes] + \
            [["plane" if k == "ground" else "box"] for k in kinds[len(shapes):]]
        label = [f"body {str(x)!r}" for x in model.body_name] + (["the ground"] if model.ground else []) \
            + [f"static box {j}" for j in range(len(model.static_box_position))]
        first = {}
        for i, j in zip(*np.nonzero(np.triu(self.can, 1))):
            for si in shape[i]:
                for sj in shape[j]:
                    first.setdefault(tuple(sorted((si, sj))), (int(i), int(j)))
        missing = missing_colliders(self.ode, list(first))
        if missing:
            i, j = first[missing[0]]
            self.close()
            raise EngineUnsupported("ode", f"{missing[0][0]}-{missing[0][1]} contact ({label[i]} and "
                                    f"{label[j]} can touch; {self.version} has no collider for "
                                    "the pair)")

    def _near_callback(self, _data, g1, g2) -> None:
        i, j = self._data(g1) - 1, self._data(g2) - 1
        if not self.can[i, j]:
            return
        # dCollide writes the points straight into the dContact array (stride sizeof(dContact)),
        # whose surfaces are rewritten only when the pair's material differs from the last one's
        k = self._collide(g1, g2, self.max_contacts, self._geom0, self._stride)
        if k <= 0:
            return
        mat = (float(self.mu_eff[i, j]), float(self.e_eff[i, j]))
        if mat != self._surface_of:
            mode = self.ode.dContactApprox1 | (self.ode.dContactBounce if mat[1] > 0 else 0)
            for c in self._contact_buf:
                c.surface.mode, c.surface.mu, c.surface.bounce = mode, mat[0], mat[1]
                c.surface.bounce_vel = self.bounce_vel
            self._surface_of = mat
        b1, b2 = self.body_of[i], self.body_of[j]
        for p in range(k):
            jt = self._create(self.world, self.group, self._cptr[p])
            self._attach(jt, b1, b2)
            if self.recording:
                g = self._contact_buf[p].geom
                self.feedback.add(jt, g.pos, g.normal, g.depth, i if i < self.n else -1,
                                  j if j < self.n else -1)

    def step(self, k: int) -> None:
        ode = self.ode
        for s in range(int(k)):
            self.recording = s == k - 1  # feedback on the logged step's contacts only
            if self.recording:
                self.feedback.clear()
            for b, f, t in self.loaded:
                ode.dBodyAddForce(b, *f)
                ode.dBodyAddTorque(b, *t)
            ode.dSpaceCollide(self.space, None, self._near)
            if not self._step(self.world, self.dt):
                raise EngineUnsupported("ode", f"the step ({self.settings['integrator']} failed: out of memory)")
            ode.dJointGroupEmpty(self.group)
        self.recording = False

    def state(self):
        """(position, quat_wxyz, velocity, angular velocity), world frame: the translation of
        rblog.adapters.ode (the body frames are the contract frames here)."""
        from rblog.adapters.ode import read_state

        return read_state(self.bodies)

    def contacts(self, step: int):
        """The contacts of the step that ended at ``step`` (rblog.adapters.ode's rows)."""
        return self.feedback.rows(self.dt, step)

    def close(self):
        ode = self.ode
        if getattr(self, "world", None) is not None:
            ode.dJointGroupDestroy(self.group)
            ode.dSpaceDestroy(self.space)
            ode.dWorldDestroy(self.world)
            self.world = None
