// Signed distance, normal and witness points of any pair of geoms (conventions: shapes.hpp),
// dispatched on the pair of types (the lower type first; a swapped pair flips n and swaps the
// witnesses). Closed forms where the geometry has one, GJK/EPA (convex.cpp) for the rest:
//
//   pair                                method                              exact?
//   plane - any                         support of the shape along -u       yes
//   sphere/capsule - sphere/capsule     closest points of two segments      yes
//                                       (a sphere: a segment of length 0)
//   sphere - box                        centre clamped to the box; inside:  yes
//                                       out through the nearest face
//   box - box                           apart: GJK; overlapping: the        yes (both polytopes)
//                                       separating-axis test (15 axes)
//   point/segment/box/mesh cores        GJK, EPA when the cores overlap     yes (polytope cores)
//   any pair with a cylinder/ellipsoid  GJK, EPA                            to gjk_tol / epa_tol
//                                       (within ~1e-6 m of touching: <= 3.3e-7 m)
//
// * plane (centre x_p, normal u = R e_z): the shape's deepest point is p = s(-u), its core's
//   support grown by the radius along -u; sep = u.(p - x_p), the plane's witness p - sep u.
// * segments P0 + s d1, Q0 + t d2, s, t in [0, 1]: Ericson, Real-Time Collision Detection 5.1.9
//   (clamped minimization of |P(s) - Q(t)|^2, parallel segments handled), then the radii.
// * the separating-axis test gives minus the penetration depth of two overlapping boxes exactly
//   (the minimum translation of two convex polyhedra lies along a face normal or an edge-edge
//   cross product); its witnesses straddle the centre of the touching patch.
#include <algorithm>
#include <cmath>
#include <limits>

#include "audit/audit.hpp"
#include "audit/shapes.hpp"

