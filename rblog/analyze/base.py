"""What every analyzer shares: the Finding / Result records, the Analyzer base class, and the
Context that computes, once per trajectory, what several analyzers need.

Derivations used by the analyzers (all from logged channels + model, never simulator internals):

* Contact impulse of body i over the sample interval [k, k+1] (length Δt):
  ``J = P(k+1) - P(k) - (m g + F) Δt`` and, about its centre, ``H = L(k+1) - L(k) - τ Δt``
  (F, τ: the model's constant applied force and torque). Constant forces change momentum exactly
  in every integrator, so a free body has J = H = 0 to round-off; a nonzero one is a contact
  (or a fault).
* A contact can have happened in [k, k+1] between two shapes only if their separation at k or
  k+1 is within the distance they can sweep in Δt: ``Δt (max |v| + ρ max |ω|)`` for each body
  (ρ: bounding radius) plus the contact distance. Logged contacts of the interval's steps count
  too.
* Contact groups: bodies (per interval) joined by such possible contacts, and kept when at least
  one member's momentum jumped. A group with no static geometry in reach is closed: its momentum
  must be conserved. Computed in one compiled pass over the intervals (union-find).

The per-sample work (kinematics, contact groups, and in the analyzers rigidity, geometry and
energy stretches) runs in the audit's compiled kernels (``rblog.analyze._audit``, csrc/audit/)
over all bodies and samples; Python only handles the findings, which are few.

Why this module is long: it holds what every analyzer shares: Finding and Result, the Context that
derives once what several analyzers need (contact groups, impulses, resting intervals), and the
calls of the compiled helpers behind them (csrc/audit/context.cpp).
"""

from __future__ import annotations

import math
import threading
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from rblog.errors import RblogError, CheckOptionError
from rblog.contract.model import (BODY_KINEMATIC, BODY_STATIC, IMPULSE_KINDS, SHAPE_NONE,
                                  SUPPLIED_LOGGED, SUPPLIED_MISSING, Model)
from rblog.contract.trajectory import STATIC_BODY, Trajectory
from rblog.analyze import _audit, geometry
from rblog.analyze import tolerances as tol


