// The audit's geometry: separations between the logged shapes, witness points, the broadphase.
// Recomputed from the logged poses and the model's shapes; nothing here reads the contacts a
// simulator reported (the analyzers judge those against these), nor the engine's narrowphase.
//
// Conventions (those of rblog.contract.trajectory.Contacts):
//
// * sep is the signed distance between two surfaces (m): > 0 apart, < 0 penetration depth.
// * normal is a unit world vector from body b into body a; point a world point midway between
//   the two surfaces along the normal: the witness of the contact, at the centre of the patch
//   where the bodies touch.
//
// Witness points (the contact point whose slip the penetration analyzer integrates as creep, the
// lever arm of a contact's velocity in the events analyzer):
//
// * A box's touching feature along a direction d is the set of its points within the band
//   (WITNESS_BAND_M, rblog/analyze/tolerances.py, passed in) of its extreme along d: axis j is
//   free (spanned by the feature) when 2 h_j |d.A_j| <= band, else fixed at sign(d.A_j) h_j. Zero
//   free axes is a corner, one an edge, two a face. (A box thinner than the band along every axis
//   keeps its axis most along d fixed.)
// * box-plane: the centre of the box's feature along -n, moved along n to the level of the box's
//   lowest point (by at most the band), so that n.point - offset is the separation.
// * box-box: the two features (a's along -n, b's along +n) projected onto the contact plane; the
//   centre of their intersection there, placed midway between the two surfaces along n. Corner vs
//   anything: the corner (two corners: their midpoint). Edge vs edge: the closest points of the
//   two segments (their crossing; parallel edges, |sin| x length <= band: the middle of their
//   overlap). Edge vs face: the middle of the part of the edge inside the face (nothing inside,
//   the two just apart: the midpoint of their closest points). Face vs face: the area centroid of
//   the overlap of the two face polygons (Sutherland-Hodgman; a zero-area overlap: its vertices'
//   mean; none: the midpoint of the faces' centres).
// * spheres: the point midway between the surfaces on the line of centres (sphere-sphere), the
//   point of the box's surface nearest the sphere (sphere-box).
// * Poses use the logged rotation (body->world, columns are the body axes in the world frame), as
//   the integrator held it; a drifted matrix maps the shape as drifted.
//
// Shape pairs (a first):
//
// * sphere-plane: n.x - offset - r;  box-plane: n.x - offset - sum_j h_j |n.A_j|.
// * sphere-sphere: |x_a - x_b| - r_a - r_b (exact).
// * sphere-box: the sphere centre in the box frame, clamped to the box: exact outside; inside,
//   the depth to the nearest face plus the radius (the minimum translation distance).
// * box-box: separating-axis test over the 15 axes (3 + 3 face normals, 9 edge cross products):
//   max_L (|L.(x_a - x_b)| - r_a(L) - r_b(L)). When the boxes overlap this is exactly minus the
//   penetration depth (the minimum translation distance of two convex polyhedra lies on one of
//   these axes); when apart it is a lower bound of the distance (exact for face-vertex and
//   edge-edge closest features), so a contact test with it errs towards "in contact". Edge cross
//   products shorter than axis_eps (rblog/analyze/geometry.py, passed in) are parallel edges
//   (their axis is skipped).
//
// Poses travel as pointers into the (T, N, 3) and (T, N, 3, 3) arrays: x is (x0, x1, x2), r the
// row-major 9 entries of the matrix (r[3 i + j] = R_ij), h the half extents (a sphere: h[0] is
// its radius). Static boxes and dynamic bodies share one index space in the pair tables: b < N is
// a body, b = N + m is static box m.
//
// Every function is the numba kernel of the same name (leading underscore dropped) that it
// replaced, in the same operation order.
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "audit/audit.hpp"

