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

For each body and metric: the onset time (first sample past tolerance) and the growth after it:
a least-squares slope of the metric against time (per second) and of its logarithm (an
e-folding rate, 1/s; the notes' unnormalized scheme grows det R like exp(h ∫|ω|² dt)).
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
    """Weighted least-squares slope of y(t) per column; w (T, N) 0/1 weights. NaN when < 2 pts."""
    sw = w.sum(0)
    with np.errstate(invalid="ignore", divide="ignore"):
        tm = (w * t[:, None]).sum(0) / sw
        ym = (w * y).sum(0) / sw
        dt_ = t[:, None] - tm
        num = (w * dt_ * (y - ym)).sum(0)
        den = (w * dt_ * dt_).sum(0)
        return np.where((sw >= 2) & (den > 0), num / den, np.nan)


class DriftAnalyzer(Analyzer):
    name = "drift"
    description = ("rigidity: ||R^T R - I||, det R - 1, |q| - 1 and body-fixed distances from the "
                   "logged rotation; onset time and growth rate")
    defaults = {
        "ortho_error": T.DRIFT_ORTHO_ERROR,
        "det_error": T.DRIFT_DET_ERROR,
        "quat_norm_error": T.DRIFT_QUAT_NORM_ERROR,
        "distance_rel": T.DRIFT_DISTANCE_REL,
    }
    units = {k: "1" for k in defaults}

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
            tl = self.tol[tkey]
            vmax = v.max(axis=0)  # (N,)
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
            stats["logged_ortho_error_mismatch_max"] = float(
                np.abs(np.asarray(tr.ortho_error, float) - mets["ortho_error"]).max())

        # onset and growth per flagged body, for its worst metric
        flagged = np.nonzero((onset_idx >= 0).any(axis=0))[0]
        if len(flagged):
            onset = np.where(onset_idx[:, flagged] >= 0, onset_idx[:, flagged], t_n).min(axis=0)
            mi = per_body_metric[flagged]
            allm = np.stack([mets[m[0]] for m in _METRICS])  # (4, T, N)
            y = allm[mi, :, flagged].T  # (T, F): each flagged body's worst metric
            w = (np.arange(t_n)[:, None] >= onset[None, :]).astype(float)
            slope = _fit(t, y, w)
            with np.errstate(divide="ignore", invalid="ignore"):
                ly = np.log(np.where(y > 0, y, np.nan))
            lw = w * np.isfinite(ly)
            log_rate = _fit(t, np.nan_to_num(ly), lw)
            for j, b in enumerate(flagged):
                key, tkey, label = _METRICS[mi[j]]
                v = mets[key][:, b]
                kmax = int(v.argmax())
                k0 = int(onset[j])
                findings.append(Finding(
                    self.name,
                    f"{body_label(model, b)} not rigid: {label} reaches {v[kmax]:.3g} "
                    f"(tol {self.tol[tkey]:.3g}) at t = {t[kmax]:.6g} s; past tolerance from "
                    f"t = {t[k0]:.6g} s, growing {slope[j]:.3g}/s (e-folding rate "
                    f"{log_rate[j]:.3g}/s)",
                    float(v[kmax]), self.tol[tkey], "1", int(tr.step[kmax]), float(t[kmax]),
                    [int(b)],
                ))
            jw = int(np.argmax(per_body_ratio[flagged]))
            stats["onset_t"] = float(t[int(onset.min())])
            stats["worst_body_onset_t"] = float(t[int(onset[jw])])
            stats["worst_growth_per_s"] = float(slope[jw])
            stats["worst_log_growth_rate_per_s"] = float(log_rate[jw])
            stats["bodies_flagged"] = float(len(flagged))
        return self.result(worst, nonfinite + findings, stats)
