// The compiled world step with contacts: many steps per call, no Python between steps.
//
// One step of ``dt`` (``h``) reads as a flat list of stages (Box2D v3's ``b2World_Step`` and
// ``b2SolverStage``; Brax's ``pipeline.step``)::
//
//     1  kick             P += h (m g + F), L += h tau              (awake bodies; skipped w/o forces)
//     2  broadphase       swept AABBs, sort-and-sweep, ground pairs  (broadphase.py)
//     3  wake             sleeping islands an awake body may touch   (island.py)
//     4  collide          narrowphase table -> manifolds, warm-start matching, sleeping carried
//     4b colour           the constraint graph's colours: sets of manifolds that share no
//                         dynamic body (constraint_graph.hpp), the order the solve sweeps in
//     5  prepare          effective masses, pre-solve gap velocities (contact_solver.cpp)
//     6  warm start       apply last step's impulses
//     7  solve            sequential impulses, Coulomb friction, speculative targets; then one
//                         sweep of the friction rows toward their anchors (solver.anchor_friction, when
//                         ContactParams.static_friction_anchors is on)
//     8  relax            split-impulse position correction on pseudo velocities (relax.cpp; the shift's
//                         orbital angular momentum h v' x P is handed back to the spin)
//     9  integrate        a body the solve and relax pushed: x += h (v + v') along its contact
//                         normals, as under constant acceleration off them (see Translation
//                         below), momenta P, L rebuilt
//                         from the solver's velocity changes; every other body flies exactly under
//                         its constant force, x += h v - h^2 a / 2 (v after the kick). Rotation by
//                         integrators.drift_rotation with the run's integrator (the body's L and its
//                         current R, so gyroscopic motion is the integrator's own)
//     10 restitution      bounce impact points (energy-consistent rule, restitution.cpp), P += J,
//                         L += r x J
//     11 store impulses   friction as world vectors for the next step
//     12 project          narrowphase again at the end-of-step poses; points deeper than
//                         projection_depth are pushed out by nonlinear Gauss-Seidel on positions
//                         and orientations (project.py); the shift's orbital angular momentum
//                         dx x P is handed back to the spin, as in 8
//     13 sleep            rest timers, islands, put resting islands to sleep (island.py)
//     1b/14 impulses      the contact stages' momentum change per body, summed per sample
//                         interval (impulses.cpp; the log's impulse_contact_*)
//
// With ContactParams.solver = "soft_step", stages 6-8 are Box2D v3's substeps instead
// (soft_step.cpp: per substep a share of the kick, warm start, soft solve, positions, relax;
// no anchor pass, no split-impulse relax stage), and stage 9 moves the bodies by the substeps'
// displacement (step::soft_stages).
//
// Translation (stage 9; mark_pushed sorts the bodies after the solve). A body that no contact
// pushes in a step (no manifold, or only manifolds whose accumulated impulses all ended at zero: a
// speculative contact that was not reached, a pair moving apart) moves exactly under its constant
// acceleration a = g + F/m: with v the velocity after the kick, x += h v - h^2 a / 2 =
// h v_start + h^2 a / 2, so free flight lies on the parabola to round-off in every scene, as in
// the free-body kernel. A body that contacts push moves with its solved velocity, x += h (v + v')
// (v' the relax stage's pseudo velocity), since the velocity solve predicts every gap at the end
// of the step as s + h w (w the solved gap rate):
//
// * in an island of pushing contacts that touches static geometry (the ground, a static box, a
//   sleeping body), exactly that along its contact normals, so that the solver's gaps hold and
//   v = 0 means still (the exact flight's term would lift a resting body by |g| h^2 / 2 each step,
//   and the solver would answer with a downward velocity |g| h / 2 at rest), and off them as under
//   a constant acceleration: x += h (v + v') - phi h P (v - v_start) / 2, P the projection off the
//   span of the body's pushing contact normals, v_start its velocity before the kick, phi = 1
//   (h (v_start + v) / 2 off the normals: a sliding box's or a rolling ball's motion to round-off),
//   or t_stop / h when a point slid at the step's start and the body stopped inside the step (the
//   closed form of a stop: decelerating until t_stop, then still). Its turn likewise, by
//   h (w - phi Q (w - w_start) / 2), Q off the span of r x n over its points (gather_supports,
//   support_correction); a body that touches another dynamic body or that a pair holds on a
//   carried friction anchor moves by symplectic Euler only;
// * in an island away from static geometry (bodies colliding in the air), by that plus the exact
//   flight's - h^2 a / 2, the same term a free body gets: under uniform gravity it moves the whole
//   island alike, so the gaps the solver predicted inside it hold, and every body of a group that
//   only pushes itself flies by one scheme. Mixing symplectic and exact bodies in such a group
//   would change its angular momentum about its centre of mass by O(h^2 |g| |P|) a step (5.6e-6
//   relative on samples/mixed.toml; both schemes alone keep it exactly).
//
// The restitution stage measures and sets bounce speeds with the exact flight's energy
// (restitution.cpp), so a bounce between exact flights keeps apexes at e^(2n) h0. Torques are
// applied as kicks.
//
// Samples follow free.advance_free: after every ``stride``-th step and after the last step when
// ``sample_last``; a non-finite state stops the call and reports the first bad local step and body.
//
// Here each stage is a function (namespace rb::step) and world_advance calls them in the order
// above, reading the profile clock after each when profiled (profile.hpp). What the step keeps
// between calls (the previous step's manifolds, the pair buffer, the log, the work arrays) lives
// in the ContactCache (records.hpp): nothing is allocated in a step once the buffers have grown
// to the scene's size.

#include <algorithm>
#include <cmath>

#include "common/task_pool.hpp"
#include "engine/contact_solver.hpp"
#include "engine/impulses.hpp"
#include "engine/integrators.hpp"
#include "engine/profile.hpp"
#include "engine/project.hpp"
#include "engine/rotation.hpp"
#include "engine/soft_step.hpp"
#include "engine/world_step.hpp"

