"""Energy: drift while only conservative forces act, and gain across contacts.

Each body's energy is recomputed from the logged state: ``P.P / 2m + L.ω / 2`` (logged momenta
and angular velocity) plus the potential of gravity and of its constant applied force,
``-(m g + F).x`` (a constant force is conservative: its work is F.Δx). A constant applied torque is
not (its work depends on the path of the rotation), so bodies with one are left out (skipped with
a reason when that is every body).

* Drift: over every stretch of samples in which a body cannot touch anything (recomputed geometry,
  swept over each interval, and the logged contacts; where the log carries the body's contact
  impulses, the intervals in which they are zero: touched), ``|E(t) - E(start)|`` must stay within
  ``DRIFT_REL x scale + DT_FACTOR x m |a| dt (|v(t)| + |v(start)|) / 2``. The scale is the
  energy that moves: ``max(max kinetic energy, range of potential energy)`` over the stretch
  (floor: ENERGY_FLOOR per kg). Total energy |E0| is no scale: the potential's zero (the world
  origin) is arbitrary, and a body dropped from rest at z = 0 has E0 = 0. The second term: a
  first-order (symplectic Euler) gravity step conserves the shadow energy E - m g.v dt / 2, so
  E itself moves by up to m |g| dt (|v(t)| + |v(start)|) / 2 (reached at every pair of samples
  symmetric about an apex), taken DT_FACTOR = 2 times for margin; dt is the integrator step from
  the log (RunInfo.dt).
* Gain across a contact: for every contact event (the contact groups of consecutive intervals
  with the same bodies, rblog.analyze.events, so that a soft contact that stores energy in one
  step and gives it back in the next is judged once), the energy of the members must not grow by more than the same dt term,
  ``m |g| POSITION_CORRECTION_M`` (an engine lifting a body out of penetration), the elastic
  energy a compliant contact may hold at the event's first sample (``F d / 2``,
  rblog.analyze.events.stored_energy: MuJoCo's soft contacts are 5-15 mm deep at a sample inside
  an impact) and CONTACT_GAIN_REL of their kinetic energy, unless a configured restitution exceeds 1. Static
  geometry does no work, and a collision between bodies cannot add energy with e <= 1.
"""

from __future__ import annotations

import numpy as np

from rblog.analyze import _audit
from rblog.analyze import tolerances as T
from rblog.analyze.base import (Analyzer, Context, Finding, Result, Worst, body_label,
                                shapeless_note,
                                static_material)
from rblog.analyze.events import configured_restitution, impact_events

_TINY = 1e-300
#: the kinds whose nonzero impulse always does work (damping -c v: -c |v|^2 dt; an actuator
#: driving a joint), so a log that logs their impulse and states their work "none" has not
#: given it (applied: "none" may be the model's constant, conservative force; joint: an ideal
#: joint's reactions do no net work on its tree)
DISSIPATIVE_KINDS = ("passive", "actuator")


#: |a_i . a_j| below which a middle hinge counts as orthogonal to its neighbours (rotor_energy)
_ORTHO = 1e-9


