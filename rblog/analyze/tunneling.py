"""Tunneling: a body that passes through the ground, a static box or another body between two
logged samples: by its centre for a body with a v2 shape (sphere, box), by its geoms (contract
v3) for a body without one.

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

Geoms of a body without a v2 shape (a capsule limb, a mesh link), against every world geom, the
other bodies' geoms and, for every body, against world geoms the v2 fields do not describe (a wall
plane, a world capsule); only pairs the engine collides (rblog.analyze.shapes.collide_mask: the
log's group/mask filter, never one body's own geoms, bodies welded together or a body and its
parent; pairs an engine excludes by name are not in the log and are judged):

* World planes (half-spaces): the geom's core (a sphere's centre, a capsule's segment, any other
  shape's centre) goes from on or above the plane at sample k to below ``-CROSSING_M`` at k+1;
  the value is how far below its lowest core point ends up (m).
* Any other pair: each geom's pose is interpolated between the samples (its centre on the
  straight line, its rotation by slerp) at sub-steps spaced so that no point of either moves by
  more than TUNNELING_SUBSTEP_FRAC of the pair's threshold ``(1 - PASS_FRAC) (r_a + r_b)`` (inner
  radii: sphere and capsule radius, smallest half-extent of a box, cylinder or ellipsoid, the
  depth of a mesh's vertex centroid inside its hull), and the audit's own signed distance
  (rblog.analyze.shapes) measured at each: a pair less deep than the threshold at both samples
  whose path goes deeper than it passed through (for two spheres the threshold is the one above:
  centres closer than PASS_FRAC (r_a + r_b)). The value is how much deeper (m). A pair that cannot
  get that deep (half the sum of its two depths and its relative displacement stays below the
  threshold) is not sub-stepped. Candidates: a sort-and-sweep of each geom's AABBs united over
  the interval's two samples and grown by its rotation's bulge rho (1 - cos(theta / 2)).

Sign convention of the result: ``worst_value`` is the worst crossing, a depth >= 0 (m): 0 when
nothing crosses. A clean log's closest approach is reported in words as a positive clearance
(``reason``; ``stats["closest_clearance_m"]``): how far above the ground a centre stays, how far
beyond half their inner radii two centres' paths stay.
"""

from __future__ import annotations

import numpy as np

from rblog.analyze import _audit
from rblog.analyze import geometry, shapes
from rblog.analyze import tolerances as T
from rblog.analyze.base import (Analyzer, Context, Finding, Result, Worst, _has_geoms, body_label,
                                shapeless, shapeless_note)
from rblog.contract.orientation import matrix_to_quat, quat_wxyz_to_matrix


