// Column layout of the packed contact arrays (Box2D's contact constraints, as SoA rows), and the
// manifold reduction (manifold.cpp).
//
// The documented home of every constant below; rblog/engine/contact/manifold.py reads them by
// name from _core.collision_layout() (tests/engine/contact/test_collision_core.py checks that the
// columns tile each array with the widths given here).
//
// Three arrays hold the manifolds of one step; a second set holds the previous step's, for warm
// starting and for manifolds of sleeping bodies, which are carried over unchanged.
//
// * mi (M, MI_COLS) int64 per manifold: pair key, solver body indices, record body indices,
//   first point, point count, active flag.
// * mf (M, MF_COLS) float64 per manifold: normal and tangent basis (world), friction,
//   restitution, relative normal acceleration from the external forces.
// * pf (K, PF_COLS) float64 per point, pid (K,) int64 feature ids.
//
// Frames and signs: the normal points from body b into body a; anchors ra/rb are the world
// offsets of the contact point from the centres of mass at the narrowphase; a positive normal
// impulse pushes a along +normal and b along -normal; the friction impulse f is the world vector
// applied to a (b gets -f). Solver body index n_bodies is a static dummy (zero inverse mass, zero
// velocity) standing for the ground, static boxes and sleeping bodies.
#pragma once

#include <cstddef>  // size_t, which common/array.hpp uses

#include "common/array.hpp"

namespace rb {

// ---- per manifold, int64 ----
constexpr i64 MI_KEY = 0;     // 2 (lo * n_shapes + hi) + part; shape ids: bodies, static boxes,
                              // ground; part 1 is a box pair's second manifold (face manifold
                              // beside an edge contact)
constexpr i64 MI_A = 1;       // solver index of body a (or the static dummy)
constexpr i64 MI_B = 2;       // solver index of body b (or the static dummy)
constexpr i64 MI_REC_A = 3;   // body index of a for the record
constexpr i64 MI_REC_B = 4;   // body index of b, or STATIC_BODY (-1)
constexpr i64 MI_START = 5;   // first point
constexpr i64 MI_COUNT = 6;   // number of points (1..4)
constexpr i64 MI_ACTIVE = 7;  // 1: solved this step; 0: carried over (both sides asleep or static)
constexpr i64 MI_COLS = 8;

// ---- per manifold, float64 ----
constexpr i64 MF_N = 0;      // normal (3), from b into a
constexpr i64 MF_T1 = 3;     // first tangent (3)
constexpr i64 MF_T2 = 6;     // second tangent (3) = n x t1
constexpr i64 MF_MU = 9;     // friction coefficient sqrt(mu_a mu_b)
constexpr i64 MF_E = 10;     // restitution max(e_a, e_b)
constexpr i64 MF_ACC = 11;   // gap acceleration from external forces: n . (a_a - a_b) (m/s^2)
constexpr i64 MF_LU = 12;    // LU factors of the regularised normal block (4 x 4, row-major)
constexpr i64 MF_PIV = 28;   // pivot row of each elimination column (4, as floats)
constexpr i64 MF_LUOK = 32;  // 1.0: the block factored (non-singular), else 0.0
constexpr i64 MF_AR = 33;    // friction anchor: pose of a in b's frame when the pair started
                             // sticking: R_b^T R_a (9, row-major) ...
constexpr i64 MF_AT = 42;    // ... and R_b^T (x_a - x_b) (3), m (b's frame: the world for the
                             // ground)
constexpr i64 MF_AOK = 45;   // 1.0: the anchor pose holds (collide sets it, store_impulses drops
                             // it), else 0.0; -1.0: dropped by stage 9's exact motion, the pair
                             // stopped inside the step (world_step.cpp, exact_correction)
constexpr i64 MF_COLS = 46;

// ---- per point, float64 ----
constexpr i64 PF_P = 0;        // contact point (3), world, midpoint of the surfaces
constexpr i64 PF_RA = 3;       // anchor on a (3): point - x_a
constexpr i64 PF_RB = 6;       // anchor on b (3): point - x_b (0 for static)
constexpr i64 PF_S = 9;        // separation at the narrowphase (m), < 0 penetration
constexpr i64 PF_NMASS = 10;   // 1 / (J M^-1 J^T) along the normal
constexpr i64 PF_TK = 11;      // 2x2 tangent block of the effective inverse mass K (k11, k12, k22)
constexpr i64 PF_LN = 14;      // accumulated normal impulse (N s)
constexpr i64 PF_L1 = 15;      // accumulated friction impulse along t1
constexpr i64 PF_L2 = 16;      // ... along t2
constexpr i64 PF_LP = 17;      // accumulated pseudo impulse of the position correction
constexpr i64 PF_LWS = 18;     // normal impulse of the velocity solve (before restitution): next
                               // step's warm start
constexpr i64 PF_W0 = 19;      // normal velocity of the gap at the start of the step (m/s)
constexpr i64 PF_F = 20;       // friction impulse on a, world (3)
constexpr i64 PF_SEND = 23;    // separation estimated at the end of the step (m)
constexpr i64 PF_IMPACT = 24;  // 1.0 if the point was an impact (approach speed above threshold)
constexpr i64 PF_WT = 25;      // restitution's target gap velocity (m/s), < 0: does not bounce
constexpr i64 PF_KN = 26;      // row of the manifold's normal block K_ij (4: one per point)
constexpr i64 PF_D = 30;       // friction anchor: slip of a's material point at the contact since
                               // the pair started sticking (3), world, m (collide)
constexpr i64 PF_DB = 33;      // the anchor's bias, FRICTION_ANCHOR_RATE (D.t1, D.t2) / h (2)
constexpr i64 PF_COLS = 35;

// ---- contact log columns (the kernels append rows at sampled steps) ----
constexpr i64 LOG_STEP = 0, LOG_A = 1, LOG_B = 2, LOG_KIND = 3;
constexpr i64 LOG_I_COLS = 4;
constexpr i64 LOG_P = 0, LOG_N = 3, LOG_S = 6, LOG_LN = 7, LOG_F = 8;
constexpr i64 LOG_F_COLS = 11;

// ---- collider point buffers ----
// rows of the collider's point buffer: a first manifold (rows 0..3 after reduction, up to 8 while
// clipping) and a box pair's second manifold (rows 4.., up to 8 while clipping)
constexpr i64 MAX_CLIP_POINTS = 12;
constexpr i64 MAX_MANIFOLD_POINTS = 4;
// m^2: triangle areas (about the normal) below this add nothing to a manifold (collinear points)
// (manifold.py's _AREA_EPS: a geometric epsilon of the reduction, not an engine tolerance)
constexpr double AREA_EPS = 1e-12;

// Exchange points i and j of a collider's output (point, separation, feature id).
inline void swap_point(double (*pts)[3], double* sep, i64* fid, i64 i, i64 j) {
    if (i == j) return;
    for (int k = 0; k < 3; ++k) {
        double t = pts[i][k];
        pts[i][k] = pts[j][k];
        pts[j][k] = t;
    }
    double t = sep[i];
    sep[i] = sep[j];
    sep[j] = t;
    i64 f = fid[i];
    fid[i] = fid[j];
    fid[j] = f;
}

// Keep four of `count` coplanar-ish points (manifold.cpp). Returns the new count (<= 4).
i64 reduce_manifold(const double* nrm, double (*pts)[3], double* sep, i64* fid, i64 count);

}  // namespace rb
