// The penetration analyzer's row passes (rblog/analyze/penetration.py, whose docstring states the
// analyzer's rules): the primary support of each body at each sample, the contact point's
// velocity relative to its partner, the slide of a contact over a sample interval from the
// poses, and the velocity kicks that mark an impact between samples.
//
// Slide over an interval (contact_slide), from the poses alone: each body's displacement over
// the interval is the rigid field d(p) = (x(k+1) - x(k)) + theta x (p - x) at the contact point,
// with p and x the midpoints of the contact point and of the centre, theta the rotation vector of
// R(k+1) R(k)^T; the slide is d_body(p) - d_partner(p) (static partners are still) minus its part
// along the normal. The field is the pose-derived velocity times the interval, so a body rolling
// on the contact point slides 0 (as a material point it would trace a cycloid, whose cubic term
// adds up over a roll), one pivoting on it slides by the third-order remainder
// (theta^3 |x - p| / 12 per interval), and a contact that slips slides by the slip.
// * An edge patch (span nonzero: the patch is point +- span) slides by the least slide of its
//   points: the field is affine along the segment, so that is the tangential part of
//   d(p) + s (theta_body - theta_partner) x span at the s in [-1, 1] that minimises it. A box
//   swinging about one end of its edge (pivoting there, its other end scraping) slides 0, like
//   one pivoting on a corner; a box sliding along does not.
// * A face patch (two boxes face to face, or a box face down on the ground) is judged at its
//   witness, the overlap's centroid, unless the pair turns over the interval about a point that
//   lies on both faces (within band): the slide field in the contact plane is then a turn about
//   c = p + (n x d) / theta_n (d the slide at the witness p, theta_n the relative turn about the
//   normal), zero at c, so the interval slides 0 (a box pivoting on one corner of its face
//   contact, the rest of the face scraping).
// * Both patch rules hold only where the pair's logged rows carry load at one point at most
//   (nload <= 1 at both samples; -1, no rows, counts as one; rows within WITNESS_BAND_M of each
//   other are one point, penetration._distinct_points): a patch whose other points are
//   loaded too holds them by static friction, so turning about one of them is creep.
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "audit/audit.hpp"

