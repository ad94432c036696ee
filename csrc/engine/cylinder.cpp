// Cylinder colliders (narrowphase.cpp's table calls them; conventions there: normal from b into
// a, sep < 0 penetration, points midway between the surfaces, feature ids for warm starting).
//
// A cylinder is x^2 + y^2 <= r^2, |z| <= h in its body frame (size [r, h, 0]; z the body's third
// axis). Its caps are discs of radius r at z = +-h; a cap's manifold uses the cap polygon: the
// CAP_VERTS rim points at angles 2 pi k / CAP_VERTS in the body frame (fixed material points, so
// their ids persist), which lie on the rim, so every gap measured at them is a true gap.
//
// * cylinder - plane (closed form): for each cap (c = x -+ h z), its deepest rim point c + r u,
//   u = -(n - (n.z) z) / |n - (n.z) z| (its gap n.c - off - r |n - (n.z) z|); a level cap (its
//   rim's heights within r |n - (n.z) z| <= MANIFOLD_TOUCH_BAND_M) or one lying within the
//   speculative band (its highest rim point's gap, the deepest's + 2 r |n - (n.z) z|, <= spec)
//   also its polygon's vertices, the rim point then only when deeper than every vertex (a cap
//   within round-off of level has all its rim at one height: the polygon alone, 4 fixed points
//   after reduction). A nearly level cap needs the polygon: its one deepest rim point cannot
//   hold it from tipping about that point, and the far side, inside the band, then sinks into
//   the plane within the step (a can landing on its rim and settling onto its cap at dt 1e-2
//   swung between opposite rim points each step, the project stage pushing it out, and its
//   kinetic energy grew from about 0.13 to 1.1 J while it stayed on its cap). A cap tilted further
//   keeps only its rim point: the polygon's vertices are material points, and one rolling
//   towards the bottom approaches the plane at omega r sin(phi), which the solve's linear gap
//   prediction takes for an impact (a cylinder rolling on its side would be kicked at every
//   vertex). Lying on its side the two caps' deepest rim points are the line contact's ends.
// * sphere - cylinder (closed form): the sphere centre p in the cylinder frame clamped to the
//   solid (rho = |p_xy| to r, p_z to [-h, h]); outside: normal (p - q) / |p - q|; inside: out
//   through the nearer of the side (r - rho) and the cap (h - |p_z|). One point.
// * box / capsule / cylinder - cylinder (no closed form): GJK + EPA (csrc/common/convex.hpp, the
//   audit's algorithm) give a normal n0 and the cores' witness points. The signed distance of two
//   convex shapes is max_u g(u), g(u) = u.s_A(-u) - u.s_B(u) (- the radii) over unit u (the
//   separating-axis theorem, both apart and overlapping), and g is exact from the support
//   functions; so the normal taken is the u of largest g among n0, the box face normals, the
//   cylinder's cap axis, the cross products of the two shapes' axes and, for two near-parallel
//   axes, the line between them (ties within round-off go to those exact axes): a face contact
//   (a cap or a box face, a side on a face, two parallel sides) gets its exact normal and gap, a
//   curved one GJK/EPA's to CONVEX_*_TOL_M (g is flat at its maximum: its error is second order
//   in n0's). The manifold (Jolt's ManifoldBetweenTwoFaces): each shape's supporting feature
//   along the normal (a: along -n, b: along +n): a box's face most aligned with it; a
//   cylinder's cap polygon when |d.z| >= |d_xy|, else its side line at the angle of d; a
//   capsule's segment moved by r along d when |d.z| < |d_xy|, else a point. The polygon better
//   aligned with n is the reference: the other feature clipped to its side planes (Sutherland -
//   Hodgman), each clipped point's gap measured along n to the reference plane; two segments
//   within SEGMENT_PARALLEL_SIN of parallel: the overlap's ends. Every gap is at least the pair's
//   (g(n) bounds every pair of surface points along n from below: clamped to it), and the
//   pair's deepest point (the witnesses' midpoint) joins when no clipped point is as deep; more
//   than four: reduce_manifold.
//
// * sphere / box / capsule / cylinder / hull - hull: the same path (collide_convex). A hull
//   (hull.hpp: body-frame vertices, faces with outward normals, edge directions) is GJK/EPA's
//   mesh core; its candidate axes are its face normals and, against a box, capsule or cylinder,
//   its edge directions crossed with the other shape's axes (two hulls: GJK/EPA's normal, exact
//   for two polytopes, and both hulls' face normals); its supporting feature along d is the face
//   whose normal is nearest d (a polygon of up to HULL_MAX_FACE_VERTICES), a sphere's is its one
//   point. Every candidate's g(u) is a lower bound of the signed distance, so the largest is
//   always safe to take.
//
// Why this module is long: the five cylinder pairs share the feature, clipping and reduction
// helpers, which belong with them (capsule.cpp's split: one file per shape).
//
// Feature ids: cap vertex k of cap c (0: -h, 1: +h): 16 c + k; deepest rim point 16 c + 8; side
// line ends 32, 33; box vertex bits (1: +x, 2: +y, 4: +z) + 64 on a, + 128 on b; capsule ends
// 256, 257; hull vertex v: 2^16 + v on a, 2^17 + v on b; a sphere's point 0; a clipped
// intersection mixes the ref side and the edge's ends (+ 2^20); the pair's
// deepest point 1023.
#include <algorithm>
#include <cmath>

