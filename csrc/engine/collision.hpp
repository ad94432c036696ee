// The collision stages of the contact step, as the other stages call them (Box2D v3's file
// split, one .cpp per stage):
//
//   broad_phase.cpp   body_aabbs, sweep_and_prune, ground_pairs          (contact/broadphase.py)
//   narrowphase.cpp   the colliders' dispatch table, sphere/plane colliders,
//                     collide, the collision constants                   (contact/narrowphase.py)
//   box_box.cpp       separating axes, clipped face manifold, edge point (contact/box_box.py)
//   capsule.cpp       the capsule pairs (closed forms)
//   cylinder.cpp      the cylinder pairs (closed forms; GJK + EPA, common/convex.hpp) and
//                     collide_convex, the GJK + EPA + clipping path of the hull pairs too
//   hull.cpp          the hull table, hull - plane (closed form)
//   manifold.cpp      reduce_manifold (manifold.hpp: the packed columns) (contact/manifold.py)
//   collide.cpp       collide_pairs, warm-start matching, tangent_basis  (contact/collide.py)
//   island.cpp        update_sleep, wake_touched, wake_pushed            (contact/island.py)
//   measure.cpp       pair_min_separations                               (contact/measure.py)
//
// Signatures mirror the Python functions: same names, same argument order; numpy arrays are
// views (V1..V3), a buffer that Python grew and returned is a Buf2<T>& grown in place (a 1-D
// int64 buffer such as pid is a Buf2<i64> of one column), tuple returns are small structs in
// the same order. Three departures, all at the collider level:
//
// * A shape's centre, size row and plane normal are `const double*` (3 values), a rotation an
//   M3 (9 values, row-major, body -> world): rows of the (N, 3) / (N, 3, 3) state arrays
//   (position.row(i), rotation.row(i)).
// * The six collider work buffers (nrm, pts, sep, fid, work, poly) are one ColliderBuffers
//   struct (narrowphase.collider_buffers()).
// * collide() takes the two geometry codes (ga, gb) instead of (code, swap): it looks the
//   collider up in the table (lower code first) and swaps when ga > gb, which is what every
//   Python caller computed (code = COLLIDE_TABLE[min, max], swap = ga > gb).
//
// Tolerances keep their one home in rblog/engine/constants.py: the Python module narrowphase.py
// hands them to C++ once at import (_core.set_collision_constants), into collision_constants().
#pragma once

#include <cstddef>  // size_t, which common/array.hpp uses

#include <array>
#include <cstdint>
#include <vector>

#include "common/array.hpp"
#include "engine/manifold.hpp"

