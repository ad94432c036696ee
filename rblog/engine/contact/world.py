"""ContactWorld: the simulator's entry point for scenes whose bodies can touch.

Usage (the simulator calls this in blocks, like ``free.advance_free``)::

    world = ContactWorld(model, ContactParams(), rotation.METHOD_SPLITTING, rotation.ORTHO_NORMALIZE)
    for stage, why in world.explain():
        print(f"{stage:32s} {why}")
    n_samples, bad_step, bad_body, contacts = world.advance(
        dt, n_steps, stride, sample_last,
        position, linear_momentum, quat_wxyz, rotation, angular_momentum,   # state, in place
        out_position, out_linear_momentum, out_quat_wxyz, out_rotation, out_angular_momentum)

The world keeps what must survive between calls: last step's manifolds and impulses (warm
starting) and the sleep state. Stages a scene does not need are chosen away once, here:

* no gravity, force or torque: no kick stage;
* nothing can ever touch (no ground, no static box, and no two bodies whose groups collide): no
  contact stages at all, the free-body kernel ``free.advance_free`` runs instead;
* isotropic inertia (spheres, cubes): the solver uses the scalar 1/I, no R diag(1/I) R^T;
* sleeping (``params.sleep``): resting islands cost nothing until touched.

``force_all_stages=True`` turns every shortcut off (benchmarks measure what they save).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from rblog.engine.constants import ISOTROPIC_RTOL, RESTITUTION_THRESHOLD_KICKS
from rblog.engine import hull
from rblog.errors import RblogError
from rblog.engine.free import advance_free
from rblog.engine.state import new_anchors
from rblog.contract.model import SHAPE_NONE, Model
from rblog.engine.rotation import quat_to_matrix_np
from rblog.contract.trajectory import Contacts
from rblog.engine.contact.broadphase import static_box_aabbs
from rblog.engine.contact.manifold import log_rows
from rblog.engine.contact.narrowphase import (
    CONTRACT_TO_GEOM, GEOM_BOX, GEOM_HULL, GEOM_NAMES, GEOM_PLANE, NARROWPHASE_TABLE, SHAPE_TO_GEOM,
    UnsupportedShapePair,
)
from rblog.engine.constants import ContactParams
from rblog.engine.contact.step import (
    N_STATS, Bodies, BodyState, ContactCache, Settings, SleepState, Statics, solver_constants,
    world_advance,
)


class EngineGeoms(NamedTuple):
    """The bodies' geoms as the engine reads them (G rows each; step.Bodies' geom fields)."""

    code: np.ndarray    # (G,) int64 engine GEOM_* code
    size: np.ndarray    # (G, 3) m (a hull's row: its id in the C++ core's hull table)
    body: np.ndarray    # (G,) int64 owner body
    offset: np.ndarray  # (G,) int64 1: at pos / rot in the body, 0: the body's frame
    pos: np.ndarray     # (G, 3) body frame, m
    rot: np.ndarray     # (G, 3, 3) geom -> body
    radius: np.ndarray  # (G,) farthest point from the body's centre of mass, m


#: a geom whose position is zero and whose quaternion is within this of +-1 in w sits in its
#: body's frame (the engine reads the body's rows for it)
GEOM_IDENTITY_TOL = 1e-12


def engine_geoms(model: Model) -> EngineGeoms:
    """The engine's geom table of the bodies, body by body: a sphere or box body (body_shape)
    one geom in its frame; any other (SHAPE_NONE) its geoms of the model's geom table, in table
    order, each at its pose in the body (a compound body has several; a geom at the centre of
    mass with the body's axes is in the body's frame). Raises UnsupportedShapePair for a body the
    engine cannot simulate (no geoms, or a geom type without an engine shape)."""
    from rblog.contract.model import geom_bounding_radius

    n = model.n_bodies
    body_size = np.asarray(model.body_size, float).reshape(n, 3)
    bradius = np.asarray(model.body_bounding_radius, float).reshape(n)
    gb = np.asarray(model.geom_body, np.int64)
    rows_of: dict[int, list[int]] = {}
    for g in np.flatnonzero(gb >= 0).tolist():
        rows_of.setdefault(int(gb[g]), []).append(g)
    code, size, body, offset, pos, rot, radius = [], [], [], [], [], [], []
    for i, shape in enumerate(np.asarray(model.body_shape).tolist()):
        if shape in SHAPE_TO_GEOM:
            code.append(SHAPE_TO_GEOM[shape])
            size.append(body_size[i])
            body.append(i)
            offset.append(0)
            pos.append(np.zeros(3))
            rot.append(np.eye(3))
            radius.append(bradius[i])
            continue
        rows = rows_of.get(i, []) if shape == SHAPE_NONE else []
        if not rows or any(int(model.geom_type[g]) not in CONTRACT_TO_GEOM for g in rows):
            raise UnsupportedShapePair(shape, shape, f"body {i} ({model.body_name[i]!r}: "
                                       f"{len(rows)} geom(s), expected one or more of sphere, "
                                       "box, capsule, cylinder, mesh)")
        for g in rows:
            t = CONTRACT_TO_GEOM[int(model.geom_type[g])]
            p = np.asarray(model.geom_pos_body[g], float)
            q = np.asarray(model.geom_quat_wxyz_body[g], float)
            centred = not np.any(p) and abs(abs(float(q[0])) - 1.0) <= GEOM_IDENTITY_TOL
            sz = np.asarray(model.geom_size[g], float).copy()
            if t == GEOM_HULL:  # its id in the C++ core's hull table
                def fail(e, i=i):
                    raise RblogError(f"body {i} ({model.body_name[i]!r}): its mesh geom: {e}")
                sz = np.array([hull.register(model.geom_vertices(g), fail), 0.0, 0.0])
            code.append(t)
            size.append(sz)
            body.append(i)
            offset.append(0 if centred else 1)
            pos.append(np.zeros(3) if centred else p)
            rot.append(np.eye(3) if centred else quat_to_matrix_np((q / np.linalg.norm(q))[None])[0])
            radius.append(float(np.linalg.norm(p)) + geom_bounding_radius(
                int(model.geom_type[g]), model.geom_size[g], model.geom_vertices(g)))
    G = len(code)
    return EngineGeoms(
        code=np.asarray(code, np.int64).reshape(G), size=np.ascontiguousarray(np.reshape(size, (G, 3)), dtype=float),
        body=np.asarray(body, np.int64).reshape(G), offset=np.asarray(offset, np.int64).reshape(G),
        pos=np.ascontiguousarray(np.reshape(pos, (G, 3)), dtype=float),
        rot=np.ascontiguousarray(np.reshape(rot, (G, 3, 3)), dtype=float),
        radius=np.ascontiguousarray(np.asarray(radius, float).reshape(G)))


class _Impulses(NamedTuple):
    acc: np.ndarray     # (N, 6) contact impulse since the last sample (linear, angular)
    start: np.ndarray   # (N, 6) momenta after the step's kick
    kicked: np.ndarray  # (N,) int64 awake at the kick
    out: np.ndarray     # (S, N, 6) the call's sample buffer


class ContactWorld:
    """Rigid bodies with contacts (see the module docstring).

    Args:
        model: the fixed scene (shapes, masses, materials, ground, static boxes, groups).
        params: contact settings (``ContactParams()`` for the defaults).
        method, ortho: rotation.METHOD_* / ORTHO_* codes of the run's integrator.
        force_all_stages: run every stage even when the scene does not need it.
    """

    def __init__(self, model: Model, params: ContactParams | None = None, method: int = 2,
                 ortho: int = 3, force_all_stages: bool = False):
        self.model = model
        self.params = params if params is not None else ContactParams()
        self.params.validate()
        self.method = int(method)
        self.ortho = int(ortho)
        self.force_all_stages = bool(force_all_stages)
        n = model.n_bodies
        self.n_bodies = n
        p = self.params

        geoms = engine_geoms(model)
        geom = geoms.code
        mass = np.asarray(model.body_mass, float).reshape(n)
        inertia = np.ascontiguousarray(np.asarray(model.body_inertia_diag, float).reshape(n, 3))
        inv_inertia = 1.0 / inertia
        radius = np.ascontiguousarray(model.body_bounding_radius, dtype=float)
        iso = (np.abs(inertia - inertia[:, :1]) <= ISOTROPIC_RTOL * inertia[:, :1]).all(axis=1)
        gravity = np.asarray(model.gravity, float).reshape(3)
        f_ext = np.asarray(model.body_force_world, float).reshape(n, 3)
        torque = np.ascontiguousarray(np.asarray(model.body_torque_world, float).reshape(n, 3))
        force = np.ascontiguousarray(mass[:, None] * gravity[None, :] + f_ext)
        accel = np.ascontiguousarray(force / mass[:, None])
        group = np.asarray(model.body_group, np.int64).reshape(n)

        # static geometry
        sb_pos = np.ascontiguousarray(np.asarray(model.static_box_position, float).reshape(-1, 3))
        n_static = len(sb_pos)
        sb_quat = np.asarray(model.static_box_quat_wxyz, float).reshape(-1, 4)
        sb_rot = np.ascontiguousarray(quat_to_matrix_np(sb_quat / np.linalg.norm(
            sb_quat, axis=1, keepdims=True)) if n_static else np.zeros((0, 3, 3)))
        sb_ext = np.ascontiguousarray(np.asarray(model.static_box_half_extents, float).reshape(-1, 3))
        sb_lo, sb_hi = static_box_aabbs(sb_pos, sb_rot, sb_ext, p.speculative_distance)
        gn = np.asarray(model.ground_normal, float).reshape(3)
        gn = gn / np.linalg.norm(gn)

        #: largest external acceleration |g + F/m| over the bodies (m/s^2): the velocity a step's
        #: kick adds is at most accel_max dt (the derived restitution threshold)
        self.accel_max = float(np.linalg.norm(accel, axis=1).max()) if n else 0.0
        # which stages this scene needs, and why (explain())
        self._explain: list[tuple[str, str]] = []
        geoms_present = sorted(set(geom.tolist()))
        pairs_possible = self._body_pairs_possible(group)
        self.contacts_possible = bool(model.ground) or n_static > 0 or pairs_possible
        self._check_pairs(geoms_present, pairs_possible, bool(model.ground), n_static)
        forces = bool(np.any(force != 0.0) or np.any(torque != 0.0))
        self.do_kick = forces or force_all_stages
        self.use_contacts = self.contacts_possible or force_all_stages
        iso_shortcut = not force_all_stages
        self.do_sleep = bool(p.sleep) and self.use_contacts and not force_all_stages
        self._explain_stages(n, geom, iso, gravity, f_ext, torque, forces, pairs_possible,
                             n_static, group)

        self._bodies = Bodies(geom, geoms.size, geoms.body, geoms.offset, geoms.pos, geoms.rot,
                              geoms.radius, np.ascontiguousarray(radius), 1.0 / mass, inertia,
                              inv_inertia, iso.astype(np.int64), force, torque, accel,
                              np.asarray(model.body_restitution, float).reshape(n).copy(),
                              np.asarray(model.body_friction, float).reshape(n).copy(), group)
        self._statics = Statics(
            n_static, sb_pos, sb_rot, sb_ext,
            np.asarray(model.static_box_restitution, float).reshape(n_static).copy(),
            np.asarray(model.static_box_friction, float).reshape(n_static).copy(),
            np.ascontiguousarray(sb_lo), np.ascontiguousarray(sb_hi), bool(model.ground), gn,
            float(model.ground_offset), float(model.ground_restitution),
            float(model.ground_friction))
        self._settings = Settings(
            do_kick=self.do_kick, do_sleep=self.do_sleep, iso_shortcut=iso_shortcut,
            velocity_iterations=int(p.velocity_iterations),
            max_velocity_iterations=int(max(p.max_velocity_iterations, p.velocity_iterations)),
            velocity_tolerance=float(p.velocity_tolerance),
            over_relaxation=float(p.over_relaxation),
            position_iterations=int(p.position_iterations),
            allowed_penetration=float(p.allowed_penetration),
            position_correction_rate=float(p.position_correction_rate),
            max_correction_speed=float(p.max_correction_speed),
            speculative_distance=float(p.speculative_distance),
            restitution_threshold=-1.0,  # set per dt by settings_at
            friction_anchor_distance=float(p.friction_anchor_distance),
            sleep_speed=float(p.sleep_speed), sleep_time=float(p.sleep_time),
            warm_starting=bool(p.warm_starting),
            projection_iterations=int(p.projection_iterations),
            projection_depth=float(p.projection_depth),
            static_friction_anchors=bool(p.static_friction_anchors),
            exact_contact_motion=bool(p.exact_contact_motion), **solver_constants(),
            soft_step=p.solver == "soft_step", substeps=int(p.substeps),
            contact_hertz=float("inf") if p.contact_hertz is None else float(p.contact_hertz),
            contact_damping_ratio=float(p.contact_damping_ratio))
        # the free-body kernel's inputs, for scenes where nothing can touch
        self._inv_mass = 1.0 / mass
        self._inv_inertia = inv_inertia

        # state kept between calls
        self._sleep = SleepState(np.ones(n, np.int64), np.zeros(n), np.full(n, -1, np.int64),
                                 np.zeros(1, np.int64))
        self.awake = self._sleep.awake
        cap = max(16, 4 * n)
        #: the C++ step's cache (step.ContactCache): last step's manifolds and the work arrays
        self._cache = ContactCache(cap, 4 * cap)
        #: counters accumulated over all calls: steps with awake bodies, candidate pairs,
        #: manifolds, points, awake body-steps, impact points, islands woken, bodies put to sleep,
        #: velocity sweeps, points pushed out by the project stage
        self.stats = np.zeros(N_STATS, np.int64)
        # the per-interval contact impulses' running sums (impulses.cpp), kept across calls
        self._impulses = _Impulses(acc=np.zeros((n, 6)), start=np.zeros((n, 6)),
                                   kicked=np.zeros(n, np.int64), out=np.zeros((0, n, 6)))
        #: cycle counts per stage (profile.STAGES) when profiled (profile.Profile.ticks handed
        #: in by the run loop), else empty: the step then reads no clock
        self.profile_ticks = np.zeros(0, np.int64)

    # ---- set-up helpers ---------------------------------------------------------------------

    @staticmethod
    def _body_pairs_possible(group: np.ndarray) -> bool:
        """Can any two bodies collide? Group 0 meets everyone; equal non-zero groups meet."""
        if len(group) < 2:
            return False
        nz = group[group != 0]
        if len(nz) < len(group):  # someone is in group 0
            return True
        return len(np.unique(nz)) < len(nz)

    def _check_pairs(self, geoms, pairs_possible, ground, n_static):
        needed = set()
        if pairs_possible:
            needed |= {(a, b) for a in geoms for b in geoms}
        if ground:
            needed |= {(a, GEOM_PLANE) for a in geoms}
        if n_static:
            needed |= {(a, GEOM_BOX) for a in geoms}
        for a, b in sorted(needed):
            key = (min(a, b), max(a, b))
            if key not in NARROWPHASE_TABLE:
                raise UnsupportedShapePair(a, b, "scene")

    def _explain_stages(self, n, geom, iso, gravity, f_ext, torque, forces, pairs_possible,
                        n_static, group):
        e = self._explain
        p = self.params
        if self.do_kick:
            why = (f"g = ({gravity[0]:g}, {gravity[1]:g}, {gravity[2]:g}) m/s^2"
                   + (", applied forces" if np.any(f_ext) else "")
                   + (", applied torques" if np.any(torque) else ""))
            if not forces:
                why = "forced on (no gravity, force or torque in the scene)"
            e.append(("kick (external forces)", why))
        else:
            e.append(("kick (external forces): skipped", "no gravity, applied force or torque"))
        if not self.use_contacts:
            e.append(("contacts: none possible",
                      "no ground, no static box, and no two bodies whose groups collide; "
                      "runs the free-body kernel advance_free"))
            return
        statics = []
        if self.model.ground:
            statics.append("ground plane")
        if n_static:
            statics.append(f"{n_static} static box(es)")
        groups = sorted(set(group.tolist()))
        e.append(("broadphase: sort-and-sweep",
                  f"{n} dynamic bodies + {n_static} static boxes, swept AABBs; "
                  + ("body pairs possible" if pairs_possible else "no two bodies can collide")
                  + (f", groups {groups}" if groups != [0] else "")
                  + ("; " + " and ".join(statics) if statics else "")))
        used = set()
        geoms = sorted(set(geom.tolist()))
        if pairs_possible:
            used |= {(min(a, b), max(a, b)) for a in geoms for b in geoms}
        if self.model.ground:
            used |= {(a, GEOM_PLANE) for a in geoms}
        if n_static:
            used |= {(min(a, GEOM_BOX), max(a, GEOM_BOX)) for a in geoms}
        names = ", ".join(NARROWPHASE_TABLE[k][1] for k in sorted(used))
        e.append(("narrowphase: table dispatch", names or "none"))
        if self.force_all_stages:
            e.append(("inertia: full R diag(1/I) R^T", "forced on"))
        elif iso.all():
            kind = "spheres" if (geom == 0).all() else "spheres or cubes"
            e.append(("isotropic shortcut", f"all bodies are {kind}: scalar 1/I, no transform"))
        elif iso.any():
            e.append(("isotropic shortcut", f"{int(iso.sum())} of {n} bodies isotropic"))
        else:
            e.append(("inertia: R diag(1/I) R^T per body", "no body has isotropic inertia"))
        if p.solver == "soft_step":
            cap = "a quarter of the substep rate" if p.contact_hertz is None else (
                f"min({p.contact_hertz:g} Hz, a quarter of the substep rate)")
            e.append(("solve: soft step (Box2D v3)",
                      (f"{p.substeps} substeps of dt / {p.substeps}" if p.max_substep is None
                       else f"max({p.substeps}, ceil(dt / {p.max_substep:g} s)) substeps")
                      + f", each a warm start, one soft "
                      f"sweep (contact springs of {cap}, damping ratio "
                      f"{p.contact_damping_ratio:g}, push-out <= {p.max_correction_speed:g} m/s), "
                      f"the positions moved, one rigid relax sweep; Coulomb friction "
                      f"sqrt(mu_a mu_b), speculative distance {p.speculative_distance:g} m + "
                      f"relative motion per step"))
        else:
            self._explain_pgs(e, p)
        if p.restitution_threshold is None:
            above = (f"{RESTITUTION_THRESHOLD_KICKS:g} |a| dt + {p.velocity_tolerance:g} m/s "
                     f"(|a| = {self.accel_max:g} m/s^2)")
        else:
            above = f"{p.restitution_threshold:g} m/s (the scene's)"
        e.append(("restitution", f"max(e_a, e_b), impacts above {above}, rebound from the "
                                 "flight energy"))
        if p.projection_iterations > 0:
            e.append(("project: nonlinear Gauss-Seidel",
                      f"narrowphase at the end-of-step poses; points deeper than "
                      f"{p.projection_depth:g} m pushed out to it, {p.projection_iterations} sweeps"))
        else:
            e.append(("project: skipped", "projection_iterations = 0"))
        if self.do_sleep:
            e.append(("sleeping", f"islands below {p.sleep_speed:g} m/s for {p.sleep_time:g} s"))
        elif self.force_all_stages:
            e.append(("sleeping: off", "forced: every body is simulated every step"))
        else:
            e.append(("sleeping: off", "contact.sleep = false"))

    @staticmethod
    def _explain_pgs(e, p):
        """explain()'s rows of the projected Gauss-Seidel solve and its relax stage."""
        e.append(("solve: sequential impulses",
                  f"{p.velocity_iterations} to {p.max_velocity_iterations} sweeps (until the "
                  f"largest correction < {p.velocity_tolerance:g} m/s), normal impulses "
                  f"over-relaxed x{p.over_relaxation:g} where bodies touch more than one "
                  f"thing, Coulomb friction sqrt(mu_a mu_b), "
                  f"warm starting {'on' if p.warm_starting else 'off'}, speculative "
                  f"distance {p.speculative_distance:g} m + relative motion per step"))
        if p.position_iterations > 0:
            e.append(("relax: split impulses",
                      f"{p.position_iterations} sweeps on pseudo velocities, slop "
                      f"{p.allowed_penetration:g} m, rate {p.position_correction_rate:g}"))
        else:
            e.append(("relax: skipped", "position_iterations = 0"))

    # ---- API --------------------------------------------------------------------------------

    def explain(self) -> list[tuple[str, str]]:
        """Stages chosen for this scene, and why, in step order."""
        return list(self._explain)

    def advance(self, dt, n_steps, stride, sample_last,
                position, linear_momentum, quat_wxyz, rotation, angular_momentum,
                out_position, out_linear_momentum, out_quat_wxyz, out_rotation,
                out_angular_momentum, anchors=None, out_impulses=None):
        """Advance ``n_steps`` steps; same arguments and sampling rule as free.advance_free.

        Args:
            dt: step (s). n_steps: steps in this call. stride: sample after every stride-th
                step; sample_last: also after the last step.
            position (N,3), linear_momentum (N,3), quat_wxyz (N,4), rotation (N,3,3),
                angular_momentum (N,3, world): the state, updated in place.
            out_*: (S, N, ...) sample buffers, S >= n_steps // stride + sample_last.
            anchors: the exact integrators' flow anchors (rblog.engine.state.FlowAnchors,
                updated in place; the run's State.anchors), None: for this call only.
            out_impulses: (S, N, 6) sample buffer of the per-interval contact impulses (linear
                N s, angular about the COM N m s, world; the log's impulse_contact_*): what the
                contact stages gave each body over the steps since the previous sample (of this
                world: the sum runs on across calls; csrc/engine/impulses.cpp), or None.

        Returns (n_samples, bad_step, bad_body, contacts). bad_step is the first local step
        (1-based) at which a body's state became non-finite (the call stops there), else -1.
        ``contacts`` holds, for each sampled step, every contact point that pushed (normal
        impulse > 0) or touches (separation <= 0), including the resting contacts of sleeping
        bodies: ``step`` is the local 1-based step index within this call, ``t`` is left 0,
        ``separation`` is the gap at the end of the step (narrowphase gap advanced by the gap
        velocity), ``point`` and ``normal`` are the narrowphase's at the start of the step,
        ``normal_impulse`` the step's total on body_a (restitution included) and
        ``friction_impulse`` the world friction impulse on body_a; ``kind`` is CONTACT_IMPACT
        when the approach speed exceeded the restitution threshold (restitution_threshold(dt)).

        Keep one ContactWorld for a whole run: it carries the impulses (warm starting) and the
        sleep state from one call to the next."""
        if anchors is None:
            anchors = new_anchors(position.shape[0])
        if out_impulses is not None and not self.use_contacts:
            out_impulses[...] = 0.0  # nothing can touch
        if not self.use_contacts:
            ns, bad_step, bad_body = advance_free(
                self.method, self.ortho, float(dt), int(n_steps), int(stride), bool(sample_last),
                self._inv_mass, self._inv_inertia, self._bodies.force, self._bodies.torque,
                position, linear_momentum, quat_wxyz, rotation, angular_momentum,
                out_position, out_linear_momentum, out_quat_wxyz, out_rotation,
                out_angular_momentum, anchors=anchors)
            return int(ns), int(bad_step), int(bad_body), Contacts.empty()
        res = world_advance(
            self._bodies, self._statics, self.settings_at(dt), self.method, self.ortho, float(dt),
            int(n_steps), int(stride), bool(sample_last),
            BodyState(position, linear_momentum, quat_wxyz, rotation, angular_momentum),
            BodyState(out_position, out_linear_momentum, out_quat_wxyz, out_rotation,
                      out_angular_momentum),
            self._sleep, self._cache, self.stats, self.profile_ticks, anchors,
            None if out_impulses is None else self._impulses._replace(out=out_impulses))
        n_samples, bad_step, bad_body, log_i, log_f = res
        ids, val = log_rows(log_i, log_f)
        contacts = Contacts(
            step=ids["step"].copy(), t=np.zeros(len(ids)), body_a=ids["a"].copy(),
            body_b=ids["b"].copy(), point=val["point"].copy(), normal=val["normal"].copy(),
            separation=val["separation"].copy(), normal_impulse=val["normal_impulse"].copy(),
            friction_impulse=val["friction"].copy(), kind=ids["kind"].astype(np.int8))
        return int(n_samples), int(bad_step), int(bad_body), contacts

    def restitution_threshold(self, dt: float) -> float:
        """The approach speed (m/s) above which an impact bounces in a step of ``dt`` (s): the
        scene's ``[contact] restitution_threshold`` if given, else derived from the step
        (constants.restitution_threshold)."""
        return self.params.restitution_threshold_at(float(dt), self.accel_max)

    def settings_at(self, dt: float):
        """The Settings record for steps of ``dt`` (s): the restitution threshold depends on it,
        and the soft step's substeps (ContactParams.substeps_at)."""
        threshold = self.restitution_threshold(dt)
        if self._settings.restitution_threshold != threshold:
            self._settings = self._settings._replace(restitution_threshold=threshold)
        sub = self.params.substeps_at(float(dt))
        if self._settings.substeps != sub:
            self._settings = self._settings._replace(substeps=sub)
        return self._settings

    @property
    def records(self):
        """The model records the compiled step reads: (Bodies, Statics, Settings); the
        Settings' restitution threshold is the last step's (see settings_at)."""
        return self._bodies, self._statics, self._settings

    @property
    def n_awake(self) -> int:
        return int(self.awake.sum())

    def describe_table(self) -> list[tuple[str, str, str]]:
        """The narrowphase table: (shape, shape, collider)."""
        return [(GEOM_NAMES[a], GEOM_NAMES[b], name) for (a, b), (_, name) in NARROWPHASE_TABLE.items()]