#include "common/convex.hpp"
#include "engine/collider_points.hpp"
#include "engine/collision.hpp"
#include "engine/hull.hpp"

namespace rb {

namespace {

using convex::Vec;
using convex::cross;
using convex::dot;
using convex::norm;

constexpr int CAP_VERTS = 8;
// two side lines or segments closer than this to parallel (sin of the angle) give a two-point
// line contact; beyond, the pair's one deepest point (a crossing's contact is a point)
constexpr double SEGMENT_PARALLEL_SIN = 1e-2;
constexpr i64 FID_DEEPEST = 1023;
// m: the second GJK/EPA run of a pair (collide_convex) sees b grown by this, so that a pair
// touching to within round-off is 1 mm deep there (EPA well-conditioned); a pair 1 mm apart is
// conditioned in the first run. Larger than any resting contact's depth (allowed_penetration
// 5e-5 m), small against the shapes (the curvature EPA resolves is the grown one's).
constexpr double TOUCH_GROW_M = 1e-3;
// a supporting feature's most points (a hull face's), and the clipped candidates' (two faces')
constexpr int MAX_FEAT = HULL_MAX_FACE_VERTICES;
constexpr int MAX_PTS = 2 * MAX_FEAT + 8;
// feature ids of a hull's vertex v: HULL_FID + v on a, 2 HULL_FID + v on b
constexpr i64 HULL_FID = 1 << 16;

inline Vec load(const double* p) { return {p[0], p[1], p[2]}; }
inline Vec col(M3 r, int j) { return {r(0, j), r(1, j), r(2, j)}; }
inline Vec to_local(M3 r, Vec d) {  // R^T d
    return {r(0, 0) * d.x + r(1, 0) * d.y + r(2, 0) * d.z,
            r(0, 1) * d.x + r(1, 1) * d.y + r(2, 1) * d.z,
            r(0, 2) * d.x + r(1, 2) * d.y + r(2, 2) * d.z};
}
inline Vec to_world(M3 r, Vec l) {  // R l
    return {r(0, 0) * l.x + r(0, 1) * l.y + r(0, 2) * l.z,
            r(1, 0) * l.x + r(1, 1) * l.y + r(1, 2) * l.z,
            r(2, 0) * l.x + r(2, 1) * l.y + r(2, 2) * l.z};
}
inline double comp(Vec a, int j) { return j == 0 ? a.x : (j == 1 ? a.y : a.z); }
// cos, sin of the cap polygon's vertex k (exact at the quarter turns)
inline void cap_angle(int k, double& c, double& s) {
    static const double q = std::sqrt(0.5);
    static const double cs[8][2] = {{1, 0}, {q, q}, {0, 1}, {-q, q}, {-1, 0}, {-q, -q}, {0, -1}, {q, -q}};
    c = cs[k][0];
    s = cs[k][1];
}

// One shape of a pair, as the engine holds it.
struct Shape {
    i64 geom;  // engine code
    Vec x;
    M3 r;
    const double* s;
    const Hull* hull = nullptr;  // a hull's (hull.hpp)
};

convex::Geom as_convex(const Shape& sh) {
    if (sh.geom == GEOM_HULL)
        return convex::Geom{convex::GEOM_MESH, sh.x, sh.r.p, sh.s, sh.hull->vert.data(),
                            sh.hull->nv};
    i64 t = sh.geom == GEOM_BOX ? convex::GEOM_BOX
            : sh.geom == GEOM_CAPSULE ? convex::GEOM_CAPSULE
            : sh.geom == GEOM_CYLINDER ? convex::GEOM_CYLINDER
                                       : convex::GEOM_SPHERE;
    return convex::Geom{t, sh.x, sh.r.p, sh.s, nullptr, 0};
}

// A length of the shape's size (m): round-off scales of the pair's tests.
double shape_scale(const Shape& sh) {
    return sh.geom == GEOM_HULL ? sh.hull->radius : sh.s[0] + sh.s[1] + sh.s[2];
}

// g(u): the gap of the projections on the unit u (from b into a), radii subtracted.
inline double axis_gap(const convex::Geom& A, const convex::Geom& B, Vec u) {
    return dot(u, convex::core_support(A, -1.0 * u)) - convex::core_radius(A) -
           dot(u, convex::core_support(B, u)) - convex::core_radius(B);
}

// A supporting feature: n = 1 point, 2 segment, >= 3 a convex polygon (ordered) with outward
// normal nf; p world points on the surface, id feature ids.
struct Feature {
    int n = 0;
    Vec p[MAX_FEAT];
    i64 id[MAX_FEAT];
    Vec nf{0, 0, 0};
};

// The supporting feature of shape sh along the unit world direction d; id_base separates a's box
// vertices from b's.
Feature supporting_feature(const Shape& sh, Vec d, i64 id_base) {
    Feature f;
    Vec dl = to_local(sh.r, d);
    if (sh.geom == GEOM_HULL) {  // the face whose normal is nearest d
        const Hull& hl = *sh.hull;
        i64 best = 0;
        double bd = -INFINITY;
        for (i64 k = 0; k < hl.nf; ++k) {
            const double* u = &hl.fnrm[3 * k];
            const double g = u[0] * dl.x + u[1] * dl.y + u[2] * dl.z;
            if (g > bd) {
                bd = g;
                best = k;
            }
        }
        const i64 s0 = hl.fstart[best], m = hl.fstart[best + 1] - s0;
        for (i64 k = 0; k < m; ++k) {
            const i64 v = hl.fvert[s0 + k];
            f.p[k] = sh.x + to_world(sh.r, {hl.vert[3 * v], hl.vert[3 * v + 1], hl.vert[3 * v + 2]});
            f.id[k] = (id_base == 64 ? 1 : 2) * HULL_FID + v;
        }
        f.n = static_cast<int>(m);
        const double* u = &hl.fnrm[3 * best];
        f.nf = to_world(sh.r, {u[0], u[1], u[2]});
        return f;
    }
    if (sh.geom == GEOM_SPHERE) {  // its point along d
        f.p[0] = sh.x + sh.s[0] * d;
        f.id[0] = 0;
        f.n = 1;
        return f;
    }
    if (sh.geom == GEOM_BOX) {
        const double* e = sh.s;
        int j = 0;
        for (int k = 1; k < 3; ++k)
            if (std::fabs(comp(dl, k)) > std::fabs(comp(dl, j))) j = k;
        const double sg = comp(dl, j) >= 0 ? 1.0 : -1.0;
        const int j1 = (j + 1) % 3, j2 = (j + 2) % 3;
        static const double U[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
        for (int k = 0; k < 4; ++k) {
            double c[3];
            c[j] = sg * e[j];
            c[j1] = U[k][0] * e[j1];
            c[j2] = U[k][1] * e[j2];
            f.p[k] = sh.x + to_world(sh.r, {c[0], c[1], c[2]});
            f.id[k] = id_base + (c[0] > 0 ? 1 : 0) + (c[1] > 0 ? 2 : 0) + (c[2] > 0 ? 4 : 0);
        }
        f.n = 4;
        f.nf = sg * col(sh.r, j);
        return f;
    }
    const double r = sh.s[0], h = sh.s[1];
    const double rho = std::sqrt(dl.x * dl.x + dl.y * dl.y);
    if (sh.geom == GEOM_CYLINDER) {
        if (std::fabs(dl.z) >= rho) {  // the cap facing d
            const double sg = dl.z >= 0 ? 1.0 : -1.0;
            for (int k = 0; k < CAP_VERTS; ++k) {
                double c, s;
                cap_angle(k, c, s);
                f.p[k] = sh.x + to_world(sh.r, {r * c, r * s, sg * h});
                f.id[k] = 16 * (sg > 0 ? 1 : 0) + k;
            }
            f.n = CAP_VERTS;
            f.nf = sg * col(sh.r, 2);
        } else {  // the side line at d's angle
            const double ux = dl.x / rho, uy = dl.y / rho;
            f.p[0] = sh.x + to_world(sh.r, {r * ux, r * uy, -h});
            f.p[1] = sh.x + to_world(sh.r, {r * ux, r * uy, h});
            f.id[0] = 32;
            f.id[1] = 33;
            f.n = 2;
        }
        return f;
    }
    // capsule: the segment (or its end) moved by r along d
    Vec z = col(sh.r, 2);
    if (std::fabs(dl.z) < rho) {
        f.p[0] = sh.x + (-h) * z + r * d;
        f.p[1] = sh.x + h * z + r * d;
        f.id[0] = 256;
        f.id[1] = 257;
        f.n = 2;
    } else {
        f.p[0] = sh.x + (dl.z >= 0 ? h : -h) * z + r * d;
        f.id[0] = dl.z >= 0 ? 257 : 256;
        f.n = 1;
    }
    return f;
}

inline i64 mix_id(int side, i64 a, i64 b) {
    return (1 << 20) + ((side * 1021 + a * 37 + b * 7919) & 0xFFFFF);
}

// Candidate points (surface point on the incident feature, its id) of the incident feature
// clipped to the side planes of the reference polygon ref (Sutherland - Hodgman).
int clip_to_polygon(const Feature& ref, const Feature& inc, Vec* out, i64* out_id) {
    Vec c{0, 0, 0};
    for (int k = 0; k < ref.n; ++k) c = c + ref.p[k];
    c = (1.0 / ref.n) * c;
    Vec buf[2][MAX_PTS];
    i64 ids[2][MAX_PTS];
    int m = inc.n;
    for (int k = 0; k < m; ++k) {
        buf[0][k] = inc.p[k];
        ids[0][k] = inc.id[k];
    }
    int cur = 0;
    for (int e = 0; e < ref.n && m > 0; ++e) {
        Vec v0 = ref.p[e], v1 = ref.p[(e + 1) % ref.n];
        Vec w = cross(v1 - v0, ref.nf);
        if (dot(w, c - v0) < 0) w = -1.0 * w;
        int nxt = 1 - cur, mo = 0;
        auto dist = [&](Vec p) { return dot(w, p - v0); };
        if (m == 2) {  // a segment: keep its clipped piece (both ends, in order)
            double d0 = dist(buf[cur][0]), d1 = dist(buf[cur][1]);
            if (d0 < 0 && d1 < 0) return 0;
            Vec p0 = buf[cur][0], p1 = buf[cur][1];
            i64 i0 = ids[cur][0], i1 = ids[cur][1];
            if (d0 < 0) {
                p0 = p0 + (d0 / (d0 - d1)) * (p1 - p0);
                i0 = mix_id(e, i0, i1);
            } else if (d1 < 0) {
                p1 = p1 + (d1 / (d1 - d0)) * (p0 - p1);
                i1 = mix_id(e, i1, i0);
            }
            buf[nxt][0] = p0;
            buf[nxt][1] = p1;
            ids[nxt][0] = i0;
            ids[nxt][1] = i1;
            mo = 2;
        } else {
            for (int i = 0; i < m; ++i) {
                Vec p = buf[cur][i], q = buf[cur][(i + 1) % m];
                double dp = dist(p), dq = dist(q);
                if (dp >= 0 && mo < MAX_PTS) {
                    buf[nxt][mo] = p;
                    ids[nxt][mo++] = ids[cur][i];
                }
                if ((dp >= 0) != (dq >= 0) && mo < MAX_PTS) {
                    buf[nxt][mo] = p + (dp / (dp - dq)) * (q - p);
                    ids[nxt][mo++] = mix_id(e, ids[cur][i], ids[cur][(i + 1) % m]);
                }
            }
        }
        m = mo;
        cur = nxt;
    }
    for (int k = 0; k < m; ++k) {
        out[k] = buf[cur][k];
        out_id[k] = ids[cur][k];
    }
    return m;
}

// reduce_manifold over points whose order and gaps do not depend on round-off: coincident points
// (within 1e-9 scale) merged, the rest ordered by feature id, then reduce_quantized
// (collider_points.hpp: the touching points count as equally deep): which four a level face's
// rim keeps must not change from step to step (warm starting).
i64 reduce_stable(const double* nrm, double (*P)[3], double* S, i64* F, i64 count, double scale) {
    i64 m = 0;
    const double tol2 = (1e-9 * scale) * (1e-9 * scale);
    for (i64 k = 0; k < count; ++k) {
        bool dup = false;
        for (i64 j = 0; j < m && !dup; ++j) {
            double dx = P[k][0] - P[j][0], dy = P[k][1] - P[j][1], dz = P[k][2] - P[j][2];
            if (dx * dx + dy * dy + dz * dz <= tol2) {
                dup = true;
                if (S[k] < S[j]) S[j] = S[k];
            }
        }
        if (!dup) {
            if (m != k) {
                for (int c = 0; c < 3; ++c) P[m][c] = P[k][c];
                S[m] = S[k];
                F[m] = F[k];
            }
            ++m;
        }
    }
    // insertion sort by feature id
    for (i64 k = 1; k < m; ++k)
        for (i64 j = k; j > 0 && F[j] < F[j - 1]; --j) swap_point(P, S, F, j, j - 1);
    if (m <= MAX_MANIFOLD_POINTS) return m;
    i64 ids[MAX_PTS];
    const i64 n = reduce_quantized<MAX_PTS>(nrm, P, S, m, ids);
    double P3[MAX_MANIFOLD_POINTS][3], S3[MAX_MANIFOLD_POINTS];
    i64 F3[MAX_MANIFOLD_POINTS];
    for (i64 k = 0; k < n; ++k) {
        for (int c = 0; c < 3; ++c) P3[k][c] = P[ids[k]][c];
        S3[k] = S[ids[k]];
        F3[k] = F[ids[k]];
    }
    for (i64 k = 0; k < n; ++k) {
        for (int c = 0; c < 3; ++c) P[k][c] = P3[k][c];
        S[k] = S3[k];
        F[k] = F3[k];
    }
    return n;
}

}  // namespace

i64 collide_cylinder_plane(const double* ca, M3 rota, const double* sa, const double* pn,
                           double poff, double spec, double* nrm, Pts pts, double* sep,
                           i64* fid) {
    const CollisionConstants& cc = collision_constants();
    const double r = sa[0], h = sa[1];
    Vec c = load(ca), n = load(pn), z = col(rota, 2);
    Vec nl = to_local(rota, n);
    const double rho = std::sqrt(nl.x * nl.x + nl.y * nl.y);
    const double hc = dot(n, c) - poff;
    if (hc - h * std::fabs(nl.z) - r * rho > spec) return 0;
    double P[MAX_PTS][3], S[MAX_PTS];
    i64 F[MAX_PTS];
    i64 count = 0;
    const double tie = 1e-12 * (r + h);
    for (int cap = 0; cap < 2; ++cap) {
        const double zc = cap == 0 ? -h : h;
        double least = INFINITY;
        // the polygon for a level cap or one lying within the speculative band (module
        // comment): a tilted one rolls on its rim
        const double s_rim = hc + nl.z * zc - r * rho;
        const bool level = r * rho <= cc.manifold_touch_band_m || s_rim + 2.0 * r * rho <= spec;
        for (int k = 0; k < CAP_VERTS && level; ++k) {
            double cs, sn;
            cap_angle(k, cs, sn);
            const double s = hc + nl.z * zc + r * (nl.x * cs + nl.y * sn);
            least = std::min(least, s);
            if (s > spec) continue;
            Vec v = c + to_world(rota, {r * cs, r * sn, zc});
            put(P, S, F, count++, v - (0.5 * s) * n, s, 16 * cap + k);
        }
        if (rho > 0 && s_rim < least - tie && s_rim <= spec) {
            Vec v = c + zc * z + to_world(rota, {-r * nl.x / rho, -r * nl.y / rho, 0.0});
            put(P, S, F, count++, v - (0.5 * s_rim) * n, s_rim, 16 * cap + 8);
        }
    }
    put_normal(nrm, n);
    count = reduce_stable(nrm, P, S, F, count, r + h);
    for (i64 k = 0; k < count; ++k) put(pts, sep, fid, k, Vec{P[k][0], P[k][1], P[k][2]}, S[k], F[k]);
    return count;
}

i64 collide_sphere_cylinder(const double* ca, double ra, const double* cb, M3 rotb,
                            const double* sb, double spec, double* nrm, Pts pts, double* sep,
                            i64* fid) {
    const double r = sb[0], h = sb[1];
    Vec xb = load(cb);
    Vec l = to_local(rotb, load(ca) - xb);
    const double rho = std::sqrt(l.x * l.x + l.y * l.y);
    Vec q, nl;
    double s;
    if (rho > r || std::fabs(l.z) > h) {
        // outside: the closest point of the solid
        const double f = rho > r ? r / rho : 1.0;
        q = {f * l.x, f * l.y, std::clamp(l.z, -h, h)};
        Vec d = l - q;
        const double dn = norm(d);
        s = dn - ra;
        if (s > spec) return 0;
        nl = (1.0 / dn) * d;
    } else if (h - std::fabs(l.z) <= r - rho) {
        // inside, nearer a cap
        const double sg = l.z >= 0 ? 1.0 : -1.0;
        q = {l.x, l.y, sg * h};
        nl = {0, 0, sg};
        s = -(h - std::fabs(l.z)) - ra;
    } else {
        // inside, nearer the side (on the axis: out along the body's x)
        nl = rho > 0 ? Vec{l.x / rho, l.y / rho, 0} : Vec{1, 0, 0};
        q = {r * nl.x, r * nl.y, l.z};
        s = -(r - rho) - ra;
    }
    Vec n = to_world(rotb, nl);
    put_normal(nrm, n);
    put(pts, sep, fid, 0, xb + to_world(rotb, q) + (0.5 * s) * n, s, 0);
    return 1;
}

double convex_axis_gap(i64 ga, const double* ca, M3 rota, const double* sa, i64 gb,
                       const double* cb, M3 rotb, const double* sb, const double* u) {
    const Shape A{ga, load(ca), rota, sa, ga == GEOM_HULL ? &hull_of(sa) : nullptr},
        B{gb, load(cb), rotb, sb, gb == GEOM_HULL ? &hull_of(sb) : nullptr};
    Vec d = load(u);
    return axis_gap(as_convex(A), as_convex(B), (1.0 / norm(d)) * d);
}

i64 collide_convex(i64 ga, const double* ca, M3 rota, const double* sa, i64 gb,
                   const double* cb, M3 rotb, const double* sb, double spec, double* nrm,
                   Pts pts, double* sep, i64* fid) {
    const CollisionConstants& cc = collision_constants();
    const Shape A{ga, load(ca), rota, sa, ga == GEOM_HULL ? &hull_of(sa) : nullptr},
        B{gb, load(cb), rotb, sb, gb == GEOM_HULL ? &hull_of(sb) : nullptr};
    const convex::Geom GA = as_convex(A), GB = as_convex(B);
    const double rA = convex::core_radius(GA), rB = convex::core_radius(GB);
    const convex::ConvexTol tol{cc.convex_gjk_tol_m, cc.convex_epa_tol_m, cc.convex_max_iter};
    convex::Dist d = convex::convex_distance(GA, GB, tol);
    if (d.sep - rA - rB > spec) return 0;
    if (d.sep < TOUCH_GROW_M) {
        // within round-off of touching GJK/EPA's normal is ill-conditioned (its simplex passes
        // through the origin): B grown by TOUCH_GROW_M is the same pair TOUCH_GROW_M deeper,
        // with the same normal; the better of the two axes is kept. Cores TOUCH_GROW_M apart
        // or more (a capsule's segment above a cylinder, say) are conditioned in the first run.
        convex::Geom GB2 = GB;
        GB2.grow = TOUCH_GROW_M;
        convex::Dist e = convex::convex_distance(GA, GB2, tol);
        if (axis_gap(GA, GB, e.n) > axis_gap(GA, GB, d.n)) {
            d = e;
            d.pb = d.pb + TOUCH_GROW_M * d.n;  // back onto B's core (+ rB below)
        }
    }
    const double scale = shape_scale(A) + shape_scale(B);
    // the separating axis of largest gap (module comment); every candidate's g is a lower bound
    // of the signed distance, so a candidate too many costs time, never correctness
    Vec n = d.n;
    double s0 = axis_gap(GA, GB, n);
    {
        Vec best_u = n;
        double best_g = -INFINITY;
        auto consider = [&](Vec u) {
            const double lu = norm(u);
            if (lu <= 1e-9) return;
            u = (dot(u, n) >= 0 ? 1.0 / lu : -1.0 / lu) * u;
            const double g = axis_gap(GA, GB, u);
            if (g > best_g) {
                best_g = g;
                best_u = u;
            }
        };
        // a shape's axes: a box's three, a capsule's or cylinder's one, a hull's edge
        // directions (world); none for a sphere
        auto axes_of = [](const Shape& sh, Vec* out, int& k) {
            if (sh.geom == GEOM_BOX)
                for (int j = 0; j < 3; ++j) out[k++] = col(sh.r, j);
            else if (sh.geom == GEOM_CAPSULE || sh.geom == GEOM_CYLINDER)
                out[k++] = col(sh.r, 2);
        };
        Vec ax_a[3], ax_b[3];
        int na = 0, nb = 0;
        axes_of(A, ax_a, na);
        axes_of(B, ax_b, nb);
        // face normals: a box's three axes, a cylinder's cap axis (not a capsule's), a hull's
        // faces' normals
        if (A.geom != GEOM_CAPSULE)
            for (int i = 0; i < na; ++i) consider(ax_a[i]);
        if (B.geom != GEOM_CAPSULE)
            for (int i = 0; i < nb; ++i) consider(ax_b[i]);
        for (const Shape* sh : {&A, &B})
            if (sh->geom == GEOM_HULL)
                for (i64 k = 0; k < sh->hull->nf; ++k) {
                    const double* u = &sh->hull->fnrm[3 * k];
                    consider(to_world(sh->r, {u[0], u[1], u[2]}));
                }
        for (int i = 0; i < na; ++i)
            for (int j = 0; j < nb; ++j) consider(cross(ax_a[i], ax_b[j]));
        // a hull's edges crossed with the other shape's axes (two hulls: EPA's normal is exact
        // for two polytopes, their edge pairs are not searched)
        auto hull_edges_x = [&](const Shape& h, const Vec* ax, int nax) {
            for (i64 e = 0; e < h.hull->ne; ++e) {
                const double* u = &h.hull->edir[3 * e];
                const Vec ew = to_world(h.r, {u[0], u[1], u[2]});
                for (int j = 0; j < nax; ++j) consider(cross(ew, ax[j]));
            }
        };
        if (A.geom == GEOM_HULL && B.geom != GEOM_HULL) hull_edges_x(A, ax_b, nb);
        if (B.geom == GEOM_HULL && A.geom != GEOM_HULL) hull_edges_x(B, ax_a, na);
        // two axis shapes (capsule, cylinder) near parallel: the line between their axes
        if (na == 1 && nb == 1 && norm(cross(ax_a[0], ax_b[0])) <= SEGMENT_PARALLEL_SIN) {
            Vec w = A.x - B.x;
            consider(w - dot(w, ax_a[0]) * ax_a[0]);
        }
        if (best_g >= s0 - 1e-12 * scale) {
            n = best_u;
            s0 = std::max(best_g, s0);
        }
    }
    if (s0 > spec) return 0;
    put_normal(nrm, n);

    double P[MAX_PTS][3], S[MAX_PTS];
    i64 F[MAX_PTS];
    i64 count = 0;
    const Feature fa = supporting_feature(A, -1.0 * n, 64), fb = supporting_feature(B, n, 128);
    auto add = [&](Vec pa, Vec pb, i64 id) {  // a's surface point, b's, along n
        double s = std::max(dot(n, pa - pb), s0);
        if (s > spec || count >= MAX_PTS) return;
        Vec m = 0.5 * (pa + pb);
        put(P, S, F, count++, m, s, id);
    };
    const bool poly_a = fa.n >= 3, poly_b = fb.n >= 3;
    if (poly_a || poly_b) {
        const bool ref_is_a =
            poly_a && (!poly_b || std::fabs(dot(fa.nf, n)) > std::fabs(dot(fb.nf, n)));
        const Feature& ref = ref_is_a ? fa : fb;
        const Feature& inc = ref_is_a ? fb : fa;
        const double nfn = dot(ref.nf, n);
        Vec q0 = ref.p[0];
        if (inc.n >= 2 && std::fabs(nfn) > 1e-6) {
            Vec cp[MAX_PTS];
            i64 cid[MAX_PTS];
            const int m = clip_to_polygon(ref, inc, cp, cid);
            for (int k = 0; k < m; ++k) {
                // along n from the incident point to the reference plane
                const double t = dot(ref.nf, q0 - cp[k]) / nfn;
                Vec on_ref = cp[k] + t * n;
                if (ref_is_a)
                    add(on_ref, cp[k], cid[k]);
                else
                    add(cp[k], on_ref, cid[k]);
            }
        }
    } else if (fa.n == 2 && fb.n == 2) {
        Vec ua = fa.p[1] - fa.p[0], ub = fb.p[1] - fb.p[0];
        const double la = norm(ua), lb = norm(ub);
        if (la > 0 && lb > 0 && norm(cross(ua, ub)) <= SEGMENT_PARALLEL_SIN * la * lb) {
            Vec u = (1.0 / lb) * ub;
            // a's segment clipped to the slab of b's: u.(p - b0) in [0, lb]
            double t0 = 0.0, t1 = 1.0;
            const double d0 = dot(u, fa.p[0] - fb.p[0]), dd = dot(u, ua);
            if (dd != 0.0) {
                double ta = (0.0 - d0) / dd, tb = (lb - d0) / dd;
                if (ta > tb) std::swap(ta, tb);
                t0 = std::max(t0, ta);
                t1 = std::min(t1, tb);
            } else if (d0 < 0 || d0 > lb) {
                t1 = -1.0;
            }
            for (int k = 0; k < 2 && t0 <= t1; ++k) {
                const double t = k == 0 ? t0 : t1;
                Vec pa = fa.p[0] + t * ua;
                Vec pb = fb.p[0] + std::clamp(dot(u, pa - fb.p[0]), 0.0, lb) * u;
                add(pa, pb, fa.id[k] * 8 + fb.id[0]);
                if (t1 - t0 <= 1e-12) break;
            }
        }
    }
    // the pair's deepest point (the witnesses, moved onto the surfaces along GJK/EPA's normal)
    double least = INFINITY;
    for (i64 k = 0; k < count; ++k) least = std::min(least, S[k]);
    if (!(least <= s0 + 1e-12 * scale) && count < MAX_PTS) {
        Vec pa = d.pa - rA * d.n, pb = d.pb + rB * d.n;
        put(P, S, F, count++, 0.5 * (pa + pb), s0, FID_DEEPEST);
    }
    count = reduce_stable(nrm, P, S, F, count, scale);
    for (i64 k = 0; k < count; ++k) put(pts, sep, fid, k, Vec{P[k][0], P[k][1], P[k][2]}, S[k], F[k]);
    return count;
}

}  // namespace rb