def rotor_energy(model, tr) -> tuple[np.ndarray | None, list[str]]:
    """The kinetic energy of the joints' rotors, ``0.5 joint_armature qdot^2`` per dof, from the
    logged motion of each joint's two bodies; (T, N) J on each joint's child body (None when no
    moving joint has an armature above 0), and the lines of what it leaves out (joints whose armature the log does not state, or whose dof rates the
    rows cannot give).

    Per child body c with parent p (the world for -1; all vectors world frame): the relative
    angular velocity ``w = w_c - w_p`` and the velocity of c's centre relative to p's frame
    ``v = v_c - v_p - w_p x (x_c - x_p)``. Its rows (the engine's order, parent side first):

    * rotations: a ball alone, ``w`` itself (its 3 dofs: 0.5 a |w|^2); hinges, ``w = sum_i qdot_i
      e_i`` solved for qdot (least squares, exact for a consistent w): the first hinge's axis
      is fixed in the parent (``e_1 = R_p axis_parent``), the last in the child
      (``e_k = R_c axis_body``); a middle one of three is normal to both (``e_1 x e_3``, its sign
      free: qdot^2 is what counts), which holds when its axis is orthogonal to its neighbours';
    * slides before the rotations, their axes fixed in the parent (``R_p axis_parent``):
      ``v - w x (x_c - a) = sum_s qdot_s e_s``, a the rotations' common anchor
      (``x_c + R_c anchor_body``).

    This is MuJoCo's qvel of a hinge (the rate about ``xaxis``), a slide and a ball (the relative
    angular velocity; its norm in any frame). A free body's rotor (MuJoCo's free-joint armature)
    has no row; the MuJoCo adapter names such bodies.
    """
    from rblog.contract.model import JOINT_BALL, JOINT_FIXED, JOINT_HINGE, JOINT_SLIDE

    T_, n = tr.n_samples, tr.n_bodies
    notes: list[str] = []
    arm = np.asarray(model.joint_armature, np.float64).reshape(-1)
    jt = np.asarray(model.joint_type, np.int64).reshape(-1)
    jb = np.asarray(model.joint_body, np.int64).reshape(-1)
    moving = jt != JOINT_FIXED
    unstated = moving & np.isnan(arm)
    if unstated.any():
        notes.append(f"the rotor energy of {int(unstated.sum())} joint(s) (bodies "
                     f"{', '.join(repr(model.body_name[b]) for b in np.unique(jb[unstated])[:3])}"
                     f"{' ...' if len(np.unique(jb[unstated])) > 3 else ''}): their armature is "
                     "not stated in the log, so it is not counted")
    active = np.unique(jb[moving & (np.nan_to_num(arm) > 0)])
    if not len(active):
        return None, notes
    out = np.zeros((T_, n))
    R, x, v, w = tr.rotation, tr.position, tr.velocity, tr.angular_velocity
    parent = np.asarray(model.body_parent, np.int64).reshape(-1)
    eye, zero = np.broadcast_to(np.eye(3), (T_, 3, 3)), np.zeros((T_, 3))
    cant = []
    for c in active:
        rows = np.flatnonzero(jb == c)
        rows = rows[jt[rows] != JOINT_FIXED]
        if np.isnan(arm[rows]).any():
            continue  # named above
        p = int(parent[c])
        Rp, xp, vp, wp = (eye, zero, zero, zero) if p < 0 else (R[:, p], x[:, p], v[:, p], w[:, p])
        w_rel = w[:, c] - wp
        v_rel = v[:, c] - vp - np.cross(wp, x[:, c] - xp)
        types = jt[rows]
        rot = rows[types != JOINT_SLIDE]
        sl = rows[types == JOINT_SLIDE]
        hinge = rot[jt[rot] == JOINT_HINGE]
        ok = (np.isin(types, (JOINT_HINGE, JOINT_SLIDE, JOINT_BALL)).all()
              and (len(sl) == 0 or sl.max() < (rot.min() if len(rot) else np.inf))
              and (len(hinge) == len(rot) and len(rot) <= 3 or len(rot) == 1))
        ab, apar = model.joint_axis_body, model.joint_axis_parent
        if ok and len(hinge) == 3:
            a1, a2, a3 = (ab[j] for j in hinge)
            ok = abs(a1 @ a2) < _ORTHO and abs(a2 @ a3) < _ORTHO
        if ok and len(rot) and len(sl):
            anc = model.joint_anchor_body[rot]
            ok = np.allclose(anc, anc[0], rtol=0.0, atol=1e-12)
        if not ok:
            cant.append(int(c))
            continue
        e_c = lambda j: np.einsum("tij,j->ti", R[:, c], ab[j])  # noqa: E731 (child-fixed axis)
        e_p = lambda j: np.einsum("tij,j->ti", Rp, apar[j])  # noqa: E731 (parent-fixed axis)
        if len(rot) == 1 and jt[rot[0]] == JOINT_BALL:
            out[:, c] += 0.5 * arm[rot[0]] * np.einsum("ti,ti->t", w_rel, w_rel)
        elif len(rot):
            axes = [e_c(hinge[-1])] if len(rot) == 1 else [e_p(hinge[0]), e_c(hinge[-1])]
            if len(rot) == 3:
                mid = np.cross(axes[0], axes[1])
                axes.insert(1, mid / np.linalg.norm(mid, axis=1, keepdims=True))
            E = np.stack(axes, axis=2)  # (T, 3, k)
            qd = np.einsum("tkj,tj->tk", np.linalg.pinv(E), w_rel)
            out[:, c] += 0.5 * (qd ** 2) @ arm[hinge]
        if len(sl):
            r = v_rel
            if len(rot):
                a_w = np.einsum("tij,j->ti", R[:, c], model.joint_anchor_body[rot[0]])
                r = v_rel + np.cross(w_rel, a_w)  # v - w x (x_c - a), a = x_c + a_w
            S = np.stack([e_p(j) for j in sl], axis=2)  # (T, 3, s)
            qd = np.einsum("tkj,tj->tk", np.linalg.pinv(S), r)
            out[:, c] += 0.5 * (qd ** 2) @ arm[sl]
    if cant:
        notes.append(f"the rotor energy of {len(cant)} bod{'ies' if len(cant) > 1 else 'y'} "
                     f"({', '.join(repr(model.body_name[b]) for b in cant[:3])}"
                     f"{' ...' if len(cant) > 3 else ''}): their joints' rates cannot be told "
                     "from the logged motion (rblog.analyze.energy.rotor_energy), so it is not "
                     "counted")
    return out, notes