class TunnelingAnalyzer(Analyzer):
    name = "tunneling"
    description = ("bodies and their geoms passing through the ground, world geoms or each other "
                   "between samples")
    defaults = T.options("tunneling", "crossing_m", "pass_frac",
                         contact_distance_m=T.CONTACT_DISTANCE_M)

    def analyze(self, ctx: Context) -> Result:
        tr = ctx.traj
        model = tr.model
        n = tr.n_bodies
        n_world = int((np.asarray(model.geom_body) < 0).sum()) if model.n_geoms else 0
        if not model.ground and not len(model.static_box_position) and n < 2 and not n_world:
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
        # bodies without a v2 shape judged on their geoms (their centres' rows are left out)
        geo = None if shapes.contacts_disabled(tr.info) else geom_crossings(
            model, tr.position, tr.rotation, self.tol["pass_frac"], cross, ctx.geom_poses)
        by_geoms = geo["bodies"] if geo is not None else np.zeros(n, bool)

        if prox.ground_height is not None:
            h = (np.where(by_geoms[None, :], -np.inf, prox.ground_height) if by_geoms.any()
                 else prox.ground_height)
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

        iv_static = (prox.iv_b >= n) & ~by_geoms[prox.iv_a]
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

        iv_dyn = (prox.iv_b < n) & ~by_geoms[prox.iv_a] & ~by_geoms[np.minimum(prox.iv_b, n - 1)]
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

        if geo is not None:
            names = model.geom_name if model.geom_name is not None else [""] * model.n_geoms
            gbody = np.asarray(model.geom_body, np.int64)

            def glabel(g):
                owner = body_label(model, int(gbody[g])) if gbody[g] >= 0 else "the world"
                return f"geom {g} ({names[g]!r}) of {owner}"

            for key, what in (("plane", "how far a geom's core ends below a world plane"),
                              ("pair", "how much deeper than their threshold two geoms' paths "
                                       "go")):
                val, kk, gi, gj = geo[key]
                stats[f"geom_{key}_crossings"] = float((val > cross).sum())
                if not len(val):
                    continue
                j = int(np.argmax(val))
                d = float(val[j])
                worst.offer(_ratio(d, cross), max(d, 0.0), cross, "m", step[kk[j] + 1],
                            t[kk[j] + 1], [int(b) for b in gbody[[gi[j], gj[j]]] if b >= 0], what)
                if d <= cross:
                    closest.append((-d, f"{glabel(int(gi[j]))} "
                                        + (f"keeps its core {-d:.3g} m above {glabel(int(gj[j]))}"
                                           if key == "plane" else
                                           f"and {glabel(int(gj[j]))} stay {-d:.3g} m shallower "
                                           "than their threshold")
                                        + f" at t = {t[kk[j] + 1]:.6g} s"))
                sel = val > cross
                found.append((f"geom {key}", val[sel], kk[sel], gi[sel], gj[sel]))
            for k_, v_ in geo["stats"].items():
                stats[k_] = v_

        for kind, val, kk, aa, bb in found:
            n_found += len(val)
            order = np.argsort(-val)[: T.MAX_FINDINGS]
            for j in order:
                k, a, b = int(kk[j]), int(aa[j]), int(bb[j])
                if kind.startswith("geom"):
                    ga, gb_ = (a, b) if gbody[a] >= 0 else (b, a)
                    if kind == "geom plane":
                        what = (f"passes through {glabel(gb_)}: its core ends {val[j]:.3g} m "
                                "below it")
                    else:
                        what = (f"passes through {glabel(gb_)}: their paths go {val[j]:.3g} m "
                                "deeper than (1 - pass_frac) x their inner radii allow")
                    findings.append(Finding(
                        self.name, f"{glabel(ga)} {what} between t = {t[k]:.6g} and "
                                   f"{t[k + 1]:.6g} s",
                        float(val[j]), cross, "m", int(step[k + 1]), float(t[k + 1]),
                        [int(x) for x in gbody[[ga, gb_]] if x >= 0]))
                    continue
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
        if geo is not None:
            ok = ("no body or geom passes through the ground, a world geom or another body "
                  "between samples")
        if closest:
            clear, what = min(closest)
            stats["closest_clearance_m"] = clear
            ok += f"; closest approach: {what} (crossings are depths > 0)"
        if geo is not None:
            ok += ("; geom pairs by the log's collision filter (group/mask; one body's, welded "
                   "and parent-child bodies' geoms left out; pairs an engine excludes by name "
                   "are not in the log)")
        off = " (the engine's contacts are switched off: disableflags)" \
            if shapes.contacts_disabled(tr.info) else ""
        return self.result(worst, findings, stats, n_findings=n_found, ok_reason=ok).leave_out(
            shapeless_note(model, "passing through other bodies (their centres against the "
                                  f"ground and static boxes are judged){off}", known=by_geoms)
            if n > 1 else [])


