// The contact solver's stages (contact_solver.cpp, relax.cpp, restitution.cpp, project.cpp), in
// the order the world step calls them; the derivations are in contact_solver.cpp's header
// comment. Each mirrors the Python function of the same name (rblog/engine/contact/solver.py,
// relax.py, restitution.py, project.py): the same parameters in the same order; the module-level
// tolerances those read from rblog.engine.constants come last, as arguments (their one home stays
// constants.py; the world step passes them from its Settings).
//
// Shapes: mi (M, MI_COLS) int64, mf (M, MF_COLS), pf (K, PF_COLS) (manifold.hpp's columns);
// per-body solver arrays have N+1 rows, row N the static dummy (zero inverse mass): bm (N+1,),
// bI (N+1, 6) world inverse inertia (xx, yy, zz, xy, xz, yz), bv/bw (N+1, 3) world velocity and
// angular velocity.
#pragma once

#include <cstddef>  // size_t, which common/array.hpp uses

#include "common/array.hpp"

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

// ---- solver.py -----------------------------------------------------------------------------

void load_bodies(V2<i64> mi, i64 n_man, i64 n_dyn, bool iso_shortcut, V1<i64> iso,
                 V1<double> inv_mass, V2<double> inv_inertia, V3<double> rotation,
                 V2<double> linear_momentum, V2<double> angular_momentum, V1<i64> in_contact,
                 V1<double> bm, V2<double> bI, V2<double> bv, V2<double> bw, V2<double> bv0,
                 V2<double> bw0, V2<double> pv, V2<double> pw, V2<double> p0, V2<double> l0);

// anchor_rate: FRICTION_ANCHOR_RATE, block_reg: BLOCK_REG (constants.py)
void prepare_contacts(V2<i64> mi, V2<double> mf, V2<double> pf, i64 n_man, V1<double> bm,
                      V2<double> bI, V2<double> bv, V2<double> bw, double h, double anchor_rate,
                      double block_reg);

void warm_start(V2<i64> mi, V2<double> mf, V2<double> pf, i64 n_man, V1<double> bm,
                V2<double> bI, V2<double> bv, V2<double> bw);

// Apply each active point's stored impulse, its (normal, t1, t2) components at
// lam[lam_stride p + 0..2], to its manifold's bodies (warm_start's loop; the soft step's).
void apply_stored_impulses(V2<i64> mi, V2<double> mf, V2<double> pf, i64 n_man, V1<double> bm,
                           V2<double> bI, V2<double> bv, V2<double> bw, const double* lam,
                           i64 lam_stride);

// newton_iters, newton_tol: FRICTION_NEWTON_ITERS, FRICTION_NEWTON_TOL; g: the colouring of
// the active manifolds (constraint_graph.hpp), lanes: work buffers. Returns the full-sweep
// equivalents (at least 1).
i64 solve_velocities(V2<i64> mi, V2<double> mf, V2<double> pf, i64 n_man, V1<double> bm,
                     V2<double> bI, V2<double> bv, V2<double> bw, double inv_h, i64 min_iter,
                     i64 max_iter, double tol, V1<i64> hot, V1<i64> degree, double sor,
                     i64 newton_iters, double newton_tol, const ConstraintGraph& g,
                     SolverLanes& lanes);

void anchor_friction(V2<i64> mi, V2<double> mf, V2<double> pf, i64 n_man, V1<double> bm,
                     V2<double> bI, V2<double> bv, V2<double> bw, i64 newton_iters,
                     double newton_tol);

// slide_frac: FRICTION_ANCHOR_SLIDE_FRAC
void store_impulses(V2<i64> mi, V2<double> mf, V2<double> pf, i64 n_man, double slide_frac);

// ---- relax.py ------------------------------------------------------------------------------

void relax_positions(V2<i64> mi, V2<double> mf, V2<double> pf, i64 n_man, V1<double> bm,
                     V2<double> bI, V2<double> pv, V2<double> pw, double inv_h, i64 n_iter,
                     double slop, double beta, double max_speed);

// ---- restitution.py ------------------------------------------------------------------------

i64 restitution(V2<i64> mi, V2<double> mf, V2<double> pf, i64 n_man, V1<double> bm,
                V2<double> bI, V2<double> bv, V2<double> bw, V2<double> pv, V2<double> pw,
                double h, double threshold, i64 n_iter, V2<double> dx,
                V2<double> linear_momentum, V2<double> angular_momentum);

}  // namespace rb