namespace rb {
namespace audit {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
}

// sep (T, N) = n.x - offset - support of the body along n; height (T, N) = n.x - offset.
void plane_kernel(V3<double> position, V4<double> rotation, V1<bool> is_sphere, V2<double> size,
                  V1<double> n, double offset, V2<double> sep, V2<double> height) {
    const i64 t_n = position.n0, nb = position.n1;
    for (i64 t = 0; t < t_n; ++t) {
        for (i64 b = 0; b < nb; ++b) {
            const double* x = &position(t, b, 0);
            double h = x[0] * n[0] + x[1] * n[1] + x[2] * n[2] - offset;
            double sup;
            if (is_sphere[b]) {
                sup = size(b, 0);
            } else {
                const double* r = &rotation(t, b, 0, 0);
                sup = 0.0;
                for (int j = 0; j < 3; ++j)
                    sup += size(b, j) * std::fabs(r[j] * n[0] + r[3 + j] * n[1] + r[6 + j] * n[2]);
            }
            height(t, b) = h;
            sep(t, b) = h - sup;
        }
    }
}

// out[r] = the ground contact point of body[r] at the pose position[k[r], j[r]],
// rotation[k[r], j[r]]: a sphere's lowest point; a box's touching feature along -n (axes with
// 2 h_c |n.A_c| <= band free, the others at their extreme), its centre moved along -n to the level
// of the box's lowest point (by sum over free axes of h_c |n.A_c|). spn[r] (when spn has rows):
// an edge's half-span h_c A_c (the patch is out[r] +- spn[r]), else left as it is (0).
void witness_kernel(V3<double> position, V4<double> rotation, V1<i64> k, V1<i64> j, V1<i64> body,
                    V1<bool> is_sphere, V2<double> size, V1<double> n, double band, V2<double> out,
                    V2<double> spn) {
    for (i64 r = 0; r < k.n0; ++r) {
        const i64 kr = k[r], jr = j[r], b = body[r];
        const double* x = &position(kr, jr, 0);
        if (is_sphere[b]) {
            for (int i = 0; i < 3; ++i) out(r, i) = x[i] - size(b, 0) * n[i];
            continue;
        }
        const double* rot = &rotation(kr, jr, 0, 0);  // rot[3 i + c] = R_ic
        double p0 = rot[0] * -n[0] + rot[3] * -n[1] + rot[6] * -n[2];  // -n . A_c
        double p1 = rot[1] * -n[0] + rot[4] * -n[1] + rot[7] * -n[2];
        double p2 = rot[2] * -n[0] + rot[5] * -n[1] + rot[8] * -n[2];
        FeatureSigns fs = feature_signs(p0, p1, p2, size(b, 0), size(b, 1), size(b, 2), band);
        for (int i = 0; i < 3; ++i)
            out(r, i) = x[i] + (rot[3 * i] * fs.s0 + rot[3 * i + 1] * fs.s1 +
                                rot[3 * i + 2] * fs.s2) - fs.drop * n[i];
        if (spn.n0 && int(fs.f0) + int(fs.f1) + int(fs.f2) == 1) {
            int c = fs.f0 ? 0 : (fs.f1 ? 1 : 2);
            for (int i = 0; i < 3; ++i) spn(r, i) = size(b, c) * rot[3 * i + c];
        }
    }
}

// --- narrowphase, one pair at a time ---------------------------------------------------------
namespace {

struct Sep7 {
    double sep, n0, n1, n2, p0, p1, p2;
};

// (sep, n from b into a, point midway between the surfaces).
Sep7 sphere_sphere(const double* xa, double ra, const double* xb, double rb) {
    double d0 = xa[0] - xb[0], d1 = xa[1] - xb[1], d2 = xa[2] - xb[2];
    double dist = std::sqrt(d0 * d0 + d1 * d1 + d2 * d2);
    double n0, n1, n2;
    if (dist > 0) {
        n0 = d0 / dist;
        n1 = d1 / dist;
        n2 = d2 / dist;
    } else {
        n0 = 0.0;
        n1 = 0.0;
        n2 = 1.0;
    }
    return {dist - ra - rb, n0, n1, n2, 0.5 * (xa[0] + xb[0] + n0 * (rb - ra)),
            0.5 * (xa[1] + xb[1] + n1 * (rb - ra)), 0.5 * (xa[2] + xb[2] + n2 * (rb - ra))};
}

// Sphere against box: (sep, n (from the box into the sphere), p on the box surface).
Sep7 sphere_box(const double* xs, double r, const double* xb, const double* rb, const double* hb) {
    double e0 = xs[0] - xb[0], e1 = xs[1] - xb[1], e2 = xs[2] - xb[2];
    // sphere centre in the box frame: R^T (xs - xb), and its clamp to the box
    double l0 = rb[0] * e0 + rb[3] * e1 + rb[6] * e2;
    double l1 = rb[1] * e0 + rb[4] * e1 + rb[7] * e2;
    double l2 = rb[2] * e0 + rb[5] * e1 + rb[8] * e2;
    double q0 = std::min(std::max(l0, -hb[0]), hb[0]);
    double q1 = std::min(std::max(l1, -hb[1]), hb[1]);
    double q2 = std::min(std::max(l2, -hb[2]), hb[2]);
    double f0 = l0 - q0, f1 = l1 - q1, f2 = l2 - q2;
    double dist = std::sqrt(f0 * f0 + f1 * f1 + f2 * f2);
    double m0, m1, m2, sep;
    if (dist > 0) {
        m0 = f0 / dist;
        m1 = f1 / dist;
        m2 = f2 / dist;
        sep = dist - r;
    } else {  // inside: out through the nearest face
        double g0 = hb[0] - std::fabs(l0), g1 = hb[1] - std::fabs(l1), g2 = hb[2] - std::fabs(l2);
        m0 = m1 = m2 = 0.0;
        if (g0 <= g1 && g0 <= g2) {
            m0 = l0 >= 0 ? 1.0 : -1.0;
            q0 = m0 * hb[0];
            sep = -g0 - r;
        } else if (g1 <= g2) {
            m1 = l1 >= 0 ? 1.0 : -1.0;
            q1 = m1 * hb[1];
            sep = -g1 - r;
        } else {
            m2 = l2 >= 0 ? 1.0 : -1.0;
            q2 = m2 * hb[2];
            sep = -g2 - r;
        }
    }
    double n0 = rb[0] * m0 + rb[1] * m1 + rb[2] * m2;
    double n1 = rb[3] * m0 + rb[4] * m1 + rb[5] * m2;
    double n2 = rb[6] * m0 + rb[7] * m1 + rb[8] * m2;
    double nn = std::sqrt(n0 * n0 + n1 * n1 + n2 * n2);
    return {sep,
            n0 / nn,
            n1 / nn,
            n2 / nn,
            xb[0] + rb[0] * q0 + rb[1] * q1 + rb[2] * q2,
            xb[1] + rb[3] * q0 + rb[4] * q1 + rb[5] * q2,
            xb[2] + rb[6] * q0 + rb[7] * q1 + rb[8] * q2};
}

struct Sep4 {
    double sep, n0, n1, n2;
};

// Separating-axis test over the 15 axes: (sep, n from b into a).
Sep4 box_box(const double* xa, const double* ra, const double* ha, const double* xb,
             const double* rb, const double* hb, double axis_eps) {
    double d0 = xa[0] - xb[0], d1 = xa[1] - xb[1], d2 = xa[2] - xb[2];
    double best_cmp = -kInf;
    double best = -kInf;
    double n0 = 0.0, n1 = 0.0, n2 = 0.0;
    for (int ax = 0; ax < 15; ++ax) {
        double l0, l1, l2;
        if (ax < 3) {
            l0 = ra[ax];
            l1 = ra[3 + ax];
            l2 = ra[6 + ax];
        } else if (ax < 6) {
            l0 = rb[ax - 3];
            l1 = rb[ax];
            l2 = rb[ax + 3];
        } else {
            int i = (ax - 6) / 3, j = (ax - 6) % 3;
            double a0 = ra[i], a1 = ra[3 + i], a2 = ra[6 + i];
            double b0 = rb[j], b1 = rb[3 + j], b2 = rb[6 + j];
            l0 = a1 * b2 - a2 * b1;
            l1 = a2 * b0 - a0 * b2;
            l2 = a0 * b1 - a1 * b0;
        }
        double norm = std::sqrt(l0 * l0 + l1 * l1 + l2 * l2);
        if (norm <= axis_eps) continue;
        l0 = l0 / norm;
        l1 = l1 / norm;
        l2 = l2 / norm;
        double rad = 0.0;
        for (int j = 0; j < 3; ++j) {
            rad += ha[j] * std::fabs(l0 * ra[j] + l1 * ra[3 + j] + l2 * ra[6 + j]);
            rad += hb[j] * std::fabs(l0 * rb[j] + l1 * rb[3 + j] + l2 * rb[6 + j]);
        }
        double dc = l0 * d0 + l1 * d1 + l2 * d2;
        double sv = std::fabs(dc) - rad;
        // prefer face axes on ties (parallel faces give equal edge axes)
        double cmp = ax >= 6 ? sv - 1e-12 * (1.0 + rad) : sv;
        if (cmp > best_cmp) {
            best_cmp = cmp;
            best = sv;
            double sg = dc >= 0 ? 1.0 : -1.0;
            n0 = sg * l0;
            n1 = sg * l1;
            n2 = sg * l2;
        }
    }
    return {best, n0, n1, n2};
}

// --- box-box witness: the centre of the touching patch, in the contact plane -----------------
// Features are projected onto the plane normal to n, in coordinates (u, v) about the midpoint o
// of the two centres: a feature is (cx, cy, free axes, e1, e2, support), its centre c and the
// projections e of h_j A_j of its free axes (none: a corner; one: an edge c +- e1; two: a face,
// the parallelogram c +- e1 +- e2).

// Unit u, v with (u, v, n) orthonormal.
void plane_basis(double n0, double n1, double n2, double* u, double* v) {
    double u0, u1, u2;
    if (std::fabs(n0) > 0.57735) {
        u0 = n1;
        u1 = -n0;
        u2 = 0.0;
    } else {
        u0 = 0.0;
        u1 = n2;
        u2 = -n1;
    }
    double un = std::sqrt(u0 * u0 + u1 * u1 + u2 * u2);
    u0 = u0 / un;
    u1 = u1 / un;
    u2 = u2 / un;
    u[0] = u0;
    u[1] = u1;
    u[2] = u2;
    v[0] = n1 * u2 - n2 * u1;
    v[1] = n2 * u0 - n0 * u2;
    v[2] = n0 * u1 - n1 * u0;
}

// (cx, cy, n_free, e1x, e1y, e2x, e2y, support of the box along d from its centre); f[] holds
// them as the Python tuple did, f[2] the number of free axes (0, 1, 2).
struct Feat {
    double f[8];
    int nf;
};

// The touching feature of box (x, r, h) along d in plane coordinates about o.
Feat feature_2d(const double* x, const double* r, const double* h, double d0, double d1,
                double d2, const double* o, const double* u, const double* v, double band) {
    double p0 = r[0] * d0 + r[3] * d1 + r[6] * d2;
    double p1 = r[1] * d0 + r[4] * d1 + r[7] * d2;
    double p2 = r[2] * d0 + r[5] * d1 + r[8] * d2;
    FeatureSigns fs = feature_signs(p0, p1, p2, h[0], h[1], h[2], band);
    double c0 = x[0] - o[0] + (r[0] * fs.s0 + r[1] * fs.s1 + r[2] * fs.s2);
    double c1 = x[1] - o[1] + (r[3] * fs.s0 + r[4] * fs.s1 + r[5] * fs.s2);
    double c2 = x[2] - o[2] + (r[6] * fs.s0 + r[7] * fs.s1 + r[8] * fs.s2);
    int nf = 0;
    double e1x = 0.0, e1y = 0.0, e2x = 0.0, e2y = 0.0;
    for (int j = 0; j < 3; ++j) {
        if (j == 0 ? fs.f0 : (j == 1 ? fs.f1 : fs.f2)) {
            double a0 = h[j] * r[j], a1 = h[j] * r[3 + j], a2 = h[j] * r[6 + j];
            double ex = a0 * u[0] + a1 * u[1] + a2 * u[2];
            double ey = a0 * v[0] + a1 * v[1] + a2 * v[2];
            if (nf == 0) {
                e1x = ex;
                e1y = ey;
            } else {
                e2x = ex;
                e2y = ey;
            }
            nf += 1;
        }
    }
    Feat o_;
    o_.f[0] = c0 * u[0] + c1 * u[1] + c2 * u[2];
    o_.f[1] = c0 * v[0] + c1 * v[1] + c2 * v[2];
    o_.f[2] = nf;
    o_.f[3] = e1x;
    o_.f[4] = e1y;
    o_.f[5] = e2x;
    o_.f[6] = e2y;
    o_.f[7] = h[0] * std::fabs(p0) + h[1] * std::fabs(p1) + h[2] * std::fabs(p2);
    o_.nf = nf;
    return o_;
}

// Closest points of segments p1 + s d1 and p2 + t d2 (s, t in [0, 1]; Ericson, Real-Time
// Collision Detection 5.1.9): (their midpoint x, y, squared distance).
void seg_closest(double p1x, double p1y, double d1x, double d1y, double p2x, double p2y,
                 double d2x, double d2y, double& mx, double& my, double& dd) {
    double rx = p1x - p2x, ry = p1y - p2y;
    double a = d1x * d1x + d1y * d1y;
    double e = d2x * d2x + d2y * d2y;
    double f = d2x * rx + d2y * ry;
    const double tiny = 1e-300;
    double s, t;
    if (a <= tiny && e <= tiny) {
        s = t = 0.0;
    } else if (a <= tiny) {
        s = 0.0;
        t = std::min(std::max(f / e, 0.0), 1.0);
    } else {
        double c = d1x * rx + d1y * ry;
        if (e <= tiny) {
            t = 0.0;
            s = std::min(std::max(-c / a, 0.0), 1.0);
        } else {
            double b = d1x * d2x + d1y * d2y;
            double den = a * e - b * b;
            s = den > 0 ? std::min(std::max((b * f - c * e) / den, 0.0), 1.0) : 0.0;
            t = (b * s + f) / e;
            if (t < 0.0) {
                t = 0.0;
                s = std::min(std::max(-c / a, 0.0), 1.0);
            } else if (t > 1.0) {
                t = 1.0;
                s = std::min(std::max((b - c) / a, 0.0), 1.0);
            }
        }
    }
    double q1x = p1x + s * d1x, q1y = p1y + s * d1y;
    double q2x = p2x + t * d2x, q2y = p2y + t * d2y;
    mx = 0.5 * (q1x + q2x);
    my = 0.5 * (q1y + q2y);
    dd = (q1x - q2x) * (q1x - q2x) + (q1y - q2y) * (q1y - q2y);
}

// Clip the parameter range [lo, hi] of t to |a0 + t ad| <= 1.
void slab(double a0, double ad, double& lo, double& hi) {
    if (ad == 0.0) {
        if (!(std::fabs(a0) <= 1.0)) {
            lo = 1.0;
            hi = -1.0;
        }
        return;
    }
    double t1 = (-1.0 - a0) / ad, t2 = (1.0 - a0) / ad;
    double nlo = std::max(lo, std::min(t1, t2));
    double nhi = std::min(hi, std::max(t1, t2));
    lo = nlo;
    hi = nhi;
}

// Corner k (0..3, cyclic: + +, - +, - -, + -) of the parallelogram f +- g1 +- g2.
inline void face_corner(double fx, double fy, double g1x, double g1y, double g2x, double g2y,
                        int k, double& x, double& y) {
    double s1 = (k == 0 || k == 3) ? 1.0 : -1.0;
    double s2 = k < 2 ? 1.0 : -1.0;
    x = fx + s1 * g1x + s2 * g2x;
    y = fy + s1 * g1y + s2 * g2y;
}

// Edge c +- e against the face parallelogram f +- g1 +- g2: (x, y, sx, sy), the middle of the
// part of the edge inside the face and half that part (the part is (x, y) +- (sx, sy)); none
// inside, the midpoint of the closest points of the edge and the face's boundary, and no span.
void edge_face(double cx, double cy, double ex, double ey, double fx, double fy, double g1x,
               double g1y, double g2x, double g2y, double& px, double& py, double& sx,
               double& sy) {
    double det = g1x * g2y - g1y * g2x;
    if (std::fabs(det) > 0.0) {
        // face coordinates (alpha, beta) of c + t e: the face is |alpha|, |beta| <= 1
        double qx = cx - fx, qy = cy - fy;
        double lo = -1.0, hi = 1.0;
        slab((qx * g2y - qy * g2x) / det, (ex * g2y - ey * g2x) / det, lo, hi);
        slab((g1x * qy - g1y * qx) / det, (g1x * ey - g1y * ex) / det, lo, hi);
        if (lo <= hi) {
            double tm = 0.5 * (lo + hi);
            double th = 0.5 * (hi - lo);
            px = cx + tm * ex;
            py = cy + tm * ey;
            sx = th * ex;
            sy = th * ey;
            return;
        }
    }
    double best = kInf;
    double bx = 0.0, by = 0.0;
    for (int k = 0; k < 4; ++k) {  // the face's four sides
        double ax, ay, qx, qy, mx, my, d2;
        face_corner(fx, fy, g1x, g1y, g2x, g2y, k, ax, ay);
        face_corner(fx, fy, g1x, g1y, g2x, g2y, (k + 1) % 4, qx, qy);
        seg_closest(cx - ex, cy - ey, 2 * ex, 2 * ey, ax, ay, qx - ax, qy - ay, mx, my, d2);
        if (d2 < best) {
            best = d2;
            bx = mx;
            by = my;
        }
    }
    px = bx;
    py = by;
    sx = 0.0;
    sy = 0.0;
}

// Area centroid of the overlap of face parallelograms fa, fb (features of feature_2d): a's
// polygon clipped by each edge of b's (Sutherland-Hodgman; buf (4, W) holds the polygons). A
// zero-area overlap: its vertices' mean; no overlap: the midpoint of the two centres.
constexpr int kBufW = 32;

void face_face(const double* fa, const double* fb, double (*buf)[kBufW], double& px, double& py) {
    const int w = kBufW;
    for (int k = 0; k < 4; ++k) face_corner(fa[0], fa[1], fa[3], fa[4], fa[5], fa[6], k, buf[0][k], buf[1][k]);
    int m = 4;
    int src = 0;
    double det_b = fb[3] * fb[6] - fb[4] * fb[5];
    double orient = det_b >= 0 ? 1.0 : -1.0;  // b's corners run counter-clockwise when det_b > 0
    for (int e = 0; e < 4; ++e) {
        double qpx, qpy, qx, qy;
        face_corner(fb[0], fb[1], fb[3], fb[4], fb[5], fb[6], e, qpx, qpy);
        face_corner(fb[0], fb[1], fb[3], fb[4], fb[5], fb[6], (e + 1) % 4, qx, qy);
        double ex = qx - qpx, ey = qy - qpy;
        int dst = 2 - src;
        int cnt = 0;
        for (int i = 0; i < m; ++i) {
            double ax = buf[src][i], ay = buf[src + 1][i];
            int j = i + 1 < m ? i + 1 : 0;
            double bx = buf[src][j], by = buf[src + 1][j];
            double da = orient * (ex * (ay - qpy) - ey * (ax - qpx));  // >= 0: inside b's edge e
            double db = orient * (ex * (by - qpy) - ey * (bx - qpx));
            if (da >= 0 && cnt < w) {
                buf[dst][cnt] = ax;
                buf[dst + 1][cnt] = ay;
                cnt += 1;
            }
            if (((da >= 0) != (db >= 0)) && cnt < w) {
                double t = da / (da - db);
                buf[dst][cnt] = ax + t * (bx - ax);
                buf[dst + 1][cnt] = ay + t * (by - ay);
                cnt += 1;
            }
        }
        m = cnt;
        src = dst;
        if (m == 0) {
            px = 0.5 * (fa[0] + fb[0]);
            py = 0.5 * (fa[1] + fb[1]);
            return;
        }
    }
    // area centroid by a fan of triangles from vertex 0
    double x0 = buf[src][0], y0 = buf[src + 1][0];
    double a2 = 0.0, sx = 0.0, sy = 0.0;
    double mx = x0, my = y0;
    for (int i = 1; i < m; ++i) {
        double xi = buf[src][i], yi = buf[src + 1][i];
        mx += xi;
        my += yi;
        if (i + 1 < m) {
            double xj = buf[src][i + 1], yj = buf[src + 1][i + 1];
            double cr = (xi - x0) * (yj - y0) - (xj - x0) * (yi - y0);
            a2 += cr;
            sx += cr * (xi + xj - 2 * x0);
            sy += cr * (yi + yj - 2 * y0);
        }
    }
    double det_a = fa[3] * fa[6] - fa[4] * fa[5];
    if (std::fabs(a2) > 1e-9 * std::min(std::fabs(det_a), std::fabs(det_b))) {
        px = x0 + sx / (3 * a2);
        py = y0 + sy / (3 * a2);
        return;
    }
    px = mx / m;
    py = my / m;
}

// Witness of boxes a, b touching along n (from b into a): the centre of the intersection of a's
// feature along -n and b's along +n in the contact plane, midway between the surfaces, and the
// patch's half-span (3,): half the part of an edge that lies on a face (the patch is the segment
// point +- span), else 0 (a point, or a face overlap judged at its centroid). out: p0..p2, e0..e2.
void box_box_point(const double* xa, const double* ra, const double* ha, const double* xb,
                   const double* rb, const double* hb, double n0, double n1, double n2,
                   double (*buf)[kBufW], double band, double* out) {
    const double o[3] = {0.5 * (xa[0] + xb[0]), 0.5 * (xa[1] + xb[1]), 0.5 * (xa[2] + xb[2])};
    double u[3], v[3];
    plane_basis(n0, n1, n2, u, v);
    Feat fa = feature_2d(xa, ra, ha, -n0, -n1, -n2, o, u, v, band);
    Feat fb = feature_2d(xb, rb, hb, n0, n1, n2, o, u, v, band);
    const double* a = fa.f;
    const double* b = fb.f;
    const int na = fa.nf, nb = fb.nf;
    double sx = 0.0, sy = 0.0, px, py;
    if (na == 0 && nb == 0) {  // corner on corner
        px = 0.5 * (a[0] + b[0]);
        py = 0.5 * (a[1] + b[1]);
    } else if (na == 0) {  // a's corner
        px = a[0];
        py = a[1];
    } else if (nb == 0) {
        px = b[0];
        py = b[1];
    } else if (na == 1 && nb == 1) {
        auto pp = edge_edge(a[0], a[1], a[3], a[4], b[0], b[1], b[3], b[4], band);
        px = std::get<0>(pp);
        py = std::get<1>(pp);
    } else if (na == 1) {
        edge_face(a[0], a[1], a[3], a[4], b[0], b[1], b[3], b[4], b[5], b[6], px, py, sx, sy);
    } else if (nb == 1) {
        edge_face(b[0], b[1], b[3], b[4], a[0], a[1], a[3], a[4], a[5], a[6], px, py, sx, sy);
    } else {
        face_face(a, b, buf, px, py);
    }
    // along n: midway between a's extreme along -n and b's along +n
    double z = 0.5 * (b[7] - a[7]);
    out[0] = o[0] + px * u[0] + py * v[0] + z * n0;
    out[1] = o[1] + px * u[1] + py * v[1] + z * n1;
    out[2] = o[2] + px * u[2] + py * v[2] + z * n2;
    out[3] = sx * u[0] + sy * v[0];
    out[4] = sx * u[1] + sy * v[1];
    out[5] = sx * u[2] + sy * v[2];
}

PairOut pair_buf(i64 sa, const double* xa, const double* ra, const double* ha, i64 sb,
                 const double* xb, const double* rb, const double* hb, bool with_point,
                 double (*buf)[kBufW], double band, double axis_eps) {
    if (sa == SHAPE_SPHERE && sb == SHAPE_SPHERE) {
        Sep7 s = sphere_sphere(xa, ha[0], xb, hb[0]);
        return {s.sep, s.n0, s.n1, s.n2, s.p0, s.p1, s.p2, 0.0, 0.0, 0.0};
    }
    if (sa == SHAPE_SPHERE) {
        Sep7 s = sphere_box(xa, ha[0], xb, rb, hb);
        return {s.sep, s.n0, s.n1, s.n2, s.p0, s.p1, s.p2, 0.0, 0.0, 0.0};
    }
    if (sb == SHAPE_SPHERE) {  // box a, sphere b: the sphere-box normal points into b; flip it
        Sep7 s = sphere_box(xb, hb[0], xa, ra, ha);
        return {s.sep, -s.n0, -s.n1, -s.n2, s.p0, s.p1, s.p2, 0.0, 0.0, 0.0};
    }
    Sep4 s = box_box(xa, ra, ha, xb, rb, hb, axis_eps);
    PairOut o{s.sep, s.n0, s.n1, s.n2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    if (with_point) {
        double w[6];
        box_box_point(xa, ra, ha, xb, rb, hb, s.n0, s.n1, s.n2, buf, band, w);
        o.p0 = w[0];
        o.p1 = w[1];
        o.p2 = w[2];
        o.e0 = w[3];
        o.e1 = w[4];
        o.e2 = w[5];
    }
    return o;
}

}  // namespace

// Edges a +- ea, b +- eb in the contact plane: parallel (the tilt between them moves an end by
// at most the band) -> the middle of their overlap along a, halfway to b's line; else the
// closest points.
std::tuple<double, double> edge_edge(double ax, double ay, double eax, double eay, double bx,
                                     double by, double ebx, double eby, double band) {
    double la = std::sqrt(eax * eax + eay * eay);
    double lb = std::sqrt(ebx * ebx + eby * eby);
    double cr = eax * eby - eay * ebx;
    if (la > 0 && lb > 0 && std::fabs(cr) / (la * lb) * 2.0 * std::max(la, lb) <= band) {
        double dx = eax / la, dy = eay / la;
        double wx = bx - ax, wy = by - ay;
        double tc = wx * dx + wy * dy;
        double hl = std::fabs(ebx * dx + eby * dy);
        // in the gap when they do not overlap
        double tm = 0.5 * (std::max(-la, tc - hl) + std::min(la, tc + hl));
        return {ax + tm * dx + 0.5 * (wx - tc * dx), ay + tm * dy + 0.5 * (wy - tc * dy)};
    }
    double mx, my, dd;
    seg_closest(ax - eax, ay - eay, 2 * eax, 2 * eay, bx - ebx, by - eby, 2 * ebx, 2 * eby, mx, my,
                dd);
    return {mx, my};
}

// Dispatch on the shape pair: (sep, n from b into a, point, span), span the half-span of an edge
// patch (see box_box_point; 0 for spheres); the box-box point and span only when with_point
// (else 0).
PairOut pair(i64 sa, const double* xa, const double* ra, const double* ha, i64 sb,
             const double* xb, const double* rb, const double* hb, bool with_point, double band,
             double axis_eps) {
    double buf[4][kBufW];
    return pair_buf(sa, xa, ra, ha, sb, xb, rb, hb, with_point, buf, band, axis_eps);
}

// Geometry of rows (ks, a, b): b < N a body at sample ks, else static box b - N. position
// (T, E, 3), rotation (T, E, 3, 3) and size (E, 3) cover bodies only; s_* the static boxes as
// (1, M, 3), (1, M, 3, 3), (M, 3). nrm, pt (R, 3) written when with_points; spn (R, 3) when it
// has rows.
void pairs_kernel(V1<i64> ks, V1<i64> a, V1<i64> b, V3<double> position, V4<double> rotation,
                  V1<i64> shape, V2<double> size, V3<double> s_pos, V4<double> s_rot,
                  V2<double> s_half, V1<double> sep, V2<double> nrm, V2<double> pt,
                  V2<double> spn, bool with_points, double band, double axis_eps) {
    const i64 nb = position.n1;
    double buf[4][kBufW];  // polygons of the face-face witness
    for (i64 r = 0; r < ks.n0; ++r) {
        const i64 k = ks[r], ia = a[r], ib = b[r];
        const double* xa = &position(k, ia, 0);
        const double* ra = &rotation(k, ia, 0, 0);
        const double* ha = &size(ia, 0);
        const double *xb, *rb, *hb;
        i64 sb;
        if (ib < nb) {
            xb = &position(k, ib, 0);
            rb = &rotation(k, ib, 0, 0);
            hb = &size(ib, 0);
            sb = shape[ib];
        } else {
            const i64 m = ib - nb;
            xb = &s_pos(0, m, 0);
            rb = &s_rot(0, m, 0, 0);
            hb = &s_half(m, 0);
            sb = SHAPE_BOX;
        }
        PairOut out = pair_buf(shape[ia], xa, ra, ha, sb, xb, rb, hb, with_points, buf, band,
                               axis_eps);
        sep[r] = out.sep;
        if (with_points) {
            nrm(r, 0) = out.n0;
            nrm(r, 1) = out.n1;
            nrm(r, 2) = out.n2;
            pt(r, 0) = out.p0;
            pt(r, 1) = out.p1;
            pt(r, 2) = out.p2;
            if (spn.n0) {
                spn(r, 0) = out.e0;
                spn(r, 1) = out.e1;
                spn(r, 2) = out.e2;
            }
        }
    }
}

// --- broadphase ------------------------------------------------------------------------------
namespace {

// Sort the index array `order` (n) by key[order[.] * stride] in place (Shell sort, Ciura's gaps).
void shell_sort(i64* order, i64 n, const double* key, i64 stride) {
    static const i64 gaps[] = {701, 301, 132, 57, 23, 10, 4, 1};
    for (i64 gap : gaps) {
        for (i64 i = gap; i < n; ++i) {
            i64 cur = order[i];
            double kv = key[cur * stride];
            i64 j = i;
            while (j >= gap && key[order[j - gap] * stride] > kv) {
                order[j] = order[j - gap];
                j -= gap;
            }
            order[j] = cur;
        }
    }
}

}  // namespace

// Sort-and-sweep over every interval [k, k+1]: the AABB of a body is its centre's box over the
// two samples grown by grow[k, i]; static boxes have fixed AABBs (s_lo, s_hi (M, 3)). Pairs
// overlapping on all three axes (not static-static, not in different non-zero groups) whose
// bounding spheres also meet (for two bodies: spheres about the middle of each centre's chord,
// radius half the chord plus grow) are written to out_* while they fit; returns how many there
// are (call again with room for them when more).
//
// The order of the previous interval seeds an insertion sort, so a scene that moves little
// between samples sorts in linear time.
i64 sweep_kernel(V3<double> position, V2<double> grow, V2<double> s_lo, V2<double> s_hi,
                 V1<i64> group, i64 axis, V1<i64> out_k, V1<i64> out_a, V1<i64> out_b) {
    const i64 t_n = position.n0, n = position.n1;
    const i64 m = s_lo.n0;
    const i64 e = n + m;
    i64 k_n = t_n > 1 ? t_n - 1 : 1;
    if (t_n == 0) k_n = 0;  // no poses: nothing to sweep (numba would have read past the array)
    std::vector<double> lo(e * 3), hi(e * 3), mid(n * 3), reach(n);
    for (i64 j = 0; j < m; ++j) {
        for (int d = 0; d < 3; ++d) {
            lo[(n + j) * 3 + d] = s_lo(j, d);
            hi[(n + j) * 3 + d] = s_hi(j, d);
        }
    }
    std::vector<i64> order(e);
    for (i64 i = 0; i < e; ++i) order[i] = i;
    const i64 cap = out_k.n0;
    i64 cnt = 0;
    for (i64 k = 0; k < k_n; ++k) {
        const i64 k1 = t_n > 1 ? k + 1 : k;
        for (i64 i = 0; i < n; ++i) {
            const double g = grow(k, i);
            double half2 = 0.0;
            for (int d = 0; d < 3; ++d) {
                double a = position(k, i, d);
                double b = position(k1, i, d);
                lo[i * 3 + d] = std::min(a, b) - g;
                hi[i * 3 + d] = std::max(a, b) + g;
                mid[i * 3 + d] = 0.5 * (a + b);
                half2 += 0.25 * (b - a) * (b - a);
            }
            reach[i] = g + std::sqrt(half2);  // a sphere about the chord's middle holds the path
        }
        // insertion sort of the previous order on lo[:, axis]; a full sort when that would take
        // more than a few moves per entity (the first interval, bodies that jump around)
        i64 moves = 0;
        for (i64 p = 1; p < e; ++p) {
            i64 cur = order[p];
            double key = lo[cur * 3 + axis];
            i64 q = p - 1;
            while (q >= 0 && lo[order[q] * 3 + axis] > key) {
                order[q + 1] = order[q];
                q -= 1;
            }
            order[q + 1] = cur;
            moves += p - 1 - q;
            if (moves > 8 * e + 64) {
                shell_sort(order.data(), e, lo.data() + axis, 3);
                break;
            }
        }
        for (i64 p = 0; p < e; ++p) {
            const i64 i = order[p];
            const double* lo_i = &lo[i * 3];
            const double* hi_i = &hi[i * 3];
            for (i64 q = p + 1; q < e; ++q) {
                const i64 j = order[q];
                const double* lo_j = &lo[j * 3];
                const double* hi_j = &hi[j * 3];
                if (lo_j[axis] > hi_i[axis]) break;
                if (i >= n && j >= n) continue;
                bool ok = true;
                for (int d = 0; d < 3; ++d) {
                    if (lo_j[d] > hi_i[d] || lo_i[d] > hi_j[d]) {
                        ok = false;
                        break;
                    }
                }
                if (!ok) continue;
                const i64 a = std::min(i, j);
                const i64 b = std::max(i, j);
                if (b < n) {
                    if (group[a] != 0 && group[b] != 0 && group[a] != group[b]) continue;
                    double dd = 0.0;
                    for (int d = 0; d < 3; ++d) {
                        double t = mid[a * 3 + d] - mid[b * 3 + d];
                        dd += t * t;
                    }
                    double rr = reach[a] + reach[b];
                    if (dd > rr * rr) continue;
                }
                if (cnt < cap) {
                    out_k[cnt] = k;
                    out_a[cnt] = a;
                    out_b[cnt] = b;
                }
                cnt += 1;
            }
        }
    }
    return cnt;
}

// out (3,) = max - min of the rows of x (P, 3), P >= 1 (np.ptp(x, axis=0) in one pass; NaN in a
// column makes its spread NaN, as there).
void spread(V2<double> x, double* out) {
    double lo[3] = {x(0, 0), x(0, 1), x(0, 2)};
    double hi[3] = {x(0, 0), x(0, 1), x(0, 2)};
    for (i64 p = 1; p < x.n0; ++p) {
        for (int d = 0; d < 3; ++d) {
            double v = x(p, d);
            if (v < lo[d]) lo[d] = v;
            if (v > hi[d]) hi[d] = v;
            if (v != v) {
                lo[d] = v;
                hi[d] = v;
            }
        }
    }
    for (int d = 0; d < 3; ++d) out[d] = hi[d] - lo[d];
    for (int d = 0; d < 3; ++d) {
        for (i64 p = 0; p < x.n0; ++p) {
            if (x(p, d) != x(p, d)) {
                out[d] = std::nan("");
                break;
            }
        }
    }
}

}  // namespace audit
}  // namespace rb
