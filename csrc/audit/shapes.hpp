// The audit's geometry of every shape of the log contract (shapes.cpp, convex.cpp,
// broadphase.cpp): signed distance, normal and witness points of any pair of geoms, and the
// broadphase that picks the pairs. The audit's own code, never the engine's (csrc/engine/).
//
// Conventions, for every pair (a, b):
//
// * sep: signed distance between the two surfaces (m): > 0 apart, < 0 penetration depth (the
//   length of the shortest translation that separates them).
// * n: unit world vector from b into a (the direction in which a moves to separate or to stay
//   apart).
// * pa, pb: witness points on a's and on b's surface (world, m), with pa - pb = sep n: apart,
//   the closest points; penetrating, the deepest points of each inside the other along n.
//
// A geom is its type, world centre x, body->world rotation r (row-major 9 entries,
// r[3 i + j] = R_ij, columns are the geom's axes in the world frame), size s and, for a convex
// mesh, its vertices in the geom frame (the hull of the vertex set is the shape):
//
//   type       s[0]        s[1]          s[2]         shape in the geom frame
//   PLANE      -           -             -            half-space z <= 0 (its normal is +z)
//   SPHERE     radius      -             -            |p| <= s0
//   CAPSULE    radius      half-length   -            segment z in [-s1, s1] grown by s0
//   ELLIPSOID  semi-axis x semi-axis y   semi-axis z  sum (p_i / s_i)^2 <= 1
//   CYLINDER   radius      half-length   -            x^2 + y^2 <= s0^2, |z| <= s1
//   BOX        half x      half y        half z       |p_i| <= s_i
//   MESH       -           -             -            hull of the vertices
//
// Each shape is a core grown by a radius (sphere: a point, capsule: a segment, both grown by
// s0; every other shape its own core, radius 0). Distances between cores are what GJK and EPA
// compute; the radii are subtracted after (exact: the Minkowski sum with a ball of radius r moves
// every boundary point by r along its normal).
#pragma once

#include <cmath>
#include <cstdint>

#include "common/array.hpp"

