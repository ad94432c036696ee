"""Contact solver: sequential impulses (projected Gauss-Seidel) with accumulated-impulse clamping.

Stages, in the order the world step calls them (Box2D v3's ``b2SolverStage``):
``load_bodies`` -> ``prepare_contacts`` -> ``warm_start`` -> ``solve_velocities`` ->
``anchor_friction`` (with ContactParams.static_friction_anchors) -> ``relax_positions`` (split impulses) -> [integrate positions, in step.py] -> ``restitution``
-> [project: fresh narrowphase and nonlinear position pass, in project.py].

Derivations
-----------
Velocity of the gap at a point with anchors r_a, r_b (normal n from b into a)::

    vn = n . (v_a + w_a x r_a - v_b - w_b x r_b)            (> 0: separating)

An impulse P at the point changes it through the effective mass
``K = (m_a^-1 + m_b^-1) I - [r_a]x I_a^-1 [r_a]x - [r_b]x I_b^-1 [r_b]x`` (world inverse inertia
``I^-1 = R diag(1/I_body) R^T``). Each sweep visits every point: for the normal row it computes the
impulse increment that makes vn reach its target, adds it to the accumulated impulse, clamps the
accumulated impulse to >= 0, and applies the difference (Catto 2005). Friction uses the 2x2
tangent block of K; when the sticking impulse leaves the disc of radius mu * lambda_n (isotropic
Coulomb cone) the point slides and gets the maximum-dissipation impulse on the circle, so that
friction opposes the slip exactly (see _friction_impulse). Equal and opposite impulses at the same point conserve the pair's linear
momentum and its angular momentum about any point, to round-off.

Normal impulses are over-relaxed (projected SOR, ``ContactParams.over_relaxation``) on manifolds
whose bodies touch more than one thing, so that loads cross stacks and piles in fewer sweeps; see
solve_velocities.

Targets: a penetrating or touching point (s <= 0) wants vn >= 0; a speculative point (s > 0)
wants vn >= -s/h, i.e. the pair may close the gap within the step but not cross it. This is what
stops fast bodies tunnelling, and stops a falling body exactly on the surface.

Friction anchor (static friction at the position level, as PhysX's friction anchors, which it
breaks when the friction limit is exceeded; ContactParams.static_friction_anchors): a manifold
whose pair sticks keeps its anchor, the pose of body a in body b's frame when the pair started
sticking (``MF_AR``, ``MF_AT``; b's frame is the world for the ground). The collide stage
carries it over with the manifold (matched by pair key, so points that come and go, a one-point
contact that becomes a face, keep it) and gives every point its drift ``D``: where a's material
point at the contact is now, minus where the anchor pose puts it (collide.py). So D holds the
pair's slip and its twist since it stuck, whatever the points did, and counts every move of the
bodies (the solve's, the split-impulse and projection shifts). A sphere's pair has no anchor: a
rolling sphere brings a new material point to the contact every step, and a pose anchor would
pull the contact back against the roll (samples/mixed.toml's balls crept 5 mm). The friction rows of the anchor
pass (``anchor_friction``: one sweep after the solve, outside its convergence loop) then target
the slip rate ``vt = -FRICTION_ANCHOR_RATE D / h``, so a solve that stops before it converges
(residual slip e) cannot add up a drift: D settles at h e / rate and the slip velocity at zero.
The bias lives in the friction rows only, which stay clamped to the Coulomb disc. A manifold
drops its anchor (store_impulses: re-anchored where the pair then is) when a point was struck
or none of its loaded points sticks (friction strictly inside the cone), and collide re-anchors
a pair that drifted beyond FRICTION_ANCHOR_MAX_DRIFT_M. Friction impulses are equal and
opposite, so the anchor changes no momentum. What the pass does not do: it is not followed by
the normal rows (a pointwise normal sweep after it was measured to make the pile creep more,
benchmarks/RESULTS.md), and a box resting on two single-point contacts can still turn about
the line through them (no friction row sees that motion).

Position correction by split impulses (stage 8) is in :mod:`rblog.engine.contact.relax`.

Restitution (the bounce after positions moved) is in :mod:`rblog.engine.contact.restitution`.

Why this module is long: the prepare, warm-start and velocity-solve stages share the derivation above and the packed
arrays' conventions; their inner loops are written out over scalars (a manifold's two bodies'
velocities stay in registers across its points), which costs lines, not ideas.
"""

from __future__ import annotations

import math

from numba import njit

from rblog.engine.constants import (
    BLOCK_REG, FRICTION_ANCHOR_RATE, FRICTION_ANCHOR_SLIDE_FRAC,
    FRICTION_NEWTON_ITERS, FRICTION_NEWTON_TOL,
)
from rblog.engine.contact.manifold import (
    MF_ACC, MF_LU, MF_LUOK, MF_MU, MF_N, MF_PIV, MF_T1, MF_T2, MI_A, MI_ACTIVE, MI_B, MI_COUNT, MI_START, PF_F,
    PF_IMPACT, PF_L1, PF_L2, PF_LN, PF_LP, PF_NMASS, PF_RA, PF_RB, PF_S, PF_TK,
    PF_W0, PF_KN, PF_D, PF_DB, MF_AOK,
)


