"""Stage 10 of the contact step: restitution, the bounce of impact points after positions moved.

Restitution (Box2D v3): after positions are integrated, points that were hit (solve impulse > 0)
while approaching faster than the threshold get a normal velocity set from the approach velocity
measured *before* the solve. rblog sharpens Box2D's rule with the flight's energy: a body that no
contact pushes flies exactly under its constant acceleration (step.py, stage 9), so between
contacts the gap s, its rate w and the relative normal acceleration a of the external forces
(gravity) keep ``E = w^2/2 - a s`` exactly (at every step boundary). The approach speed at
contact is therefore ``u = sqrt(2 E) = sqrt(w0^2 - 2 a s0)`` from the start-of-step gap s0 and
rate w0 (before the kick), and the rebound rate w+ is chosen so that the post-impact state at the
end-of-step gap s1 has energy e^2 E: ``w+^2/2 - a s1 = e^2 u^2/2``, i.e.
``w+ = sqrt(e^2 u^2 + 2 a s1)``. The exact flight after the bounce keeps that energy, so the
apex is e^2 times the drop height: bounce apexes e^(2n) h0 to round-off plus the sampling of the
apex (a rule that ignored the gravity over the step would be ~1% off at dt = 1e-3). Without
external acceleration this is w+ = e |w0|.
"""

from __future__ import annotations

import math

from numba import njit

from rblog.engine.contact.manifold import (
    MF_ACC, MF_E, MF_MU, MF_N, MF_T1, MF_T2, MI_A, MI_ACTIVE, MI_B, MI_COUNT, MI_START, PF_IMPACT, PF_L1, PF_L2, PF_LN, PF_LWS, PF_NMASS, PF_RA, PF_RB, PF_S, PF_SEND, PF_W0, PF_WT,
)
from rblog.engine.contact.solver import _cross, apply_impulse


@njit(cache=True)
def _gap_rate(v, w, ia, ib, nx, ny, nz, rax, ray, raz, rbx, rby, rbz):
    dvx = v[ia, 0] + w[ia, 1] * raz - w[ia, 2] * ray - v[ib, 0] - w[ib, 1] * rbz + w[ib, 2] * rby
    dvy = v[ia, 1] + w[ia, 2] * rax - w[ia, 0] * raz - v[ib, 1] - w[ib, 2] * rbx + w[ib, 0] * rbz
    dvz = v[ia, 2] + w[ia, 0] * ray - w[ia, 1] * rax - v[ib, 2] - w[ib, 0] * rby + w[ib, 1] * rbx
    return dvx * nx + dvy * ny + dvz * nz