namespace rb {

TaskPool& pool();  // the engine's pool (threads.cpp)

namespace {

// Items per block when a stage's loop over bodies or manifolds is split over the task pool, and
// the fewest items worth a hand-off (a body's integration costs ~1,200 instructions, a
// manifold's preparation ~3,500: below a few hundred items, ~100 us, the scene is small and
// the caller's thread does the loop alone).
constexpr i64 BODIES_PER_BLOCK = 128;
constexpr i64 MANIFOLDS_PER_BLOCK = 64;
constexpr i64 MIN_ITEMS = 256;

// fn(i0, i1) over [0, n) cut in blocks of about per_block items, the blocks on the task pool
// (one block, on the caller, with one thread or a small n). For loops whose items write only
// their own rows: the result is the serial loop's whatever the threads.
template <class F>
void par_ranges(i64 n, i64 per_block, const F& fn) {
    const i64 nb = pool().threads() > 1 ? TaskPool::blocks_for(n, per_block, MIN_ITEMS) : 1;
    if (nb <= 1) {
        fn(i64(0), n);
        return;
    }
    pool().run(nb, [&](i64 b, int) { fn(n * b / nb, n * (b + 1) / nb); });
}

// Rows [r0, r1) of a (M, C) view.
template <class T>
V2<T> rows(V2<T> v, i64 r0, i64 r1) {
    return V2<T>{v.p + r0 * v.n1, r1 - r0, v.n1};
}

template <class T>
void zeroed(Buf2<T>& b, i64 rows, i64 cols) {
    if (b.rows != rows || b.cols != cols) {
        b = Buf2<T>(rows, cols);
    } else {
        std::fill(b.data.begin(), b.data.end(), T(0));
    }
}

// P = P0 + m (v - v0), L = L0 + I_world (w - w0): momenta change only by what the solver applied
// (exactly not at all without impulses).
inline void store_momenta(i64 i, const Bodies& bd, V3<double> rotation,
                          V2<double> linear_momentum, V2<double> angular_momentum, V2<double> bv,
                          V2<double> bw, V2<double> bv0, V2<double> bw0, V2<double> p0,
                          V2<double> l0, bool iso_shortcut) {
    double m = 1.0 / bd.inv_mass[i];
    for (int k = 0; k < 3; ++k) linear_momentum(i, k) = p0(i, k) + m * (bv(i, k) - bv0(i, k));
    double dx = bw(i, 0) - bw0(i, 0), dy = bw(i, 1) - bw0(i, 1), dz = bw(i, 2) - bw0(i, 2);
    double lx, ly, lz;
    if (iso_shortcut && bd.iso[i]) {
        double s = bd.inertia(i, 0);
        lx = s * dx; ly = s * dy; lz = s * dz;
    } else {
        // R diag(I_body) R^T (x, y, z) (rotation.omega_world with the inertia for its inverse)
        Vec3 l = omega_world(load_mat(rotation, i), bd.inertia(i, 0), bd.inertia(i, 1),
                             bd.inertia(i, 2), dx, dy, dz);
        lx = l[0]; ly = l[1]; lz = l[2];
    }
    angular_momentum(i, 0) = l0(i, 0) + lx;
    angular_momentum(i, 1) = l0(i, 1) + ly;
    angular_momentum(i, 2) = l0(i, 2) + lz;
}

// Orthonormal rows basis[0 .. 3 count) of a span in R^3 (count <= 3): add v when its part off the
// span is longer than SPAN_RTOL sqrt(scale2) (Gram-Schmidt). SPAN_RTOL is a geometric epsilon of the
// test, not an engine tolerance: a sphere's r x n is round-off (~1e-17 r) and adds nothing, two
// contact normals 1e-9 rad apart count as one (the part dropped then is 1e-9 of the correction).
constexpr double SPAN_RTOL = 1e-9;
// m: a friction anchor whose drift D is below this at every point of its manifold was taken at
// this step's start (a fresh anchor's D is the round-off of the pose transforms, ~1e-16 m; a
// carried one holds the solve's leftover slip, ~h velocity_tolerance = 1e-7 m)
constexpr double FRESH_ANCHOR_M = 1e-12;
inline void span_add(double* basis, double& count, const double* v, double scale2) {
    int c = int(count);
    if (c >= 3) return;
    double u[3] = {v[0], v[1], v[2]};
    for (int j = 0; j < c; ++j) {
        const double* e = basis + 3 * j;
        double d = u[0] * e[0] + u[1] * e[1] + u[2] * e[2];
        for (int k = 0; k < 3; ++k) u[k] -= d * e[k];
    }
    double l2 = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    if (!(l2 > SPAN_RTOL * SPAN_RTOL * scale2)) return;
    double l = std::sqrt(l2);
    for (int k = 0; k < 3; ++k) basis[3 * c + k] = u[k] / l;
    count = double(c + 1);
}

// v minus its part in the span of basis[0 .. 3 count) (orthonormal rows): 0 when it spans R^3.
inline void off_span(const double* basis, double count, double* v) {
    int c = int(count);
    if (c >= 3) {
        v[0] = v[1] = v[2] = 0.0;
        return;
    }
    for (int j = 0; j < c; ++j) {
        const double* e = basis + 3 * j;
        double d = v[0] * e[0] + v[1] * e[1] + v[2] * e[2];
        for (int k = 0; k < 3; ++k) v[k] -= d * e[k];
    }
}

// A symmetric 3x3 (xx, yy, zz, xy, xz, yz) times (x, y, z).
inline void smul6(const double* s, double x, double y, double z, double& ox, double& oy,
                  double& oz) {
    ox = s[0] * x + s[3] * y + s[4] * z;
    oy = s[3] * x + s[1] * y + s[5] * z;
    oz = s[4] * x + s[5] * y + s[2] * z;
}

// Manifold m pushed this step: one of its accumulated normal, friction or pseudo impulses ended
// nonzero.
inline bool manifold_pushed(V2<i64> mi, V2<double> pf, i64 m) {
    i64 start = mi(m, MI_START);
    for (i64 p = start; p < start + mi(m, MI_COUNT); ++p)
        if (pf(p, PF_LN) != 0.0 || pf(p, PF_L1) != 0.0 || pf(p, PF_L2) != 0.0 ||
            pf(p, PF_LP) != 0.0)
            return true;
    return false;
}

// One sum that is non-finite when any of the body's state is (position, momenta, R).
inline double state_sum(i64 i, V2<double> position, V2<double> linear_momentum,
                        V2<double> angular_momentum, V3<double> rotation) {
    return (position(i, 0) + position(i, 1) + position(i, 2) + linear_momentum(i, 0) +
            linear_momentum(i, 1) + linear_momentum(i, 2) + angular_momentum(i, 0) +
            angular_momentum(i, 1) + angular_momentum(i, 2) + rotation(i, 0, 0) +
            rotation(i, 1, 1) + rotation(i, 2, 2) + rotation(i, 0, 1));
}

}  // namespace

// ---- the records kept between calls -----------------------------------------------------------

void Scratch::make(i64 n_bodies, const Statics& st) {
    i64 n1 = n_bodies + 1, nn = n_bodies + st.n_static;
    n = n_bodies;
    ns = st.n_static;
    zeroed(lo, nn, 3);
    zeroed(hi, nn, 3);
    for (i64 k = 0; k < ns; ++k)
        for (int c = 0; c < 3; ++c) {
            lo(n + k, c) = st.lo(k, c);
            hi(n + k, c) = st.hi(k, c);
        }
    zeroed(reach, nn, 1);
    zeroed(in_contact, n1, 1);
    zeroed(bm, n1, 1);
    zeroed(bI, n1, 6);
    zeroed(bv, n1, 3);
    zeroed(bw, n1, 3);
    zeroed(bv0, n1, 3);
    zeroed(bw0, n1, 3);
    zeroed(pv, n1, 3);
    zeroed(pw, n1, 3);
    zeroed(p0, n, 3);
    zeroed(l0, n, 3);
    zeroed(l_drift, n, 3);
    zeroed(parent, n, 1);
    zeroed(isl_time, n, 1);
    zeroed(isl_sup, n, 1);
    cb = collider_buffers();
    zeroed(hot, n1, 1);
    zeroed(dx_step, n1, 3);
    zeroed(proj_dx, n1, 3);
    zeroed(proj_dth, n1, 3);
    zeroed(pushed, n1, 1);
    zeroed(push_root, n1, 1);
    zeroed(support, n1, SUP_COLS);
    if (flow_c.rows != n || flow_c.cols != N_FLOW) flow_c = Buf2<double>(n, N_FLOW);
    flow_ok.resize(n);
    zeroed(ring, n1, 1);
    if (proj_rows.cols != PROJ_COLS) {
        proj_rows = Buf2<double>(64, PROJ_COLS);
        proj_ids = Buf2<i64>(64, 2);
    }
}

ContactCache::ContactCache(i64 cap_manifolds, i64 cap_points)
    : mi0(cap_manifolds, MI_COLS), mf0(cap_manifolds, MF_COLS), pf0(cap_points, PF_COLS),
      pid0(cap_points, 1), keys0(1, 1), idx0(1, 1), mi1(cap_manifolds, MI_COLS),
      mf1(cap_manifolds, MF_COLS), pf1(cap_points, PF_COLS), pid1(cap_points, 1),
      pairs(cap_manifolds, 2), log_i(64, LOG_I_COLS), log_f(64, LOG_F_COLS) {}

// ---- the stages, in step order ------------------------------------------------------------------

namespace step {

// 1 kick: P += h (m g + F), L += h tau for awake bodies (world frame).
void kick(const Bodies& bd, V1<i64> awake, const BodyState& x, double h) {
    for (i64 i = 0; i < x.position.n0; ++i) {
        if (awake[i]) {
            for (int k = 0; k < 3; ++k) {
                x.linear_momentum(i, k) += h * bd.force(i, k);
                x.angular_momentum(i, k) += h * bd.torque(i, k);
            }
        }
    }
}

// 2 broadphase: AABBs (of awake bodies swept over the step, padded by margin), sort-and-sweep,
// and (body, ground) pairs into `pairs` (grown in place). Returns n_pairs.
i64 broadphase(const Bodies& bd, const Statics& st, double margin, V1<i64> awake,
               const BodyState& x, double h, Scratch& sc, Buf2<i64>& pairs) {
    i64 n = x.position.n0;
    body_aabbs(bd.geom, bd.size, bd.radius, bd.inv_mass, bd.inv_inertia, awake, x.position,
               x.linear_momentum, x.rotation, x.angular_momentum, h, margin, sc.lo.view(),
               sc.hi.view(), col(sc.reach));
    i64 n_pairs = sweep_and_prune(n + st.n_static, n, sc.lo.view(), sc.hi.view(), bd.group,
                                  awake, pairs);
    if (st.ground)
        n_pairs = ground_pairs(n, st.n_static, st.gn, st.goff, sc.lo.view(), sc.hi.view(), pairs,
                               n_pairs);
    return n_pairs;
}

// 3 wake: sleeping islands that an awake body may touch within the step. Returns islands woken.
i64 wake(const Bodies& bd, const Statics& st, const Settings& cfg, const SleepState& sl,
         const BodyState& x, double h, Scratch& sc, V2<i64> pairs, i64 n_pairs) {
    return wake_touched(pairs, n_pairs, x.position.n0, st.n_static, bd.geom, bd.size, sl.awake,
                        sl.timer, sl.island_of, x.position, x.rotation, col(sc.reach), cfg.speculative_distance,
                        cfg.allowed_penetration, st.pos, st.rot, st.ext, st.gn, st.goff, x.linear_momentum,
                        x.angular_momentum, bd.force, bd.torque, h, cfg.do_kick, sc.cb,
                        bd.inv_mass, bd.accel, bd.radius, bd.inv_inertia);
}

// 4 collide: the narrowphase table over the candidate pairs into this step's buffers (c.mi1,
// ...), matching last step's manifolds (c.mi0, ...) for warm starting. Returns (n_man, n_pts);
// the buffers may have grown.
CollideCount collide(const Bodies& bd, const Statics& st, const Settings& cfg, V1<i64> awake,
                     const BodyState& x, Scratch& sc, V2<i64> pairs, i64 n_pairs,
                     ContactCache& c) {
    grow_manifolds(c.mi1, c.mf1, 2 * n_pairs);
    grow_points(c.pf1, c.pid1, 8 * n_pairs);
    return collide_pairs(pairs, n_pairs, x.position.n0, st.n_static, bd.geom, bd.size, awake,
                         x.position, x.rotation, col(sc.reach), cfg.speculative_distance, bd.restitution,
                         bd.friction, bd.accel, st.pos, st.rot, st.ext, st.e, st.mu, st.gn,
                         st.goff, st.g_e, st.g_mu, c.mi0.view(), c.mf0.view(), c.pf0.view(),
                         col(c.pid0), col(c.keys0), col(c.idx0), c.n_man0, c.mi1.view(),
                         c.mf1.view(), c.pf1.view(), col(c.pid1), cfg.warm_starting, cfg.friction_anchor_distance, sc.cb);
}

// 5 prepare: load the bodies in contact into the solver arrays; effective masses and pre-solve
// gap velocities of every point.
void prepare(const Bodies& bd, const Settings& cfg, const BodyState& x, Scratch& sc, V2<i64> mi,
             V2<double> mf, V2<double> pf, i64 n_man, double h) {
    load_bodies(mi, n_man, x.position.n0, cfg.iso_shortcut, bd.iso, bd.inv_mass, bd.inv_inertia,
                x.rotation, x.linear_momentum, x.angular_momentum, col(sc.in_contact),
                col(sc.bm), sc.bI.view(), sc.bv.view(), sc.bw.view(), sc.bv0.view(),
                sc.bw0.view(), sc.pv.view(), sc.pw.view(), sc.p0.view(), sc.l0.view());
    // a manifold's preparation writes only its own rows (mf, its points' pf): blocks of
    // manifolds on the pool (pf stays whole: a manifold's MI_START indexes it)
    const StepContext ctx{h, 1.0 / h, cfg};
    const SolverBodies b{col(sc.bm), sc.bI.view(), sc.bv.view(), sc.bw.view()};
    par_ranges(n_man, MANIFOLDS_PER_BLOCK, [&](i64 m0, i64 m1) {
        prepare_contacts(ctx, ContactConstraints{rows(mi, m0, m1), rows(mf, m0, m1), pf, m1 - m0},
                         b);
    });
}

// Sort the awake bodies by how they move this step (sc.pushed, read by stage 9):
//
// * 0: no contact pushed it (no manifold, or manifolds whose accumulated normal, friction and
//   pseudo impulses all ended at zero): it flies exactly;
// * 1: pushed, within a group of bodies that pushing contacts connect (an island of this step)
//   that touches no static geometry: it moves by the solver's velocity plus the same
//   exact-flight term as a free body, so that every body away from static geometry flies alike
//   (one scheme inside any group of bodies that only push each other);
// * 2: pushed, in an island that some static contact pushes: symplectic Euler (resting contact).
void mark_pushed(V2<i64> mi, V2<double> pf, i64 n_man, i64 n, Scratch& sc) {
    V1<i64> pushed = col(sc.pushed), root = col(sc.push_root);
    for (i64 i = 0; i < n + 1; ++i) {
        pushed[i] = 0;
        root[i] = i;
    }
    for (i64 m = 0; m < n_man; ++m) {
        if (!mi(m, MI_ACTIVE) || !manifold_pushed(mi, pf, m)) continue;
        i64 a = mi(m, MI_A), b = mi(m, MI_B);
        pushed[a] = 1;
        pushed[b] = 1;
        i64 ra = find_root(root, a), rb_ = find_root(root, b);
        if (ra != rb_) {  // the static dummy (row n) joins the island it pushes: no self-root
            if (ra == n) {
                root[rb_] = ra;
            } else {
                root[ra] = rb_;
            }
        }
    }
    // an island that holds the static dummy touches static geometry
    for (i64 i = 0; i < n; ++i)
        if (pushed[i] && find_root(root, i) == find_root(root, n)) pushed[i] = 2;
}

// The position and spin corrections of stage 9 for a pushed body on static support (su: its
// sc.support row; v, v0, w, w0: its solver velocity and spin after the solve and at its start,
// after the kick; a: g + F/m; inv_i: its world inverse inertia (xx, yy, zz, xy, xz, yz); tau:
// its torque; kh: h when the step kicks, else 0). With dv = v_new - v_start and dw = w_new -
// w_start the step's velocity and spin changes (v_start = v0 - h a, w_start = w0 - h I^-1 tau:
// before the kick), and P, Q the projections off the spans of the contacts' normals and of their
// r x n:
//
//     cx = - phi h P dv / 2,   cw = - phi Q dw / 2
//
// so x += h v_new + cx is h (v_start + v_new) / 2 off the normals (phi = 1: exact for constant
// acceleration) and h v_new along them, the end-of-step gap the velocity solve predicts,
// s + h w_n; the turn is h (w_new + cw), h (w_start + w_new) / 2 about the axes that move no
// contact (exact for a constant spin-up about a fixed axis: a rolling sphere's). phi = t_stop / h
// when a point slid at the start and the body stopped inside the step: the velocity runs linearly from v_start to v_new by t_stop, then
// holds, so x += h v_new + t_stop (v_start - v_new) / 2; t_stop comes from the velocity change a
// whole step of sliding would give, s = h a + su[SUP_SLIDE]: dv = (t_stop / h) s, solved in least
// squares off the normals, phi = |P dv|^2 / (P dv . P s), and 1 when that is not below 1 (the
// body slid through the step).
inline void support_correction(const double* su, const double* v, const double* v0,
                               const double* w, const double* w0, const double* a,
                               const double* inv_i, const double* tau, double kh, double h,
                               double* cx, double* cw, double& stopped) {
    double dv[3], dw[3];
    smul6(inv_i, kh * tau[0], kh * tau[1], kh * tau[2], dw[0], dw[1], dw[2]);
    for (int k = 0; k < 3; ++k) {
        dv[k] = v[k] - v0[k] + kh * a[k];
        dw[k] += w[k] - w0[k];
    }
    off_span(su + SUP_NB, su[SUP_NN], dv);
    off_span(su + SUP_RB, su[SUP_RN], dw);
    double phi = 1.0;
    if (su[SUP_SLID] != 0.0) {
        double s[3];
        for (int k = 0; k < 3; ++k) s[k] = kh * a[k] + su[SUP_SLIDE + k];
        off_span(su + SUP_NB, su[SUP_NN], s);
        double num = dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2];
        double den = dv[0] * s[0] + dv[1] * s[1] + dv[2] * s[2];
        if (den > num) phi = num / den;
    }
    stopped = phi < 1.0;
    for (int k = 0; k < 3; ++k) {
        cx[k] = -0.5 * phi * h * dv[k];
        cw[k] = -0.5 * phi * dw[k];
    }
}

// After mark_pushed (default solver): what stage 9 needs of the contacts that pushed each body
// (sc.support, records.hpp's SUP_* columns), from this step's pushing manifolds: the span of
// their normals and the span of r x n over their points (the directions in which a move of the
// body changes a gap, to first order), whether a point slid at the step's start (tangential slip
// above cfg.slide_start_speed, from the velocities before the kick), and the velocity change
// that a whole step of sliding would give: sum over the points of (lambda_n n + f) / m, with
// f = -mu lambda_n u_t / |u_t| at a sliding point (u_t its start slip) and the solve's friction
// impulse at the others (serial over manifolds: a body gathers from several). Then each such
// body's corrections (support_correction, into SUP_CX, SUP_CW; none for a body that a pair holds
// on a carried friction anchor, SUP_SKIP), and the friction anchor of a pair that slid into the
// step on a fresh anchor takes their slide. rotation: (N, 3, 3) the
// bodies' R at the step's start.
void gather_supports(const Bodies& bd, const Settings& cfg, V2<i64> mi, V2<double> mf,
                     V2<double> pf, i64 n_man, i64 n, double h, V3<double> rotation,
                     Scratch& sc) {
    V2<double> sup = sc.support.view();
    V2<double> bv0 = sc.bv0.view(), bw0 = sc.bw0.view(), bI = sc.bI.view();
    V1<double> bm = col(sc.bm);
    const double kh = cfg.do_kick ? h : 0.0;
    for (i64 i = 0; i < n + 1; ++i) std::fill(sup.row(i), sup.row(i) + SUP_COLS, 0.0);
    // u: the velocity of solver body i's material point at anchor r at the step's start (before
    // the kick: v0 - h a, w0 - h I^-1 tau); 0 for the static dummy
    auto start_velocity = [&](i64 i, const double* r, double* u) {
        if (i >= n) {
            u[0] = u[1] = u[2] = 0.0;
            return;
        }
        double dwx = 0.0, dwy = 0.0, dwz = 0.0;
        if (bd.torque(i, 0) != 0.0 || bd.torque(i, 1) != 0.0 || bd.torque(i, 2) != 0.0)
            smul6(bI.row(i), kh * bd.torque(i, 0), kh * bd.torque(i, 1), kh * bd.torque(i, 2),
                  dwx, dwy, dwz);
        double wx = bw0(i, 0) - dwx, wy = bw0(i, 1) - dwy, wz = bw0(i, 2) - dwz;
        u[0] = bv0(i, 0) - kh * bd.accel(i, 0) + (wy * r[2] - wz * r[1]);
        u[1] = bv0(i, 1) - kh * bd.accel(i, 1) + (wz * r[0] - wx * r[2]);
        u[2] = bv0(i, 2) - kh * bd.accel(i, 2) + (wx * r[1] - wy * r[0]);
    };
    auto rxn = [](const double* r, const double* nv, double* o) {
        o[0] = r[1] * nv[2] - r[2] * nv[1];
        o[1] = r[2] * nv[0] - r[0] * nv[2];
        o[2] = r[0] * nv[1] - r[1] * nv[0];
    };
    auto dot3 = [](const double* u, const double* v) { return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]; };
    for (i64 m = 0; m < n_man; ++m) {
        if (!mi(m, MI_ACTIVE)) continue;
        if (mi(m, MI_A) < n && mi(m, MI_B) < n) {
            // two dynamic bodies in touch or within reach (pushing or not: a speculative contact
            // that pushes every other step would switch the bodies' scheme with it): no
            // corrections for either (SUP_SKIP, below)
            sup(mi(m, MI_A), SUP_SKIP) = 1.0;
            sup(mi(m, MI_B), SUP_SKIP) = 1.0;
        }
        if (!manifold_pushed(mi, pf, m)) continue;
        i64 a = mi(m, MI_A), b = mi(m, MI_B);
        const double* nv = mf.row(m) + MF_N;
        double mu = mf(m, MF_MU);
        if (a < n) {
            span_add(sup.row(a) + SUP_NB, sup(a, SUP_NN), nv, 1.0);
            sup(a, SUP_ON) = 1.0;
        }
        if (b < n) {
            span_add(sup.row(b) + SUP_NB, sup(b, SUP_NN), nv, 1.0);
            sup(b, SUP_ON) = 1.0;
        }
        i64 start = mi(m, MI_START);
        bool slid_in = false, fresh = true;
        for (i64 p = start; p < start + mi(m, MI_COUNT); ++p) {
            const double* ra = pf.row(p) + PF_RA;
            if (dot3(pf.row(p) + PF_D, pf.row(p) + PF_D) > FRESH_ANCHOR_M * FRESH_ANCHOR_M)
                fresh = false;
            const double* rb = pf.row(p) + PF_RB;
            double t[3];
            if (a < n && sup(a, SUP_RN) < 3.0) {
                rxn(ra, nv, t);
                span_add(sup.row(a) + SUP_RB, sup(a, SUP_RN), t, dot3(ra, ra));
            }
            if (b < n && sup(b, SUP_RN) < 3.0) {
                rxn(rb, nv, t);
                span_add(sup.row(b) + SUP_RB, sup(b, SUP_RN), t, dot3(rb, rb));
            }
            // start slip u_t: the relative velocity of a's point past b's, off the normal
            double ua[3], ub[3], u[3];
            start_velocity(a, ra, ua);
            start_velocity(b, rb, ub);
            for (int k = 0; k < 3; ++k) u[k] = ua[k] - ub[k];
            double un = u[0] * nv[0] + u[1] * nv[1] + u[2] * nv[2];
            for (int k = 0; k < 3; ++k) u[k] -= un * nv[k];
            double slip = std::sqrt(dot3(u, u));
            double ln = pf(p, PF_LN), j[3];  // the impulse on a over a whole step of sliding
            if (slip > cfg.slide_start_speed) {
                for (int k = 0; k < 3; ++k) j[k] = ln * nv[k] - mu * ln * u[k] / slip;
                if (a < n) sup(a, SUP_SLID) = 1.0;
                if (b < n) sup(b, SUP_SLID) = 1.0;
                if (slip > cfg.velocity_tolerance) slid_in = true;
            } else {  // the solve's friction impulse (PF_F is written at stage 11)
                double l1 = pf(p, PF_L1), l2 = pf(p, PF_L2);
                for (int k = 0; k < 3; ++k)
                    j[k] = ln * nv[k] + l1 * mf(m, MF_T1 + k) + l2 * mf(m, MF_T2 + k);
            }
            for (int k = 0; k < 3; ++k) {
                if (a < n) sup(a, SUP_SLIDE + k) += bm[a] * j[k];
                if (b < n) sup(b, SUP_SLIDE + k) -= bm[b] * j[k];
            }
        }
        // a pair that slid into the step (beyond the solve's leftover, velocity_tolerance) on an
        // anchor taken at this step's start (it slid in the last step: drift D still round-off)
        // sticks, if at all, only from inside the step: marked (MF_AOK = -1 until the end of
        // this stage) for its anchor to take the corrections' slide below
        if (slid_in && fresh && mf(m, MF_AOK) > 0.0) mf(m, MF_AOK) = -1.0;
        // No corrections (SUP_SKIP) for the bodies of a pair held on a carried anchor: its
        // friction rows steer the pair's drift D back at FRICTION_ANCHOR_RATE a step, position
        // control by impulses at the step's start, which x += h v_new follows; moved by
        // h (v_start + v_new) / 2 the loop lags half a step and rings (D_k+1 = D_k - rate
        // (D_k + D_k-1) / 2 has complex roots). Nor for a pair of two dynamic bodies: the solve
        // leaves the coupled rows of stacks and piles at velocity_tolerance, and the closed forms
        // are those of a body on static support. (With both corrected, the 500-box pile's
        // resting jitter was 1.1-1.2e-3 m/s against 3.1-6.3e-4 on main over three seeds, and its
        // solve 10-20 % slower per point.)
        if (cfg.static_friction_anchors && mf(m, MF_AOK) > 0.0 && !fresh) {
            if (a < n) sup(a, SUP_SKIP) = 1.0;
            if (b < n) sup(b, SUP_SKIP) = 1.0;
        }
    }
    // the corrections of the bodies on static support (each body its own row)
    V1<i64> pushed_of = col(sc.pushed);
    V2<double> bv = sc.bv.view(), bw = sc.bw.view();
    par_ranges(n, BODIES_PER_BLOCK, [&](i64 i0, i64 i1) {
        for (i64 i = i0; i < i1; ++i)
            if (pushed_of[i] == 2 && sup(i, SUP_ON) != 0.0 && sup(i, SUP_SKIP) == 0.0)
                support_correction(sup.row(i), bv.row(i), bv0.row(i), bw.row(i), bw0.row(i),
                                   bd.accel.row(i), bI.row(i), bd.torque.row(i), kh, h,
                                   sup.row(i) + SUP_CX, sup.row(i) + SUP_CW, sup(i, SUP_STOP));
    });
    // a marked pair with a body that stopped inside the step (SUP_STOP): its anchor pose moves
    // with the corrections' relative shift, so that it holds
    // the pose where the slide ends (it would pull the pair back by the rest of the slide, 1.4e-6
    // m for the test's stopping box; the turn's correction, second order in a stop, is not
    // taken): A_t = R_b^T (x_a - x_b) += R_b^T (cx_a - cx_b), R_b^T = A_R R_a^T (the anchor
    // was taken at this step's start, R_a unchanged since). The next step's D then holds the
    // solve's own slip, so the anchor is carried (not fresh) and keeps its memory.
    for (i64 m = 0; m < n_man; ++m) {
        if (mf(m, MF_AOK) != -1.0) continue;
        mf(m, MF_AOK) = 1.0;
        i64 a = mi(m, MI_A), b = mi(m, MI_B), ra = mi(m, MI_REC_A);
        if (!((a < n && sup(a, SUP_STOP) != 0.0) || (b < n && sup(b, SUP_STOP) != 0.0)))
            continue;  // slid through the step: store_impulses drops the anchor if it slides on
        double d[3];
        for (int k = 0; k < 3; ++k)
            d[k] = (a < n ? sup(a, SUP_CX + k) : 0.0) - (b < n ? sup(b, SUP_CX + k) : 0.0);
        if (d[0] == 0.0 && d[1] == 0.0 && d[2] == 0.0) continue;
        double u[3];  // R_a^T d
        for (int k = 0; k < 3; ++k)
            u[k] = rotation(ra, 0, k) * d[0] + rotation(ra, 1, k) * d[1] +
                   rotation(ra, 2, k) * d[2];
        for (int r = 0; r < 3; ++r)
            mf(m, MF_AT + r) += mf(m, MF_AR + 3 * r) * u[0] + mf(m, MF_AR + 3 * r + 1) * u[1] +
                                mf(m, MF_AR + 3 * r + 2) * u[2];
    }
}