@njit(cache=True)
def _smul(i0, i1, i2, i3, i4, i5, x, y, z):
    """Symmetric 3x3 (xx, yy, zz, xy, xz, yz) times a vector."""
    return (i0 * x + i3 * y + i4 * z, i3 * x + i1 * y + i5 * z, i4 * x + i5 * y + i2 * z)


@njit(cache=True)
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(inline="always")
def apply_impulse(ma, a6, mb, b6, ra, rb, p, va, wa, vb, wb):
    """The one place an impulse acts on a pair: +P on body a at anchor r_a, -P on body b at r_b.

    Velocity changes m^-1 P and I_world^-1 (r x P), so the pair's linear momentum and its angular
    momentum about any point are unchanged to round-off. ``ma``/``mb`` inverse masses (0 for the
    static dummy), ``a6``/``b6`` world inverse inertias (xx, yy, zz, xy, xz, yz), ``ra``/``rb``
    anchors and ``p`` the impulse (world, N s), ``va, wa, vb, wb`` the bodies' velocity and angular
    velocity (world) as 3-tuples; returns them updated. Inlined: callers keep them in registers."""
    px, py, pz = p
    cx, cy, cz = _cross(ra[0], ra[1], ra[2], px, py, pz)
    ex, ey, ez = _smul(a6[0], a6[1], a6[2], a6[3], a6[4], a6[5], cx, cy, cz)
    va = (va[0] + ma * px, va[1] + ma * py, va[2] + ma * pz)
    wa = (wa[0] + ex, wa[1] + ey, wa[2] + ez)
    cx, cy, cz = _cross(rb[0], rb[1], rb[2], px, py, pz)
    ex, ey, ez = _smul(b6[0], b6[1], b6[2], b6[3], b6[4], b6[5], cx, cy, cz)
    vb = (vb[0] - mb * px, vb[1] - mb * py, vb[2] - mb * pz)
    wb = (wb[0] - ex, wb[1] - ey, wb[2] - ez)
    return va, wa, vb, wb


@njit(cache=True)
def load_bodies(mi, n_man, n_dyn, iso_shortcut, iso, inv_mass, inv_inertia, rotation,
                linear_momentum, angular_momentum, in_contact, bm, bI, bv, bw, bv0, bw0, pv, pw,
                p0, l0):
    """Count the active manifolds of each body (``in_contact``: (N+1,), row N the static
    dummy) and load the solver state of the bodies that have any.

    bm: (N+1,) inverse mass, bI: (N+1, 6) world inverse inertia (xx, yy, zz, xy, xz, yz), bv/bw:
    (N+1, 3) velocity and angular velocity (world), bv0/bw0 their values before the solve, pv/pw
    pseudo velocities, p0/l0 momenta before the solve. Row N is the static dummy (all zero)."""
    for i in range(n_dyn + 1):
        in_contact[i] = 0
    for m in range(n_man):
        if mi[m, MI_ACTIVE]:
            in_contact[mi[m, MI_A]] += 1
            in_contact[mi[m, MI_B]] += 1
    for i in range(n_dyn):
        if not in_contact[i]:
            continue
        im = inv_mass[i]
        bm[i] = im
        if iso_shortcut and iso[i]:
            # isotropic inertia: I^-1 is a scalar in every frame, no transform needed
            s = inv_inertia[i, 0]
            bI[i, 0], bI[i, 1], bI[i, 2] = s, s, s
            bI[i, 3], bI[i, 4], bI[i, 5] = 0.0, 0.0, 0.0
        else:
            r = rotation[i]
            d0, d1, d2 = inv_inertia[i, 0], inv_inertia[i, 1], inv_inertia[i, 2]
            # R diag(d) R^T
            bI[i, 0] = d0 * r[0, 0] * r[0, 0] + d1 * r[0, 1] * r[0, 1] + d2 * r[0, 2] * r[0, 2]
            bI[i, 1] = d0 * r[1, 0] * r[1, 0] + d1 * r[1, 1] * r[1, 1] + d2 * r[1, 2] * r[1, 2]
            bI[i, 2] = d0 * r[2, 0] * r[2, 0] + d1 * r[2, 1] * r[2, 1] + d2 * r[2, 2] * r[2, 2]
            bI[i, 3] = d0 * r[0, 0] * r[1, 0] + d1 * r[0, 1] * r[1, 1] + d2 * r[0, 2] * r[1, 2]
            bI[i, 4] = d0 * r[0, 0] * r[2, 0] + d1 * r[0, 1] * r[2, 1] + d2 * r[0, 2] * r[2, 2]
            bI[i, 5] = d0 * r[1, 0] * r[2, 0] + d1 * r[1, 1] * r[2, 1] + d2 * r[1, 2] * r[2, 2]
        for k in range(3):
            p0[i, k] = linear_momentum[i, k]
            l0[i, k] = angular_momentum[i, k]
            bv[i, k] = linear_momentum[i, k] * im
            bv0[i, k] = bv[i, k]
            pv[i, k] = 0.0
            pw[i, k] = 0.0
        wx, wy, wz = _smul(bI[i, 0], bI[i, 1], bI[i, 2], bI[i, 3], bI[i, 4], bI[i, 5],
                           l0[i, 0], l0[i, 1], l0[i, 2])
        bw[i, 0], bw[i, 1], bw[i, 2] = wx, wy, wz
        bw0[i, 0], bw0[i, 1], bw0[i, 2] = wx, wy, wz
    # the static dummy: reset every step so that a bad value can never stick to it
    s = n_dyn
    bm[s] = 0.0
    for k in range(3):
        bv[s, k] = 0.0
        bw[s, k] = 0.0
        bv0[s, k] = 0.0
        bw0[s, k] = 0.0
        pv[s, k] = 0.0
        pw[s, k] = 0.0
    for k in range(6):
        bI[s, k] = 0.0