@njit(cache=True)
def restitution(mi, mf, pf, n_man, bm, bI, bv, bw, pv, pw, h, threshold, n_iter, dx,
                linear_momentum, angular_momentum):
    """Store the solve's impulses for warm starting, estimate end-of-step gaps, then bounce.

    A point bounces when its solve impulse is positive (it was hit), the gap was closing at the
    start of the step, and its impact speed u exceeds ``threshold``. Returns the number of
    impact points.

    Bounces come after the positions moved (dx: (N+1, 3) each body's displacement this step).
    Between two bodies the impulse is applied at one point that moved with them, the midpoint
    p + (dx_a + dx_b)/2, so that both anchors end at the same point: otherwise the pair's angular
    momentum would change by h (v_a - v_b) x J. The bounce impulses go straight into the momenta
    (P += J, L += r x J), since the orientations have already moved on."""
    n_impacts = 0
    for m in range(n_man):
        if not mi[m, MI_ACTIVE]:
            continue
        ia = mi[m, MI_A]
        ib = mi[m, MI_B]
        nx, ny, nz = mf[m, MF_N], mf[m, MF_N + 1], mf[m, MF_N + 2]
        e = mf[m, MF_E]
        acc = mf[m, MF_ACC]
        start = mi[m, MI_START]
        for p in range(start, start + mi[m, MI_COUNT]):
            rax, ray, raz = pf[p, PF_RA], pf[p, PF_RA + 1], pf[p, PF_RA + 2]
            rbx, rby, rbz = pf[p, PF_RB], pf[p, PF_RB + 1], pf[p, PF_RB + 2]
            vn = _gap_rate(bv, bw, ia, ib, nx, ny, nz, rax, ray, raz, rbx, rby, rbz)
            pn = _gap_rate(pv, pw, ia, ib, nx, ny, nz, rax, ray, raz, rbx, rby, rbz)
            s0 = pf[p, PF_S]
            s1 = s0 + h * (vn + pn)
            pf[p, PF_SEND] = s1
            pf[p, PF_LWS] = pf[p, PF_LN]
            pf[p, PF_WT] = -1.0
            w0 = pf[p, PF_W0]
            if w0 >= 0.0 or pf[p, PF_LN] <= 0.0:
                continue
            # approach speed at contact from the flight's energy (see module docstring)
            u2 = w0 * w0 - 2.0 * acc * s0
            if u2 <= threshold * threshold:
                continue
            pf[p, PF_IMPACT] = 1.0
            n_impacts += 1
            if e <= 0.0:
                continue
            # rebound rate whose flight energy at the end-of-step gap s1 is e^2 times the impact's
            c = e * e * u2 + 2.0 * acc * s1
            if c > 0.0:
                pf[p, PF_WT] = math.sqrt(c)
            else:
                pf[p, PF_WT] = e * math.sqrt(u2)
    if n_impacts == 0:
        return 0
    # Gauss-Seidel on the bounce targets of the impact points only
    for _ in range(n_iter):
        for m in range(n_man):
            if not mi[m, MI_ACTIVE]:
                continue
            start = mi[m, MI_START]
            end = start + mi[m, MI_COUNT]
            any_target = False
            for p in range(start, end):
                if pf[p, PF_WT] >= 0.0:
                    any_target = True
            if not any_target:
                continue
            ia = mi[m, MI_A]
            ib = mi[m, MI_B]
            ma = bm[ia]
            mb = bm[ib]
            nx, ny, nz = mf[m, MF_N], mf[m, MF_N + 1], mf[m, MF_N + 2]
            shared = ma > 0.0 and mb > 0.0
            hx = 0.5 * (dx[ib, 0] - dx[ia, 0])
            hy = 0.5 * (dx[ib, 1] - dx[ia, 1])
            hz = 0.5 * (dx[ib, 2] - dx[ia, 2])
            for p in range(start, end):
                wt = pf[p, PF_WT]
                if wt < 0.0:
                    continue
                rax, ray, raz = pf[p, PF_RA], pf[p, PF_RA + 1], pf[p, PF_RA + 2]
                rbx, rby, rbz = pf[p, PF_RB], pf[p, PF_RB + 1], pf[p, PF_RB + 2]
                if shared:
                    rax, ray, raz = rax + hx, ray + hy, raz + hz
                    rbx, rby, rbz = rbx - hx, rby - hy, rbz - hz
                vn = _gap_rate(bv, bw, ia, ib, nx, ny, nz, rax, ray, raz, rbx, rby, rbz)
                old = pf[p, PF_LN]
                new = old + pf[p, PF_NMASS] * (wt - vn)
                if new < 0.0:
                    new = 0.0
                pf[p, PF_LN] = new
                d = new - old
                _apply_pair_impulse(bv, bw, linear_momentum, angular_momentum, bm, bI, ia, ib,
                                    rax, ray, raz, rbx, rby, rbz, d * nx, d * ny, d * nz)
    _reclamp_friction(mi, mf, pf, n_man, bm, bI, bv, bw, dx, linear_momentum, angular_momentum)
    return n_impacts


