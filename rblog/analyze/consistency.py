"""Consistency of a log with its own contract: do the channels agree with each other?

A log written by another program can follow the layout of docs/log-format.md and still mean
something else: quaternions in xyzw order where wxyz is expected, a transposed rotation matrix,
angular velocity in the body frame where the world frame is expected, velocity and momentum that
are not ``p = m v``, a clock that runs backwards. Such a log loads silently and would give wrong
verdicts, so these checks run when a log is read (``rblog.load`` adds them to ``warnings``) and as
the first analyzer of ``rblog check``. Each finding names the channel and the likely cause.

Checks (all from logged channels and the body table; tolerances in rblog.analyze.tolerances):

* finite values in every state channel; ``t`` and ``step`` strictly increasing;
* ``quat_wxyz`` vs ``rotation``: ``||R(q/|q|) - R||_F``. When they disagree, the hypotheses
  "quaternion in xyzw order" (reorder and compare) and "matrix transposed" are tested and the
  one that makes them agree is named;
* ``linear_momentum = m velocity``;
* ``angular_velocity = R diag(1/I_body) R^T angular_momentum`` (world frame; the contract's
  definition, so a drifted R is not counted here: drift judges it);
* kinematics: the logged orientation must turn at the logged world angular velocity. Over each
  sample interval the rotation ``dR = R(k+1) R(k)^T`` has rotation vector ``theta`` (world
  frame); ``theta / dt`` must match the mean of ``w(k)`` and ``w(k+1)`` (midpoint rule, error
  ~(|w| dt)^2; the mean rate is compared with the segment between the end rates, which a
  first-order integrator's rate lies on), with CONSISTENCY_CORRECTION (1e-3 rad) of turn per
  interval allowed on top (an engine's position correction turns a pressed body without a
  velocity) and intervals turning less than it not used. Intervals whose w changes by more
  than a quarter (an impulse: a contact) are left out, and, when a body would fail otherwise, the intervals of the
  momentum analyzer's impact events (:func:`impact_intervals`: an impact between samples changes
  w at an unknown moment), and the intervals of several steps of a body driven by a logged
  non-contact load (its net over an interval past SMOOTH_FRAC of the momentum: the load changes
  at every step between the samples; such a body with nothing else left is named not judged);
  the median mismatch over a body's intervals is judged. When it
  fails, the same test under "w is body frame" (``R w``), "matrix transposed" and "quaternion in
  xyzw order" names the cause; when R is not
  orthonormal (||R^T R - I||_F past the drift analyzer's tolerance) and its rotation part (polar
  decomposition) turns at the logged w, the finding says so ("R is not orthonormal: see drift"):
  the stretch of an integrator that does not re-orthonormalize, not a logging bug. The same for
  position and velocity (``dx / dt`` vs the mean velocity, with one sample's gravity change
  allowed).

May import numpy and rblog.contract / rblog.analyze only (never rblog.engine).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rblog.analyze import _audit
from rblog.analyze import tolerances as T
from rblog.analyze.base import Analyzer, Context, Finding, Result, Worst, all_finite
from rblog.contract.orientation import quat_wxyz_to_matrix
from rblog.contract.trajectory import BODY_CHANNELS, TOTAL_CHANNELS, Trajectory


@dataclass
class Issue:
    """One disagreement: which check, which channel, the likely cause, where and how big."""

    check: str
    channel: str
    message: str
    value: float
    tolerance: float
    step: int
    t: float
    bodies: list[int]


SMOOTH_FRAC = T.CONSISTENCY_SMOOTH_FRAC

_XYZW_AS_WXYZ = [3, 0, 1, 2]  # a quaternion stored (x, y, z, w) read as (w, x, y, z) -> fix


def _first(mask_tn: np.ndarray) -> tuple[int, list[int]]:
    """First sample where any body is flagged, and the flagged bodies there."""
    k = int(np.argmax(mask_tn.any(axis=1)))
    return k, [int(b) for b in np.flatnonzero(mask_tn[k])]


def _names(traj: Trajectory, bodies) -> str:
    names = [repr(traj.model.body_name[b]) for b in list(bodies)[:3]]
    more = f" +{len(bodies) - 3} more" if len(bodies) > 3 else ""
    return ", ".join(names) + more


def _mv(m, v):
    """(..., 3, 3) @ (..., 3) -> (..., 3) (matmul: much faster than einsum on big stacks)."""
    return (m @ v[..., None])[..., 0]


def _segment_distance(r, a, b):
    """|r - closest point of the segment [a, b]| over the last axis: an integrator's mean rate
    over an interval lies between the rates at its ends (explicit, semi-implicit, midpoint alike)
    when nothing kicks the body inside it."""
    u = b - a
    uu = np.einsum("...i,...i->...", u, u)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(uu > 0, np.einsum("...i,...i->...", r - a, u) / uu, 0.0)
    s = np.clip(s, 0.0, 1.0)
    return np.linalg.norm(r - (a + s[..., None] * u), axis=-1)


def _rotation_part(rot):
    """The rotation nearest each matrix of ``rot`` (..., 3, 3): U V^T of its SVD (the orthogonal
    factor of the polar decomposition), with det +1."""
    u, _, vt = np.linalg.svd(rot)
    r = u @ vt
    flip = np.linalg.det(r) < 0
    if flip.any():
        u[flip, :, 2] *= -1.0
        r[flip] = u[flip] @ vt[flip]
    return r


def interval_rotvec(rot, k1, k0, b):
    """Rotation vector (angle times axis, world frame, rad) of R(k1) R(k0)^T of body b, rot
    (T, N, 3, 3): a tuple (x, y, z) (the compiled passes' own function, csrc/audit/audit.hpp)."""
    return _audit.interval_rotvec(np.ascontiguousarray(rot, dtype=np.float64), int(k1), int(k0),
                                  int(b))


def _kinematic_median(rot, omega_world, dts, min_angle, skip=None):
    """Per body: (median relative mismatch, usable interval count) between the rotation vector of
    R(k+1) R(k)^T over dt and the logged world angular velocity (kinematic_rel,
    csrc/audit/consistency.cpp). rot (T, N, 3, 3), omega_world (T, N, 3), dts (T-1,); skip
    (T-1, N) bool: intervals left out (impacts)."""
    rel = np.empty((len(dts), rot.shape[1]))
    _audit.kinematic_rel(np.ascontiguousarray(rot, np.float64),
                         np.ascontiguousarray(omega_world, np.float64),
                         np.ascontiguousarray(dts, np.float64), float(min_angle),
                         float(SMOOTH_FRAC), float(T.CONSISTENCY_CORRECTION), rel)
    return _median(rel, skip)


def _median(rel, skip=None):
    """Per body (column): (nanmedian, count of non-NaN) of rel (T-1, N), without the ``skip``
    intervals."""
    if skip is not None:
        rel = np.where(skip, np.nan, rel)
    # np.nanmedian's value, from one sort of every column (NaN sorts last): the middle one of a
    # column's c values, or the mean of the middle two (np.nanmedian goes column by column)
    s = np.array(rel.T, np.float64, order="C")
    s.sort(axis=1)
    count = rel.shape[0] - np.isnan(s).sum(axis=1)
    med = np.full(rel.shape[1], np.nan)
    cols = np.flatnonzero(count > 0)
    c = count[cols]
    lo, hi = s[cols, (c - 1) // 2], s[cols, c // 2]
    med[cols] = np.where(c % 2 == 1, lo, (lo + hi) / 2)
    return med, count


def impact_intervals(ctx: Context) -> np.ndarray:
    """(T-1, N) bool: the intervals in which each body is in one of the momentum analyzer's impact
    events (rblog.analyze.events, with the momentum analyzer's defaults): the kinematic checks
    leave them out. Between two samples an impact changes w (and v) at an unknown moment, and
    an engine's position correction turns and shifts a pressed body without a velocity, so the
    rate over such an interval has nothing to do with the end samples' rates (rblog's loose
    500-box pile: box 41's w goes 0.14 -> 0.06 rad/s while its pose turns as if at 1 rad/s)."""
    from rblog.analyze.events import impact_events

    ev = impact_events(ctx, T.CONTACT_DISTANCE_M, T.ENERGY_DT_FACTOR)
    return ev.impact_intervals(T.MOMENTUM_IMPACT_SPEED_MPS, max(ctx.traj.n_samples - 1, 0),
                               ctx.traj.n_bodies)


def inspect(traj: Trajectory, tol: dict | None = None, finite=(), ctx: Context | None = None
            ) -> list[Issue]:
    """Every consistency issue of ``traj`` (see the module docstring); ``tol`` overrides the
    defaults of :class:`ConsistencyAnalyzer` by name; ``finite`` names channels already known
    to hold no NaN or inf (not scanned again). ``ctx``: the analyzers' Context of ``traj``
    (its impact events are computed, once, only when a kinematic check would otherwise fail)."""
    tol = {**ConsistencyAnalyzer.defaults, **(tol or {})}
    out: list[Issue] = []
    n_t, n = traj.n_samples, traj.n_bodies
    if n_t == 0 or n == 0:
        return out
    t, step = np.asarray(traj.t, float), np.asarray(traj.step)

    # finite values
    known_finite, finite = finite, np.ones(n_t, bool)
    for name in BODY_CHANNELS:
        if name in known_finite or all_finite(getattr(traj, name)):
            continue
        a = np.asarray(getattr(traj, name), float).reshape(n_t, n, -1)
        bad = ~np.isfinite(a).all(axis=-1)
        if bad.any():
            finite &= ~bad.any(axis=1)
            k, bodies = _first(bad)
            out.append(Issue("finite", name, f"{name} is not finite from step {int(step[k])} "
                             f"(t = {t[k]:.6g} s) for {_names(traj, bodies)}", float("inf"), 0.0,
                             int(step[k]), float(t[k]), bodies))
    for name in ("t", *TOTAL_CHANNELS):
        a = np.asarray(getattr(traj, name), float).reshape(n_t, -1)
        bad = ~np.isfinite(a).all(axis=-1)
        if bad.any():
            if name == "t":
                finite &= ~bad
            k = int(np.argmax(bad))
            out.append(Issue("finite", name, f"{name} is not finite from sample {k}", float("inf"),
                             0.0, int(step[k]), float(t[k]) if np.isfinite(t[k]) else 0.0, []))
    # monotonic time
    for name, a in (("t", t), ("step", step)):
        back = np.flatnonzero(~(np.diff(a) > 0))
        if len(back):
            k = int(back[0]) + 1
            out.append(Issue("time", name, f"{name} does not increase at sample {k} "
                             f"({a[k - 1]!r} then {a[k]!r}): samples out of order or repeated",
                             float(a[k - 1] - a[k]), 0.0, int(step[k]), float(t[k]), []))
    keep = np.flatnonzero(finite)
    if len(keep) == 0:
        return out
    whole = len(keep) == n_t
    sel = lambda a: np.asarray(a, float) if whole else np.asarray(a, float)[keep]  # noqa: E731
    if not whole:
        t, step = t[keep], step[keep]
    rot, quat = sel(traj.rotation), sel(traj.quat_wxyz)
    omega, lw = sel(traj.angular_velocity), sel(traj.angular_momentum)
    vel, mom, pos = sel(traj.velocity), sel(traj.linear_momentum), sel(traj.position)
    model = traj.model
    mass = np.asarray(model.body_mass, float)
    inertia = np.asarray(model.body_inertia_diag, float)

    # quaternion vs matrix, p = m v, w = R diag(1/I) R^T L: one compiled pass
    shape = (len(t), n)
    err, ortho, dp, p_mag, rel_l, scale_l = (np.empty(shape) for _ in range(6))
    def c(a):
        return np.ascontiguousarray(a, dtype=np.float64)
    _audit.pointwise(c(quat), c(rot), c(mom), c(vel), c(omega), c(lw), c(mass), c(inertia), err,
                     ortho, dp, p_mag, rel_l, scale_l)
    allow = tol["quat_matrix"] + 2.0 * ortho
    bad_qm = err > allow
    if bad_qm.any():
        bodies = [int(b) for b in np.flatnonzero(bad_qm.any(axis=0))]
        k, _ = _first(bad_qm)
        r_q = quat_wxyz_to_matrix(quat)
        err_xyzw = np.linalg.norm(quat_wxyz_to_matrix(quat[..., _XYZW_AS_WXYZ]) - rot, axis=(-2, -1))
        err_tr = np.linalg.norm(r_q - np.swapaxes(rot, -1, -2), axis=(-2, -1))
        sub = bad_qm.any(axis=0)
        if (err_xyzw[:, sub] <= allow[:, sub]).all():
            channel, cause = "quat_wxyz", "quat_wxyz looks like xyzw order (scalar last)"
        elif (err_tr[:, sub] <= allow[:, sub]).all():
            channel, cause = "rotation", ("rotation looks transposed (world->body where body->"
                                          "world is expected)")
        else:
            channel, cause = "quat_wxyz", "quat_wxyz and rotation describe different orientations"
        out.append(Issue("quat_matrix", channel,
                         f"{cause}: ||R(q) - R||_F up to {float(err.max()):.3g} for "
                         f"{_names(traj, bodies)} from t = {t[k]:.6g} s", float(err.max()),
                         tol["quat_matrix"], int(step[k]), float(t[k]), bodies))

    # p = m v
    scale_p = tol["momentum_rel"] * p_mag + 1e-12
    bad = dp > scale_p
    if bad.any():
        k, _ = _first(bad)
        bodies = [int(b) for b in np.flatnonzero(bad.any(axis=0))]
        ratio = dp / np.maximum(p_mag, 1e-300)
        out.append(Issue("momentum", "linear_momentum",
                         f"linear_momentum is not mass * velocity (relative error up to "
                         f"{float(ratio.max()):.3g}) for {_names(traj, bodies)}: velocity or "
                         "momentum in another frame or unit, or the body table's mass differs",
                         float(ratio.max()), tol["momentum_rel"], int(step[k]), float(t[k]), bodies))

    bad = (rel_l > tol["angular_momentum_rel"]) & (scale_l > 1e-12)
    if bad.any():
        k, _ = _first(bad)
        bodies = [int(b) for b in np.flatnonzero(bad.any(axis=0))]
        # would a body-frame w explain it? w_logged = diag(1/I) R^T L
        body_l = _mv(np.swapaxes(rot, -1, -2), lw)
        rel_b = np.linalg.norm(omega - body_l / inertia[None], axis=-1) / np.maximum(scale_l, 1e-300)
        sub = bad.any(axis=0)
        if (rel_b[:, sub][bad[:, sub]] <= tol["angular_momentum_rel"]).all():
            cause = "angular_velocity looks like body frame (world frame is expected)"
        else:
            cause = ("angular_momentum is not R I_body R^T angular_velocity (frames, units or "
                     "the body table's inertia differ)")
        out.append(Issue("angular_momentum", "angular_velocity",
                         f"{cause}: relative error up to {float(rel_l.max()):.3g} for "
                         f"{_names(traj, bodies)} from t = {t[k]:.6g} s", float(rel_l.max()),
                         tol["angular_momentum_rel"], int(step[k]), float(t[k]), bodies))

    # kinematics: orientation turns at the logged world angular velocity
    if len(t) >= 2:
        dts = np.diff(t)
        good = dts > 0
        if not good.all():  # the time issue is reported; judge the increasing intervals only
            dts = np.where(good, dts, np.nan)
        min_angle = tol["min_angle_rad"]
        min_count = tol["min_intervals_samples"]
        rel_w = np.empty((len(dts), n))
        _audit.kinematic_rel(c(rot), c(omega), c(dts), float(min_angle), float(SMOOTH_FRAC),
                             float(T.CONSISTENCY_CORRECTION), rel_w)
        med, count = _median(rel_w)
        # position vs velocity: allow one sample's change of velocity by gravity and loads
        g = np.linalg.norm(np.asarray(model.gravity, float))
        acc = g + np.linalg.norm(np.asarray(model.body_force_world, float), axis=-1) / mass
        rel_v = np.empty((len(dts), n))
        # (min_angle in m: see the tolerance)
        _audit.linear_rel(c(pos), c(vel), c(dts), float(min_angle) * 1.0, float(SMOOTH_FRAC),
                          c(acc), float(T.CONSISTENCY_CORRECTION), rel_v)
        med_v, cnt = _median(rel_v)
        skip = None
        if whole and (((count >= min_count) & (med > tol["kinematic_rel"])).any()
                      or ((cnt >= min_count) & (med_v > tol["kinematic_rel"])).any()):
            # judged over the intervals without an impact only (computed when needed: the
            # events cost a proximity pass)
            skip = impact_intervals(ctx if ctx is not None else Context(traj))
            med, count = _median(rel_w, skip)
            med_v, cnt = _median(rel_v, skip)
        if whole and len(step) >= 2 and (np.diff(step) > 1).any() and (
                ((count >= min_count) & (med > tol["kinematic_rel"])).any()
                or ((cnt >= min_count) & (med_v > tol["kinematic_rel"])).any()):
            # bodies driven by a logged non-contact load (joints, actuators, damping, pushes):
            # one whose net over some interval exceeds SMOOTH_FRAC of the body's momentum
            # there. Sampled every several steps, such loads change at every step between the
            # samples and the log holds only their net (which can cancel while the rate swings),
            # so the end samples' rates do not describe an interval's path: those bodies'
            # intervals of several steps are left out (dm_control's walker at every 10th step
            # under random controls: median 0.68; a free body's logged loads are round-off,
            # 1e-15 of its momentum, and keep it judged)
            ctx_ = ctx if ctx is not None else Context(traj)
            strided = (np.diff(step) > 1)[:, None]
            bad_w = (count >= min_count) & (med > tol["kinematic_rel"])
            bad_v = (cnt >= min_count) & (med_v > tol["kinematic_rel"])
            before = bad_w | bad_v
            masks = []
            for ext, mom_ in ((ctx_.ext_angular, lw), (ctx_.ext_linear, mom)):
                if ext is None:
                    masks.append(np.zeros((len(step) - 1, n), bool))
                    continue
                size = np.maximum(np.linalg.norm(mom_[:-1], axis=-1),
                                  np.linalg.norm(mom_[1:], axis=-1))
                driven = (np.linalg.norm(ext[1:], axis=-1) > SMOOTH_FRAC * size).any(axis=0)
                masks.append(strided & driven[None, :])
            over_w, over_v = masks
            med_l, count_l = _median(rel_w, over_w if skip is None else (skip | over_w))
            med_vl, cnt_l = _median(rel_v, over_v if skip is None else (skip | over_v))
            # only the bodies that fail over all their intervals are judged without these
            drop = before & (over_w | over_v).any(axis=0)
            med = np.where(drop, med_l, med)
            count = np.where(drop, count_l, count)
            med_v = np.where(drop, med_vl, med_v)
            cnt = np.where(drop, cnt_l, cnt)
            gone = np.flatnonzero(drop & ((bad_w & (count < min_count))
                                          | (bad_v & (cnt < min_count))))
            if len(gone):
                out.append(Issue(
                    "not judged", "kinematics",
                    f"kinematics of {len(gone)} bodies under logged loads ({_names(traj, gone)}) "
                    f"not judged: sampled every {int(np.median(np.diff(step)))} steps, the loads "
                    "move them between the samples (the log holds each interval's net)",
                    0.0, 0.0, int(step[0]), float(t[0]), [int(b) for b in gone]))
        bad = (count >= min_count) & (med > tol["kinematic_rel"])
        if bad.any():
            stretch_note = ""
            skip_b = None if skip is None else skip[:, bad]
            bodies = [int(b) for b in np.flatnonzero(bad)]
            omega_as_body = _mv(rot, omega)
            hyps = (
                ("angular_velocity", "angular_velocity looks like body frame (world frame is "
                 "expected)", rot, omega_as_body),
                ("rotation", "rotation looks transposed (world->body where body->world is "
                 "expected)", np.swapaxes(rot, -1, -2), omega),
                ("quat_wxyz", "quat_wxyz looks like xyzw order (scalar last)",
                 quat_wxyz_to_matrix(quat[..., _XYZW_AS_WXYZ]), omega),
            )
            best = None
            # a stretched R (the drift analyzer's ||R^T R - I||_F past its tolerance) has no
            # rotation vector to compare: when its rotation part (polar decomposition) turns at
            # the logged w, the stretch is the cause, not the logging
            stretched = ortho[:, bad].max(axis=0) > T.DRIFT_ORTHO_ERROR
            if stretched.any():
                sub = np.flatnonzero(bad)[stretched]
                m_p, _ = _kinematic_median(_rotation_part(rot[:, sub]), omega[:, sub], dts,
                                           min_angle, None if skip is None else skip[:, sub])
                score = float(np.nanmax(m_p)) if np.isfinite(m_p).any() else np.inf
                o_max = float(ortho[:, sub].max())
                if score <= tol["kinematic_rel"]:
                    best = (score, "rotation", (
                        f"R is not orthonormal (||R^T R - I||_F up to {o_max:.3g}: see drift), so "
                        "R(k+1) R(k)^T is not a rotation; its rotation part (polar decomposition) "
                        f"turns at angular_velocity (median mismatch {score:.3g})"))
                    hyps = ()
                else:
                    stretch_note = (f"; R is not orthonormal either (||R^T R - I||_F up to "
                                    f"{o_max:.3g}: see drift), and its rotation part does not "
                                    f"turn at angular_velocity (median mismatch {score:.3g})")
            for channel, cause, r_h, w_h in hyps:
                m_h, c_h = _kinematic_median(r_h[:, bad], w_h[:, bad], dts, min_angle, skip_b)
                score = float(np.nanmax(m_h)) if np.isfinite(m_h).any() else np.inf
                if score <= tol["kinematic_rel"] and (best is None or score < best[0]):
                    best = (score, channel, cause)
            channel, cause = (best[1], best[2]) if best else (
                "angular_velocity", "angular_velocity does not turn the logged orientation "
                "(wrong frame, sign, unit or orientation channel)" + stretch_note)
            worst = float(np.nanmax(med[bad]))
            out.append(Issue("kinematics", channel,
                             f"{cause}: the orientation's rate of change disagrees with "
                             f"angular_velocity by a median {worst:.3g} (relative) for "
                             f"{_names(traj, bodies)}", worst, tol["kinematic_rel"],
                             int(step[0]), float(t[0]), bodies))
        bad = (cnt >= min_count) & (med_v > tol["kinematic_rel"])
        if bad.any():
            bodies = [int(b) for b in np.flatnonzero(bad)]
            worst = float(np.nanmax(med_v[bad]))
            out.append(Issue("kinematics", "velocity",
                             f"velocity does not move the logged position (median relative "
                             f"mismatch {worst:.3g}) for {_names(traj, bodies)}: velocity in "
                             "another frame or unit, or positions not of the centre of mass",
                             worst, tol["kinematic_rel"], int(step[0]), float(t[0]), bodies))
    return out


def consistency_warnings(traj: Trajectory) -> list[str]:
    """One line per consistency issue of ``traj`` (what ``rblog.load`` adds to ``warnings``)."""
    return [f"contract: {i.channel}: {i.message}" for i in inspect(traj) if i.check != "not judged"]


class ConsistencyAnalyzer(Analyzer):
    name = "consistency"
    description = ("channels agree with each other: quaternion vs matrix, p = m v, L = I_world w, "
                   "orientation turning at the world angular velocity, finite values, time order")
    defaults = T.options("consistency", "quat_matrix", "momentum_rel", "angular_momentum_rel",
                         "kinematic_rel", "min_angle_rad", "min_intervals_samples")

    def analyze(self, ctx: Context) -> Result:
        # the samples before the first non-finite one (drift reports that one; load's warnings
        # name the channel)
        return self._result(ctx.traj, inspect(ctx.traj, self.tol, ctx.finite_channels, ctx))

    def _result(self, traj: Trajectory, issues: list[Issue]) -> Result:
        worst = Worst("1", self.tol["kinematic_rel"])
        findings = []
        notes = [i.message for i in issues if i.check == "not judged"]
        issues = [i for i in issues if i.check != "not judged"]
        for i in issues:
            findings.append(Finding(self.name, i.message, i.value, i.tolerance, "1", i.step, i.t,
                                    i.bodies))
            ratio = i.value / i.tolerance if i.tolerance > 0 else float("inf")
            worst.offer(ratio, i.value, i.tolerance, "1", i.step, i.t, i.bodies, i.check)
        ok = "every channel agrees with the others (quaternion/matrix, p = m v, L = I w, kinematics)"
        return self.result(worst, findings, {"issues": len(issues)}, ok_reason=ok).leave_out(notes)