@njit(cache=True)
def prepare_contacts(mi, mf, pf, n_man, bm, bI, bv, bw, h):
    """Effective masses, and the gap velocity before the step (for restitution)."""
    for m in range(n_man):
        if not mi[m, MI_ACTIVE]:
            continue
        ia = mi[m, MI_A]
        ib = mi[m, MI_B]
        ma = bm[ia]
        mb = bm[ib]
        a0, a1, a2, a3, a4, a5 = bI[ia, 0], bI[ia, 1], bI[ia, 2], bI[ia, 3], bI[ia, 4], bI[ia, 5]
        b0, b1, b2, b3, b4, b5 = bI[ib, 0], bI[ib, 1], bI[ib, 2], bI[ib, 3], bI[ib, 4], bI[ib, 5]
        nx, ny, nz = mf[m, MF_N], mf[m, MF_N + 1], mf[m, MF_N + 2]
        t1x, t1y, t1z = mf[m, MF_T1], mf[m, MF_T1 + 1], mf[m, MF_T1 + 2]
        t2x, t2y, t2z = mf[m, MF_T2], mf[m, MF_T2 + 1], mf[m, MF_T2 + 2]
        acc = mf[m, MF_ACC]
        vax, vay, vaz = bv[ia, 0], bv[ia, 1], bv[ia, 2]
        wax, way, waz = bw[ia, 0], bw[ia, 1], bw[ia, 2]
        vbx, vby, vbz = bv[ib, 0], bv[ib, 1], bv[ib, 2]
        wbx, wby, wbz = bw[ib, 0], bw[ib, 1], bw[ib, 2]
        start = mi[m, MI_START]
        cnt = mi[m, MI_COUNT]
        # normal block K_ij = J_i M^-1 J_j^T of the manifold's points
        for p in range(start, start + cnt):
            cax, cay, caz = _cross(pf[p, PF_RA], pf[p, PF_RA + 1], pf[p, PF_RA + 2], nx, ny, nz)
            cbx, cby, cbz = _cross(pf[p, PF_RB], pf[p, PF_RB + 1], pf[p, PF_RB + 2], nx, ny, nz)
            ix, iy, iz = _smul(a0, a1, a2, a3, a4, a5, cax, cay, caz)
            jx, jy, jz = _smul(b0, b1, b2, b3, b4, b5, cbx, cby, cbz)
            for q in range(start, start + cnt):
                dax, day, daz = _cross(pf[q, PF_RA], pf[q, PF_RA + 1], pf[q, PF_RA + 2], nx, ny, nz)
                dbx, dby, dbz = _cross(pf[q, PF_RB], pf[q, PF_RB + 1], pf[q, PF_RB + 2], nx, ny, nz)
                pf[p, PF_KN + q - start] = (ma + mb + dax * ix + day * iy + daz * iz
                                            + dbx * jx + dby * jy + dbz * jz)
        if cnt > 1:
            _factor_block(mf, m, pf, start, cnt)
        for p in range(start, start + cnt):
            rax, ray, raz = pf[p, PF_RA], pf[p, PF_RA + 1], pf[p, PF_RA + 2]
            rbx, rby, rbz = pf[p, PF_RB], pf[p, PF_RB + 1], pf[p, PF_RB + 2]
            # normal row
            cax, cay, caz = _cross(rax, ray, raz, nx, ny, nz)
            cbx, cby, cbz = _cross(rbx, rby, rbz, nx, ny, nz)
            ix, iy, iz = _smul(a0, a1, a2, a3, a4, a5, cax, cay, caz)
            jx, jy, jz = _smul(b0, b1, b2, b3, b4, b5, cbx, cby, cbz)
            k = ma + mb + cax * ix + cay * iy + caz * iz + cbx * jx + cby * jy + cbz * jz
            pf[p, PF_NMASS] = 1.0 / k if k > 0.0 else 0.0
            # tangent block
            ua1x, ua1y, ua1z = _cross(rax, ray, raz, t1x, t1y, t1z)
            ua2x, ua2y, ua2z = _cross(rax, ray, raz, t2x, t2y, t2z)
            ub1x, ub1y, ub1z = _cross(rbx, rby, rbz, t1x, t1y, t1z)
            ub2x, ub2y, ub2z = _cross(rbx, rby, rbz, t2x, t2y, t2z)
            ia1x, ia1y, ia1z = _smul(a0, a1, a2, a3, a4, a5, ua1x, ua1y, ua1z)
            ia2x, ia2y, ia2z = _smul(a0, a1, a2, a3, a4, a5, ua2x, ua2y, ua2z)
            ib1x, ib1y, ib1z = _smul(b0, b1, b2, b3, b4, b5, ub1x, ub1y, ub1z)
            ib2x, ib2y, ib2z = _smul(b0, b1, b2, b3, b4, b5, ub2x, ub2y, ub2z)
            k11 = ma + mb + ua1x * ia1x + ua1y * ia1y + ua1z * ia1z + ub1x * ib1x + ub1y * ib1y + ub1z * ib1z
            k22 = ma + mb + ua2x * ia2x + ua2y * ia2y + ua2z * ia2z + ub2x * ib2x + ub2y * ib2y + ub2z * ib2z
            k12 = ua1x * ia2x + ua1y * ia2y + ua1z * ia2z + ub1x * ib2x + ub1y * ib2y + ub1z * ib2z
            pf[p, PF_TK], pf[p, PF_TK + 1], pf[p, PF_TK + 2] = k11, k12, k22
            # friction anchor: the slip rate that takes back FRICTION_ANCHOR_RATE of the drift
            dx, dy, dz = pf[p, PF_D], pf[p, PF_D + 1], pf[p, PF_D + 2]
            pf[p, PF_DB] = FRICTION_ANCHOR_RATE * (dx * t1x + dy * t1y + dz * t1z) / h
            pf[p, PF_DB + 1] = FRICTION_ANCHOR_RATE * (dx * t2x + dy * t2y + dz * t2z) / h
            # gap velocity now (after the force kick), and before the kick
            wxrax, wxray, wxraz = _cross(wax, way, waz, rax, ray, raz)
            wxrbx, wxrby, wxrbz = _cross(wbx, wby, wbz, rbx, rby, rbz)
            vn = (nx * (vax + wxrax - vbx - wxrbx) + ny * (vay + wxray - vby - wxrby)
                  + nz * (vaz + wxraz - vbz - wxrbz))
            pf[p, PF_W0] = vn - acc * h
            pf[p, PF_LP] = 0.0
            pf[p, PF_IMPACT] = 0.0