def geom_crossings(model, position, rotation, pass_frac: float, cross: float, poses=None):
    """The geom rules of the module docstring over a trajectory's poses (T, N, 3), (T, N, 3, 3)
    (``poses``: a callable that returns the geoms' world frames, Context.geom_poses).

    Returns None when no geom needs them (every body has a v2 shape and every world geom is the
    ground or a static box), else a dict: ``bodies`` (N,) bool, the bodies judged on their geoms;
    ``plane`` and ``pair``: (value (R,) m, interval k (R,), geom i (R,), geom j (R,)) of every
    pair-interval judged (plane: i the body's geom, j the plane; a crossing where value > cross);
    ``stats``."""
    n = model.n_bodies
    if not n or not getattr(model, "n_geoms", 0) or len(position) < 2:
        return None
    geoms = shapes.model_geoms(model)
    gb = geoms.body
    judged = shapeless(model) & _has_geoms(model)
    unseen = shapes.partner_codes(model) >= n + len(model.static_box_position)
    world = gb < 0
    mine = ((gb >= 0) & judged[np.maximum(gb, 0)]) | (world & unseen)
    if not mine.any():
        return None
    t_n = len(position)
    gpos, grot = poses() if poses is not None else shapes.geom_poses(model, position, rotation)
    is_plane = geoms.type == shapes.GEOM_TYPES["plane"]
    stats: dict[str, float] = {}
    e = np.zeros(0, np.int64)
    out = dict(bodies=judged, stats=stats, plane=(np.zeros(0), e, e, e),
               pair=(np.zeros(0), e, e, e))

    # world planes: the core's lowest point above the plane at every sample
    planes, movers = np.flatnonzero(world & is_plane), np.flatnonzero(~world & ~is_plane)
    if len(planes) and len(movers):
        gi, gp = np.repeat(movers, len(planes)), np.tile(planes, len(movers))
        keep = (mine[gi] | mine[gp]) & shapes.collide_mask(model, gi, gp)
        gi, gp = gi[keep], gp[keep]
        if len(gi):
            u = grot[0, gp][..., 2]  # the planes' normals (world geoms: fixed)
            h = np.einsum("tpi,pi->tp", gpos[:, gi], u) - (u * gpos[0, gp]).sum(1)
            cap = geoms.type[gi] == shapes.GEOM_TYPES["capsule"]
            if cap.any():
                h[:, cap] -= geoms.size[gi[cap], 1] * np.abs(
                    np.einsum("tpi,pi->tp", grot[:, gi[cap]][..., 2], u[cap]))
            kk, pp = np.nonzero(h[:-1] >= 0)
            out["plane"] = (-h[kk + 1, pp], kk, gi[pp], gp[pp])
            stats["geom_plane_pairs"] = float(len(gi))

    # other pairs: the swept broadphase, then depth along the interpolated path
    rho = geometry.geom_bounding_radius(model)
    c = np.einsum("knij,knij->kn", rotation[:-1], rotation[1:])  # trace(R_k^T R_k+1)
    theta_b = np.arccos(np.clip(0.5 * (c - 1.0), -1.0, 1.0))  # (K, N)
    theta = np.where(world[None, :], 0.0, theta_b[:, np.maximum(gb, 0)])  # (K, G)
    grow = rho[None, :] * (1.0 - np.cos(0.5 * theta))
    k, i, j = _sweep(geoms, gpos, grot, mine, grow)
    keep = shapes.collide_mask(model, i, j)
    k, i, j = k[keep], i[keep], j[keep]
    stats["geom_pair_rows"] = float(len(k))
    if not len(k):
        return out
    inner = _inner_radius(model, geoms)
    thr = (1.0 - pass_frac) * (inner[i] + inner[j])
    d0 = -shapes.pair_distance(geoms, gpos, grot, k, i, j, with_points=False)["sep"]
    d1 = -shapes.pair_distance(geoms, gpos, grot, k + 1, i, j, with_points=False)["sep"]
    disp = lambda g: (np.linalg.norm(gpos[k + 1, g] - gpos[k, g], axis=1)
                      + rho[g] * theta[k, g])
    delta = disp(i) + disp(j)
    apart = (d0 < thr) & (d1 < thr)
    deepest = np.maximum(d0, d1)
    sub = np.flatnonzero(apart & (0.5 * (d0 + d1 + delta) > thr))
    stats["geom_rows_substepped"] = float(len(sub))
    if len(sub):
        deepest[sub] = np.maximum(deepest[sub], _substep_depth(
            geoms, gpos, grot, k[sub], i[sub], j[sub], delta[sub], thr[sub], stats))
    a = np.flatnonzero(apart)
    out["pair"] = (deepest[a] - thr[a], k[a], i[a], j[a])
    return out


def _sweep(geoms, gpos, grot, mine, grow):
    """Candidate pairs (k, i < j) of csrc/audit/broadphase.cpp's geom_sweep_broadphase."""
    c = np.ascontiguousarray
    cap = max(1024, 8 * len(gpos))  # grown to the exact count when short
    while True:
        out = [np.empty(cap, np.int64) for _ in range(3)]
        cnt = _audit.geom_sweep_broadphase(
            c(gpos, dtype=np.float64), c(grot, dtype=np.float64), c(geoms.type, dtype=np.int64),
            c(geoms.size, dtype=np.float64), c(geoms.mesh_start, dtype=np.int64),
            c(geoms.mesh_count, dtype=np.int64), c(geoms.verts, dtype=np.float64).reshape(-1, 3),
            c(geoms.body, dtype=np.int64), c(mine, dtype=np.bool_), c(grow, dtype=np.float64),
            *out)
        if cnt <= cap:
            return tuple(o[:cnt] for o in out)
        cap = cnt


