// The contact solver's stages (contact_solver.cpp, relax.cpp, restitution.cpp, project.cpp), in
// the order the world step calls them; the derivations are in contact_solver.cpp's header
// comment. Python calls each through rblog/engine/contact/solver.py, relax.py, restitution.py
// (for tests); the tolerances they read reach them in the Settings (their one home stays
// constants.py).
//
// Shapes: mi (M, MI_COLS) int64, mf (M, MF_COLS), pf (K, PF_COLS) (manifold.hpp's columns);
// per-body solver arrays have N+1 rows, row N the static dummy (zero inverse mass): bm (N+1,),
// bI (N+1, 6) world inverse inertia (xx, yy, zz, xy, xz, yz), bv/bw (N+1, 3) world velocity and
// angular velocity.
#pragma once

#include <cstddef>  // size_t, which common/array.hpp uses

#include "common/array.hpp"
#include "engine/step_context.hpp"

namespace rb {

struct ConstraintGraph;
struct SolverLanes;

// ---- the one place an impulse acts on a pair ---------------------------------------------------

// +P on body a at anchor r_a, -P on body b at r_b: velocity changes m^-1 P and I_world^-1 (r x P),
// so the pair's linear momentum and its angular momentum about any point are unchanged to
// round-off. ma/mb inverse masses (0 for the static dummy), a6/b6 world inverse inertias (xx, yy,
// zz, xy, xz, yz), r_a/r_b anchors and p the impulse (world, N s); the bodies' velocities are
// updated in place (callers keep them in locals, i.e. registers).
inline void apply_impulse(double ma, const double* a6, double mb, const double* b6, double rax,
                          double ray, double raz, double rbx, double rby, double rbz, double px,
                          double py, double pz, double& vax, double& vay, double& vaz,
                          double& wax, double& way, double& waz, double& vbx, double& vby,
                          double& vbz, double& wbx, double& wby, double& wbz) {
    double cx = ray * pz - raz * py, cy = raz * px - rax * pz, cz = rax * py - ray * px;
    double ex = a6[0] * cx + a6[3] * cy + a6[4] * cz;
    double ey = a6[3] * cx + a6[1] * cy + a6[5] * cz;
    double ez = a6[4] * cx + a6[5] * cy + a6[2] * cz;
    vax = vax + ma * px;
    vay = vay + ma * py;
    vaz = vaz + ma * pz;
    wax = wax + ex;
    way = way + ey;
    waz = waz + ez;
    cx = rby * pz - rbz * py;
    cy = rbz * px - rbx * pz;
    cz = rbx * py - rby * px;
    ex = b6[0] * cx + b6[3] * cy + b6[4] * cz;
    ey = b6[3] * cx + b6[1] * cy + b6[5] * cz;
    ez = b6[4] * cx + b6[5] * cy + b6[2] * cz;
    vbx = vbx - mb * px;
    vby = vby - mb * py;
    vbz = vbz - mb * pz;
    wbx = wbx - ex;
    wby = wby - ey;
    wbz = wbz - ez;
}

// A manifold's two bodies while a stage applies impulses to them, held in locals (registers):
// rows ia, ib of the solver's bodies, their inverse masses, world inverse inertias (xx, yy, zz,
// xy, xz, yz) and velocities. apply() is apply_impulse on them; store() writes the velocities
// back.
struct BodyPair {
    i64 ia, ib;
    double ma, mb;
    double a6[6], b6[6];
    double vax, vay, vaz, wax, way, waz, vbx, vby, vbz, wbx, wby, wbz;

    BodyPair(const SolverBodies& b, i64 ia_, i64 ib_) : ia(ia_), ib(ib_) {
        ma = b.inv_mass[ia];
        mb = b.inv_mass[ib];
        for (int k = 0; k < 6; ++k) {
            a6[k] = b.inv_inertia(ia, k);
            b6[k] = b.inv_inertia(ib, k);
        }
        vax = b.v(ia, 0); vay = b.v(ia, 1); vaz = b.v(ia, 2);
        wax = b.w(ia, 0); way = b.w(ia, 1); waz = b.w(ia, 2);
        vbx = b.v(ib, 0); vby = b.v(ib, 1); vbz = b.v(ib, 2);
        wbx = b.w(ib, 0); wby = b.w(ib, 1); wbz = b.w(ib, 2);
    }
    void apply(double rax, double ray, double raz, double rbx, double rby, double rbz, double px,
               double py, double pz) {
        apply_impulse(ma, a6, mb, b6, rax, ray, raz, rbx, rby, rbz, px, py, pz, vax, vay, vaz,
                      wax, way, waz, vbx, vby, vbz, wbx, wby, wbz);
    }
    // the velocity of a's material point at a + r_a relative to b's at b + r_b:
    // v_a + w_a x r_a - v_b - w_b x r_b
    void relative_velocity(double rax, double ray, double raz, double rbx, double rby, double rbz,
                           double& dvx, double& dvy, double& dvz) const {
        dvx = vax + way * raz - waz * ray - vbx - wby * rbz + wbz * rby;
        dvy = vay + waz * rax - wax * raz - vby - wbz * rbx + wbx * rbz;
        dvz = vaz + wax * ray - way * rax - vbz - wbx * rby + wby * rbx;
    }
    void store(const SolverBodies& b) const {
        b.v(ia, 0) = vax; b.v(ia, 1) = vay; b.v(ia, 2) = vaz;
        b.w(ia, 0) = wax; b.w(ia, 1) = way; b.w(ia, 2) = waz;
        b.v(ib, 0) = vbx; b.v(ib, 1) = vby; b.v(ib, 2) = vbz;
        b.w(ib, 0) = wbx; b.w(ib, 1) = wby; b.w(ib, 2) = wbz;
    }
};

// ---- solver.py -----------------------------------------------------------------------------
// Each stage reads the step's context (h, 1/h, the settings: step_context.hpp), the contact
// constraints and the solver's bodies, whose velocities it updates in place.

void load_bodies(V2<i64> mi, i64 n_man, i64 n_dyn, bool iso_shortcut, V1<i64> iso,
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

// ---- relax.py ------------------------------------------------------------------------------

// pseudo: the solver's bodies with the pseudo velocities (pv, pw) for v and w. settings:
// position_iterations, allowed_penetration, position_correction_rate, max_correction_speed
void relax_positions(const StepContext& ctx, const ContactConstraints& c,
                     const SolverBodies& pseudo);

// ---- restitution.py ------------------------------------------------------------------------

// pv, pw: (N+1, 3) the relax stage's pseudo velocities; dx: (N+1, 3) each body's displacement
// this step; the bounces go into linear_momentum, angular_momentum (N, 3). settings:
// restitution_threshold, velocity_iterations (the bounce's sweeps)
i64 restitution(const StepContext& ctx, const ContactConstraints& c, const SolverBodies& b,
                V2<double> pv, V2<double> pw, V2<double> dx, V2<double> linear_momentum,
                V2<double> angular_momentum);

}  // namespace rb