@njit(cache=True)
def warm_start(mi, mf, pf, n_man, bm, bI, bv, bw):
    """Apply the impulses carried over from the previous step."""
    for m in range(n_man):
        if not mi[m, MI_ACTIVE]:
            continue
        ia = mi[m, MI_A]
        ib = mi[m, MI_B]
        ma = bm[ia]
        mb = bm[ib]
        a0, a1, a2, a3, a4, a5 = bI[ia, 0], bI[ia, 1], bI[ia, 2], bI[ia, 3], bI[ia, 4], bI[ia, 5]
        b0, b1, b2, b3, b4, b5 = bI[ib, 0], bI[ib, 1], bI[ib, 2], bI[ib, 3], bI[ib, 4], bI[ib, 5]
        nx, ny, nz = mf[m, MF_N], mf[m, MF_N + 1], mf[m, MF_N + 2]
        t1x, t1y, t1z = mf[m, MF_T1], mf[m, MF_T1 + 1], mf[m, MF_T1 + 2]
        t2x, t2y, t2z = mf[m, MF_T2], mf[m, MF_T2 + 1], mf[m, MF_T2 + 2]
        vax, vay, vaz = bv[ia, 0], bv[ia, 1], bv[ia, 2]
        wax, way, waz = bw[ia, 0], bw[ia, 1], bw[ia, 2]
        vbx, vby, vbz = bv[ib, 0], bv[ib, 1], bv[ib, 2]
        wbx, wby, wbz = bw[ib, 0], bw[ib, 1], bw[ib, 2]
        start = mi[m, MI_START]
        for p in range(start, start + mi[m, MI_COUNT]):
            ln, l1, l2 = pf[p, PF_LN], pf[p, PF_L1], pf[p, PF_L2]
            if ln == 0.0 and l1 == 0.0 and l2 == 0.0:
                continue
            px = ln * nx + l1 * t1x + l2 * t2x
            py = ln * ny + l1 * t1y + l2 * t2y
            pz = ln * nz + l1 * t1z + l2 * t2z
            rax, ray, raz = pf[p, PF_RA], pf[p, PF_RA + 1], pf[p, PF_RA + 2]
            rbx, rby, rbz = pf[p, PF_RB], pf[p, PF_RB + 1], pf[p, PF_RB + 2]
            (vax, vay, vaz), (wax, way, waz), (vbx, vby, vbz), (wbx, wby, wbz) = apply_impulse(
                ma, (a0, a1, a2, a3, a4, a5), mb, (b0, b1, b2, b3, b4, b5), (rax, ray, raz),
                (rbx, rby, rbz), (px, py, pz), (vax, vay, vaz), (wax, way, waz), (vbx, vby, vbz),
                (wbx, wby, wbz))
        bv[ia, 0], bv[ia, 1], bv[ia, 2] = vax, vay, vaz
        bw[ia, 0], bw[ia, 1], bw[ia, 2] = wax, way, waz
        bv[ib, 0], bv[ib, 1], bv[ib, 2] = vbx, vby, vbz
        bw[ib, 0], bw[ib, 1], bw[ib, 2] = wbx, wby, wbz


