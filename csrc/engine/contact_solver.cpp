// Contact solver: sequential impulses (projected Gauss-Seidel) with accumulated-impulse clamping.
//
// Stages, in the order the world step calls them (Box2D v3's ``b2SolverStage``):
// ``load_bodies`` -> ``prepare_contacts`` -> ``warm_start`` -> ``solve_velocities`` ->
// ``anchor_friction`` (with ContactParams.static_friction_anchors) -> ``relax_positions`` (split impulses) -> [integrate positions, in step.py] -> ``restitution``
// -> [project: fresh narrowphase and nonlinear position pass, in project.cpp].
//
// Derivations
// -----------
// Velocity of the gap at a point with anchors r_a, r_b (normal n from b into a)::
//
//     vn = n . (v_a + w_a x r_a - v_b - w_b x r_b)            (> 0: separating)
//
// An impulse P at the point changes it through the effective mass
// ``K = (m_a^-1 + m_b^-1) I - [r_a]x I_a^-1 [r_a]x - [r_b]x I_b^-1 [r_b]x`` (world inverse inertia
// ``I^-1 = R diag(1/I_body) R^T``). Each sweep visits every point: for the normal row it computes the
// impulse increment that makes vn reach its target, adds it to the accumulated impulse, clamps the
// accumulated impulse to >= 0, and applies the difference (Catto 2005). Friction uses the 2x2
// tangent block of K; when the sticking impulse leaves the disc of radius mu * lambda_n (isotropic
// Coulomb cone) the point slides and gets the maximum-dissipation impulse on the circle, so that
// friction opposes the slip exactly (see _friction_impulse). Equal and opposite impulses at the same point conserve the pair's linear
// momentum and its angular momentum about any point, to round-off.
//
// Normal impulses are over-relaxed (projected SOR, ``ContactParams.over_relaxation``) on manifolds
// whose bodies touch more than one thing, so that loads cross stacks and piles in fewer sweeps; see
// solve_velocities.
//
// Targets: a penetrating or touching point (s <= 0) wants vn >= 0; a speculative point (s > 0)
// wants vn >= -s/h, i.e. the pair may close the gap within the step but not cross it. This is what
// stops fast bodies tunnelling, and stops a falling body exactly on the surface.
//
// Friction anchor (static friction at the position level, as PhysX's friction anchors, which it
// breaks when the friction limit is exceeded; ContactParams.static_friction_anchors): a manifold
// whose pair sticks keeps its anchor, the pose of body a in body b's frame when the pair started
// sticking (``anchor_rot``, ``anchor_pos``; b's frame is the world for the ground). The collide
// stage carries it over with the manifold (matched by pair key, so points that come and go, a
// one-point contact that becomes a face, keep it) and gives every point its drift ``D``: where a's
// material point at the contact is now, minus where the anchor pose puts it (collide.py). So D
// holds the pair's slip and its twist since it stuck, whatever the points did, and counts every
// move of the bodies (the solve's, the split-impulse and projection shifts). A sphere's pair has no
// anchor: a rolling sphere brings a new material point to the contact every step, and a pose anchor
// would pull the contact back against the roll (samples/mixed.toml's balls crept 5 mm). The
// friction rows of the anchor pass (``anchor_friction``: one sweep after the solve, outside its
// convergence loop) then target
// the slip rate ``vt = -FRICTION_ANCHOR_RATE D / h``, so a solve that stops before it converges
// (residual slip e) cannot add up a drift: D settles at h e / rate and the slip velocity at zero.
// The bias lives in the friction rows only, which stay clamped to the Coulomb disc. A manifold
// drops its anchor (store_impulses: re-anchored where the pair then is) when a point was struck
// or none of its loaded points sticks (friction strictly inside the cone), and collide re-anchors
// a pair that drifted beyond FRICTION_ANCHOR_MAX_DRIFT_M. Friction impulses are equal and
// opposite, so the anchor changes no momentum. What the pass does not do: it is not followed by
// the normal rows (a pointwise normal sweep after it was measured to make the pile creep more;
// `git log -p benchmarks/RESULTS.md`), and a box resting on two single-point contacts can still turn about
// the line through them (no friction row sees that motion).
//
// Position correction by split impulses (stage 8) is in relax.cpp.
//
// Restitution (the bounce after positions moved) is in restitution.cpp.
#include <cmath>
#include <cstddef>  // offsetof
#include <vector>

