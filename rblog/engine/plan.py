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

    def make_contact_world(self, method: int, ortho: int):
        from rblog.engine.constants import ContactParams
        from rblog.engine.contact.world import ContactWorld

        params = ContactParams.from_dict(self.scene.contact)  # validated by the scene loader
        self._world = ContactWorld(self.scene.model, params, method, ortho,
                                   force_all_stages=self.force_all)
        self.stages = [("integrate", self.stages[0][1]), *self._world.explain()]
        return self._world


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
