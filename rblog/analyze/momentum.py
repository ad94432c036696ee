"""Momentum in collisions.

Collision events come from the contact groups of :class:`~rblog.analyze.base.Context`: per sample
interval, the bodies whose momentum jumped (beyond m g + F and τ over the interval) joined with
every body they could have touched (recomputed geometry, and the logged contacts). So collisions
are found from velocity jumps when a log has no contacts, and from both when it has.

Checks:

* Closed groups (no static geometry in reach; two colliding bodies, or one body whose momentum
  changed with nothing in reach): the sum of the members' impulses J must vanish (linear momentum
  conserved, relative to sum m|v|), and the change of the group's angular momentum about its
  centre of mass must equal the applied torques (relative to sum |L| + |x - c||P|). About the
  centre of mass uniform gravity exerts no torque, in continuous and in discrete time, so this is
  the conservation of angular momentum about the origin with the gravity torque accounted exactly.
* One body against one static feature (the ground, or one static box): the inferred impulse J
  must lie in the Coulomb cone about the contact normal, ``|J_t| <= mu J_n`` with J_n >= 0
  (pair materials by the log's combine rules, RunInfo.combine_friction / combine_restitution;
  rblog's, which v1 logs imply: mu = sqrt(mu_a mu_b), e = max(e_a, e_b), Box2D's mixing rules). Logged contact impulses are checked against the cone as well.
* Impacts (approach speed at the contact above IMPACT_SPEED_MPS): the effective restitution
  ``e = -v_n+ / v_n-`` of the contact point's normal velocity, both extrapolated under the free
  acceleration to the moment of contact (estimated from the separation and normal velocity
  before), is reported for every impact (``Result.events``) and compared with the configured one
  for spheres (boxes' multi-point impacts have no single-number restitution): more than
  configured is flagged at any speed, less only above RESTITUTION_MIN_SPEED_MPS (engines drop
  restitution for slow impacts so that bodies come to rest). The tolerance is RESTITUTION_ABS
  plus ``(1 + e) |a_n| dt / |v_n-|``: a discrete engine resolves the impact at a step boundary,
  up to dt away from the exact moment of contact, which shifts both normal velocities by up to
  |a_n| dt. The energy (kinetic + potential) of the bodies must not grow across an impact when
  e <= 1 (same allowances as the energy analyzer's contact check).
"""

from __future__ import annotations

import numpy as np

from rblog.contract.model import SHAPE_SPHERE
from rblog.contract.trajectory import STATIC_BODY
from rblog.analyze import geometry
from rblog.analyze import tolerances as T
from rblog.analyze.base import (Analyzer, Context, Finding, Result, Worst, body_label, combine_friction,
                   combine_restitution, static_material)

_TINY = 1e-300