// 9 integrate: move every awake body over the step (how: sc.pushed, see mark_pushed). A body
// that a contact pushed (solve or relax) moves with the solver's velocity, x += h (v + v'), its
// momenta rebuilt from the solver's velocity changes, and when its island touches no static
// geometry, by - h^2 a / 2 more (the exact flight's term), when it does, as under constant
// acceleration off its contact normals (support_correction, from sc.support; left out when
// gather_supports did not run this step or with soft_step); every other body flies exactly under
// its constant acceleration a, x += h v - h^2 a / 2 with v after the kick (a body whose
// manifolds all ended without impulse gets its start-of-solve momenta back bitwise: warm
// starting applies and withdraws impulses, which leaves round-off). Rotation by the run's
// integrator (drift_rotation) with the body's L, plus the pseudo spin of the relax stage. The
// exact integrators rotate from the body's flow anchor (an; a new one whenever the L it drifts
// with changed).
void integrate_positions(int method, int ortho, const Bodies& bd, const Settings& cfg,
                         V1<i64> awake, const BodyState& x, Scratch& sc, double h,
                         const FlowAnchors& an) {
    i64 n = x.position.n0;
    V2<double> l_drift = sc.l_drift.view(), dx_step = sc.dx_step.view();
    V2<double> pv = sc.pv.view(), pw = sc.pw.view();
    V2<double> bv = sc.bv.view(), bw = sc.bw.view(), bv0 = sc.bv0.view(), bw0 = sc.bw0.view();
    V2<double> p0 = sc.p0.view(), l0 = sc.l0.view();
    V1<i64> in_contact = col(sc.in_contact), pushed_of = col(sc.pushed);
    V2<double> lm = x.linear_momentum, am = x.angular_momentum, pos = x.position;
    V2<double> sup = sc.support.view();
    // each body reads and writes only its own rows: blocks of bodies on the pool
    par_ranges(n, BODIES_PER_BLOCK, [&](i64 i0, i64 i1) {
    for (i64 i = i0; i < i1; ++i) {
        if (!awake[i]) continue;
        double im = bd.inv_mass[i];
        for (int k = 0; k < 3; ++k) l_drift(i, k) = am(i, k);
        bool pushed = in_contact[i] && pushed_of[i] != 0;
        if (pushed) {
            store_momenta(i, bd, x.rotation, lm, am, bv, bw, bv0, bw0, p0, l0, cfg.iso_shortcut);
            // the exact-flight term, for islands away from static geometry
            double fly = pushed_of[i] == 1 ? 0.5 * h : 0.0;
            // on static support: the constant-acceleration term off the contacts' gaps
            const double zero[3] = {0.0, 0.0, 0.0};
            const bool on = pushed_of[i] == 2 && !cfg.soft_step && sup(i, SUP_ON) != 0.0;
            const double* cx = on ? sup.row(i) + SUP_CX : zero;
            const double* cw = on ? sup.row(i) + SUP_CW : zero;
            for (int k = 0; k < 3; ++k) {
                dx_step(i, k) = h * (lm(i, k) * im + pv(i, k) - fly * bd.accel(i, k)) + cx[k];
                pos(i, k) += dx_step(i, k);
                l_drift(i, k) = am(i, k);
            }
            if (cw[0] != 0.0 || cw[1] != 0.0 || cw[2] != 0.0) {
                // drift with the spin w_new + cw: L + I_world cw
                Vec3 j = (cfg.iso_shortcut && bd.iso[i])
                             ? Vec3{bd.inertia(i, 0) * cw[0], bd.inertia(i, 0) * cw[1],
                                    bd.inertia(i, 0) * cw[2]}
                             : omega_world(load_mat(x.rotation, i), bd.inertia(i, 0),
                                           bd.inertia(i, 1), bd.inertia(i, 2), cw[0], cw[1],
                                           cw[2]);
                for (int k = 0; k < 3; ++k) l_drift(i, k) += j[k];
            }
            if (pw(i, 0) != 0.0 || pw(i, 1) != 0.0 || pw(i, 2) != 0.0) {
                // rotate by L + I_world w' so the pseudo spin goes through the integrator
                double jx, jy, jz;
                if (cfg.iso_shortcut && bd.iso[i]) {
                    double s0 = bd.inertia(i, 0);
                    jx = s0 * pw(i, 0); jy = s0 * pw(i, 1); jz = s0 * pw(i, 2);
                } else {
                    Vec3 j = omega_world(load_mat(x.rotation, i), bd.inertia(i, 0),
                                         bd.inertia(i, 1), bd.inertia(i, 2), pw(i, 0), pw(i, 1),
                                         pw(i, 2));
                    jx = j[0]; jy = j[1]; jz = j[2];
                }
                l_drift(i, 0) += jx;
                l_drift(i, 1) += jy;
                l_drift(i, 2) += jz;
            }
        } else {
            if (in_contact[i]) {
                // untouched by the solve: the momenta and solver velocities it started with
                for (int k = 0; k < 3; ++k) {
                    lm(i, k) = p0(i, k);
                    am(i, k) = l0(i, k);
                    l_drift(i, k) = l0(i, k);
                    bv(i, k) = bv0(i, k);
                    bw(i, k) = bw0(i, k);
                }
            }
            // exact flight under constant force: x += h v_start + h^2 a / 2
            for (int k = 0; k < 3; ++k) {
                double d = h * (lm(i, k) * im - 0.5 * h * bd.accel(i, k));
                pos(i, k) += d;
                dx_step(i, k) = d;
            }
        }
        if (method == METHOD_EXACT || method == METHOD_EXACT4) {
            drift_exact_anchored(x.quat_wxyz, x.rotation, l_drift, bd.inv_inertia, i, h,
                                 an.anchor_quat_wxyz, an.anchor_L_world, an.anchor_steps,
                                 an.anchor_dt_s, sc.flow_c.view(), i, sc.flow_ok.view());
        } else {
            drift_rotation(method, ortho, x.quat_wxyz, x.rotation, l_drift, bd.inv_inertia, i, h);
        }
        if (pushed && (pv(i, 0) != 0.0 || pv(i, 1) != 0.0 || pv(i, 2) != 0.0)) {
            // the pseudo shift h v' moved the body's momentum line: give the orbital change back
            // to its spin so that sum(x x P + L) stays exact
            double sx = h * pv(i, 0), sy = h * pv(i, 1), sz = h * pv(i, 2);
            double qx = lm(i, 0), qy = lm(i, 1), qz = lm(i, 2);
            am(i, 0) -= sy * qz - sz * qy;
            am(i, 1) -= sz * qx - sx * qz;
            am(i, 2) -= sx * qy - sy * qx;
        }
    }
    });
}

