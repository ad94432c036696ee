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
  first-order integrator's rate lies on). Intervals whose w changes by more than a quarter (an impulse: a contact) are
  left out; the median mismatch over a body's intervals is judged (contacts make a few
  intervals disagree). When it fails, the same test under "w is body frame" (``R w``),
  "matrix transposed" and "quaternion in xyzw order" names the cause. The same for position and
  velocity (``dx / dt`` vs the mean velocity, with one sample's gravity change allowed).

May import numpy and rblog.contract / rblog.analyze only (never rblog.engine).
"""

from __future__ import annotations

from dataclasses import dataclass

import math

import numpy as np
from numba import njit

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


@njit(cache=True, nogil=True, inline="always")
def _row_dot(rot, k1, k0, b, i, j):
    """(R(k1) R(k0)^T)_ij of body b: row i of R(k1) dot row j of R(k0)."""
    return (rot[k1, b, i, 0] * rot[k0, b, j, 0] + rot[k1, b, i, 1] * rot[k0, b, j, 1]
            + rot[k1, b, i, 2] * rot[k0, b, j, 2])


@njit(cache=True, nogil=True, inline="always")
def interval_rotvec(rot, k1, k0, b):
    """Rotation vector (angle times axis, world frame, rad) of R(k1) R(k0)^T of body b, from the
    entries it needs as scalars (an array here was a heap allocation per body-sample)."""
    d00 = _row_dot(rot, k1, k0, b, 0, 0)
    d11 = _row_dot(rot, k1, k0, b, 1, 1)
    d22 = _row_dot(rot, k1, k0, b, 2, 2)
    vx = 0.5 * (_row_dot(rot, k1, k0, b, 2, 1) - _row_dot(rot, k1, k0, b, 1, 2))
    vy = 0.5 * (_row_dot(rot, k1, k0, b, 0, 2) - _row_dot(rot, k1, k0, b, 2, 0))
    vz = 0.5 * (_row_dot(rot, k1, k0, b, 1, 0) - _row_dot(rot, k1, k0, b, 0, 1))
    sn = math.sqrt(vx * vx + vy * vy + vz * vz)
    ang = math.atan2(sn, 0.5 * (d00 + d11 + d22 - 1.0))
    f = ang / sn if sn > 1e-300 else 1.0
    return vx * f, vy * f, vz * f


@njit(cache=True, nogil=True)
def _kinematic_rel(rot, omega, dts, min_angle, smooth_frac, corr, rel):
    """rel[k, n] (T-1, N): distance of the rotation vector of R(k+1) R(k)^T over dt from the
    segment [w(k), w(k+1)], relative to max(|mean w|, |rate|); NaN where the interval is not
    usable (turns less than min_angle or more than 1.5 rad, or w jumps by more than smooth_frac
    of it). One compiled pass (the numpy form of the same costs ~1 s on a 500-body pile log)."""
    n_k, n_b = rel.shape
    for k in range(n_k):
        h = dts[k]
        for b in range(n_b):
            tx, ty, tz = interval_rotvec(rot, k + 1, k, b)
            rx, ry, rz = tx / h, ty / h, tz / h
            w0, w1 = omega[k, b], omega[k + 1, b]
            ux, uy, uz = w1[0] - w0[0], w1[1] - w0[1], w1[2] - w0[2]
            mx, my, mz = 0.5 * (w0[0] + w1[0]), 0.5 * (w0[1] + w1[1]), 0.5 * (w0[2] + w1[2])
            scale = max(math.sqrt(mx * mx + my * my + mz * mz), math.sqrt(rx * rx + ry * ry + rz * rz))
            jump = math.sqrt(ux * ux + uy * uy + uz * uz)
            if not (scale * h > min_angle and scale * h < 1.5 and jump <= smooth_frac * scale):
                rel[k, b] = np.nan
                continue
            uu = ux * ux + uy * uy + uz * uz
            t = 0.0
            if uu > 0:
                t = ((rx - w0[0]) * ux + (ry - w0[1]) * uy + (rz - w0[2]) * uz) / uu
                t = min(1.0, max(0.0, t))
            ex, ey, ez = rx - (w0[0] + t * ux), ry - (w0[1] + t * uy), rz - (w0[2] + t * uz)
            rel[k, b] = math.sqrt(ex * ex + ey * ey + ez * ez) / (scale + corr / h)


@njit(cache=True, nogil=True)
def _linear_rel(pos, vel, dts, min_move, smooth_frac, acc, corr, rel):
    """rel[k, n]: distance of (x(k+1) - x(k)) / dt from the segment [v(k), v(k+1)], relative to
    max(|mean v|, |rate|) + acc dt + corr / dt; NaN where not usable (moves less than min_move,
    or v jumps by more than smooth_frac of it plus acc dt)."""
    n_k, n_b = rel.shape
    for k in range(n_k):
        h = dts[k]
        for b in range(n_b):
            x0, x1, v0, v1 = pos[k, b], pos[k + 1, b], vel[k, b], vel[k + 1, b]
            rx, ry, rz = (x1[0] - x0[0]) / h, (x1[1] - x0[1]) / h, (x1[2] - x0[2]) / h
            ux, uy, uz = v1[0] - v0[0], v1[1] - v0[1], v1[2] - v0[2]
            mx, my, mz = 0.5 * (v0[0] + v1[0]), 0.5 * (v0[1] + v1[1]), 0.5 * (v0[2] + v1[2])
            scale = max(math.sqrt(mx * mx + my * my + mz * mz), math.sqrt(rx * rx + ry * ry + rz * rz))
            uu = ux * ux + uy * uy + uz * uz
            if not (scale * h > min_move and math.sqrt(uu) <= smooth_frac * scale + acc[b] * h):
                rel[k, b] = np.nan
                continue
            t = 0.0
            if uu > 0:
                t = ((rx - v0[0]) * ux + (ry - v0[1]) * uy + (rz - v0[2]) * uz) / uu
                t = min(1.0, max(0.0, t))
            ex, ey, ez = rx - (v0[0] + t * ux), ry - (v0[1] + t * uy), rz - (v0[2] + t * uz)
            rel[k, b] = math.sqrt(ex * ex + ey * ey + ez * ez) / (scale + acc[b] * h + corr / h)


@njit(cache=True, nogil=True)
def _pointwise(quat, rot, mom, vel, omega, lw, mass, inertia, err_qm, ortho, dp, p_mag, rel_l,
               l_scale):
    """Per sample and body: ||R(q/|q|) - R||_F, ||R^T R - I||_F, |p - m v|, |p|,
    |w - R diag(1/I) R^T L| / (|w| + |L| / I_min) and that scale."""
    n_t, n_b = err_qm.shape
    rq = np.empty((3, 3))
    for k in range(n_t):
        for b in range(n_b):
            q = quat[k, b]
            nq = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
            if nq == 0.0:
                nq = 1.0
            w, x, y, z = q[0] / nq, q[1] / nq, q[2] / nq, q[3] / nq
            rq[0, 0] = 1 - 2 * (y * y + z * z)
            rq[0, 1] = 2 * (x * y - w * z)
            rq[0, 2] = 2 * (x * z + w * y)
            rq[1, 0] = 2 * (x * y + w * z)
            rq[1, 1] = 1 - 2 * (x * x + z * z)
            rq[1, 2] = 2 * (y * z - w * x)
            rq[2, 0] = 2 * (x * z - w * y)
            rq[2, 1] = 2 * (y * z + w * x)
            rq[2, 2] = 1 - 2 * (x * x + y * y)
            r = rot[k, b]
            e = 0.0
            g = 0.0
            for i in range(3):
                for j in range(3):
                    d = rq[i, j] - r[i, j]
                    e += d * d
                    gij = r[0, i] * r[0, j] + r[1, i] * r[1, j] + r[2, i] * r[2, j]
                    if i == j:
                        gij -= 1.0
                    g += gij * gij
            err_qm[k, b] = math.sqrt(e)
            ortho[k, b] = math.sqrt(g)
            m = mass[b]
            p, v = mom[k, b], vel[k, b]
            a0, a1, a2 = p[0] - m * v[0], p[1] - m * v[1], p[2] - m * v[2]
            dp[k, b] = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
            p_mag[k, b] = math.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
            l_ = lw[k, b]
            om = omega[k, b]
            b0 = (r[0, 0] * l_[0] + r[1, 0] * l_[1] + r[2, 0] * l_[2]) / inertia[b, 0]
            b1 = (r[0, 1] * l_[0] + r[1, 1] * l_[1] + r[2, 1] * l_[2]) / inertia[b, 1]
            b2 = (r[0, 2] * l_[0] + r[1, 2] * l_[1] + r[2, 2] * l_[2]) / inertia[b, 2]
            c0 = om[0] - (r[0, 0] * b0 + r[0, 1] * b1 + r[0, 2] * b2)
            c1 = om[1] - (r[1, 0] * b0 + r[1, 1] * b1 + r[1, 2] * b2)
            c2 = om[2] - (r[2, 0] * b0 + r[2, 1] * b1 + r[2, 2] * b2)
            imin = min(inertia[b, 0], min(inertia[b, 1], inertia[b, 2]))
            sc = (math.sqrt(om[0] * om[0] + om[1] * om[1] + om[2] * om[2])
                  + math.sqrt(l_[0] * l_[0] + l_[1] * l_[1] + l_[2] * l_[2]) / imin)
            l_scale[k, b] = sc
            rel_l[k, b] = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2) / max(sc, 1e-300)


def _kinematic_median(rot, omega_world, dts, min_angle):
    """Per body: (median relative mismatch, usable interval count) between the rotation vector of
    R(k+1) R(k)^T over dt and the logged world angular velocity (see _kinematic_rel). rot
    (T, N, 3, 3), omega_world (T, N, 3), dts (T-1,)."""
    rel = np.empty((len(dts), rot.shape[1]))
    _kinematic_rel(np.ascontiguousarray(rot, np.float64), np.ascontiguousarray(omega_world, np.float64),
                   np.ascontiguousarray(dts, np.float64), float(min_angle), float(SMOOTH_FRAC),
                   float(T.CONSISTENCY_CORRECTION), rel)
    use = ~np.isnan(rel)
    count = use.sum(axis=0)
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            med = np.nanmedian(rel, axis=0) if rel.shape[0] else np.full(rel.shape[1], np.nan)
    return med, count


def inspect(traj: Trajectory, tol: dict | None = None, finite=()) -> list[Issue]:
    """Every consistency issue of ``traj`` (see the module docstring); ``tol`` overrides the
    defaults of :class:`ConsistencyAnalyzer` by name; ``finite`` names channels already known
    to hold no NaN or inf (not scanned again)."""
    tol = {**ConsistencyAnalyzer.defaults, **(tol or {})}
    out: list[Issue] = []
    n_t, n = traj.n_samples, traj.n_bodies
    if n_t == 0 or n == 0:
        return out
    t, step = np.asarray(traj.t, float), np.asarray(traj.step)

    # finite values
    finite = np.ones(n_t, bool)
    for name in BODY_CHANNELS:
        if name in finite or all_finite(getattr(traj, name)):
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
    c = np.ascontiguousarray
    _pointwise(c(quat), c(rot), c(mom), c(vel), c(omega), c(lw), c(mass), c(inertia), err, ortho,
               dp, p_mag, rel_l, scale_l)
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
        med, count = _kinematic_median(rot, omega, dts, min_angle)
        bad = (count >= min_count) & (med > tol["kinematic_rel"])
        if bad.any():
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
            for channel, cause, r_h, w_h in hyps:
                m_h, c_h = _kinematic_median(r_h[:, bad], w_h[:, bad], dts, min_angle)
                score = float(np.nanmax(m_h)) if np.isfinite(m_h).any() else np.inf
                if score <= tol["kinematic_rel"] and (best is None or score < best[0]):
                    best = (score, channel, cause)
            channel, cause = (best[1], best[2]) if best else (
                "angular_velocity", "angular_velocity does not turn the logged orientation "
                "(wrong frame, sign, unit or orientation channel)")
            worst = float(np.nanmax(med[bad]))
            out.append(Issue("kinematics", channel,
                             f"{cause}: the orientation's rate of change disagrees with "
                             f"angular_velocity by a median {worst:.3g} (relative) for "
                             f"{_names(traj, bodies)}", worst, tol["kinematic_rel"],
                             int(step[0]), float(t[0]), bodies))
        # position vs velocity: allow one sample's change of velocity by gravity and loads
        g = np.linalg.norm(np.asarray(model.gravity, float))
        acc = g + np.linalg.norm(np.asarray(model.body_force_world, float), axis=-1) / mass
        rel = np.empty((len(dts), n))
        _linear_rel(c(pos), c(vel), c(dts), float(min_angle) * 1.0, float(SMOOTH_FRAC), c(acc),
                    float(T.CONSISTENCY_CORRECTION), rel)  # min_angle in m: see the tolerance
        use = ~np.isnan(rel)
        cnt = use.sum(axis=0)
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            med_v = np.nanmedian(rel, axis=0)
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
    return [f"contract: {i.channel}: {i.message}" for i in inspect(traj)]


class ConsistencyAnalyzer(Analyzer):
    name = "consistency"
    description = ("channels agree with each other: quaternion vs matrix, p = m v, L = I_world w, "
                   "orientation turning at the world angular velocity, finite values, time order")
    defaults = {
        "quat_matrix": T.CONSISTENCY_QUAT_MATRIX,
        "momentum_rel": T.CONSISTENCY_MOMENTUM_REL,
        "angular_momentum_rel": T.CONSISTENCY_ANGULAR_MOMENTUM_REL,
        "kinematic_rel": T.CONSISTENCY_KINEMATIC_REL,
        "min_angle_rad": T.CONSISTENCY_MIN_ANGLE_RAD,
        "min_intervals_samples": T.CONSISTENCY_MIN_INTERVALS_SAMPLES,
    }
    units = {"min_angle_rad": "rad", "min_intervals_samples": "samples"}

    def analyze(self, ctx: Context) -> Result:
        # the samples before the first non-finite one (drift reports that one; load's warnings
        # name the channel)
        return self._result(ctx.traj, inspect(ctx.traj, self.tol, ctx.finite_channels))

    def _result(self, traj: Trajectory, issues: list[Issue]) -> Result:
        worst = Worst("1", self.tol["kinematic_rel"])
        findings = []
        for i in issues:
            findings.append(Finding(self.name, i.message, i.value, i.tolerance, "1", i.step, i.t,
                                    i.bodies))
            ratio = i.value / i.tolerance if i.tolerance > 0 else float("inf")
            worst.offer(ratio, i.value, i.tolerance, "1", i.step, i.t, i.bodies, i.check)
        ok = "every channel agrees with the others (quaternion/matrix, p = m v, L = I w, kinematics)"
        return self.result(worst, findings, {"issues": len(issues)}, ok_reason=ok)
