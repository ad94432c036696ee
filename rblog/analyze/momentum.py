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
  rblog's, which v1 logs imply: mu = sqrt(mu_a mu_b), e = max(e_a, e_b), Box2D's mixing rules).
  Logged contact impulses are checked against the cone as well. A body without a contract shape
  (a capsule, cylinder or mesh: only its geoms say where it touches) against a static box is not
  judged so (the box's face at the contact is not known from the body's centre).
* Impact events (rblog.analyze.events: the contact groups of consecutive intervals with the
  same bodies, so that an impact a compliant engine spreads over many steps is one event): the
  effective restitution ``e = -v_n(separation) / v_n(touch)`` of the contact point's normal
  velocity, each extrapolated under the free acceleration to the moment of touch / separation,
  is reported for every event (``Result.events``: e_eff, impulse, duration, peak penetration) and
  compared with the configured one (the log's combine rule) for spheres (boxes'
  multi-point impacts have no single-number restitution): more than configured is flagged at any
  speed, less only above RESTITUTION_MIN_SPEED_MPS (engines drop restitution for slow impacts so
  that bodies come to rest). What the samples leave unknown is when the impulse acted: anywhere
  from the touch to the separation (a soft contact's duration D, over which gravity acts too),
  widened to the integrator steps they fall in (a rigid engine applies it at a step boundary, on
  either side of its gravity kick) and by the touch's own uncertainty (a stepper whose logged
  velocities disagree with its positions, its flight error dv, misplaces the extrapolated touch
  by dv tau / |v_n|). Any restitution -v_n+(tau) / v_n-(tau) with both arcs taken to a moment tau
  in that window is consistent with the log: that range (``Events.e_lo .. e_hi``, the event's
  ``restitution_range``) holds e_eff, and the tolerance is RESTITUTION_REL x e plus the part of
  the range between e_eff and the configured e. Exact arcs allow the one integrator step the
  touch falls in ((1 + e) |a_n| dt / |v_n-|, 0.033 for a 1 m drop at dt = 10 ms, 0.0033 at
  1 ms); a 10% mismatch at 100 Hz on a 1 m drop is flagged for exact logs and for first-order
  steppers that clamp or reflect the penetration, at every phase of the touch within the step
  (tests/analyze/test_restitution.py). The touch height (an engine's contact margin or allowed
  penetration, ~0.1 mm) moves the touch by height / |v_n|, well within a step.
  A sphere that arrives faster than RESTITUTION_MIN_SPEED_MPS with e > 0 and
  never leaves (e |v_n| >= LOST_BOUNCE_MPS) has lost its bounce. The energy (kinetic + potential)
  of the bodies must not grow across an event when e <= 1, and must stay within
  ELASTIC_ENERGY_REL of the kinetic energy before it when e = 1 (same allowances as the energy
  analyzer's contact check).
* A contact on a static box's edge or corner (the witness point within the contact distance of
  two or three of its faces) has a fan of normals, any between those faces' normals: the cone is
  judged about the most favourable normal of the fan, not the one the geometry happens to pick.