def _json_float(x):
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _json(v):
    if isinstance(v, dict):
        return {str(k): _json(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_json(x) for x in v]
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return _json_float(v)
    if isinstance(v, np.ndarray):
        return _json(v.tolist())
    return v


@dataclass
class Finding:
    """One flagged problem.

    Attributes:
        analyzer: name of the analyzer.  message: one-line reason.
        value, tolerance, unit: the measured value against its tolerance.
        step, t: when (step index and simulated time of the sample where it shows).
        bodies: which bodies (indices; names via model.body_name).
        onset_step, onset_t: where a finding that grows began (the first sample past its
            tolerance, e.g. the drift's onset), when that is earlier than ``step``; else None.
            The viewers place the finding there.
    """

    analyzer: str
    message: str
    value: float
    tolerance: float
    unit: str
    step: int
    t: float
    bodies: list[int]
    onset_step: int | None = None
    onset_t: float | None = None

    def to_dict(self) -> dict:
        return _json(asdict(self))


@dataclass
class Result:
    """One analyzer's verdict on one trajectory.

    ``worst_*`` is the measurement closest to (or furthest past) its tolerance, also when the
    trajectory passes. ``events`` lists what the analyzer measured that is not a problem in itself
    (impacts with their effective restitution, resting intervals), at most MAX_EVENTS of them.

    The verdict (:attr:`verdict`) is one of:

    * ``pass``: judged, nothing found (``passed``).
    * ``FAIL``: findings (``passed`` False).
    * ``skip``: nothing this analyzer checks is in the log (tunneling in a scene of one body
      without ground or static boxes): ``skipped``, and ``passed`` (nothing can be wrong).
    * ``not judged``: the analyzer could not judge the trajectory (a failed recording, a log
      without samples): ``judged`` False, ``skipped``, and ``passed`` False, so code that reads
      ``passed`` never takes it for a clean run; the reason starts with "not judged".

    ``not_judged`` lists the parts of a judged trajectory an analyzer left out, one line each with
    why (bodies without a shape the contract describes, impacts whose restitution the engine did
    not state); the verdict is about the rest.
    """

    analyzer: str
    passed: bool
    worst_value: float
    tolerance: float
    unit: str
    worst_step: int | None
    worst_t: float | None
    worst_bodies: list[int]
    reason: str
    findings: list[Finding] = field(default_factory=list)
    stats: dict[str, float] = field(default_factory=dict)
    skipped: bool = False
    events: list[dict] = field(default_factory=list)
    judged: bool = True
    not_judged: list[str] = field(default_factory=list)
    #: what ``worst_value`` measures, in words ("resting penetration depth"): the tolerance is
    #: that quantity's own
    worst_what: str = ""

    def leave_out(self, lines: list[str]) -> "Result":
        """Add ``lines`` to ``not_judged`` and say them in the reason (the verdict is about the
        rest); returns self."""
        lines = [x for x in lines if x not in self.not_judged]
        if lines:
            self.not_judged += lines
            self.reason = "; ".join([self.reason, *lines]) if self.reason else "; ".join(lines)
        return self

    @property
    def verdict(self) -> str:
        """``pass``, ``FAIL``, ``skip`` or ``not judged`` (see the class docstring)."""
        if not self.judged:
            return "not judged"
        if self.findings or not self.passed:
            return "FAIL"
        return "skip" if self.skipped else "pass"

    def to_dict(self, model: Model | None = None) -> dict:
        """JSON-able dict (non-finite floats become None); with ``model``, body names too."""
        d = _json(asdict(self))
        d["verdict"] = self.verdict
        if model is not None:
            d["worst_body_names"] = [model.body_name[i] for i in self.worst_bodies]
            for f, fd in zip(self.findings, d["findings"]):
                fd["body_names"] = [model.body_name[i] for i in f.bodies]
        return d


class Worst:
    """Keeps the measurement with the largest value/tolerance ratio offered so far."""

    def __init__(self, unit: str, tolerance: float):
        self.ratio = -math.inf
        self.value = 0.0
        self.tolerance = tolerance
        self.unit = unit
        self.step: int | None = None
        self.t: float | None = None
        self.bodies: list[int] = []
        self.what = ""

    def offer(self, ratio, value, tolerance, unit, step=None, t=None, bodies=(), what=""):
        if ratio is not None and not np.isnan(ratio) and ratio > self.ratio:
            self.ratio, self.value, self.tolerance, self.unit = float(ratio), float(value), \
                float(tolerance), unit
            self.step = None if step is None else int(step)
            self.t = None if t is None else float(t)
            self.bodies = [int(b) for b in bodies]
            self.what = what

    def offer_array(self, value, tolerance, unit, steps, ts, bodies, what=""):
        """Offer the worst of arrays: value, tolerance (or scalar) (P,); bodies (P, k) or (P,)."""
        value = np.asarray(value, float)
        if value.size == 0:
            return
        tol_ = np.broadcast_to(np.asarray(tolerance, float), value.shape)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(tol_ > 0, value / tol_, np.where(value > 0, np.inf, 0.0))
        ratio = np.where(np.isnan(ratio), -np.inf, ratio)
        i = int(np.argmax(ratio))
        b = np.atleast_1d(np.asarray(bodies)[i]).tolist() if len(bodies) else []
        self.offer(ratio[i], value[i], tol_[i], unit, steps[i], ts[i], b, what)


class Analyzer:
    """Base class. Subclasses set ``name``, ``description`` and ``defaults`` (tolerance name ->
    default value, rblog.analyze.tolerances.options; the name ends in its unit) and implement
    :meth:`analyze`."""

    name: str = ""
    description: str = ""
    #: tolerance name -> default value
    defaults: dict[str, float] = {}

    def __init__(self, **tolerances):
        self.tol = dict(self.defaults)
        for k, v in tolerances.items():
            if k not in self.defaults:
                raise CheckOptionError(
                    f"unknown tolerance {self.name}.{k}; {self.name} has: "
                    + ", ".join(sorted(self.defaults))
                )
            try:
                self.tol[k] = float(v)
            except (TypeError, ValueError):
                raise CheckOptionError(f"tolerance {self.name}.{k} must be a number, got {v!r}")
            if not math.isfinite(self.tol[k]) or self.tol[k] < 0:
                raise CheckOptionError(f"tolerance {self.name}.{k} must be finite and >= 0")

    @classmethod
    def tolerance_table(cls) -> list[tuple[str, float, str]]:
        """(``analyzer.name``, default, unit) of every tolerance, for listings (``--list``)."""
        return [(f"{cls.name}.{k}", v, tol.unit_of(k)) for k, v in cls.defaults.items()]

    def run(self, traj: Trajectory, ctx: "Context | None" = None) -> Result:
        """Analyze ``traj`` (``ctx`` shares work between analyzers of one trajectory).

        A state that turns NaN or infinite ends the analysis at the sample before it (the drift
        analyzer reports it)."""
        ctx = ctx if ctx is not None else Context(traj)
        if ctx.traj.n_samples == 0 and not (ctx.nonfinite is not None and self.name == "drift"):
            res = self.not_judged("the log holds no samples" if ctx.nonfinite is None else
                                  "the first sample is already non-finite")
        else:
            res = self.analyze(ctx)
        failed = getattr(ctx.full_traj, "failed", "")
        if failed:
            res = _failed_recording(res, failed, ctx.full_traj.n_samples)
        return res

    def analyze(self, ctx: "Context") -> Result:  # pragma: no cover - abstract
        raise NotImplementedError

    # --- helpers for subclasses ---------------------------------------------------------------
    def skip(self, reason: str) -> Result:
        """Nothing this analyzer checks is in the log (verdict ``skip``, passed)."""
        return Result(self.name, True, 0.0, 0.0, "", None, None, [], reason, skipped=True)

    def not_judged(self, reason: str) -> Result:
        """The trajectory cannot be judged (verdict ``not judged``: never ``passed``)."""
        return Result(self.name, False, 0.0, 0.0, "", None, None, [], f"not judged: {reason}",
                      skipped=True, judged=False, not_judged=[reason])

    def result(self, worst: Worst, findings: list[Finding], stats: dict, events=(), ok_reason="",
               n_findings: int | None = None) -> Result:
        """Assemble a Result: findings sorted worst first and capped at MAX_FINDINGS."""
        findings = sorted(findings, key=lambda f: -(f.value / f.tolerance if f.tolerance > 0
                                                    else math.inf))
        total = len(findings) if n_findings is None else n_findings
        stats = dict(stats)
        stats["findings"] = float(total)
        events = list(events)
        if total:
            first = findings[0]
            more = f" (+{total - 1} more)" if total > 1 else ""
            reason = first.message + more
        elif worst.step is not None:
            u = "" if worst.unit in ("", "1") else f" {worst.unit}"
            reason = ok_reason or (f"worst {worst.what}: {worst.value:.3g}{u} <= "
                                   f"{worst.tolerance:.3g}{u} at t = {worst.t:.6g} s")
        else:
            reason = ok_reason or "nothing to check"
        return Result(
            analyzer=self.name, passed=total == 0,
            worst_value=worst.value if worst.step is not None else 0.0,
            tolerance=worst.tolerance, unit=worst.unit, worst_step=worst.step, worst_t=worst.t,
            worst_bodies=worst.bodies, reason=reason, findings=findings[: tol.MAX_FINDINGS],
            stats={k: float(v) for k, v in stats.items()}, events=events[: tol.MAX_EVENTS],
            worst_what=worst.what if worst.step is not None else "",
        )


def _failed_recording(res: Result, failed: str, n_samples: int) -> Result:
    """``res`` on a trajectory whose recording failed (Trajectory.failed): findings on the samples
    recorded stand, but no result passes: what was not recorded cannot be judged."""
    why = f"the recording failed ({failed})"
    res.not_judged = [why] + [w for w in res.not_judged if w != why]
    if res.passed or not res.judged:
        before = "" if not res.judged else \
            f"; the {n_samples} samples recorded before it: {res.reason}"
        res.passed, res.skipped, res.judged = False, True, False
        res.reason = f"not judged: {why}{before}"
    return res


def shapeless(model: Model) -> np.ndarray:
    """(N,) bool: bodies without a shape the contract describes (SHAPE_NONE: another engine's
    capsule, cylinder, mesh), whose separations cannot be computed."""
    return np.asarray(model.body_shape) == SHAPE_NONE


def shapeless_note(model: Model, what: str, known: np.ndarray | None = None) -> list[str]:
    """``not_judged`` line for the bodies without a shape ([] when there are none), leaving out
    the ``known`` ones ((N,) bool: e.g. those whose logged contact impulses say when they touch)
    and the bodies with no geom whose contact impulse is known (logged, or none in the engine):
    the writer says they touch nothing, they have no collision geometry (dm_control's 'pinch
    site', a massless marker), so there is nothing to judge. A body with no geom whose contact
    impulse is missing (a v2 log's shape 'none': a geometry the log does not describe) stays."""
    mask = shapeless(model)
    if known is not None:
        mask = mask & ~known
    has_any = np.zeros(model.n_bodies, bool)
    if getattr(model, "n_geoms", 0):
        gb = np.asarray(model.geom_body, np.int64)
        has_any[gb[gb >= 0]] = True
    mask = mask & (has_any | ~model.impulse_supplied("contact"))
    idx = np.flatnonzero(mask)
    if not len(idx):
        return []
    names = ", ".join(repr(model.body_name[i]) for i in idx[:3])
    more = f" +{len(idx) - 3} more" if len(idx) > 3 else ""
    return [f"{len(idx)} bod{'y' if len(idx) == 1 else 'ies'} without a shape in the contract "
            f"({names}{more}: a capsule, cylinder or mesh): {what} not judged"]


def _has_geoms(model: Model) -> np.ndarray:
    """(N,) bool: bodies with at least one geom that is not a plane (contract v3)."""
    out = np.zeros(model.n_bodies, bool)
    if getattr(model, "n_geoms", 0):
        from rblog.contract.model import GEOM_PLANE

        gb = np.asarray(model.geom_body, np.int64)
        solid = (gb >= 0) & (np.asarray(model.geom_type, np.int64) != GEOM_PLANE)
        out[gb[solid]] = True
    return out


def body_label(model: Model, i: int) -> str:
    return f"body {i} ({model.body_name[i]!r})" if 0 <= i < model.n_bodies else "static geometry"


# --- shared computations ----------------------------------------------------------------------
@dataclass
class Groups:
    """Contact groups per sample interval (see the module docstring).

    Attributes:
        k: (C,) interval index of each group.  size: (C,) members.
        static: (C,) True when static geometry (ground, static boxes) is in reach of a member.
        static_features: (C,) number of distinct static features in reach (ground, each box).
        static_id: (C,) the static feature in reach when exactly one: -1 ground, m static box m.
        mem_group, mem_k, mem_i: (Q,) members, sorted by group.
    """

    k: np.ndarray
    size: np.ndarray
    static: np.ndarray
    static_features: np.ndarray
    static_id: np.ndarray
    mem_group: np.ndarray
    mem_k: np.ndarray
    mem_i: np.ndarray

    def __len__(self) -> int:
        return len(self.k)

    @property
    def starts(self) -> np.ndarray:
        """(C,) index of each group's first member."""
        if not hasattr(self, "_starts"):
            # members of the groups before each (mem_group is sorted, >= 0): the index where
            # np.searchsorted(mem_group, arange(C)) puts each group, in one counting pass
            c_n = len(self.k)
            before = np.zeros(c_n, np.int64)
            if c_n > 1:
                np.cumsum(np.bincount(self.mem_group, minlength=c_n)[:c_n - 1], out=before[1:])
            self._starts = before
        return self._starts

    def sum(self, per_member: np.ndarray) -> np.ndarray:
        """Sum per group of a (Q, ...) per-member array."""
        if not len(self.k):
            return np.zeros((0,) + per_member.shape[1:])
        return np.add.reduceat(per_member, self.starts, axis=0)

    def max(self, per_member: np.ndarray) -> np.ndarray:
        """Max per group of a (Q, ...) per-member array."""
        if not len(self.k):
            return np.zeros((0,) + per_member.shape[1:])
        return np.maximum.reduceat(per_member, self.starts, axis=0)

    def subset(self, sel: np.ndarray) -> "Groups":
        """The groups where ``sel`` (C,) is true, renumbered 0..; ``.index`` maps them back."""
        idx = np.nonzero(sel)[0]
        keep = sel[self.mem_group]
        remap = np.cumsum(sel) - 1
        sub = Groups(k=self.k[idx], size=self.size[idx], static=self.static[idx],
                     static_features=self.static_features[idx], static_id=self.static_id[idx],
                     mem_group=remap[self.mem_group[keep]], mem_k=self.mem_k[keep],
                     mem_i=self.mem_i[keep])
        sub.index = idx
        return sub

    def members(self, j: int) -> list[int]:
        """Body indices of group j."""
        lo = self.starts[j]
        hi = self.starts[j + 1] if j + 1 < len(self.k) else len(self.mem_i)
        return self.mem_i[lo:hi].tolist()


_STATE_CHANNELS = ("position", "rotation", "quat_wxyz", "velocity", "linear_momentum",
                   "angular_momentum", "angular_velocity")


def all_finite(arr) -> bool:
    """``np.isfinite(arr).all()``, in one pass over the memory without temporaries for a
    contiguous float64 array (the common case: every channel of a log)."""
    a = np.asarray(arr)
    if a.dtype == np.float64 and a.flags.c_contiguous:
        return bool(_audit.all_finite(a))
    return bool(np.isfinite(a).all())


def _first_nonfinite(traj: Trajectory):
    """(first sample index with a NaN or inf in a state channel, bodies), or (None, [])."""
    t_n, n = traj.n_samples, traj.n_bodies
    if all_finite(traj.t) and all(all_finite(getattr(traj, name)) for name in _STATE_CHANNELS):
        return None, []
    bad = np.zeros((t_n, n), bool)
    for name in _STATE_CHANNELS:
        arr = np.asarray(getattr(traj, name))
        if arr.size:
            bad |= ~np.isfinite(arr.reshape(t_n, n, -1)).all(axis=2)
    bad_t = ~np.isfinite(np.asarray(traj.t, float))
    rows = bad.any(axis=1) | bad_t
    if not rows.any():
        return None, []
    k0 = int(np.argmax(rows))
    return k0, [int(b) for b in np.nonzero(bad[k0])[0]]


class Context:
    """Computations several analyzers share, done once per trajectory and cached.

    Analyzers never read simulator internals: only ``traj`` (channels, model, info, contacts).
    """

    def __init__(self, traj: Trajectory):
        self.model = traj.model
        self._cache: dict[Any, Any] = {}
        # analyzers may run in threads (rblog.analyze.check): one lock per key, so that a value
        # is computed once, by the first thread that asks, while the others wait for it
        self._locks: dict[Any, threading.Lock] = {}
        self._locks_lock = threading.Lock()
        #: (sample index, bodies) of the first sample with a non-finite state, or None. The
        #: analyzers then see the samples before it only (drift reports it as a finding).
        self.nonfinite: tuple[int, list[int]] | None = None
        self.full_traj = traj
        self.traj = traj
        k0, bodies = _first_nonfinite(traj)
        #: state channels known to hold no NaN or inf (the consistency analyzer skips them)
        self.finite_channels = _STATE_CHANNELS if k0 is None else ()
        if k0 is not None:
            self.nonfinite = (k0, bodies)
            self.traj = traj.slice(slice(0, k0))

    def cached(self, key, fn):
        """``fn()``, computed once per key (thread-safe: the values are pure functions of the
        trajectory, so which thread computes one does not change it)."""
        try:
            return self._cache[key]
        except KeyError:
            pass
        with self._locks_lock:
            lock = self._locks.setdefault(key, threading.Lock())
        with lock:
            if key not in self._cache:
                self._cache[key] = fn()
        return self._cache[key]

    # --- basic kinematics ---------------------------------------------------------------------
    @property
    def dts(self) -> np.ndarray:
        """(T-1,) sample intervals (s)."""
        return self.cached("dts", lambda: np.diff(self.traj.t))

    @property
    def dt_step(self) -> float:
        """The integrator step (s): RunInfo.dt, or the smallest sample interval if not logged."""
        def f():
            dt = getattr(self.traj.info, "dt", 0.0) or 0.0
            if dt > 0 and math.isfinite(dt):
                return float(dt)
            d = self.dts
            return float(d[d > 0].min()) if (d > 0).any() else 0.0
        return self.cached("dt_step", f)

    @property
    def mass(self) -> np.ndarray:
        return np.asarray(self.model.body_mass, float)

    # --- the forces besides contacts ----------------------------------------------------------
    # A body's momentum changes by gravity, its contacts and the other loads of
    # Model.body_impulse_supplied's kinds (applied, passive, actuator, joint). Constant loads
    # (m g, and the model's body_force_world / body_torque_world where the applied impulse is
    # not logged) are handled in closed form (force_const, torque_const); the logged per-interval
    # impulses of the other kinds are summed into ext_linear / ext_angular. p_eff / l_eff are the
    # momenta with those logged impulses taken out (cumulatively from the first sample), so that
    # a body under any logged load reads as a body under its constant loads and contacts only:
    # every check written for free bodies (jumps, free flights, inferred contact impulses)
    # applies to it unchanged. A body with a load of unknown size (a kind SUPPLIED_MISSING) or
    # without dynamics (kinematic, static) is in momentum_unjudged, with the reason.
    def _loads(self):
        def f():
            model, tr = self.model, self.traj
            n = tr.n_bodies
            sup = np.asarray(model.body_impulse_supplied, np.int64).reshape(n, len(IMPULSE_KINDS))
            kind = np.asarray(model.body_kind, np.int64).reshape(n)
            applied_logged = sup[:, IMPULSE_KINDS.index("applied")] == SUPPLIED_LOGGED
            force = np.where(applied_logged[:, None], 0.0,
                             np.asarray(model.body_force_world, float))
            torque = np.where(applied_logged[:, None], 0.0,
                              np.asarray(model.body_torque_world, float))
            unjudged: dict[int, str] = {}
            for i in np.flatnonzero(kind == BODY_KINEMATIC):
                unjudged[int(i)] = "moves as its writer drives it (kinematic)"
            for i in np.flatnonzero(kind == BODY_STATIC):
                unjudged[int(i)] = "is static"
            lin = ang = None
            # (T, N): intervals (by the sample ending them) in which a body's logged kind is
            # NaN: its writer did not know that impulse there (pybullet: a joint limit's)
            gaps: dict[str, np.ndarray] = {}
            for kk in IMPULSE_KINDS[1:]:
                col = sup[:, IMPULSE_KINDS.index(kk)]
                for i in np.flatnonzero(col == SUPPLIED_MISSING):
                    unjudged.setdefault(int(i), f"its {kk} impulses are not in the log")
                if not (col == SUPPLIED_LOGGED).any():
                    continue
                got = tr.impulse(kk)
                if got is None:
                    continue
                nan = (np.isnan(got[0]).any(axis=2) | np.isnan(got[1]).any(axis=2)) \
                    & (col == SUPPLIED_LOGGED)[None, :]
                if nan.any():
                    gaps[kk] = nan
                a, b = (np.nan_to_num(x, nan=0.0) for x in got)
                lin = a.copy() if lin is None else lin + a
                ang = b.copy() if ang is None else ang + b
            return dict(force=force, torque=torque, unjudged=unjudged, ext_lin=lin, ext_ang=ang,
                        gaps=gaps)
        return self.cached("loads", f)

    @property
    def impulse_gaps(self) -> dict[str, np.ndarray]:
        """{kind: (T, N) bool}: the intervals (by the sample ending them) in which a body
        whose kind is logged has NaN there, the writer not knowing it (pybullet: the impulse of
        a joint limit); its momentum is not judged in them. Empty when there are none."""
        return self._loads()["gaps"]

    @property
    def interval_unjudged(self) -> np.ndarray | None:
        """(T, N) bool, any kind of :attr:`impulse_gaps`; None when there are none."""
        g = self.impulse_gaps
        if not g:
            return None
        return self.cached("interval_unjudged", lambda: np.logical_or.reduce(list(g.values())))

    @property
    def force_const(self) -> np.ndarray:
        """(N, 3) constant applied force besides gravity (N): body_force_world, or 0 where the
        log carries the applied impulses (they include it)."""
        return self._loads()["force"]

    @property
    def torque_const(self) -> np.ndarray:
        """(N, 3) constant applied torque (N m), likewise."""
        return self._loads()["torque"]

    @property
    def momentum_unjudged(self) -> dict[int, str]:
        """Bodies whose momentum cannot be judged: body index -> the reason."""
        return self._loads()["unjudged"]

    @property
    def joint_impulse_logged(self) -> np.ndarray:
        """(N,) bool: bodies whose joint constraint impulses the log carries."""
        return self.cached("joint_logged", lambda: np.asarray(
            self.model.body_impulse_supplied).reshape(self.traj.n_bodies, len(IMPULSE_KINDS))[
            :, IMPULSE_KINDS.index("joint")] == SUPPLIED_LOGGED)

    @property
    def integration_logged(self) -> np.ndarray:
        """(N,) bool: bodies whose log carries the integration kind, the momentum change of the
        engine's steps beyond its forces at their starts: their balance closes to round-off."""
        return self.cached("integration_logged", lambda: np.asarray(
            self.model.body_impulse_supplied).reshape(self.traj.n_bodies, len(IMPULSE_KINDS))[
            :, IMPULSE_KINDS.index("integration")] == SUPPLIED_LOGGED)

    @property
    def ext_linear(self) -> np.ndarray | None:
        """(T, N, 3) logged non-contact impulses besides gravity and force_const over the
        interval ending at each sample (N s, world), or None when the log has none."""
        return self._loads()["ext_lin"]

    @property
    def ext_angular(self) -> np.ndarray | None:
        """(T, N, 3) their angular part about each body's centre of mass (N m s), or None."""
        return self._loads()["ext_ang"]

    def _eff(self, name):
        def f():
            raw = getattr(self.traj, name)
            ext = self.ext_linear if name == "linear_momentum" else self.ext_angular
            if ext is None:
                return raw
            cum = np.cumsum(ext[1:], axis=0)
            out = np.array(raw, float, copy=True)
            out[1:] -= cum
            return out
        return self.cached(("eff", name), f)

    @property
    def loaded(self) -> np.ndarray:
        """(N,) bool: bodies that are not judged, or on which a logged non-contact load besides
        the constant ones acts at some interval (their energy and impacts need that load's
        work and moment arm, which a free body's checks leave out)."""
        def f():
            # a load counts where it moves the body's momentum by more than the jump detector's
            # resolution (MOMENTUM_JUMP_REL of m (max |v| + |a| dt), or of max |L|): an engine's
            # round-off in a load that is zero (MuJoCo's 2e-15 N s joint impulse on a free
            # ball) is no load
            tr = self.traj
            out = np.zeros(tr.n_bodies, bool)
            out[list(self.momentum_unjudged)] = True
            if tr.n_samples < 2:
                return out
            if self.ext_linear is not None:
                p_scale = self.mass * (self.speed.max(axis=0) + np.linalg.norm(self.accel, axis=1)
                                       * self.dt_step + tol.MOMENTUM_SPEED_FLOOR_MPS)
                out |= np.linalg.norm(self.ext_linear[1:], axis=2).max(axis=0) > \
                    tol.MOMENTUM_JUMP_REL * p_scale
            if self.ext_angular is not None:
                i_max = np.asarray(self.model.body_inertia_diag, float).max(axis=1)
                l_scale = np.linalg.norm(tr.angular_momentum, axis=2).max(axis=0) \
                    + i_max * tol.MOMENTUM_SPIN_FLOOR_RADPS
                out |= np.linalg.norm(self.ext_angular[1:], axis=2).max(axis=0) > \
                    tol.MOMENTUM_JUMP_REL * l_scale
            return out
        return self.cached("loaded", f)

    def groups_with(self, grp: "Groups", bodies: np.ndarray) -> np.ndarray:
        """(C,) bool: the groups of ``grp`` with a member among ``bodies`` ((N,) bool)."""
        if not len(grp) or not bodies.any():
            return np.zeros(len(grp), bool)
        return np.bincount(grp.mem_group, weights=bodies[grp.mem_i].astype(float),
                           minlength=len(grp)) > 0

    @property
    def p_eff(self) -> np.ndarray:
        """(T, N, 3) linear momentum less the logged non-contact impulses since the first sample."""
        return self._eff("linear_momentum")

    @property
    def l_eff(self) -> np.ndarray:
        """(T, N, 3) angular momentum (about each centre of mass) less the logged non-contact
        angular impulses since the first sample."""
        return self._eff("angular_momentum")

    @property
    def accel(self) -> np.ndarray:
        """(N, 3) acceleration of a body under its constant loads: g + force_const/m (m/s^2)."""
        return self.cached("accel", lambda: np.asarray(self.model.gravity, float)[None, :]
                           + self.force_const / self.mass[:, None])

    @property
    def has_torque(self) -> np.ndarray:
        return self.cached("torque", lambda: np.abs(self.torque_const).max(axis=1) > 0)

    def contact_impulse_known(self) -> np.ndarray:
        """(N,) bool: bodies whose contact impulses the log carries at every interval (so when
        they touch anything is known, whatever their shapes)."""
        logged = self.logged_contact_impulse()
        if logged is None or self.traj.n_samples < 2:
            return np.zeros(self.traj.n_bodies, bool)
        return ~np.isnan(logged[0][1:]).any(axis=(0, 2))

    def logged_contact_impulse(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(linear, angular) (T, N, 3) logged per-interval contact impulses, NaN for bodies
        that do not log them; None when the log has none."""
        return self.cached("contact_impulse", lambda: self.traj.impulse("contact"))

    def _kin(self):
        def f():
            tr = self.traj
            t_n, n = tr.n_samples, tr.n_bodies
            out = [np.empty((t_n, n)) for _ in range(4)]
            kn = max(t_n - 1, 0)
            jump = np.empty((kn, n), np.bool_)
            sweep = np.empty((kn, n))
            c = np.ascontiguousarray

            def kernel(p, l, out, jump, sweep):
                _audit.kinematics(c(tr.t, dtype=np.float64), c(tr.position, dtype=np.float64),
                                  c(tr.velocity, dtype=np.float64), c(p, dtype=np.float64),
                                  c(l, dtype=np.float64),
                                  c(tr.angular_velocity, dtype=np.float64), c(self.mass),
                                  c(self.mass[:, None] * self.accel, dtype=np.float64),
                                  c(self.torque_const, dtype=np.float64),
                                  c(self.rho, dtype=np.float64),
                                  c(np.asarray(self.model.body_inertia_diag, float).max(axis=1)),
                                  float(tol.MOMENTUM_JUMP_REL), *out, jump, sweep)

            # energies and speeds from the logged momenta; jumps from the effective ones (the
            # logged non-contact impulses taken out), in a second pass only when they differ
            kernel(tr.linear_momentum, tr.angular_momentum, out, jump, sweep)
            if self.ext_linear is not None:
                scratch = [np.empty((t_n, n)) for _ in range(4)]
                kernel(self.p_eff, self.l_eff, scratch, jump, np.empty((kn, n)))
            return dict(speed=out[0], spin=out[1], ke=out[2], u=out[3], jump=jump, sweep=sweep)
        return self.cached("kin", f)

    @property
    def speed(self) -> np.ndarray:
        """(T, N) |v| (m/s)."""
        return self._kin()["speed"]

    @property
    def spin(self) -> np.ndarray:
        """(T, N) |ω| (rad/s)."""
        return self._kin()["spin"]

    @property
    def rho(self) -> np.ndarray:
        return self.cached("rho", lambda: geometry.bounding_radius(self.model))

    def impulse(self, k: np.ndarray, i: np.ndarray) -> np.ndarray:
        """(P, 3) contact impulse of bodies i over intervals k (N s), inferred from the momenta:
        ``J = P_eff(k+1) - P_eff(k) - (m g + F) dt``. Constant forces change momentum exactly in
        every integrator, so a free body has J = 0 to round-off."""
        out = np.empty((len(k), 3))
        c = np.ascontiguousarray
        _audit.impulse_kernel(c(self.p_eff, dtype=np.float64),
                              c(self.dts, dtype=np.float64), c(self.mass, dtype=np.float64),
                              c(self.accel, dtype=np.float64), c(k, dtype=np.int64),
                              c(i, dtype=np.int64), out)
        return out

    def jumps(self) -> np.ndarray:
        """(T-1, N) True where the momentum (or angular momentum) changed beyond what gravity and
        the applied force and torque explain, by more than MOMENTUM_JUMP_REL of its scale
        m (|v| + |a| dt) (or |L|)."""
        return self._kin()["jump"]

    def geom_poses(self):
        """World frames of every geom at every sample, (T, G, 3) and (T, G, 3, 3)
        (rblog.analyze.shapes.geom_poses), computed once per context."""
        from rblog.analyze import shapes

        tr = self.traj
        return self.cached("geom_poses", lambda: shapes.geom_poses(self.model, tr.position,
                                                                     tr.rotation))

    def proximity(self, pad: float) -> geometry.Proximity:
        tr = self.traj
        return self.cached(("prox", pad), lambda: geometry.proximity(
            self.model, tr.position, tr.rotation, pad, self.sweep() if tr.n_samples > 1 else None))

    def sweep(self) -> np.ndarray:
        """(T-1, N) how far any point of a body can move over each interval (m):
        ``dt (max |v| + ρ max |ω|) + |a| dt² / 2`` (ρ: bounding radius)."""
        return self._kin()["sweep"]

    def contact_interval_of_steps(self, steps: np.ndarray) -> np.ndarray:
        """Interval index k (contacts of steps in (step[k], step[k+1]]) or -1."""
        st = self.traj.step
        k = np.searchsorted(st, steps, side="left") - 1
        return np.where((k >= 0) & (k < len(st) - 1), k, -1)

    def touches(self, cd: float):
        """Possible contacts per interval.

        Returns dict: ``ground`` (T-1, N) bool, ``static_rows`` (indices into the proximity
        interval table of body-static rows in reach), ``dyn_k, dyn_a, dyn_b`` body-body edges
        (unique, a < b),
        ``any`` (T-1, N) bool, ``n_static`` (T-1, N) number of static features in reach,
        ``static_id`` (T-1, N) the last one seen (-1 ground, m box).
        """
        def f():
            tr = self.traj
            t_n, n = tr.n_samples, tr.n_bodies
            kn = max(t_n - 1, 0)
            prox = self.proximity(cd)
            sw = self.sweep()
            ground = np.zeros((kn, n), bool)
            if prox.ground_sep is not None and kn:
                g = prox.ground_sep
                ground = np.minimum(g[:-1], g[1:]) <= sw + cd
            reach = np.minimum(prox.iv_sep0, prox.iv_sep1) <= (
                sw[prox.iv_k, prox.iv_a] + np.where(prox.iv_b < n, sw[prox.iv_k, np.minimum(
                    prox.iv_b, n - 1)], 0.0) + cd)
            is_dyn = prox.iv_b < n
            dk, da, db = prox.iv_k[reach & is_dyn], prox.iv_a[reach & is_dyn], \
                prox.iv_b[reach & is_dyn]
            srow = np.nonzero(reach & ~is_dyn)[0]
            n_static = ground.astype(np.int64)
            static_id = np.where(ground, -1, -2)
            n_static += np.bincount(prox.iv_k[srow] * n + prox.iv_a[srow],
                                    minlength=kn * n).reshape(kn, n)
            static_id[prox.iv_k[srow], prox.iv_a[srow]] = prox.iv_b[srow] - n
            # logged contacts of the interval's steps
            c = tr.contacts
            if len(c) and kn:
                ck = self.contact_interval_of_steps(c.step)
                ok = ck >= 0
                ca, cb = c.body_a[ok].astype(np.int64), c.body_b[ok].astype(np.int64)
                ck = ck[ok]
                valid = (ca >= 0) & (ca < n)
                st = valid & (cb == STATIC_BODY)
                dyn = valid & (cb >= 0) & (cb < n) & (cb != ca)
                extra = st & (n_static[ck, ca] == 0)
                if tr.model.ground and len(ck):
                    # a row off the ground's normal while the ground is in reach: another
                    # static feature (a plane the contract's ground and boxes do not hold)
                    off = np.asarray(c.normal)[ok] @ np.asarray(tr.model.ground_normal, float) \
                        < math.cos(tol.STATIC_NORMAL_OTHER_RAD)
                    other = st & off & ground[ck, np.clip(ca, 0, n - 1)]
                    if other.any():
                        key = np.unique(ck[other] * n + ca[other])
                        n_static.reshape(-1)[key] += 1
                        static_id.reshape(-1)[key] = -3
                n_static[ck[extra], ca[extra]] = 1
                static_id[ck[extra], ca[extra]] = -3  # unknown static feature
                dk = np.concatenate([dk, ck[dyn]])
                da = np.concatenate([da, np.minimum(ca, cb)[dyn]])
                db = np.concatenate([db, np.maximum(ca, cb)[dyn]])
                if len(dk):
                    key = np.unique((dk * n + da) * n + db)
                    dk, da, db = key // (n * n), (key // n) % n, key % n
            none = shapeless(self.model)
            logged = self.logged_contact_impulse()
            # a body whose contact impulses are logged touches nothing where they are zero
            none &= ~self.contact_impulse_known()
            if none.any() and not len(c) and kn:
                # a body without a shape in a log without contact rows: its contacts cannot be
                # found from the poses. It may touch an unknown static feature at any interval
                # (so it is never taken for a body in free flight), and any body whose momentum
                # jumps in an interval where it is (its geometry unknown, it may be the partner)
                # A body without geoms either has no separation at all (its centre's height is
                # none: plane_separation takes it for a point), so the ground or a static box near
                # its centre is not a contact of its: its static feature is unknown everywhere
                add = none[None, :] & ((n_static == 0) | ~_has_geoms(self.model)[None, :])
                n_static = np.where(add, np.maximum(n_static, 1), n_static)
                static_id = np.where(add, -3, static_id)
                jump = self.jumps()
                ek, eb = np.nonzero(jump)
                for s_ in np.flatnonzero(none):
                    m_ = eb != s_
                    dk = np.concatenate([dk, ek[m_]])
                    da = np.concatenate([da, np.minimum(eb[m_], s_)])
                    db = np.concatenate([db, np.maximum(eb[m_], s_)])
                if len(dk):
                    key = np.unique((dk * n + da) * n + db)
                    dk, da, db = key // (n * n), (key // n) % n, key % n
            if logged is not None and kn:
                # a body whose logged contact impulse over an interval is not zero touched
                # something in it, seen by the poses and contact rows or not (a contact between
                # two samples): where nothing else is in reach, an unknown static feature
                lin, ang = logged
                hit = (np.abs(np.nan_to_num(lin[1:])).max(axis=2) > 0) | \
                    (np.abs(np.nan_to_num(ang[1:])).max(axis=2) > 0)
                add = hit & (n_static == 0)
                add[dk, da] = False
                add[dk, db] = False
                n_static = np.where(add, 1, n_static)
                static_id = np.where(add, -3, static_id)
            anyt = n_static > 0
            anyt[dk, da] = True
            anyt[dk, db] = True
            return dict(ground=ground, static_rows=srow, dyn_k=dk, dyn_a=da, dyn_b=db, any=anyt,
                        n_static=n_static, static_id=static_id)
        return self.cached(("touch", cd), f)

    def groups(self, cd: float) -> Groups:
        """Contact groups with at least one jumped member (see the module docstring)."""
        def f():
            jump = self.jumps()
            tch = self.touches(cd)
            order = np.argsort(tch["dyn_k"], kind="stable")
            ek, ea, eb = tch["dyn_k"][order], tch["dyn_a"][order], tch["dyn_b"][order]
            cap = int(jump.sum()) + 2 * len(ek)
            g_k, g_size, g_nstat, g_sid = (np.empty(cap, np.int64) for _ in range(4))
            m_k, m_i, m_g = (np.empty(cap, np.int64) for _ in range(3))
            a = np.ascontiguousarray
            c, q = _audit.groups_kernel(a(jump, dtype=np.bool_),
                                        a(tch["n_static"], dtype=np.int64),
                                        a(tch["static_id"], dtype=np.int64),
                                        a(ek, dtype=np.int64), a(ea, dtype=np.int64),
                                        a(eb, dtype=np.int64), g_k, g_size, g_nstat, g_sid, m_k,
                                        m_i, m_g)
            nst = g_nstat[:c]
            return Groups(k=g_k[:c], size=g_size[:c], static=nst > 0, static_features=nst,
                          static_id=g_sid[:c], mem_group=m_g[:q], mem_k=m_k[:q], mem_i=m_i[:q])
        return self.cached(("groups", cd), f)

    # --- energy ------------------------------------------------------------------------------
    def energies(self):
        """(KE (T, N), U (T, N)): kinetic energy recomputed from the logged momenta and angular
        velocity, and the potential of gravity plus constant applied forces (-(m g + F).x)."""
        k = self._kin()
        return k["ke"], k["u"]

    def group_energy(self, cd: float, rel: float, position_correction_m: float,
                     dt_factor: float = tol.ENERGY_DT_FACTOR):
        """Energy change of each contact group across its interval, and what may explain it.

        Returns dict of (C,) arrays: ``change`` (J, kinetic + potential of gravity and applied
        forces); ``allowed`` (J): per member dt_factor m |a| dt (|v_k| + |v_k+1|) / 2 (the shadow
        energy of a first-order gravity step) + m |a| position_correction_m (an engine lifting a
        body out of penetration), plus rel x ``ke_scale``; ``ke_scale`` (J, the members' max
        kinetic energy at the two samples); ``scale`` (ke_scale + the dt and position
        allowances: the denominator of relative figures, finite for a group at rest);
        ``restitution`` (the largest configured restitution in play: members', and the static
        features' in reach) and ``torque_free``.
        """
        def f():
            grp = self.groups(cd)
            c = len(grp)
            g, mk, mi = grp.mem_group, grp.mem_k, grp.mem_i
            ke, u = self.energies()
            e = ke + u
            mm = self.mass[mi]
            amag = np.linalg.norm(self.accel, axis=1)[mi]
            sp0, sp1 = self.speed[mk, mi], self.speed[mk + 1, mi]
            change = grp.sum(e[mk + 1, mi] - e[mk, mi])
            ke_scale = grp.sum(np.maximum(ke[mk, mi], ke[mk + 1, mi]))
            base = grp.sum(0.5 * dt_factor * mm * amag * self.dt_step * (sp0 + sp1)
                           + mm * amag * position_correction_m)
            rest = grp.max(np.asarray(self.model.body_restitution, float)[mi])
            sid = np.where(grp.static_features == 1, grp.static_id, -2)
            s_rest, _ = static_material(self.model, sid)
            rest = np.where(grp.static, np.maximum(rest, s_rest), rest)
            torque_free = grp.sum(self.has_torque[mi].astype(float)) == 0
            return dict(change=change, base=base, ke_scale=ke_scale, restitution=rest,
                        torque_free=torque_free)
        d = dict(self.cached(("group_energy", cd, position_correction_m, dt_factor), f))
        d["allowed"] = d["base"] + rel * d["ke_scale"]
        # scale for relative figures: the kinetic energy, plus the allowance (a group at rest has
        # no kinetic energy)
        d["scale"] = d["ke_scale"] + d["base"] + 1e-300
        return d


def static_material(model: Model, static_id: np.ndarray):
    """(restitution, friction) of static features: -1 ground, m static box m, other: worst case
    (max restitution, max friction over every static feature)."""
    rest = np.concatenate([[model.ground_restitution],
                           np.asarray(model.static_box_restitution, float)])
    fric = np.concatenate([[model.ground_friction], np.asarray(model.static_box_friction, float)])
    idx = np.where(static_id >= 0, static_id + 1, 0)
    unknown = static_id < -1
    r = np.where(unknown, rest.max(), rest[np.minimum(idx, len(rest) - 1)])
    f = np.where(unknown, fric.max(), fric[np.minimum(idx, len(fric) - 1)])
    return r, f


def _combine(a, b, rule: str):
    a, b = np.asarray(a, float), np.asarray(b, float)
    if rule == "max":
        return np.maximum(a, b)
    if rule == "min":
        return np.minimum(a, b)
    if rule == "product":
        return a * b
    if rule == "mean":
        return 0.5 * (a + b)
    return np.sqrt(a * b)  # "geometric"


def combine_friction(mu_a, mu_b, rule: str = "geometric"):
    """Friction of a pair by the log's rule (RunInfo.combine_friction): ``geometric``
    sqrt(mu_a mu_b) (rblog, Box2D's b2MixFriction), ``max`` (MuJoCo), ``product`` (Bullet),
    ``min``, ``mean``."""
    return _combine(mu_a, mu_b, rule)


def combine_restitution(e_a, e_b, rule: str = "max"):
    """Restitution of a pair by the log's rule (RunInfo.combine_restitution): ``max`` (rblog,
    Box2D's b2MixRestitution), ``product`` (Bullet), ``geometric``, ``min``, ``mean``."""
    return _combine(e_a, e_b, rule)
