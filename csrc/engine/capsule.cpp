// Capsule colliders (narrowphase.cpp's table calls them; conventions there: normal from b into
// a, sep < 0 penetration, points midway between the surfaces, feature ids for warm starting).
//
// A capsule is the segment x + t z, t in [-h, h] (z: the body's third axis, h = size[1]) grown
// by the radius r = size[0] (the contract's capsule [r, h, 0], MuJoCo's convention). Every
// capsule pair is then a segment pair with the radii subtracted, exact in closed form:
//
// * capsule - plane: each end's sphere against the plane: up to 2 points (fid 0: end -h,
//   1: end +h).
// * sphere - capsule: the sphere centre's closest point on the segment (t clamped), then
//   sphere - sphere: 1 point.
// * capsule - capsule: closest points of the two segments (Ericson, Real-Time Collision
//   Detection 5.1.9). When the axes are parallel to within CAPSULE_PARALLEL_SIN and their
//   projections overlap, two points at the ends of the overlap on a's axis (fids 1, 2), each
//   with its own gap along the common normal; else the one closest pair (fid 0).
// * box - capsule: the segment's closest point to the box, exact: in the box frame the squared
//   distance g(t) = sum_j (p_j(t) - clamp(p_j(t), -e_j, e_j))^2 of the segment point p(t) is a
//   piecewise quadratic with breaks where a coordinate crosses +-e_j (at most 6); the minimum of
//   each piece is its vertex clamped to the piece. Apart (g > 0): normal (p - q) / |p - q|. The
//   segment meeting the box: the separating-axis test over the axes of the Minkowski sum of box
//   and segment, the box's 3 face normals and the 3 products z x e_j (the least overlap is the
//   penetration depth, exact for polytopes), a face axis kept unless an edge axis beats it by
//   (1 - EDGE_REL_TOL) |gap| + AXIS_ABS_TOL, as box_box.cpp does. When the normal is a box
//   face's, the segment clipped to that face's rectangle gives up to 2 points with their own
//   gaps (fids 8 + 2 face + k, k = 0 lower end, 1 upper end of the clipped piece; face = 2 axis
//   + (sign > 0)); else one point (fid 0). A manifold's least gap is always the pair's: the
//   one point joins the clipped ones when the deepest part of the segment is off the face.
#include <algorithm>
#include <cmath>

#include "engine/collider_points.hpp"
#include "engine/collision.hpp"
#include "engine/vec3.hpp"