namespace rb {
namespace audit {

// Geom type codes of the audit (rblog/analyze/shapes.py maps the contract's shape names onto
// these and checks them at import).
constexpr i64 GEOM_PLANE = 0;
constexpr i64 GEOM_SPHERE = 1;
constexpr i64 GEOM_CAPSULE = 2;
constexpr i64 GEOM_ELLIPSOID = 3;
constexpr i64 GEOM_CYLINDER = 4;
constexpr i64 GEOM_BOX = 5;
constexpr i64 GEOM_MESH = 6;
constexpr i64 GEOM_N_TYPES = 7;

// Status of one pair's result.
constexpr i64 DIST_OK = 0;           // converged (closed form, or GJK/EPA within tolerance)
constexpr i64 DIST_NOT_CONVERGED = 1;  // iteration cap hit: the value is the best bound found
constexpr i64 DIST_UNSUPPORTED = 2;  // plane-plane: no finite distance; sep is NaN

struct Vec {
    double x, y, z;
};
inline Vec operator+(Vec a, Vec b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec operator-(Vec a, Vec b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec operator-(Vec a) { return {-a.x, -a.y, -a.z}; }
inline Vec operator*(double s, Vec a) { return {s * a.x, s * a.y, s * a.z}; }
inline double dot(Vec a, Vec b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec cross(Vec a, Vec b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double norm(Vec a) { return std::sqrt(dot(a, a)); }

struct Geom {
    i64 type;
    Vec x;
    const double* r;     // 9 entries, row-major
    const double* s;     // 3 entries
    const double* vert;  // (nv, 3) geom-frame vertices of a mesh, else null
    i64 nv;
};

// R^T d (a world direction in the geom frame) and x + R p (a geom-frame point in the world).
inline Vec to_local(const Geom& g, Vec d) {
    const double* r = g.r;
    return {r[0] * d.x + r[3] * d.y + r[6] * d.z, r[1] * d.x + r[4] * d.y + r[7] * d.z,
            r[2] * d.x + r[5] * d.y + r[8] * d.z};
}
inline Vec to_world(const Geom& g, Vec p) {
    const double* r = g.r;
    return {g.x.x + r[0] * p.x + r[1] * p.y + r[2] * p.z,
            g.x.y + r[3] * p.x + r[4] * p.y + r[5] * p.z,
            g.x.z + r[6] * p.x + r[7] * p.y + r[8] * p.z};
}
inline Vec axis(const Geom& g, int j) { return {g.r[j], g.r[3 + j], g.r[6 + j]}; }

// Radius by which the core is grown (sphere, capsule: s0; else 0).
inline double core_radius(const Geom& g) {
    return (g.type == GEOM_SPHERE || g.type == GEOM_CAPSULE) ? g.s[0] : 0.0;
}

// World point of the core farthest along the world direction d (any length; ties broken
// towards +).
Vec core_support(const Geom& g, Vec d);

// World AABB [lo, hi] of the whole shape (core grown by its radius): lo_i = s(-e_i)_i,
// hi_i = s(e_i)_i from the support s, so it is tight for every shape (not for a plane).
void aabb(const Geom& g, Vec& lo, Vec& hi);

struct Dist {
    double sep;
    Vec n, pa, pb;
    i64 status;
    i64 iters;  // GJK + EPA iterations (0 for a closed form)
};

// Iteration settings of GJK and EPA (tolerances from rblog/analyze/tolerances.py).
struct ConvexTol {
    double gjk_tol;   // m: GJK stops when the distance is known to within this
    double epa_tol;   // m: EPA stops when the depth is known to within this
    i64 max_iter;     // per stage
};

// GJK distance between the cores of a and b; when the cores overlap, EPA's penetration depth.
// The radii are not subtracted here. (convex.cpp)
Dist convex_distance(const Geom& a, const Geom& b, const ConvexTol& tol);

// The full dispatch over the pair's types (shapes.cpp).
// band, axis_eps: the box-box witness band and parallel-edge cut (geometry.cpp's pair).
Dist geom_distance(const Geom& a, const Geom& b, const ConvexTol& tol, double band,
                   double axis_eps);

// --- kernels (bound in bind_shapes.cpp) ---------------------------------------------------

// Rows (k, i, j): geoms i and j at sample k. position (T, G, 3), rotation (T, G, 3, 3), type (G),
// size (G, 3), mesh_start / mesh_count (G) rows of verts (V, 3). Outputs (R,) sep, status,
// iters and (R, 3) n, pa, pb (skipped when n has no rows).
void geom_pairs_kernel(V1<i64> k, V1<i64> i, V1<i64> j, V3<double> position, V4<double> rotation,
                       V1<i64> type, V2<double> size, V1<i64> mesh_start, V1<i64> mesh_count,
                       V2<double> verts, double gjk_tol, double epa_tol, i64 max_iter,
                       double band, double axis_eps, V1<double> sep, V2<double> n, V2<double> pa,
                       V2<double> pb, V1<i64> status, V1<i64> iters);

// Broadphase (broadphase.cpp): candidate pairs (k, i < j) whose world AABBs, grown by pad, overlap
// at sample k (a plane: whose AABB reaches within pad of its half-space), skipping pairs of the
// same body (body (G)) and pairs of two static geoms (body < 0). Writes up to out_k.n0 rows and
// returns how many there are (call again with more room when larger).
i64 geom_broadphase(V3<double> position, V4<double> rotation, V1<i64> type, V2<double> size,
                    V1<i64> mesh_start, V1<i64> mesh_count, V2<double> verts, V1<i64> body,
                    double pad, V1<i64> out_k, V1<i64> out_i, V1<i64> out_j);

}  // namespace audit
}  // namespace rb
