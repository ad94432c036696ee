// Convex geometry shared by the engine (csrc/engine/cylinder.cpp) and the audit (csrc/audit/):
// the shapes as a core grown by a radius, their support functions, GJK for the distance of two
// cores and EPA for their penetration depth. One home for the algorithm; each side keeps its
// own dispatch, tolerances and manifolds (both include this header; neither links the other).
// Why this header is long: GJK, its simplex reduction and EPA with its polytope are one derivation
// (below), header-only so that each extension module compiles its own copy.
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
//
// Support functions of every core, GJK for the distance of two cores and EPA for their
// penetration depth (the method of libccd, coal/FCL and MuJoCo's engine_collision_gjk.c).
//
// Derivation. For convex A, B the signed distance is a property of the Minkowski difference
// D = A - B = {p - q}: apart, sep = min_{w in D} |w| (the closest point v of D to the origin is
// pa - pb); overlapping, sep = -(distance from the origin to the boundary of D) and the
// separating translation is along the outward normal of the nearest boundary point. D's support
// function is s_D(d) = s_A(d) - s_B(-d), so both need only each shape's support.
//
// * GJK (Gilbert, Johnson, Keerthi 1988): a simplex of at most four points of D; each iteration
//   replaces it by the smallest sub-simplex holding the point v of it closest to the origin
//   (Ericson, Real-Time Collision Detection 5.1.5-5.1.6: Voronoi regions of the triangle; a
//   tetrahedron is reduced through its faces that see the origin), then adds w = s_D(-v). Since
//   v.w / |v| is a lower bound of the distance and |v| an upper bound, it stops when
//   |v| - v.w / |v| <= gjk_tol: the distance is known to within gjk_tol. For polytope cores
//   (point, segment, box, mesh) D is a polytope and w is a vertex of D: GJK ends in finitely
//   many steps with the exact closest feature, so the distance is exact up to rounding; for
//   cylinders and ellipsoids the gap closes geometrically and gjk_tol is the error.
// * EPA (van den Bergen 2001): from a tetrahedron of D points that holds the origin (GJK's last
//   simplex, blown up to a tetrahedron when the origin lies on a lower-dimensional one: the
//   shapes touch), grow a polytope inside D: take its face nearest the origin (distance d along
//   its outward normal u), add w = s_D(u); when u.w - d <= epa_tol the face lies on D's
//   boundary to within epa_tol and d is the depth; else the faces that see w are replaced by
//   the cone from w to their horizon. Again exact for polytopes (the faces become D's own),
//   within epa_tol for curved cores.
// * Witness points: v (or the face's nearest point d u) in barycentric coordinates of its
//   simplex (face) is the same combination of the A and B support points that made it.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <utility>
#include <vector>

#include "common/array.hpp"