namespace rb {

// ---- geometry codes (narrowphase.py GEOM_*; the test checks they agree) ---------------------
// size rows: sphere [r, 0, 0]; box half extents; capsule [r, h, 0] (the segment |z| <= h of the
// body's z axis grown by r); cylinder [r, h, 0] (radius r, |z| <= h); hull [id, 0, 0] (its
// vertices and faces in the process's hull table, engine/hull.hpp). The plane is the highest
// code, so it is always shape b.
constexpr i64 GEOM_SPHERE = 0;
constexpr i64 GEOM_BOX = 1;
constexpr i64 GEOM_CAPSULE = 2;
constexpr i64 GEOM_CYLINDER = 3;
constexpr i64 GEOM_HULL = 4;
constexpr i64 GEOM_PLANE = 5;
constexpr i64 N_GEOM = 6;

// ---- constants from Python (set once at import) ---------------------------------------------
struct CollisionConstants {
    double manifold_touch_band_m = 0.0;        // constants.MANIFOLD_TOUCH_BAND_M
    double edge_rel_tol = 0.0;                 // constants.EDGE_REL_TOL
    double face_rel_tol = 0.0;                 // constants.FACE_REL_TOL
    double axis_abs_tol = 0.0;                 // constants.AXIS_ABS_TOL
    double edge_parallel_tol = 0.0;            // constants.EDGE_PARALLEL_TOL
    double friction_anchor_max_drift_m = 0.0;  // constants.FRICTION_ANCHOR_MAX_DRIFT_M
    i64 static_body = -1;                      // contract.trajectory.STATIC_BODY
    double convex_gjk_tol_m = 0.0;             // constants.CONVEX_GJK_TOL_M
    double convex_epa_tol_m = 0.0;             // constants.CONVEX_EPA_TOL_M
    i64 convex_max_iter = 0;                   // constants.CONVEX_MAX_ITER
    bool set = false;                          // set_collision_constants was called
};
// The process's collision constants (narrowphase.cpp).
CollisionConstants& collision_constants();
// Throws rb::Error("RblogError", ...) unless set_collision_constants has run (narrowphase.py
// calls it at import); the stage entry points check it once per call.
void require_collision_constants();

// ---- small views ----------------------------------------------------------------------------
// A 3x3 matrix, row-major (rotation.row(i) of an (N, 3, 3) array): m(r, c).
struct M3 {
    const double* p;
    M3(const double* q) : p(q) {}  // NOLINT: implicit from a row pointer, on purpose
    double operator()(i64 r, i64 c) const { return p[3 * r + c]; }
};
using Pts = double (*)[3];                           // (rows, 3) points
using Poly = double (*)[2 * MAX_CLIP_POINTS][4];     // poly[0], poly[1]: (24, 4) polygons

// The work buffers every collider call takes (narrowphase.collider_buffers): nrm: two
// manifolds' normals (6); pts, sep, fid: MAX_CLIP_POINTS rows (a first manifold in rows 0..3, a
// box pair's second in rows 4..7); work: 32 floats; poly: two clipping polygons.
struct ColliderBuffers {
    double nrm[6];
    double pts[MAX_CLIP_POINTS][3];
    double sep[MAX_CLIP_POINTS];
    i64 fid[MAX_CLIP_POINTS];
    double work[32];
    double poly[2][2 * MAX_CLIP_POINTS][4];
};
inline ColliderBuffers collider_buffers() { return ColliderBuffers{}; }  // zeroed

// ---- narrowphase (narrowphase.cpp, box_box.cpp) ---------------------------------------------
// Each collider returns the number of points written (normal from b into a in nrm[0:3]).
i64 collide_sphere_sphere(const double* ca, double ra, const double* cb, double r_b, double spec,
                          double* nrm, Pts pts, double* sep, i64* fid);
i64 collide_sphere_box(const double* ca, double ra, const double* cb, M3 rotb, const double* eb,
                       double spec, double* nrm, Pts pts, double* sep, i64* fid);
i64 collide_sphere_plane(const double* ca, double ra, const double* pn, double poff, double spec,
                         double* nrm, Pts pts, double* sep, i64* fid);
i64 collide_box_plane(const double* ca, M3 rota, const double* ea, const double* pn, double poff,
                      double spec, double* nrm, Pts pts, double* sep, i64* fid);
// capsule.cpp (a: the capsule, but sphere - capsule: the sphere)
i64 collide_capsule_plane(const double* ca, M3 rota, const double* sa, const double* pn,
                          double poff, double spec, double* nrm, Pts pts, double* sep, i64* fid);
i64 collide_sphere_capsule(const double* ca, double ra, const double* cb, M3 rotb,
                           const double* sb, double spec, double* nrm, Pts pts, double* sep,
                           i64* fid);
i64 collide_capsule_capsule(const double* ca, M3 rota, const double* sa, const double* cb,
                            M3 rotb, const double* sb, double spec, double* nrm, Pts pts,
                            double* sep, i64* fid);
i64 collide_capsule_box(const double* ca, M3 rota, const double* sa, const double* cb, M3 rotb,
                        const double* eb, double spec, double* nrm, Pts pts, double* sep,
                        i64* fid);
// cylinder.cpp (a: the cylinder, but sphere - cylinder: the sphere; collide_convex: any two of
// box, capsule, cylinder, hull, or a sphere and a hull, by engine geometry code)
i64 collide_cylinder_plane(const double* ca, M3 rota, const double* sa, const double* pn,
                           double poff, double spec, double* nrm, Pts pts, double* sep,
                           i64* fid);
i64 collide_sphere_cylinder(const double* ca, double ra, const double* cb, M3 rotb,
                            const double* sb, double spec, double* nrm, Pts pts, double* sep,
                            i64* fid);
i64 collide_convex(i64 ga, const double* ca, M3 rota, const double* sa, i64 gb,
                   const double* cb, M3 rotb, const double* sb, double spec, double* nrm,
                   Pts pts, double* sep, i64* fid);
// g(u) of any two of sphere, box, capsule, cylinder, hull (engine codes): the gap of the two
// solids' projections on the unit u (normalized here; from b into a), radii included:
// u . s_a(-u) - u . s_b(u), at most the pair's signed distance (the separating-axis theorem).
double convex_axis_gap(i64 ga, const double* ca, M3 rota, const double* sa, i64 gb,
                       const double* cb, M3 rotb, const double* sb, const double* u);
// hull.cpp (a: the hull; its pairs with every other shape but the plane are collide_convex's)
i64 collide_hull_plane(const double* ca, M3 rota, const double* sa, const double* pn,
                       double poff, double spec, double* nrm, Pts pts, double* sep, i64* fid);
// Returns n1 + 8 n2 (a second, face manifold of n2 points in rows 4.., normal nrm[3:6]).
i64 collide_box_box(const double* ca, M3 rota, const double* ea, const double* cb, M3 rotb,
                    const double* eb, double spec, double* nrm, Pts pts, double* sep, i64* fid,
                    double* work, Poly poly);

// The table's entries share one signature (sa, sb: size rows, radius in [0] or half extents;
// for a plane b, (pn, poff) is its data and cb, rotb, sb are a's, unused).
using ColliderFn = i64 (*)(const double* ca, M3 rota, const double* sa, const double* cb,
                           M3 rotb, const double* sb, const double* pn, double poff, double spec,
                           ColliderBuffers& buf);
// NARROWPHASE_TABLE[lower geometry code][higher code] -> collider, nullptr when none (the world
// refuses such a scene in Python, UnsupportedShapePair).
ColliderFn narrowphase_fn(i64 geom_lo, i64 geom_hi);

// Run the collider of geometry codes (ga, gb) on shape a and shape b; when ga > gb the table's
// first shape is b: the collider runs as (b, a) and the normals are negated so that they still
// point from b into a. Returns n1 + 8 n2 (manifold_part), or -1 when the table has no collider.
i64 collide(i64 ga, i64 gb, const double* ca, M3 rota, const double* sa, const double* cb,
            M3 rotb, const double* sb, const double* pn, double poff, double spec,
            ColliderBuffers& buf);

// True when collide() of the same arguments at speculative distance spec provably returns no
// point, decided from the gap along the one axis u (any world vector, from b into a): the pairs
// whose colliders never report a gap below the signed distance (collide_convex's, capsule -
// box, for which axis_parts(ga, gb) holds); false for every other pair. Proof in
// narrowphase.cpp.
constexpr bool axis_parts_rule(i64 ga, i64 gb) {
    const i64 lo = ga < gb ? ga : gb, hi = ga < gb ? gb : ga;
    const bool convex_pair = (hi == GEOM_CYLINDER && lo != GEOM_SPHERE) ||
                             (hi == GEOM_HULL && lo != GEOM_BOX && lo != GEOM_HULL);
    return convex_pair || (lo == GEOM_BOX && hi == GEOM_CAPSULE);
}
// axis_parts_rule as bits N_GEOM ga + gb of one word: every pair asks it (collide, project)
constexpr std::uint64_t axis_parts_bits() {
    std::uint64_t m = 0;
    for (i64 a = 0; a < N_GEOM; ++a)
        for (i64 b = 0; b < N_GEOM; ++b)
            if (axis_parts_rule(a, b)) m |= std::uint64_t{1} << (N_GEOM * a + b);
    return m;
}
static_assert(N_GEOM * N_GEOM <= 64, "axis_parts_bits: one bit a pair of codes");
constexpr std::uint64_t AXIS_PARTS_BITS = axis_parts_bits();
inline bool axis_parts(i64 ga, i64 gb) { return (AXIS_PARTS_BITS >> (N_GEOM * ga + gb)) & 1; }
bool parted_along(i64 ga, i64 gb, const double* ca, M3 rota, const double* sa, const double* cb,
                  M3 rotb, const double* sb, const double* u, double spec);

// (point count, first row) of manifold `part` (0 or 1) in a result of collide.
struct ManifoldPart {
    i64 count, row;
};
inline ManifoldPart manifold_part(i64 res, i64 part) {
    if (part == 0) return {res % 8, 0};
    return {res / 8, 4};
}

// ---- the geom table ---------------------------------------------------------------------------
// The dynamic shapes are geoms, each owned by one body (a compound body owns several): shape ids
// 0..G-1 are geoms, G..G+S-1 the static boxes, G+S the ground. A geom's frame is its body's
// (centre of mass, principal axes) when offset[g] == 0; else it sits at pos[g] (body frame, m)
// turned by rot[g] (geom -> body), and its world pose is x + R pos, R rot. radius[g] bounds the
// distance of its points from its body's centre of mass (m): the turn bound of its swept AABB.
// A scene of one-shape bodies has G = N, geom g = body g, offset 0: every stage reads the body
// rows as it would without the table.
struct Geoms {
    V1<i64> code;       // (G,) GEOM_*
    V2<double> size;    // (G, 3) size rows (above)
    V1<i64> body;       // (G,) owner body
    V1<i64> offset;     // (G,) 1: pos / rot below, 0: the body's frame
    V2<double> pos;     // (G, 3) geom origin in the body frame, m
    V3<double> rot;     // (G, 3, 3) geom -> body, row-major
    V1<double> radius;  // (G,) farthest point of the geom from its body's centre of mass, m
    i64 n() const { return code.n0; }
};

// A geom's world pose: centre and rotation (9, row-major). For an offset geom they are computed
// into `c` / `r` (the caller's 3 and 9 values); else they point into the body's state rows.
struct GeomPose {
    const double* centre;
    const double* rotation;
};
inline GeomPose geom_pose(const Geoms& gm, i64 g, V2<double> position, V3<double> rotation,
                          double* c, double* r) {
    const i64 i = gm.body[g];
    if (!gm.offset[g]) return {position.row(i), rotation.row(i)};
    const double* x = position.row(i);
    const double* R = rotation.row(i);
    const double* p = gm.pos.row(g);
    const double* L = gm.rot.row(g);
    for (int k = 0; k < 3; ++k) {
        c[k] = x[k] + R[3 * k] * p[0] + R[3 * k + 1] * p[1] + R[3 * k + 2] * p[2];
        for (int j = 0; j < 3; ++j)
            r[3 * k + j] = R[3 * k] * L[j] + R[3 * k + 1] * L[3 + j] + R[3 * k + 2] * L[6 + j];
    }
    return {c, r};
}

// (geom_b, centre_b, rotation_b, size_b) of shape id b (a's data stand in for the plane; ca, ra
// are a's world pose, cb / rb the room for an offset geom b's).
struct PairGeometry {
    i64 geom;
    const double* centre;
    const double* rotation;  // 9, row-major
    const double* size;
};
inline PairGeometry pair_geometry(i64 a, i64 b, i64 n_geom, i64 n_static, const Geoms& gm,
                                  GeomPose pa, V2<double> position, V3<double> rotation,
                                  V2<double> sb_pos, V3<double> sb_rot, V2<double> sb_ext,
                                  double* cb, double* rb) {
    if (b < n_geom) {
        GeomPose q = geom_pose(gm, b, position, rotation, cb, rb);
        return {gm.code[b], q.centre, q.rotation, gm.size.row(b)};
    }
    if (b < n_geom + n_static) {
        i64 k = b - n_geom;
        return {GEOM_BOX, sb_pos.row(k), sb_rot.row(k), sb_ext.row(k)};
    }
    return {GEOM_PLANE, pa.centre, pa.rotation, gm.size.row(a)};
}

// The shape ids' bodies: a geom's owner, -1 for static geometry.
inline i64 shape_body(const Geoms& gm, i64 s) { return s < gm.n() ? gm.body[s] : -1; }

// ---- broad phase (broad_phase.cpp) ----------------------------------------------------------
// World AABBs of the geoms (rows 0..G-1 of lo, hi), swept over the step with their bodies;
// reach (G,).
void body_aabbs(const Geoms& gm, V1<double> inv_mass, V2<double> inv_inertia, V1<i64> awake,
                V2<double> position, V2<double> linear_momentum, V3<double> rotation,
                V2<double> angular_momentum, double h, double margin, V2<double> lo,
                V2<double> hi, V1<double> reach);
// Candidate pairs (lo id, hi id) among items 0..n_items-1 whose AABBs overlap, into rows
// 0..count-1 of `pairs` (2 columns, grown in place): items 0..n_dyn-1 are geoms of the bodies
// `body` (two geoms of one body never pair), `group` per body. Returns count.
i64 sweep_and_prune(i64 n_items, i64 n_dyn, V2<double> lo, V2<double> hi, V1<i64> body,
                    V1<i64> group, V1<i64> awake, Buf2<i64>& pairs);
// Append (body, ground) for every body whose padded AABB reaches the plane dot(gn, x) = goff
// (Python: the Statics record st; here its gn, goff). Returns the new pair count.
i64 ground_pairs(i64 n_dyn, i64 n_static, V1<double> gn, double goff, V2<double> lo,
                 V2<double> hi, Buf2<i64>& pairs, i64 n_pairs);

// ---- collide (collide.cpp) ------------------------------------------------------------------
// Unit t1, t2 with (t1, t2, n) right-handed, a deterministic function of n: (t1x, t1y, t1z,
// t2x, t2y, t2z).
std::array<double, 6> tangent_basis(double nx, double ny, double nz);
// Index of the manifold with `key` among the first n sorted keys, or -1.
i64 find_manifold(V1<i64> sorted_keys, V1<i64> sorted_idx, i64 n, i64 key);
// Fill sorted_keys/sorted_idx (length >= n_man) with the manifolds ordered by pair key (stable).
void sort_manifolds(V1<ManifoldHead> mi, i64 n_man, V1<i64> sorted_keys, V1<i64> sorted_idx);
// Room for cap manifolds / points (contents kept).
void grow_manifolds(Buf2<i64>& mi, Buf2<double>& mf, i64 cap);
void grow_points(Buf2<double>& pf, Buf2<i64>& pid, i64 cap);

struct CollideCount {
    i64 n_man, n_pts;
};
// Manifolds of the candidate pairs into (mi, mf, pf, pid), which must have room for 2 n_pairs
// manifolds and 8 n_pairs points (grow_manifolds, grow_points). Returns (n_man, n_pts).
CollideCount collide_pairs(V2<i64> pairs, i64 n_pairs, i64 n_dyn, i64 n_static, const Geoms& gm,
                           V1<i64> awake, V2<double> position,
                           V3<double> rotation, V1<double> reach, double margin,
                           V1<double> restitution, V1<double> friction, V2<double> accel,
                           V2<double> sb_pos, V3<double> sb_rot, V2<double> sb_ext,
                           V1<double> sb_e, V1<double> sb_mu, V1<double> gn, double goff,
                           double g_e, double g_mu, V1<ManifoldHead> prev_mi, V1<Manifold> prev_mf,
                           V1<ContactPoint> prev_pf, V1<i64> prev_pid, V1<i64> prev_keys,
                           V1<i64> prev_idx, i64 prev_n, V1<ManifoldHead> mi, V1<Manifold> mf,
                           V1<ContactPoint> pf, V1<i64> pid, bool warm, double anchor_distance,
                           ColliderBuffers& buf);

// ---- islands (island.cpp) -------------------------------------------------------------------
// Root of i in the union-find forest `parent`, halving the path on the way.
inline i64 find_root(V1<i64> parent, i64 i) {
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    return i;
}
// Advance rest timers, build islands, put islands at rest to sleep. Returns bodies put to sleep.
i64 update_sleep(i64 n_dyn, V1<ManifoldHead> mi, V1<ContactPoint> pf, i64 n_man, V1<i64> awake,
                 V1<double> sleep_timer, V1<i64> island_of, V1<i64> island_counter,
                 V2<double> linear_momentum, V2<double> angular_momentum, V1<double> inv_mass,
                 V2<double> inv_inertia, V1<double> radius, double h, double sleep_speed,
                 double sleep_time, V1<i64> parent, V1<double> island_min_time,
                 V1<i64> island_supported);
// Wake every body of a sleeping island, giving it this step's force kick when do_kick.
void wake_island(i64 island, i64 n_dyn, V1<i64> awake, V1<double> sleep_timer,
                 V1<i64> island_of, V2<double> linear_momentum, V2<double> angular_momentum,
                 V2<double> force, V2<double> torque, double h, bool do_kick);
// Wake the sleeping islands an awake body will reach within this step. Returns islands woken.
i64 wake_touched(V2<i64> pairs, i64 n_pairs, i64 n_dyn, i64 n_static, const Geoms& gm,
                 V1<i64> awake, V1<double> sleep_timer, V1<i64> island_of,
                 V2<double> position, V3<double> rotation, V1<double> reach,
                 double speculative_distance, double allowed_penetration, V2<double> sb_pos,
                 V3<double> sb_rot, V2<double> sb_ext, V1<double> gn, double goff,
                 V2<double> linear_momentum,
                 V2<double> angular_momentum, V2<double> force, V2<double> torque, double h,
                 bool do_kick, ColliderBuffers& buf, V1<double> inv_mass, V2<double> accel,
                 V1<double> radius, V2<double> inv_inertia);
// Wake the sleeping islands an awake body pushed on in this step's solve (their impulses handed
// to the sleepers). Returns islands woken.
i64 wake_pushed(V1<ManifoldHead> mi, V1<Manifold> mf, V1<ContactPoint> pf, i64 n_man, i64 n_dyn,
                V1<i64> awake,
                V1<double> sleep_timer, V1<i64> island_of, V2<double> position,
                V2<double> linear_momentum, V2<double> angular_momentum, V2<double> force,
                V2<double> torque, double h);

// ---- measure (measure.cpp) ------------------------------------------------------------------
// Least separation of every touching pair of shapes at this configuration (bodies at rest:
// unswept boxes padded by margin); measure.separations hands the world's model arrays in.
std::vector<double> pair_min_separations(const Geoms& gm, V1<double> inv_mass, V2<double> inv_inertia,
                                         V1<i64> group, i64 n_static, V2<double> sb_pos,
                                         V3<double> sb_rot, V2<double> sb_ext, V2<double> sb_lo,
                                         V2<double> sb_hi, bool ground, V1<double> gn,
                                         double goff, V2<double> position, V3<double> rotation,
                                         double margin);

}  // namespace rb