@njit(cache=True)
def _friction_impulse(k11, k12, k22, o1, o2, vt1, vt2, fmax):
    """Accumulated friction impulse (t1, t2) after one Gauss-Seidel update of a point.

    Sticking: the impulse that zeroes the slip, lambda = o - K^-1 vt. When that leaves the
    Coulomb disc |lambda| <= fmax, the point slides and the impulse is the *maximum-dissipation*
    one: the minimiser of the kinetic energy 1/2 (lambda - c)^T K (lambda - c) on the circle
    |lambda| = fmax, lambda = (K + g I)^-1 K c with g >= 0 found by Newton on
    1/|lambda(g)| = 1/fmax (More-Sorensen's secular equation). The slip after the impulse is
    then -g lambda: friction opposes the sliding velocity exactly, which a radial projection of
    the unconstrained impulse does not do when K couples the two tangents (off-centre points).
    """
    det0 = k11 * k22 - k12 * k12
    if det0 <= 0.0 or fmax <= 0.0:
        return 0.0, 0.0
    # K c = K o - vt  (c: the sticking impulse)
    kc1 = k11 * o1 + k12 * o2 - vt1
    kc2 = k12 * o1 + k22 * o2 - vt2
    g = 0.0
    l1 = (k22 * kc1 - k12 * kc2) / det0
    l2 = (k11 * kc2 - k12 * kc1) / det0
    nl = math.sqrt(l1 * l1 + l2 * l2)
    if nl <= fmax:
        return l1, l2
    for _ in range(FRICTION_NEWTON_ITERS):
        a = k11 + g
        d = k22 + g
        det = a * d - k12 * k12
        l1 = (d * kc1 - k12 * kc2) / det
        l2 = (a * kc2 - k12 * kc1) / det
        nl = math.sqrt(l1 * l1 + l2 * l2)
        if nl <= fmax * (1.0 + FRICTION_NEWTON_TOL):
            break
        m1 = (d * l1 - k12 * l2) / det
        m2 = (a * l2 - k12 * l1) / det
        # f(g) = 1/fmax - 1/|l|,  f'(g) = -(l . (K + g I)^-1 l) / |l|^3
        f = 1.0 / fmax - 1.0 / nl
        fp = -(l1 * m1 + l2 * m2) / (nl * nl * nl)
        g -= f / fp
    sc = fmax / nl
    return l1 * sc, l2 * sc


@njit(cache=True)
def _factor_block(mf, m, pf, start, n):
    """LU-factor manifold m's regularised normal block (K + BLOCK_REG diag(K), n x n, from the
    points' PF_KN rows) into mf[m, MF_LU:] (U on and above the diagonal, the elimination
    multipliers below it, each left where it was computed), the pivot rows into mf[m, MF_PIV:]
    and mf[m, MF_LUOK] = 1.0 if no pivot vanished. The block depends on the geometry and masses
    only, so it is factored once per step here instead of once per sweep; _lu_solve then makes
    exactly the floating-point operations of Gaussian elimination with partial pivoting on
    [K | rhs] (the same pivots, multipliers, order), so its results are bitwise those of an
    elimination per sweep."""
    base = MF_LU
    for i in range(n):
        p = start + i
        for j in range(n):
            mf[m, base + 4 * i + j] = pf[p, PF_KN + j]
        mf[m, base + 5 * i] += BLOCK_REG * pf[p, PF_KN + i]
    mf[m, MF_LUOK] = 0.0
    for c in range(n):
        piv = c
        for r in range(c + 1, n):
            if abs(mf[m, base + 4 * r + c]) > abs(mf[m, base + 4 * piv + c]):
                piv = r
        mf[m, MF_PIV + c] = piv
        if abs(mf[m, base + 4 * piv + c]) <= 0.0:
            return
        if piv != c:
            for k in range(c, n):
                t = mf[m, base + 4 * c + k]
                mf[m, base + 4 * c + k] = mf[m, base + 4 * piv + k]
                mf[m, base + 4 * piv + k] = t
        for r in range(c + 1, n):
            f = mf[m, base + 4 * r + c] / mf[m, base + 5 * c]
            for k in range(c + 1, n):
                mf[m, base + 4 * r + k] -= f * mf[m, base + 4 * c + k]
            mf[m, base + 4 * r + c] = f
    mf[m, MF_LUOK] = 1.0


@njit(inline="always")
def _lu_solve(mf, m, blk, n):
    """Solve the factored block of manifold m (see _factor_block) for the right-hand side in
    blk[:n, 4], in place."""
    base = MF_LU
    for c in range(n):
        piv = int(mf[m, MF_PIV + c])
        if piv != c:
            t = blk[c, 4]
            blk[c, 4] = blk[piv, 4]
            blk[piv, 4] = t
        for r in range(c + 1, n):
            blk[r, 4] -= mf[m, base + 4 * r + c] * blk[c, 4]
    for c in range(n - 1, -1, -1):
        x = blk[c, 4]
        for k in range(c + 1, n):
            x -= mf[m, base + 4 * c + k] * blk[k, 4]
        blk[c, 4] = x / mf[m, base + 5 * c]


