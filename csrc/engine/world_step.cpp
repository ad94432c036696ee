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
//     9  integrate        a body the solve and relax pushed: x += h (v + v'), momenta P, L rebuilt
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
//   sleeping body), by symplectic Euler, exactly that: a body resting on a contact must move by h
//   times its velocity so that v = 0 means still (the exact flight's term would lift it by
//   |g| h^2 / 2 each step, and the solver would answer with a downward velocity |g| h / 2 at rest);
// * in an island away from static geometry (bodies colliding in the air), by that plus the exact
//   flight's - h^2 a / 2, the same term a free body gets: under uniform gravity it moves the whole
//   island alike, so the gaps the solver predicted inside it hold, and every body of a group that
//   only pushes itself flies by one scheme. Mixing symplectic and exact bodies in such a group
//   would change its angular momentum about its centre of mass by O(h^2 |g| |P|) a step (5.6e-6
//   relative on samples/mixed.toml; both schemes alone keep it exactly).
//
// Exact motion on one static surface (ContactParams.exact_contact_motion, off by default; the PGS
// solve only). Symplectic Euler's x += h v_new is first order under a constant contact force:
// a box sliding to a stop falls short of v0^2 / (2 mu g) by about h v0 / 2, a ball rolling down
// a slope lags s = a t^2 / 2 by a relative h / t. The trapezoid x += h (v_start + v_new) / 2 is
// exact for constant acceleration, and it is applied where the force is constant over the step
// and the gaps the solve predicted stay as predicted: a body whose one pushing manifold is
// against static geometry, with no point struck this step (mark_exact; an impact's impulse is
// not spread over the step, and bodies pushing each other keep the one-scheme rule above). There
// it is applied to the tangential displacement only (the normal one stays h w_n, the solve's
// s + h w_n) and to the part of the turn that moves no contact point along the normal; a stop or
// reversal of the tangential velocity inside the step gets the kinetic-friction closed form
// (exact_correction). The log's velocities stay the solver's: the step's mean velocity is their
// average, which the consistency analyzer's interval test accepts (it lies on the segment
// between the sampled velocities).
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

