// The audit's geometry of every shape of the log contract (shapes.cpp, convex.cpp,
// broadphase.cpp): signed distance, normal and witness points of any pair of geoms, and the
// broadphase that picks the pairs. The audit's own code, never the engine's (csrc/engine/).
// GJK, EPA, the support functions and the Geom record are csrc/common/convex.hpp's (shared with
// the engine's cylinder colliders: one home for the algorithm).
//
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
#include "common/convex.hpp"

namespace rb {
namespace audit {

// the convex shapes, their support (core_support) and GJK/EPA (convex_distance)
using namespace ::rb::convex;

// World AABB [lo, hi] of the whole shape (core grown by its radius): lo_i = s(-e_i)_i,
// hi_i = s(e_i)_i from the support s, so it is tight for every shape (not for a plane).
void aabb(const Geom& g, Vec& lo, Vec& hi);

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

// Swept broadphase over sample intervals (broadphase.cpp, for the tunneling analyzer): candidate
// pairs (k, i < j) whose AABBs united over samples k and k+1 and grown by grow (K, G) (m: how far
// a geom's points stray outside that union on the interpolated path, its rotation's bulge)
// overlap; planes left out, and pairs of one body, of two static geoms or where neither geom is
// ``mine``. Writes up to out_k.n0 rows and returns how many there are.
i64 geom_sweep_broadphase(V3<double> position, V4<double> rotation, V1<i64> type, V2<double> size,
                          V1<i64> mesh_start, V1<i64> mesh_count, V2<double> verts, V1<i64> body,
                          V1<bool> mine, V2<double> grow, V1<i64> out_k, V1<i64> out_i,
                          V1<i64> out_j);

}  // namespace audit
}  // namespace rb