namespace rb {
namespace audit {

// The deepest contact of each body at each sample: kind[i, k] (0 ground, 1 pair row as a, 2 pair
// row as b; left as it is, -1, where none) and ref[i, k] (its pair row), among the ground (T, N)
// separations within cd and the pair rows (pk, pa, pb, ps) (pairs count for both bodies).
void deepest(V2<double> ground, double cd, V1<i64> pk, V1<i64> pa, V1<i64> pb, V1<double> ps,
             i64 n, V2<std::int8_t> kind, V2<i64> ref) {
    const i64 nb = kind.n0, t_n = kind.n1;
    std::vector<double> best(nb * t_n, std::numeric_limits<double>::infinity());
    auto B = [&](i64 i, i64 k) -> double& { return best[i * t_n + k]; };
    for (i64 k = 0; k < ground.n0; ++k) {
        for (i64 i = 0; i < ground.n1; ++i) {
            if (ground(k, i) <= cd) {
                B(i, k) = ground(k, i);
                kind(i, k) = 0;
            }
        }
    }
    for (i64 r = 0; r < pk.n0; ++r) {
        const i64 k = pk[r], a = pa[r], b = pb[r];
        const double sv = ps[r];
        if (sv < B(a, k)) {
            B(a, k) = sv;
            kind(a, k) = 1;
            ref(a, k) = r;
        }
        if (b < n && sv < B(b, k)) {
            B(b, k) = sv;
            kind(b, k) = 2;
            ref(b, k) = r;
        }
    }
}

// Per support row r (body pi_[r] at sample pk[r] on partner pb[r], contact point point[r], normal
// normal[r]): the contact point's velocity relative to the partner (a body partner's point
// velocity subtracted; static partners are still) cv = v + w x (p - x), its tangential part
// slip = cv - (cv.n) n, cspeed = |cv| and wspeed = |w - w_partner| (m/s, rad/s).
void contact_velocity(V1<i64> pk, V1<i64> pi_, V1<i64> pb, V2<double> point, V2<double> normal,
                      V3<double> position, V3<double> velocity, V3<double> omega, i64 n,
                      V2<double> cv, V2<double> slip, V1<double> cspeed, V1<double> wspeed) {
    for (i64 r = 0; r < pk.n0; ++r) {
        const i64 k = pk[r], i = pi_[r], b = pb[r];
        double w0 = omega(k, i, 0), w1 = omega(k, i, 1), w2 = omega(k, i, 2);
        double r0 = point(r, 0) - position(k, i, 0);
        double r1 = point(r, 1) - position(k, i, 1);
        double r2 = point(r, 2) - position(k, i, 2);
        double c0 = velocity(k, i, 0) + (w1 * r2 - w2 * r1);
        double c1 = velocity(k, i, 1) + (w2 * r0 - w0 * r2);
        double c2 = velocity(k, i, 2) + (w0 * r1 - w1 * r0);
        if (b >= 0 && b < n) {  // the partner body's point velocity at the same point
            double u0 = omega(k, b, 0), u1 = omega(k, b, 1), u2 = omega(k, b, 2);
            double q0 = point(r, 0) - position(k, b, 0);
            double q1 = point(r, 1) - position(k, b, 1);
            double q2 = point(r, 2) - position(k, b, 2);
            c0 -= velocity(k, b, 0) + (u1 * q2 - u2 * q1);
            c1 -= velocity(k, b, 1) + (u2 * q0 - u0 * q2);
            c2 -= velocity(k, b, 2) + (u0 * q1 - u1 * q0);
            w0 = w0 - u0;
            w1 = w1 - u1;
            w2 = w2 - u2;
        }
        const double n0 = normal(r, 0), n1 = normal(r, 1), n2 = normal(r, 2);
        // dot products summed as numpy's einsum sums a row of three: (p0 + p2) + p1
        const double vn = (c0 * n0 + c2 * n2) + c1 * n1;  // normal component
        cv(r, 0) = c0;
        cv(r, 1) = c1;
        cv(r, 2) = c2;
        slip(r, 0) = c0 - vn * n0;
        slip(r, 1) = c1 - vn * n1;
        slip(r, 2) = c2 - vn * n2;
        cspeed[r] = std::sqrt((c0 * c0 + c2 * c2) + c1 * c1);
        wspeed[r] = std::sqrt((w0 * w0 + w2 * w2) + w1 * w1);
    }
}

namespace {

// True when box (centre x, rotation rot body -> world row-major, half extents h) touches along
// (d0, d1, d2) with a face (two free axes, feature_signs) and the point c lies on that face
// within band (its body coordinates along the free axes within h + band).
bool on_face(const double* x, const double* rot, const double* h, double d0, double d1,
             double d2, double c0, double c1, double c2, double band) {
    double p0 = rot[0] * d0 + rot[3] * d1 + rot[6] * d2;
    double p1 = rot[1] * d0 + rot[4] * d1 + rot[7] * d2;
    double p2 = rot[2] * d0 + rot[5] * d1 + rot[8] * d2;
    FeatureSigns fs = feature_signs(p0, p1, p2, h[0], h[1], h[2], band);
    if (int(fs.f0) + int(fs.f1) + int(fs.f2) != 2) return false;
    for (int j = 0; j < 3; ++j) {
        if (!(j == 0 ? fs.f0 : (j == 1 ? fs.f1 : fs.f2))) continue;
        double loc = (rot[j] * (c0 - x[0]) + rot[3 + j] * (c1 - x[1]) + rot[6 + j] * (c2 - x[2]));
        if (std::fabs(loc) > h[j] + band) return false;
    }
    return true;
}

}  // namespace

// Per support row r whose next row r + 1 is the same body on the same partner at the next sample
// (nxt[r], which the caller sets only then): the tangential slide (m, world) at the contact point
// over that sample interval, from the poses alone (see the header). is_box/size: the bodies'
// shapes (is_box true only for a v2 box); s_* the static boxes (partner b = n + m, m < M; a
// partner b >= n + M is another world geom). A row whose body is not a box, or whose partner
// is neither a box body nor a static box, has no face patch to test; with span 0 (a geom pair's
// support, penetration.py rule "geom_pair_support") no edge patch either: its slide is the
// witness point's as it is.
void contact_slide(V1<i64> pk, V1<i64> pi_, V1<i64> pb, V2<double> point, V2<double> span,
                   V2<double> normal, V3<double> position, V4<double> rotation, i64 n,
                   V1<bool> nxt, V2<double> disp, V1<bool> is_box, V2<double> size,
                   V2<double> s_pos, V3<double> s_rot, V2<double> s_half, double band,
                   V1<i64> nload) {
    for (i64 r = 0; r < pk.n0; ++r) {
        disp(r, 0) = 0.0;
        disp(r, 1) = 0.0;
        disp(r, 2) = 0.0;
        if (!nxt[r]) continue;
        const i64 k = pk[r], i = pi_[r], b = pb[r];
        double d0 = 0.0, d1 = 0.0, d2 = 0.0;
        double q0 = 0.0, q1 = 0.0, q2 = 0.0;  // theta_body - theta_partner
        for (int side = 0; side < 2; ++side) {
            const i64 j = side == 0 ? i : b;
            if (side == 1 && (j < 0 || j >= n)) continue;
            const double sg = side == 0 ? 1.0 : -1.0;
            double t0, t1, t2;
            interval_rotvec(rotation, k + 1, k, j, t0, t1, t2);
            // lever arm from the centre to the contact point, both at the interval's midpoint
            // (the midpoint rule: exact for a body rolling at constant rates, third order for
            // one pivoting on the point)
            double y0 = 0.5 * (point(r, 0) + point(r + 1, 0) - position(k, j, 0) -
                               position(k + 1, j, 0));
            double y1 = 0.5 * (point(r, 1) + point(r + 1, 1) - position(k, j, 1) -
                               position(k + 1, j, 1));
            double y2 = 0.5 * (point(r, 2) + point(r + 1, 2) - position(k, j, 2) -
                               position(k + 1, j, 2));
            d0 += sg * (position(k + 1, j, 0) - position(k, j, 0) + t1 * y2 - t2 * y1);
            d1 += sg * (position(k + 1, j, 1) - position(k, j, 1) + t2 * y0 - t0 * y2);
            d2 += sg * (position(k + 1, j, 2) - position(k, j, 2) + t0 * y1 - t1 * y0);
            q0 += sg * t0;
            q1 += sg * t1;
            q2 += sg * t2;
        }
        const double m0 = normal(r, 0), m1 = normal(r, 1), m2 = normal(r, 2);
        const double dn = d0 * m0 + d1 * m1 + d2 * m2;
        d0 = d0 - dn * m0;
        d1 = d1 - dn * m1;
        d2 = d2 - dn * m2;
        // the edge patch's half-span at the interval's midpoint (ends aligned: the feature's
        // direction may flip sign between samples)
        double e0 = span(r + 1, 0), e1 = span(r + 1, 1), e2 = span(r + 1, 2);
        if (e0 * span(r, 0) + e1 * span(r, 1) + e2 * span(r, 2) < 0.0) {
            e0 = -e0;
            e1 = -e1;
            e2 = -e2;
        }
        e0 = 0.5 * (span(r, 0) + e0);
        e1 = 0.5 * (span(r, 1) + e1);
        e2 = 0.5 * (span(r, 2) + e2);
        if (nload[r] > 1 || nload[r + 1] > 1) e0 = e1 = e2 = 0.0;  // loaded over the patch
        const double qn = q0 * m0 + q1 * m1 + q2 * m2;
        // (slides under a nanometre keep the witness's value: nothing to gain from the test)
        if (e0 == 0.0 && e1 == 0.0 && e2 == 0.0 && is_box[i] && std::fabs(qn) > 0.0 &&
            nload[r] <= 1 && nload[r + 1] <= 1 && d0 * d0 + d1 * d1 + d2 * d2 > 1e-18) {
            // a face patch turning about c = p + (n x d) / theta_n: on both faces, no slide
            const double px = 0.5 * (point(r, 0) + point(r + 1, 0)) + (m1 * d2 - m2 * d1) / qn;
            const double py = 0.5 * (point(r, 1) + point(r + 1, 1)) + (m2 * d0 - m0 * d2) / qn;
            const double pz = 0.5 * (point(r, 2) + point(r + 1, 2)) + (m0 * d1 - m1 * d0) / qn;
            bool on = on_face(&position(k, i, 0), &rotation(k, i, 0, 0), &size(i, 0), -m0, -m1,
                              -m2, px, py, pz, band);
            if (on && b >= n) {
                const i64 mm = b - n;  // a world geom past the static boxes: no face known
                on = mm < s_pos.n0 && on_face(&s_pos(mm, 0), &s_rot(mm, 0, 0), &s_half(mm, 0), m0, m1, m2, px, py,
                             pz, band);
            } else if (on && b >= 0) {
                on = is_box[b] && on_face(&position(k, b, 0), &rotation(k, b, 0, 0), &size(b, 0),
                                          m0, m1, m2, px, py, pz, band);
            }
            if (on) d0 = d1 = d2 = 0.0;
        }
        if (e0 != 0.0 || e1 != 0.0 || e2 != 0.0) {
            // slide per unit s along the patch: (theta_body - theta_partner) x span, tangential
            double g0 = q1 * e2 - q2 * e1;
            double g1 = q2 * e0 - q0 * e2;
            double g2 = q0 * e1 - q1 * e0;
            const double gn = g0 * m0 + g1 * m1 + g2 * m2;
            g0 = g0 - gn * m0;
            g1 = g1 - gn * m1;
            g2 = g2 - gn * m2;
            const double gg = g0 * g0 + g1 * g1 + g2 * g2;
            if (gg > 0.0) {
                double sm = -(d0 * g0 + d1 * g1 + d2 * g2) / gg;
                sm = std::min(std::max(sm, -1.0), 1.0);
                d0 = d0 + sm * g0;
                d1 = d1 + sm * g1;
                d2 = d2 + sm * g2;
            }
        }
        disp(r, 0) = d0;
        disp(r, 1) = d1;
        disp(r, 2) = d2;
    }
}

// out (T-1, N): how much each sample interval changes a body's velocity, plus its angular
// velocity times reach (N,), beyond the mean change of the neighbouring intervals (m/s): 0 under
// any steady acceleration, the size of the kick where the body was struck between samples. (The
// first and last intervals compare with their one neighbour; a single interval with 0.)
void impact_jump(V3<double> velocity, V3<double> omega, V1<double> reach, V2<double> out) {
    const i64 m = velocity.n0 - 1;
    const i64 n = velocity.n1;
    for (i64 k = 0; k < m; ++k) {
        for (i64 i = 0; i < n; ++i) {
            double tot = 0.0;
            for (int which = 0; which < 2; ++which) {
                const V3<double>& a = which == 0 ? velocity : omega;
                double e2 = 0.0;
                for (int c = 0; c < 3; ++c) {
                    const double d = a(k + 1, i, c) - a(k, i, c);
                    double ref;
                    if (m == 1) ref = 0.0;
                    else if (k == 0) ref = a(2, i, c) - a(1, i, c);
                    else if (k == m - 1) ref = a(k, i, c) - a(k - 1, i, c);
                    else
                        ref = 0.5 * ((a(k, i, c) - a(k - 1, i, c)) +
                                     (a(k + 2, i, c) - a(k + 1, i, c)));
                    e2 += (d - ref) * (d - ref);
                }
                tot += std::sqrt(e2) * (which == 0 ? 1.0 : reach[i]);
            }
            out(k, i) = tot;
        }
    }
}

}  // namespace audit
}  // namespace rb