// Records [r0, r1) of a view.
template <class T>
V1<T> rows(V1<T> v, i64 r0, i64 r1) {
    return V1<T>{v.p + r0, r1 - r0};
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

void Scratch::make(i64 n_bodies, i64 n_geoms, const Statics& st) {
    i64 n1 = n_bodies + 1, nn = n_geoms + st.n_static;
    n = n_bodies;
    ns = st.n_static;
    zeroed(lo, nn, 3);
    zeroed(hi, nn, 3);
    for (i64 k = 0; k < ns; ++k)
        for (int c = 0; c < 3; ++c) {
            lo(n_geoms + k, c) = st.lo(k, c);
            hi(n_geoms + k, c) = st.hi(k, c);
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
    zeroed(exact_man, n1, 1);
    if (flow_c.rows != n || flow_c.cols != N_FLOW) flow_c = Buf2<double>(n, N_FLOW);
    flow_ok.resize(n);
    zeroed(ring, n1, 1);
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
    const Geoms gm = bd.geoms();
    i64 n = gm.n();  // the dynamic shape ids are geoms
    body_aabbs(gm, bd.inv_mass, bd.inv_inertia, awake, x.position, x.linear_momentum,
               x.rotation, x.angular_momentum, h, margin, sc.lo.view(), sc.hi.view(),
               col(sc.reach));
    i64 n_pairs = sweep_and_prune(n + st.n_static, n, sc.lo.view(), sc.hi.view(), gm.body,
                                  bd.group, awake, pairs);
    if (st.ground)
        n_pairs = ground_pairs(n, st.n_static, st.gn, st.goff, sc.lo.view(), sc.hi.view(), pairs,
                               n_pairs);
    return n_pairs;
}

// 3 wake: sleeping islands that an awake body may touch within the step. Returns islands woken.
i64 wake(const Bodies& bd, const Statics& st, const Settings& cfg, const SleepState& sl,
         const BodyState& x, double h, Scratch& sc, V2<i64> pairs, i64 n_pairs) {
    return wake_touched(pairs, n_pairs, bd.geom.n0, st.n_static, bd.geoms(), sl.awake,
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
    return collide_pairs(pairs, n_pairs, bd.geom.n0, st.n_static, bd.geoms(), awake,
                         x.position, x.rotation, col(sc.reach), cfg.speculative_distance, bd.restitution,
                         bd.friction, bd.accel, st.pos, st.rot, st.ext, st.e, st.mu, st.gn,
                         st.goff, st.g_e, st.g_mu, heads(c.mi0.view()), manifolds(c.mf0.view()),
                                                         points(c.pf0.view()),
                         col(c.pid0), col(c.keys0), col(c.idx0), c.n_man0, heads(c.mi1.view()),
                         manifolds(c.mf1.view()), points(c.pf1.view()), col(c.pid1),
                                   cfg.warm_starting, cfg.friction_anchor_distance, sc.cb);
}

// 5 prepare: load the bodies in contact into the solver arrays; effective masses and pre-solve
// gap velocities of every point.
void prepare(const Bodies& bd, const Settings& cfg, const BodyState& x, Scratch& sc,
             V1<ManifoldHead> mi,
             V1<Manifold> mf, V1<ContactPoint> pf, i64 n_man, double h) {
    load_bodies(mi, n_man, x.position.n0, cfg.iso_shortcut, bd.iso, bd.inv_mass, bd.inv_inertia,
                x.rotation, x.linear_momentum, x.angular_momentum, col(sc.in_contact),
                col(sc.bm), sc.bI.view(), sc.bv.view(), sc.bw.view(), sc.bv0.view(),
                sc.bw0.view(), sc.pv.view(), sc.pw.view(), sc.p0.view(), sc.l0.view());
    // a manifold's preparation writes only its own rows (mf, its points' pf): blocks of
    // manifolds on the pool (pf stays whole: a manifold's start indexes it)
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
void mark_pushed(V1<ManifoldHead> mi, V1<ContactPoint> pf, i64 n_man, i64 n, Scratch& sc) {
    V1<i64> pushed = col(sc.pushed), root = col(sc.push_root);
    for (i64 i = 0; i < n + 1; ++i) {
        pushed[i] = 0;
        root[i] = i;
    }
    for (i64 m = 0; m < n_man; ++m) {
        if (!mi[m].active) continue;
        i64 start = mi[m].start;
        bool push = false;
        for (i64 p = start; p < start + mi[m].count; ++p) {
            if (pf[p].ln != 0.0 || pf[p].l1 != 0.0 || pf[p].l2 != 0.0 ||
                pf[p].lp != 0.0) {
                push = true;
                break;
            }
        }
        if (!push) continue;
        i64 a = mi[m].a, b = mi[m].b;
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

// Whether manifold m pushed in this step's solve or relax (any accumulated normal, friction or
// pseudo impulse).
inline bool manifold_pushes(V1<ManifoldHead> mi, V1<ContactPoint> pf, i64 m) {
    i64 start = mi[m].start;
    for (i64 p = start; p < start + mi[m].count; ++p)
        if (pf[p].ln != 0.0 || pf[p].l1 != 0.0 || pf[p].l2 != 0.0 ||
            pf[p].lp != 0.0)
            return true;
    return false;
}

// The bodies that move exactly under their contact force (sc.exact_man, read by stage 9, with
// ContactParams.exact_contact_motion): a body whose one pushing manifold is against static
// geometry (the ground, a static box, a sleeping body: the solver's static dummy, row n) and
// none of whose points was struck (restitution's rule, struck()) gets that manifold's index;
// a body pushed by several manifolds, by another awake body or at an impact gets -2; every
// other body -1. See "Exact motion on one static surface" in the header comment.
void mark_exact(const Settings& cfg, V1<ManifoldHead> mi, V1<Manifold> mf, V1<ContactPoint> pf,
                i64 n_man, i64 n,
                Scratch& sc) {
    V1<i64> ex = col(sc.exact_man);
    for (i64 i = 0; i < n + 1; ++i) ex[i] = -1;
    for (i64 m = 0; m < n_man; ++m) {
        if (!mi[m].active || !manifold_pushes(mi, pf, m)) continue;
        i64 a = mi[m].a, b = mi[m].b;
        if (a != n && b != n) {
            ex[a] = -2;
            ex[b] = -2;
            continue;
        }
        bool hit = false;
        i64 start = mi[m].start;
        for (i64 p = start; p < start + mi[m].count; ++p)
            hit = hit || struck(pf[p].w0, pf[p].ln, mf[m].acc, pf[p].s,
                                cfg.restitution_threshold);
        i64 k = a == n ? b : a;
        ex[k] = ex[k] == -1 && !hit ? m : -2;
    }
}

// The exact motion's corrections to symplectic Euler for body i on its one static manifold m
// (mark_exact; header comment, "Exact motion on one static surface"): dx (3) the displacement
// to add to h (v + v'), dl (3) the angular momentum to add to the L the rotation drifts with.
// u, w: the body's velocity at the step's start (before the kick) and after the solve, n the
// manifold's normal, t the tangential part (x - (x . n) n).
//
// * At rest as far as the solve can tell (|u_t| + |w_start| r and |w_t| + |w_end| r both within
//   velocity_tolerance, r the bounding radius): no correction. Its velocities are the solve's
//   residual, not a motion under a constant force, and x += h w keeps rest still; a cylinder
//   standing on its cap on a 15 deg slope (a rolling pair: no friction anchor) settled over
//   0.17 s with the trapezoid on that residual instead of 0.05 s, 0.27 um past its 0.1 s pose.
// * On an edge or a corner (fewer than 3 points) of a pair that does not roll (not a sphere's or a
//   capsule's): no correction, the body tips or rocks under a varying force.
// * Stuck (an anchored pair, anchor_ok > 0, whose loaded points stick by the anchor's rule,
//   point_sticks) and not stopping: no correction. The anchor pass sets w_t = -rate D / h, a
//   position loop designed for x += h w_t; a trapezoid inside it (x += h (w_prev + w_t) / 2)
//   turns its decay into a damped oscillation (roots of z^2 - (1 - rate/2) z + rate/2: |z| =
//   0.5 at rate 0.5, complex), jitter on every resting box.
// * Sliding or rolling on (u_t . w_t > 0, or starting from u_t = 0): dx = h (u_t - w_t) / 2,
//   the trapezoid's x += h (u + w) / 2 in the tangent plane, exact for a constant force; and the
//   turn likewise, dl = I (w_start - w_new) / 2 with I = R I_body R^T, keeping only the part of
//   the change that moves no point of the manifold along n (the component of w orthogonal to
//   every r_p x n: a sphere's whole w, a lying capsule's about its axis and n, a face's spin
//   about n), so that the gaps the solve predicted, s + h w_n, hold.
// * Stopped inside the step: it slid along u_hat = u_t / |u_t| under kinetic friction,
//   deceleration d = mu sum(lambda_n) / (m h) - a_t . u_hat (a = g + F/m), which would end the
//   slide at t* = |u_t| / d < h, and the solve's w_t . u_hat <= |u_t| / 2 says it did (a body
//   rolling or driven on keeps its speed along u_hat or gains): it went on from rest to w_t at
//   a constant rate, displacement (u_t t* + w_t (h - t*)) / 2; no turn. An anchored pair stops
//   so only after a step of sliding (its anchor dropped), and is then re-anchored where it
//   stopped (anchor_ok = -1: collide takes the pose of the next step's start, and that step is
//   not a stop), since its anchor, taken at this step's start, would count the slide as slip.
// The sums over the step telescope: where nothing between steps changes the velocity (u of a
// step = w of the last), the trapezoid's corrections add up to h (w_first - w_last) / 2, so
// they cannot accumulate into creep.
inline void exact_correction(i64 i, i64 m, const Bodies& bd, const Settings& cfg,
                             const ExactInputs& ex, Scratch& sc, V3<double> rotation, double h,
                             double* dx, double* dl) {
    const V1<ManifoldHead> mi = ex.now.mi;
    const V1<Manifold> mf = ex.now.mf;
    V1<ContactPoint> pf = ex.now.pf;
    const double im = bd.inv_mass[i];
    const V2<double> bv = sc.bv.view(), bv0 = sc.bv0.view(), bw = sc.bw.view(),
                     bw0 = sc.bw0.view(), bI = sc.bI.view();
    const double nx = mf[m].normal[0], ny = mf[m].normal[1], nz = mf[m].normal[2];
    double u[3], w[3], a[3];
    for (int k = 0; k < 3; ++k) {
        a[k] = cfg.do_kick ? bd.accel(i, k) : 0.0;
        u[k] = bv0(i, k) - h * a[k];
        w[k] = bv(i, k);
    }
    const double un = u[0] * nx + u[1] * ny + u[2] * nz;
    const double wn = w[0] * nx + w[1] * ny + w[2] * nz;
    const double an = a[0] * nx + a[1] * ny + a[2] * nz;
    const double ut[3] = {u[0] - un * nx, u[1] - un * ny, u[2] - un * nz};
    const double wt[3] = {w[0] - wn * nx, w[1] - wn * ny, w[2] - wn * nz};
    const double at[3] = {a[0] - an * nx, a[1] - an * ny, a[2] - an * nz};
    const double uu = std::sqrt(ut[0] * ut[0] + ut[1] * ut[1] + ut[2] * ut[2]);
    const double uw = ut[0] * wt[0] + ut[1] * wt[1] + ut[2] * wt[2];
    dx[0] = dx[1] = dx[2] = 0.0;
    dl[0] = dl[1] = dl[2] = 0.0;
    const double mu = mf[m].mu;
    const i64 start = mi[m].start, end = start + mi[m].count;
    // at rest as far as the solve can tell: the tangential speed plus the turn rate times the
    // bounding radius within velocity_tolerance at both ends of the step
    {
        const double r = bd.radius[i];
        const double s0 = uu + r * std::sqrt(bw0(i, 0) * bw0(i, 0) + bw0(i, 1) * bw0(i, 1) +
                                             bw0(i, 2) * bw0(i, 2));
        const double s1 = std::sqrt(wt[0] * wt[0] + wt[1] * wt[1] + wt[2] * wt[2]) +
                          r * std::sqrt(bw(i, 0) * bw(i, 0) + bw(i, 1) * bw(i, 1) +
                                        bw(i, 2) * bw(i, 2));
        if (s0 <= cfg.velocity_tolerance && s1 <= cfg.velocity_tolerance) return;
    }
    // a rolling pair (a sphere's, a capsule's: collide gives every other pair an anchor) on any
    // points; any other on a face (3 or 4 points): on an edge or a corner a body is tipping or
    // rocking, and its contact force varies inside the step
    if (mf[m].anchor_ok > 0.0 && mi[m].count < 3) return;
    // An anchored pair (collide gives every pair but a rolling one an anchor, anchor_ok > 0) may
    // stop in this step only if it slid over the last one (warm started from a manifold whose
    // anchor store_impulses dropped, anchor_ok 0): not if it was held (anchor_ok > 0 then) or
    // stopped in the last step (anchor_ok -1, below), which the anchor's position loop owns.
    const bool anchored = cfg.static_friction_anchors && mf[m].anchor_ok > 0.0;
    bool may_stop = !anchored;
    if (anchored && cfg.warm_starting) {
        const i64 j = find_manifold(ex.prev_keys, ex.prev_idx, ex.prev_n, mi[m].key);
        may_stop = j >= 0 && ex.prev_mf[j].anchor_ok == 0.0;
    }
    if (may_stop && uu > 0.0 && uw <= 0.5 * uu * uu) {
        double ln = 0.0;
        for (i64 p = start; p < end; ++p) ln += pf[p].ln;
        const double d = mu * ln * im / h - (at[0] * ut[0] + at[1] * ut[1] + at[2] * ut[2]) / uu;
        if (d > 0.0 && uu < d * h) {
            const double ts = uu / d;
            for (int k = 0; k < 3; ++k)
                dx[k] = 0.5 * (ut[k] * ts + wt[k] * (h - ts)) - h * wt[k];
            if (anchored) mf[m].anchor_ok = -1.0;
            return;
        }
    }
    if (anchored) {
        for (i64 p = start; p < end; ++p)
            if (pf[p].ln > 0.0 &&
                point_sticks(pf[p].l1, pf[p].l2, mu, pf[p].ln,
                             cfg.friction_anchor_slide_frac))
                return;
    }
    for (int k = 0; k < 3; ++k) dx[k] = 0.5 * h * (ut[k] - wt[k]);
    // the turn: half the step's change of w (w_start = w0 - h I^-1 tau), less what moves a point
    const double* bi = bI.row(i);  // world inverse inertia (xx, yy, zz, xy, xz, yz)
    double tq[3] = {0.0, 0.0, 0.0};
    if (cfg.do_kick)
        for (int k = 0; k < 3; ++k) tq[k] = h * bd.torque(i, k);
    const double iw[3] = {bi[0] * tq[0] + bi[3] * tq[1] + bi[4] * tq[2],
                          bi[3] * tq[0] + bi[1] * tq[1] + bi[5] * tq[2],
                          bi[4] * tq[0] + bi[5] * tq[1] + bi[2] * tq[2]};
    double dw[3];
    for (int k = 0; k < 3; ++k) dw[k] = 0.5 * (bw0(i, k) - iw[k] - bw(i, k));
    // Gram-Schmidt over the points' r_p x n (r_p: the point from the body's centre), dropping
    // those below 1e-9 |r_p| (a sphere's r_p lies along n)
    double e[3][3];
    int ne = 0;
    const bool on_a = mi[m].a == i;
    for (i64 p = start; p < end && ne < 3; ++p) {
        const double* r = on_a ? pf[p].ra : pf[p].rb;
        const double rx = r[0], ry = r[1], rz = r[2];
        double c[3] = {ry * nz - rz * ny, rz * nx - rx * nz, rx * ny - ry * nx};
        for (int j = 0; j < ne; ++j) {
            const double cj = c[0] * e[j][0] + c[1] * e[j][1] + c[2] * e[j][2];
            for (int k = 0; k < 3; ++k) c[k] -= cj * e[j][k];
        }
        const double cc = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        if (cc <= 1e-9 * std::sqrt(rx * rx + ry * ry + rz * rz)) continue;
        for (int k = 0; k < 3; ++k) e[ne][k] = c[k] / cc;
        ne += 1;
    }
    for (int j = 0; j < ne; ++j) {
        const double dj = dw[0] * e[j][0] + dw[1] * e[j][1] + dw[2] * e[j][2];
        for (int k = 0; k < 3; ++k) dw[k] -= dj * e[j][k];
    }
    if (cfg.iso_shortcut && bd.iso[i]) {
        const double s0 = bd.inertia(i, 0);
        for (int k = 0; k < 3; ++k) dl[k] = s0 * dw[k];
    } else {
        Vec3 l = omega_world(load_mat(rotation, i), bd.inertia(i, 0), bd.inertia(i, 1),
                             bd.inertia(i, 2), dw[0], dw[1], dw[2]);
        for (int k = 0; k < 3; ++k) dl[k] = l[k];
    }
}

// 9 integrate: move every awake body over the step (how: sc.pushed, see mark_pushed). A body
// that a contact pushed (solve or relax) moves with the solver's velocity, x += h (v + v'), its
// momenta rebuilt from the solver's velocity changes, and when its island touches no static
// geometry, by - h^2 a / 2 more (the exact flight's term); every other body flies exactly under
// its constant acceleration a, x += h v - h^2 a / 2 with v after the kick (a body whose
// manifolds all ended without impulse gets its start-of-solve momenta back bitwise: warm
// starting applies and withdraws impulses, which leaves round-off). Rotation by the run's
// integrator (drift_rotation) with the body's L, plus the pseudo spin of the relax stage. The
// exact integrators rotate from the body's flow anchor (an; a new one whenever the L it drifts
// with changed).
void integrate_positions(int method, int ortho, const Bodies& bd, const Settings& cfg,
                         V1<i64> awake, const BodyState& x, Scratch& sc, double h,
                         const FlowAnchors& an, const ExactInputs* exact) {
    i64 n = x.position.n0;
    V1<i64> exact_man = col(sc.exact_man);
    V2<double> l_drift = sc.l_drift.view(), dx_step = sc.dx_step.view();
    V2<double> pv = sc.pv.view(), pw = sc.pw.view();
    V2<double> bv = sc.bv.view(), bw = sc.bw.view(), bv0 = sc.bv0.view(), bw0 = sc.bw0.view();
    V2<double> p0 = sc.p0.view(), l0 = sc.l0.view();
    V1<i64> in_contact = col(sc.in_contact), pushed_of = col(sc.pushed);
    V2<double> lm = x.linear_momentum, am = x.angular_momentum, pos = x.position;
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
            for (int k = 0; k < 3; ++k) {
                dx_step(i, k) = h * (lm(i, k) * im + pv(i, k) - fly * bd.accel(i, k));
                l_drift(i, k) = am(i, k);
            }
            if (exact && pushed_of[i] == 2 && exact_man[i] >= 0) {
                // on one static surface: exact under the constant contact force
                double ex[3], el[3];
                exact_correction(i, exact_man[i], bd, cfg, *exact, sc, x.rotation, h, ex, el);
                for (int k = 0; k < 3; ++k) {
                    dx_step(i, k) += ex[k];
                    l_drift(i, k) += el[k];
                }
            }
            for (int k = 0; k < 3; ++k) pos(i, k) += dx_step(i, k);
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
            V1<Manifold> mf, V1<i64> keys, V1<i64> idx, i64 n_man, const FlowAnchors& an) {
    i64 n_deep = project_positions(cfg, bd, st, awake, x, pairs, n_pairs, mf, keys, idx, n_man,
                                   sc);
    if (n_deep > 0)
        apply_projection(V1<ProjectPoint>{sc.proj_points.data(), n_deep}, sc.proj_dx.view(),
                         sc.proj_dth.view(), method, ortho, bd, cfg.iso_shortcut, x,
                         sc.l_drift.view(), an.anchor_steps);
    return n_deep;
}

// 13 sleep: wake what this step pushed on (when some bodies slept at the step's start, n_awake <
// N), advance rest timers, put resting islands to sleep. Returns (islands woken, bodies put to
// sleep).
std::pair<i64, i64> sleep_stage(const Bodies& bd, const Settings& cfg, const SleepState& sl,
                                const BodyState& x, Scratch& sc, V1<ManifoldHead> mi,
                                V1<Manifold> mf, V1<ContactPoint> pf, i64 n_man, double h,
                                i64 n_awake) {
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
                V1<i64> awake, V1<ManifoldHead> mi, V1<Manifold> mf, V1<ContactPoint> pf,
                i64 n_man, int method, int ortho, double h, const FlowAnchors& an, V1<i64> prof,
                i64& t) {
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
// A point's two anchors start at the one world point p (ra = p - x_a, rb = p - x_b at the
// step's start; pose0: (N, 12) each body's position and row-major rotation then) with the gap
// s along the normal n. Each anchor moves with its body's whole motion over the step, the
// project stage's pushes included: a_end = x_a + R_a R0_a^T r_a (b likewise; static geometry
// does not move), so the end-of-step gap is s + n . (a_end - b_end). The normal is the
// step's: its turn changes the gap only by turn x |a_end - b_end|, second order, since the
// anchors start together. (s_end, the solver's linear estimate s + h (v_n + v_n pseudo) read by
// the restitution and sleep stages, misses the project stage's pushes: up to 1.3 mm off the
// poses on samples/pile.toml's rows.) Returns n_log; the log may have grown.
i64 record_contacts(i64 s, V1<ManifoldHead> mi, V1<Manifold> mf, V1<ContactPoint> pf, i64 n_man,
                    V2<double> position, V3<double> rotation, V2<double> pose0,
                    Buf2<i64>& log_i, Buf2<double>& log_f, i64 n_log) {
    i64 need = n_log;
    for (i64 m = 0; m < n_man; ++m) need += mi[m].count;
    log_i.grow(need);
    log_f.grow(need);
    V1<ContactLogIds> ids = as_records<ContactLogIds>(log_i.view(), "log_i");
    V1<ContactLogValues> values = as_records<ContactLogValues>(log_f.view(), "log_f");
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
        i64 start = mi[m].start;
        i64 a = mi[m].rec_a, b = mi[m].rec_b;
        const double n[3] = {mf[m].normal[0], mf[m].normal[1], mf[m].normal[2]};
        for (i64 p = start; p < start + mi[m].count; ++p) {
            double da[3], db[3] = {0.0, 0.0, 0.0};
            moved(a, pf[p].ra, da);
            if (b >= 0) moved(b, pf[p].rb, db);
            double sep = pf[p].s + n[0] * (da[0] - db[0]) + n[1] * (da[1] - db[1]) +
                         n[2] * (da[2] - db[2]);
            if (pf[p].ln <= 0.0 && sep > 0.0) continue;
            ContactLogIds& li = ids[n_log];
            ContactLogValues& lf = values[n_log];
            li.step = s;
            li.a = a;
            li.b = b;
            li.kind = pf[p].impact > 0.0 ? CONTACT_IMPACT : CONTACT_RESTING;
            for (int k = 0; k < 3; ++k) {
                lf.point[k] = pf[p].point[k];
                lf.normal[k] = n[k];
                lf.friction[k] = pf[p].friction[k];
            }
            lf.separation = sep;
            lf.normal_impulse = pf[p].ln;
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
// rows, manifold.hpp's ContactLogIds / ContactLogValues). stats: (N_STATS,) counters. prof: (N_PROF,) int64 cycle
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
    sc.make(n, bd.geom.n0, st);
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
            colour_manifolds(heads(c.mi1.view()), n_man, n,
                             sc.graph);                          // 4b
            if (do_prof) t = lap(prof, P_COLOUR, t);
            V1<ManifoldHead> mi1 = heads(c.mi1.view());
            V1<Manifold> mf1 = manifolds(c.mf1.view());
    V1<ContactPoint> pf1 = points(c.pf1.view());
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
            if (cfg.exact_contact_motion) mark_exact(cfg, mi1, mf1, pf1, n_man, n, sc);
            if (do_prof) t = lap(prof, P_RELAX, t);
            const ExactInputs exact{cons, manifolds(c.mf0.view()), col(c.keys0), col(c.idx0),
                                                    c.n_man0};
            integrate_positions(method, ortho, bd, cfg, sl.awake, x, sc, h, an,             // 9
                                cfg.exact_contact_motion ? &exact : nullptr);
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
                                               n_pairs, manifolds(c.mf0.view()), col(c.keys0),
                                               col(c.idx0), c.n_man0, an);
            if (do_prof) t = lap(prof, P_PROJECT, t);
            if (cfg.do_sleep) {                                                             // 13
                std::pair<i64, i64> ws = sleep_stage(bd, cfg, sl, x, sc, heads(c.mi0.view()),
                                                     manifolds(c.mf0.view()),
                                                               points(c.pf0.view()), c.n_man0, h,
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
            n_log = record_contacts(s, heads(c.mi0.view()), manifolds(c.mf0.view()),
                                    points(c.pf0.view()), c.n_man0,
                                    x.position, x.rotation, c.pose0.view(), c.log_i, c.log_f,
                                    n_log);
            if (do_prof) t = lap(prof, P_SAMPLE, t);
        }
    }
    for (i64 i = 0; i < n; ++i) sync_quat(method, x.quat_wxyz, x.rotation, i);
    return AdvanceResult{n_samples, -1, -1, n_log};
}

}  // namespace rb
