// Stage 10 of the contact step: restitution, the bounce of impact points after positions moved.
//
// Restitution (Box2D v3): after positions are integrated, points that were hit (solve impulse > 0)
// while approaching faster than the threshold get a normal velocity set from the approach velocity
// measured *before* the solve. rblog sharpens Box2D's rule with the flight's energy: a body that no
// contact pushes flies exactly under its constant acceleration (step.py, stage 9), so between
// contacts the gap s, its rate w and the relative normal acceleration a of the external forces
// (gravity) keep ``E = w^2/2 - a s`` exactly (at every step boundary). The approach speed at
// contact is therefore ``u = sqrt(2 E) = sqrt(w0^2 - 2 a s0)`` from the start-of-step gap s0 and
// rate w0 (before the kick), and the rebound rate w+ is chosen so that the post-impact state at the
// end-of-step gap s1 has energy e^2 E: ``w+^2/2 - a s1 = e^2 u^2/2``, i.e.
// ``w+ = sqrt(e^2 u^2 + 2 a s1)``. The exact flight after the bounce keeps that energy, so the
// apex is e^2 times the drop height: bounce apexes e^(2n) h0 to round-off plus the sampling of the
// apex (a rule that ignored the gravity over the step would be ~1% off at dt = 1e-3). Without
// external acceleration this is w+ = e |w0|.

#include <cmath>
#include <vector>

#include "common/task_pool.hpp"
#include "engine/contact_solver.hpp"
#include "engine/manifold.hpp"