namespace rb {
namespace convex {
// Geom type codes of the convex shapes (the audit's: rblog/analyze/shapes.py maps the contract's
// shape names onto these and checks them at import; the engine maps its own codes onto them).
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
    // m: GJK/EPA see the core grown by a ball of this radius too (0: the core itself). For convex
    // sets sd(A, B + ball(e)) = sd(A, B) - e with the same normal, apart or overlapping, so a
    // caller can move a touching pair (where GJK's simplex passes through the origin and its
    // normal is ill-conditioned) to a depth of e.
    double grow = 0.0;
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
inline Vec core_support(const Geom& g, Vec d);

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

namespace detail {
constexpr double kInf = std::numeric_limits<double>::infinity();
inline double sgn(double v) { return v >= 0 ? 1.0 : -1.0; }
}  // namespace detail

inline Vec core_support(const Geom& g, Vec d) {
    using detail::kInf;
    using detail::sgn;
    switch (g.type) {
        case GEOM_SPHERE:
            return g.x;
        case GEOM_CAPSULE: {
            Vec a = axis(g, 2);
            return g.x + (sgn(dot(a, d)) * g.s[1]) * a;
        }
        case GEOM_BOX: {
            Vec l = to_local(g, d);
            return to_world(g, {sgn(l.x) * g.s[0], sgn(l.y) * g.s[1], sgn(l.z) * g.s[2]});
        }
        case GEOM_CYLINDER: {
            Vec l = to_local(g, d);
            double rho = std::sqrt(l.x * l.x + l.y * l.y);
            double f = rho > 0 ? g.s[0] / rho : 0.0;
            return to_world(g, {f * l.x, f * l.y, sgn(l.z) * g.s[1]});
        }
        case GEOM_ELLIPSOID: {
            // the point with outward normal along d: p_i = a_i^2 d_i / |diag(a) d|
            Vec l = to_local(g, d);
            Vec e{g.s[0] * l.x, g.s[1] * l.y, g.s[2] * l.z};
            double m = norm(e);
            if (m == 0) return g.x;
            return to_world(g, {g.s[0] * e.x / m, g.s[1] * e.y / m, g.s[2] * e.z / m});
        }
        case GEOM_MESH: {
            Vec l = to_local(g, d);
            i64 best = 0;
            double bd = -kInf;
            for (i64 v = 0; v < g.nv; ++v) {
                const double* p = g.vert + 3 * v;
                double s = p[0] * l.x + p[1] * l.y + p[2] * l.z;
                if (s > bd) {
                    bd = s;
                    best = v;
                }
            }
            const double* p = g.vert + 3 * best;
            return to_world(g, {p[0], p[1], p[2]});
        }
        default:
            return g.x;
    }
}

namespace detail {

// A point of D with the A and B support points that made it.
struct SV {
    Vec w, a, b;
};

inline SV support(const Geom& A, const Geom& B, Vec d) {
    Vec a = core_support(A, d);
    Vec b = core_support(B, -d);
    if (A.grow != 0.0 || B.grow != 0.0) {
        const double dn = norm(d);
        if (dn > 0) {
            a = a + (A.grow / dn) * d;
            b = b - (B.grow / dn) * d;
        }
    }
    return {a - b, a, b};
}

// Closest point of the simplex s[0..n) to the origin; s is reduced to the vertices of the
// feature that holds it and lam to their barycentric weights. Returns false when the origin is
// inside the tetrahedron (n == 4 kept).
inline bool closest_on_simplex(SV* s, int& n, double* lam, Vec& v);

inline void keep(SV* s, int& n, double* lam, std::initializer_list<int> idx,
          std::initializer_list<double> w) {
    SV t[4];
    int m = 0;
    for (int i : idx) t[m++] = s[i];
    int q = 0;
    for (double x : w) lam[q++] = x;
    for (int i = 0; i < m; ++i) s[i] = t[i];
    n = m;
}

// Ericson 5.1.5 with p = origin: Voronoi regions of triangle abc.
inline void closest_on_triangle(SV* s, int& n, double* lam) {
    Vec a = s[0].w, b = s[1].w, c = s[2].w;
    Vec ab = b - a, ac = c - a, ap = -a;
    double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) return keep(s, n, lam, {0}, {1.0});
    Vec bp = -b;
    double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) return keep(s, n, lam, {1}, {1.0});
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        double t = d1 / (d1 - d3);
        return keep(s, n, lam, {0, 1}, {1 - t, t});
    }
    Vec cp = -c;
    double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0 && d5 <= d6) return keep(s, n, lam, {2}, {1.0});
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        double t = d2 / (d2 - d6);
        return keep(s, n, lam, {0, 2}, {1 - t, t});
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return keep(s, n, lam, {1, 2}, {1 - t, t});
    }
    double den = 1.0 / (va + vb + vc);
    double v_ = vb * den, w_ = vc * den;
    return keep(s, n, lam, {0, 1, 2}, {1 - v_ - w_, v_, w_});
}

