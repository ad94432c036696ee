// Stage 8 of the contact step: split-impulse position correction (relax).
//
// Position correction by split impulses (Catto 2006; Bullet's split impulse): a second Gauss-Seidel
// pass on *pseudo velocities* (v', w') pushes penetrating points apart with target
// ``vn' = min(position_correction_rate (-(s + allowed_penetration)) / h, max_correction_speed)``
// (ContactParams's names); positions move by h (v + v') and the pseudo
// velocities are then discarded. Real momenta never see the correction, so it injects neither
// momentum nor kinetic energy (the pseudo impulses are also equal and opposite, so the pair's
// centre of mass does not move either).

#include <vector>

#include "engine/contact_solver.hpp"
#include "engine/manifold.hpp"

namespace rb {

// Split impulses: Gauss-Seidel on pseudo velocities that remove penetration beyond
// allowed_penetration.
//
// Three shortcuts that leave every bit as the plain sweeps make it:
//
// * the manifolds with a point at s <= 0 (the only ones a sweep touches; s does not change
//   here) are listed once, not found again every sweep;
// * a point whose accumulated pseudo impulse did not change (d = 0: most points, whose target is
//   0 and which already separate) applies nothing. Applying d = 0 would add products that are +0
//   or -0 to the pseudo velocities, which leaves a value unchanged unless it is -0; and they are
//   never -0: load_bodies starts them at +0, and in round-to-nearest x + y or x - y is -0 only
//   when x is -0 already;
// * a manifold whose last visit applied nothing, and whose two bodies no visit has pushed since,
//   is not visited again: the visit would read the same velocities and accumulated impulses
//   (lp: never -0 either, it starts at +0 and only takes sums and the clamp's +0), so it would
//   compute every nw bitwise as last time, equal to the old value, and write back what is there.
//   (`pushed`: for each body the count of applies when one last pushed it; `seen`: for each
//   listed manifold the count when its last visit ended.)
void relax_positions(const StepContext& ctx, const ContactConstraints& c,
                     const SolverBodies& pseudo) {
    const Settings& cfg = ctx.settings;
    const double inv_h = ctx.inv_h;
    if (cfg.position_iterations <= 0) return;
    static thread_local std::vector<i64> deep_kept;
    std::vector<i64>& deep = deep_kept;
    deep.clear();
    for (i64 m = 0; m < c.n_man; ++m) {
        if (!c.mi[m].active) continue;
        const i64 start = c.mi[m].start;
        const i64 end = start + c.mi[m].count;
        for (i64 p = start; p < end; ++p) {
            if (c.pf[p].s <= 0.0) {
                deep.push_back(m);
                break;
            }
        }
    }
    const i64 n_deep = (i64)deep.size();
    static thread_local std::vector<i64> pushed_kept, seen_kept;
    std::vector<i64>& pushed = pushed_kept;
    std::vector<i64>& seen = seen_kept;
    pushed.assign((size_t)pseudo.inv_mass.n0, 0);
    seen.assign((size_t)n_deep, -1);  // -1: visit (the first sweep, or the last visit applied)
    i64 applies = 0;
    for (i64 it = 0; it < cfg.position_iterations; ++it) {
        for (i64 k = 0; k < n_deep; ++k) {
            const i64 m = deep[(size_t)k];
            i64 ia = c.mi[m].a, ib = c.mi[m].b;
            const i64 last = seen[(size_t)k];
            if (last >= 0 && pushed[(size_t)ia] <= last && pushed[(size_t)ib] <= last) continue;
            const i64 applies0 = applies;
            i64 start = c.mi[m].start;
            i64 end = start + c.mi[m].count;
            BodyPair bp(pseudo, ia, ib);
            double nx = c.mf[m].normal[0], ny = c.mf[m].normal[1], nz = c.mf[m].normal[2];
            for (i64 p = start; p < end; ++p) {
                ContactPoint& q = c.pf[p];
                double s = q.s;
                if (s > 0.0) continue;
                double rax = q.ra[0], ray = q.ra[1], raz = q.ra[2];
                double rbx = q.rb[0], rby = q.rb[1], rbz = q.rb[2];
                double dvx, dvy, dvz;
                bp.relative_velocity(rax, ray, raz, rbx, rby, rbz, dvx, dvy, dvz);
                double vn = dvx * nx + dvy * ny + dvz * nz;
                double target =
                    -(s + cfg.allowed_penetration) * cfg.position_correction_rate * inv_h;
                if (target < 0.0) {
                    target = 0.0;
                } else if (target > cfg.max_correction_speed) {
                    target = cfg.max_correction_speed;
                }
                double old = q.lp;
                double nw = old + q.normal_mass * (target - vn);
                if (nw < 0.0) nw = 0.0;
                q.lp = nw;
                double d = nw - old;
                if (d == 0.0) continue;  // (see above: applying it would change no bit)
                bp.apply(rax, ray, raz, rbx, rby, rbz, d * nx, d * ny, d * nz);
                applies += 1;
                pushed[(size_t)ia] = applies;
                pushed[(size_t)ib] = applies;
            }
            seen[(size_t)k] = applies == applies0 ? applies : -1;
            bp.store(pseudo);
        }
    }
}

}  // namespace rb
