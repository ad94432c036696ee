// The contact constraints' records (Box2D's contact constraints: a manifold's head, its frame
// and solver data, its points), the contact log's columns, and the manifold reduction
// (manifold.cpp).
//
// The documented home of every field below; rblog/engine/contact/manifold.py reads the records'
// fields by name from _core.contact_fields() (tests/engine/contact/test_collision_core.py checks
// that the listed fields tile each record).
//
// Three arrays hold the manifolds of one step; a second set holds the previous step's, for warm
// starting and for manifolds of sleeping bodies, which are carried over unchanged.
//
// * mi (M, MI_COLS) int64, a ManifoldHead per row: pair key, solver body indices, record body
//   indices, first point, point count, active flag.
// * mf (M, MF_COLS) float64, a Manifold per row: normal and tangent basis (world), friction,
//   restitution, relative normal acceleration from the external forces, the normal block's
//   factors, the friction anchor.
// * pf (K, PF_COLS) float64, a ContactPoint per row; pid (K,) int64 feature ids.
//
// Frames and signs: the normal points from body b into body a; anchors ra/rb are the world
// offsets of the contact point from the centres of mass at the narrowphase; a positive normal
// impulse pushes a along +normal and b along -normal; the friction impulse is the world vector
// applied to a (b gets its negative). Solver body index n_bodies is a static dummy (zero inverse
// mass, zero velocity) standing for the ground, static boxes and sleeping bodies.
#pragma once

#include <cstddef>  // size_t, which common/array.hpp uses

#include <stdexcept>
#include <string>

#include "common/array.hpp"