// 12 project: narrowphase again at the end-of-step poses; points deeper than projection_depth
// are pushed out (project.cpp) and the bodies moved (a moved body's flow anchor is dropped: its
// attitude changed other than by the flow). Returns n_deep.
i64 project(int method, int ortho, const Bodies& bd, const Statics& st, const Settings& cfg,
            V1<i64> awake, const BodyState& x, Scratch& sc, V2<i64> pairs, i64 n_pairs,
            const FlowAnchors& an) {
    i64 n = x.position.n0;
    i64 n_deep = project_positions(
        pairs, n_pairs, n, st.n_static, bd.geom, bd.size, bd.inv_mass, bd.inv_inertia, bd.iso,
        cfg.iso_shortcut, awake, x.position, x.rotation, st.pos, st.rot, st.ext, st.gn, st.goff,
        cfg.projection_depth, cfg.projection_iterations, sc.proj_rows, sc.proj_ids, sc.cb, sc.proj_dx.view(),
        sc.proj_dth.view(), cfg.projection_rings, sc.ring, sc.done);
    if (n_deep > 0)
        apply_projection(n_deep, sc.proj_ids.view(), sc.proj_dx.view(), sc.proj_dth.view(), n,
                         method, ortho, bd, cfg.iso_shortcut, x.position, x.rotation, x.quat_wxyz,
                         x.linear_momentum, x.angular_momentum, sc.l_drift.view(),
                         an.anchor_steps);
    return n_deep;
}