@njit(cache=True)
def _apply_pair_impulse(bv, bw, linear_momentum, angular_momentum, bm, bI, ia, ib,
                        rax, ray, raz, rbx, rby, rbz, px, py, pz):
    """Impulse (px, py, pz) on a at anchor r_a and its negative on b at r_b: into the solver
    velocities (bv, bw) and straight into the momenta of dynamic bodies (P += J, L += r x J)."""
    n_dyn = linear_momentum.shape[0]
    va, wa, vb, wb = apply_impulse(
        bm[ia], (bI[ia, 0], bI[ia, 1], bI[ia, 2], bI[ia, 3], bI[ia, 4], bI[ia, 5]),
        bm[ib], (bI[ib, 0], bI[ib, 1], bI[ib, 2], bI[ib, 3], bI[ib, 4], bI[ib, 5]),
        (rax, ray, raz), (rbx, rby, rbz), (px, py, pz),
        (bv[ia, 0], bv[ia, 1], bv[ia, 2]), (bw[ia, 0], bw[ia, 1], bw[ia, 2]),
        (bv[ib, 0], bv[ib, 1], bv[ib, 2]), (bw[ib, 0], bw[ib, 1], bw[ib, 2]))
    bv[ia, 0], bv[ia, 1], bv[ia, 2] = va
    bw[ia, 0], bw[ia, 1], bw[ia, 2] = wa
    bv[ib, 0], bv[ib, 1], bv[ib, 2] = vb
    bw[ib, 0], bw[ib, 1], bw[ib, 2] = wb
    # angular impulses r x J straight into L (the orientations have already moved on)
    for body, sign, rx, ry, rz in ((ia, 1.0, rax, ray, raz), (ib, -1.0, rbx, rby, rbz)):
        if body < n_dyn:
            cx, cy, cz = _cross(rx, ry, rz, px, py, pz)
            linear_momentum[body, 0] += sign * px
            linear_momentum[body, 1] += sign * py
            linear_momentum[body, 2] += sign * pz
            angular_momentum[body, 0] += sign * cx
            angular_momentum[body, 1] += sign * cy
            angular_momentum[body, 2] += sign * cz


@njit(cache=True)
def _reclamp_friction(mi, mf, pf, n_man, bm, bI, bv, bw, dx, linear_momentum, angular_momentum):
    """Keep the friction impulse of every bouncing point inside the Coulomb cone.

    The bounce pass may lower a point's accumulated normal impulse (down to 0) after friction
    was solved against the higher one; the friction impulse is then scaled back onto the cone
    |lambda_t| <= mu lambda_n and the difference applied, at the same shared anchors as the
    bounce, so that the pair's momenta stay exactly balanced."""
    for m in range(n_man):
        if not mi[m, MI_ACTIVE]:
            continue
        mu = mf[m, MF_MU]
        ia = mi[m, MI_A]
        ib = mi[m, MI_B]
        ma = bm[ia]
        mb = bm[ib]
        shared = ma > 0.0 and mb > 0.0
        hx = 0.5 * (dx[ib, 0] - dx[ia, 0])
        hy = 0.5 * (dx[ib, 1] - dx[ia, 1])
        hz = 0.5 * (dx[ib, 2] - dx[ia, 2])
        t1x, t1y, t1z = mf[m, MF_T1], mf[m, MF_T1 + 1], mf[m, MF_T1 + 2]
        t2x, t2y, t2z = mf[m, MF_T2], mf[m, MF_T2 + 1], mf[m, MF_T2 + 2]
        start = mi[m, MI_START]
        for p in range(start, start + mi[m, MI_COUNT]):
            if pf[p, PF_WT] < 0.0:
                continue
            l1, l2 = pf[p, PF_L1], pf[p, PF_L2]
            nl = math.sqrt(l1 * l1 + l2 * l2)
            fmax = mu * pf[p, PF_LN]
            if nl <= fmax:
                continue
            scale = fmax / nl
            d1, d2 = l1 * scale - l1, l2 * scale - l2
            pf[p, PF_L1] = l1 * scale
            pf[p, PF_L2] = l2 * scale
            px = d1 * t1x + d2 * t2x
            py = d1 * t1y + d2 * t2y
            pz = d1 * t1z + d2 * t2z
            rax, ray, raz = pf[p, PF_RA], pf[p, PF_RA + 1], pf[p, PF_RA + 2]
            rbx, rby, rbz = pf[p, PF_RB], pf[p, PF_RB + 1], pf[p, PF_RB + 2]
            if shared:
                rax, ray, raz = rax + hx, ray + hy, raz + hz
                rbx, rby, rbz = rbx - hx, rby - hy, rbz - hz
            _apply_pair_impulse(bv, bw, linear_momentum, angular_momentum, bm, bI, ia, ib,
                                rax, ray, raz, rbx, rby, rbz, px, py, pz)
