// The contact solver's stages (contact_solver.cpp, relax.cpp, restitution.cpp, project.cpp), in
// the order the world step calls them; the derivations are in contact_solver.cpp's header
// comment. The tests call each from Python (bind_contact.cpp); the tolerances they read reach
// them in the Settings (their one home stays constants.py).
//
// Records: the constraints' heads, manifolds and points (manifold.hpp, step_context.hpp);
// per-body solver arrays have N+1 rows, row N the static dummy (zero inverse mass): bm (N+1,),
// bI (N+1, 6) world inverse inertia (xx, yy, zz, xy, xz, yz), bv/bw (N+1, 3) world velocity and
// angular velocity.
#pragma once

#include <cstddef>  // size_t, which common/array.hpp uses

#include "common/array.hpp"
#include "engine/constraint_row.hpp"
#include "engine/step_context.hpp"

namespace rb {

struct ConstraintGraph;
struct SolverLanes;

// ---- the one place an impulse acts on a pair ---------------------------------------------------

// A manifold's two bodies while a stage applies impulses to them, held in locals (registers):
// rows ia, ib of the solver's bodies, their inverse masses, world inverse inertias (xx, yy, zz,
// xy, xz, yz) and velocities. apply() is constraint_row.hpp's impulse_row on them (the velocity
// solve's lanes run the same template); store() writes the velocities back.
struct BodyPair {
    i64 ia, ib;
    double ma, mb;
    double a6[6], b6[6];
    double va[3], wa[3], vb[3], wb[3];

    BodyPair(const SolverBodies& b, i64 ia_, i64 ib_) : ia(ia_), ib(ib_) {
        ma = b.inv_mass[ia];
        mb = b.inv_mass[ib];
        for (int k = 0; k < 6; ++k) {
            a6[k] = b.inv_inertia(ia, k);
            b6[k] = b.inv_inertia(ib, k);
        }
        for (int k = 0; k < 3; ++k) {
            va[k] = b.v(ia, k);
            wa[k] = b.w(ia, k);
            vb[k] = b.v(ib, k);
            wb[k] = b.w(ib, k);
        }
    }
    // +P at anchor r_a on a, -P at r_b on b (world, N s)
    void apply(double rax, double ray, double raz, double rbx, double rby, double rbz, double px,
               double py, double pz) {
        const double ra[3] = {rax, ray, raz}, rb[3] = {rbx, rby, rbz};
        impulse_row<double, ScalarLane>(
            true, ma, [this](int k) { return a6[k]; }, mb, [this](int k) { return b6[k]; }, ra,
            rb, px, py, pz, va, wa, vb, wb);
    }
    // the velocity of a's material point at a + r_a relative to b's at b + r_b
    void relative_velocity(double rax, double ray, double raz, double rbx, double rby, double rbz,
                           double& dvx, double& dvy, double& dvz) const {
        const double ra[3] = {rax, ray, raz}, rb[3] = {rbx, rby, rbz};
        gap_velocity<double, ScalarLane>(va, wa, vb, wb, ra, rb, dvx, dvy, dvz);
    }
    void store(const SolverBodies& b) const {
        for (int k = 0; k < 3; ++k) {
            b.v(ia, k) = va[k];
            b.w(ia, k) = wa[k];
            b.v(ib, k) = vb[k];
            b.w(ib, k) = wb[k];
        }
    }
};

// ---- contact_solver.cpp ---------------------------------------------------------------------
// Each stage reads the step's context (h, 1/h, the settings: step_context.hpp), the contact
// constraints and the solver's bodies, whose velocities it updates in place.

void load_bodies(V1<ManifoldHead> mi, i64 n_man, i64 n_dyn, bool iso_shortcut, V1<i64> iso,
                 V1<double> inv_mass, V2<double> inv_inertia, V3<double> rotation,
                 V2<double> linear_momentum, V2<double> angular_momentum, V1<i64> in_contact,
                 V1<double> bm, V2<double> bI, V2<double> bv, V2<double> bw, V2<double> bv0,
                 V2<double> bw0, V2<double> pv, V2<double> pw, V2<double> p0, V2<double> l0);

// settings: friction_anchor_rate, block_reg
void prepare_contacts(const StepContext& ctx, const ContactConstraints& c, const SolverBodies& b);

void warm_start(const ContactConstraints& c, const SolverBodies& b);

// Apply each active point's stored impulse, its (normal, t1, t2) components at
// lam[lam_stride p + 0..2], to its manifold's bodies (warm_start's loop; the soft step's).
void apply_stored_impulses(const ContactConstraints& c, const SolverBodies& b, const double* lam,
                           i64 lam_stride);

// settings: velocity_iterations, max_velocity_iterations, velocity_tolerance, over_relaxation,
// friction_newton_iters, friction_newton_tol. hot: (N+1,) work marks, degree: (N+1,) active
// manifolds per body; g: the colouring of the active manifolds (constraint_graph.hpp), lanes:
// work buffers. Returns the full-sweep equivalents (at least 1).
i64 solve_velocities(const StepContext& ctx, const ContactConstraints& c, const SolverBodies& b,
                     V1<i64> hot, V1<i64> degree, const ConstraintGraph& g, SolverLanes& lanes);

// settings: friction_newton_iters, friction_newton_tol
void anchor_friction(const StepContext& ctx, const ContactConstraints& c, const SolverBodies& b);

// settings: friction_anchor_slide_frac
void store_impulses(const StepContext& ctx, const ContactConstraints& c);

// ---- relax.cpp -----------------------------------------------------------------------------

// pseudo: the solver's bodies with the pseudo velocities (pv, pw) for v and w. settings:
// position_iterations, allowed_penetration, position_correction_rate, max_correction_speed
void relax_positions(const StepContext& ctx, const ContactConstraints& c,
                     const SolverBodies& pseudo);

// Whether a loaded point's friction (l1, l2 along the tangents) sticks: strictly inside the
// Coulomb disc shrunk by slide_frac (FRICTION_ANCHOR_SLIDE_FRAC), the anchor's rule
// (store_impulses).
inline bool point_sticks(double l1, double l2, double mu, double ln, double slide_frac) {
    const double fmax = mu * ln;
    const double lim = (1.0 - slide_frac) * fmax;
    return fmax > 0.0 && l1 * l1 + l2 * l2 < lim * lim;
}

// ---- restitution.cpp -----------------------------------------------------------------------

// Whether a point was struck this step (restitution's impact, known once the solve ended): its
// solve impulse ln is positive, its gap was closing at the start (its w0 < 0) and the approach
// speed at contact from the flight's energy, u^2 = w0^2 - 2 acc s0 (the manifold's acc, the
// point's s as s0), exceeds the threshold.
inline bool struck(double w0, double ln, double acc, double s0, double threshold) {
    if (w0 >= 0.0 || ln <= 0.0) return false;
    return w0 * w0 - 2.0 * acc * s0 > threshold * threshold;
}

// pv, pw: (N+1, 3) the relax stage's pseudo velocities; dx: (N+1, 3) each body's displacement
// this step; the bounces go into linear_momentum, angular_momentum (N, 3). settings:
// restitution_threshold, velocity_iterations (the bounce's sweeps)
i64 restitution(const StepContext& ctx, const ContactConstraints& c, const SolverBodies& b,
                V2<double> pv, V2<double> pw, V2<double> dx, V2<double> linear_momentum,
                V2<double> angular_momentum);

}  // namespace rb