inline Vec combine(const SV* s, int n, const double* lam, int which) {
    Vec r{0, 0, 0};
    for (int i = 0; i < n; ++i) r = r + lam[i] * (which == 0 ? s[i].w : which == 1 ? s[i].a : s[i].b);
    return r;
}

inline bool closest_on_simplex(SV* s, int& n, double* lam, Vec& v) {
    if (n == 1) {
        lam[0] = 1.0;
    } else if (n == 2) {
        Vec a = s[0].w, ab = s[1].w - s[0].w;
        double den = dot(ab, ab);
        double t = den > 0 ? -dot(a, ab) / den : 0.0;
        if (t <= 0) keep(s, n, lam, {0}, {1.0});
        else if (t >= 1) keep(s, n, lam, {1}, {1.0});
        else keep(s, n, lam, {0, 1}, {1 - t, t});
    } else if (n == 3) {
        closest_on_triangle(s, n, lam);
    } else {
        // tetrahedron: the faces whose plane has the origin on the side away from the fourth
        // vertex; none -> the origin is inside
        static const int F[4][4] = {{0, 1, 2, 3}, {0, 1, 3, 2}, {0, 2, 3, 1}, {1, 2, 3, 0}};
        bool outside_any = false;
        double best = kInf;
        SV bs[4];
        int bn = 0;
        double bl[4];
        for (const auto& f : F) {
            Vec p = s[f[0]].w;
            Vec nr = cross(s[f[1]].w - p, s[f[2]].w - p);
            double so = dot(nr, -p), sd = dot(nr, s[f[3]].w - p);
            if (so * sd > 0) continue;  // the origin is on the fourth vertex's side
            outside_any = true;
            SV t[4] = {s[f[0]], s[f[1]], s[f[2]]};
            int tn = 3;
            double tl[4];
            closest_on_triangle(t, tn, tl);
            Vec q = combine(t, tn, tl, 0);
            double dq = dot(q, q);
            if (dq < best) {
                best = dq;
                bn = tn;
                for (int i = 0; i < tn; ++i) {
                    bs[i] = t[i];
                    bl[i] = tl[i];
                }
            }
        }
        if (!outside_any) {
            v = {0, 0, 0};
            return false;
        }
        n = bn;
        for (int i = 0; i < bn; ++i) {
            s[i] = bs[i];
            lam[i] = bl[i];
        }
    }
    v = combine(s, n, lam, 0);
    return true;
}

// --- EPA -------------------------------------------------------------------------------------
// The polytope is a closed triangle mesh with its adjacency: edge e of face f runs from
// v[e] to v[(e + 1) % 3] (counter-clockwise seen from outside) and is shared with face
// adj_f[e], where it is that face's edge adj_e[e]. The faces that see a new point w are found by
// a depth-first walk from the nearest face over this adjacency (van den Bergen's silhouette), so
// that they form one connected patch whose boundary (the horizon) is one loop even when rounding
// makes nearly coplanar faces disagree: the mesh stays closed.
struct Face {
    int v[3];
    int adj_f[3], adj_e[3];
    Vec u;     // unit normal from the winding (outward)
    double d;  // distance of the face's plane from the origin along u
    bool alive;
};

struct Polytope {
    std::vector<SV> v;
    std::vector<Face> f;
    std::vector<std::pair<int, int>> horizon;  // (face, edge) of the alive side, in loop order