def _contact_time(sep0, vn0, an, dt):
    """Smallest tau in [0, dt] with sep0 + vn0 tau + an tau^2 / 2 = 0 (clamped; 0 if sep0 <= 0)."""
    sep0 = np.maximum(sep0, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        disc = vn0 * vn0 - 2.0 * an * sep0
        sq = np.sqrt(np.maximum(disc, 0.0))
        # numerically stable roots of (an/2) tau^2 + vn0 tau + sep0 = 0
        qq = -0.5 * (vn0 + np.copysign(sq, vn0))
        r1 = np.where(qq != 0, sep0 / qq, np.inf)
        r2 = np.where(an != 0, 2.0 * qq / an, np.inf)
    r1 = np.where(r1 >= 0, r1, np.inf)
    r2 = np.where(r2 >= 0, r2, np.inf)
    tau = np.minimum(r1, r2)
    tau = np.where((disc >= 0) & np.isfinite(tau), tau, dt)
    return np.clip(tau, 0.0, dt)


def static_feature_of_points(model, point, normal):
    """For logged contacts with static geometry: the feature nearest the point (-1 ground, m
    static box m)."""
    k = len(point)
    best = np.full(k, np.inf)
    fid = np.full(k, -3, np.int64)
    if model.ground:
        n = np.asarray(model.ground_normal, float)
        best = np.abs(point @ n - model.ground_offset)
        fid[:] = -1
    sx, sr, sh = geometry.static_boxes(model)
    for m in range(len(sx)):  # a few static boxes at most: walls and ramps
        p = np.einsum("ji,kj->ki", sr[m], point - sx[m])
        q = np.clip(p, -sh[m], sh[m])
        dist = np.linalg.norm(p - q, axis=1) + np.maximum(0, -(sh[m] - np.abs(p)).max(axis=1))
        better = dist < best
        best = np.where(better, dist, best)
        fid = np.where(better, m, fid)
    return fid


class MomentumAnalyzer(Analyzer):
    name = "momentum"
    description = ("collision momentum: conservation across body-body collisions, impulses in the "
                   "friction cone at static contacts, restitution and energy at impacts")
    defaults = {
        "linear_rel": T.MOMENTUM_LINEAR_REL,
        "angular_rel": T.MOMENTUM_ANGULAR_REL,
        "cone_rel": T.MOMENTUM_CONE_REL,
        "impact_speed_mps": T.MOMENTUM_IMPACT_SPEED_MPS,
        "restitution_abs": T.MOMENTUM_RESTITUTION_ABS,
        "restitution_min_speed_mps": T.MOMENTUM_RESTITUTION_MIN_SPEED_MPS,
        "energy_rel": T.MOMENTUM_ENERGY_REL,
        "position_correction_m": T.ENERGY_POSITION_CORRECTION_M,
        "dt_factor": T.ENERGY_DT_FACTOR,
        "contact_distance_m": T.CONTACT_DISTANCE_M,
    }
    units = {"impact_speed_mps": "m/s", "restitution_min_speed_mps": "m/s",
             "position_correction_m": "m", "contact_distance_m": "m"}

    def analyze(self, ctx: Context) -> Result:
        tr = ctx.traj
        if tr.n_samples < 2:
            return self.skip("needs at least two samples")
        cd = self.tol["contact_distance_m"]
        grp = ctx.groups(cd)
        self._ctx, self._grp, self._tr, self._model = ctx, grp, tr, tr.model
        self._worst = Worst("1", self.tol["linear_rel"])
        self._findings: list[Finding] = []
        self._n_found = 0
        c = len(grp)
        stats: dict[str, float] = {"groups": float(c)}
        # per group: impact?, approach speed, effective / configured restitution and its tolerance
        ev = dict(impact=np.zeros(c, bool), approach=np.zeros(c), e_eff=np.full(c, np.nan),
                  e_cfg=np.full(c, np.nan), e_tol=np.full(c, np.nan),
                  sphere=np.zeros(c, bool))
        self._closed(stats, ev)
        self._single_static(stats, ev)
        self._restitution_and_energy(stats, ev)
        self._logged_cone(stats)
        # events: every impact with its effective restitution
        impact = ev["impact"]
        iidx = np.nonzero(impact)[0]
        stats["impacts"] = float(len(iidx))
        t, step = tr.t, tr.step
        gen = ctx.group_energy(cd, self.tol["energy_rel"], self.tol["position_correction_m"],
                               self.tol["dt_factor"])
        events = []
        for j in iidx[: T.MAX_EVENTS]:
            e_eff, e_cfg = ev["e_eff"][j], ev["e_cfg"][j]
            events.append({
                "kind": "impact", "step": int(step[grp.k[j] + 1]), "t": float(t[grp.k[j] + 1]),
                "t_before": float(t[grp.k[j]]), "bodies": grp.members(j),
                "static": bool(grp.static[j]),
                "approach_speed_mps": float(ev["approach"][j]) if ev["approach"][j] else None,
                "restitution_effective": None if np.isnan(e_eff) else float(e_eff),
                "restitution_configured": None if np.isnan(e_cfg) else float(e_cfg),
                "energy_change_J": float(gen["change"][j]),
            })
        fe = np.isfinite(ev["e_eff"]) & impact
        if fe.any():
            stats["restitution_effective_mean"] = float(ev["e_eff"][fe].mean())
        ok_reason = "no contacts or momentum jumps found" if not len(grp) else ""
        return self.result(self._worst, self._findings, stats, events, ok_reason=ok_reason,
                           n_findings=self._n_found)

    # --- pieces -----------------------------------------------------------------------------
    def _add(self, flag, ratio, make):
        """Findings for the flagged entries, the worst MAX_FINDINGS of them built."""
        idx = np.nonzero(flag)[0]
        self._n_found += len(idx)
        idx = idx[np.argsort(-ratio[idx], kind="stable")][: T.MAX_FINDINGS]
        for j in idx:
            self._findings.append(make(int(j)))

    def _who(self, bodies):
        model = self._model
        return " and ".join(body_label(model, i) for i in bodies[:3]) + (
            " ..." if len(bodies) > 3 else "")

    def _closed(self, stats, ev):
        """Linear and angular momentum of closed groups (no static geometry in reach)."""
        ctx, tr, model, grp = self._ctx, self._tr, self._model, self._grp
        t, step = tr.t, tr.step
        sub = grp.subset(~grp.static)
        stats["closed_groups"] = float(len(sub))
        if not len(sub):
            return
        g, mk, mi = sub.mem_group, sub.mem_k, sub.mem_i
        m = ctx.mass[mi]
        dtm = ctx.dts[mk]
        x0, x1 = tr.position[mk, mi], tr.position[mk + 1, mi]
        p0, p1 = tr.linear_momentum[mk, mi], tr.linear_momentum[mk + 1, mi]
        l0, l1 = tr.angular_momentum[mk, mi], tr.angular_momentum[mk + 1, mi]
        amag = np.linalg.norm(ctx.accel, axis=1)[mi]
        sp = np.maximum(ctx.speed[mk, mi], ctx.speed[mk + 1, mi])
        lin_res = np.linalg.norm(sub.sum(ctx.impulse(mk, mi)), axis=1)
        lin_scale = sub.sum(m * (sp + amag * dtm)) + _TINY
        # angular momentum about the group's centre of mass (no gravity torque there)
        mtot = sub.sum(m)
        c0 = sub.sum(m[:, None] * x0) / mtot[:, None]
        c1 = sub.sum(m[:, None] * x1) / mtot[:, None]
        r0, r1 = x0 - c0[g], x1 - c1[g]
        force = np.asarray(model.body_force_world, float)[mi]
        tau = np.asarray(model.body_torque_world, float)[mi]
        ext = dtm[:, None] * (tau + 0.5 * (np.cross(r0, force) + np.cross(r1, force)))
        ang = sub.sum(np.cross(r1, p1) + l1 - np.cross(r0, p0) - l0 - ext)
        ang_res = np.linalg.norm(ang, axis=1)
        ang_scale = sub.sum(np.maximum(
            np.linalg.norm(l0, axis=1) + np.linalg.norm(r0, axis=1) * np.linalg.norm(p0, axis=1),
            np.linalg.norm(l1, axis=1) + np.linalg.norm(r1, axis=1) * np.linalg.norm(p1, axis=1),
        )) + _TINY
        rels = {"linear": lin_res / lin_scale, "angular": ang_res / ang_scale}
        gk = sub.k
        for what, rel in rels.items():
            tl = self.tol[f"{what}_rel"]
            stats[f"{what}_rel_max"] = float(rel.max())
            j = int(np.argmax(rel))
            self._worst.offer(rel[j] / tl if tl > 0 else np.inf, rel[j], tl, "1",
                              step[gk[j] + 1], t[gk[j] + 1], sub.members(j),
                              f"relative {what} momentum change")

            def make(j, what=what, rel=rel, tl=tl):
                b = sub.members(j)
                kind = "collision of" if len(b) > 1 else "unexplained momentum change of"
                return Finding(
                    self.name,
                    f"{what} momentum not conserved in {kind} {self._who(b)} between t = "
                    f"{t[gk[j]]:.6g} and {t[gk[j] + 1]:.6g} s: relative change {rel[j]:.3g} "
                    f"(tol {tl:.3g})",
                    float(rel[j]), tl, "1", int(step[gk[j] + 1]), float(t[gk[j] + 1]), b)

            self._add(rel > tl, rel / max(tl, _TINY), make)
        # collisions of two or more bodies are impacts
        many = sub.size >= 2
        ev["impact"][sub.index[many]] = True
        # two spheres: effective restitution along the line of centres
        self._sphere_pairs(sub, many, ev)

    def _interval_rows(self, k, a, b):
        """Rows of the proximity interval table for pairs (k, a, b), and whether found."""
        prox = self._ctx.proximity(self.tol["contact_distance_m"])
        e_n = prox.n_bodies + prox.n_static
        key = (prox.iv_k * e_n + prox.iv_a) * e_n + prox.iv_b
        order = np.argsort(key, kind="stable")
        want = (k * e_n + a) * e_n + b
        if not len(order):
            return np.zeros(len(want), np.int64), np.zeros(len(want), bool)
        pos = np.clip(np.searchsorted(key[order], want), 0, len(order) - 1)
        return order[pos], key[order][pos] == want

    def _sphere_pairs(self, sub, many, ev):
        ctx, tr, model = self._ctx, self._tr, self._model
        two = np.nonzero(sub.size == 2)[0]
        if not len(two):
            return
        prox = ctx.proximity(self.tol["contact_distance_m"])
        st = sub.starts[two]
        a, b = sub.mem_i[st], sub.mem_i[st + 1]
        k = sub.k[two]
        shp = np.asarray(model.body_shape)
        rows, found = self._interval_rows(k, a, b)
        ok = (shp[a] == SHAPE_SPHERE) & (shp[b] == SHAPE_SPHERE) & found
        if not ok.any():
            return
        two, a, b, k, rows = two[ok], a[ok], b[ok], k[ok], rows[ok]
        nrm = prox.iv_geometry(rows, 0)[1]
        acc = ctx.accel
        vn0 = np.einsum("ij,ij->i", tr.velocity[k, a] - tr.velocity[k, b], nrm)
        vn1 = np.einsum("ij,ij->i", tr.velocity[k + 1, a] - tr.velocity[k + 1, b], nrm)
        an = np.einsum("ij,ij->i", acc[a] - acc[b], nrm)
        dti = ctx.dts[k]
        tc = _contact_time(prox.iv_sep0[rows], vn0, an, dti)
        vminus = vn0 + an * tc
        vplus = vn1 - an * (dti - tc)
        imp = vminus < -self.tol["impact_speed_mps"]
        g = sub.index[two[imp]]
        e_r = np.asarray(model.body_restitution, float)
        ev["approach"][g] = -vminus[imp]
        ev["e_eff"][g] = -vplus[imp] / vminus[imp]
        ev["e_cfg"][g] = combine_restitution(e_r[a[imp]], e_r[b[imp]], tr.info.combine_restitution)
        ev["e_tol"][g] = self.tol["restitution_abs"] + (1 + ev["e_cfg"][g]) * np.abs(an[imp]) \
            * ctx.dt_step / np.abs(vminus[imp])
        ev["sphere"][g] = True

    def _single_static(self, stats, ev):
        """One body against one static feature: friction cone; impacts and their restitution."""
        ctx, tr, model, grp = self._ctx, self._tr, self._model, self._grp
        t, step = tr.t, tr.step
        n = tr.n_bodies
        sel = grp.static & (grp.size == 1) & (grp.static_features == 1) & (grp.static_id >= -1)
        gidx = np.nonzero(sel)[0]
        if not len(gidx):
            return
        prox = ctx.proximity(self.tol["contact_distance_m"])
        k = grp.k[gidx]
        i = grp.mem_i[grp.starts[gidx]]
        sid = grp.static_id[gidx]
        s_rest, s_fric = static_material(model, sid)
        on_ground = sid == -1
        nrm = np.empty((len(gidx), 3))
        sep0 = np.empty(len(gidx))
        rows = np.zeros(len(gidx), np.int64)
        if on_ground.any():
            nrm[on_ground] = np.asarray(model.ground_normal, float)
            sep0[on_ground] = prox.ground_sep[k[on_ground], i[on_ground]]
        sb = np.nonzero(~on_ground)[0]
        if len(sb):
            rows[sb], _ = self._interval_rows(k[sb], i[sb], n + sid[sb])
            r = rows[sb]
            use1 = prox.iv_sep1[r] < prox.iv_sep0[r]
            _, nn0, _ = prox.iv_geometry(r, 0)
            _, nn1, _ = prox.iv_geometry(r, 1)
            nrm[sb] = np.where(use1[:, None], nn1, nn0)
            sep0[sb] = prox.iv_sep0[r]

        # Coulomb cone of the inferred impulse J = P(k+1) - P(k) - (m g + F) dt
        mu = combine_friction(np.asarray(model.body_friction, float)[i], s_fric, tr.info.combine_friction)
        jv = ctx.impulse(k, i)
        jn = np.einsum("ij,ij->i", jv, nrm)
        jt = np.linalg.norm(jv - jn[:, None] * nrm, axis=1)
        jm = np.linalg.norm(jv, axis=1) + _TINY
        excess = np.maximum(jt - mu * jn, -jn) / jm
        tcone = self.tol["cone_rel"]
        stats["cone_excess_rel_max"] = float(excess.max())
        self._worst.offer_array(excess, tcone, "1", step[k + 1], t[k + 1], i,
                                "friction cone excess (relative to |J|)")
        self._add(excess > tcone, excess / max(tcone, _TINY), lambda j: Finding(
            self.name,
            f"{body_label(model, int(i[j]))}: contact impulse with "
            f"{'the ground' if sid[j] == -1 else f'static box {sid[j]}'} outside the friction "
            f"cone between t = {t[k[j]]:.6g} and {t[k[j] + 1]:.6g} s: J_n = {jn[j]:.3g} N s, "
            f"|J_t| = {jt[j]:.3g} N s, mu = {mu[j]:.3g} (excess {excess[j]:.3g} of |J|, tol "
            f"{tcone:.3g})",
            float(excess[j]), tcone, "1", int(step[k[j] + 1]), float(t[k[j] + 1]), [int(i[j])]))

        # impacts: only bodies whose points can approach faster than the impact speed
        acc = ctx.accel[i]
        an = np.einsum("ij,ij->i", acc, nrm)
        dti = ctx.dts[k]
        vcom = np.einsum("ij,ij->i", tr.velocity[k, i], nrm)
        bound = vcom - ctx.spin[k, i] * ctx.rho[i] + np.minimum(an * dti, 0.0)
        cand = np.nonzero(bound < -self.tol["impact_speed_mps"])[0]
        if not len(cand):
            return
        k, i, sid, nrm, sep0, an, dti = (k[cand], i[cand], sid[cand], nrm[cand], sep0[cand],
                                         an[cand], dti[cand])
        g = gidx[cand]
        pt0 = np.empty((len(cand), 3))
        pt1 = np.empty((len(cand), 3))
        og = sid == -1
        if og.any():
            pt0[og] = geometry.plane_witness(model, i[og], tr.position[k[og], i[og]],
                                             tr.rotation[k[og], i[og]])
            pt1[og] = geometry.plane_witness(model, i[og], tr.position[k[og] + 1, i[og]],
                                             tr.rotation[k[og] + 1, i[og]])
        if (~og).any():
            r = rows[cand][~og]
            pt0[~og] = prox.iv_geometry(r, 0)[2]
            pt1[~og] = prox.iv_geometry(r, 1)[2]
        vv0 = tr.velocity[k, i] + np.cross(tr.angular_velocity[k, i], pt0 - tr.position[k, i])
        vv1 = tr.velocity[k + 1, i] + np.cross(tr.angular_velocity[k + 1, i],
                                               pt1 - tr.position[k + 1, i])
        vn0 = np.einsum("ij,ij->i", vv0, nrm)
        vn1 = np.einsum("ij,ij->i", vv1, nrm)
        tc = _contact_time(sep0, vn0, an, dti)
        vminus = vn0 + an * tc
        vplus = vn1 - an * (dti - tc)
        imp = vminus < -self.tol["impact_speed_mps"]
        g, i, an, vminus, vplus = g[imp], i[imp], an[imp], vminus[imp], vplus[imp]
        ev["impact"][g] = True
        ev["approach"][g] = -vminus
        ev["e_eff"][g] = -vplus / vminus
        e_body = np.asarray(model.body_restitution, float)[i]
        ev["e_cfg"][g] = combine_restitution(e_body, s_rest[cand][imp], tr.info.combine_restitution)
        ev["e_tol"][g] = self.tol["restitution_abs"] + (1 + ev["e_cfg"][g]) * np.abs(an) \
            * ctx.dt_step / np.abs(vminus)
        ev["sphere"][g] = np.asarray(model.body_shape)[i] == SHAPE_SPHERE

    def _restitution_and_energy(self, stats, ev):
        """Restitution of spheres' impacts against the configured one; no energy gain at impacts."""
        ctx, tr, model, grp = self._ctx, self._tr, self._model, self._grp
        t, step = tr.t, tr.step
        gk = grp.k
        e_eff, e_cfg, e_tol, approach = ev["e_eff"], ev["e_cfg"], ev["e_tol"], ev["approach"]
        impact = ev["impact"]
        dev = np.abs(e_eff - e_cfg)
        judged = ev["sphere"] & impact & np.isfinite(dev)
        slow_low = (e_eff < e_cfg) & (approach < self.tol["restitution_min_speed_mps"])
        ridx = np.nonzero(judged & ~slow_low)[0]
        if len(ridx):
            stats["restitution_abs_error_max"] = float(dev[ridx].max())
            self._worst.offer_array(dev[ridx], e_tol[ridx], "1", step[gk[ridx] + 1],
                                    t[gk[ridx] + 1], grp.mem_i[grp.starts[ridx]],
                                    "restitution deviation")
        self._add(judged & (dev > e_tol) & ~slow_low, dev / np.where(e_tol > 0, e_tol, _TINY),
                  lambda j: Finding(
                      self.name,
                      f"{self._who(grp.members(j))}: effective restitution {e_eff[j]:.4g} at the "
                      f"impact near t = {t[gk[j]]:.6g} s (approach {approach[j]:.3g} m/s), "
                      f"configured {e_cfg[j]:.4g} (tol {e_tol[j]:.3g})",
                      float(dev[j]), float(e_tol[j]), "1", int(step[gk[j] + 1]),
                      float(t[gk[j] + 1]), grp.members(j)))

        gen = ctx.group_energy(self.tol["contact_distance_m"], self.tol["energy_rel"],
                               self.tol["position_correction_m"], self.tol["dt_factor"])
        d_e, allow = gen["change"], gen["allowed"]
        ke_scale = gen["scale"]
        gain_rel, allow_rel = d_e / ke_scale, allow / ke_scale
        check = impact & (gen["restitution"] <= 1.0) & gen["torque_free"]
        eidx = np.nonzero(check)[0]
        if len(eidx):
            stats["impact_energy_gain_rel_max"] = float(gain_rel[eidx].max())
            self._worst.offer_array(gain_rel[eidx], allow_rel[eidx], "1", step[gk[eidx] + 1],
                                    t[gk[eidx] + 1], grp.mem_i[grp.starts[eidx]],
                                    "energy gain at impact (relative to kinetic energy "
                                    "+ allowance)")
        self._add(check & (d_e > allow), gain_rel / np.maximum(allow_rel, _TINY),
                  lambda j: Finding(
                      self.name,
                      f"{self._who(grp.members(j))}: energy grows by {d_e[j]:.3g} J "
                      f"({gain_rel[j]:.3g} of the kinetic energy) across the impact near t = "
                      f"{t[gk[j]]:.6g} s with restitution <= 1 (allowed {allow[j]:.3g} J)",
                      float(gain_rel[j]), float(allow_rel[j]), "1", int(step[gk[j] + 1]),
                      float(t[gk[j] + 1]), grp.members(j)))

    def _logged_cone(self, stats):
        """Logged contact impulses: normal >= 0, friction perpendicular and inside the cone."""
        tr, model = self._tr, self._model
        n = tr.n_bodies
        cts = tr.contacts
        if not len(cts):
            return
        ca = cts.body_a.astype(np.int64)
        cb = cts.body_b.astype(np.int64)
        valid = (ca >= 0) & (ca < n)
        mu_a = np.asarray(model.body_friction, float)[np.where(valid, ca, 0)]
        static = cb == STATIC_BODY
        fid = np.full(len(cts), -3, np.int64)
        if static.any():
            fid[static] = static_feature_of_points(model, cts.point[static], cts.normal[static])
        _, s_mu = static_material(model, fid)
        mu_b = np.where(static, s_mu,
                        np.asarray(model.body_friction, float)[np.clip(cb, 0, n - 1)])
        mu = combine_friction(mu_a, mu_b, self._tr.info.combine_friction)
        jn = cts.normal_impulse
        ft = cts.friction_impulse
        along = np.einsum("ij,ij->i", ft, cts.normal)
        ftt = np.linalg.norm(ft - along[:, None] * cts.normal, axis=1)
        mag = np.abs(jn) + np.linalg.norm(ft, axis=1) + _TINY
        excess = np.maximum.reduce([ftt - mu * jn, -jn, np.abs(along)]) / mag
        excess = np.where(valid, excess, 0.0)
        tcone = self.tol["cone_rel"]
        stats["logged_cone_excess_rel_max"] = float(excess.max())
        self._worst.offer_array(excess, tcone, "1", cts.step, cts.t, ca,
                                "logged contact impulse cone excess")
        self._add(excess > tcone, excess / max(tcone, _TINY), lambda j: Finding(
            self.name,
            f"logged contact of {body_label(model, int(ca[j]))} with "
            f"{'static geometry' if cb[j] == STATIC_BODY else body_label(model, int(cb[j]))} "
            f"at t = {cts.t[j]:.6g} s: impulse outside the friction cone (normal {jn[j]:.3g} N s, "
            f"friction {ftt[j]:.3g} N s, along the normal {along[j]:.3g} N s, mu = {mu[j]:.3g})",
            float(excess[j]), tcone, "1", int(cts.step[j]), float(cts.t[j]), [int(ca[j])]))
