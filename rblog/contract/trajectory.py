"""A recorded run as flat numpy arrays: time first, bodies second.

The simulator hands blocks of samples to the recorders as :class:`Trajectory` objects, the log
readers return one, and the analyzers take one, so the three agree on names and layouts by
construction. Derived channels (velocities, energies, errors) are computed once, here, from the
state the integrator holds (see :func:`derive`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from rblog.contract.model import IMPULSE_KINDS, WORK_KINDS, Model

CONTACT_RESTING = 0
CONTACT_IMPACT = 1
#: body index used for static geometry in contact records (the ground, static boxes)
STATIC_BODY = -1


@dataclass
class RunInfo:
    """Run metadata logged once.

    Attributes:
        integrator: name (``seed``, ``seed-quat``, ``splitting``, ``rk4``, ...).
        orthonormalize: method name, or "none".
        dt: step (s).  log_every: steps between logged samples.
        duration_s: requested simulated time.  rblog_version: writer's version.
        scene_path: where the scene came from.  scene_toml: its text as given.
        scene_resolved: the scene after defaults and generators (JSON-able dict).
        seed: random seed used by generators (or None).
        writer: program that wrote the log (``rblog x.y.z`` or another engine).
        combine_friction: how the engine combines two materials' friction into a pair's
            (``geometric`` sqrt(mu_a mu_b): rblog; ``max``: MuJoCo; ``product``: Bullet; ``min``,
            ``mean``). combine_restitution: likewise (``max``: rblog; ``product``; ``min``, ``mean``).
            The body table holds each body's own material; analyzers combine with these rules.
        engine_settings: every solver setting the writer used (JSON-able dict; engine name,
            version, integrator, iterations, ...).
        log_format: version of the log contract the log follows (docs/log-format.md).
    """

    integrator: str
    orthonormalize: str
    dt: float
    log_every: int
    duration_s: float
    rblog_version: str
    scene_path: str = ""
    scene_toml: str = ""
    scene_resolved: dict = field(default_factory=dict)
    seed: int | None = None
    writer: str = ""
    combine_friction: str = "geometric"
    combine_restitution: str = "max"
    engine_settings: dict = field(default_factory=dict)
    log_format: int = 3


@dataclass
class Contacts:
    """Contacts of the logged steps, flattened (K of them).

    ``normal`` points from body_b into body_a (for the ground, body_b = STATIC_BODY and the normal
    is the ground's outward normal); ``separation`` < 0 means penetration (m). Impulses are the
    ones applied to body_a over the step (N s); body_b receives their negatives.

    Attributes:
        step: (K,) step of the sample the contact belongs to.  t: (K,) s.
        body_a, body_b: (K,) int body indices (STATIC_BODY for static geometry).
        point: (K, 3) world contact point (m).  normal: (K, 3) unit, world.
        separation: (K,) m.  normal_impulse: (K,) N s (>= 0).
        friction_impulse: (K, 3) world-frame tangential impulse (N s).
        kind: (K,) CONTACT_RESTING or CONTACT_IMPACT.
    """

    step: np.ndarray
    t: np.ndarray
    body_a: np.ndarray
    body_b: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    separation: np.ndarray
    normal_impulse: np.ndarray
    friction_impulse: np.ndarray
    kind: np.ndarray

    @staticmethod
    def empty() -> "Contacts":
        z = np.zeros
        return Contacts(
            z(0, np.int64), z(0), z(0, np.int64), z(0, np.int64), z((0, 3)), z((0, 3)), z(0), z(0),
            z((0, 3)), z(0, np.int8),
        )

    def __len__(self) -> int:
        return len(self.step)

    def select(self, mask: np.ndarray) -> "Contacts":
        """The contacts where ``mask`` (K,) is true."""
        return Contacts(**{f.name: getattr(self, f.name)[mask] for f in fields(Contacts)})

    @staticmethod
    def concat(parts: list["Contacts"]) -> "Contacts":
        if not parts:
            return Contacts.empty()
        return Contacts(
            **{f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(Contacts)}
        )


#: per-sample, per-body channels: name -> trailing shape
BODY_CHANNELS = {
    "position": (3,),
    "quat_wxyz": (4,),
    "rotation": (3, 3),
    "velocity": (3,),
    "linear_momentum": (3,),
    "angular_velocity": (3,),
    "angular_momentum": (3,),
    "energy_translational": (),
    "energy_rotational": (),
    "energy_potential": (),
    "ortho_error": (),
    "quat_norm_error": (),
}
#: per-sample totals over all bodies: name -> trailing shape
TOTAL_CHANNELS = {
    "total_linear_momentum": (3,),
    "total_angular_momentum": (3,),
    "total_energy": (),
}
#: per-interval, per-body channels (contract v3), optional: name -> trailing shape. Sample i
#: holds what acted over the steps s with step[i-1] < s <= step[i] (sample 0: the steps since
#: the recording began), world frame: impulses in N s (linear) and N m s (angular, about the
#: body's centre of mass), work in J. A body that does not log a kind
#: (Model.body_impulse_supplied / body_work_supplied) has NaN there; a channel no body logs is
#: None on the Trajectory and absent from the log. Read them through Trajectory.impulse(kind) /
#: work(kind), which also fill the zeros of forces an engine does not have.
INTERVAL_CHANNELS = {
    **{f"impulse_{k}_{part}": (3,) for k in IMPULSE_KINDS for part in ("linear", "angular")},
    **{f"work_{k}": () for k in WORK_KINDS},
}


@dataclass
class Trajectory:
    """A run (or a block of it). T samples of N bodies, float64, world frame.

    Attributes:
        model: the fixed model (bodies' shapes, masses, inertia, materials, ground, statics).
        info: run metadata.
        step: (T,) int64 step index of each sample.  t: (T,) simulated time (s).
        position: (T, N, 3) m.  quat_wxyz: (T, N, 4) body->world, scalar first.
        rotation: (T, N, 3, 3) the body->world matrix the integrator holds.
        velocity: (T, N, 3) m/s.  linear_momentum: (T, N, 3) kg m/s.
        angular_velocity: (T, N, 3) rad/s, world.  angular_momentum: (T, N, 3) kg m^2/s, world,
            about the body's centre of mass.
        energy_translational, energy_rotational, energy_potential: (T, N) J (potential of
            gravity, zero at the world origin).
        ortho_error: (T, N) ||R^T R - I||_F.  quat_norm_error: (T, N) |q| - 1.
        total_linear_momentum: (T, 3).  total_angular_momentum: (T, 3) about the world origin
            (sum of x cross P + L).  total_energy: (T,) J.
        impulse_<kind>_linear, impulse_<kind>_angular: (T, N, 3) or None, kind in
            IMPULSE_KINDS; work_<kind>: (T, N) or None, kind in WORK_KINDS (INTERVAL_CHANNELS).
        contacts: contacts at the logged steps.
        truncated: True when the log ended early (interrupted or diverged run, cut file).
        failed: why the recording failed ('' when it did not): a write that raised (bad arrays,
            a full disk) leaves a run whose samples stop or have a gap where it raised, so the
            analyzers judge none of it clean (rblog.analyze: "not judged"); findings on the
            samples that were recorded are still reported.
        warnings: messages from the reader.
    """

    model: Model
    info: RunInfo
    step: np.ndarray
    t: np.ndarray
    position: np.ndarray
    quat_wxyz: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    linear_momentum: np.ndarray
    angular_velocity: np.ndarray
    angular_momentum: np.ndarray
    energy_translational: np.ndarray
    energy_rotational: np.ndarray
    energy_potential: np.ndarray
    ortho_error: np.ndarray
    quat_norm_error: np.ndarray
    total_linear_momentum: np.ndarray
    total_angular_momentum: np.ndarray
    total_energy: np.ndarray
    contacts: Contacts = field(default_factory=Contacts.empty)
    truncated: bool = False
    warnings: list[str] = field(default_factory=list)
    failed: str = ""
    impulse_contact_linear: np.ndarray | None = None
    impulse_contact_angular: np.ndarray | None = None
    impulse_applied_linear: np.ndarray | None = None
    impulse_applied_angular: np.ndarray | None = None
    impulse_passive_linear: np.ndarray | None = None
    impulse_passive_angular: np.ndarray | None = None
    impulse_actuator_linear: np.ndarray | None = None
    impulse_actuator_angular: np.ndarray | None = None
    impulse_joint_linear: np.ndarray | None = None
    impulse_joint_angular: np.ndarray | None = None
    impulse_integration_linear: np.ndarray | None = None
    impulse_integration_angular: np.ndarray | None = None
    work_applied: np.ndarray | None = None
    work_passive: np.ndarray | None = None
    work_actuator: np.ndarray | None = None
    work_joint: np.ndarray | None = None

    def impulse(self, kind: str) -> tuple[np.ndarray, np.ndarray] | None:
        """(linear (T, N, 3), angular (T, N, 3)) of impulse ``kind`` (IMPULSE_KINDS): the
        logged values, 0 for bodies whose engine has no such force (SUPPLIED_NONE), NaN for
        bodies that miss it; None when no body's is known."""
        from rblog.contract.model import SUPPLIED_LOGGED, SUPPLIED_NONE

        status = self.model.body_impulse_supplied[:, IMPULSE_KINDS.index(kind)]
        lin = getattr(self, f"impulse_{kind}_linear")
        if lin is None and not np.any(status == SUPPLIED_NONE):
            return None
        ang = getattr(self, f"impulse_{kind}_angular")
        if np.all(status == SUPPLIED_LOGGED):
            return lin, ang
        shape = (self.n_samples, self.n_bodies, 3)
        out = []
        for a in (lin, ang):
            a = np.full(shape, np.nan) if a is None else a.copy()
            a[:, status == SUPPLIED_NONE] = 0.0
            out.append(a)
        return out[0], out[1]

    def work(self, kind: str) -> np.ndarray | None:
        """(T, N) work ``kind`` (WORK_KINDS), filled as :meth:`impulse`; None when no body's is
        known."""
        from rblog.contract.model import SUPPLIED_LOGGED, SUPPLIED_NONE

        status = self.model.body_work_supplied[:, WORK_KINDS.index(kind)]
        w = getattr(self, f"work_{kind}")
        if w is None and not np.any(status == SUPPLIED_NONE):
            return None
        if np.all(status == SUPPLIED_LOGGED):
            return w
        w = np.full((self.n_samples, self.n_bodies), np.nan) if w is None else w.copy()
        w[:, status == SUPPLIED_NONE] = 0.0
        return w

    @property
    def interval_channels(self) -> list[str]:
        """The names of the INTERVAL_CHANNELS this trajectory holds."""
        return [k for k in INTERVAL_CHANNELS if getattr(self, k) is not None]

    @property
    def n_samples(self) -> int:
        return len(self.t)

    @property
    def n_bodies(self) -> int:
        return self.model.n_bodies

    @property
    def quat_xyzw(self) -> np.ndarray:
        """(T, N, 4) the same quaternions, scalar last (Rerun, Foxglove, scipy order)."""
        return self.quat_wxyz[..., [1, 2, 3, 0]]

    @property
    def energy(self) -> np.ndarray:
        """(T, N) total energy per body (J)."""
        return self.energy_translational + self.energy_rotational + self.energy_potential

    def slice(self, sl: slice) -> "Trajectory":
        """The samples ``sl`` (time axis) of this trajectory, with the contacts of those steps."""
        kw = {name: getattr(self, name)[sl]
              for name in ("step", "t", *BODY_CHANNELS, *TOTAL_CHANNELS, *self.interval_channels)}
        steps = kw["step"]
        c = self.contacts
        if len(steps):
            c = c.select((c.step >= steps[0]) & (c.step <= steps[-1]))
        else:
            c = Contacts.empty()
        return Trajectory(self.model, self.info, contacts=c, truncated=self.truncated,
                          warnings=list(self.warnings), failed=self.failed, **kw)

    @staticmethod
    def concat(parts: list["Trajectory"]) -> "Trajectory":
        """Join blocks of one run along time."""
        first = parts[0]
        kw = {
            name: np.concatenate([getattr(p, name) for p in parts])
            for name in ("step", "t", *BODY_CHANNELS, *TOTAL_CHANNELS)
        }
        for name in INTERVAL_CHANNELS:
            got = [getattr(p, name) for p in parts]
            if any(g is not None for g in got):
                trail = INTERVAL_CHANNELS[name]
                kw[name] = np.concatenate([
                    g if g is not None else np.full((p.n_samples, p.n_bodies, *trail), np.nan)
                    for g, p in zip(got, parts)])
        return Trajectory(
            first.model, first.info, contacts=Contacts.concat([p.contacts for p in parts]),
            truncated=any(p.truncated for p in parts),
            warnings=[w for p in parts for w in p.warnings],
            failed=next((p.failed for p in parts if p.failed), ""), **kw,
        )


def derive(
    model: Model,
    info: RunInfo,
    step: np.ndarray,
    t: np.ndarray,
    position: np.ndarray,
    linear_momentum: np.ndarray,
    quat_wxyz: np.ndarray,
    rotation: np.ndarray,
    angular_momentum: np.ndarray,
    contacts: Contacts | None = None,
) -> Trajectory:
    """Build a trajectory from the integrator's state samples, computing every derived channel.

    Args: step (T,), t (T,), position (T,N,3), linear_momentum (T,N,3), quat_wxyz (T,N,4),
    rotation (T,N,3,3), angular_momentum (T,N,3) world frame.

    The angular velocity is ``R diag(1/I_body) R^T L`` with the logged R, exactly as the notes'
    integrator computes it, so a non-orthonormal R shows up in omega and in the energy. For the
    quaternion scheme without normalization (``seed-quat``, ``orthonormalize = "none"``), whose
    R = |q|^2 Q is a scaled rotation, it is ``(R I_body R^T)^-1 L``, as that integrator computes
    it (rblog.engine.integrators): the same for an orthonormal R.
    """
    from rblog.contract.derive import derive_channels

    c = np.ascontiguousarray
    position, linear_momentum, quat_wxyz, rotation, angular_momentum = (
        c(a, dtype=np.float64) for a in (position, linear_momentum, quat_wxyz, rotation, angular_momentum))
    shape_tn = position.shape[:2]
    velocity, omega = np.empty_like(position), np.empty_like(position)
    e_trans, e_rot, e_pot, ortho, qnorm = (np.empty(shape_tn) for _ in range(5))
    n_t = shape_tn[0]
    total_p, total_l, total_e = np.empty((n_t, 3)), np.empty((n_t, 3)), np.empty(n_t)
    derive_channels(c(model.body_mass, dtype=np.float64), c(model.body_inv_inertia_diag, dtype=np.float64),
                    c(model.gravity, dtype=np.float64), position, linear_momentum, quat_wxyz, rotation,
                    angular_momentum, velocity, omega, e_trans, e_rot, e_pot, ortho, qnorm,
                    total_p, total_l, total_e,
                    info.integrator == "seed-quat" and info.orthonormalize == "none")
    return Trajectory(
        model=model, info=info, step=np.asarray(step, np.int64), t=np.asarray(t, np.float64),
        position=position, quat_wxyz=quat_wxyz, rotation=rotation, velocity=velocity,
        linear_momentum=linear_momentum, angular_velocity=omega, angular_momentum=angular_momentum,
        energy_translational=e_trans, energy_rotational=e_rot, energy_potential=e_pot,
        ortho_error=ortho, quat_norm_error=qnorm, total_linear_momentum=total_p,
        total_angular_momentum=total_l, total_energy=total_e,
        contacts=contacts if contacts is not None else Contacts.empty(),
    )