    int add_face(int i, int j, int k) {
        Face q{};
        q.v[0] = i;
        q.v[1] = j;
        q.v[2] = k;
        Vec p = v[i].w;
        Vec nr = cross(v[j].w - p, v[k].w - p);
        double len = norm(nr);
        if (len > 0) {
            q.u = (1.0 / len) * nr;
            q.d = dot(q.u, p);
        } else {  // degenerate: never the nearest, seen by any point
            q.u = {0, 0, 0};
            q.d = kInf;
        }
        q.alive = true;
        f.push_back(q);
        return (int)f.size() - 1;
    }
    void link(int fa, int ea, int fb, int eb) {
        f[fa].adj_f[ea] = fb;
        f[fa].adj_e[ea] = eb;
        f[fb].adj_f[eb] = fa;
        f[fb].adj_e[eb] = ea;
    }
    bool sees(int fi, Vec w) const {
        const Face& q = f[fi];
        return q.d == kInf || dot(q.u, w) - q.d > 0;
    }
    // walk from face fi, entered across its edge e
    void silhouette(int fi, int e, Vec w) {
        if (!f[fi].alive) return;
        if (!sees(fi, w)) {
            horizon.push_back({fi, e});
            return;
        }
        f[fi].alive = false;
        silhouette(f[fi].adj_f[(e + 1) % 3], f[fi].adj_e[(e + 1) % 3], w);
        silhouette(f[fi].adj_f[(e + 2) % 3], f[fi].adj_e[(e + 2) % 3], w);
    }
};

// Blow a GJK simplex that holds the origin on its boundary (n < 4) up to a tetrahedron of D.
inline bool to_tetrahedron(const Geom& A, const Geom& B, SV* s, int& n) {
    static const Vec dirs[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    auto far_from = [](Vec p, Vec q) { return norm(p - q) > 1e-12 * (1.0 + norm(p) + norm(q)); };
    if (n == 1) {
        for (const Vec& d : dirs) {
            SV w = support(A, B, d);
            if (far_from(w.w, s[0].w)) {
                s[n++] = w;
                break;
            }
        }
        if (n < 2) return false;
    }
    if (n == 2) {
        Vec e = s[1].w - s[0].w;
        // a direction normal to e, turned about e in steps of 60 degrees
        Vec t = std::fabs(e.x) < std::fabs(e.y) ? (std::fabs(e.x) < std::fabs(e.z) ? Vec{1, 0, 0} : Vec{0, 0, 1})
                                                : (std::fabs(e.y) < std::fabs(e.z) ? Vec{0, 1, 0} : Vec{0, 0, 1});
        Vec p = cross(e, t);
        Vec q = cross((1.0 / norm(e)) * e, p);
        for (int r = 0; r < 6 && n < 3; ++r) {
            double ang = r * M_PI / 3.0;
            Vec d = std::cos(ang) * p + std::sin(ang) * q;
            SV w = support(A, B, d);
            Vec c = cross(e, w.w - s[0].w);
            if (norm(c) > 1e-12 * norm(e) * (1.0 + norm(w.w - s[0].w))) s[n++] = w;
        }
        if (n < 3) return false;
    }
    if (n == 3) {
        Vec nr = cross(s[1].w - s[0].w, s[2].w - s[0].w);
        for (int sgn_ = 0; sgn_ < 2 && n < 4; ++sgn_) {
            SV w = support(A, B, sgn_ == 0 ? nr : -nr);
            double h = dot(nr, w.w - s[0].w);
            if (std::fabs(h) > 1e-12 * norm(nr) * (1.0 + norm(w.w - s[0].w))) s[n++] = w;
        }
        if (n < 4) return false;
    }
    return true;
}

}  // namespace detail

