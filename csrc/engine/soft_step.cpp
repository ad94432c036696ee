// The soft step: Box2D v3's sub-stepped contact solve (solver.c, b2SolverStage; contact_solver.c),
// stages 6-8 of the world step when ContactParams.solver is "soft_step" (world_step.cpp).
//
// Box2D v3 (Catto, "Solver2D" 2024) replaces the converged Gauss-Seidel solve with a fixed
// number of substeps of h_s = h / substeps, each one sweep of a *soft* solve and one of a rigid
// relax:
//
//     for each substep:
//         integrate velocities   v += h_s a, w += h_s I^-1 tau                (b2IntegrateVelocities)
//         warm start             apply the points' impulses of the last substep (b2WarmStartContactsTask)
//         solve, with bias       soft normal rows, friction                    (b2SolveContactsTask(useBias))
//         integrate positions    dp += h_s v, dtheta += h_s w                  (b2IntegratePositions)
//         relax, without bias    rigid normal rows, friction                   (b2RelaxContactsTask)
//     restitution, store impulses: the world step's own stages 10 and 11
//
// Separation. A point's gap is updated every substep from the bodies' displacements since the
// narrowphase (Box2D's anchor form, linear in the rotation): with the anchors r_a, r_b (world, at
// the narrowphase) and n from b into a,
//
//     s = s0 + n . (dp_a + dtheta_a x r_a - dp_b - dtheta_b x r_b)
//
// (the rotation's second-order term |dtheta|^2 |r| / 2 is left out, as Box2D does in 2-D with
// its exact rotation; over a step of a box turning at 1 rad/s at dt = 1e-3 it is 5e-8 m).
//
// Soft contact (b2MakeSoft): a penetrating point (s <= 0) is a spring-damper of frequency
// omega = 2 pi f and damping ratio zeta stepped by implicit Euler over h_s:
//
//     a1 = 2 zeta + h_s omega,  a2 = h_s omega a1,  a3 = 1 / (1 + a2)
//     bias_rate = omega / a1,  mass_scale = a2 a3,  impulse_scale = a3
//     bias = max(bias_rate s, -push_max)
//     dlambda = -m_n mass_scale (v_n + bias) - impulse_scale lambda
//
// (m_n = 1 / (J M^-1 J^T), lambda the point's impulse of this substep). f is
// min(contact_hertz, substep rate / 4) (Box2D's cap: stiffer springs are not resolved by the
// substep), twice that when one side is static (Box2D's staticSoftness). A speculative point
// (s > 0) is rigid, bias = s / h_s: it may close its gap within the substep but not cross it.
// The relax sweep is the same with bias 0 for s <= 0 (rigid, no push-out): it takes the
// spring's velocity back out of the bodies, so that the push-out moves positions (the solve's
// velocity was integrated) but leaves no velocity behind.
//
// Resting depth. At rest under a load W (N) per point the spring holds s = -W / (m omega^2)
// in steady state: a cube of mass m on the ground sits g / (2 omega)^2 deep (static softness),
// a stack's contacts deeper in proportion to the weight above them. So the step rate and the
// substeps set how stiff the contacts can be: at dt = 1e-3 with 4 substeps f <= 1 kHz and the
// cube sits 0.06 um deep; at dt = 1e-2, 0.1 kHz and 6.2 um.
//
// Normal rows of a manifold together: the soft update of every point at once through the
// manifold's factored block K (prepare_contacts' LU of K + BLOCK_REG diag K, as the PGS solve),
// x = K^-1 (-(v_n + bias)), dlambda_i = mass_scale_i x_i - impulse_scale_i lambda_i, taken when
// no point's impulse would go negative, else the points one by one. One point at a time, one
// sweep a substep leaves a face's loads uneven (the first point takes most), and the torque of
// that rocks tall stacks: the 10-box stack at dt = 1e-3 with 4 substeps moved its top 0.61 mm
// one by one, 0.023 mm (its springs' sag, see above) with the block.
//
// Friction: the Coulomb cone of the PGS solve (friction.hpp: the 2x2 tangent block, maximum
// dissipation on the circle) against this substep's normal impulse, in both sweeps; with the
// friction anchors on (ContactParams.static_friction_anchors), the solve sweep's rows aim at
// the anchor's slip rate -FRICTION_ANCHOR_RATE D / h (slip_bias, as the PGS solve's anchor pass),
// whose displacement the relax sweep then keeps while it takes the velocity back.
//
// Bookkeeping with the rest of the step. ln, l1, l2 enter as the warm-start impulses of
// the step (the last step's totals) and leave as this step's totals (the sum over the substeps),
// so every later stage (restitution, store_impulses, sleep, the contact log) reads impulses as
// with the PGS solve; a substep starts from the step's total / substeps. The kick stage put h a
// into the velocities: it is taken back out and applied a substep at a time. Positions move in
// stage 9 (integrate_positions), which sees the displacement as x += h (v + v') with the pseudo
// velocity v' = dp / h - v (w' likewise): momenta rebuilt from the velocity changes, unpushed
// bodies on their exact parabolas, and the orbital angular momentum of the v' shift handed back
// to the spin, as for the relax stage's pseudo velocities.

