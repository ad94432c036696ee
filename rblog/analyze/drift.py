"""Non-rigid drift: does every body keep its shape?

Recomputed from the logged rotation and quaternion (the logged ``ortho_error`` is only compared,
never trusted):

* ``||R^T R - I||_F`` and ``det R - 1`` (volume change);
* ``|q| - 1`` of the logged quaternion;
* the distances between body-fixed points mapped by the logged R: a body vector d (from one
  body-fixed point to another: a box's edge or diagonal, a sphere's diameter) maps to length
  ``sqrt(d^T G d)`` with ``G = R^T R``, so its relative change lies between ``sigma_min - 1`` and
  ``sigma_max - 1`` (sigma: singular values of R, sigma^2 the eigenvalues of G, in closed form).
  The metric is ``max(sigma_max - 1, 1 - sigma_min)``: the largest relative change of any
  distance between two points of the body, corners included; times the body's diameter it
  bounds the change in metres (a statistic).

For each body and metric: the onset time (first sample past tolerance) and the growth after it,
described by the better of two least-squares fits over the samples from the onset: a line
(y = a + b t: "growing linearly, b per second") or an exponential (log y = c + r t: "growing
exponentially, e-folding rate r"), the one whose values stay closer to the metric's (root mean
square of y - fit, in y). The notes' unnormalized scheme grows ||R^T R - I|| about linearly at
small drift (0.0056/s on the tumbling box at dt = 1 ms); a run whose drift feeds on itself
(det R like exp(h ∫|ω|² dt) at large |ω| h) grows exponentially.
"""

from __future__ import annotations

import numpy as np

from rblog.analyze import _audit
from rblog.analyze import geometry
from rblog.analyze import tolerances as T
from rblog.analyze.base import Analyzer, Context, Finding, Result, Worst, body_label

# (name, tolerance key, label)
_METRICS = (
    ("ortho_error", "ortho_error", "||R^T R - I||_F"),
    ("det_error", "det_error", "|det R - 1|"),
    ("quat_norm_error", "quat_norm_error", "||q| - 1|"),
    ("distance_rel", "distance_rel", "relative body-fixed distance change"),
)