// 13 sleep: wake what this step pushed on (when some bodies slept at the step's start, n_awake <
// N), advance rest timers, put resting islands to sleep. Returns (islands woken, bodies put to
// sleep).
std::pair<i64, i64> sleep_stage(const Bodies& bd, const Settings& cfg, const SleepState& sl,
                                const BodyState& x, Scratch& sc, V2<i64> mi, V2<double> mf,
                                V2<double> pf, i64 n_man, double h, i64 n_awake) {
    i64 n = x.position.n0;
    i64 woken = 0;
    if (n_awake < n)
        woken = wake_pushed(mi, mf, pf, n_man, n, sl.awake, sl.timer, sl.island_of, x.position,
                            x.linear_momentum, x.angular_momentum, bd.force, bd.torque, h);
    i64 slept = update_sleep(n, mi, pf, n_man, sl.awake, sl.timer, sl.island_of,
                             sl.island_counter, x.linear_momentum, x.angular_momentum,
                             bd.inv_mass, bd.inv_inertia, bd.radius, h, cfg.sleep_speed,
                             cfg.sleep_time, col(sc.parent), col(sc.isl_time), col(sc.isl_sup));
    return {woken, slept};
}

// 6-9 in soft_step mode: the substeps (soft_step.cpp: warm start, soft solve, relax per
// substep), then the bodies sorted, the pseudo velocities of islands away from static geometry
// made the contacts' part only (soft_island_flight), and stage 9 as ever. Returns the
// sweeps; t: the profile clock, lapped into P_SOLVE, P_RELAX and P_INTEGRATE.
i64 soft_stages(const Bodies& bd, const Settings& cfg, const BodyState& x, Scratch& sc,
                V1<i64> awake, V2<i64> mi, V2<double> mf, V2<double> pf, i64 n_man, int method,
                int ortho, double h, const FlowAnchors& an, V1<i64> prof, i64& t) {
    bool do_prof = prof.n0 > 0;
    i64 sweeps = soft_solve(StepContext{h, 1.0 / h, cfg}, ContactConstraints{mi, mf, pf, n_man},
                            SolverBodies{col(sc.bm), sc.bI.view(), sc.bv.view(), sc.bw.view()},
                            sc.pv.view(), sc.pw.view(), col(sc.in_contact), bd.accel, bd.torque,
                            cfg.do_kick);
    if (do_prof) t = lap(prof, P_SOLVE, t);
    mark_pushed(mi, pf, n_man, x.position.n0, sc);
    if (cfg.do_kick)
        soft_island_flight(awake, col(sc.in_contact), col(sc.pushed), bd.accel, sc.pv.view(), h,
                           cfg.substeps);
    if (do_prof) t = lap(prof, P_RELAX, t);
    integrate_positions(method, ortho, bd, cfg, awake, x, sc, h, an);
    if (do_prof) t = lap(prof, P_INTEGRATE, t);
    return sweeps;
}

