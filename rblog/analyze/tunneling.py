"""Tunneling: a body that passes through the ground, a static box or another body between two
logged samples.

* Ground: the centre's height above the plane goes from >= 0 at sample k to below
  ``-CROSSING_M`` at k+1. A correct run never puts a centre under the ground (it would have sunk by
  its whole inner radius); the value is how far below the centre ends up (m).
* Static boxes: the straight path of the centre from k to k+1 enters the box (slab test in the
  box frame) while the centre was outside it at k: the centre went into or through solid
  geometry, also when both samples are outside a thin wall. The value is how deep the path goes
  (m, depth of its midpoint inside the box, at least the crossing itself).
* Two bodies: the straight relative path of their centres from k to k+1 comes closer than
  ``PASS_FRAC x (r_a + r_b)`` (inner radii: sphere radius, smallest box half-extent) while they
  are at least that far apart at both samples: they passed through each other. Legitimate
  contact keeps the centres apart by about r_a + r_b (two spheres rolling around each other
  would need to turn by 120 degrees in one interval to reach half of it).

Candidates come from the broadphase of bounding spheres swept over each interval, so bodies that
are far apart at both samples but meet in between are still examined.

Sign convention of the result: ``worst_value`` is the worst crossing, a depth >= 0 (m): 0 when
nothing crosses. A clean log's closest approach is reported in words as a positive clearance
(``reason``; ``stats["closest_clearance_m"]``): how far above the ground a centre stays, how far
beyond half their inner radii two centres' paths stay.
"""

from __future__ import annotations

import numpy as np

from rblog.analyze import _audit
from rblog.analyze import geometry
from rblog.analyze import tolerances as T
from rblog.analyze.base import (Analyzer, Context, Finding, Result, Worst, body_label,
                                shapeless_note)


