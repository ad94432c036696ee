"""What a run reports about itself, and how its engine logs it.

:class:`RunSummary` is the run's figures (steps, throughput, the drifts over the logged samples);
:class:`Drift` measures those drifts from each block handed to the recorders: the engine's
self-report that `rblog run` prints under "the engine's own figures", one whole-scene number
each, the penetration by the engine's own narrowphase. It is not the audit: ``rblog check``'s
analyzers (rblog.analyze) judge each body and contact of the log with their own tolerances. :func:`engine_model` is the body table as
rblog's engine logs it (contract v3: which per-interval impulses it carries).
"""

from __future__ import annotations

import dataclasses
from dataclasses import asdict, dataclass, field

import numpy as np

from rblog.contract.model import (IMPULSE_KINDS, SUPPLIED_LOGGED, SUPPLIED_NONE, WORK_KINDS,
                                  Model)
from rblog.contract.trajectory import Trajectory
from rblog.engine.scene import Scene


@dataclass
class RunSummary:
    """Figures of a finished (or stopped) run. Drifts are over the logged samples.

    energy_drift_rel: max |E - E0| of the total energy (kinetic + gravity potential) over the
        run's energy scale: the largest kinetic energy plus sum_i m_i |g| (height range of body
        i), so that it does not depend on where the potential's zero is (see ``Drift``).
    angular_momentum_drift_rel: max over bodies of | |L_i| - |L_i0| | / |L_i0| (spin angular
        momentum about each body's centre of mass; 0 for bodies with no initial spin).
    ortho_error_max: max ||R^T R - I||_F over bodies and samples.
    not_applicable: the figures above that do not measure an error in this scene, each with why
        (:func:`drift_not_applicable`): energy is an invariant only of free flight without applied
        forces or torques, each body's |L| only of free flight without applied torques. The
        figures are still computed; ``rblog run`` shows the reason instead of the number.
    contact_penetration_max_m: the deepest overlap (m) of any two shapes (bodies, ground, static
        boxes) at the logged samples, measured on their poses by the contact narrowphase
        (``contact.measure``); 0 if none overlaps; None in a scene that runs no contact stage.
    """

    status: str
    steps: int
    bodies: int
    samples: int
    sim_time_s: float
    wall_time_s: float
    steps_per_s: float
    body_steps_per_s: float
    energy_drift_rel: float
    angular_momentum_drift_rel: float
    ortho_error_max: float
    quat_norm_error_max: float
    integrator: str
    orthonormalize: str
    dt: float
    log_every: int
    stages: list[str] = field(default_factory=list)
    message: str = ""
    not_applicable: dict[str, str] = field(default_factory=dict)
    contact_penetration_max_m: float | None = None

    def to_dict(self) -> dict:
        return asdict(self)


def drift_not_applicable(model: Model, contacts: bool) -> dict[str, str]:
    """Which of RunSummary's drift figures are not errors in a scene, and why: ``contacts`` is
    True when bodies can touch (the run has a contact stage: impulses turn bodies, restitution
    and friction take energy); applied forces and torques (``body_force_world``,
    ``body_torque_world``) do work, and torques change |L|. Gravity is in the energy."""
    why: dict[str, str] = {}
    torque = bool(np.any(model.body_torque_world != 0))
    force = bool(np.any(model.body_force_world != 0))
    if contacts:
        touch = "bodies touch (contacts take energy and turn bodies: not invariants here)"
        why["energy_drift_rel"] = why["angular_momentum_drift_rel"] = touch
    else:
        if force or torque:
            why["energy_drift_rel"] = "applied forces or torques do work"
        if torque:
            why["angular_momentum_drift_rel"] = "applied torques change L"
    return why


