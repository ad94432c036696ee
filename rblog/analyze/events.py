"""Impact events: contact groups of consecutive sample intervals joined into one event.

A compliant engine (MuJoCo's soft contacts, Bullet's penalty and split impulses) spreads an impact
over several steps: the bodies approach, press into each other and separate again, a little of the
momentum exchanged in each step. Judged interval by interval, one clean bounce looks like dozens of
"energy grows" (the spring gives back what it stored) and negative "restitutions" (the normal
velocity still approaching after a step). Judged as one event, it is one bounce with one effective
restitution.

Event: the contact groups of :meth:`Context.groups` (bodies whose momentum jumped, with everything
they could touch) of consecutive intervals k0 .. k1 with the same members and the same static
feature. Its state before is sample k0, after is sample k1 + 1 (both outside the contact, when the
contact began and ended between samples).

Per event (arrays of E events):

* ``k0, k1`` first and last interval; ``t0 = t[k0]``, ``t1 = t[k1 + 1]``; ``members`` via
  :meth:`Events.members`; ``static_id`` (-1 ground, m static box m, -2 none, -3 unknown).
* ``v_minus``, ``v_plus`` (m/s): the normal velocity of the contact point (relative to the partner)
  at the moment of touch and of separation, extrapolated under the free acceleration from the
  samples before and after (the time of touch is where the separation sep + v_n tau + a_n tau^2/2
  reaches 0). Computed for one body against one static feature (contact point: witness of the
  deepest point) and for two spheres (line of centres); NaN otherwise.
* ``e_eff = -v_plus / v_minus`` (Newton's restitution of the whole event); ``e_lo, e_hi`` the
  range of restitutions the samples allow: ``-v_n+(tau) / v_n-(tau)`` with the approach arc (from
  sample k0) and the rebound arc (back from k1+1) both taken to one moment tau of the impulse,
  for tau anywhere from the touch to the separation, widened by the touch's and the separation's
  own uncertainty (the stepper's flight error, :func:`flight_error`, over the extrapolation) and
  then to the integrator steps (RunInfo.dt) they fall in, within the event's samples; +inf where
  the approach would have stopped within the window. e(tau) is monotonic, so the range is its
  ends' (and holds e_eff). Exact arcs give the range of the one step the touch falls in (their
  touch and separation coincide, and their flight error is round-off). ``gap_s`` the
  separation minus the touch time (negative when the rebound arc leaves before the approach arc
  arrives: a stepper that reflects the penetration), ``duration_s`` (from
  touch to separation when both are known, else the event's sample span), ``impulse_ns`` (|sum of
  the first member's contact impulses over the event|, N s), ``peak_penetration_m`` (deepest
  overlap of the members with their partner at the event's samples, recomputed from the poses),
  ``separated`` (the event ended before the log did and the contact point separates).
* ``energy_change`` (J, kinetic + potential of the members, after minus before), ``ke_before``,
  ``ke_after`` (J), ``dt_allow`` (J, the shadow-energy term of a first-order gravity step at the
  two end samples: dt_factor m |a| dt (|v_before| + |v_after|) / 2 per member; a state function,
  so it does not grow with the event's length); ``stored_before``, ``stored_after`` (J, the
  elastic energy a compliant contact may hold in the members at the end samples, ``F d / 2``:
  :func:`stored_energy`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rblog.analyze import _audit
from rblog.contract.model import SHAPE_SPHERE
from rblog.analyze import geometry
from rblog.analyze import tolerances as T


#: a touch within this fraction of a step of a step boundary may lie in either step
_STEP_EPS = 1e-6


def contact_time(sep0, vn0, an, dt):
    """Smallest tau in [0, dt] with sep0 + vn0 tau + an tau^2 / 2 = 0 (clamped; 0 if sep0 <= 0)."""
    sep0 = np.maximum(sep0, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        disc = vn0 * vn0 - 2.0 * an * sep0
        sq = np.sqrt(np.maximum(disc, 0.0))
        qq = -0.5 * (vn0 + np.copysign(sq, vn0))
        r1 = np.where(qq != 0, sep0 / qq, np.inf)
        r2 = np.where(an != 0, 2.0 * qq / an, np.inf)
    r1 = np.where(r1 >= 0, r1, np.inf)
    r2 = np.where(r2 >= 0, r2, np.inf)
    tau = np.minimum(r1, r2)
    tau = np.where((disc >= 0) & np.isfinite(tau), tau, dt)
    return np.clip(tau, 0.0, dt)


@dataclass
class Events:
    k0: np.ndarray
    k1: np.ndarray
    static_id: np.ndarray
    size: np.ndarray
    first: np.ndarray          # (E,) index of the event's first group (for its members)
    groups: object             # the Context.groups table
    t0: np.ndarray
    t1: np.ndarray
    v_minus: np.ndarray
    v_plus: np.ndarray
    e_eff: np.ndarray
    e_lo: np.ndarray           # (E,) restitution range the samples allow (see the docstring)
    e_hi: np.ndarray
    gap_s: np.ndarray          # (E,) separation minus touch time, signed (NaN: not computed)
    sphere: np.ndarray         # (E,) restitution is one number (spheres)
    duration_s: np.ndarray
    impulse_ns: np.ndarray
    peak_penetration_m: np.ndarray
    peak_point: np.ndarray     # (E, 3) where the deepest overlap is (m, world)
    separated: np.ndarray
    energy_change: np.ndarray
    ke_before: np.ndarray
    ke_after: np.ndarray
    dt_allow: np.ndarray
    mass_accel: np.ndarray     # (E,) sum of m |a| of the members (N)
    speed_before: np.ndarray   # (E,) fastest member's |v| at the sample before (m/s)
    stored_before: np.ndarray  # (E,) elastic energy a compliant contact may hold at k0 (J)
    stored_after: np.ndarray   # (E,) ... at k1 + 1 (J)
    member_event: np.ndarray   # (Q,) the event of each member (groups.mem_k, groups.mem_i)

    def __len__(self) -> int:
        return len(self.k0)

    def impact(self, impact_speed: float) -> np.ndarray:
        """(E,) which events are impacts: the contact point approaches faster than
        ``impact_speed`` (m/s); for events without a single normal velocity (boxes' multi-point
        contacts, groups of three or more), two or more bodies meet and one arrives faster."""
        approach = -self.v_minus
        return np.where(np.isfinite(approach), approach > impact_speed,
                        (self.size >= 2) & (self.speed_before > impact_speed))

    def impact_intervals(self, impact_speed: float, n_intervals: int, n_bodies: int) -> np.ndarray:
        """(T-1, N) bool: the sample intervals in which each body is a member of an impact
        event (:meth:`impact`)."""
        out = np.zeros((n_intervals, n_bodies), bool)
        if len(self):
            sel = self.impact(impact_speed)[self.member_event]
            out[self.groups.mem_k[sel], self.groups.mem_i[sel]] = True
        return out

    def members(self, j: int) -> list[int]:
        return self.groups.members(int(self.first[j]))


def impact_events(ctx, cd: float, dt_factor: float) -> Events:
    """The events of ``ctx`` (see the module docstring); cached per (cd, dt_factor)."""
    return ctx.cached(("events", cd, dt_factor), lambda: _events(ctx, cd, dt_factor))


def _events(ctx, cd, dt_factor) -> Events:
    tr, model = ctx.traj, ctx.model
    grp = ctx.groups(cd)
    # a lone body (a group of one with nothing in reach) is in no contact: an explicit-Euler
    # rotation step changes its L every interval, which is judged per free flight (momentum)
    lone = ~grp.static & (grp.size < 2)
    if lone.any():
        grp = grp.subset(~lone)
    c = len(grp)
    n = tr.n_bodies
    # a key per group: its member set and static feature
    if c:
        sizes = grp.size
        mix = grp.mem_i.astype(np.int64) * 1_000_003 + 7
        h = np.add.reduceat(mix * mix % 2_147_483_647, grp.starts)
        sid_g = np.asarray(grp.static_id, np.int64)
        mem0 = np.asarray(grp.mem_i[grp.starts], np.int64)
        # groups are ordered by interval, then by smallest member: link each to the group of
        # the previous interval with the same key (one compiled pass)
        eid_of = np.empty(c, np.int64)
        head_of = np.empty(c, np.int64)
        k1 = np.empty(c, np.int64)
        asc = np.ascontiguousarray
        n_ev = _audit.link_groups(asc(grp.k, dtype=np.int64), asc(h, dtype=np.int64),
                                  asc(sizes, dtype=np.int64), asc(sid_g, dtype=np.int64),
                                  asc(mem0, dtype=np.int64), n, eid_of, head_of, k1)
        first, k1 = head_of[:n_ev], k1[:n_ev]
        k0 = grp.k[first]
        # events in the order of their first interval, then of their key (hash, size, static
        # feature, smallest member: unique within an interval)
        srt = np.lexsort((mem0[first], sid_g[first], sizes[first], h[first], k0))
        k0, k1, first = k0[srt], k1[srt], first[srt]
        rank = np.empty(n_ev, np.int64)
        rank[srt] = np.arange(n_ev)
        ev_of_member = rank[eid_of[grp.mem_group]]  # (Q,) event of each group member
    else:
        k0 = k1 = first = np.zeros(0, np.int64)
        ev_of_member = np.zeros(0, np.int64)
    e_n = len(k0)
    t = tr.t
    st = grp.starts[first] if e_n else np.zeros(0, np.int64)
    size = grp.size[first] if e_n else np.zeros(0, np.int64)
    sid = np.where(grp.static_features[first] == 1, grp.static_id[first], np.where(
        grp.static[first], -3, -2)) if e_n else np.zeros(0, np.int64)
    a_mem = grp.mem_i[st] if e_n else np.zeros(0, np.int64)
    b_mem = np.where(size >= 2, grp.mem_i[np.minimum(st + 1, len(grp.mem_i) - 1)], -1) \
        if e_n else np.zeros(0, np.int64)
    kb, ka = k0, k1 + 1  # samples before and after

    # energy of the members, before and after; allowances
    ke, u = ctx.energies()
    mass = ctx.mass
    amag = np.linalg.norm(ctx.accel, axis=1)
    ev_of_mem = np.repeat(np.arange(e_n), size)
    if e_n:  # the members of each event's first group, event after event (Groups.members)
        lo = grp.starts[first]
        cnt = np.append(grp.starts, len(grp.mem_i))[first + 1] - lo
        off = np.cumsum(cnt) - cnt
        mem = grp.mem_i[np.repeat(lo - off, cnt) + np.arange(int(cnt.sum()))].astype(np.int64)
    else:
        mem = np.zeros(0, np.int64)
    kbm, kam = kb[ev_of_mem], ka[ev_of_mem]

    def per_event(x):
        return np.bincount(ev_of_mem, weights=x, minlength=e_n) if e_n else np.zeros(0)

    energy_change = per_event(ke[kam, mem] + u[kam, mem] - ke[kbm, mem] - u[kbm, mem])
    ke_before = per_event(ke[kbm, mem])
    ke_after = per_event(ke[kam, mem])
    dt_allow = per_event(0.5 * dt_factor * mass[mem] * amag[mem] * ctx.dt_step
                         * (ctx.speed[kbm, mem] + ctx.speed[kam, mem]))
    mass_accel = per_event(mass[mem] * amag[mem])
    speed_before = np.zeros(e_n)
    if e_n:
        np.maximum.at(speed_before, ev_of_mem, ctx.speed[kbm, mem])
    # impulse on the first member over the event: P(after) - P(before) - (m g + F) (t1 - t0)
    pa = tr.linear_momentum
    span = t[ka] - t[kb] if e_n else np.zeros(0)
    force = mass[a_mem, None] * ctx.accel[a_mem] if e_n else np.zeros((0, 3))
    impulse = np.linalg.norm(pa[ka, a_mem] - pa[kb, a_mem] - span[:, None] * force, axis=1) \
        if e_n else np.zeros(0)

    v_minus = np.full(e_n, np.nan)
    v_plus = np.full(e_n, np.nan)
    gap = np.full(e_n, np.nan)
    e_at_touch = np.full(e_n, np.nan)
    e_at_sep = np.full(e_n, np.nan)
    duration = span.astype(float).copy()
    peak = np.zeros(e_n)
    peak_pt = np.full((e_n, 3), np.nan)
    sphere = np.zeros(e_n, bool)
    shape = np.asarray(model.body_shape)
    single = (size == 1) & (sid >= -1)
    pair = (size == 2) & (sid == -2)
    if pair.any():
        pair &= (shape[a_mem] == SHAPE_SPHERE) & (shape[np.maximum(b_mem, 0)] == SHAPE_SPHERE)
    for sel, kind in ((single, "static"), (pair, "pair")):
        idx = np.nonzero(sel)[0]
        if not len(idx):
            continue
        a = a_mem[idx]
        b = np.where(sid[idx] >= 0, n + sid[idx], -1) if kind == "static" else b_mem[idx]
        vn = {}
        sep = {}
        for end, kk in (("b", kb[idx]), ("a", ka[idx])):
            if kind == "static":
                ground = sid[idx] == -1
                s_ = np.empty(len(idx))
                nrm = np.empty((len(idx), 3))
                pt = np.empty((len(idx), 3))
                if ground.any():
                    gi = np.nonzero(ground)[0]
                    nrm[gi] = np.asarray(model.ground_normal, float)
                    pos, rot = tr.position[kk[gi], a[gi]], tr.rotation[kk[gi], a[gi]]
                    pt[gi] = geometry.plane_witness(model, a[gi], pos, rot)
                    s_[gi] = pt[gi] @ np.asarray(model.ground_normal, float) - model.ground_offset
                if (~ground).any():
                    bi = np.nonzero(~ground)[0]
                    s_[bi], nrm[bi], pt[bi] = geometry.pair_geometry(
                        model, tr.position, tr.rotation, kk[bi], a[bi], b[bi])
                vrel = tr.velocity[kk, a] + np.cross(tr.angular_velocity[kk, a],
                                                     pt - tr.position[kk, a])
            else:
                s_, nrm, pt = geometry.pair_geometry(model, tr.position, tr.rotation, kk, a, b)
                vrel = tr.velocity[kk, a] - tr.velocity[kk, b]
            an = np.einsum("ij,ij->i", ctx.accel[a] - (ctx.accel[b] if kind == "pair" else 0.0),
                           nrm)
            vn[end] = (np.einsum("ij,ij->i", vrel, nrm), an)
            sep[end] = s_
        dt_b = ctx.dts[kb[idx]]
        dt_a = ctx.dts[k1[idx]]
        vn0, an0 = vn["b"]
        vn1, an1 = vn["a"]
        tc = contact_time(sep["b"], vn0, an0, dt_b)               # touch after sample k0
        ts = contact_time(sep["a"], -vn1, an1, dt_a)              # separation before sample k1+1
        v_minus[idx] = vn0 + an0 * tc
        v_plus[idx] = vn1 - an1 * ts
        gap[idx] = span[idx] - tc - ts
        duration[idx] = np.maximum(gap[idx], 0.0)
        # the window the impulse may lie in (s after sample k0): from the touch to the separation,
        # widened to the integrator steps they fall in; both arcs are taken to its ends
        sp = span[idx]
        t_sep = sp - ts
        h = ctx.dt_step if ctx.dt_step > 0 else np.inf
        # the touch and the separation come from the logged velocity and position at k0 (k1+1);
        # where a stepper's velocities disagree with its positions by dv (its flight error,
        # measured over the free intervals next to the event), the extrapolated height is off by
        # dv tau and the moment by dv tau / |v_n|
        dv = np.fmax(flight_error(ctx, kb[idx] - 1, a, b if kind == "pair" else None),
                     flight_error(ctx, ka[idx], a, b if kind == "pair" else None))
        dv = np.where(np.isnan(dv), 0.5 * np.abs(np.fmax(an0, an1)) * (h if np.isfinite(h)
                                                                        else dt_b), dv)
        with np.errstate(invalid="ignore", divide="ignore"):
            d_tc = np.nan_to_num(dv * tc / np.abs(v_minus[idx]), nan=np.inf)
            d_ts = np.nan_to_num(dv * ts / np.abs(v_plus[idx]), nan=np.inf)
        lo = np.minimum(tc - d_tc, t_sep - d_ts)
        hi = np.maximum(tc + d_tc, t_sep + d_ts)
        if np.isfinite(h):
            lo = np.floor(lo / h - _STEP_EPS) * h
            hi = (np.floor(hi / h + _STEP_EPS) + 1.0) * h
        else:
            lo, hi = np.zeros_like(sp), sp
        lo, hi = np.clip(lo, 0.0, sp), np.clip(hi, 0.0, sp)
        with np.errstate(invalid="ignore", divide="ignore"):
            for out, tau in ((e_at_touch, lo), (e_at_sep, hi)):
                v_in = vn0 + an0 * tau
                out[idx] = np.where(v_in < 0, -(vn1 - an1 * (sp - tau)) / v_in, np.inf)
        sphere[idx] = shape[a] == SHAPE_SPHERE
    with np.errstate(invalid="ignore", divide="ignore"):
        e_eff = -v_plus / v_minus
    e_lo = np.fmin(np.fmin(e_at_touch, e_at_sep), e_eff)
    e_hi = np.fmax(np.fmax(e_at_touch, e_at_sep), e_eff)
    last = tr.n_samples - 1
    separated = (ka < last) & ~(v_plus < 0)
    # peak penetration over the event's samples: the members against the ground (at both samples
    # of each member interval) and in every interval row of the proximity table (pairs, static
    # boxes) of a member's interval; vectorized over the members (each body is in one group per
    # interval, so this is O(members + rows))
    prox = ctx.proximity(cd)
    best = np.full(e_n, np.inf)
    cand_val, cand_ev, cand_src = [], [], []  # per candidate: separation, event, where
    if e_n and prox.ground_sep is not None:
        gs = prox.ground_sep
        mk, mi = grp.mem_k, grp.mem_i
        for end in (0, 1):
            cand_val.append(gs[mk + end, mi])
            cand_ev.append(ev_of_member)
            cand_src.append(np.stack([np.zeros_like(mk), mk + end, mi], axis=1))
    if e_n and len(prox.iv_k):
        ev_map = np.full((max(tr.n_samples - 1, 0), n), -1, np.int64)
        ev_map[grp.mem_k, grp.mem_i] = ev_of_member
        for side in (prox.iv_a, prox.iv_b):
            ok = side < n
            rows = np.nonzero(ok)[0]
            e_r = ev_map[prox.iv_k[rows], side[rows]]
            has = e_r >= 0
            rows, e_r = rows[has], e_r[has]
            for end, sep_ in ((0, prox.iv_sep0), (1, prox.iv_sep1)):
                cand_val.append(sep_[rows])
                cand_ev.append(e_r)
                cand_src.append(np.stack([np.ones_like(rows), rows, np.full_like(rows, end)],
                                         axis=1))
    if cand_val:
        val = np.concatenate(cand_val)
        evs = np.concatenate(cand_ev)
        src = np.concatenate(cand_src)
        np.minimum.at(best, evs, val)
        hit = np.nonzero((val == best[evs]) & (val < 0))[0]
        evs_hit, first_hit = np.unique(evs[hit], return_index=True)
        h = hit[first_hit]
        peak[evs_hit] = -val[h]
        kind, x, y = src[h, 0], src[h, 1], src[h, 2]
        g = kind == 0
        if g.any():
            peak_pt[evs_hit[g]] = geometry.plane_witness_at(model, x[g], y[g], y[g],
                                                            tr.position, tr.rotation)
        for end in (0, 1):
            r = ~g & (y == end)
            if r.any():
                peak_pt[evs_hit[r]] = prox.iv_geometry(x[r], end)[2]
    return Events(k0=k0, k1=k1, static_id=sid, size=size, first=first, groups=grp,
                  t0=t[kb] if e_n else np.zeros(0), t1=t[ka] if e_n else np.zeros(0),
                  v_minus=v_minus, v_plus=v_plus, e_eff=e_eff, e_lo=e_lo, e_hi=e_hi,
                  gap_s=gap, sphere=sphere, duration_s=duration, impulse_ns=impulse,
                  peak_penetration_m=peak,
                  peak_point=peak_pt, separated=separated, energy_change=energy_change,
                  ke_before=ke_before, ke_after=ke_after, dt_allow=dt_allow,
                  mass_accel=mass_accel, speed_before=speed_before,
                  stored_before=per_event(stored_energy(ctx, kbm, mem)),
                  stored_after=per_event(stored_energy(ctx, kam, mem)),
                  member_event=ev_of_member)


def flight_error(ctx, k: np.ndarray, a: np.ndarray, b: np.ndarray | None = None) -> np.ndarray:
    """(P,) how far the logged velocities of body a (and b) disagree with their positions over
    the sample interval k .. k+1 (m/s): ``|(x(k+1) - x(k)) / dt - (v(k) + v(k+1)) / 2|``, summed
    over the two bodies (a bound on their relative motion's); NaN where k is outside the log. The
    trapezoid rule is exact for motion at constant acceleration, so exact flight gives round-off;
    a first-order stepper logs the velocity of its step's second half (symplectic Euler) or first
    half (explicit Euler): |a| dt / 2. An impulse inside the interval shows as a larger value."""
    tr = ctx.traj
    out = np.full(len(k), np.nan)
    ok = (k >= 0) & (k < tr.n_samples - 1)
    if not ok.any():
        return out
    kk = k[ok]
    dt = ctx.dts[kk]
    res = np.zeros(len(kk))
    for body in (a, b):
        if body is None:
            continue
        i = body[ok]
        x0, x1 = tr.position[kk, i], tr.position[kk + 1, i]
        v0, v1 = tr.velocity[kk, i], tr.velocity[kk + 1, i]
        with np.errstate(invalid="ignore", divide="ignore"):
            d = np.linalg.norm((x1 - x0) / dt[:, None] - 0.5 * (v0 + v1), axis=1)
        res = res + np.where(dt > 0, d, np.inf)
    out[ok] = res
    return out


def stored_energy(ctx, k: np.ndarray, i: np.ndarray) -> np.ndarray:
    """(P,) elastic energy a compliant contact may hold in body i at sample k (J): ``F d / 2``,
    the energy of a linear spring pressed d deep by the force F (d: the body's deepest
    penetration at k, recomputed from the poses; F: its logged contact force at the step that
    ends at k, sum of J_n / dt, or else the mean force of its inferred impulse over the interval
    before k). A soft engine (MuJoCo) holds a body pressed 5-15 mm into the ground at a sample
    inside an impact; the energy it gives back after the sample is not a gain. For a rigid
    engine d is ~1e-5 m and this is negligible."""
    tr = ctx.traj
    n = tr.n_bodies
    p_n = len(k)
    if not p_n:
        return np.zeros(0)
    depth = np.zeros(p_n)
    prox = ctx.proximity(T.CONTACT_DISTANCE_M)
    if prox.ground_sep is not None:
        depth = np.maximum(depth, -prox.ground_sep[k, i])
    want = k * n + i
    order = np.argsort(want, kind="stable")
    ws = want[order]
    for end, sep_ in ((0, prox.iv_sep0), (1, prox.iv_sep1)):
        kk = prox.iv_k + end
        for side in (prox.iv_a, prox.iv_b):
            ok = (side < n) & (sep_ < 0)
            key = kk[ok] * n + side[ok]
            pos = np.clip(np.searchsorted(ws, key), 0, p_n - 1)
            hit = ws[pos] == key
            # every occurrence of the key among the wanted (members repeat across events)
            lo = np.searchsorted(ws, key[hit], side="left")
            hi = np.searchsorted(ws, key[hit], side="right")
            d = -sep_[ok][hit]
            for j in range(int((hi - lo).max()) if len(lo) else 0):
                m = lo + j < hi
                np.maximum.at(depth, order[(lo + j)[m]], d[m])
    force = np.zeros(p_n)
    c = tr.contacts
    if len(c):
        kr = np.searchsorted(tr.step, c.step)
        ok = kr < tr.n_samples
        ok[ok] = tr.step[kr[ok]] == c.step[ok]
        dt = ctx.dt_step if ctx.dt_step > 0 else 1.0
        for side in (c.body_a, c.body_b):
            s_ = side.astype(np.int64)
            m = ok & (s_ >= 0) & (s_ < n)
            key = kr[m] * n + s_[m]
            pos = np.clip(np.searchsorted(ws, key), 0, p_n - 1)
            hit = ws[pos] == key
            lo = np.searchsorted(ws, key[hit], side="left")
            hi = np.searchsorted(ws, key[hit], side="right")
            f = c.normal_impulse[m][hit] / dt
            for j in range(int((hi - lo).max()) if len(lo) else 0):
                mm = lo + j < hi
                np.add.at(force, order[(lo + j)[mm]], f[mm])
    before = k >= 1
    if before.any() and tr.n_samples > 1:
        kb = k[before] - 1
        j_ = np.linalg.norm(ctx.impulse(kb, i[before]), axis=1) / ctx.dts[kb]
        force[before] = np.maximum(force[before], j_)
    return 0.5 * force * depth


def configured_restitution(ev: Events, model, rule: str = "max") -> np.ndarray:
    """(E,) the restitution each event should show, by the log's combine rule
    (RunInfo.combine_restitution): one body against one static feature, or two bodies, combine
    their two coefficients; larger groups get the largest combination in play (an upper bound: the
    rules all stay within [min, max] of the pair for e in [0, 1])."""
    from rblog.analyze.base import combine_restitution, static_material

    e_body = np.asarray(model.body_restitution, float)
    grp = ev.groups
    if not len(ev):
        return np.zeros(0)
    st = grp.starts[ev.first]
    a = grp.mem_i[st]
    b = grp.mem_i[np.minimum(st + 1, len(grp.mem_i) - 1)]
    e_max = grp.max(e_body[grp.mem_i])[ev.first]
    s_rest, _ = static_material(model, ev.static_id)
    static = ev.static_id != -2
    single = static & (ev.size == 1)
    pair = ~static & (ev.size == 2)
    out = np.where(static, np.maximum(e_max, s_rest), e_max)
    out = np.where(single, combine_restitution(e_body[a], s_rest, rule), out)
    out = np.where(pair, combine_restitution(e_body[a], e_body[b], rule), out)
    return out