class TunnelingAnalyzer(Analyzer):
    name = "tunneling"
    description = "bodies passing through the ground, static boxes or each other between samples"
    defaults = T.options("tunneling", "crossing_m", "pass_frac",
                         contact_distance_m=T.CONTACT_DISTANCE_M)

    def analyze(self, ctx: Context) -> Result:
        tr = ctx.traj
        model = tr.model
        n = tr.n_bodies
        if not model.ground and not len(model.static_box_position) and n < 2:
            return self.skip("nothing to pass through: no ground, no static boxes, one body")
        if tr.n_samples < 2:
            return self.skip("needs at least two samples")
        t, step = tr.t, tr.step
        prox = ctx.proximity(self.tol["contact_distance_m"])
        cross = self.tol["crossing_m"]
        worst = Worst("m", cross)
        findings: list[Finding] = []
        stats: dict[str, float] = {}
        n_found = 0
        # candidates: (kind, value m, interval k, body a, other b (-1 ground, N+m static))
        found = []
        # the closest approach without a crossing: (clearance m > 0, its description)
        closest: list[tuple[float, str]] = []

        if prox.ground_height is not None:
            h = prox.ground_height
            depth = -h[1:]  # how far below the plane the centre ends up
            above = h[:-1] >= 0
            kk, ii = np.nonzero(above)
            if len(kk):
                # worst: the deepest any centre gets right after being above (passes: negative)
                j = int(np.argmax(depth[kk, ii]))
                d = float(depth[kk[j], ii[j]])
                worst.offer(_ratio(d, cross), max(d, 0.0), cross, "m", step[kk[j] + 1],
                            t[kk[j] + 1], [ii[j]], "depth of a centre below the ground")
                if d < 0:
                    closest.append((-d, f"{body_label(model, int(ii[j]))}'s centre "
                                        f"{-d:.3g} m above the ground at t = "
                                        f"{t[kk[j] + 1]:.6g} s"))
            hit = above & (depth > cross)
            kk, ii = np.nonzero(hit)
            found.append(("the ground", depth[kk, ii], kk, ii, np.full(len(kk), -1)))
            stats["ground_crossings"] = float(len(kk))

        iv_static = prox.iv_b >= n
        if iv_static.any():
            sx, sr, sh = geometry.static_boxes(model)
            k, a, b = prox.iv_k[iv_static], prox.iv_a[iv_static], prox.iv_b[iv_static] - n
            x0 = np.einsum("pji,pj->pi", sr[b], tr.position[k, a] - sx[b])  # box frame
            x1 = np.einsum("pji,pj->pi", sr[b], tr.position[k + 1, a] - sx[b])
            hb = sh[b] - cross
            d = x1 - x0
            with np.errstate(divide="ignore", invalid="ignore"):
                ta = (-hb - x0) / d
                tb = (hb - x0) / d
            tmin = np.where(d != 0, np.minimum(ta, tb), np.where(np.abs(x0) <= hb, -np.inf, np.inf))
            tmax = np.where(d != 0, np.maximum(ta, tb), np.where(np.abs(x0) <= hb, np.inf, -np.inf))
            t_in = np.maximum(tmin.max(axis=1), 0.0)
            t_out = np.minimum(tmax.min(axis=1), 1.0)
            outside0 = (np.abs(x0) > sh[b]).any(axis=1)
            enters = outside0 & (t_in <= t_out) & (hb > 0).all(axis=1)
            t_mid = 0.5 * (np.where(enters, t_in, 0.0) + np.where(enters, t_out, 0.0))
            mid = x0 + t_mid[:, None] * d
            depth = np.where(enters, np.maximum((sh[b] - np.abs(mid)).min(axis=1), 0.0), -np.inf)
            if len(depth):
                j = int(np.argmax(depth))
                if np.isfinite(depth[j]):
                    worst.offer(_ratio(depth[j], cross), max(float(depth[j]), 0.0), cross, "m",
                                step[k[j] + 1], t[k[j] + 1], [a[j]],
                                "depth of a centre's path inside a static box")
            sel = enters & (depth > cross)
            found.append(("static box", depth[sel], k[sel], a[sel], n + b[sel]))
            stats["static_crossings"] = float(sel.sum())

        iv_dyn = prox.iv_b < n
        if iv_dyn.any():
            k, a, b = prox.iv_k[iv_dyn], prox.iv_a[iv_dyn], prox.iv_b[iv_dyn]
            ri = geometry.inner_radius(model)
            depth = np.empty(len(k))
            asc = np.ascontiguousarray
            _audit.chord_overlap(asc(tr.position, dtype=np.float64), asc(k, dtype=np.int64),
                                 asc(a, dtype=np.int64), asc(b, dtype=np.int64),
                                 asc(self.tol["pass_frac"] * ri, dtype=np.float64), depth)
            apart = np.isfinite(depth)
            if len(depth):
                j = int(np.argmax(depth))
                if np.isfinite(depth[j]):
                    d = float(depth[j])
                    worst.offer(_ratio(d, cross), max(d, 0.0), cross, "m", step[k[j] + 1],
                                t[k[j] + 1], [a[j], b[j]],
                                "how much closer than half their inner radii two centres' "
                                "paths come")
                    if d < 0:
                        closest.append((-d, f"the centres of {body_label(model, int(a[j]))} and "
                                            f"{body_label(model, int(b[j]))} stay {-d:.3g} m "
                                            "beyond half their inner radii at t = "
                                            f"{t[k[j] + 1]:.6g} s"))
            sel = apart & (depth > cross)
            found.append(("body", depth[sel], k[sel], a[sel], b[sel]))
            stats["body_crossings"] = float(sel.sum())

        for kind, val, kk, aa, bb in found:
            n_found += len(val)
            order = np.argsort(-val)[: T.MAX_FINDINGS]
            for j in order:
                k, a, b = int(kk[j]), int(aa[j]), int(bb[j])
                if kind == "the ground":
                    what = f"passes through the ground: its centre ends {val[j]:.3g} m below it"
                    bodies = [a]
                elif kind == "static box":
                    what = (f"passes into static box {b - n}: its centre's path goes "
                            f"{val[j]:.3g} m "
                            "deep")
                    bodies = [a]
                else:
                    what = (f"passes through {body_label(model, b)}: their centres come "
                            f"{val[j]:.3g} m closer than half their inner radii allow")
                    bodies = [a, b]
                findings.append(Finding(
                    self.name,
                    f"{body_label(model, a)} {what} between t = {t[k]:.6g} and {t[k + 1]:.6g} s",
                    float(val[j]), cross, "m", int(step[k + 1]), float(t[k + 1]), bodies))
        ok = "no body passes through the ground, a static box or another body between samples"
        if closest:
            clear, what = min(closest)
            stats["closest_clearance_m"] = clear
            ok += f"; closest approach: {what} (crossings are depths > 0)"
        return self.result(worst, findings, stats, n_findings=n_found, ok_reason=ok).leave_out(
            shapeless_note(model, "passing through other bodies (their centres against the "
                                  "ground and static boxes are judged)") if n > 1 else [])


def _ratio(value, tolerance):
    """value / tolerance with a zero tolerance: +inf past it, -inf (never worse) below."""
    if tolerance > 0:
        return value / tolerance
    return np.inf if value > 0 else float(value)