namespace rb {

namespace {

// sin of the angle below which two capsule axes count as parallel (two-point manifold): at
// 1e-3 rad a 1 m capsule's ends differ in gap by at most 1 mm from the common normal's
// prediction, which the next step's manifold corrects.
constexpr double CAPSULE_PARALLEL_SIN = 1e-3;

using vec::V;
inline double len(V a) { return std::sqrt(dot(a, a)); }
inline V load(const double* p) { return {p[0], p[1], p[2]}; }
inline V col(M3 r, int j) { return {r(0, j), r(1, j), r(2, j)}; }
inline V to_local(M3 r, V d) {  // R^T d
    return {r(0, 0) * d.x + r(1, 0) * d.y + r(2, 0) * d.z, r(0, 1) * d.x + r(1, 1) * d.y + r(2, 1) * d.z,
            r(0, 2) * d.x + r(1, 2) * d.y + r(2, 2) * d.z};
}
inline V to_world(M3 r, V l) {  // R l
    return {r(0, 0) * l.x + r(0, 1) * l.y + r(0, 2) * l.z, r(1, 0) * l.x + r(1, 1) * l.y + r(1, 2) * l.z,
            r(2, 0) * l.x + r(2, 1) * l.y + r(2, 2) * l.z};
}
inline double comp(V a, int j) { return j == 0 ? a.x : (j == 1 ? a.y : a.z); }
inline void set_comp(V& a, int j, double v) { (j == 0 ? a.x : (j == 1 ? a.y : a.z)) = v; }


// Closest points c1 = p0 + s d1, c2 = q0 + t d2 of two segments (Ericson 5.1.9); returns (s, t).
void segment_segment(V p0, V d1, V q0, V d2, double& s, double& t) {
    V r = p0 - q0;
    double a = dot(d1, d1), e = dot(d2, d2), f = dot(d2, r);
    if (a <= 0 && e <= 0) {
        s = t = 0;
        return;
    }
    if (a <= 0) {
        s = 0;
        t = std::clamp(f / e, 0.0, 1.0);
        return;
    }
    double c = dot(d1, r);
    if (e <= 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
        return;
    }
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

// A unit vector normal to u (deterministic in u).
V any_normal(V u) {
    V c = std::fabs(u.x) < 0.9 ? cross(u, {1, 0, 0}) : cross(u, {0, 1, 0});
    return (1.0 / len(c)) * c;
}

// Squared distance of the point p (box frame) from the box |x_j| <= e_j.
inline double box_dist2(V p, const double* e) {
    double g = 0.0;
    for (int j = 0; j < 3; ++j) {
        double x = comp(p, j);
        double o = x - std::clamp(x, -e[j], e[j]);
        g += o * o;
    }
    return g;
}

// t in [0, 1] minimising the distance of p0 + t d from the box (box frame), exactly: the minimum
// over the pieces of the piecewise quadratic (module comment). Returns the squared distance.
double segment_box_closest(V p0, V d, const double* e, double& t_best) {
    double br[8];
    int nb = 0;
    br[nb++] = 0.0;
    br[nb++] = 1.0;
    for (int j = 0; j < 3; ++j) {
        double dj = comp(d, j);
        if (dj == 0.0) continue;
        for (int sgn = -1; sgn <= 1; sgn += 2) {
            double t = (sgn * e[j] - comp(p0, j)) / dj;
            if (t > 0.0 && t < 1.0) br[nb++] = t;
        }
    }
    std::sort(br, br + nb);
    t_best = 0.0;
    double g_best = box_dist2(p0, e);
    auto consider = [&](double t) {
        double g = box_dist2(p0 + t * d, e);
        if (g < g_best) {
            g_best = g;
            t_best = t;
        }
    };
    for (int k = 0; k + 1 < nb; ++k) {
        double ta = br[k], tb = br[k + 1];
        consider(tb);
        if (tb <= ta) continue;
        V pm = p0 + (0.5 * (ta + tb)) * d;
        double num = 0.0, den = 0.0;
        for (int j = 0; j < 3; ++j) {
            double x = comp(pm, j);
            if (x > e[j] || x < -e[j]) {
                double bnd = x > e[j] ? e[j] : -e[j];
                double dj = comp(d, j);
                num -= (comp(p0, j) - bnd) * dj;
                den += dj * dj;
            }
        }
        if (den > 0.0) consider(std::clamp(num / den, ta, tb));
    }
    return g_best;
}

}  // namespace

i64 collide_capsule_plane(const double* ca, M3 rota, const double* sa, const double* pn,
                          double poff, double spec, double* nrm, Pts pts, double* sep, i64* fid) {
    const double r = sa[0], h = sa[1];
    V c = load(ca), z = col(rota, 2), n = load(pn);
    i64 count = 0;
    for (int k = 0; k < 2; ++k) {
        V e = c + (k == 0 ? -h : h) * z;
        double s = dot(n, e) - poff - r;
        if (s > spec) continue;
        put(pts, sep, fid, count++, e - (r + 0.5 * s) * n, s, k);
    }
    put_normal(nrm, n);
    return count;
}

i64 collide_sphere_capsule(const double* ca, double ra, const double* cb, M3 rotb,
                           const double* sb, double spec, double* nrm, Pts pts, double* sep,
                           i64* fid) {
    V c = load(ca), x = load(cb), z = col(rotb, 2);
    double t = std::clamp(dot(c - x, z), -sb[1], sb[1]);
    V q = x + t * z;
    double qq[3] = {q.x, q.y, q.z};
    return collide_sphere_sphere(ca, ra, qq, sb[0], spec, nrm, pts, sep, fid);
}

i64 collide_capsule_capsule(const double* ca, M3 rota, const double* sa, const double* cb,
                            M3 rotb, const double* sb, double spec, double* nrm, Pts pts,
                            double* sep, i64* fid) {
    const double ra = sa[0], ha = sa[1], rb = sb[0], hb = sb[1];
    V xa = load(ca), za = col(rota, 2), xb = load(cb), zb = col(rotb, 2);
    V p0 = xa - ha * za, d1 = (2 * ha) * za, q0 = xb - hb * zb, d2 = (2 * hb) * zb;
    double s, t;
    segment_segment(p0, d1, q0, d2, s, t);
    V c1 = p0 + s * d1, c2 = q0 + t * d2;
    V dv = c1 - c2;
    double dist = len(dv);
    const double sep0 = dist - ra - rb;
    if (sep0 > spec) return 0;
    V n;
    if (dist > 1e-12 * (ra + rb)) {
        n = (1.0 / dist) * dv;
    } else {  // the axes cross: normal to both (or to a's, parallel)
        V cz = cross(za, zb);
        double lc = len(cz);
        n = lc > CAPSULE_PARALLEL_SIN ? (1.0 / lc) * cz : any_normal(za);
    }
    put_normal(nrm, n);
    // parallel axes with overlapping projections: two points at the overlap's ends on a's axis
    if (len(cross(za, zb)) <= CAPSULE_PARALLEL_SIN) {
        double u0 = dot(q0 - xa, za), u1 = dot(q0 + d2 - xa, za);
        double lo = std::max(-ha, std::min(u0, u1)), hi = std::min(ha, std::max(u0, u1));
        if (hi - lo > 1e-9 * (ha + hb + ra + rb)) {
            i64 count = 0;
            for (int k = 0; k < 2; ++k) {
                V pa = xa + (k == 0 ? lo : hi) * za;
                double tb = std::clamp(dot(pa - xb, zb), -hb, hb);
                V pb = xb + tb * zb;
                double sk = len(pa - pb) - ra - rb;  // >= sep0: the pair's true gap is the least
                if (sk > spec) continue;
                put(pts, sep, fid, count++, pb + (rb + 0.5 * sk) * n, sk, 1 + k);
            }
            // the closest pair inside the overlap (axes not exactly parallel): its point too,
            // so that the manifold's least gap is the pair's
            double least = count > 0 ? std::min(sep[0], sep[count - 1]) : INFINITY;
            if (count > 0 && least > sep0 + 1e-12 * (ra + rb + ha + hb))
                put(pts, sep, fid, count++, c2 + (rb + 0.5 * sep0) * n, sep0, 0);
            if (count > 0) return count;
        }
    }
    put(pts, sep, fid, 0, c2 + (rb + 0.5 * sep0) * n, sep0, 0);
    return 1;
}

i64 collide_capsule_box(const double* ca, M3 rota, const double* sa, const double* cb, M3 rotb,
                        const double* eb, double spec, double* nrm, Pts pts, double* sep,
                        i64* fid) {
    const CollisionConstants& cc = collision_constants();
    const double r = sa[0], h = sa[1];
    V xa = load(ca), za = col(rota, 2), xb = load(cb);
    // the segment in the box frame: p0 + t d, t in [0, 1]
    V p0 = to_local(rotb, xa - h * za - xb), d = to_local(rotb, (2 * h) * za);
    double t;
    double g = segment_box_closest(p0, d, eb, t);
    // within round-off of touching counts as meeting the box (a crossing's breakpoints round
    // to a hair outside): the separating-axis test then gives the gap, ~0, exactly
    const double scale = 2 * h + eb[0] + eb[1] + eb[2];
    if (g <= 1e-24 * scale * scale) g = 0.0;
    V nl;          // normal, box frame, from the box into the capsule
    double depth;  // signed gap of the segment (the capsule's core) along nl
    int face_axis = -1, edge_axis = -1;
    V p = p0 + t * d;
    if (g > 0.0) {
        V q{std::clamp(p.x, -eb[0], eb[0]), std::clamp(p.y, -eb[1], eb[1]),
            std::clamp(p.z, -eb[2], eb[2])};
        depth = std::sqrt(g);
        if (depth - r > spec) return 0;
        nl = (1.0 / depth) * (p - q);
        // a face normal exactly when the closest box point is inside that face
        for (int j = 0; j < 3; ++j)
            if (comp(nl, (j + 1) % 3) == 0.0 && comp(nl, (j + 2) % 3) == 0.0) face_axis = j;
    } else {
        // the segment meets the box: least overlap over the face normals and z x e_j
        V p1 = p0 + d;
        double best = -INFINITY;
        double best_face = -INFINITY;
        V n_face{0, 0, 0}, n_edge{0, 0, 0};
        int f_axis = -1, e_axis = -1;
        double dl = len(d);
        for (int k = 0; k < 6; ++k) {
            V u{0, 0, 0};
            if (k < 3) {
                set_comp(u, k, 1.0);
            } else {
                if (dl == 0.0) continue;
                V e{0, 0, 0};
                set_comp(e, k - 3, 1.0);
                u = cross(d, e);
                double lu = len(u);
                if (lu <= cc.edge_parallel_tol * dl) continue;
                u = (1.0 / lu) * u;
            }
            double box_half = std::fabs(u.x) * eb[0] + std::fabs(u.y) * eb[1] + std::fabs(u.z) * eb[2];
            double s0 = dot(u, p0), s1 = dot(u, p1);
            double smin = std::min(s0, s1), smax = std::max(s0, s1);
            // gap when the segment leaves along +u (smin - box_half) or along -u
            double gp = smin - box_half, gm = -box_half - smax;
            double gk = std::max(gp, gm);
            V uk = gp >= gm ? u : -1.0 * u;
            if (k < 3) {
                if (gk > best_face) {
                    best_face = gk;
                    n_face = uk;
                    f_axis = k;
                }
            } else if (gk > best) {
                best = gk;
                n_edge = uk;
                e_axis = k - 3;
            }
        }
        // prefer the face axis unless an edge axis is clearly better (box_box.cpp's rule)
        if (best > best_face + (1.0 - cc.edge_rel_tol) * std::fabs(best_face) + cc.axis_abs_tol) {
            nl = n_edge;
            depth = best;
            edge_axis = e_axis;
        } else {
            nl = n_face;
            depth = best_face;
            face_axis = f_axis;
        }
        if (depth - r > spec) return 0;
    }
    V n = to_world(rotb, nl);
    put_normal(nrm, n);
    i64 clipped = 0;  // points from the face's clip already written
    if (face_axis >= 0) {
        // clip the segment to the face's rectangle: |p_j| <= e_j for the two other axes
        const double sgn = comp(nl, face_axis) > 0 ? 1.0 : -1.0;
        double t0 = 0.0, t1 = 1.0;
        for (int j = 0; j < 3 && t0 <= t1; ++j) {
            if (j == face_axis) continue;
            double a = comp(p0, j), dj = comp(d, j);
            if (dj == 0.0) {
                if (a > eb[j] || a < -eb[j]) t1 = -1.0;
                continue;
            }
            double ta = (-eb[j] - a) / dj, tb = (eb[j] - a) / dj;
            if (ta > tb) std::swap(ta, tb);
            t0 = std::max(t0, ta);
            t1 = std::min(t1, tb);
        }
        if (t0 <= t1) {
            i64 count = 0;
            const i64 face = 2 * face_axis + (sgn > 0 ? 1 : 0);
            const int n_end = t1 - t0 > 1e-12 ? 2 : 1;
            for (int k = 0; k < n_end; ++k) {
                V pk = p0 + (k == 0 ? t0 : t1) * d;
                double sk = sgn * comp(pk, face_axis) - eb[face_axis] - r;
                if (sk > spec) continue;
                V fk = pk;
                set_comp(fk, face_axis, sgn * eb[face_axis]);
                V w = xb + to_world(rotb, fk) + (0.5 * sk) * n;
                put(pts, sep, fid, count++, w, sk, 8 + 2 * face + k);
            }
            // the segment's deepest point can lie off the face's rectangle (a capsule through a
            // corner): then the one-point contact below as well, so that the manifold's least
            // gap is the pair's
            double least = INFINITY;
            for (i64 k = 0; k < count; ++k) least = std::min(least, sep[k]);
            if (count > 0 && least <= depth - r + 1e-12 * (r + h + eb[0] + eb[1] + eb[2]))
                return count;
            face_axis = -1;
            clipped = count;
        }
    }
    // one point: the segment's point and the box's, midway between the surfaces
    V q;
    if (g > 0.0) {
        q = {std::clamp(p.x, -eb[0], eb[0]), std::clamp(p.y, -eb[1], eb[1]),
             std::clamp(p.z, -eb[2], eb[2])};
    } else if (edge_axis >= 0) {
        // the box's edge along e_k that supports it along nl, and the segment's closest point
        V e0{0, 0, 0}, ed{0, 0, 0};
        for (int j = 0; j < 3; ++j)
            set_comp(e0, j, j == edge_axis ? -eb[j] : (comp(nl, j) >= 0 ? eb[j] : -eb[j]));
        set_comp(ed, edge_axis, 2 * eb[edge_axis]);
        double s_, u_;
        segment_segment(p0, d, e0, ed, s_, u_);
        V c_seg = p0 + s_ * d;
        q = c_seg - depth * nl;
    } else {
        // a face axis whose rectangle the segment misses: the segment's deepest end, moved
        // onto the face's plane
        V p1 = p0 + d;
        V pd = dot(nl, p0) <= dot(nl, p1) ? p0 : p1;
        q = pd - depth * nl;
    }
    const double s0 = depth - r;
    V w = xb + to_world(rotb, q) + (0.5 * s0) * n;
    put(pts, sep, fid, clipped, w, s0, 0);
    return clipped + 1;
}

}  // namespace rb