namespace rb {
namespace audit {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Shape a against plane b: (sep, n from the plane into a, pa on a, pb on the plane) with b's
// half-space z <= 0 in b's frame.
Dist plane_shape(const Geom& plane, const Geom& g) {
    Vec u = axis(plane, 2);
    Vec p = core_support(g, -u) - core_radius(g) * u;
    double sep = dot(u, p - plane.x);
    return {sep, u, p, p - sep * u, DIST_OK, 0};
}

// Closest points c1 = P0 + s d1, c2 = Q0 + t d2 of two segments (Ericson 5.1.9).
void segment_segment(Vec p0, Vec d1, Vec q0, Vec d2, Vec& c1, Vec& c2) {
    Vec r = p0 - q0;
    double a = dot(d1, d1), e = dot(d2, d2), f = dot(d2, r);
    double s, t;
    if (a <= 0 && e <= 0) {
        s = t = 0;
    } else if (a <= 0) {
        s = 0;
        t = std::clamp(f / e, 0.0, 1.0);
    } else {
        double c = dot(d1, r);
        if (e <= 0) {
            t = 0;
            s = std::clamp(-c / a, 0.0, 1.0);
        } else {
            double b = dot(d1, d2);
            double den = a * e - b * b;
            s = den > 0 ? std::clamp((b * f - c * e) / den, 0.0, 1.0) : 0.0;
            t = (b * s + f) / e;
            if (t < 0) {
                t = 0;
                s = std::clamp(-c / a, 0.0, 1.0);
            } else if (t > 1) {
                t = 1;
                s = std::clamp((b - c) / a, 0.0, 1.0);
            }
        }
    }
    c1 = p0 + s * d1;
    c2 = q0 + t * d2;
}

// Sphere or capsule a against sphere or capsule b.
Dist round_round(const Geom& a, const Geom& b) {
    double ha = a.type == GEOM_CAPSULE ? a.s[1] : 0.0;
    double hb = b.type == GEOM_CAPSULE ? b.s[1] : 0.0;
    Vec za = axis(a, 2), zb = axis(b, 2);
    Vec c1, c2;
    segment_segment(a.x - ha * za, (2 * ha) * za, b.x - hb * zb, (2 * hb) * zb, c1, c2);
    Vec d = c1 - c2;
    double dist = norm(d);
    Vec n;
    if (dist > 0) {
        n = (1.0 / dist) * d;
    } else {  // the cores cross: any direction normal to both axes
        Vec c = cross(za, zb);
        if (ha == 0 || hb == 0 || norm(c) == 0) c = std::fabs(za.x) < 0.9 ? cross(za, {1, 0, 0}) : cross(za, {0, 1, 0});
        if (ha == 0 && hb == 0) c = {0, 0, 1};
        n = (1.0 / norm(c)) * c;
    }
    return {dist - a.s[0] - b.s[0], n, c1 - a.s[0] * n, c2 + b.s[0] * n, DIST_OK, 0};
}

// Sphere a against box b.
Dist sphere_box(const Geom& a, const Geom& b) {
    Vec l = to_local(b, a.x - b.x);
    const double* h = b.s;
    Vec q{std::clamp(l.x, -h[0], h[0]), std::clamp(l.y, -h[1], h[1]), std::clamp(l.z, -h[2], h[2])};
    Vec f = l - q;
    double dist = norm(f);
    Vec m;
    double sep;
    if (dist > 0) {
        m = (1.0 / dist) * f;
        sep = dist - a.s[0];
    } else {  // inside: out through the nearest face
        double g0 = h[0] - std::fabs(l.x), g1 = h[1] - std::fabs(l.y), g2 = h[2] - std::fabs(l.z);
        m = {0, 0, 0};
        if (g0 <= g1 && g0 <= g2) {
            m.x = l.x >= 0 ? 1.0 : -1.0;
            q.x = m.x * h[0];
            sep = -g0 - a.s[0];
        } else if (g1 <= g2) {
            m.y = l.y >= 0 ? 1.0 : -1.0;
            q.y = m.y * h[1];
            sep = -g1 - a.s[0];
        } else {
            m.z = l.z >= 0 ? 1.0 : -1.0;
            q.z = m.z * h[2];
            sep = -g2 - a.s[0];
        }
    }
    Vec n = to_world(b, m) - b.x;
    n = (1.0 / norm(n)) * n;
    return {sep, n, a.x - a.s[0] * n, to_world(b, q), DIST_OK, 0};
}

// Overlapping boxes by the separating-axis test (geometry.cpp's pair): depth and normal exact;
// the witnesses straddle the centre m of the touching patch (geometry.cpp's box-box witness,
// midway between the surfaces): pa = m + sep n / 2, pb = m - sep n / 2.
Dist box_box_sat(const Geom& a, const Geom& b, double band, double axis_eps) {
    double xa[3] = {a.x.x, a.x.y, a.x.z}, xb[3] = {b.x.x, b.x.y, b.x.z};
    PairOut o = pair(SHAPE_BOX, xa, a.r, a.s, SHAPE_BOX, xb, b.r, b.s, true, band, axis_eps);
    Vec n{o.n0, o.n1, o.n2}, m{o.p0, o.p1, o.p2};
    return {o.sep, n, m + (0.5 * o.sep) * n, m - (0.5 * o.sep) * n, DIST_OK, 0};
}

Dist flip(Dist d) {
    std::swap(d.pa, d.pb);
    d.n = -d.n;
    return d;
}

}  // namespace

Dist geom_distance(const Geom& a, const Geom& b, const ConvexTol& tol, double band,
                   double axis_eps) {
    if (a.type > b.type) return flip(geom_distance(b, a, tol, band, axis_eps));
    const i64 ta = a.type, tb = b.type;
    if (ta == GEOM_PLANE) {
        if (tb == GEOM_PLANE) return {kNaN, {0, 0, 0}, {kNaN, kNaN, kNaN}, {kNaN, kNaN, kNaN}, DIST_UNSUPPORTED, 0};
        return flip(plane_shape(a, b));
    }
    if (tb <= GEOM_CAPSULE) return round_round(a, b);
    if (ta == GEOM_SPHERE && tb == GEOM_BOX) return sphere_box(a, b);
    Dist d = convex_distance(a, b, tol);
    if (ta == GEOM_BOX && tb == GEOM_BOX && d.sep <= 0) {
        Dist s = box_box_sat(a, b, band, axis_eps);
        s.iters = d.iters;
        return s;
    }
    double ra = core_radius(a), rb = core_radius(b);
    d.sep -= ra + rb;
    d.pa = d.pa - ra * d.n;
    d.pb = d.pb + rb * d.n;
    return d;
}

void geom_pairs_kernel(V1<i64> k, V1<i64> i, V1<i64> j, V3<double> position, V4<double> rotation,
                       V1<i64> type, V2<double> size, V1<i64> mesh_start, V1<i64> mesh_count,
                       V2<double> verts, double gjk_tol, double epa_tol, i64 max_iter,
                       double band, double axis_eps, V1<double> sep, V2<double> n, V2<double> pa,
                       V2<double> pb, V1<i64> status, V1<i64> iters) {
    ConvexTol tol{gjk_tol, epa_tol, max_iter};
    auto geom = [&](i64 kk, i64 g) {
        const double* x = &position(kk, g, 0);
        const double* vp = mesh_count[g] > 0 ? &verts(mesh_start[g], 0) : nullptr;
        return Geom{type[g], {x[0], x[1], x[2]}, &rotation(kk, g, 0, 0), &size(g, 0), vp,
                    mesh_count[g]};
    };
    for (i64 r = 0; r < k.n0; ++r) {
        Dist d = geom_distance(geom(k[r], i[r]), geom(k[r], j[r]), tol, band, axis_eps);
        sep[r] = d.sep;
        status[r] = d.status;
        iters[r] = d.iters;
        if (n.n0) {
            n(r, 0) = d.n.x;
            n(r, 1) = d.n.y;
            n(r, 2) = d.n.z;
            pa(r, 0) = d.pa.x;
            pa(r, 1) = d.pa.y;
            pa(r, 2) = d.pa.z;
            pb(r, 0) = d.pb.x;
            pb(r, 1) = d.pb.y;
            pb(r, 2) = d.pb.z;
        }
    }
}

}  // namespace audit
}  // namespace rb