// The first awake body whose state is not finite or that turns more than
// MAX_ROTATION_PER_STEP_RAD in a step of h (turn_within_bound), or -1: the run has diverged
// there (a torque of 1e40 N m on a resting box, say), though its state may be finite.
i64 first_diverged(V1<i64> awake, const BodyState& x, V2<double> inv_inertia, double h) {
    for (i64 i = 0; i < x.position.n0; ++i) {
        if (awake[i] && (!std::isfinite(state_sum(i, x.position, x.linear_momentum,
                                                  x.angular_momentum, x.rotation)) ||
                         !turn_within_bound(h, i, inv_inertia, x.rotation, x.angular_momentum)))
            return i;
    }
    return -1;
}

// The contact rows of step s: every point that pushed or touches (trajectory.Contacts), from
// the manifolds of the last step run (mi, mf, pf), with the separation at the end-of-step poses
// (the contract's "after the step").
//
// A point's two anchors start at the one world point p (PF_RA = p - x_a, PF_RB = p - x_b at the
// step's start; pose0: (N, 12) each body's position and row-major rotation then) with the gap
// PF_S along the normal n. Each anchor moves with its body's whole motion over the step, the
// project stage's pushes included: a_end = x_a + R_a R0_a^T r_a (b likewise; static geometry
// does not move), so the end-of-step gap is PF_S + n . (a_end - b_end). The normal is the
// step's: its turn changes the gap only by turn x |a_end - b_end|, second order, since the
// anchors start together. (PF_SEND, the solver's linear estimate s + h (v_n + v_n pseudo) read by
// the restitution and sleep stages, misses the project stage's pushes: up to 1.3 mm off the
// poses on samples/pile.toml's rows.) Returns n_log; the log may have grown.
i64 record_contacts(i64 s, V2<i64> mi, V2<double> mf, V2<double> pf, i64 n_man,
                    V2<double> position, V3<double> rotation, V2<double> pose0,
                    Buf2<i64>& log_i, Buf2<double>& log_f, i64 n_log) {
    i64 need = n_log;
    for (i64 m = 0; m < n_man; ++m) need += mi(m, MI_COUNT);
    log_i.grow(need);
    log_f.grow(need);
    // the world displacement of anchor r of body i over the step: x - x0 + (R R0^T - I) r
    auto moved = [&](i64 i, const double* r, double* d) {
        const double* q0 = pose0.row(i);
        const double* R0 = q0 + 3;
        double u[3];  // R0^T r: the anchor in the body frame
        for (int k = 0; k < 3; ++k) u[k] = R0[k] * r[0] + R0[3 + k] * r[1] + R0[6 + k] * r[2];
        for (int k = 0; k < 3; ++k)
            d[k] = position(i, k) - q0[k] +
                   (rotation(i, k, 0) * u[0] + rotation(i, k, 1) * u[1] + rotation(i, k, 2) * u[2]) -
                   r[k];
    };
    for (i64 m = 0; m < n_man; ++m) {
        i64 start = mi(m, MI_START);
        i64 a = mi(m, MI_REC_A), b = mi(m, MI_REC_B);
        const double n[3] = {mf(m, MF_N), mf(m, MF_N + 1), mf(m, MF_N + 2)};
        for (i64 p = start; p < start + mi(m, MI_COUNT); ++p) {
            double da[3], db[3] = {0.0, 0.0, 0.0};
            moved(a, pf.row(p) + PF_RA, da);
            if (b >= 0) moved(b, pf.row(p) + PF_RB, db);
            double sep = pf(p, PF_S) + n[0] * (da[0] - db[0]) + n[1] * (da[1] - db[1]) +
                         n[2] * (da[2] - db[2]);
            if (pf(p, PF_LN) <= 0.0 && sep > 0.0) continue;
            log_i(n_log, LOG_STEP) = s;
            log_i(n_log, LOG_A) = a;
            log_i(n_log, LOG_B) = b;
            log_i(n_log, LOG_KIND) = pf(p, PF_IMPACT) > 0.0 ? CONTACT_IMPACT : CONTACT_RESTING;
            for (int k = 0; k < 3; ++k) {
                log_f(n_log, LOG_P + k) = pf(p, PF_P + k);
                log_f(n_log, LOG_N + k) = n[k];
                log_f(n_log, LOG_F + k) = pf(p, PF_F + k);
            }
            log_f(n_log, LOG_S) = sep;
            log_f(n_log, LOG_LN) = pf(p, PF_LN);
            n_log += 1;
        }
    }
    return n_log;
}

}  // namespace step