def _fit(t: np.ndarray, y: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted least-squares slope of y(t) per column; w (T, N) weights >= 0. NaN when fewer
    than 2 points carry weight."""
    sw = w.sum(0)
    with np.errstate(invalid="ignore", divide="ignore"):
        tm = (w * t[:, None]).sum(0) / sw
        ym = (w * y).sum(0) / sw
        dt_ = t[:, None] - tm
        num = (w * dt_ * (y - ym)).sum(0)
        den = (w * dt_ * dt_).sum(0)
        return np.where(((w > 0).sum(0) >= 2) & (den > 0), num / den, np.nan)


def _residuals(t, y, w, rate, y_exp=None, w_res=None):
    """Root mean square of y - fit per column (T, F), for the weighted (``w``) least-squares line
    of slope ``rate`` through y, over the samples of ``w_res`` (0/1; default w); with ``y_exp``,
    y is log(y_exp) and the residual is of y_exp - exp(fit), so that both fits are compared in
    the metric's own units."""
    w_res = w if w_res is None else w_res
    sw = w.sum(0)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        tm = (w * t[:, None]).sum(0) / sw
        ym = (w * y).sum(0) / sw
        fit = ym + rate * (t[:, None] - tm)
        r = (y_exp - np.exp(fit)) if y_exp is not None else (y - fit)
        r = np.where(w_res > 0, r, 0.0)
        n = (w_res > 0).sum(0)
        return np.where(n >= 2, np.sqrt((r * r).sum(0) / np.maximum(n, 1)), np.inf)


def _growth(slope: float, log_rate: float, exponential: bool) -> str:
    """The growth in words, from the better fit (see the module docstring)."""
    if exponential:
        return (f"growing exponentially (e-folding rate {log_rate:.3g}/s, doubling every "
                f"{np.log(2.0) / log_rate:.3g} s)")
    if not np.isfinite(slope):
        return "growing (too few finite samples past tolerance to fit a rate)"
    return f"growing linearly, {slope:.3g}/s"


class DriftAnalyzer(Analyzer):
    name = "drift"
    description = ("rigidity: ||R^T R - I||, det R - 1, |q| - 1 and body-fixed distances from the "
                   "logged rotation; onset time and growth rate")
    defaults = T.options("drift", "ortho_error", "det_error", "quat_norm_error", "distance_rel")

    def metrics(self, ctx: Context) -> dict[str, np.ndarray]:
        """Each metric (T, N), recomputed from the logged rotation and quaternion."""
        tr = ctx.traj
        out = np.empty((4,) + tr.rotation.shape[:2])
        _audit.rigidity(np.ascontiguousarray(tr.rotation, dtype=np.float64),
                        np.ascontiguousarray(tr.quat_wxyz, dtype=np.float64), out)
        return {"ortho_error": out[0], "det_error": out[1], "quat_norm_error": out[2],
                "distance_rel": out[3]}

    def analyze(self, ctx: Context) -> Result:
        tr = ctx.traj
        model = tr.model
        t = tr.t
        nonfinite = []
        if ctx.nonfinite is not None:
            k0, bad = ctx.nonfinite
            full = ctx.full_traj
            nonfinite.append(Finding(
                self.name,
                f"{', '.join(body_label(model, b) for b in bad[:3])}"
                f"{' ...' if len(bad) > 3 else ''} has a non-finite state (NaN or inf) at t = "
                f"{full.t[k0]:.6g} s (step {int(full.step[k0])}); analyzed up to the sample before",
                float("inf"), 0.0, "1", int(full.step[k0]), float(full.t[k0]), bad))
            if tr.n_samples == 0:
                w = Worst("1", 0.0)
                return self.result(w, nonfinite, {})
        mets = self.metrics(ctx)
        worst = Worst("1", self.tol["ortho_error"])
        stats: dict[str, float] = {}
        findings: list[Finding] = []
        t_n, n = tr.n_samples, tr.n_bodies
        per_body_ratio = np.full(n, -np.inf)
        per_body_metric = np.zeros(n, np.int64)
        onset_idx = np.full((len(_METRICS), n), -1)
        for mi, (key, tkey, label) in enumerate(_METRICS):
            v = mets[key]
            vmax = v.max(axis=0)  # (N,); NaN where a body's metric is NaN at some sample
            if np.isnan(vmax).any():
                # a metric that overflows (a rotation grown to ~1e100 has det R = inf, then NaN)
                # is at its worst: NaN counts as inf for the maximum and the onset
                v = np.where(np.isnan(v), np.inf, v)
                mets[key] = v
                vmax = v.max(axis=0)
            tl = self.tol[tkey]
            stats[f"{key}_max"] = float(vmax.max()) if n else 0.0
            kmax = v.argmax(axis=0)
            worst.offer_array(vmax, tl, "1", tr.step[kmax], t[kmax], np.arange(n), label)
            over = np.nonzero(vmax > tl)[0]
            if len(over):  # first sample past tolerance, for the bodies that get there
                onset_idx[mi, over] = (v[:, over] > tl).argmax(axis=0)
            with np.errstate(divide="ignore"):
                ratio = vmax / tl if tl > 0 else np.where(vmax > 0, np.inf, 0.0)
            better = ratio > per_body_ratio
            per_body_ratio = np.where(better, ratio, per_body_ratio)
            per_body_metric = np.where(better, mi, per_body_metric)
        if n:
            # a distance d changes by at most distance_rel x d: bound it with the body's diameter
            diam = 2.0 * geometry.bounding_radius(model)
            stats["distance_abs_max_m"] = float((mets["distance_rel"] * diam[None]).max())
            with np.errstate(invalid="ignore"):  # inf - inf where both overflowed
                stats["logged_ortho_error_mismatch_max"] = float(np.nanmax(
                    np.abs(np.asarray(tr.ortho_error, float) - mets["ortho_error"]), initial=0.0))

        # onset and growth per flagged body, for its worst metric
        flagged = np.nonzero((onset_idx >= 0).any(axis=0))[0]
        if len(flagged):
            onset = np.where(onset_idx[:, flagged] >= 0, onset_idx[:, flagged], t_n).min(axis=0)
            mi = per_body_metric[flagged]
            allm = np.stack([mets[m[0]] for m in _METRICS])  # (4, T, N)
            y = allm[mi, :, flagged].T  # (T, F): each flagged body's worst metric
            # the fits take the finite samples from the onset on
            w = ((np.arange(t_n)[:, None] >= onset[None, :]) & np.isfinite(y)).astype(float)
            y = np.where(np.isfinite(y), y, 0.0)
            slope = _fit(t, y, w)
            with np.errstate(divide="ignore", invalid="ignore"):
                ly = np.log(np.where(y > 0, y, np.nan))
            # the log fit weighted by y^2: a least-squares fit in the metric's own units (its
            # early, small values would otherwise pull the rate: log(e^(rt) - 1) is steeper
            # than rt near 0)
            lw = w * np.isfinite(ly) * np.nan_to_num(y / np.nanmax(np.where(w > 0, y, np.nan),
                                                                   axis=0)) ** 2
            log_rate = _fit(t, np.nan_to_num(ly), lw)
            # which describes the growth better: the line or the exponential (rms of y - fit)
            rms_lin = _residuals(t, y, w, slope)
            rms_exp = _residuals(t, np.nan_to_num(ly), lw, log_rate, y_exp=y, w_res=w)
            exponential = (rms_exp < rms_lin) & (log_rate > 0)
            for j, b in enumerate(flagged):
                key, tkey, label = _METRICS[mi[j]]
                v = mets[key][:, b]
                kmax = int(v.argmax())
                k0 = int(onset[j])
                reach = (f"reaches {v[kmax]:.3g} (tol {self.tol[tkey]:.3g}) at t = {t[kmax]:.6g} s"
                         if np.isfinite(v[kmax]) else
                         f"is not finite from t = {t[kmax]:.6g} s (tol {self.tol[tkey]:.3g})")
                findings.append(Finding(
                    self.name,
                    f"{body_label(model, b)} not rigid: {label} {reach}; past tolerance from "
                    f"t = {t[k0]:.6g} s, {_growth(slope[j], log_rate[j], exponential[j])}",
                    float(v[kmax]), self.tol[tkey], "1", int(tr.step[kmax]), float(t[kmax]),
                    [int(b)], onset_step=int(tr.step[k0]), onset_t=float(t[k0]),
                ))
            jw = int(np.argmax(per_body_ratio[flagged]))
            stats["onset_t"] = float(t[int(onset.min())])
            stats["worst_body_onset_t"] = float(t[int(onset[jw])])
            stats["worst_growth_per_s"] = float(slope[jw])
            stats["worst_log_growth_rate_per_s"] = float(log_rate[jw])
            stats["worst_growth_exponential"] = float(exponential[jw])
            stats["bodies_flagged"] = float(len(flagged))
        return self.result(worst, nonfinite + findings, stats)