* Lone bodies (nothing in reach) are judged per free flight: ``P(k) - P(k0) - (m g + F)(t - t0)``
  and ``L(k) - L(k0) - tau (t - t0)`` over the flight, relative to m max|v| and max|L|, once per
  flight (an engine's explicit-Euler gyroscopic drift is one finding per flight). Collisions of
  two or more bodies: one finding per event (consecutive intervals with the same members), the
  worst interval's.
* Friction cone findings need an excess above an absolute floor (CONE_FLOOR_NS plus the round-off
  of a momentum difference): sub-micro-newton-second residues are not findings.

Why this module is long: momentum is judged four ways that share the contact groups and events of
the Context (closed collisions, lone bodies' free flights, the Coulomb cone at static contacts
inferred and logged, and impact events), and each turns its measurements into findings with their
scale in words; splitting them would pass the same half-dozen arrays between modules.
"""

from __future__ import annotations

import math

import numpy as np

from rblog.analyze import _audit
from rblog.contract.model import BODY_STATIC, SHAPE_NONE, SHAPE_SPHERE
from rblog.contract.trajectory import STATIC_BODY
from rblog.analyze import geometry
from rblog.analyze import tolerances as T
from rblog.analyze.events import configured_restitution, impact_events
from rblog.analyze.base import (Analyzer, Context, Finding, Result, Worst, body_label, combine_friction,
                                shapeless_note,
                   combine_restitution, static_material)

_TINY = 1e-300


def _unjudged_line(model, unjudged: dict[int, str]) -> str:
    """One not-judged line for the bodies of Context.momentum_unjudged, grouped by reason."""
    by_reason: dict[str, list[int]] = {}
    for b, why in unjudged.items():
        by_reason.setdefault(why, []).append(b)
    parts = []
    for why, bodies in by_reason.items():
        names = ", ".join(repr(model.body_name[b]) for b in bodies[:3])
        more = f" +{len(bodies) - 3} more" if len(bodies) > 3 else ""
        parts.append(f"{len(bodies)} bod{'ies' if len(bodies) > 1 else 'y'} ({names}{more}): "
                     f"{why.replace('its ', 'their ') if len(bodies) > 1 else why}")
    return "momentum not judged for " + "; ".join(parts)


def _gap_line(model, gaps, bodies, gap) -> str:
    """One not-judged line for the intervals of Context.impulse_gaps in the balance: how many,
    of which bodies, and which kinds the writer left NaN there."""
    who = bodies[gap.any(axis=0)]
    names = ", ".join(repr(model.body_name[b]) for b in who[:3])
    more = f" +{len(who) - 3} more" if len(who) > 3 else ""
    kinds = " and ".join(sorted(gaps))
    n = int(gap.sum())
    return (f"momentum not judged in {n} interval{'s' if n > 1 else ''} of {len(who)} "
            f"bod{'ies' if len(who) > 1 else 'y'} ({names}{more}): their {kinds} impulses are "
            "not in the log there (NaN: the writer did not know them, e.g. pybullet's joint "
            "limits)")


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


def mu_static(model, i, sid, rule):
    """Friction of bodies i against static features sid (-1 ground, m static box m)."""
    _, s_fric = static_material(model, sid)
    return combine_friction(np.asarray(model.body_friction, float)[i], s_fric, rule)


#: points per arc between two face normals when searching a fan of normals
_FAN_SAMPLES = 33


def _fan_normal(model, sid, point, normal, jv, mu, cd):
    """For contacts with static boxes sid at ``point`` (world): where the point lies on an edge
    or corner of the box (within ``cd`` (P,) of two or three faces), the normal of the fan between
    those faces' outward normals for which the impulse jv is deepest inside (least outside) the
    Coulomb cone ``|J_t| <= mu J_n``; elsewhere ``normal`` unchanged. (P, 3)."""
    out = normal.copy()
    sx, sr, sh = geometry.static_boxes(model)
    for j in range(len(sid)):
        m = int(sid[j])
        if m < 0:
            continue
        q = sr[m].T @ (point[j] - sx[m])
        faces = [np.sign(q[a]) * sr[m][:, a] for a in range(3) if abs(q[a]) >= sh[m][a] - cd[j]]
        if len(faces) < 2:
            continue
        cands = [normal[j]]
        for a in range(len(faces)):
            for b in range(a + 1, len(faces)):
                w = np.linspace(0.0, 1.0, _FAN_SAMPLES)[:, None]
                arc = (1 - w) * faces[a] + w * faces[b]
                cands.extend(arc / np.linalg.norm(arc, axis=1)[:, None])
        cn = np.asarray(cands)
        jn = cn @ jv[j]
        jt = np.linalg.norm(jv[j][None] - jn[:, None] * cn, axis=1)
        out[j] = cn[int(np.argmin(np.maximum(jt - mu[j] * jn, -jn)))]
    return out


class MomentumAnalyzer(Analyzer):
    name = "momentum"
    description = ("collision momentum: conservation across body-body collisions, impulses in the "
                   "friction cone at static contacts, restitution and energy at impacts")
    defaults = T.options("momentum", "linear_rel", "angular_rel", "cone_rel", "impact_speed_mps",
                         "restitution_rel", "elastic_energy_rel", "cone_floor_ns",
                         "lost_bounce_mps", "restitution_min_speed_mps", "energy_rel",
                         position_correction_m=T.ENERGY_POSITION_CORRECTION_M,
                         dt_factor=T.ENERGY_DT_FACTOR, contact_distance_m=T.CONTACT_DISTANCE_M)

    def analyze(self, ctx: Context) -> Result:
        tr = ctx.traj
        if tr.n_samples < 2:
            return self.skip("needs at least two samples")
        cd = self.tol["contact_distance_m"]
        grp = ctx.groups(cd)
        # the impact events first: the energy analyzer shares them, and when the analyzers run
        # in threads it would otherwise wait for them until the end of this analysis
        impact_events(ctx, cd, self.tol["dt_factor"])
        self._not_judged: list[str] = []
        unjudged = ctx.momentum_unjudged
        if unjudged:
            bad = np.zeros(tr.n_bodies, bool)
            bad[list(unjudged)] = True
            # a static body has no momentum to judge: it is named only where a group it is in
            # has other members, left out with it (dm_control's 'target', welded and touching
            # nothing, reads as a group of its own at every interval: no gap in the verdict)
            static = np.asarray(tr.model.body_kind, np.int64).reshape(-1) == BODY_STATIC
            size = np.bincount(grp.mem_group, minlength=len(grp))
            shared = np.zeros(tr.n_bodies, bool)
            shared[grp.mem_i[size[grp.mem_group] > 1]] = True
            named = {b: w for b, w in unjudged.items() if not static[b] or shared[b]}
            grp = grp.subset(~ctx.groups_with(grp, bad))
            if named:
                self._not_judged.append(_unjudged_line(tr.model, named))
        self._ctx, self._grp, self._tr, self._model = ctx, grp, tr, tr.model
        self._worst = Worst("1", self.tol["linear_rel"])
        self._findings: list[Finding] = []
        self._n_found = 0
        stats: dict[str, float] = {"groups": float(len(grp))}
        self._balance(stats)
        self._closed(stats)
        self._flights(stats)
        self._single_static(stats)
        events = self._events(stats)
        self._logged_cone(stats)
        ok_reason = "no contacts or momentum jumps found" if not len(grp) else ""
        if stats.get("balance_intervals"):
            ok_reason = ""
        res = self.result(self._worst, self._findings, stats, events, ok_reason=ok_reason,
                          n_findings=self._n_found)
        res.leave_out(self._not_judged)
        return res.leave_out([] if len(tr.contacts) else shapeless_note(
            tr.model, "their free flights, collisions and contacts (the log has no contact "
                      "rows, and their contacts cannot be told from the poses)",
            known=ctx.contact_impulse_known()))

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

    def _balance(self, stats):
        """Bodies whose log carries their contact impulses: over every interval, the momentum
        change must equal the logged impulses plus the constant loads,
        ``P(k+1) - P(k) = (m g + F) dt + J_contact + J_other`` and ``L(k+1) - L(k) = tau dt +
        J_contact,ang + J_other,ang`` (J_other: the logged applied, passive, actuator and joint
        impulses, taken out in Context.p_eff / l_eff), at any stride and for any integrator
        whose writer sums the impulses over every step of the interval. Relative to the
        interval's scale m (max |v| + |a| dt) + |J_contact| (angular: max |L| + |J_contact,ang| +
        rho |J_contact|, and rho m |a| dt on logged joints), floored as the flights' are. An
        interval in which a logged impulse of the body is NaN (its writer did not know it there)
        is not judged, and the result says how many. One finding per body: its worst interval."""
        ctx, tr, model = self._ctx, self._tr, self._model
        logged = ctx.logged_contact_impulse()
        if logged is None or tr.n_samples < 2:
            return
        jl, ja = logged
        judged = ~np.isnan(jl[1:]).any(axis=(0, 2))
        if ctx.momentum_unjudged:
            judged[list(ctx.momentum_unjudged)] = False
        bodies = np.flatnonzero(judged)
        if not len(bodies):
            return
        t, step = tr.t, tr.step
        dts = ctx.dts[:, None, None]
        m = ctx.mass[bodies]
        p, l_ = ctx.p_eff[:, bodies], ctx.l_eff[:, bodies]
        jl, ja = jl[1:, bodies], ja[1:, bodies]
        force = m[:, None] * ctx.accel[bodies]
        r_lin = np.linalg.norm(np.diff(p, axis=0) - dts * force[None] - jl, axis=2)
        r_ang = np.linalg.norm(np.diff(l_, axis=0) - dts * ctx.torque_const[bodies][None] - ja,
                               axis=2)
        sp = ctx.speed[:, bodies]
        amag = np.linalg.norm(ctx.accel[bodies], axis=1)
        s_lin = m * (np.maximum(sp[:-1], sp[1:]) + amag * ctx.dt_step
                     + T.MOMENTUM_SPEED_FLOOR_MPS) + np.linalg.norm(jl, axis=2)
        lmag = np.linalg.norm(tr.angular_momentum[:, bodies], axis=2)
        i_max = np.asarray(model.body_inertia_diag, float)[bodies].max(axis=1)
        # the contact torques about the centre of mass are sums of r x f with |r| up to the
        # bounding radius: rho |J| is the size of their terms, which cancel at rest
        s_ang = np.maximum(lmag[:-1], lmag[1:]) + i_max * T.MOMENTUM_SPIN_FLOOR_RADPS \
            + np.linalg.norm(ja, axis=2) + ctx.rho[bodies] * np.linalg.norm(jl, axis=2)
        # a body on logged joints: they carry the moments of its loads (m g at a lever up to
        # rho), which cancel in free fall to the engine's round-off: rho m |a| dt is the size of
        # those terms (r2d2 falling: the ABA's reaction on its gripper pole, m 0.05 kg, is
        # 1e-20..3e-19 N m s a step of round-off, 1.5e-6 of a scale of 1.8e-13 without it)
        on_joints = ctx.joint_impulse_logged[bodies]
        s_ang = s_ang + np.where(on_joints, ctx.rho[bodies] * m * amag * ctx.dts[:, None], 0.0)
        # A first-order rotation step (MuJoCo's Euler, Bullet, ODE: w_b += h I^-1 (tau_b -
        # w_b x I w_b), then R turned by the new w_b) changes L = R I w_b by h tau + h (w' x L'
        # - w x L) a step: the gyroscopic term taken at the step's start instead of across it.
        # Over an interval that is h times the change of w x L (world) between its samples,
        # allowed dt_factor times; an exact rotation (rblog's) has no such error and is not
        # near it (its residues are at round-off).
        g = np.cross(tr.angular_velocity[:, bodies], tr.angular_momentum[:, bodies])
        rot_allow = self.tol["dt_factor"] * ctx.dt_step * np.linalg.norm(np.diff(g, axis=0),
                                                                         axis=2)
        # a logged contact impulse is known to the resolution the cone check grants it
        # (cone_rel of its size: an iterative solver's forces, MuJoCo's efc_force at its
        # tolerance, are not exactly the ones it integrated)
        jl_mag, ja_mag = np.linalg.norm(jl, axis=2), np.linalg.norm(ja, axis=2)
        lin_allow = self.tol["cone_rel"] * jl_mag
        rot_allow = rot_allow + self.tol["cone_rel"] * (ja_mag + ctx.rho[bodies] * jl_mag)
        # Bodies whose joint impulses are logged: an engine in generalized coordinates (MuJoCo,
        # Bullet's multibodies) integrates the joints' velocities, and a body's centre of mass
        # moves by J(q) qdot, not linearly in them; its joint impulse (the Newton-Euler residual
        # at a step's start) leaves the step's first-order error, h/2 times the change of the
        # momentum's rate over the step. Summed over an interval's steps that is h/2 times the
        # rate's change across it, estimated from the neighbouring intervals' mean rates and
        # allowed dt_factor times. The rates are those of the logged loads (contacts, every
        # other logged kind, gravity and the constant ones: the forces the writer knows), not
        # of the momenta under test: a jump in the log only, a velocity kick, would otherwise
        # allow itself (at every step: dt_factor h/2 |m dv / h| = m dv). Measured on kuka
        # under random motor targets at every step: the residual beyond the resolution below
        # is at most 1.64 times h/2 times the change of its loads' rate (1.34 of its momentum's).
        jointed = ctx.joint_impulse_logged[bodies] & ~ctx.integration_logged[bodies]
        if jointed.any():
            # such a writer's joint impulses come out of the engine's solve as its contact
            # impulses do (pybullet: the ABA's reaction plus the motor's constraint impulse of
            # the solver's last iteration), known to the same resolution, cone_rel of their size
            # (measured: r2d2 with its joints off their limits, a link's residual is a median
            # 1.6e-6 of its joint impulse, kuka holding itself up 2e-10)
            jj = ctx.traj.impulse("joint")
            jjl = np.linalg.norm(np.nan_to_num(jj[0][1:, bodies]), axis=2)
            jja = np.linalg.norm(np.nan_to_num(jj[1][1:, bodies]), axis=2)
            lin_allow += np.where(jointed[None, :], self.tol["cone_rel"] * jjl, 0.0)
            rot_allow += np.where(jointed[None, :], self.tol["cone_rel"]
                                  * (jja + ctx.rho[bodies] * jjl), 0.0)
        if jointed.any() and r_lin.shape[0] >= 2:
            ext_l, ext_a = ctx.ext_linear, ctx.ext_angular
            load_l = jl + dts * force[None]
            load_a = ja + dts * ctx.torque_const[bodies][None]
            if ext_l is not None:
                load_l = load_l + ext_l[1:, bodies]
                load_a = load_a + ext_a[1:, bodies]
            for allow, load in ((lin_allow, load_l), (rot_allow, load_a)):
                rate = load / dts  # (T-1, B, 3)
                d_rate = np.linalg.norm(np.diff(rate, axis=0), axis=2)  # (T-2, B)
                near = np.zeros_like(allow)
                near[:-1] = d_rate
                near[1:] = np.maximum(near[1:], d_rate)
                allow += np.where(jointed[None, :],
                                  self.tol["dt_factor"] * 0.5 * ctx.dt_step * near, 0.0)
        # Bodies whose log carries the integration kind (the momentum change of the engine's
        # steps beyond their start's forces, computed by the writer from the engine's own state):
        # their balance closes to round-off, with no allowance for the step's error
        exact = ctx.integration_logged[bodies]
        if exact.any():
            lin_allow[:, exact] = 0.0
            rot_allow[:, exact] = 0.0
        # intervals in which a logged impulse of the body is NaN (its writer did not know it:
        # pybullet's joint limits) are not judged
        gap = ctx.interval_unjudged
        gap = np.zeros(r_lin.shape, bool) if gap is None else gap[1:, bodies]
        stats["balance_bodies"] = float(len(bodies))
        stats["balance_intervals"] = float(r_lin.size - gap.sum())
        if gap.any():
            stats["balance_intervals_not_judged"] = float(gap.sum())
            self._not_judged.append(_gap_line(model, ctx.impulse_gaps, bodies, gap))
        for what, res, allow, scale, unit in (("linear", r_lin, lin_allow, s_lin, "kg m/s"),
                                              ("angular", r_ang, rot_allow, s_ang, "kg m^2/s")):
            tl = self.tol[f"{what}_rel"]
            # the residual beyond the step's own error, relative to the interval's scale
            rel = np.where(gap, 0.0, np.maximum(res - allow, 0.0) / scale)
            stats[f"balance_{what}_rel_max"] = float(rel.max())
            k_w = np.argmax(rel, axis=0)  # each body's worst interval
            rel_w = rel[k_w, np.arange(len(bodies))]
            n_bad = (rel > tl).sum(axis=0)
            self._worst.offer_array(rel_w, tl, "1", step[k_w + 1], t[k_w + 1], bodies,
                                    f"relative {what} momentum balance residual")

            def make(j, what=what, res=res, allow=allow, scale=scale, rel_w=rel_w, k_w=k_w,
                     n_bad=n_bad, unit=unit, tl=tl):
                b, k = int(bodies[j]), int(k_w[j])
                return Finding(
                    self.name,
                    f"{body_label(model, b)}: {what} momentum change between t = {t[k]:.6g} and "
                    f"{t[k + 1]:.6g} s differs from its logged impulses (contacts and every "
                    f"other load) plus gravity by {res[k, j]:.3g} {unit}; beyond the step's own "
                    f"error ({allow[k, j]:.2g} {unit}) that is {rel_w[j]:.3g} of the "
                    f"interval's scale {scale[k, j]:.3g} {unit} (tol {tl:.3g}; "
                    f"{int(n_bad[j])} interval{'s' if n_bad[j] != 1 else ''} over it)",
                    float(rel_w[j]), tl, "1", int(step[k + 1]), float(t[k + 1]), [b])

            self._add(rel_w > tl, rel_w / max(tl, _TINY), make)

    def _closed(self, stats):
        """Linear and angular momentum of closed groups (no static geometry in reach)."""
        ctx, tr, model, grp = self._ctx, self._tr, self._model, self._grp
        t, step = tr.t, tr.step
        # a lone body (a group of one, nothing in reach) is judged per free flight (_flights); a
        # group with a body on logged joints per body and interval (_balance): its joints'
        # impulses carry the engine's integration error, and parent and child touch by design
        sub = grp.subset(~grp.static & (grp.size >= 2)
                         & ~ctx.groups_with(grp, ctx.joint_impulse_logged))
        stats["closed_groups"] = float(len(sub))
        if not len(sub):
            return
        g, mk, mi = sub.mem_group, sub.mem_k, sub.mem_i
        m = ctx.mass[mi]
        dtm = ctx.dts[mk]
        x0, x1 = tr.position[mk, mi], tr.position[mk + 1, mi]
        p0, p1 = tr.linear_momentum[mk, mi], tr.linear_momentum[mk + 1, mi]
        l0, l1 = tr.angular_momentum[mk, mi], tr.angular_momentum[mk + 1, mi]
        ext_l, ext_a = ctx.ext_linear, ctx.ext_angular
        amag = np.linalg.norm(ctx.accel, axis=1)[mi]
        sp = np.maximum(ctx.speed[mk, mi], ctx.speed[mk + 1, mi])
        lin_res = np.linalg.norm(sub.sum(ctx.impulse(mk, mi)), axis=1)
        # floored: bodies at rest in zero gravity have no momentum to compare with (MuJoCo's
        # 1e-32 round-off over a 1e-33 scale once read as a relative change of 1.86)
        lin_scale = sub.sum(m * (sp + amag * dtm + T.MOMENTUM_SPEED_FLOOR_MPS))
        # angular momentum about the group's centre of mass (no gravity torque there)
        mtot = sub.sum(m)
        c0 = sub.sum(m[:, None] * x0) / mtot[:, None]
        c1 = sub.sum(m[:, None] * x1) / mtot[:, None]
        r0, r1 = x0 - c0[g], x1 - c1[g]
        force = ctx.force_const[mi]
        tau = ctx.torque_const[mi]
        ext = dtm[:, None] * (tau + 0.5 * (np.cross(r0, force) + np.cross(r1, force)))
        if ext_l is not None:
            # logged loads over the interval, their moment taken at the interval's mid-point
            # lever (as the constant force's: exact to first order in the interval)
            ext = ext + 0.5 * np.cross(r0 + r1, ext_l[mk + 1, mi]) + ext_a[mk + 1, mi]
        ang = sub.sum(np.cross(r1, p1) + l1 - np.cross(r0, p0) - l0 - ext)
        ang_res = np.linalg.norm(ang, axis=1)
        i_max = np.asarray(model.body_inertia_diag, float).max(axis=1)[mi]
        ang_scale = sub.sum(np.maximum(
            np.linalg.norm(l0, axis=1) + np.linalg.norm(r0, axis=1) * np.linalg.norm(p0, axis=1),
            np.linalg.norm(l1, axis=1) + np.linalg.norm(r1, axis=1) * np.linalg.norm(p1, axis=1),
        ) + i_max * T.MOMENTUM_SPIN_FLOOR_RADPS)
        # about the world origin too (for the message): L_O = sum x x P + L, less the torque of
        # gravity and the applied forces about the origin (midpoint rule: exact about the centre
        # of mass only, so this one is reported, not judged)
        fo = m[:, None] * ctx.accel[mi]
        ext_o = dtm[:, None] * (tau + 0.5 * (np.cross(x0, fo) + np.cross(x1, fo)))
        ang_o = np.linalg.norm(sub.sum(np.cross(x1, p1) + l1 - np.cross(x0, p0) - l0 - ext_o),
                               axis=1)
        rels = {"linear": lin_res / lin_scale, "angular": ang_res / ang_scale}
        res = {"linear": lin_res, "angular": ang_res}
        scales = {"linear": lin_scale, "angular": ang_scale}
        gk = sub.k
        # events: runs of consecutive intervals with the same members (a contact that lasts
        # is one collision); one finding per event, its worst interval
        mix = sub.mem_i.astype(np.int64) * 1_000_003 + 7
        h = np.add.reduceat(mix * mix % 2_147_483_647, sub.starts)
        order = np.lexsort((gk, sub.size, h))
        new = np.ones(len(sub), bool)
        new[1:] = ~((h[order][1:] == h[order][:-1]) & (sub.size[order][1:] == sub.size[order][:-1])
                    & (gk[order][1:] == gk[order][:-1] + 1))
        ev_id = np.empty(len(sub), np.int64)
        ev_id[order] = np.cumsum(new) - 1
        span0 = np.full(int(ev_id.max()) + 1, np.iinfo(np.int64).max)
        span1 = np.full(len(span0), -1)
        np.minimum.at(span0, ev_id, gk)
        np.maximum.at(span1, ev_id, gk)
        for what, rel in rels.items():
            tl = self.tol[f"{what}_rel"]
            stats[f"{what}_rel_max"] = float(rel.max())
            j = int(np.argmax(rel))
            self._worst.offer(rel[j] / tl if tl > 0 else np.inf, rel[j], tl, "1",
                              step[gk[j] + 1], t[gk[j] + 1], sub.members(j),
                              f"relative {what} momentum change")

            def make(j, what=what, rel=rel, tl=tl):
                b = sub.members(j)
                if what == "linear":
                    detail = (f"the members' impulses sum to {res[what][j]:.3g} N s, "
                              f"{rel[j]:.3g} of the scale sum m (|v| + |a| dt) = "
                              f"{scales[what][j]:.3g} kg m/s")
                else:
                    detail = (f"about the group's centre of mass it changes by "
                              f"{res[what][j]:.3g} kg m^2/s, {rel[j]:.3g} of the scale "
                              f"sum (|L_i| + |r_i| |P_i|) = {scales[what][j]:.3g} kg m^2/s "
                              f"(about the world origin, less the gravity torque: "
                              f"{ang_o[j]:.3g} kg m^2/s)")
                e = ev_id[j]
                n_iv = int(span1[e] - span0[e] + 1)
                during = (f" (worst of the contact's {n_iv} intervals, t = {t[span0[e]]:.6g} to "
                          f"{t[span1[e] + 1]:.6g} s)" if n_iv > 1 else "")
                return Finding(
                    self.name,
                    f"{what} momentum not conserved in the collision of {self._who(b)} between "
                    f"t = {t[gk[j]]:.6g} and {t[gk[j] + 1]:.6g} s{during}: {detail} "
                    f"(tol {tl:.3g})",
                    float(rel[j]), tl, "1", int(step[gk[j] + 1]), float(t[gk[j] + 1]), b)

            # the worst flagged interval of each event
            bad = np.nonzero(rel > tl)[0]
            keep = np.zeros(len(rel), bool)
            if len(bad):
                o = bad[np.lexsort((-rel[bad], ev_id[bad]))]
                first = np.ones(len(o), bool)
                first[1:] = ev_id[o][1:] != ev_id[o][:-1]
                keep[o[first]] = True
            self._add(keep, rel / max(tl, _TINY), make)

    def _flights(self, stats):
        """Lone bodies: linear and angular momentum over each free flight (a maximal run of
        intervals in which the body can touch nothing). Constant forces and torques change P and
        L exactly (P(k) = P(k0) + (m g + F)(t - t0), L(k) = L(k0) + tau (t - t0)), so the
        largest deviation over the flight, relative to the flight's scale m (max |v| + |a| dt)
        or max |L|, is judged once per flight: an engine whose explicit Euler step drifts L a
        little every step gets one finding per flight, not one per sample."""
        ctx, tr, model = self._ctx, self._tr, self._model
        t, step = tr.t, tr.step
        cd = self.tol["contact_distance_m"]
        free = ~ctx.touches(cd)["any"]
        if ctx.momentum_unjudged:
            free[:, list(ctx.momentum_unjudged)] = False
        # a body on joints is judged interval by interval (_balance: its joints' impulses carry
        # the engine's integration error, which a flight would accumulate)
        free[:, ctx.joint_impulse_logged] = False
        free = np.ascontiguousarray(free)
        if not free.any():
            stats["free_flights"] = 0.0
            return
        force = ctx.mass[:, None] * ctx.accel
        tau = ctx.torque_const
        i_max = np.asarray(model.body_inertia_diag, float).max(axis=1)
        p_floor = ctx.mass * (np.linalg.norm(ctx.accel, axis=1) * ctx.dt_step
                              + T.MOMENTUM_SPEED_FLOOR_MPS)
        # one call: as many flights as runs of free intervals
        cap = int(free[0].sum() + (free[1:] & ~free[:-1]).sum())
        while True:
            segs = np.empty((cap, 5), np.int64)  # body, k0, k1, worst k linear, worst k angular
            vals = np.empty((cap, 6))  # linear rel, scale, drift; angular rel, scale, drift
            c = np.ascontiguousarray
            cnt = _audit.flight_drift(c(free, dtype=np.bool_), c(tr.t, dtype=np.float64),
                                      c(ctx.p_eff, dtype=np.float64),
                                      c(ctx.l_eff, dtype=np.float64),
                                      c(ctx.speed, dtype=np.float64),
                                      c(ctx.mass, dtype=np.float64), c(force, dtype=np.float64),
                                      c(tau, dtype=np.float64), c(p_floor, dtype=np.float64),
                                      c(i_max * T.MOMENTUM_SPIN_FLOOR_RADPS, dtype=np.float64),
                                      segs, vals)
            if cnt <= cap:
                break
            cap = cnt
        segs, vals = segs[:cnt], vals[:cnt]
        stats["free_flights"] = float(cnt)
        for what, col, kcol, unit_l in (("linear", 0, 3, "kg m/s"), ("angular", 3, 4, "kg m^2/s")):
            tl = self.tol[f"{what}_rel"]
            rel = vals[:, col]
            stats[f"flight_{what}_rel_max"] = float(rel.max())
            j = int(np.argmax(rel))
            self._worst.offer(rel[j] / tl if tl > 0 else np.inf, rel[j], tl, "1",
                              step[segs[j, kcol]], t[segs[j, kcol]], [int(segs[j, 0])],
                              f"relative {what} momentum drift in free flight")

            def make(j, what=what, col=col, kcol=kcol, unit_l=unit_l, tl=tl, rel=rel):
                b, k0, k1, kw = (int(segs[j, 0]), int(segs[j, 1]), int(segs[j, 2]),
                                 int(segs[j, kcol]))
                scale, drift = vals[j, col + 1], vals[j, col + 2]
                if what == "linear":
                    about = (f"its momentum departs from P(t0) + (m g + F)(t - t0) by "
                             f"{drift:.3g} {unit_l}, {rel[j]:.3g} of the flight's scale "
                             f"m (max |v| + |a| dt) = {scale:.3g} {unit_l}")
                else:
                    about = (f"its angular momentum about its centre of mass departs from "
                             f"L(t0) + tau (t - t0) by {drift:.3g} {unit_l}, {rel[j]:.3g} of "
                             f"the flight's largest |L| = {scale:.3g} {unit_l}")
                return Finding(
                    self.name,
                    f"{body_label(model, b)}: {what} momentum not conserved in free flight "
                    f"between t = {t[k0]:.6g} and {t[k1]:.6g} s (touching nothing): {about}, "
                    f"worst at t = {t[kw]:.6g} s (tol {tl:.3g})",
                    float(rel[j]), tl, "1", int(step[kw]), float(t[kw]), [b])

            self._add(rel > tl, rel / max(tl, _TINY), make)

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

    def _single_static(self, stats):
        """One body against one static feature: the inferred impulse in the friction cone."""
        ctx, tr, model, grp = self._ctx, self._tr, self._model, self._grp
        t, step = tr.t, tr.step
        n = tr.n_bodies
        sel = grp.static & (grp.size == 1) & (grp.static_features == 1) & (grp.static_id >= -1)
        # a body without a contract shape (a capsule, cylinder, mesh) against a static box: the
        # box's normal at the contact is not known from the body's centre (a capsule on a slope
        # near its lower end is nearest the end face, 78 deg off the face it lies on), so its
        # cone is not judged; against the ground the normal is the plane's
        shapeless = np.asarray(model.body_shape) == SHAPE_NONE
        skip = (sel & shapeless[grp.mem_i[grp.starts]] & (grp.static_id >= 0) if shapeless.any()
                else np.zeros(len(sel), bool))
        stats["cone_not_judged_shapeless_on_static_box"] = float(skip.sum())
        gap = ctx.interval_unjudged
        if gap is not None:
            # a body whose logged impulse is NaN in the interval (a pybullet joint limit's): its
            # contact impulse cannot be inferred from its momentum
            ig = np.flatnonzero(sel & ~skip)
            hole = np.zeros(len(sel), bool)
            hole[ig] = gap[grp.k[ig] + 1, grp.mem_i[grp.starts[ig]]]
            stats["cone_not_judged_impulse_gap"] = float(hole.sum())
            skip = skip | hole
        gidx = np.nonzero(sel & ~skip)[0]
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
            ss0, nn0, pp0 = prox.iv_geometry(r, 0)
            ss1, nn1, pp1 = prox.iv_geometry(r, 1)
            nrm[sb] = np.where(use1[:, None], nn1, nn0)
            pts = np.where(use1[:, None], pp1, pp0)
            # how far the witness point may lie from the faces: the contact distance, plus the
            # penetration (the point is inside the box by that much)
            near_tol = self.tol["contact_distance_m"] + np.maximum(-np.where(use1, ss1, ss0), 0)
            sep0[sb] = prox.iv_sep0[r]

        # Coulomb cone of the inferred impulse J = P(k+1) - P(k) - (m g + F) dt
        mu = combine_friction(np.asarray(model.body_friction, float)[i], s_fric, tr.info.combine_friction)
        jv = ctx.impulse(k, i)
        if len(sb):
            # a contact on a static box's edge or corner has a fan of normals (any between the
            # adjacent faces' normals): judge the cone about the most favourable one
            nrm[sb] = _fan_normal(model, sid[sb], pts, nrm[sb], jv[sb], mu_static(
                model, i[sb], sid[sb], tr.info.combine_friction), near_tol)
        jn, jt, excess = (np.empty(len(k)) for _ in range(3))
        asc = np.ascontiguousarray
        _audit.cone_kernel(asc(jv, dtype=np.float64), asc(nrm, dtype=np.float64),
                           asc(mu, dtype=np.float64), asc(ctx.mass, dtype=np.float64),
                           asc(ctx.speed, dtype=np.float64),
                           asc(np.linalg.norm(ctx.accel, axis=1), dtype=np.float64),
                           asc(ctx.dts, dtype=np.float64), asc(k, dtype=np.int64),
                           asc(i, dtype=np.int64), float(self.tol["cone_floor_ns"]),
                           float(T.MOMENTUM_CONE_RESOLUTION_ULPS * np.finfo(float).eps), _TINY,
                           jn, jt, excess)
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


    def _events(self, stats) -> list[dict]:
        """Impact events: restitution, lost bounces, energy (see the module docstring)."""
        ctx, tr, model = self._ctx, self._tr, self._model
        ev = impact_events(ctx, self.tol["contact_distance_m"], self.tol["dt_factor"])
        e_n = len(ev)
        stats["events"] = float(e_n)
        if not e_n:
            return []
        t, step = tr.t, tr.step
        kb, ka = ev.k0, ev.k1 + 1
        # configured restitution by the log's combine rule
        grp = ev.groups
        e_cfg = configured_restitution(ev, model, tr.info.combine_restitution)
        approach = -ev.v_minus
        # what the samples leave unknown: the moment of the impulse, anywhere between the touch
        # (the approach arc reaching the partner) and the separation (the rebound arc leaving
        # it); the restitution is known to within e_lo .. e_hi (rblog.analyze.events), and the
        # relative tolerance is on top of the part of that range between e_eff and e_cfg
        with np.errstate(invalid="ignore"):
            slack = np.where(e_cfg < ev.e_eff, ev.e_eff - ev.e_lo, ev.e_hi - ev.e_eff)
        slack = np.where(np.isnan(slack), 0.0, np.maximum(slack, 0.0))
        e_tol = self.tol["restitution_rel"] * e_cfg + slack
        # events without a single normal velocity (boxes' multi-point contacts, groups of
        # three or more): an impact when two or more bodies meet and one arrives faster than the
        # impact speed
        impact = ev.impact(self.tol["impact_speed_mps"])
        if ctx.loaded.any():
            # a member under a logged load (joints, actuators, damping): its approach and
            # rebound are not free arcs, and the load does work across the event
            loaded = ctx.groups_with(ev.groups, ctx.loaded)[ev.first] & impact
            if loaded.any():
                stats["impacts_under_load_not_judged"] = float(loaded.sum())
                self._not_judged.append(
                    f"{int(loaded.sum())} impact{'s' if loaded.sum() > 1 else ''} of bodies under "
                    "logged loads (joints, actuators, damping) not judged for restitution and "
                    "energy: their arcs are not free flights")
            impact = impact & ~loaded
        stats["impacts"] = float(impact.sum())
        fast = approach >= self.tol["restitution_min_speed_mps"]
        # restitution the engine did not state (NaN in the body table: MuJoCo's soft contacts):
        # the impacts it would decide are not judged, and the result says so
        unknown = ev.sphere & impact & ~np.isfinite(e_cfg)
        stats["restitution_not_judged"] = float(unknown.sum())
        if unknown.any():
            who = sorted({b for j in np.flatnonzero(unknown) for b in ev.members(j)})
            names = ", ".join(repr(model.body_name[b]) for b in who[:3])
            more = f" +{len(who) - 3} more" if len(who) > 3 else ""
            self._not_judged.append(
                f"restitution of {int(unknown.sum())} impact{'s' if unknown.sum() > 1 else ''} "
                f"({names}{more}) not judged: the log states no restitution (NaN) for "
                f"{'them' if len(who) > 1 else 'it'}, so the bounce, a lost bounce and the "
                "energy across the impact have no expected value")
        dev = np.abs(ev.e_eff - e_cfg)
        judged = ev.sphere & impact & ev.separated & np.isfinite(dev)
        judged &= fast | (ev.e_eff > e_cfg)
        a_n = np.linalg.norm(ctx.accel, axis=1)[grp.mem_i[grp.starts[ev.first]]]
        short = a_n * ev.duration_s < T.MOMENTUM_IMPACT_GRAVITY_FRAC * np.abs(ev.v_minus)
        judged &= short
        ridx = np.nonzero(judged)[0]
        if len(ridx):
            stats["restitution_error_max"] = float(dev[ridx].max())
            self._worst.offer_array(dev[ridx], e_tol[ridx], "1", step[ka[ridx]], t[ka[ridx]],
                                    grp.mem_i[grp.starts[ev.first[ridx]]],
                                    "restitution deviation")

        def when(j):
            return f"t = {t[kb[j]]:.4g}..{t[ka[j]]:.4g} s"

        with np.errstate(invalid="ignore", divide="ignore"):
            dev_ratio = np.nan_to_num(dev / np.where(e_tol > 0, e_tol, _TINY))
        self._add(judged & (dev > e_tol), dev_ratio,
                  lambda j: Finding(
                      self.name,
                      f"{self._who(ev.members(j))}: restitution {ev.e_eff[j]:.4g} at the impact "
                      f"{when(j)} (approach {approach[j]:.3g} m/s), expected {e_cfg[j]:.4g}: "
                      f"off by {dev[j]:.3g} (limit {e_tol[j]:.3g} = "
                      f"{self.tol['restitution_rel']:.0%} of e + {slack[j]:.3g}: the samples allow "
                      f"{ev.e_lo[j]:.4g}..{ev.e_hi[j]:.4g}, the impulse anywhere from the touch "
                      f"to the separation)",
                      float(dev[j]), float(e_tol[j]), "1", int(step[ka[j]]), float(t[ka[j]]),
                      ev.members(j)))
        # lost bounce: a fast impact that never separates although e v_n is large
        # (an event that runs to the end of the log counts once it outlasts the flight the bounce
        # would have given, 2 e |v_n| / |a_n|)
        with np.errstate(invalid="ignore", divide="ignore"):
            outlasts = (ev.t1 - ev.t0) > 2 * e_cfg * approach / a_n
        lost = ev.sphere & fast & ~ev.separated & ((ka < tr.n_samples - 1) | outlasts) \
            & (e_cfg * approach >= self.tol["lost_bounce_mps"]) & np.isfinite(approach)
        lost &= ~(ev.v_plus > 0)
        if ctx.loaded.any():
            lost &= ~ctx.groups_with(ev.groups, ctx.loaded)[ev.first]
        self._add(lost, e_cfg * approach, lambda j: Finding(
            self.name,
            f"{self._who(ev.members(j))}: bounce lost at the impact {when(j)}: arrives at "
            f"{approach[j]:.3g} m/s with e = {e_cfg[j]:.3g} and should leave at "
            f"{e_cfg[j] * approach[j]:.3g} m/s, leaves at {max(ev.v_plus[j], 0.0):.3g} m/s "
            f"(limit: a rebound of at least {self.tol['lost_bounce_mps']:.3g} m/s)",
            float(e_cfg[j] * approach[j]), self.tol["lost_bounce_mps"], "m/s",
            int(step[ka[j]]), float(t[ka[j]]), ev.members(j)))

        # energy across the event
        torque_free = grp.sum(self.has_torque_f(grp.mem_i))[ev.first] == 0
        d_e = ev.energy_change
        base = ev.dt_allow + ev.mass_accel * self.tol["position_correction_m"]
        # the kinetic energy before, floored by the allowance (a group at rest has none)
        ke0 = np.maximum(ev.ke_before, base) + _TINY
        allow = base + self.tol["energy_rel"] * ev.ke_before + ev.stored_before
        check = impact & (e_cfg <= 1.0) & torque_free
        eidx = np.nonzero(check)[0]
        if len(eidx):
            stats["impact_energy_gain_rel_max"] = float((d_e[eidx] / ke0[eidx]).max())
            self._worst.offer_array(d_e[eidx] / ke0[eidx], allow[eidx] / ke0[eidx], "1",
                                    step[ka[eidx]], t[ka[eidx]],
                                    grp.mem_i[grp.starts[ev.first[eidx]]],
                                    "energy gain at an impact (relative to the kinetic energy "
                                    "before it)")
        self._add(check & (d_e > allow), d_e / np.maximum(allow, _TINY), lambda j: Finding(
            self.name,
            f"{self._who(ev.members(j))}: energy grows by {d_e[j]:.3g} J "
            f"({d_e[j] / ke0[j]:.3g} of the kinetic energy before the impact, "
            f"{ev.ke_before[j]:.3g} J) across the impact {when(j)} with restitution "
            f"{e_cfg[j]:.3g} <= 1 (limit {allow[j]:.3g} J)",
            float(d_e[j] / ke0[j]), float(allow[j] / ke0[j]), "1", int(step[ka[j]]),
            float(t[ka[j]]), ev.members(j)))
        elastic = check & (e_cfg >= 1.0) & (ev.static_id == -2)
        elastic_allow = ev.dt_allow + self.tol["elastic_energy_rel"] * ev.ke_before + ev.stored_after
        loss = -d_e
        self._add(elastic & (loss > elastic_allow), loss / np.maximum(elastic_allow, _TINY),
                  lambda j: Finding(
                      self.name,
                      f"{self._who(ev.members(j))}: elastic impact (e = 1) {when(j)} loses "
                      f"{loss[j] / ke0[j]:.3%} of the kinetic energy before it "
                      f"({ev.ke_before[j]:.4g} J -> {ev.ke_after[j]:.4g} J; limit "
                      f"{self.tol['elastic_energy_rel']:.2%})",
                      float(loss[j] / ke0[j]), float(elastic_allow[j] / ke0[j]), "1",
                      int(step[ka[j]]), float(t[ka[j]]), ev.members(j)))
        out = []
        js = np.flatnonzero(impact[:T.MAX_EVENTS])
        # the events' columns as Python lists, read once (not one numpy scalar per field)
        col = lambda a: np.asarray(a)[js].tolist()  # noqa: E731
        fin = lambda x: x if math.isfinite(x) else None  # noqa: E731
        for j, (st_, t_, tb_, t0_, t1_, stat_, ap_, vp_, ee_, ec_, elo_, ehi_, imp_, dur_, pen_,
                pt_, sep_, de_) in zip(js.tolist(), zip(
                    col(step[ka]), col(t[ka]), col(t[kb]), col(ev.t0), col(ev.t1),
                    col(ev.static_id != -2), col(approach), col(ev.v_plus), col(ev.e_eff),
                    col(e_cfg), col(ev.e_lo), col(ev.e_hi), col(ev.impulse_ns),
                    col(ev.duration_s), col(ev.peak_penetration_m), col(ev.peak_point),
                    col(ev.separated), col(d_e))):
            out.append({
                "kind": "impact", "step": int(st_), "t": float(t_),
                "t_before": float(tb_), "t_start": float(t0_), "t_end": float(t1_),
                "bodies": ev.members(j), "static": bool(stat_),
                "approach_speed_mps": fin(ap_),
                "separation_speed_mps": fin(vp_),
                "restitution_effective": fin(ee_),
                "restitution_configured": fin(ec_),
                "restitution_range": [fin(elo_), fin(ehi_)],
                "impulse_ns": float(imp_), "duration_s": float(dur_),
                "peak_penetration_m": float(pen_),
                "point": [fin(x) for x in pt_],
                "separated": bool(sep_),
                "energy_change_J": float(de_),
            })
        fe = np.isfinite(ev.e_eff) & impact
        if fe.any():
            stats["restitution_effective_mean"] = float(ev.e_eff[fe].mean())
        return out

    def has_torque_f(self, mi):
        return self._ctx.has_torque[mi].astype(float)

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
        excess_ns = np.maximum.reduce([ftt - mu * jn, -jn, np.abs(along)])
        excess = excess_ns / mag
        excess = np.where(valid & (excess_ns > self.tol["cone_floor_ns"]), excess, 0.0)
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