@njit(cache=True)
def solve_velocities(mi, mf, pf, n_man, bm, bI, bv, bw, inv_h, min_iter, max_iter, tol, blk,
                     hot, degree, sor):
    """Sequential impulses: per manifold, the normal rows, then friction (Box2D v3 order).

    Sweeps at least ``min_iter`` times, then until the largest velocity change a sweep makes at
    any point is below ``tol`` (m/s), at most ``max_iter`` sweeps. Past ``min_iter`` a sweep
    visits only manifolds with a body that a previous sweep changed by more than ``tol``
    (``hot``: (N+1,) last sweep that did), so settled regions of a pile cost nothing while an
    unsettled one converges. Returns the number of manifold visits divided by the manifolds
    (full-sweep equivalents, at least 1).

    Successive over-relaxation (ODE's quickstep; projected SOR converges for 0 < sor < 2 on the
    normal rows, Cryer 1971): the normal impulse increment of a manifold is scaled by ``sor``
    before the clamp when one of its dynamic bodies touches something else (``degree``: (N+1,)
    active manifolds per body). Plain Gauss-Seidel moves a load through a chain of n bodies in
    ~n^2 sweeps, over-relaxed in ~n. A manifold whose bodies touch nothing else is solved
    exactly by one update, so it is not relaxed (that would only make it oscillate)."""
    it = 0
    visits = 0
    for k in range(hot.shape[0]):
        hot[k] = 0
    active = 0
    for m in range(n_man):
        active += mi[m, MI_ACTIVE]
    while it < max_iter:
        it += 1
        change = 0.0
        for m in range(n_man):
            if not mi[m, MI_ACTIVE]:
                continue
            ia = mi[m, MI_A]
            ib = mi[m, MI_B]
            if it > min_iter and hot[ia] < it - 1 and hot[ib] < it - 1:
                continue
            visits += 1
            mark_a = False
            ma = bm[ia]
            mb = bm[ib]
            om = 1.0
            if (ma > 0.0 and degree[ia] > 1) or (mb > 0.0 and degree[ib] > 1):
                om = sor
            a0, a1, a2, a3, a4, a5 = bI[ia, 0], bI[ia, 1], bI[ia, 2], bI[ia, 3], bI[ia, 4], bI[ia, 5]
            b0, b1, b2, b3, b4, b5 = bI[ib, 0], bI[ib, 1], bI[ib, 2], bI[ib, 3], bI[ib, 4], bI[ib, 5]
            nx, ny, nz = mf[m, MF_N], mf[m, MF_N + 1], mf[m, MF_N + 2]
            t1x, t1y, t1z = mf[m, MF_T1], mf[m, MF_T1 + 1], mf[m, MF_T1 + 2]
            t2x, t2y, t2z = mf[m, MF_T2], mf[m, MF_T2 + 1], mf[m, MF_T2 + 2]
            mu = mf[m, MF_MU]
            vax, vay, vaz = bv[ia, 0], bv[ia, 1], bv[ia, 2]
            wax, way, waz = bw[ia, 0], bw[ia, 1], bw[ia, 2]
            vbx, vby, vbz = bv[ib, 0], bv[ib, 1], bv[ib, 2]
            wbx, wby, wbz = bw[ib, 0], bw[ib, 1], bw[ib, 2]
            start = mi[m, MI_START]
            end = start + mi[m, MI_COUNT]
            # non-penetration: the manifold's points together (block), else one by one
            solved = False
            cnt = end - start
            if cnt > 1 and mf[m, MF_LUOK] > 0.0:
                for i in range(cnt):
                    p = start + i
                    rax, ray, raz = pf[p, PF_RA], pf[p, PF_RA + 1], pf[p, PF_RA + 2]
                    rbx, rby, rbz = pf[p, PF_RB], pf[p, PF_RB + 1], pf[p, PF_RB + 2]
                    dvx = vax + way * raz - waz * ray - vbx - wby * rbz + wbz * rby
                    dvy = vay + waz * rax - wax * raz - vby - wbz * rbx + wbx * rbz
                    dvz = vaz + wax * ray - way * rax - vbz - wbx * rby + wby * rbx
                    vn = dvx * nx + dvy * ny + dvz * nz
                    s = pf[p, PF_S]
                    target = -s * inv_h if s > 0.0 else 0.0
                    blk[i, 4] = target - vn
                _lu_solve(mf, m, blk, cnt)
                ok = True
                for i in range(cnt):
                    if pf[start + i, PF_LN] + om * blk[i, 4] < 0.0:
                        ok = False
                if ok:
                    solved = True
                    for i in range(cnt):
                        p = start + i
                        d = om * blk[i, 4]
                        pf[p, PF_LN] += d
                        if d != 0.0:
                            dv = abs(d) / pf[p, PF_NMASS]
                            if dv > change:
                                change = dv
                            if dv > tol:
                                mark_a = True
                        rax, ray, raz = pf[p, PF_RA], pf[p, PF_RA + 1], pf[p, PF_RA + 2]
                        rbx, rby, rbz = pf[p, PF_RB], pf[p, PF_RB + 1], pf[p, PF_RB + 2]
                        px, py, pz = d * nx, d * ny, d * nz
                        (vax, vay, vaz), (wax, way, waz), (vbx, vby, vbz), (wbx, wby, wbz) = apply_impulse(
                            ma, (a0, a1, a2, a3, a4, a5), mb, (b0, b1, b2, b3, b4, b5), (rax, ray, raz),
                            (rbx, rby, rbz), (px, py, pz), (vax, vay, vaz), (wax, way, waz), (vbx, vby, vbz),
                            (wbx, wby, wbz))
            for p in range(start, end):
                if solved:
                    break
                rax, ray, raz = pf[p, PF_RA], pf[p, PF_RA + 1], pf[p, PF_RA + 2]
                rbx, rby, rbz = pf[p, PF_RB], pf[p, PF_RB + 1], pf[p, PF_RB + 2]
                # relative normal velocity at the contact (a minus b)
                dvx = vax + way * raz - waz * ray - vbx - wby * rbz + wbz * rby
                dvy = vay + waz * rax - wax * raz - vby - wbz * rbx + wbx * rbz
                dvz = vaz + wax * ray - way * rax - vbz - wbx * rby + wby * rbx
                vn = dvx * nx + dvy * ny + dvz * nz
                s = pf[p, PF_S]
                # speculative: the gap may close within the step, not more
                target = -s * inv_h if s > 0.0 else 0.0
                # clamp the accumulated impulse
                old = pf[p, PF_LN]
                new = old + om * pf[p, PF_NMASS] * (target - vn)
                if new < 0.0:
                    new = 0.0
                pf[p, PF_LN] = new
                d = new - old
                if d != 0.0:
                    dv = abs(d) / pf[p, PF_NMASS]
                    if dv > change:
                        change = dv
                    if dv > tol:
                        mark_a = True
                px, py, pz = d * nx, d * ny, d * nz
                (vax, vay, vaz), (wax, way, waz), (vbx, vby, vbz), (wbx, wby, wbz) = apply_impulse(
                    ma, (a0, a1, a2, a3, a4, a5), mb, (b0, b1, b2, b3, b4, b5), (rax, ray, raz),
                    (rbx, rby, rbz), (px, py, pz), (vax, vay, vaz), (wax, way, waz), (vbx, vby, vbz),
                    (wbx, wby, wbz))
            # friction
            if mu > 0.0:
                for p in range(start, end):
                    rax, ray, raz = pf[p, PF_RA], pf[p, PF_RA + 1], pf[p, PF_RA + 2]
                    rbx, rby, rbz = pf[p, PF_RB], pf[p, PF_RB + 1], pf[p, PF_RB + 2]
                    dvx = vax + way * raz - waz * ray - vbx - wby * rbz + wbz * rby
                    dvy = vay + waz * rax - wax * raz - vby - wbz * rbx + wbx * rbz
                    dvz = vaz + wax * ray - way * rax - vbz - wbx * rby + wby * rbx
                    vt1 = dvx * t1x + dvy * t1y + dvz * t1z
                    vt2 = dvx * t2x + dvy * t2y + dvz * t2z
                    k11, k12, k22 = pf[p, PF_TK], pf[p, PF_TK + 1], pf[p, PF_TK + 2]
                    o1, o2 = pf[p, PF_L1], pf[p, PF_L2]
                    n1, n2 = _friction_impulse(k11, k12, k22, o1, o2, vt1, vt2,
                                               mu * pf[p, PF_LN])
                    pf[p, PF_L1] = n1
                    pf[p, PF_L2] = n2
                    d1 = n1 - o1
                    d2 = n2 - o2
                    dv = abs(d1) * k11 + abs(d2) * k22
                    if dv > change:
                        change = dv
                    if dv > tol:
                        mark_a = True
                    px = d1 * t1x + d2 * t2x
                    py = d1 * t1y + d2 * t2y
                    pz = d1 * t1z + d2 * t2z
                    (vax, vay, vaz), (wax, way, waz), (vbx, vby, vbz), (wbx, wby, wbz) = apply_impulse(
                        ma, (a0, a1, a2, a3, a4, a5), mb, (b0, b1, b2, b3, b4, b5), (rax, ray, raz),
                        (rbx, rby, rbz), (px, py, pz), (vax, vay, vaz), (wax, way, waz), (vbx, vby, vbz),
                        (wbx, wby, wbz))
            bv[ia, 0], bv[ia, 1], bv[ia, 2] = vax, vay, vaz
            bw[ia, 0], bw[ia, 1], bw[ia, 2] = wax, way, waz
            bv[ib, 0], bv[ib, 1], bv[ib, 2] = vbx, vby, vbz
            bw[ib, 0], bw[ib, 1], bw[ib, 2] = wbx, wby, wbz
            if mark_a:
                # the static dummy (zero inverse mass) never turns hot
                if ma > 0.0:
                    hot[ia] = it
                if mb > 0.0:
                    hot[ib] = it
        if it >= min_iter and change <= tol:
            break
    return max(1, (visits + active - 1) // max(active, 1))


@njit(cache=True)
def anchor_friction(mi, mf, pf, n_man, bm, bI, bv, bw):
    """The anchor pass (after the velocity solve, before relax): one Gauss-Seidel sweep of the
    friction rows of loaded points with the anchors' targets (slip rate -FRICTION_ANCHOR_RATE D
    / h, clamped to the Coulomb disc; see "Friction anchor" above). It runs once per step, outside the solve's
    convergence loop, so the bias never keeps the solve's sweeps going; the anchor closes the
    loop over steps (what one sweep leaves of the target is still in D next step)."""
    for m in range(n_man):
        if not mi[m, MI_ACTIVE]:
            continue
        mu = mf[m, MF_MU]
        if mu <= 0.0:
            continue
        start = mi[m, MI_START]
        end = start + mi[m, MI_COUNT]
        loaded = False
        for p in range(start, end):
            if pf[p, PF_LN] > 0.0:
                loaded = True
        if not loaded:
            continue
        ia = mi[m, MI_A]
        ib = mi[m, MI_B]
        ma = bm[ia]
        mb = bm[ib]
        a0, a1, a2, a3, a4, a5 = bI[ia, 0], bI[ia, 1], bI[ia, 2], bI[ia, 3], bI[ia, 4], bI[ia, 5]
        b0, b1, b2, b3, b4, b5 = bI[ib, 0], bI[ib, 1], bI[ib, 2], bI[ib, 3], bI[ib, 4], bI[ib, 5]
        nx, ny, nz = mf[m, MF_N], mf[m, MF_N + 1], mf[m, MF_N + 2]
        t1x, t1y, t1z = mf[m, MF_T1], mf[m, MF_T1 + 1], mf[m, MF_T1 + 2]
        t2x, t2y, t2z = mf[m, MF_T2], mf[m, MF_T2 + 1], mf[m, MF_T2 + 2]
        vax, vay, vaz = bv[ia, 0], bv[ia, 1], bv[ia, 2]
        wax, way, waz = bw[ia, 0], bw[ia, 1], bw[ia, 2]
        vbx, vby, vbz = bv[ib, 0], bv[ib, 1], bv[ib, 2]
        wbx, wby, wbz = bw[ib, 0], bw[ib, 1], bw[ib, 2]
        for p in range(start, end):
            if pf[p, PF_LN] <= 0.0:
                continue
            rax, ray, raz = pf[p, PF_RA], pf[p, PF_RA + 1], pf[p, PF_RA + 2]
            rbx, rby, rbz = pf[p, PF_RB], pf[p, PF_RB + 1], pf[p, PF_RB + 2]
            dvx = vax + way * raz - waz * ray - vbx - wby * rbz + wbz * rby
            dvy = vay + waz * rax - wax * raz - vby - wbz * rbx + wbx * rbz
            dvz = vaz + wax * ray - way * rax - vbz - wbx * rby + wby * rbx
            # slip relative to the anchor's target rate -D rate / h
            vt1 = dvx * t1x + dvy * t1y + dvz * t1z + pf[p, PF_DB]
            vt2 = dvx * t2x + dvy * t2y + dvz * t2z + pf[p, PF_DB + 1]
            k11, k12, k22 = pf[p, PF_TK], pf[p, PF_TK + 1], pf[p, PF_TK + 2]
            o1, o2 = pf[p, PF_L1], pf[p, PF_L2]
            n1, n2 = _friction_impulse(k11, k12, k22, o1, o2, vt1, vt2, mu * pf[p, PF_LN])
            pf[p, PF_L1] = n1
            pf[p, PF_L2] = n2
            d1 = n1 - o1
            d2 = n2 - o2
            px = d1 * t1x + d2 * t2x
            py = d1 * t1y + d2 * t2y
            pz = d1 * t1z + d2 * t2z
            (vax, vay, vaz), (wax, way, waz), (vbx, vby, vbz), (wbx, wby, wbz) = apply_impulse(
                ma, (a0, a1, a2, a3, a4, a5), mb, (b0, b1, b2, b3, b4, b5), (rax, ray, raz),
                (rbx, rby, rbz), (px, py, pz), (vax, vay, vaz), (wax, way, waz), (vbx, vby, vbz),
                (wbx, wby, wbz))
        bv[ia, 0], bv[ia, 1], bv[ia, 2] = vax, vay, vaz
        bw[ia, 0], bw[ia, 1], bw[ia, 2] = wax, way, waz
        bv[ib, 0], bv[ib, 1], bv[ib, 2] = vbx, vby, vbz
        bw[ib, 0], bw[ib, 1], bw[ib, 2] = wbx, wby, wbz


@njit(cache=True)
def store_impulses(mi, mf, pf, n_man):
    """Friction impulses as world vectors, so the next step can project them on its tangents;
    a manifold keeps its friction anchor while some loaded point sticks (friction strictly inside
    its cone; see "Friction anchor" above): an impact, or a manifold none of whose points
    sticks, drops it, and the next step's collide anchors the pair anew where it then is. (A
    point at its cone while others stick just gives what the cone allows; a pair that slides
    drifts beyond FRICTION_ANCHOR_MAX_DRIFT_M and collide re-anchors it.)"""
    for m in range(n_man):
        if not mi[m, MI_ACTIVE]:
            continue
        t1x, t1y, t1z = mf[m, MF_T1], mf[m, MF_T1 + 1], mf[m, MF_T1 + 2]
        t2x, t2y, t2z = mf[m, MF_T2], mf[m, MF_T2 + 1], mf[m, MF_T2 + 2]
        mu = mf[m, MF_MU]
        start = mi[m, MI_START]
        cnt = mi[m, MI_COUNT]
        stick = False
        struck = False
        for p in range(start, start + cnt):
            l1, l2 = pf[p, PF_L1], pf[p, PF_L2]
            pf[p, PF_F] = l1 * t1x + l2 * t2x
            pf[p, PF_F + 1] = l1 * t1y + l2 * t2y
            pf[p, PF_F + 2] = l1 * t1z + l2 * t2z
            fmax = mu * pf[p, PF_LN]
            if pf[p, PF_IMPACT] != 0.0:
                struck = True
            elif fmax > 0.0 and l1 * l1 + l2 * l2 < ((1.0 - FRICTION_ANCHOR_SLIDE_FRAC) * fmax) ** 2:
                stick = True
        if struck or not stick:
            mf[m, MF_AOK] = 0.0
