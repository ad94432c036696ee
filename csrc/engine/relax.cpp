// Stage 8 of the contact step: split-impulse position correction (relax).
//
// Position correction by split impulses (Catto 2006; Bullet's split impulse): a second Gauss-Seidel
// pass on *pseudo velocities* (v', w') pushes penetrating points apart with target
// ``vn' = min(beta * (-(s + slop)) / h, max_speed)``; positions move by h (v + v') and the pseudo
// velocities are then discarded. Real momenta never see the correction, so it injects neither
// momentum nor kinetic energy (the pseudo impulses are also equal and opposite, so the pair's
// centre of mass does not move either).

#include <vector>

#include "engine/contact_solver.hpp"
#include "engine/manifold.hpp"

namespace rb {

// Split impulses: Gauss-Seidel on pseudo velocities that remove penetration beyond slop.
//
// Three shortcuts that leave every bit as the plain sweeps make it:
//
// * the manifolds with a point at s <= 0 (the only ones a sweep touches; PF_S does not change
//   here) are listed once, not found again every sweep;
// * a point whose accumulated pseudo impulse did not change (d = 0: most points, whose target is
//   0 and which already separate) applies nothing. Applying d = 0 would add products that are +0
//   or -0 to the pseudo velocities, which leaves a value unchanged unless it is -0; and they are
//   never -0: load_bodies starts them at +0, and in round-to-nearest x + y or x - y is -0 only
//   when x is -0 already;
// * a manifold whose last visit applied nothing, and whose two bodies no visit has pushed since,
//   is not visited again: the visit would read the same velocities and accumulated impulses
//   (PF_LP: never -0 either, it starts at +0 and only takes sums and the clamp's +0), so it would
//   compute every nw bitwise as last time, equal to the old value, and write back what is there.
//   (`pushed`: for each body the count of applies when one last pushed it; `seen`: for each
//   listed manifold the count when its last visit ended.)
void relax_positions(V2<i64> mi, V2<double> mf, V2<double> pf, i64 n_man, V1<double> bm,
                     V2<double> bI, V2<double> pv, V2<double> pw, double inv_h, i64 n_iter,
                     double slop, double beta, double max_speed) {
    if (n_iter <= 0) return;
    static thread_local std::vector<i64> deep_kept;
    std::vector<i64>& deep = deep_kept;
    deep.clear();
    for (i64 m = 0; m < n_man; ++m) {
        if (!mi(m, MI_ACTIVE)) continue;
        const i64 start = mi(m, MI_START);
        const i64 end = start + mi(m, MI_COUNT);
        for (i64 p = start; p < end; ++p) {
            if (pf(p, PF_S) <= 0.0) {
                deep.push_back(m);
                break;
            }
        }
    }
    const i64 n_deep = (i64)deep.size();
    static thread_local std::vector<i64> pushed_kept, seen_kept;
    std::vector<i64>& pushed = pushed_kept;
    std::vector<i64>& seen = seen_kept;
    pushed.assign((size_t)bm.n0, 0);
    seen.assign((size_t)n_deep, -1);  // -1: visit (the first sweep, or the last visit applied)
    i64 applies = 0;
    for (i64 it = 0; it < n_iter; ++it) {
        for (i64 k = 0; k < n_deep; ++k) {
            const i64 m = deep[(size_t)k];
            i64 ia = mi(m, MI_A), ib = mi(m, MI_B);
            const i64 last = seen[(size_t)k];
            if (last >= 0 && pushed[(size_t)ia] <= last && pushed[(size_t)ib] <= last) continue;
            const i64 applies0 = applies;
            i64 start = mi(m, MI_START);
            i64 end = start + mi(m, MI_COUNT);
            double ma = bm[ia], mb = bm[ib];
            const double a6[6] = {bI(ia, 0), bI(ia, 1), bI(ia, 2), bI(ia, 3), bI(ia, 4), bI(ia, 5)};
            const double b6[6] = {bI(ib, 0), bI(ib, 1), bI(ib, 2), bI(ib, 3), bI(ib, 4), bI(ib, 5)};
            double nx = mf(m, MF_N), ny = mf(m, MF_N + 1), nz = mf(m, MF_N + 2);
            double vax = pv(ia, 0), vay = pv(ia, 1), vaz = pv(ia, 2);
            double wax = pw(ia, 0), way = pw(ia, 1), waz = pw(ia, 2);
            double vbx = pv(ib, 0), vby = pv(ib, 1), vbz = pv(ib, 2);
            double wbx = pw(ib, 0), wby = pw(ib, 1), wbz = pw(ib, 2);
            for (i64 p = start; p < end; ++p) {
                double* q = pf.row(p);
                double s = q[PF_S];
                if (s > 0.0) continue;
                double rax = q[PF_RA], ray = q[PF_RA + 1], raz = q[PF_RA + 2];
                double rbx = q[PF_RB], rby = q[PF_RB + 1], rbz = q[PF_RB + 2];
                double dvx = vax + way * raz - waz * ray - vbx - wby * rbz + wbz * rby;
                double dvy = vay + waz * rax - wax * raz - vby - wbz * rbx + wbx * rbz;
                double dvz = vaz + wax * ray - way * rax - vbz - wbx * rby + wby * rbx;
                double vn = dvx * nx + dvy * ny + dvz * nz;
                double target = -(s + slop) * beta * inv_h;
                if (target < 0.0) {
                    target = 0.0;
                } else if (target > max_speed) {
                    target = max_speed;
                }
                double old = q[PF_LP];
                double nw = old + q[PF_NMASS] * (target - vn);
                if (nw < 0.0) nw = 0.0;
                q[PF_LP] = nw;
                double d = nw - old;
                if (d == 0.0) continue;  // (see above: applying it would change no bit)
                apply_impulse(ma, a6, mb, b6, rax, ray, raz, rbx, rby, rbz, d * nx, d * ny,
                              d * nz, vax, vay, vaz, wax, way, waz, vbx, vby, vbz, wbx, wby, wbz);
                applies += 1;
                pushed[(size_t)ia] = applies;
                pushed[(size_t)ib] = applies;
            }
            seen[(size_t)k] = applies == applies0 ? applies : -1;
            pv(ia, 0) = vax; pv(ia, 1) = vay; pv(ia, 2) = vaz;
            pw(ia, 0) = wax; pw(ia, 1) = way; pw(ia, 2) = waz;
            pv(ib, 0) = vbx; pv(ib, 1) = vby; pv(ib, 2) = vbz;
            pw(ib, 0) = wbx; pw(ib, 1) = wby; pw(ib, 2) = wbz;
        }
    }
}

}  // namespace rb