#include "engine/constraint_graph.hpp"
#include "engine/contact_lanes.hpp"
#include "engine/contact_solver.hpp"
#include "engine/friction.hpp"
#include "engine/manifold.hpp"
#include "engine/solve_stages.hpp"

namespace rb {

namespace {

inline void smul(const double* i6, double x, double y, double z, double& ox, double& oy,
                 double& oz) {
    // symmetric 3x3 (xx, yy, zz, xy, xz, yz) times a vector
    ox = i6[0] * x + i6[3] * y + i6[4] * z;
    oy = i6[3] * x + i6[1] * y + i6[5] * z;
    oz = i6[4] * x + i6[5] * y + i6[2] * z;
}

inline void cross(double ax, double ay, double az, double bx, double by, double bz, double& ox,
                  double& oy, double& oz) {
    ox = ay * bz - az * by;
    oy = az * bx - ax * bz;
    oz = ax * by - ay * bx;
}

// LU-factor manifold m's regularised normal block (K + BLOCK_REG diag(K), n x n, from the points'
// kn rows) into mf[m].lu (U on and above the diagonal, the elimination multipliers below
// it, each left where it was computed), the pivot rows into mf[m].piv and mf[m].lu_ok =
// 1.0 if no pivot vanished. The block depends on the geometry and masses only, so it is factored
// once per step here instead of once per sweep; the sweep (solve_group in contact_lanes.inl)
// then makes exactly the floating-point operations of Gaussian elimination with partial pivoting
// on [K | rhs] (the same pivots, multipliers, order), so its results are bitwise those of an
// elimination per sweep.
// (N: the point count as a template argument, so that the compiler unrolls the short loops;
// factor_block picks it, N = 0: n_any. The loops and their order are the same for every N.)
template <i64 N>
void factor_block_n(V1<Manifold> mf, i64 m, V1<ContactPoint> pf, i64 start, i64 n_any,
                    double block_reg) {
    const i64 n = N > 0 ? N : n_any;
    Manifold& f = mf[m];
    double* lu = f.lu;
    for (i64 i = 0; i < n; ++i) {
        i64 p = start + i;
        for (i64 j = 0; j < n; ++j) lu[4 * i + j] = pf[p].kn[j];
        lu[5 * i] += block_reg * pf[p].kn[i];
    }
    f.lu_ok = 0.0;
    for (i64 c = 0; c < n; ++c) {
        i64 piv = c;
        for (i64 r = c + 1; r < n; ++r)
            if (std::fabs(lu[4 * r + c]) > std::fabs(lu[4 * piv + c])) piv = r;
        f.piv[c] = (double)piv;
        if (std::fabs(lu[4 * piv + c]) <= 0.0) return;
        if (piv != c) {
            for (i64 k = c; k < n; ++k) {
                double t = lu[4 * c + k];
                lu[4 * c + k] = lu[4 * piv + k];
                lu[4 * piv + k] = t;
            }
        }
        for (i64 r = c + 1; r < n; ++r) {
            double fr = lu[4 * r + c] / lu[5 * c];
            for (i64 k = c + 1; k < n; ++k) lu[4 * r + k] -= fr * lu[4 * c + k];
            lu[4 * r + c] = fr;
        }
    }
    f.lu_ok = 1.0;
}

void factor_block(V1<Manifold> mf, i64 m, V1<ContactPoint> pf, i64 start, i64 n,
                  double block_reg) {
    switch (n) {
        case 2: factor_block_n<2>(mf, m, pf, start, n, block_reg); break;
        case 3: factor_block_n<3>(mf, m, pf, start, n, block_reg); break;
        case 4: factor_block_n<4>(mf, m, pf, start, n, block_reg); break;
        default: factor_block_n<0>(mf, m, pf, start, n, block_reg); break;
    }
}

}  // namespace

// Count the active manifolds of each body (in_contact: (N+1,), row N the static dummy) and load
// the solver state of the bodies that have any.
//
// bm: (N+1,) inverse mass, bI: (N+1, 6) world inverse inertia (xx, yy, zz, xy, xz, yz), bv/bw:
// (N+1, 3) velocity and angular velocity (world), bv0/bw0 their values before the solve, pv/pw
// pseudo velocities, p0/l0 momenta before the solve. Row N is the static dummy (all zero).
void load_bodies(V1<ManifoldHead> mi, i64 n_man, i64 n_dyn, bool iso_shortcut, V1<i64> iso,
                 V1<double> inv_mass, V2<double> inv_inertia, V3<double> rotation,
                 V2<double> linear_momentum, V2<double> angular_momentum, V1<i64> in_contact,
                 V1<double> bm, V2<double> bI, V2<double> bv, V2<double> bw, V2<double> bv0,
                 V2<double> bw0, V2<double> pv, V2<double> pw, V2<double> p0, V2<double> l0) {
    for (i64 i = 0; i < n_dyn + 1; ++i) in_contact[i] = 0;
    for (i64 m = 0; m < n_man; ++m) {
        if (mi[m].active) {
            in_contact[mi[m].a] += 1;
            in_contact[mi[m].b] += 1;
        }
    }
    for (i64 i = 0; i < n_dyn; ++i) {
        if (!in_contact[i]) continue;
        double im = inv_mass[i];
        bm[i] = im;
        double* b = bI.row(i);
        if (iso_shortcut && iso[i]) {
            // isotropic inertia: I^-1 is a scalar in every frame, no transform needed
            double s = inv_inertia(i, 0);
            b[0] = s; b[1] = s; b[2] = s;
            b[3] = 0.0; b[4] = 0.0; b[5] = 0.0;
        } else {
            const double* r = rotation.row(i);  // r[3 a + b] = R[a, b]
            double d0 = inv_inertia(i, 0), d1 = inv_inertia(i, 1), d2 = inv_inertia(i, 2);
            // R diag(d) R^T
            b[0] = d0 * r[0] * r[0] + d1 * r[1] * r[1] + d2 * r[2] * r[2];
            b[1] = d0 * r[3] * r[3] + d1 * r[4] * r[4] + d2 * r[5] * r[5];
            b[2] = d0 * r[6] * r[6] + d1 * r[7] * r[7] + d2 * r[8] * r[8];
            b[3] = d0 * r[0] * r[3] + d1 * r[1] * r[4] + d2 * r[2] * r[5];
            b[4] = d0 * r[0] * r[6] + d1 * r[1] * r[7] + d2 * r[2] * r[8];
            b[5] = d0 * r[3] * r[6] + d1 * r[4] * r[7] + d2 * r[5] * r[8];
        }
        for (int k = 0; k < 3; ++k) {
            p0(i, k) = linear_momentum(i, k);
            l0(i, k) = angular_momentum(i, k);
            bv(i, k) = linear_momentum(i, k) * im;
            bv0(i, k) = bv(i, k);
            pv(i, k) = 0.0;
            pw(i, k) = 0.0;
        }
        double wx, wy, wz;
        smul(b, l0(i, 0), l0(i, 1), l0(i, 2), wx, wy, wz);
        bw(i, 0) = wx; bw(i, 1) = wy; bw(i, 2) = wz;
        bw0(i, 0) = wx; bw0(i, 1) = wy; bw0(i, 2) = wz;
    }
    // the static dummy: reset every step so that a bad value can never stick to it
    i64 s = n_dyn;
    bm[s] = 0.0;
    for (int k = 0; k < 3; ++k) {
        bv(s, k) = 0.0;
        bw(s, k) = 0.0;
        bv0(s, k) = 0.0;
        bw0(s, k) = 0.0;
        pv(s, k) = 0.0;
        pw(s, k) = 0.0;
    }
    for (int k = 0; k < 6; ++k) bI(s, k) = 0.0;
}

// Effective masses, and the gap velocity before the step (for restitution).
void prepare_contacts(const StepContext& cx, const ContactConstraints& c, const SolverBodies& b) {
    const Settings& cfg = cx.settings;
    const double h = cx.h;
    for (i64 m = 0; m < c.n_man; ++m) {
        if (!c.mi[m].active) continue;
        i64 ia = c.mi[m].a, ib = c.mi[m].b;
        BodyPair bp(b, ia, ib);
        const double mab = bp.ma + bp.mb;  // (the first sum of every K entry below)
        double nx = c.mf[m].normal[0], ny = c.mf[m].normal[1], nz = c.mf[m].normal[2];
        double t1x = c.mf[m].t1[0], t1y = c.mf[m].t1[1], t1z = c.mf[m].t1[2];
        double t2x = c.mf[m].t2[0], t2y = c.mf[m].t2[1], t2z = c.mf[m].t2[2];
        double acc = c.mf[m].acc;
        i64 start = c.mi[m].start;
        i64 cnt = c.mi[m].count;
        // normal block K_ij = J_i M^-1 J_j^T of the manifold's points (r x n of each point and
        // I^-1 (r x n) once per point, then the products; a manifold has at most 4 points)
        double ca[4][3], cb[4][3], jna[4][3], jnb[4][3];
        for (i64 i = 0; i < cnt; ++i) {
            i64 p = start + i;
            cross(c.pf[p].ra[0], c.pf[p].ra[1], c.pf[p].ra[2], nx, ny, nz, ca[i][0],
                  ca[i][1], ca[i][2]);
            cross(c.pf[p].rb[0], c.pf[p].rb[1], c.pf[p].rb[2], nx, ny, nz, cb[i][0],
                  cb[i][1], cb[i][2]);
            smul(bp.a6, ca[i][0], ca[i][1], ca[i][2], jna[i][0], jna[i][1], jna[i][2]);
            smul(bp.b6, cb[i][0], cb[i][1], cb[i][2], jnb[i][0], jnb[i][1], jnb[i][2]);
        }
        for (i64 i = 0; i < cnt; ++i) {
            ContactPoint& q_ = c.pf[start + i];
            for (i64 j = 0; j < cnt; ++j)
                q_.kn[j] = (mab + ca[j][0] * jna[i][0] + ca[j][1] * jna[i][1] +
                                 ca[j][2] * jna[i][2] + cb[j][0] * jnb[i][0] +
                                 cb[j][1] * jnb[i][1] + cb[j][2] * jnb[i][2]);
        }
        if (cnt > 1) factor_block(c.mf, m, c.pf, start, cnt, cfg.block_reg);
        for (i64 p = start; p < start + cnt; ++p) {
            double rax = c.pf[p].ra[0], ray = c.pf[p].ra[1], raz = c.pf[p].ra[2];
            double rbx = c.pf[p].rb[0], rby = c.pf[p].rb[1], rbz = c.pf[p].rb[2];
            // normal row: K_pp, the block's diagonal (the same products in the same order)
            double k = c.pf[p].kn[(p - start)];
            c.pf[p].normal_mass = k > 0.0 ? 1.0 / k : 0.0;
            // tangent block
            double ua1x, ua1y, ua1z, ua2x, ua2y, ua2z, ub1x, ub1y, ub1z, ub2x, ub2y, ub2z;
            cross(rax, ray, raz, t1x, t1y, t1z, ua1x, ua1y, ua1z);
            cross(rax, ray, raz, t2x, t2y, t2z, ua2x, ua2y, ua2z);
            cross(rbx, rby, rbz, t1x, t1y, t1z, ub1x, ub1y, ub1z);
            cross(rbx, rby, rbz, t2x, t2y, t2z, ub2x, ub2y, ub2z);
            double ia1x, ia1y, ia1z, ia2x, ia2y, ia2z, ib1x, ib1y, ib1z, ib2x, ib2y, ib2z;
            smul(bp.a6, ua1x, ua1y, ua1z, ia1x, ia1y, ia1z);
            smul(bp.a6, ua2x, ua2y, ua2z, ia2x, ia2y, ia2z);
            smul(bp.b6, ub1x, ub1y, ub1z, ib1x, ib1y, ib1z);
            smul(bp.b6, ub2x, ub2y, ub2z, ib2x, ib2y, ib2z);
            double k11 = mab + ua1x * ia1x + ua1y * ia1y + ua1z * ia1z + ub1x * ib1x +
                         ub1y * ib1y + ub1z * ib1z;
            double k22 = mab + ua2x * ia2x + ua2y * ia2y + ua2z * ia2z + ub2x * ib2x +
                         ub2y * ib2y + ub2z * ib2z;
            double k12 = ua1x * ia2x + ua1y * ia2y + ua1z * ia2z + ub1x * ib2x + ub1y * ib2y +
                         ub1z * ib2z;
            c.pf[p].tangent_k[0] = k11;
            c.pf[p].tangent_k[1] = k12;
            c.pf[p].tangent_k[2] = k22;
            // friction anchor: the slip rate that takes back FRICTION_ANCHOR_RATE of the drift
            double dx = c.pf[p].slip[0], dy = c.pf[p].slip[1], dz = c.pf[p].slip[2];
            c.pf[p].slip_bias[0] = cfg.friction_anchor_rate * (dx * t1x + dy * t1y + dz * t1z) / h;
            c.pf[p].slip_bias[1] = cfg.friction_anchor_rate * (dx * t2x + dy * t2y + dz * t2z) / h;
            // gap velocity now (after the force kick), and before the kick
            double wxrax, wxray, wxraz, wxrbx, wxrby, wxrbz;
            cross(bp.wa[0], bp.wa[1], bp.wa[2], rax, ray, raz, wxrax, wxray, wxraz);
            cross(bp.wb[0], bp.wb[1], bp.wb[2], rbx, rby, rbz, wxrbx, wxrby, wxrbz);
            double vn = (nx * (bp.va[0] + wxrax - bp.vb[0] - wxrbx) +
                         ny * (bp.va[1] + wxray - bp.vb[1] - wxrby) +
                         nz * (bp.va[2] + wxraz - bp.vb[2] - wxrbz));
            c.pf[p].w0 = vn - acc * h;
            c.pf[p].lp = 0.0;
            c.pf[p].impact = 0.0;
        }
    }
}

// Apply each active point's stored impulse (normal, t1, t2 components at lam + lam_stride p) to
// its manifold's bodies: the velocity solve's warm start (the impulses carried over from the
// previous step, pf[p].ln, l1, l2) and the soft step's (the last substep's).
void apply_stored_impulses(const ContactConstraints& c, const SolverBodies& b, const double* lam,
                           i64 lam_stride) {
    for (i64 m = 0; m < c.n_man; ++m) {
        if (!c.mi[m].active) continue;
        i64 ia = c.mi[m].a, ib = c.mi[m].b;
        BodyPair bp(b, ia, ib);
        double nx = c.mf[m].normal[0], ny = c.mf[m].normal[1], nz = c.mf[m].normal[2];
        double t1x = c.mf[m].t1[0], t1y = c.mf[m].t1[1], t1z = c.mf[m].t1[2];
        double t2x = c.mf[m].t2[0], t2y = c.mf[m].t2[1], t2z = c.mf[m].t2[2];
        i64 start = c.mi[m].start;
        for (i64 p = start; p < start + c.mi[m].count; ++p) {
            const double* l = lam + lam_stride * p;
            double ln = l[0], l1 = l[1], l2 = l[2];
            if (ln == 0.0 && l1 == 0.0 && l2 == 0.0) continue;
            double px = ln * nx + l1 * t1x + l2 * t2x;
            double py = ln * ny + l1 * t1y + l2 * t2y;
            double pz = ln * nz + l1 * t1z + l2 * t2z;
            const ContactPoint& q = c.pf[p];
            bp.apply(q.ra[0], q.ra[1], q.ra[2], q.rb[0], q.rb[1], q.rb[2], px,
                     py, pz);
        }
        bp.store(b);
    }
}

// Apply the impulses carried over from the previous step (a point's ln, l1, l2: adjacent).
void warm_start(const ContactConstraints& c, const SolverBodies& b) {
    constexpr size_t ln_at = offsetof(ContactPoint, ln), d = sizeof(double);
    static_assert(offsetof(ContactPoint, l1) == ln_at + d &&
                      offsetof(ContactPoint, l2) == ln_at + 2 * d,
                  "warm start reads three adjacent fields");
    apply_stored_impulses(c, b, &c.pf.p[0].ln, PF_COLS);
}

// Sequential impulses: per manifold, the normal rows, then friction (Box2D v3 order), the
// manifolds in the order of the constraint graph's colouring (constraint_graph.hpp): the
// overflow set one manifold after another, then each colour, whose manifolds share no dynamic
// body and are solved four at a time in the lanes of a vector, in pack_lanes' order (by the
// last solve's hot marks: contact_lanes.hpp; the kernel's
// formulas are the ones of the scalar code above and below: solve_group in contact_lanes.inl).
//
// Sweeps at least velocity_iterations times, then until the largest velocity change a sweep makes
// at any point is below velocity_tolerance (m/s), at most max_velocity_iterations sweeps. Past
// velocity_iterations a sweep visits only manifolds with a body that a previous sweep changed by
// more than velocity_tolerance (hot: (N+1,) last sweep that did), so settled regions of a pile
// cost nothing while an unsettled one converges. Returns the number of manifold visits divided by
// the manifolds (full-sweep equivalents, at least 1).
//
// Successive over-relaxation (ODE's quickstep; projected SOR converges for 0 < over_relaxation < 2
// on the normal rows, Cryer 1971): the normal impulse increment of a manifold is scaled by
// over_relaxation before the clamp when one of its dynamic bodies touches something else
// (degree: (N+1,) active manifolds per body). Plain Gauss-Seidel moves a load through a chain of
// n bodies in ~n^2 sweeps, over-relaxed in ~n. A manifold whose bodies touch nothing else is
// solved exactly by one update, so it is not relaxed (that would only make it oscillate).
//
// Nothing in a sweep depends on the order of the manifolds inside a colour (each reads and
// writes only its own bodies' velocities and hot marks; the largest change is a max and the
// visits a sum), so the result is the same whichever lanes and threads solve them.
i64 solve_velocities(const StepContext& ctx, const ContactConstraints& c,
                     const SolverBodies& bodies, V1<i64> hot, V1<i64> degree,
                     const ConstraintGraph& g, SolverLanes& lanes) {
    const Settings& cfg = ctx.settings;
    const double inv_h = ctx.inv_h;
    i64 active = 0;
    for (i64 m = 0; m < c.n_man; ++m) active += c.mi[m].active;
    // (hot still holds the last solve's marks: pack_lanes orders the colours' lanes by them)
    pack_lanes(c.mi, c.mf, c.pf, g, bodies.inv_mass, bodies.inv_inertia, degree, hot, inv_h,
               cfg.over_relaxation, lanes);
    for (i64 k = 0; k < hot.n0; ++k) hot[k] = 0;
    // the velocities in the kernels' layout (contact_lanes.hpp: BodyVel) while the sweeps run
    const i64 n_rows = bodies.inv_mass.n0;
    lanes.vel.resize(n_rows);
    for (i64 i = 0; i < n_rows; ++i) {
        BodyVel& b = lanes.vel[i];
        for (int k = 0; k < 3; ++k) {
            b.v[k] = bodies.v(i, k);
            b.w[k] = bodies.w(i, k);
        }
        b.v[3] = 0.0;
        b.w[3] = 0.0;
    }
    LaneCtx cx{reinterpret_cast<double*>(lanes.vel.data()), hot.p, bodies.inv_mass.n0 - 1, 0,
               cfg.velocity_iterations, cfg.velocity_tolerance, cfg.friction_newton_iters,
               cfg.friction_newton_tol, 1.0 + cfg.friction_newton_tol};
    WideGroup* gr = lanes.groups.data();
    // the sweeps, on the task pool or on this thread (solve_stages.hpp): a set's groups
    // [g0, g1) in sweep `sweep` (set 0, the overflow set, one manifold after another)
    const i64 n_sets = (i64)lanes.set_group.size() - 1;
    const SweepCount sw = run_sweeps(
        SweepPlan{n_sets, lanes.set_group.data(), cfg.velocity_iterations,
                  cfg.max_velocity_iterations, cfg.velocity_tolerance},
        [&](i64 sweep, i64 s, i64 g0, i64 g1, double* change, i64* vis) {
            LaneCtx tc = cx;
            tc.it = sweep;
            if (s == 0)
                solve_groups_scalar(gr, g0, g1, tc, change, vis);
            else
                solve_groups_wide(gr, g0, g1, tc, change, vis);
        });
    const i64 visits = sw.visits;
    unpack_lanes(c.mi, c.pf, lanes);
    for (i64 i = 0; i < n_rows; ++i) {
        const BodyVel& b = lanes.vel[i];
        for (int k = 0; k < 3; ++k) {
            bodies.v(i, k) = b.v[k];
            bodies.w(i, k) = b.w[k];
        }
    }
    i64 den = active > 1 ? active : 1;
    i64 r = (visits + active - 1) / den;
    return r > 1 ? r : 1;
}

// The anchor pass (after the velocity solve, before relax): one Gauss-Seidel sweep of the
// friction rows of loaded points with the anchors' targets (slip rate -FRICTION_ANCHOR_RATE D /
// h, clamped to the Coulomb disc; see "Friction anchor" above). It runs once per step, outside
// the solve's convergence loop, so the bias never keeps the solve's sweeps going; the anchor
// closes the loop over steps (what one sweep leaves of the target is still in D next step).
void anchor_friction(const StepContext& cx, const ContactConstraints& c, const SolverBodies& b) {
    const Settings& cfg = cx.settings;
    for (i64 m = 0; m < c.n_man; ++m) {
        if (!c.mi[m].active) continue;
        double mu = c.mf[m].mu;
        if (mu <= 0.0) continue;
        i64 start = c.mi[m].start;
        i64 end = start + c.mi[m].count;
        bool loaded = false;
        for (i64 p = start; p < end; ++p)
            if (c.pf[p].ln > 0.0) loaded = true;
        if (!loaded) continue;
        i64 ia = c.mi[m].a, ib = c.mi[m].b;
        BodyPair bp(b, ia, ib);
        double t1x = c.mf[m].t1[0], t1y = c.mf[m].t1[1], t1z = c.mf[m].t1[2];
        double t2x = c.mf[m].t2[0], t2y = c.mf[m].t2[1], t2z = c.mf[m].t2[2];
        for (i64 p = start; p < end; ++p) {
            ContactPoint& q = c.pf[p];
            if (q.ln <= 0.0) continue;
            double rax = q.ra[0], ray = q.ra[1], raz = q.ra[2];
            double rbx = q.rb[0], rby = q.rb[1], rbz = q.rb[2];
            double dvx, dvy, dvz;
            bp.relative_velocity(rax, ray, raz, rbx, rby, rbz, dvx, dvy, dvz);
            // slip relative to the anchor's target rate -D rate / h
            double vt1 = dvx * t1x + dvy * t1y + dvz * t1z + q.slip_bias[0];
            double vt2 = dvx * t2x + dvy * t2y + dvz * t2z + q.slip_bias[1];
            double k11 = q.tangent_k[0], k12 = q.tangent_k[1], k22 = q.tangent_k[2];
            double o1 = q.l1, o2 = q.l2;
            double n1, n2;
            friction_impulse(k11, k12, k22, o1, o2, vt1, vt2, mu * q.ln, cfg.friction_newton_iters,
                             cfg.friction_newton_tol, n1, n2);
            q.l1 = n1;
            q.l2 = n2;
            double d1 = n1 - o1;
            double d2 = n2 - o2;
            double px = d1 * t1x + d2 * t2x;
            double py = d1 * t1y + d2 * t2y;
            double pz = d1 * t1z + d2 * t2z;
            bp.apply(rax, ray, raz, rbx, rby, rbz, px, py, pz);
        }
        bp.store(b);
    }
}

// Friction impulses as world vectors, so the next step can project them on its tangents; a
// manifold keeps its friction anchor while some loaded point sticks (friction strictly inside its
// cone; see "Friction anchor" above): an impact, or a manifold none of whose points sticks, drops
// it, and the next step's collide anchors the pair anew where it then is. (A point at its cone
// while others stick just gives what the cone allows; a pair that slides drifts beyond
// FRICTION_ANCHOR_MAX_DRIFT_M and collide re-anchors it.)
void store_impulses(const StepContext& cx, const ContactConstraints& c) {
    const Settings& cfg = cx.settings;
    for (i64 m = 0; m < c.n_man; ++m) {
        if (!c.mi[m].active) continue;
        double t1x = c.mf[m].t1[0], t1y = c.mf[m].t1[1], t1z = c.mf[m].t1[2];
        double t2x = c.mf[m].t2[0], t2y = c.mf[m].t2[1], t2z = c.mf[m].t2[2];
        double mu = c.mf[m].mu;
        i64 start = c.mi[m].start;
        i64 cnt = c.mi[m].count;
        bool stick = false;
        bool struck = false;
        for (i64 p = start; p < start + cnt; ++p) {
            ContactPoint& q = c.pf[p];
            double l1 = q.l1, l2 = q.l2;
            q.friction[0] = l1 * t1x + l2 * t2x;
            q.friction[1] = l1 * t1y + l2 * t2y;
            q.friction[2] = l1 * t1z + l2 * t2z;
            if (q.impact != 0.0) {
                struck = true;
            } else if (point_sticks(l1, l2, mu, q.ln, cfg.friction_anchor_slide_frac)) {
                stick = true;
            }
        }
        if (struck || !stick) c.mf[m].anchor_ok = 0.0;
    }
}

}  // namespace rb