namespace rb {

TaskPool& pool();  // the engine's pool (threads.cpp)

namespace {

// manifolds per block of the first pass on the task pool, and the fewest worth a hand-off
// (~660 instructions a manifold)
constexpr i64 MANIFOLDS_PER_BLOCK = 128;
constexpr i64 MIN_MANIFOLDS = 256;

inline double gap_rate(V2<double> v, V2<double> w, i64 ia, i64 ib, double nx, double ny,
                       double nz, double rax, double ray, double raz, double rbx, double rby,
                       double rbz) {
    double dvx = v(ia, 0) + w(ia, 1) * raz - w(ia, 2) * ray - v(ib, 0) - w(ib, 1) * rbz + w(ib, 2) * rby;
    double dvy = v(ia, 1) + w(ia, 2) * rax - w(ia, 0) * raz - v(ib, 1) - w(ib, 2) * rbx + w(ib, 0) * rbz;
    double dvz = v(ia, 2) + w(ia, 0) * ray - w(ia, 1) * rax - v(ib, 2) - w(ib, 0) * rby + w(ib, 1) * rbx;
    return dvx * nx + dvy * ny + dvz * nz;
}

// Impulse (px, py, pz) on a at anchor r_a and its negative on b at r_b: into the solver
// velocities (b.v, b.w) and straight into the momenta of dynamic bodies (P += J, L += r x J).
void apply_pair_impulse(const SolverBodies& b, V2<double> linear_momentum,
                        V2<double> angular_momentum, i64 ia, i64 ib, double rax, double ray,
                        double raz, double rbx, double rby, double rbz, double px, double py,
                        double pz) {
    i64 n_dyn = linear_momentum.n0;
    BodyPair bp(b, ia, ib);
    bp.apply(rax, ray, raz, rbx, rby, rbz, px, py, pz);
    bp.store(b);
    // angular impulses r x J straight into L (the orientations have already moved on)
    const i64 body[2] = {ia, ib};
    const double sign[2] = {1.0, -1.0};
    const double r[2][3] = {{rax, ray, raz}, {rbx, rby, rbz}};
    for (int k = 0; k < 2; ++k) {
        i64 i = body[k];
        if (i < n_dyn) {
            double rx = r[k][0], ry = r[k][1], rz = r[k][2];
            double cx = ry * pz - rz * py, cy = rz * px - rx * pz, cz = rx * py - ry * px;
            double sg = sign[k];
            linear_momentum(i, 0) += sg * px;
            linear_momentum(i, 1) += sg * py;
            linear_momentum(i, 2) += sg * pz;
            angular_momentum(i, 0) += sg * cx;
            angular_momentum(i, 1) += sg * cy;
            angular_momentum(i, 2) += sg * cz;
        }
    }
}

// Keep the friction impulse of every bouncing point inside the Coulomb cone.
//
// The bounce pass may lower a point's accumulated normal impulse (down to 0) after friction was
// solved against the higher one; the friction impulse is then scaled back onto the cone
// |lambda_t| <= mu lambda_n and the difference applied, at the same shared anchors as the bounce,
// so that the pair's momenta stay exactly balanced. targeted: the manifolds with a bouncing point
// (wt >= 0), in manifold order.
void reclamp_friction(const ContactConstraints& c, const std::vector<i64>& targeted,
                      const SolverBodies& b, V2<double> dx, V2<double> linear_momentum,
                      V2<double> angular_momentum) {
    V1<ManifoldHead> mi = c.mi;
    V1<Manifold> mf = c.mf;
    V1<ContactPoint> pf = c.pf;
    for (const i64 m : targeted) {
        double mu = mf[m].mu;
        i64 ia = mi[m].a, ib = mi[m].b;
        bool shared = b.inv_mass[ia] > 0.0 && b.inv_mass[ib] > 0.0;
        double hx = 0.5 * (dx(ib, 0) - dx(ia, 0));
        double hy = 0.5 * (dx(ib, 1) - dx(ia, 1));
        double hz = 0.5 * (dx(ib, 2) - dx(ia, 2));
        double t1x = mf[m].t1[0], t1y = mf[m].t1[1], t1z = mf[m].t1[2];
        double t2x = mf[m].t2[0], t2y = mf[m].t2[1], t2z = mf[m].t2[2];
        i64 start = mi[m].start;
        for (i64 p = start; p < start + mi[m].count; ++p) {
            ContactPoint& q = pf[p];
            if (q.wt < 0.0) continue;
            double l1 = q.l1, l2 = q.l2;
            double nl = std::sqrt(l1 * l1 + l2 * l2);
            double fmax = mu * q.ln;
            if (nl <= fmax) continue;
            double scale = fmax / nl;
            double d1 = l1 * scale - l1, d2 = l2 * scale - l2;
            q.l1 = l1 * scale;
            q.l2 = l2 * scale;
            double px = d1 * t1x + d2 * t2x;
            double py = d1 * t1y + d2 * t2y;
            double pz = d1 * t1z + d2 * t2z;
            double rax = q.ra[0], ray = q.ra[1], raz = q.ra[2];
            double rbx = q.rb[0], rby = q.rb[1], rbz = q.rb[2];
            if (shared) {
                rax = rax + hx; ray = ray + hy; raz = raz + hz;
                rbx = rbx - hx; rby = rby - hy; rbz = rbz - hz;
            }
            apply_pair_impulse(b, linear_momentum, angular_momentum, ia, ib, rax, ray, raz, rbx,
                               rby, rbz, px, py, pz);
        }
    }
}

}  // namespace

// Store the solve's impulses for warm starting, estimate end-of-step gaps, then bounce.
//
// A point bounces when its solve impulse is positive (it was hit), the gap was closing at the
// start of the step, and its impact speed u exceeds threshold. Returns the number of impact
// points.
//
// Bounces come after the positions moved (dx: (N+1, 3) each body's displacement this step).
// Between two bodies the impulse is applied at one point that moved with them, the midpoint
// p + (dx_a + dx_b)/2, so that both anchors end at the same point: otherwise the pair's angular
// momentum would change by h (v_a - v_b) x J. The bounce impulses go straight into the momenta
// (P += J, L += r x J), since the orientations have already moved on.
i64 restitution(const StepContext& ctx, const ContactConstraints& c, const SolverBodies& b,
                V2<double> pv, V2<double> pw, V2<double> dx, V2<double> linear_momentum,
                V2<double> angular_momentum) {
    const Settings& cfg = ctx.settings;
    const double h = ctx.h;
    // the end-of-step gaps and the impact points: each manifold writes only its own points'
    // rows, so blocks of manifolds run on the task pool; the impacts are counted per block
    const i64 n_blocks =
        pool().threads() > 1 ? TaskPool::blocks_for(c.n_man, MANIFOLDS_PER_BLOCK, MIN_MANIFOLDS)
                             : 1;
    std::vector<i64> blk_impacts((size_t)n_blocks, 0);
    // bodies whose pseudo velocities are all zero (the relax stage pushed most bodies not at
    // all): a point between two of them has the pseudo gap rate pn = +-0 (a sum of products
    // with a zero factor), and s0 + h (vn + pn) is s0 + h vn bit for bit unless vn and s0 are
    // both zero (then the sum is taken as written)
    static thread_local std::vector<char> still_kept;
    std::vector<char>& still = still_kept;
    still.resize((size_t)pv.n0);
    for (i64 i = 0; i < pv.n0; ++i)
        still[(size_t)i] = pv(i, 0) == 0.0 && pv(i, 1) == 0.0 && pv(i, 2) == 0.0 &&
                           pw(i, 0) == 0.0 && pw(i, 1) == 0.0 && pw(i, 2) == 0.0;
    pool().run(n_blocks, [&](i64 blk, int) {
    i64 n_impacts = 0;
    for (i64 m = c.n_man * blk / n_blocks; m < c.n_man * (blk + 1) / n_blocks; ++m) {
        if (!c.mi[m].active) continue;
        i64 ia = c.mi[m].a, ib = c.mi[m].b;
        double nx = c.mf[m].normal[0], ny = c.mf[m].normal[1], nz = c.mf[m].normal[2];
        double e = c.mf[m].e;
        double acc = c.mf[m].acc;
        const bool pair_still = still[(size_t)ia] && still[(size_t)ib];
        i64 start = c.mi[m].start;
        for (i64 p = start; p < start + c.mi[m].count; ++p) {
            ContactPoint& q = c.pf[p];
            double rax = q.ra[0], ray = q.ra[1], raz = q.ra[2];
            double rbx = q.rb[0], rby = q.rb[1], rbz = q.rb[2];
            double vn = gap_rate(b.v, b.w, ia, ib, nx, ny, nz, rax, ray, raz, rbx, rby, rbz);
            double s0 = q.s;
            double s1;
            if (pair_still && (vn != 0.0 || s0 != 0.0)) {
                s1 = s0 + h * vn;
            } else {
                double pn = gap_rate(pv, pw, ia, ib, nx, ny, nz, rax, ray, raz, rbx, rby, rbz);
                s1 = s0 + h * (vn + pn);
            }
            q.s_end = s1;
            q.lws = q.ln;
            q.wt = -1.0;
            double w0 = q.w0;
            // approach speed at contact from the flight's energy (see the header comment)
            if (!struck(w0, q.ln, acc, s0, cfg.restitution_threshold)) continue;
            double u2 = w0 * w0 - 2.0 * acc * s0;
            q.impact = 1.0;
            n_impacts += 1;
            if (e <= 0.0) continue;
            // rebound rate whose flight energy at the end-of-step gap s1 is e^2 times the impact's
            double c = e * e * u2 + 2.0 * acc * s1;
            if (c > 0.0) {
                q.wt = std::sqrt(c);
            } else {
                q.wt = e * std::sqrt(u2);
            }
        }
    }
    blk_impacts[(size_t)blk] = n_impacts;
    });
    i64 n_impacts = 0;
    for (i64 c : blk_impacts) n_impacts += c;
    if (n_impacts == 0) return 0;
    // Gauss-Seidel on the bounce targets of the impact points only (the manifolds with a
    // target listed once: wt does not change in the sweeps)
    static thread_local std::vector<i64> kept;
    std::vector<i64>& targeted = kept;
    targeted.clear();
    for (i64 m = 0; m < c.n_man; ++m) {
        if (!c.mi[m].active) continue;
        const i64 start = c.mi[m].start;
        for (i64 p = start; p < start + c.mi[m].count; ++p) {
            if (c.pf[p].wt >= 0.0) {
                targeted.push_back(m);
                break;
            }
        }
    }
    for (i64 it = 0; it < cfg.velocity_iterations; ++it) {
        for (const i64 m : targeted) {
            i64 start = c.mi[m].start;
            i64 end = start + c.mi[m].count;
            i64 ia = c.mi[m].a, ib = c.mi[m].b;
            double ma = b.inv_mass[ia], mb = b.inv_mass[ib];
            double nx = c.mf[m].normal[0], ny = c.mf[m].normal[1], nz = c.mf[m].normal[2];
            bool shared = ma > 0.0 && mb > 0.0;
            double hx = 0.5 * (dx(ib, 0) - dx(ia, 0));
            double hy = 0.5 * (dx(ib, 1) - dx(ia, 1));
            double hz = 0.5 * (dx(ib, 2) - dx(ia, 2));
            for (i64 p = start; p < end; ++p) {
                ContactPoint& q = c.pf[p];
                double wt = q.wt;
                if (wt < 0.0) continue;
                double rax = q.ra[0], ray = q.ra[1], raz = q.ra[2];
                double rbx = q.rb[0], rby = q.rb[1], rbz = q.rb[2];
                if (shared) {
                    rax = rax + hx; ray = ray + hy; raz = raz + hz;
                    rbx = rbx - hx; rby = rby - hy; rbz = rbz - hz;
                }
                double vn = gap_rate(b.v, b.w, ia, ib, nx, ny, nz, rax, ray, raz, rbx, rby, rbz);
                double old = q.ln;
                double nw = old + q.normal_mass * (wt - vn);
                if (nw < 0.0) nw = 0.0;
                q.ln = nw;
                double d = nw - old;
                apply_pair_impulse(b, linear_momentum, angular_momentum, ia, ib, rax, ray, raz,
                                   rbx, rby, rbz, d * nx, d * ny, d * nz);
            }
        }
    }
    // (only the targeted manifolds hold points with wt >= 0, the ones reclamp_friction acts on)
    reclamp_friction(c, targeted, b, dx, linear_momentum, angular_momentum);
    return n_impacts;
}

}  // namespace rb
