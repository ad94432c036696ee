"""Stage 8 of the contact step: split-impulse position correction (relax).

Position correction by split impulses (Catto 2006; Bullet's split impulse): a second Gauss-Seidel
pass on *pseudo velocities* (v', w') pushes penetrating points apart with target
``vn' = min(beta * (-(s + slop)) / h, max_speed)``; positions move by h (v + v') and the pseudo
velocities are then discarded. Real momenta never see the correction, so it injects neither
momentum nor kinetic energy (the pseudo impulses are also equal and opposite, so the pair's
centre of mass does not move either).
"""

from __future__ import annotations

from numba import njit

from rblog.engine.contact.manifold import MF_N, MI_A, MI_ACTIVE, MI_B, MI_COUNT, MI_START, PF_LP, PF_NMASS, PF_RA, PF_RB, PF_S
from rblog.engine.contact.solver import apply_impulse


@njit(cache=True)
def relax_positions(mi, mf, pf, n_man, bm, bI, pv, pw, inv_h, n_iter, slop, beta, max_speed):
    """Split impulses: Gauss-Seidel on pseudo velocities that remove penetration beyond slop."""
    for _ in range(n_iter):
        for m in range(n_man):
            if not mi[m, MI_ACTIVE]:
                continue
            ia = mi[m, MI_A]
            ib = mi[m, MI_B]
            start = mi[m, MI_START]
            end = start + mi[m, MI_COUNT]
            deep = False
            for p in range(start, end):
                if pf[p, PF_S] <= 0.0:
                    deep = True
            if not deep:
                continue
            ma = bm[ia]
            mb = bm[ib]
            a0, a1, a2, a3, a4, a5 = bI[ia, 0], bI[ia, 1], bI[ia, 2], bI[ia, 3], bI[ia, 4], bI[ia, 5]
            b0, b1, b2, b3, b4, b5 = bI[ib, 0], bI[ib, 1], bI[ib, 2], bI[ib, 3], bI[ib, 4], bI[ib, 5]
            nx, ny, nz = mf[m, MF_N], mf[m, MF_N + 1], mf[m, MF_N + 2]
            vax, vay, vaz = pv[ia, 0], pv[ia, 1], pv[ia, 2]
            wax, way, waz = pw[ia, 0], pw[ia, 1], pw[ia, 2]
            vbx, vby, vbz = pv[ib, 0], pv[ib, 1], pv[ib, 2]
            wbx, wby, wbz = pw[ib, 0], pw[ib, 1], pw[ib, 2]
            for p in range(start, end):
                s = pf[p, PF_S]
                if s > 0.0:
                    continue
                rax, ray, raz = pf[p, PF_RA], pf[p, PF_RA + 1], pf[p, PF_RA + 2]
                rbx, rby, rbz = pf[p, PF_RB], pf[p, PF_RB + 1], pf[p, PF_RB + 2]
                dvx = vax + way * raz - waz * ray - vbx - wby * rbz + wbz * rby
                dvy = vay + waz * rax - wax * raz - vby - wbz * rbx + wbx * rbz
                dvz = vaz + wax * ray - way * rax - vbz - wbx * rby + wby * rbx
                vn = dvx * nx + dvy * ny + dvz * nz
                target = -(s + slop) * beta * inv_h
                if target < 0.0:
                    target = 0.0
                elif target > max_speed:
                    target = max_speed
                old = pf[p, PF_LP]
                new = old + pf[p, PF_NMASS] * (target - vn)
                if new < 0.0:
                    new = 0.0
                pf[p, PF_LP] = new
                d = new - old
                px, py, pz = d * nx, d * ny, d * nz
                (vax, vay, vaz), (wax, way, waz), (vbx, vby, vbz), (wbx, wby, wbz) = apply_impulse(
                    ma, (a0, a1, a2, a3, a4, a5), mb, (b0, b1, b2, b3, b4, b5), (rax, ray, raz),
                    (rbx, rby, rbz), (px, py, pz), (vax, vay, vaz), (wax, way, waz), (vbx, vby, vbz),
                    (wbx, wby, wbz))
            pv[ia, 0], pv[ia, 1], pv[ia, 2] = vax, vay, vaz
            pw[ia, 0], pw[ia, 1], pw[ia, 2] = wax, way, waz
            pv[ib, 0], pv[ib, 1], pv[ib, 2] = vbx, vby, vbz
            pw[ib, 0], pw[ib, 1], pw[ib, 2] = wbx, wby, wbz