def _inner_radius(model, geoms) -> np.ndarray:
    """(G,) each geom's inner radius (m): shapes.inner_half_extent, and for a mesh the depth of
    its vertex centroid inside its hull by the audit's own distance (0 if outside)."""
    inner = shapes.inner_half_extent(geoms)
    mesh = np.flatnonzero(geoms.type == shapes.GEOM_TYPES["mesh"])
    for g in mesh:
        a, m = int(geoms.mesh_start[g]), int(geoms.mesh_count[g])
        v = geoms.verts[a:a + m]
        d = shapes.distance("sphere", v.mean(axis=0)[None], np.eye(3), [0.0, 0.0, 0.0], "mesh",
                            np.zeros((1, 3)), np.eye(3), [0.0, 0.0, 0.0], verts_b=v,
                            with_points=False)["sep"][0]
        inner[g] = max(-float(d), 0.0)
    return inner


def _substep_depth(geoms, gpos, grot, k, i, j, delta, thr, stats) -> np.ndarray:
    """(R,) the deepest signed-distance depth of rows (k, i, j) at the interior sub-steps of
    their intervals (an even count, so the middle is one: module docstring)."""
    step = T.TUNNELING_SUBSTEP_FRAC * thr
    n_sub = np.ceil(delta / np.maximum(step, 1e-300)).astype(np.int64)
    n_sub = np.clip(n_sub + n_sub % 2, 2, T.TUNNELING_MAX_SUBSTEPS)
    stats["geom_rows_capped"] = float((delta > step * T.TUNNELING_MAX_SUBSTEPS).sum())
    row = np.repeat(np.arange(len(k)), n_sub - 1)
    first = np.repeat(np.cumsum(n_sub - 1) - (n_sub - 1), n_sub - 1)
    s = (np.arange(len(row)) - first + 1) / n_sub[row]  # (S,) in (0, 1)
    kr = k[row]
    pos, rot = [], []
    for g in (i[row], j[row]):
        x0, x1 = gpos[kr, g], gpos[kr + 1, g]
        pos.append(x0 + s[:, None] * (x1 - x0))
        rot.append(_slerp(grot[kr, g], grot[kr + 1, g], s))
    m = len(row)
    sub = shapes.Geoms(np.concatenate([geoms.type[i[row]], geoms.type[j[row]]]),
                       np.concatenate([geoms.size[i[row]], geoms.size[j[row]]]),
                       np.concatenate([geoms.mesh_start[i[row]], geoms.mesh_start[j[row]]]),
                       np.concatenate([geoms.mesh_count[i[row]], geoms.mesh_count[j[row]]]),
                       geoms.verts, np.concatenate([geoms.body[i[row]], geoms.body[j[row]]]))
    sep = shapes.pair_distance(sub, np.concatenate(pos)[None], np.concatenate(rot)[None],
                               np.zeros(m, np.int64), np.arange(m), np.arange(m, 2 * m),
                               with_points=False)["sep"]
    deepest = np.full(len(k), -np.inf)
    np.maximum.at(deepest, row, -sep)
    return deepest


def _slerp(r0: np.ndarray, r1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(P, 3, 3) rotations a fraction s (P,) of the way from r0 to r1 (P, 3, 3) about the axis
    of r0^T r1, by the shorter way."""
    q = matrix_to_quat(np.einsum("pji,pjk->pik", r0, r1))  # w >= 0: the angle is <= pi
    half = np.arctan2(np.linalg.norm(q[:, 1:], axis=1), q[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(half > 0, np.sin(s * half) / np.sin(half), s)
    qs = np.concatenate([np.cos(s * half)[:, None], scale[:, None] * q[:, 1:]], axis=1)
    return np.einsum("pij,pjk->pik", r0, quat_wxyz_to_matrix(qs))


def _ratio(value, tolerance):
    """value / tolerance with a zero tolerance: +inf past it, -inf (never worse) below."""
    if tolerance > 0:
        return value / tolerance
    return np.inf if value > 0 else float(value)