def touched(ctx: Context, tch) -> np.ndarray:
    """(T-1, N) bool: the intervals in which a contact may have done work on each body. Where the
    log carries a body's contact impulses at every interval (contact_impulse_known), what the
    engine applied: a nonzero impulse, linear or angular, summed over the interval's steps (a
    contact that pushed with no force did no work); elsewhere the geometric reach of
    Context.touches (swept bounds, conservative: at a stride of 10 MuJoCo's humanoid reads
    touching the floor in steps 0-40 that MuJoCo ran without a contact)."""
    reach = tch["any"]
    known = ctx.contact_impulse_known()
    if not known.any():
        return reach
    lin, ang = ctx.logged_contact_impulse()
    pushed = (np.abs(lin[1:]).max(axis=2) > 0) | (np.abs(ang[1:]).max(axis=2) > 0)
    return np.where(known[None, :], pushed, reach)


def trees(ctx: Context, free, e, ke, u, sp, m, amag, not_judged: list[str]):
    """The energy columns of the drift check with the bodies under logged loads joined into
    articulated trees (``body_parent`` links; a body and its descendants down to free bodies),
    or None when no body is under a logged load (every column a body, as before).

    A tree's column: touching nothing when none of its members does; its energy is the sum of
    its members' less the logged work of their loads since the first sample (``work_applied``,
    ``work_passive``, ``work_actuator``, ``work_joint``); its mass the sum, its acceleration the
    largest of its members' and its speed such that the dt allowance's m |a| v is the members'
    sum of m_b |a_b| |v_b| (the bias of each member's first-order step). Ideal joints (no
    friction in them, no limit violated) pass energy between a tree's bodies and do no net work
    on it, so this sum is conserved up to the integrator's error, the same dt allowance as a free body's; an engine's step error
    beyond it is a finding, as a free body's drift is (dm_control's fish, Euler without gravity,
    its passive work logged: 3.8 % of its largest kinetic energy lost in 4 s, 2.0 % at half the
    step; tests/adapters/test_mujoco_fish_energy.py). An interval whose logged work is NaN ends
    the stretch (the tree is judged on either side, and the result says how many intervals it
    left out). A tree with a member whose
    load has no logged work (its impulse kind logged or missing, its work missing) is not
    judged, and ``not_judged`` says which.

    Returns (free, e, ke, u, sp, m, amag, labels, members) over the columns.
    """
    from rblog.contract.model import (BODY_KINEMATIC, BODY_STATIC, IMPULSE_KINDS,
                                      SUPPLIED_LOGGED, SUPPLIED_NONE, WORK_KINDS)

    tr, model = ctx.traj, ctx.model
    loaded = ctx.loaded
    if not loaded.any():
        return None
    n = tr.n_bodies
    parent = np.asarray(model.body_parent, np.int64).reshape(n)
    kind = np.asarray(model.body_kind, np.int64).reshape(n)
    root = np.arange(n)
    for _ in range(n):  # follow parents up to a body on the world (depth <= n)
        up = parent[root]
        step_up = (up >= 0) & (kind[np.maximum(up, 0)] != BODY_STATIC)
        if not step_up.any():
            break
        root = np.where(step_up, up, root)
    # the work of each load kind, where its impulse acts: a kind whose impulse is logged or
    # unknown must have its work logged (or be known absent)
    isup = np.asarray(model.body_impulse_supplied, np.int64).reshape(n, len(IMPULSE_KINDS))
    wsup = np.asarray(model.body_work_supplied, np.int64).reshape(n, len(WORK_KINDS))
    work_known = np.ones(n, bool)
    unstated: dict[str, np.ndarray] = {}  # kind -> bodies whose acting force's work is "none"
    work = np.zeros((tr.n_samples, n))
    # intervals in which a body's logged work is NaN (its writer did not know it there: an
    # RK4 step with a joint limit, MuJoCo's adapter): a stretch ends before them
    gap = np.zeros((tr.n_samples - 1, n), bool)
    for j, kk in enumerate(WORK_KINDS):
        acts = isup[:, IMPULSE_KINDS.index(kk)] != SUPPLIED_NONE
        w = tr.work(kk)
        known = wsup[:, j] == SUPPLIED_NONE
        if kk in DISSIPATIVE_KINDS and (known & acts).any():
            # work "none" with a nonzero impulse of the kind logged: the force acts (a damping's
            # impulse -c v dt does the work -c v.v dt != 0), so its work is not known, only
            # unstated (pybullet's log: its damping impulse logged, every work "none")
            imp = tr.impulse(kk)
            if imp is not None:
                nz = np.zeros(n, bool)
                for a in imp:
                    nz |= (np.abs(np.nan_to_num(a[1:])) > 0).any(axis=(0, 2))
                unstated[kk] = known & acts & nz
                known = known & ~unstated[kk]
        if w is not None:
            nan = np.isnan(w[1:])
            logged = ~nan.all(axis=0) if len(nan) else np.zeros(n, bool)
            logged &= wsup[:, j] == SUPPLIED_LOGGED  # "none" reads as zeros, not as logged
            known |= logged
            gap |= nan & logged[None, :]
            work += np.nan_to_num(w)
        work_known &= ~acts | known
    cum = np.concatenate([np.zeros((1, n)), np.cumsum(work[1:], axis=0)])
    e = e - cum
    rigid = (kind == BODY_KINEMATIC) | (kind == BODY_STATIC)
    roots = np.unique(root[~rigid])
    cols = []
    for r in roots:
        mem = np.flatnonzero((root == r) & ~rigid)
        cols.append(mem)
    bad = [c for c in cols if not work_known[c].all()]
    ok = [c for c in cols if work_known[c].all()]
    if bad:
        names = ", ".join(repr(model.body_name[c[0]]) for c in bad[:3])
        more = f" +{len(bad) - 3} more" if len(bad) > 3 else ""
        why = [k for k, b in unstated.items() if any(b[c].any() for c in bad)]
        why = (f" (its {' and '.join(why)} impulse is logged, nonzero, with its work stated "
               "none)") if why else ""
        not_judged.append(f"energy of {len(bad)} bod{'ies' if len(bad) > 1 else 'y'} or tree(s) "
                          f"({names}{more}) not judged: the work of a load on them is not in "
                          f"the log{why}")
    c_n = len(ok)
    kn = free.shape[0]
    f_free = np.zeros((kn, c_n), bool)
    f_e, f_ke, f_u, f_sp = (np.zeros((tr.n_samples, c_n)) for _ in range(4))
    f_m, f_a = np.zeros(c_n), np.zeros(c_n)
    labels = []
    gaps = [int(gap[:, c].any(axis=1).sum()) for c in ok]
    if any(gaps):
        who = [repr(model.body_name[c[0]]) for c, g_ in zip(ok, gaps) if g_][:3]
        not_judged.append(f"energy not judged in {sum(gaps)} interval(s) of "
                          f"{sum(1 for g_ in gaps if g_)} tree(s) ({', '.join(who)}): the work "
                          "of a load on them is not in the log there (NaN: the writer did not "
                          "know it: a joint limit's force inside an RK4 step, or in a pybullet "
                          "step that begins at the limit)")
    for j, c in enumerate(ok):
        f_free[:, j] = free[:, c].all(axis=1) & ~gap[:, c].any(axis=1)
        f_e[:, j] = e[:, c].sum(axis=1)
        f_ke[:, j] = ke[:, c].sum(axis=1)
        f_u[:, j] = u[:, c].sum(axis=1)
        f_m[j] = m[c].sum()
        f_a[j] = amag[c].max()
        # the speed that makes the allowance's m |a| v the members' sum of m_b |a_b| |v_b|:
        # each member's first-order step moves its energy by up to m_b |a_b| dt |v_b| / 2
        ma = m[c] * amag[c]
        f_sp[:, j] = (sp[:, c] @ ma) / (f_m[j] * f_a[j]) if f_m[j] * f_a[j] > 0 \
            else sp[:, c].max(axis=1)
        lab = body_label(model, int(c[0]))
        labels.append(lab if len(c) == 1 else f"the tree of {lab} ({len(c)} bodies)")
    return f_free, f_e, f_ke, f_u, f_sp, f_m, f_a, labels, [list(map(int, c)) for c in ok]