class Drift:
    """Running maxima of the summary figures over blocks.

    The energy drift is max |E - E0| over a scale that, like E - E0, does not depend on where the
    zero of potential energy is: the largest kinetic energy seen plus sum_i m_i |g| times the
    range of heights (along g) body i covered. A run where nothing moves has drift 0.
    """

    def __init__(self, model: Model | None = None, contact_world=None):
        self.e0 = None
        self.l0 = None
        self.de_max = 0.0
        self.ke_max = 0.0
        self.h_lo = None
        self.h_hi = None
        self.spin = 0.0
        self.ortho = 0.0
        self.qnorm = 0.0
        self.penetration = 0.0  # deepest overlap at the samples' poses, m
        self.model = model
        # a ContactWorld of the scene that is never stepped: its narrowphase measures the poses
        self.contact_world = contact_world

    @property
    def energy(self) -> float:
        scale = self.ke_max
        if self.model is not None and self.h_lo is not None:
            g = float(np.linalg.norm(self.model.gravity))
            scale += float(np.sum(self.model.body_mass * g * (self.h_hi - self.h_lo)))
        return self.de_max / scale if scale > 0 else 0.0

    def update(self, b: Trajectory):
        if b.n_samples == 0:
            return
        if self.e0 is None:
            self.e0 = float(b.total_energy[0])
            self.l0 = np.linalg.norm(b.angular_momentum[0], axis=-1)
        self.de_max = max(self.de_max, float(np.max(np.abs(b.total_energy - self.e0))))
        self.ke_max = max(self.ke_max, float(np.max((b.energy_translational + b.energy_rotational).sum(axis=1))))
        if self.model is not None:
            g = np.asarray(self.model.gravity, float)
            gn = float(np.linalg.norm(g))
            if gn > 0:
                h = -(b.position @ (g / gn))  # (S, N) height along -g, m
                lo, hi = h.min(axis=0), h.max(axis=0)
                self.h_lo = lo if self.h_lo is None else np.minimum(self.h_lo, lo)
                self.h_hi = hi if self.h_hi is None else np.maximum(self.h_hi, hi)
        spin = np.linalg.norm(b.angular_momentum, axis=-1)
        has = self.l0 > 0
        if np.any(has):
            d = np.abs(spin[:, has] - self.l0[has]) / self.l0[has]
            self.spin = max(self.spin, float(d.max()))
        self.ortho = max(self.ortho, float(b.ortho_error.max()))
        self.qnorm = max(self.qnorm, float(np.abs(b.quat_norm_error).max()))
        if self.contact_world is not None:
            from rblog.engine.contact.measure import max_penetration

            for k in range(b.n_samples):  # 0.2 s of CPU for the 500-box pile's 301 samples
                self.penetration = max(self.penetration, max_penetration(
                    self.contact_world, b.position[k], b.rotation[k]))



def engine_model(model: Model, contacts: bool) -> Model:
    """``model`` as rblog's engine logs it (contract v3): it logs the contact impulses of every
    interval when bodies can touch (else they are none), the applied ones when a body has a
    constant force or torque (else none); it has no passive forces, actuators or joints (none),
    and no applied work besides its constant loads' (none: F . dx follows from the poses)."""
    n = model.n_bodies
    loads = bool(np.any(model.body_force_world) or np.any(model.body_torque_world))
    imp = np.full((n, len(IMPULSE_KINDS)), SUPPLIED_NONE, np.int64)
    imp[:, IMPULSE_KINDS.index("contact")] = SUPPLIED_LOGGED if contacts else SUPPLIED_NONE
    imp[:, IMPULSE_KINDS.index("applied")] = SUPPLIED_LOGGED if loads else SUPPLIED_NONE
    work = np.full((n, len(WORK_KINDS)), SUPPLIED_NONE, np.int64)
    return dataclasses.replace(model, body_impulse_supplied=imp, body_work_supplied=work)


def measure_world(scene: Scene, method: int, ortho_code: int):
    """A ContactWorld of ``scene`` for measuring overlaps at the logged samples (on the writer
    thread; the stepping world is not shared with it)."""
    from rblog.engine.constants import ContactParams
    from rblog.engine.contact.world import ContactWorld

    return ContactWorld(scene.model, ContactParams.from_dict(scene.contact), method, ortho_code)
