"""Choose, once and up front, the stages a scene needs (and say why).

A scene where nothing can ever touch runs the free-body kernel: no broadphase, no narrowphase, no
solver. "Can touch" is decided conservatively: any ground plane or static box means contacts; for
free bodies, each body's bounding sphere is swept along its exact constant-acceleration path over
the run, and contacts are planned only when two swept boxes (of bodies allowed to collide) overlap.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rblog.contract.model import Model
from rblog.engine.scene import Scene


@dataclass
class Plan:
    """The stages of a run: ``stages`` is a list of (stage, why) in execution order."""

    stages: list[tuple[str, str]] = field(default_factory=list)
    contacts: bool = False
    scene: Scene | None = None
    force_all: bool = False
    _world: object = None
    #: one-line warnings found while planning (bodies that start overlapping)
    warnings: list[str] = field(default_factory=list)

    def make_contact_world(self, method: int, ortho: int):
        from rblog.engine.constants import ContactParams
        from rblog.engine.contact.world import ContactWorld

        params = ContactParams.from_dict(self.scene.contact)  # validated by the scene loader
        self._world = ContactWorld(self.scene.model, params, method, ortho,
                                   force_all_stages=self.force_all)
        self.stages = [("integrate", self.stages[0][1]), *self._world.explain()]
        self.warnings = initial_overlap_warnings(self.scene, method, ortho)
        return self._world


def initial_overlap_warnings(scene: Scene, method: int, ortho: int) -> list[str]:
    """Warnings for bodies that start interpenetrating (body-body, body-ground, body-static box)
    deeper than OVERLAP_WARN_DEPTH_M, naming the pairs and depths (deepest first).

    Candidates are the pairs whose bounding spheres overlap (at most OVERLAP_CHECK_MAX_PAIRS);
    each is measured with the contact narrowphase on a model of just that pair."""
    from dataclasses import replace

    from rblog.engine.constants import (ContactParams, OVERLAP_CHECK_MAX_PAIRS,
                                        OVERLAP_WARN_DEPTH_M)
    from rblog.engine.contact.measure import separations
    from rblog.engine.contact.world import ContactWorld

    m, st = scene.model, scene.state
    x, rot = st.position, st.rotation
    r = m.body_bounding_radius
    n = m.n_bodies
    cands: list[tuple[int, str, int]] = []  # (body, kind, other)
    if m.ground:
        gn = np.asarray(m.ground_normal, float)
        for i in np.nonzero(x @ gn - m.ground_offset < r)[0]:
            cands.append((int(i), "ground", -1))
    for k, c in enumerate(np.asarray(m.static_box_position, float).reshape(-1, 3)):
        rk = float(np.linalg.norm(m.static_box_half_extents[k]))
        for i in np.nonzero(np.linalg.norm(x - c, axis=1) < r + rk)[0]:
            cands.append((int(i), "static", k))
    if n >= 2:
        order = np.argsort(x[:, 0] - r)
        for a in range(n):
            i = order[a]
            for b in range(a + 1, n):
                j = order[b]
                if x[j, 0] - r[j] > x[i, 0] + r[i]:
                    break
                gi, gj = m.body_group[i], m.body_group[j]
                if gi != 0 and gj != 0 and gi != gj:
                    continue
                if np.linalg.norm(x[i] - x[j]) < r[i] + r[j]:
                    cands.append((int(min(i, j)), "body", int(max(i, j))))
    found = []
    for i, kind, o in cands[:OVERLAP_CHECK_MAX_PAIRS]:
        idx = [i] if kind != "body" else [i, o]
        sub = replace(
            m, body_name=[m.body_name[b] for b in idx],
            **{f: np.asarray(getattr(m, f))[idx] for f in (
                "body_shape", "body_size", "body_mass", "body_inertia_diag", "body_force_world",
                "body_torque_world", "body_restitution", "body_friction")},
            body_group=np.zeros(len(idx), np.int64), ground=kind == "ground",
            **({f: np.asarray(getattr(m, f))[[o] if kind == "static" else []]
                for f in ("static_box_position", "static_box_quat_wxyz",
                          "static_box_half_extents", "static_box_restitution",
                          "static_box_friction")}))
        world = ContactWorld(sub, ContactParams(), method, ortho)
        sep = separations(world, x[idx], rot[idx])
        depth = float(-sep.min()) if len(sep) else 0.0
        if depth > OVERLAP_WARN_DEPTH_M:
            other = ("the ground" if kind == "ground" else f"static_box[{o}]" if kind == "static"
                     else repr(m.body_name[o]))
            found.append((depth, f"{m.body_name[i]!r} and {other}"))
    if not found:
        return []
    found.sort(reverse=True)
    shown = ", ".join(f"{who} by {d * 1e3:.3g} mm" for d, who in found[:5])
    more = f" (+{len(found) - 5} more)" if len(found) > 5 else ""
    unchecked = len(cands) - OVERLAP_CHECK_MAX_PAIRS
    tail = f"; {unchecked} more candidate pairs not measured" if unchecked > 0 else ""
    return [f"{scene.path}: {len(found)} pair(s) of shapes start overlapping: {shown}{more}"
            f"{tail} (the solver pushes them apart in the first steps)"]


def swept_bounds(model: Model, position, velocity, duration: float):
    """(N, 3) lower and upper corners of the box each bounding sphere sweeps over [0, duration]
    on its exact path x0 + v t + a t^2 / 2 (a = g + F/m: constant without contacts)."""
    a = model.gravity[None, :] + model.body_force_world / model.body_mass[:, None]
    t_end = np.full_like(position, duration)
    cands = [position, position + velocity * t_end + 0.5 * a * t_end**2]
    with np.errstate(divide="ignore", invalid="ignore"):
        t_star = np.where(a != 0, -velocity / a, -1.0)
    inside = (t_star > 0) & (t_star < duration)
    t_star = np.where(inside, t_star, 0.0)
    cands.append(np.where(inside, position + velocity * t_star + 0.5 * a * t_star**2, position))
    stack = np.stack(cands)
    r = model.body_bounding_radius[:, None]
    return stack.min(axis=0) - r, stack.max(axis=0) + r


def _any_overlap(lo, hi, group) -> bool:
    """Whether any two boxes (N, 3 corners) of bodies allowed to collide overlap: the contact
    broadphase's own sort-and-sweep over them."""
    from rblog.engine.contact.broadphase import sweep_and_prune

    n = len(lo)
    _, count = sweep_and_prune(n, n, np.ascontiguousarray(lo), np.ascontiguousarray(hi),
                               np.ascontiguousarray(group, dtype=np.int64), np.ones(n, np.int64),
                               np.empty((max(n, 1), 2), np.int64))
    return count > 0