// GJK distance between the cores of a and b; when the cores overlap, EPA's penetration depth.
// The radii are not subtracted here.
inline Dist convex_distance(const Geom& A, const Geom& B, const ConvexTol& tol) {
    using namespace detail;
    Dist out{};
    SV s[4];
    int n = 1;
    double lam[4] = {1, 0, 0, 0};
    Vec d0 = A.x - B.x;
    if (dot(d0, d0) == 0) d0 = {1, 0, 0};
    s[0] = support(A, B, -d0);
    Vec v = s[0].w;
    bool overlap = false;
    bool converged = false;
    bool stalled = false;
    double lower = -kInf;  // the best lower bound v.w / |v| of the distance seen
    i64 it = 0;
    // |v| below round-off of the points of D: the origin is on the simplex (touching or
    // overlapping); D's extent is |w| of its points seen so far
    double scale = norm(s[0].w);
    for (; it < tol.max_iter; ++it) {
        double vv = dot(v, v);
        if (std::sqrt(vv) <= 1e-14 * scale) {
            overlap = true;
            converged = true;
            break;
        }
        SV w = support(A, B, -v);
        scale = std::max(scale, norm(w.w));
        double vn = std::sqrt(vv);
        lower = std::max(lower, dot(v, w.w) / vn);
        // |v| - v.w/|v|: the gap between the upper and the lower bound of the distance
        if (vn - dot(v, w.w) / vn <= tol.gjk_tol) {
            converged = true;
            break;
        }
        SV prev[4];
        int pn = n;
        double pl[4];
        for (int q = 0; q < n; ++q) {
            prev[q] = s[q];
            pl[q] = lam[q];
        }
        s[n++] = w;
        Vec nv;
        if (!closest_on_simplex(s, n, lam, nv)) {
            overlap = true;
            converged = true;
            break;
        }
        if (dot(nv, nv) >= vv) {
            // no progress: the previous simplex is the answer. Within ~1e-6 m of touching a
            // curved core stops here before the bounds meet (the support along -v jumps to a
            // cap's rim, say, while the contact is inside the cap); EPA then decides below.
            n = pn;
            for (int q = 0; q < n; ++q) {
                s[q] = prev[q];
                lam[q] = pl[q];
            }
            converged = true;
            // near touching with the bounds apart (the lower one <= 0: maybe overlapping):
            // EPA decides below
            stalled = vv - std::sqrt(vv) * lower > std::sqrt(vv) * tol.gjk_tol && lower <= 0;
            break;
        }
        v = nv;
    }
    if (!overlap) {
        double dist = norm(v);
        out.sep = dist;
        out.pa = combine(s, n, lam, 1);
        out.pb = combine(s, n, lam, 2);
        out.n = dist > 0 ? (1.0 / dist) * v : Vec{0, 0, 1};
        out.status = converged ? DIST_OK : DIST_NOT_CONVERGED;
        out.iters = it;
        if (dist > 1e-14 * scale && !stalled) return out;
        overlap = true;  // touching exactly, or stalled near it: EPA gives the depth, normal
    }
    const Dist gjk_out = out;

    // --- EPA
    if (!to_tetrahedron(A, B, s, n)) {
        if (stalled) return gjk_out;
        // D is flat (a flat mesh, or a point in a segment): touching with depth 0 along any
        // normal; report it as such
        out.sep = 0;
        out.pa = combine(s, 1, lam, 1);
        out.pb = out.pa;
        out.n = {0, 0, 1};
        out.status = DIST_OK;
        out.iters = it;
        return out;
    }
    Polytope P;
    P.v.assign(s, s + 4);
    P.f.reserve(4 + 8 * tol.max_iter);
    {
        // wind the tetrahedron's faces outward: vertex 3 must lie below face (0, 1, 2)
        Vec nr = cross(P.v[1].w - P.v[0].w, P.v[2].w - P.v[0].w);
        if (dot(nr, P.v[3].w - P.v[0].w) > 0) std::swap(P.v[1], P.v[2]);
        // faces (0 1 2), (0 3 1), (1 3 2), (2 3 0) with edges shared pairwise
        int f0 = P.add_face(0, 1, 2), f1 = P.add_face(0, 3, 1), f2 = P.add_face(1, 3, 2),
            f3 = P.add_face(2, 3, 0);
        P.link(f0, 0, f1, 2);  // 0-1
        P.link(f0, 1, f2, 2);  // 1-2
        P.link(f0, 2, f3, 2);  // 2-0
        P.link(f1, 0, f3, 1);  // 0-3
        P.link(f1, 1, f2, 0);  // 3-1
        P.link(f2, 1, f3, 0);  // 3-2
    }
    int best = -1;
    bool epa_conv = false;
    i64 e_it = 0;
    for (; e_it < tol.max_iter; ++e_it) {
        best = -1;
        double bd = kInf;
        for (int q = 0; q < (int)P.f.size(); ++q)
            if (P.f[q].alive && P.f[q].d < bd) {
                bd = P.f[q].d;
                best = q;
            }
        if (best < 0) break;
        const Face fb = P.f[best];
        SV w = support(A, B, fb.u);
        if (dot(fb.u, w.w) - fb.d <= tol.epa_tol) {
            epa_conv = true;
            break;
        }
        int wi = (int)P.v.size();
        P.v.push_back(w);
        P.horizon.clear();
        P.f[best].alive = false;
        for (int e = 0; e < 3; ++e) P.silhouette(fb.adj_f[e], fb.adj_e[e], w.w);
        // the cone from w over the horizon: face k on horizon edge (b, a) of the alive face,
        // wound (a, b, w); its edge 0 borders that face, edges 1 and 2 the next and last faces
        const int h_n = (int)P.horizon.size();
        const int first = (int)P.f.size();
        for (int k = 0; k < h_n; ++k) {
            auto [af, ae] = P.horizon[k];
            int a = P.f[af].v[(ae + 1) % 3], b = P.f[af].v[ae];
            int nf = P.add_face(a, b, wi);
            P.link(nf, 0, af, ae);
        }
        for (int k = 0; k < h_n; ++k) P.link(first + k, 1, first + (k + 1) % h_n, 2);
    }
    if (best < 0) {
        if (stalled) return gjk_out;
        out.sep = 0;
        out.status = DIST_NOT_CONVERGED;
        out.n = {0, 0, 1};
        out.iters = it + e_it;
        return out;
    }
    const Face& f = P.f[best];
    // barycentric coordinates of the origin's projection d u in the face
    Vec p = f.d * f.u;
    Vec a = P.v[f.v[0]].w, b = P.v[f.v[1]].w, c = P.v[f.v[2]].w;
    Vec v0 = b - a, v1 = c - a, v2 = p - a;
    double d00 = dot(v0, v0), d01 = dot(v0, v1), d11 = dot(v1, v1), d20 = dot(v2, v0),
           d21 = dot(v2, v1);
    double den = d00 * d11 - d01 * d01;
    double lb = den != 0 ? (d11 * d20 - d01 * d21) / den : 0.0;
    double lc = den != 0 ? (d00 * d21 - d01 * d20) / den : 0.0;
    double la = 1.0 - lb - lc;
    out.pa = la * P.v[f.v[0]].a + lb * P.v[f.v[1]].a + lc * P.v[f.v[2]].a;
    out.pb = la * P.v[f.v[0]].b + lb * P.v[f.v[1]].b + lc * P.v[f.v[2]].b;
    // the weights of a sliver face rebuild p only roughly: share the miss between the two
    // witnesses, so that pa - pb = d u holds (each moves by half of it)
    Vec back = la * a + lb * b + lc * c;
    Vec miss = 0.5 * (p - back);
    out.pa = out.pa + miss;
    out.pb = out.pb - miss;
    // a moves along -u to separate: the normal from b into a is -u
    out.sep = -f.d;
    out.n = -f.u;
    out.status = epa_conv ? DIST_OK : DIST_NOT_CONVERGED;
    out.iters = it + e_it;
    // A stalled GJK: EPA's answer when it converged and either the origin is inside its
    // polytope (d >= 0: the cores overlap by d to within epa_tol) or just outside with its
    // projection d u inside the nearest face (that triangle lies in D, so the distance is at
    // most -d; D lies below the face's plane + epa_tol, so at least -d - epa_tol); else GJK's
    // upper bound.
    const double bary_eps = -1e-9;
    bool inside_face = la >= bary_eps && lb >= bary_eps && lc >= bary_eps &&
                       norm(back - p) <= tol.epa_tol;
    if (stalled && !(epa_conv && (f.d >= 0 || inside_face))) return gjk_out;
    return out;
}

}  // namespace convex
}  // namespace rb