// ---- the step ---------------------------------------------------------------------------------

// Advance n_steps steps of dt with contacts; write samples and contact rows.
//
// bd, st, cfg: the model records. method, ortho: integrators' METHOD_* / ORTHO_* codes. n_steps,
// stride, sample_last: as free.advance_free (a sample after every stride-th step, and after the
// last one when sample_last). x: BodyState, updated in place; out: the (S, N, ...) sample
// buffers. sl: SleepState, updated in place. c: the ContactCache (its log receives the contact
// rows, manifold.hpp's LOG_* columns). stats: (N_STATS,) counters. prof: (N_PROF,) int64 cycle
// counts per stage, added to; empty: not profiled. an: the exact integrators' flow anchors,
// updated in place.
//
// Returns (n_samples, bad_step, bad_body, n_log): bad_step is the first local step (1-based) at
// which some body's state became non-finite or turned beyond the bound (-1 if none).
AdvanceResult world_advance(const Bodies& bd, const Statics& st, const Settings& cfg, int method,
                            int ortho, double dt, i64 n_steps, i64 stride, bool sample_last,
                            const BodyState& x, const SampleState& out, const SleepState& sl,
                            ContactCache& c, V1<i64> stats, V1<i64> prof, const FlowAnchors& an,
                            const IntervalImpulses& im) {
    using namespace step;
    i64 n = x.position.n0;
    double h = dt;
    const StepContext ctx{h, 1.0 / dt, cfg};
    Scratch& sc = c.sc;
    sc.make(n, st);
    if (c.pose0.rows != n || c.pose0.cols != 12) c.pose0 = Buf2<double>(n, 12);
    i64 n_log = 0;
    i64 n_samples = 0;
    // garbage in: a non-finite state handed to this call is reported at its first step
    for (i64 i = 0; i < n; ++i) {
        if (!std::isfinite(state_sum(i, x.position, x.linear_momentum, x.angular_momentum,
                                     x.rotation)))
            return AdvanceResult{0, 1, i, 0};
    }
    bool do_prof = prof.n0 > 0;
    i64 t = 0;
    for (i64 s = 1; s < n_steps + 1; ++s) {
        i64 n_awake = 0;
        for (i64 i = 0; i < n; ++i) n_awake += sl.awake[i] != 0;
        if (n_awake > 0) {
            stats[ST_STEPS] += 1;
            stats[ST_AWAKE] += n_awake;
            // the poses the contact rows' anchors start from (record_contacts)
            for (i64 i = 0; i < n; ++i) {
                double* q0 = &c.pose0(i, 0);
                for (int k = 0; k < 3; ++k) q0[k] = x.position(i, k);
                for (int k = 0; k < 9; ++k) q0[3 + k] = x.rotation(i, k / 3, k % 3);
            }
            if (do_prof) t = ticks();
            if (cfg.do_kick) kick(bd, sl.awake, x, h);                                     // 1
            if (im.on()) impulses_begin(sl.awake, x, im);                                  // 1b
            if (do_prof) t = lap(prof, P_KICK, t);
            i64 n_pairs = broadphase(bd, st, cfg.speculative_distance, sl.awake, x, h, sc, c.pairs);     // 2
            V2<i64> pairs = c.pairs.view();
            stats[ST_PAIRS] += n_pairs;
            if (do_prof) t = lap(prof, P_BROADPHASE, t);
            if (n_awake < n) stats[ST_WOKEN] += wake(bd, st, cfg, sl, x, h, sc, pairs, n_pairs);  // 3
            if (do_prof) t = lap(prof, P_WAKE, t);
            CollideCount cc = step::collide(bd, st, cfg, sl.awake, x, sc, pairs, n_pairs, c);  // 4
            i64 n_man = cc.n_man;
            stats[ST_MANIFOLDS] += n_man;
            stats[ST_POINTS] += cc.n_pts;
            if (do_prof) t = lap(prof, P_COLLIDE, t);
            colour_manifolds(c.mi1.view(), n_man, n, sc.graph);                          // 4b
            if (do_prof) t = lap(prof, P_COLOUR, t);
            V2<i64> mi1 = c.mi1.view();
            V2<double> mf1 = c.mf1.view(), pf1 = c.pf1.view();
            const ContactConstraints cons{mi1, mf1, pf1, n_man};
            const SolverBodies bodies{col(sc.bm), sc.bI.view(), sc.bv.view(), sc.bw.view()};
            const SolverBodies pseudo{col(sc.bm), sc.bI.view(), sc.pv.view(), sc.pw.view()};
            prepare(bd, cfg, x, sc, mi1, mf1, pf1, n_man, h);                               // 5
            if (cfg.soft_step) {  // 6-9 as Box2D v3's substeps (soft_step.cpp)
                stats[ST_SWEEPS] += soft_stages(bd, cfg, x, sc, sl.awake, mi1, mf1, pf1, n_man,
                                                method, ortho, h, an, prof, t);
            } else {
            if (cfg.warm_starting) warm_start(cons, bodies);                               // 6
            stats[ST_SWEEPS] += solve_velocities(ctx, cons, bodies, col(sc.hot),           // 7
                                                 col(sc.in_contact), sc.graph, sc.lanes);
            if (cfg.static_friction_anchors) anchor_friction(ctx, cons, bodies);           // 7b
            if (do_prof) t = lap(prof, P_SOLVE, t);
            if (cfg.position_iterations > 0) relax_positions(ctx, cons, pseudo);           // 8
            mark_pushed(mi1, pf1, n_man, n, sc);
            if (do_prof) t = lap(prof, P_RELAX, t);
            gather_supports(bd, cfg, mi1, mf1, pf1, n_man, n, h, x.rotation, sc);                     // 9
            integrate_positions(method, ortho, bd, cfg, sl.awake, x, sc, h, an);            // 9
            if (do_prof) t = lap(prof, P_INTEGRATE, t);
            }
            stats[ST_IMPACTS] += restitution(ctx, cons, bodies, sc.pv.view(), sc.pw.view(), // 10
                                             sc.dx_step.view(), x.linear_momentum,
                                             x.angular_momentum);
            store_impulses(ctx, cons);                                                      // 11
            // this step's manifolds become "previous"
            c.keys0.grow(std::max<i64>(n_man, 1));
            c.idx0.grow(std::max<i64>(n_man, 1));
            sort_manifolds(mi1, n_man, col(c.keys0), col(c.idx0));
            std::swap(c.mi0, c.mi1);
            std::swap(c.mf0, c.mf1);
            std::swap(c.pf0, c.pf1);
            std::swap(c.pid0, c.pid1);
            c.n_man0 = n_man;
            if (do_prof) t = lap(prof, P_RESTITUTION, t);
            if (cfg.projection_iterations > 0)                                                             // 12
                stats[ST_PROJECTED] += project(method, ortho, bd, st, cfg, sl.awake, x, sc, pairs,
                                               n_pairs, an);
            if (do_prof) t = lap(prof, P_PROJECT, t);
            if (cfg.do_sleep) {                                                             // 13
                std::pair<i64, i64> ws = sleep_stage(bd, cfg, sl, x, sc, c.mi0.view(),
                                                     c.mf0.view(), c.pf0.view(), c.n_man0, h,
                                                     n_awake);
                stats[ST_WOKEN] += ws.first;
                stats[ST_SLEPT] += ws.second;
            }
            i64 bad = first_diverged(sl.awake, x, bd.inv_inertia, h);
            if (do_prof) t = lap(prof, P_SLEEP, t);
            if (bad >= 0) return AdvanceResult{n_samples, s, bad, n_log};
        }
        if (im.on()) impulses_end(bd, x, h, n_awake > 0, im);                              // 14
        if (s % stride == 0 || (sample_last && s == n_steps)) {
            if (do_prof) t = ticks();
            for (i64 i = 0; i < n; ++i)
                write_sample(method, n_samples, i, x.position, x.linear_momentum, x.quat_wxyz,
                             x.rotation, x.angular_momentum, out.position, out.linear_momentum,
                             out.quat_wxyz, out.rotation, out.angular_momentum);
            if (im.on()) impulses_sample(im, n_samples);
            n_samples += 1;
            n_log = record_contacts(s, c.mi0.view(), c.mf0.view(), c.pf0.view(), c.n_man0,
                                    x.position, x.rotation, c.pose0.view(), c.log_i, c.log_f,
                                    n_log);
            if (do_prof) t = lap(prof, P_SAMPLE, t);
        }
    }
    for (i64 i = 0; i < n; ++i) sync_quat(method, x.quat_wxyz, x.rotation, i);
    return AdvanceResult{n_samples, -1, -1, n_log};
}

}  // namespace rb