class EnergyAnalyzer(Analyzer):
    name = "energy"
    description = ("energy drift of free bodies under conservative forces, and energy gain "
                   "across contacts")
    defaults = T.options("energy", "drift_rel", "contact_gain_rel", "position_correction_m",
                         "dt_factor", "floor_j_per_kg", contact_distance_m=T.CONTACT_DISTANCE_M)

    def analyze(self, ctx: Context) -> Result:
        tr = ctx.traj
        model = tr.model
        if tr.n_samples < 2:
            return self.skip("needs at least two samples")
        if ctx.has_torque.all():
            return self.skip("every body has a constant applied torque (not conservative)")
        n, t_n = tr.n_bodies, tr.n_samples
        cd = self.tol["contact_distance_m"]
        t, step = tr.t, tr.step
        worst = Worst("1", self.tol["drift_rel"])
        findings: list[Finding] = []
        stats: dict[str, float] = {}
        n_found = 0
        ke, u = ctx.energies()
        # + the joints' rotors (MuJoCo's armature), which move with the bodies: part of the
        # model's kinetic energy that no body's momenta hold
        rotor, not_judged = rotor_energy(model, tr)
        if rotor is not None and rotor.any():
            ke = ke + rotor
        e = ke + u
        m = ctx.mass
        amag = np.linalg.norm(ctx.accel, axis=1)
        sp = ctx.speed
        tch = ctx.touches(cd)

        # ---- drift over contact-free stretches: free bodies under their constant loads one by
        # one; bodies under logged loads (joints, actuators, damping, pushes) as whole
        # articulated trees, whose energy less the logged work of those loads is conserved
        # (ideal joints do no net work on a tree; rblog.analyze.energy.trees)
        free = ~touched(ctx, tch) & ~ctx.has_torque[None, :]  # (T-1, N)
        tr_cols = trees(ctx, free, e, ke, u, sp, m, amag, not_judged)
        if tr_cols is not None:
            free, e, ke, u, sp, m, amag, labels, _ = tr_cols
        else:
            labels = [body_label(model, b) for b in range(n)]
        free = np.ascontiguousarray(free)
        cap = 1024
        while True:
            segs = np.empty((cap, 4), np.int64)  # body, first sample, last sample, worst sample
            vals = np.empty((cap, 5))  # worst ratio, rel, tol rel, scale, rate (rel/s)
            asc = np.ascontiguousarray
            cnt = _audit.free_drift(asc(free, dtype=np.bool_), asc(t, dtype=np.float64),
                                    asc(e, dtype=np.float64), asc(ke, dtype=np.float64),
                                    asc(u, dtype=np.float64), asc(sp, dtype=np.float64),
                                    asc(m, dtype=np.float64), asc(amag, dtype=np.float64),
                                    float(ctx.dt_step * self.tol["dt_factor"]),
                                    float(self.tol["drift_rel"]),
                                    float(self.tol["floor_j_per_kg"]), segs, vals)
            if cnt <= cap:
                break
            cap = cnt
        segs, vals = segs[:cnt], vals[:cnt]
        stats["free_stretches"] = float(cnt)
        members = (lambda c: [c]) if tr_cols is None else (lambda c: tr_cols[-1][c])
        if cnt:
            j = int(np.argmax(vals[:, 0]))
            b, k = int(segs[j, 0]), int(segs[j, 3])
            worst.offer(vals[j, 0], vals[j, 1], vals[j, 2], "1", step[k], t[k], members(b),
                        "relative energy drift in a contact-free stretch")
            bad = np.nonzero(vals[:, 0] > 1.0)[0]
            n_found += len(bad)
            for s_ in bad[np.argsort(-vals[bad, 0])][: T.MAX_FINDINGS]:
                b, k0, k = int(segs[s_, 0]), int(segs[s_, 1]), int(segs[s_, 3])
                ratio, rel, tol_rel, scale, rate = vals[s_]
                where = ("in free flight" if tr_cols is None or len(members(b)) == 1
                         and not ctx.loaded[members(b)[0]] else
                         "less the logged work of its loads, touching nothing,")
                findings.append(Finding(
                    self.name,
                    f"{labels[b]}: energy {'grows' if e[k, b] > e[k0, b] else 'drops'}"
                    f" by {abs(e[k, b] - e[k0, b]):.3g} J {where} between t = {t[k0]:.6g} "
                    f"and {t[k]:.6g} s: {rel:.3g} of the flight's energy scale {scale:.3g} J "
                    f"(its largest kinetic energy or potential-energy range; independent of the "
                    f"potential's zero), limit {tol_rel:.3g} (rate {rate:+.3g}/s)",
                    float(rel), float(tol_rel), "1", int(step[k]), float(t[k]), members(b)))

        # ---- gain across contact events (rblog.analyze.events: consecutive intervals of one
        # contact joined, so a soft contact that stores and gives back energy is judged once)
        ev = impact_events(ctx, cd, self.tol["dt_factor"])
        if len(ev):
            grp = ev.groups
            rest = configured_restitution(ev, model, tr.info.combine_restitution)
            torque_free = grp.sum(ctx.has_torque[grp.mem_i].astype(float))[ev.first] == 0
            check = (rest <= 1.0) & torque_free
            loaded = ctx.groups_with(grp, ctx.loaded)[ev.first]
            if (check & loaded).any():
                not_judged.append(
                    f"the energy across {int((check & loaded).sum())} contact event(s) of bodies "
                    "under logged loads (joints, actuators, damping): their work over the event "
                    "is not separated from the contact's")
            check &= ~loaded
            kscale = np.maximum(ev.ke_before, ev.ke_after)
            # + the elastic energy a compliant contact may hold at the event's first sample
            # (rblog.analyze.events.stored_energy): given back after it, it is no gain
            allowed = (ev.dt_allow + ev.mass_accel * self.tol["position_correction_m"]
                       + self.tol["contact_gain_rel"] * kscale + ev.stored_before)
            scale = kscale + ev.dt_allow + ev.mass_accel * self.tol["position_correction_m"] \
                + ev.stored_before + _TINY
            gain_rel, allow_rel = ev.energy_change / scale, allowed / scale
            ka = ev.k1 + 1
            cidx = np.nonzero(check)[0]
            stats["contact_events"] = float(len(cidx))
            if len(cidx):
                stats["contact_gain_rel_max"] = float(gain_rel[cidx].max())
                worst.offer_array(gain_rel[cidx], allow_rel[cidx], "1", step[ka[cidx]],
                                  t[ka[cidx]], grp.mem_i[grp.starts[ev.first[cidx]]],
                                  "energy gain across a contact (relative to the kinetic energy "
                                  "+ allowance)")
            bad = np.nonzero(check & (ev.energy_change > allowed))[0]
            n_found += len(bad)
            bad = bad[np.argsort(-(gain_rel[bad] / np.maximum(allow_rel[bad], _TINY)))]
            for j in bad[: T.MAX_FINDINGS]:
                bodies = ev.members(j)
                who = " and ".join(body_label(model, x) for x in bodies[:3]) + \
                    (" ..." if len(bodies) > 3 else "")
                what = "each other" if ev.static_id[j] == -2 else "static geometry"
                findings.append(Finding(
                    self.name,
                    f"{who}: energy grows by {ev.energy_change[j]:.3g} J across a contact with "
                    f"{what} between t = {t[ev.k0[j]]:.6g} and {t[ka[j]]:.6g} s (limit "
                    f"{allowed[j]:.3g} J: {self.tol['contact_gain_rel']:.2g} of the kinetic energy "
                    f"{kscale[j]:.3g} J + step, position-correction and stored-contact "
                    f"({ev.stored_before[j]:.3g} J) terms, restitution {rest[j]:.3g} <= 1)",
                    float(gain_rel[j]), float(allow_rel[j]), "1", int(step[ka[j]]),
                    float(t[ka[j]]), bodies))
        if ctx.has_torque.any():
            stats["bodies_with_torque_skipped"] = float(ctx.has_torque.sum())
        if not cnt and not stats.get("contact_events"):
            # no contact-free stretch and no contact event checked: nothing was judged
            return self.not_judged("; ".join(not_judged or [
                "no stretch of two samples touching nothing and no contact event to judge"]))
        res = self.result(worst, findings, stats, n_findings=n_found)
        res.leave_out(not_judged)
        return res.leave_out([] if len(tr.contacts) else shapeless_note(
            tr.model, "their free-flight energy (the log has no contact rows, and their contacts "
                      "cannot be told from the poses)", known=ctx.contact_impulse_known()))