def plan_stages(scene: Scene, duration: float, force_contacts: bool = False) -> Plan:
    """Pick the stages ``scene`` needs for a run of ``duration`` seconds."""
    m = scene.model
    plan = Plan(scene=scene, force_all=force_contacts)
    plan.stages.append(("integrate", f"{scene.sim.integrator} integrator"))
    g = np.linalg.norm(m.gravity)
    plan.stages.append(("gravity" if g > 0 else "gravity: skipped",
                        f"|g| = {g:g} m/s^2"))
    if np.any(m.body_force_world) or np.any(m.body_torque_world):
        plan.stages.append(("applied forces/torques", "some bodies have force or torque"))
    if force_contacts:
        plan.contacts = True
        plan.stages.append(("contacts", "forced on (--all-stages)"))
        return plan
    if m.ground or len(m.static_box_position):
        plan.contacts = True
        plan.stages.append(("contacts", "the scene has static geometry (ground or static boxes)"))
        return plan
    if m.n_bodies < 2:
        plan.stages.append(("contacts: skipped", "one body and no static geometry"))
        return plan
    vel = scene.state.linear_momentum / m.body_mass[:, None]
    lo, hi = swept_bounds(m, scene.state.position, vel, duration)
    if _any_overlap(lo, hi, m.body_group):
        plan.contacts = True
        plan.stages.append(("contacts", "two bodies' swept bounds overlap within the run"))
    else:
        plan.stages.append(("contacts: skipped",
                            "no two bodies' swept bounding spheres overlap within the run"))
    return plan