namespace rb {

// ---- the records ------------------------------------------------------------------------------
// A row of mi is a ManifoldHead, a row of mf a Manifold, a row of pf a ContactPoint: the buffers
// are rows of MI_COLS int64 / MF_COLS and PF_COLS float64 values, read through these structs
// (heads(), manifolds(), points() below); Python reads the same rows by field name through numpy
// structured dtypes built from contact_fields() (bind_collision.cpp).

// per manifold, int64
struct ManifoldHead {
    i64 key;     // 2 (lo * n_shapes + hi) + part; shape ids: bodies, static boxes, ground; part 1
                 // is a box pair's second manifold (face manifold beside an edge contact)
    i64 a;       // solver index of body a (or the static dummy)
    i64 b;       // solver index of body b (or the static dummy)
    i64 rec_a;   // body index of a for the record
    i64 rec_b;   // body index of b, or STATIC_BODY (-1)
    i64 start;   // first point
    i64 count;   // number of points (1..4)
    i64 active;  // 1: solved this step; 0: carried over (both sides asleep or static)
};

// per manifold, float64
struct Manifold {
    double normal[3];      // from b into a, world
    double t1[3];          // first tangent, world
    double t2[3];          // second tangent = normal x t1
    double mu;             // friction coefficient sqrt(mu_a mu_b)
    double e;              // restitution max(e_a, e_b)
    double acc;            // gap acceleration from external forces: n . (a_a - a_b) (m/s^2)
    double lu[16];         // LU factors of the regularised normal block (4 x 4, row-major)
    double piv[4];         // pivot row of each elimination column (as floats)
    double lu_ok;          // 1.0: the block factored (non-singular), else 0.0
    double anchor_rot[9];  // friction anchor: pose of a in b's frame when the pair started
                           // sticking: R_b^T R_a (row-major) ...
    double anchor_pos[3];  // ... and R_b^T (x_a - x_b), m (b's frame: the world for the ground)
    double anchor_ok;      // 1.0: the anchor pose holds (collide sets it, store_impulses drops
                           // it), else 0.0; -1.0: dropped by stage 9's exact motion, the pair
                           // stopped inside the step (world_step.cpp, exact_correction)
};

// per point, float64
struct ContactPoint {
    double point[3];        // contact point, world, midpoint of the surfaces
    double ra[3];           // anchor on a: point - x_a
    double rb[3];           // anchor on b: point - x_b (0 for static)
    double s;               // separation at the narrowphase (m), < 0 penetration
    double normal_mass;     // 1 / (J M^-1 J^T) along the normal
    double tangent_k[3];    // 2x2 tangent block of the effective inverse mass K (k11, k12, k22)
    double ln;              // accumulated normal impulse (N s)
    double l1;              // accumulated friction impulse along t1 (N s)
    double l2;              // ... along t2
    double lp;              // accumulated pseudo impulse of the position correction
    double lws;             // normal impulse of the velocity solve (before restitution): next
                            // step's warm start
    double w0;              // normal velocity of the gap at the start of the step (m/s)
    double friction[3];     // friction impulse on a, world (N s)
    double s_end;           // separation estimated at the end of the step (m)
    double impact;          // 1.0 if the point was an impact (approach speed above threshold)
    double wt;              // restitution's target gap velocity (m/s), < 0: does not bounce
    double kn[4];           // row of the manifold's normal block K_ij (one per point)
    double slip[3];         // friction anchor: slip of a's material point at the contact since
                            // the pair started sticking, world, m (collide)
    double slip_bias[2];    // the anchor's bias, FRICTION_ANCHOR_RATE (D.t1, D.t2) / h
};

// per point of the project stage (project.cpp), rebuilt every step from the end-of-step poses
struct ProjectPoint {
    i64 a;                // solver index of body a (or the static dummy)
    i64 b;                // solver index of body b (or the static dummy)
    double normal[3];     // from b into a, world
    double ra[3];         // anchor on a: point - x_a
    double rb[3];         // anchor on b: point - x_b (0 for static)
    double s;             // separation at the end of the step (m), before the pass
    double normal_mass;   // 1 / (J M^-1 J^T) along the normal (kg)
    double lambda;        // accumulated position impulse (kg m), >= 0
};

// A record's 3-vector field v = (x, y, z).
inline void set3(double* v, double x, double y, double z) {
    v[0] = x;
    v[1] = y;
    v[2] = z;
}

// the buffers' row widths
constexpr i64 MI_COLS = (i64)(sizeof(ManifoldHead) / sizeof(i64));
constexpr i64 MF_COLS = (i64)(sizeof(Manifold) / sizeof(double));
constexpr i64 PF_COLS = (i64)(sizeof(ContactPoint) / sizeof(double));
static_assert(MI_COLS == 8 && MF_COLS == 46 && PF_COLS == 35, "records without padding");

// A buffer's rows as records (the view's width must be the record's: a wrong one is a
// std::invalid_argument naming the array, a ValueError in Python).
template <class R, class T>
inline V1<R> as_records(V2<T> v, const char* name) {
    if (v.n1 * (i64)sizeof(T) != (i64)sizeof(R))
        throw std::invalid_argument(std::string(name) + ": expected " +
                                    std::to_string(sizeof(R) / sizeof(T)) + " columns, got " +
                                    std::to_string(v.n1));
    return V1<R>{reinterpret_cast<R*>(v.p), v.n0};
}
inline V1<ManifoldHead> heads(V2<i64> v, const char* name = "mi") {
    return as_records<ManifoldHead>(v, name);
}
inline V1<Manifold> manifolds(V2<double> v, const char* name = "mf") {
    return as_records<Manifold>(v, name);
}
inline V1<ContactPoint> points(V2<double> v, const char* name = "pf") {
    return as_records<ContactPoint>(v, name);
}

// ---- the contact log's records (the kernels append a row per point at sampled steps) ----------
// log_i (K, LOG_I_COLS) int64, a ContactLogIds per row; log_f (K, LOG_F_COLS) float64, a
// ContactLogValues per row (world frame, the step's end: rblog.contract's contact rows).
struct ContactLogIds {
    i64 step;  // the step that made the contact
    i64 a;     // body index of a
    i64 b;     // body index of b, or STATIC_BODY (-1)
    i64 kind;  // CONTACT_IMPACT or CONTACT_RESTING
};
struct ContactLogValues {
    double point[3];        // contact point (midpoint of the surfaces), m
    double normal[3];       // from b into a
    double separation;      // gap at the step's end along the normal (m), < 0 penetration
    double normal_impulse;  // N s
    double friction[3];     // friction impulse on a (N s)
};
constexpr i64 LOG_I_COLS = (i64)(sizeof(ContactLogIds) / sizeof(i64));
constexpr i64 LOG_F_COLS = (i64)(sizeof(ContactLogValues) / sizeof(double));
static_assert(LOG_I_COLS == 4 && LOG_F_COLS == 11, "log records without padding");

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