#include <cmath>
#include <vector>

#include "engine/contact_solver.hpp"
#include "engine/friction.hpp"
#include "engine/manifold.hpp"
#include "engine/soft_step.hpp"

namespace rb {

namespace {

constexpr double PI = 3.14159265358979323846;

// Per-thread work rows of the soft step (grown, never shrunk): each body's displacement and
// rotation vector since the narrowphase, (N+1, 3) each, and each point's impulses of the current
// substep (normal, t1, t2) and their running sums over the substeps, (K, 3) each.
struct SoftWork {
    std::vector<double> dp, dth, lam, sum;
};
thread_local SoftWork g_work;

// Solve K x = b in place (b: x, n <= 4) with manifold f's factors from prepare_contacts'
// factor_block: the row exchanges piv, the multipliers below lu's diagonal, U on and above.
inline void lu_solve(const Manifold& f, i64 n, double* x) {
    const bool pt[4] = {true, true, true, true};
    lu_solve_rows<double, ScalarLane>(
        (int)n, pt, [&f](int k) { return f.lu[k]; }, [&f](int c) { return f.piv[c]; }, x);
}

// The impulses x_i n at anchors r_a,i / r_b,i of one manifold at once: D = sum x_i, sa = sum x_i
// r_a,i, sb = sum x_i r_b,i; velocity changes +-m^-1 D n and +-I^-1 (s x n), what apply_impulse
// makes point by point (to round-off).
inline void apply_moments(double ma, const double* a6, double mb, const double* b6,
                          const double* sa, const double* sb, double dsum, double nx, double ny,
                          double nz, double& vax, double& vay, double& vaz, double& wax,
                          double& way, double& waz, double& vbx, double& vby, double& vbz,
                          double& wbx, double& wby, double& wbz) {
    double cx = sa[1] * nz - sa[2] * ny, cy = sa[2] * nx - sa[0] * nz, cz = sa[0] * ny - sa[1] * nx;
    vax += ma * dsum * nx;
    vay += ma * dsum * ny;
    vaz += ma * dsum * nz;
    wax += a6[0] * cx + a6[3] * cy + a6[4] * cz;
    way += a6[3] * cx + a6[1] * cy + a6[5] * cz;
    waz += a6[4] * cx + a6[5] * cy + a6[2] * cz;
    cx = sb[1] * nz - sb[2] * ny;
    cy = sb[2] * nx - sb[0] * nz;
    cz = sb[0] * ny - sb[1] * nx;
    vbx -= mb * dsum * nx;
    vby -= mb * dsum * ny;
    vbz -= mb * dsum * nz;
    wbx -= b6[0] * cx + b6[3] * cy + b6[4] * cz;
    wby -= b6[3] * cx + b6[1] * cy + b6[5] * cz;
    wbz -= b6[4] * cx + b6[5] * cy + b6[2] * cz;
}

// One sweep over the manifolds (in manifold order): the normal rows, then friction (Box2D v3's
// order), with the soft bias when use_bias, rigid otherwise; sum: the relax sweep adds each
// point's impulses of the substep into it (nullptr: the solve sweep).
void sweep(V1<ManifoldHead> mi, V1<Manifold> mf, V1<ContactPoint> pf, i64 n_man, V1<double> bm,
           V2<double> bI,
           V2<double> bv, V2<double> bw, const double* dp, const double* dth, double* lam,
           double inv_hs, bool use_bias, const Softness& soft, const Softness& soft_static,
           double push_max, bool anchors, bool block_rows, i64 newton_iters,
           double newton_tol, double* sum) {
    for (i64 m = 0; m < n_man; ++m) {
        if (!mi[m].active) continue;
        i64 ia = mi[m].a, ib = mi[m].b;
        BodyPair bp(SolverBodies{bm, bI, bv, bw}, ia, ib);
        const Softness& sf = (bp.ma == 0.0 || bp.mb == 0.0) ? soft_static : soft;
        double nx = mf[m].normal[0], ny = mf[m].normal[1], nz = mf[m].normal[2];
        double t1x = mf[m].t1[0], t1y = mf[m].t1[1], t1z = mf[m].t1[2];
        double t2x = mf[m].t2[0], t2y = mf[m].t2[1], t2z = mf[m].t2[2];
        double mu = mf[m].mu;
        const double* pa = dp + 3 * ia;
        const double* qa = dth + 3 * ia;
        const double* pb = dp + 3 * ib;
        const double* qb = dth + 3 * ib;
        i64 start = mi[m].start;
        i64 end = start + mi[m].count;
        // normal rows: each point's target (the soft bias, or the speculative one), then the
        // manifold's points together through its factored block K (prepare_contacts' lu, as
        // the PGS solve), else one by one
        i64 cnt = end - start;
        double rhs[4], ms[4], is[4];
        for (i64 p = start; p < end; ++p) {
            const ContactPoint& q = pf[p];
            i64 i = p - start;
            double rax = q.ra[0], ray = q.ra[1], raz = q.ra[2];
            double rbx = q.rb[0], rby = q.rb[1], rbz = q.rb[2];
            // current separation: s0 + n . (dp_a + dth_a x r_a - dp_b - dth_b x r_b)
            double dx = pa[0] + qa[1] * raz - qa[2] * ray - pb[0] - qb[1] * rbz + qb[2] * rby;
            double dy = pa[1] + qa[2] * rax - qa[0] * raz - pb[1] - qb[2] * rbx + qb[0] * rbz;
            double dz = pa[2] + qa[0] * ray - qa[1] * rax - pb[2] - qb[0] * rby + qb[1] * rbx;
            double s = q.s + nx * dx + ny * dy + nz * dz;
            double bias = 0.0;
            ms[i] = 1.0;
            is[i] = 0.0;
            if (s > 0.0) {
                bias = s * inv_hs;  // speculative: close the gap, do not cross it
            } else if (use_bias) {
                bias = sf.bias_rate * s;
                if (bias < -push_max) bias = -push_max;
                ms[i] = sf.mass_scale;
                is[i] = sf.impulse_scale;
            }
            rhs[i] = bias;
        }
        bool block = block_rows && cnt > 1 && mf[m].lu_ok > 0.0;
        if (block) {
            // x = K^-1 (-(v_n + bias)); dlambda_i = mass_scale_i x_i - impulse_scale_i lambda_i
            double x[4];
            for (i64 i = 0; i < cnt; ++i) {
                const ContactPoint& q = pf[start + i];
                double rax = q.ra[0], ray = q.ra[1], raz = q.ra[2];
                double rbx = q.rb[0], rby = q.rb[1], rbz = q.rb[2];
                double dvx, dvy, dvz;
                bp.relative_velocity(rax, ray, raz, rbx, rby, rbz, dvx, dvy, dvz);
                x[i] = -(dvx * nx + dvy * ny + dvz * nz + rhs[i]);
            }
            lu_solve(mf[m], cnt, x);
            for (i64 i = 0; i < cnt && block; ++i) {
                double* l = lam + 3 * (start + i);
                x[i] = ms[i] * x[i] - is[i] * l[0];
                if (l[0] + x[i] < 0.0) block = false;
            }
            if (block) {
                // the points' impulses at once: D n on the bodies' centres, and the moments
                // (sum x_i r_i) x n, so one velocity update instead of one per point
                double dsum = 0.0, sa[3] = {0.0, 0.0, 0.0}, sb[3] = {0.0, 0.0, 0.0};
                for (i64 i = 0; i < cnt; ++i) {
                    const ContactPoint& q = pf[start + i];
                    lam[3 * (start + i)] += x[i];
                    dsum += x[i];
                    for (int k = 0; k < 3; ++k) {
                        sa[k] += x[i] * q.ra[k];
                        sb[k] += x[i] * q.rb[k];
                    }
                }
                apply_moments(bp.ma, bp.a6, bp.mb, bp.b6, sa, sb, dsum, nx, ny, nz, bp.va[0],
                              bp.va[1], bp.va[2], bp.wa[0], bp.wa[1], bp.wa[2], bp.vb[0],
                              bp.vb[1], bp.vb[2], bp.wb[0], bp.wb[1], bp.wb[2]);
            }
        }
        if (!block) {
            for (i64 p = start; p < end; ++p) {
                const ContactPoint& q = pf[p];
                double* l = lam + 3 * p;
                i64 i = p - start;
                double rax = q.ra[0], ray = q.ra[1], raz = q.ra[2];
                double rbx = q.rb[0], rby = q.rb[1], rbz = q.rb[2];
                // relative normal velocity
                double dvx, dvy, dvz;
                bp.relative_velocity(rax, ray, raz, rbx, rby, rbz, dvx, dvy, dvz);
                double vn = dvx * nx + dvy * ny + dvz * nz;
                // incremental impulse, clamp the accumulated one
                double old = l[0];
                double nw = old - q.normal_mass * ms[i] * (vn + rhs[i]) - is[i] * old;
                if (nw < 0.0) nw = 0.0;
                l[0] = nw;
                double d = nw - old;
                if (d == 0.0) continue;  // (a speculative point left open)
                bp.apply(rax, ray, raz, rbx, rby, rbz, d * nx, d * ny, d * nz);
            }
        }
        // friction rows: the cone of this substep's normal impulse
        if (mu > 0.0) {
            for (i64 p = start; p < end; ++p) {
                const ContactPoint& q = pf[p];
                double* l = lam + 3 * p;
                // no normal impulse and no friction impulse: the cone is a point, nothing to do
                if (l[0] == 0.0 && l[1] == 0.0 && l[2] == 0.0) continue;
                double rax = q.ra[0], ray = q.ra[1], raz = q.ra[2];
                double rbx = q.rb[0], rby = q.rb[1], rbz = q.rb[2];
                double dvx, dvy, dvz;
                bp.relative_velocity(rax, ray, raz, rbx, rby, rbz, dvx, dvy, dvz);
                double vt1 = dvx * t1x + dvy * t1y + dvz * t1z;
                double vt2 = dvx * t2x + dvy * t2y + dvz * t2z;
                if (use_bias && anchors) {  // slip relative to the anchor's target -D rate / h
                    vt1 += q.slip_bias[0];
                    vt2 += q.slip_bias[1];
                }
                double o1 = l[1], o2 = l[2];
                double n1, n2;
                friction_impulse(q.tangent_k[0], q.tangent_k[1], q.tangent_k[2], o1, o2, vt1, vt2,
                                 mu * l[0], newton_iters, newton_tol, n1, n2);
                l[1] = n1;
                l[2] = n2;
                double d1 = n1 - o1, d2 = n2 - o2;
                bp.apply(rax, ray, raz, rbx, rby, rbz, d1 * t1x + d2 * t2x, d1 * t1y + d2 * t2y,
                         d1 * t1z + d2 * t2z);
            }
        }
        bp.store(SolverBodies{bm, bI, bv, bw});
        if (sum != nullptr)  // the relax sweep: what this substep applied, into the step's sums
            for (i64 p = 3 * start; p < 3 * end; ++p) sum[p] += lam[p];
    }
}

}  // namespace

Softness make_soft(double hertz, double zeta, double h) {
    if (hertz == 0.0) return Softness{0.0, 1.0, 0.0};
    double omega = 2.0 * PI * hertz;
    double a1 = 2.0 * zeta + h * omega;
    double a2 = h * omega * a1;
    double a3 = 1.0 / (1.0 + a2);
    return Softness{omega / a1, a2 * a3, a3};
}

i64 soft_solve(const StepContext& ctx, const ContactConstraints& c, const SolverBodies& b,
               V2<double> pv, V2<double> pw, V1<i64> in_contact, V2<double> accel,
               V2<double> torque, bool do_kick) {
    const V1<ManifoldHead> mi = c.mi;
    const V1<Manifold> mf = c.mf;
    V1<ContactPoint> pf = c.pf;
    const i64 n_man = c.n_man;
    const V1<double> bm = b.inv_mass;
    const V2<double> bI = b.inv_inertia, bv = b.v, bw = b.w;
    const Settings& cfg = ctx.settings;
    const double h = ctx.h;
    // the sweeps' switches: the soft bias capped at max_correction_speed, the friction rows aimed
    // at the anchors' slip rate (slip_bias) with static_friction_anchors, a manifold's normal rows
    // solved together (its factored block K)
    const bool block = true;
    const double hs = h / double(cfg.substeps);
    const double inv_hs = 1.0 / hs;
    const i64 n_rows = bm.n0;  // N + 1: row N the static dummy
    const i64 n_dyn = n_rows - 1;
    double hz = cfg.contact_hertz;
    if (hz > 0.25 * inv_hs) hz = 0.25 * inv_hs;
    const Softness soft = make_soft(hz, cfg.contact_damping_ratio, hs);
    const Softness soft_static = make_soft(2.0 * hz, cfg.contact_damping_ratio, hs);

    i64 n_pts = 0;
    for (i64 m = 0; m < n_man; ++m) {
        i64 e = mi[m].start + mi[m].count;
        if (e > n_pts) n_pts = e;
    }
    SoftWork& wk = g_work;
    wk.dp.assign((size_t)(3 * n_rows), 0.0);
    wk.dth.assign((size_t)(3 * n_rows), 0.0);
    if (wk.lam.size() < (size_t)(3 * n_pts)) {
        wk.lam.resize((size_t)(3 * n_pts));
        wk.sum.resize((size_t)(3 * n_pts));
    }
    double* dp = wk.dp.data();
    double* dth = wk.dth.data();
    double* lam = wk.lam.data();
    double* sum = wk.sum.data();
    // a substep's share of the step's warm-start impulses
    const double share = 1.0 / double(cfg.substeps);
    for (i64 m = 0; m < n_man; ++m) {
        if (!mi[m].active) continue;
        i64 start = mi[m].start;
        for (i64 p = start; p < start + mi[m].count; ++p) {
            lam[3 * p] = pf[p].ln * share;
            lam[3 * p + 1] = pf[p].l1 * share;
            lam[3 * p + 2] = pf[p].l2 * share;
            sum[3 * p] = sum[3 * p + 1] = sum[3 * p + 2] = 0.0;
        }
    }
    // the kick stage's velocity change comes back out: the substeps apply it a share at a time
    for (i64 i = 0; i < n_dyn; ++i) {
        if (!in_contact[i] || !do_kick) continue;
        for (int k = 0; k < 3; ++k) bv(i, k) -= h * accel(i, k);
        double tx = torque(i, 0), ty = torque(i, 1), tz = torque(i, 2);
        if (tx != 0.0 || ty != 0.0 || tz != 0.0) {
            const double* b = bI.row(i);
            bw(i, 0) -= h * (b[0] * tx + b[3] * ty + b[4] * tz);
            bw(i, 1) -= h * (b[3] * tx + b[1] * ty + b[5] * tz);
            bw(i, 2) -= h * (b[4] * tx + b[5] * ty + b[2] * tz);
        }
    }
    for (i64 sub = 0; sub < cfg.substeps; ++sub) {
        // integrate velocities
        if (do_kick) {
            for (i64 i = 0; i < n_dyn; ++i) {
                if (!in_contact[i]) continue;
                for (int k = 0; k < 3; ++k) bv(i, k) += hs * accel(i, k);
                double tx = torque(i, 0), ty = torque(i, 1), tz = torque(i, 2);
                if (tx != 0.0 || ty != 0.0 || tz != 0.0) {
                    const double* b = bI.row(i);
                    bw(i, 0) += hs * (b[0] * tx + b[3] * ty + b[4] * tz);
                    bw(i, 1) += hs * (b[3] * tx + b[1] * ty + b[5] * tz);
                    bw(i, 2) += hs * (b[4] * tx + b[5] * ty + b[2] * tz);
                }
            }
        }
        // warm start: this substep begins with the last one's impulses applied
        apply_stored_impulses(c, b, lam, 3);
        // solve, with the soft bias
        sweep(mi, mf, pf, n_man, bm, bI, bv, bw, dp, dth, lam, inv_hs, true, soft, soft_static,
              cfg.max_correction_speed, cfg.static_friction_anchors, block,
              cfg.friction_newton_iters, cfg.friction_newton_tol, nullptr);
        // integrate positions (into the displacements; the static dummy's stay zero)
        for (i64 i = 0; i < n_dyn; ++i) {
            if (!in_contact[i]) continue;
            for (int k = 0; k < 3; ++k) {
                dp[3 * i + k] += hs * bv(i, k);
                dth[3 * i + k] += hs * bw(i, k);
            }
        }
        // relax, rigid
        sweep(mi, mf, pf, n_man, bm, bI, bv, bw, dp, dth, lam, inv_hs, false, soft, soft_static,
              cfg.max_correction_speed, cfg.static_friction_anchors, block,
              cfg.friction_newton_iters, cfg.friction_newton_tol, sum);
    }
    // the step's impulses, and the pseudo velocities that carry the substeps' displacement
    for (i64 m = 0; m < n_man; ++m) {
        if (!mi[m].active) continue;
        i64 start = mi[m].start;
        for (i64 p = start; p < start + mi[m].count; ++p) {
            pf[p].ln = sum[3 * p];
            pf[p].l1 = sum[3 * p + 1];
            pf[p].l2 = sum[3 * p + 2];
        }
    }
    const double inv_h = 1.0 / h;
    for (i64 i = 0; i < n_dyn; ++i) {
        if (!in_contact[i]) continue;
        for (int k = 0; k < 3; ++k) {
            pv(i, k) = dp[3 * i + k] * inv_h - bv(i, k);
            pw(i, k) = dth[3 * i + k] * inv_h - bw(i, k);
        }
    }
    return 2 * cfg.substeps;
}

void soft_island_flight(V1<i64> awake, V1<i64> in_contact, V1<i64> pushed, V2<double> accel,
                        V2<double> pv, double h, i64 substeps) {
    const double c = h * double(substeps - 1) / (2.0 * double(substeps));
    for (i64 i = 0; i < accel.n0; ++i) {
        if (!awake[i] || !in_contact[i] || pushed[i] != 1) continue;
        for (int k = 0; k < 3; ++k) pv(i, k) += c * accel(i, k);
    }
}

}  // namespace rb
