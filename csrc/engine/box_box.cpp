// Box-box contact (rblog/engine/contact/box_box.py, the same formulas in the same order).
//
// Follows the separating-axis test of Gottschalk et al. (15 axes: three face normals of each box,
// nine cross products of their edge directions) with the face/edge preference tolerances of
// Gregorius (GDC 2013, 2015): a face axis is kept unless an edge axis is clearly better,
//
//   edge wins   when  sep_e > face_sep + (1 - EDGE_REL_TOL) |face_sep| + AXIS_ABS_TOL
//   b's face    when  sep_b > sep_a    + (1 - FACE_REL_TOL) |sep_a|    + AXIS_ABS_TOL
//
// (relative margins on |separation| favour faces for gaps and overlaps alike), so manifolds stay
// coherent from step to step. Edge axes shorter than EDGE_PARALLEL_TOL (near-parallel edges) are
// skipped. All tolerances: rblog/engine/constants.py, via collision_constants().
//
// A face contact takes the reference face (the winning face axis, on box r, its normal n_ref
// pointing from r towards the incident box i) and the incident face (the face of i most
// anti-parallel to n_ref), expresses the incident face's four corners in the reference face's
// frame (x along t1, y along t2, z along n_ref), clips that polygon against the reference
// face's four side planes (Sutherland-Hodgman), keeps the vertices with z <= spec, each moved
// half its gap back towards the reference face (the midpoint between the surfaces), and reduces
// them to four points (manifold.cpp). Manifold normal (from b into a): -n_ref when r is a, n_ref
// when r is b.
//
// Feature ids: a face point gets ((face_code 3 + incident axis) 2 + incident side) 128 + clip id,
// the clip id 16 (plane + 1) + start vertex of the clipped edge (or the corner 0..3); an edge
// point 100000 + ((i 3 + j) 8 + code_a) 8 + code_b (the edges' axes and which side of each box).
//
// An edge contact is one point midway between the closest points of the two supporting edges
// (clamped to the edges), normal along a_i x b_j. When a face is also within reach of the step
// (face_sep <= spec and face_sep >= sep_e - spec) its face manifold goes in rows 4.. as the
// pair's second manifold (normal nrm[3:6]): a tumbling box would swing that face's corners in.
#include <algorithm>
#include <cmath>

#include "engine/collision.hpp"

namespace rb {

using Poly4 = double (*)[4];

// Sutherland-Hodgman: keep the part of polygon src (rows x, y, z, id) with
// sign * src[:, axis] <= limit. Returns the number of vertices written to dst.
static i64 clip_polygon(Poly4 src, i64 n_src, Poly4 dst, int axis, double sign, double limit,
                        int plane_id) {
    i64 n_dst = 0;
    if (n_src == 0) return 0;
    for (i64 i = 0; i < n_src; ++i) {
        i64 j = (i + 1) % n_src;
        double di = sign * src[i][axis] - limit;
        double dj = sign * src[j][axis] - limit;
        if (di <= 0.0) {
            for (int k = 0; k < 4; ++k) dst[n_dst][k] = src[i][k];
            n_dst += 1;
        }
        if ((di <= 0.0) != (dj <= 0.0)) {
            double t = di / (di - dj);
            for (int k = 0; k < 3; ++k) dst[n_dst][k] = src[i][k] + t * (src[j][k] - src[i][k]);
            // id: which edge (by its start vertex's id) crossed which clip plane
            // (ids are integers 0..79 held in doubles: fmod(id, 16) is exactly id & 15)
            dst[n_dst][3] = 16.0 * (plane_id + 1) + (double)((i64)src[i][3] & 15);
            n_dst += 1;
        }
    }
    return n_dst;
}

// Clip the incident face of box i against reference face `axis` of box r. The reference normal
// n_ref = nsign * (axis column of rotr) points from r towards i. The manifold normal (from b
// into a) is -n_ref when r is a (flip false), n_ref when r is b.
static i64 face_contact(const double* cr, M3 rotr, const double* er, const double* ci, M3 roti,
                        const double* ei, int axis, double nsign, double spec, bool flip,
                        i64 face_code, double* nrm, Pts pts, double* sep, i64* fid, Poly poly) {
    double rx = nsign * rotr(0, axis), ry = nsign * rotr(1, axis), rz = nsign * rotr(2, axis);
    // incident face: the face of i whose normal is most anti-parallel to n_ref
    int best = 0;
    double bd = -1.0;
    for (int j = 0; j < 3; ++j) {
        double d = std::fabs(rx * roti(0, j) + ry * roti(1, j) + rz * roti(2, j));
        if (d > bd) {
            bd = d;
            best = j;
        }
    }
    double dj = rx * roti(0, best) + ry * roti(1, best) + rz * roti(2, best);
    double msign = dj > 0.0 ? -1.0 : 1.0;
    int u = (best + 1) % 3;
    int v = (best + 2) % 3;
    double icx = ci[0] + msign * ei[best] * roti(0, best);
    double icy = ci[1] + msign * ei[best] * roti(1, best);
    double icz = ci[2] + msign * ei[best] * roti(2, best);
    // reference face frame: tangents t1, t2 and its centre
    int k1 = (axis + 1) % 3;
    int k2 = (axis + 2) % 3;
    double fcx = cr[0] + er[axis] * rx;
    double fcy = cr[1] + er[axis] * ry;
    double fcz = cr[2] + er[axis] * rz;
    double t1x = rotr(0, k1), t1y = rotr(1, k1), t1z = rotr(2, k1);
    double t2x = rotr(0, k2), t2y = rotr(1, k2), t2z = rotr(2, k2);
    // incident polygon in reference coordinates (x along t1, y along t2, z along n_ref)
    Poly4 src = poly[0];
    // (in locals: the stores into poly could alias them for all the compiler knows)
    const double eu = ei[u], ev = ei[v];
    const double ru0 = roti(0, u), ru1 = roti(1, u), ru2 = roti(2, u);
    const double rv0 = roti(0, v), rv1 = roti(1, v), rv2 = roti(2, v);
    for (int k = 0; k < 4; ++k) {
        double su = (k == 0 || k == 3) ? 1.0 : -1.0;
        double sv = k < 2 ? 1.0 : -1.0;
        double px = icx + su * eu * ru0 + sv * ev * rv0 - fcx;
        double py = icy + su * eu * ru1 + sv * ev * rv1 - fcy;
        double pz = icz + su * eu * ru2 + sv * ev * rv2 - fcz;
        src[k][0] = px * t1x + py * t1y + pz * t1z;
        src[k][1] = px * t2x + py * t2y + pz * t2z;
        src[k][2] = px * rx + py * ry + pz * rz;
        src[k][3] = k;
    }
    i64 n = 4;
    n = clip_polygon(poly[0], n, poly[1], 0, 1.0, er[k1], 0);
    n = clip_polygon(poly[1], n, poly[0], 0, -1.0, er[k1], 1);
    n = clip_polygon(poly[0], n, poly[1], 1, 1.0, er[k2], 2);
    n = clip_polygon(poly[1], n, poly[0], 1, -1.0, er[k2], 3);
    Poly4 out = poly[0];
    i64 count = 0;
    for (i64 k = 0; k < n; ++k) {
        double z = out[k][2];
        if (z > spec) continue;
        double x = out[k][0], y = out[k][1];
        // incident point, moved half the gap back towards the reference face
        double zh = 0.5 * z;
        pts[count][0] = fcx + x * t1x + y * t2x + zh * rx;
        pts[count][1] = fcy + x * t1y + y * t2y + zh * ry;
        pts[count][2] = fcz + x * t1z + y * t2z + zh * rz;
        sep[count] = z;
        fid[count] = ((face_code * 3 + best) * 2 + (msign > 0.0 ? 1 : 0)) * 128 + (i64)out[k][3];
        count += 1;
    }
    if (flip) {
        nrm[0] = rx;
        nrm[1] = ry;
        nrm[2] = rz;
    } else {
        nrm[0] = -rx;
        nrm[1] = -ry;
        nrm[2] = -rz;
    }
    return reduce_manifold(nrm, pts, sep, fid, count);
}

static i64 best_face_contact(const double* ca, M3 rota, const double* ea, const double* cb,
                             M3 rotb, const double* eb, double sep_a, int ax_a, double sep_b,
                             int ax_b, const double* work, double dx, double dy, double dz,
                             double spec, double* nrm, Pts pts, double* sep, i64* fid,
                             Poly poly) {
    const CollisionConstants& cc = collision_constants();
    if (sep_b > sep_a + (1.0 - cc.face_rel_tol) * std::fabs(sep_a) + cc.axis_abs_tol) {
        double dbj = rotb(0, ax_b) * dx + rotb(1, ax_b) * dy + rotb(2, ax_b) * dz;
        // reference face on b; its normal points from b towards a
        double nsign = dbj > 0.0 ? -1.0 : 1.0;
        return face_contact(cb, rotb, eb, ca, rota, ea, ax_b, nsign, spec, true, 3 + ax_b, nrm,
                            pts, sep, fid, poly);
    }
    double nsign = work[18 + ax_a] > 0.0 ? 1.0 : -1.0;
    return face_contact(ca, rota, ea, cb, rotb, eb, ax_a, nsign, spec, false, ax_a, nrm, pts, sep,
                        fid, poly);
}

// Closest points of the supporting edges (a's edge along axis i, b's along axis j), and a
// feature id: (qa, qb, id); the axis L = a_i x b_j is oriented from a to b.
static void edge_points(const double* ca, M3 rota, const double* ea, const double* cb, M3 rotb,
                        const double* eb, int i, int j, double dx, double dy, double dz,
                        double* qa, double* qb, i64& code) {
    double uax = rota(0, i), uay = rota(1, i), uaz = rota(2, i);
    double ubx = rotb(0, j), uby = rotb(1, j), ubz = rotb(2, j);
    double lx = uay * ubz - uaz * uby;
    double ly = uaz * ubx - uax * ubz;
    double lz = uax * uby - uay * ubx;
    if (lx * dx + ly * dy + lz * dz < 0.0) {  // orient from a to b
        lx = -lx;
        ly = -ly;
        lz = -lz;
    }
    // supporting edge of a (farthest along L) and of b (farthest along -L): their midpoints
    double pax = ca[0], pay = ca[1], paz = ca[2];
    i64 code_a = 0;
    for (int k = 0; k < 3; ++k) {
        if (k == i) continue;
        double s = (lx * rota(0, k) + ly * rota(1, k) + lz * rota(2, k)) > 0.0 ? 1.0 : -1.0;
        if (s > 0.0) code_a |= i64(1) << k;
        pax += s * ea[k] * rota(0, k);
        pay += s * ea[k] * rota(1, k);
        paz += s * ea[k] * rota(2, k);
    }
    double pbx = cb[0], pby = cb[1], pbz = cb[2];
    i64 code_b = 0;
    for (int k = 0; k < 3; ++k) {
        if (k == j) continue;
        double s = (lx * rotb(0, k) + ly * rotb(1, k) + lz * rotb(2, k)) > 0.0 ? -1.0 : 1.0;
        if (s > 0.0) code_b |= i64(1) << k;
        pbx += s * eb[k] * rotb(0, k);
        pby += s * eb[k] * rotb(1, k);
        pbz += s * eb[k] * rotb(2, k);
    }
    // closest points of the lines pa + ta ua, pb + tb ub, clamped to the edges
    double rx = pax - pbx, ry = pay - pby, rz = paz - pbz;
    double b = uax * ubx + uay * uby + uaz * ubz;
    double d1 = uax * rx + uay * ry + uaz * rz;
    double d2 = ubx * rx + uby * ry + ubz * rz;
    double den = 1.0 - b * b;
    double ta = 0.0;
    if (den > 1e-12) ta = (b * d2 - d1) / den;
    ta = std::min(std::max(ta, -ea[i]), ea[i]);
    double tb = std::min(std::max(b * ta + d2, -eb[j]), eb[j]);
    ta = std::min(std::max(b * tb - d1, -ea[i]), ea[i]);
    code = 100000 + ((i * 3 + j) * 8 + code_a) * 8 + code_b;
    qa[0] = pax + ta * uax;
    qa[1] = pay + ta * uay;
    qa[2] = paz + ta * uaz;
    qb[0] = pbx + tb * ubx;
    qb[1] = pby + tb * uby;
    qb[2] = pbz + tb * ubz;
}

// One point between the supporting edges, normal along a_i x b_j (from b into a).
static i64 edge_contact(const double* ca, M3 rota, const double* ea, const double* cb, M3 rotb,
                        const double* eb, int i, int j, double dx, double dy, double dz,
                        double spec, double* nrm, Pts pts, double* sep, i64* fid) {
    double qa[3], qb[3];
    i64 code;
    edge_points(ca, rota, ea, cb, rotb, eb, i, j, dx, dy, dz, qa, qb, code);
    double lx = rota(1, i) * rotb(2, j) - rota(2, i) * rotb(1, j);
    double ly = rota(2, i) * rotb(0, j) - rota(0, i) * rotb(2, j);
    double lz = rota(0, i) * rotb(1, j) - rota(1, i) * rotb(0, j);
    double ln = std::sqrt(lx * lx + ly * ly + lz * lz);
    lx = lx / ln;
    ly = ly / ln;
    lz = lz / ln;
    if (lx * dx + ly * dy + lz * dz < 0.0) {
        lx = -lx;
        ly = -ly;
        lz = -lz;
    }
    double s = (qb[0] - qa[0]) * lx + (qb[1] - qa[1]) * ly + (qb[2] - qa[2]) * lz;
    if (s > spec) return 0;
    nrm[0] = -lx;
    nrm[1] = -ly;
    nrm[2] = -lz;
    pts[0][0] = 0.5 * (qa[0] + qb[0]);
    pts[0][1] = 0.5 * (qa[1] + qb[1]);
    pts[0][2] = 0.5 * (qa[2] + qb[2]);
    sep[0] = s;
    fid[0] = code;
    return 1;
}

// The separation along edge axis a_I x b_j (in a's frame e_I x c[:, j], c[3 i + j] = a_i . b_j),
// as the 15-axis test defines it:
//
//   l = e_I x c[:, j],  ln = |l|,  s = (|l . da| - sum_i ea_i |l_i| - sum_m eb_m |l . c[:, m]|) / ln
//
// Component I of l is exactly 0, and its terms are left out of every sum here. That changes no
// bit: 0 * x is +-0 for finite x, and adding +-0 to a sum changes at most the sign of an exact
// zero; ln's and r_a's sums are of non-negative terms, which start at +0 and stay >= +0, and the
// other sums are taken in absolute value. Returns false (no s) for near-parallel edges
// (ln < tol).
template <int I>
static inline bool edge_axis_sep(const double* c, int j, const double* ea, const double* eb,
                                 const double* da, double tol, double& s) {
    const double c0 = c[j], c1 = c[3 + j], c2 = c[6 + j];
    // the two nonzero components (u, v) of l, on axes (U, V), U < V
    constexpr int U = I == 0 ? 1 : 0;
    constexpr int V = I == 2 ? 1 : 2;
    double lu, lv;
    if (I == 0) {
        lu = -c2;  // l = (0, -c2, c1)
        lv = c1;
    } else if (I == 1) {
        lu = c2;  // l = (c2, 0, -c0)
        lv = -c0;
    } else {
        lu = -c1;  // l = (-c1, c0, 0)
        lv = c0;
    }
    const double ln = std::sqrt(lu * lu + lv * lv);
    if (ln < tol) return false;
    const double r_a = ea[U] * std::fabs(lu) + ea[V] * std::fabs(lv);
    double r_b = 0.0;
    for (int m = 0; m < 3; ++m)
        r_b += eb[m] * std::fabs(lu * c[3 * U + m] + lv * c[3 * V + m]);
    s = (std::fabs(lu * da[U] + lv * da[V]) - r_a - r_b) / ln;
    return true;
}

// Box a vs box b: separating-axis test over 15 axes, then a clipped face manifold (up to four
// points) or a single edge-edge point (plus, maybe, a face manifold in rows 4..). `work` (>= 24
// floats) and `poly` are scratch. Returns n1 + 8 n2.
i64 collide_box_box(const double* ca, M3 rota, const double* ea, const double* cb, M3 rotb,
                    const double* eb, double spec, double* nrm, Pts pts, double* sep, i64* fid,
                    double* work, Poly poly) {
    const CollisionConstants& cc = collision_constants();
    double dx = cb[0] - ca[0], dy = cb[1] - ca[1], dz = cb[2] - ca[2];
    double* c = work;  // c[3 i + j] = a_i . b_j ; c[9 + ...] = |c| + eps
    // faces of a: row i of c and a's axis i . d just before its test (a pair separated along
    // a_0 needs neither the other rows nor b's axes; the same values, the same operations)
    double sep_a = -1e300;
    int ax_a = 0;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            double v = rota(0, i) * rotb(0, j) + rota(1, i) * rotb(1, j) + rota(2, i) * rotb(2, j);
            c[3 * i + j] = v;
            c[9 + 3 * i + j] = std::fabs(v) + 1e-14;
        }
        work[18 + i] = rota(0, i) * dx + rota(1, i) * dy + rota(2, i) * dz;
        double s = std::fabs(work[18 + i]) - ea[i] -
                   (c[9 + 3 * i] * eb[0] + c[10 + 3 * i] * eb[1] + c[11 + 3 * i] * eb[2]);
        if (s > spec) return 0;
        if (s > sep_a) {
            sep_a = s;
            ax_a = i;
        }
    }
    const double da0 = work[18], da1 = work[19], da2 = work[20];
    // faces of b
    double sep_b = -1e300;
    int ax_b = 0;
    for (int j = 0; j < 3; ++j) {
        double dbj = rotb(0, j) * dx + rotb(1, j) * dy + rotb(2, j) * dz;
        double s = std::fabs(dbj) - eb[j] -
                   (c[9 + j] * ea[0] + c[12 + j] * ea[1] + c[15 + j] * ea[2]);
        if (s > spec) return 0;
        if (s > sep_b) {
            sep_b = s;
            ax_b = j;
        }
    }
    // edges: axis a_i x b_j, expressed in a's frame: e_i x c[:, j] (edge_axis_sep: the terms of
    // its zero component left out, which changes no bit)
    double sep_e = -1e300;
    int ei_best = -1;
    int ej_best = -1;
    const double tol = cc.edge_parallel_tol;
    const double da[3] = {da0, da1, da2};
    for (int j = 0; j < 3; ++j) {
        double s;
        if (!edge_axis_sep<0>(c, j, ea, eb, da, tol, s)) continue;
        if (s > spec) return 0;
        if (s > sep_e) {
            sep_e = s;
            ei_best = 0;
            ej_best = j;
        }
    }
    for (int j = 0; j < 3; ++j) {
        double s;
        if (!edge_axis_sep<1>(c, j, ea, eb, da, tol, s)) continue;
        if (s > spec) return 0;
        if (s > sep_e) {
            sep_e = s;
            ei_best = 1;
            ej_best = j;
        }
    }
    for (int j = 0; j < 3; ++j) {
        double s;
        if (!edge_axis_sep<2>(c, j, ea, eb, da, tol, s)) continue;
        if (s > spec) return 0;
        if (s > sep_e) {
            sep_e = s;
            ei_best = 2;
            ej_best = j;
        }
    }
    double face_sep = std::max(sep_a, sep_b);
    // relative margins taken on |separation| so that they favour faces for gaps and overlaps alike
    const double edge_margin = (1.0 - cc.edge_rel_tol) * std::fabs(face_sep);
    bool edge_best = ei_best >= 0 && sep_e > face_sep + edge_margin + cc.axis_abs_tol;
    if (edge_best) {
        i64 cnt = edge_contact(ca, rota, ea, cb, rotb, eb, ei_best, ej_best, dx, dy, dz, spec, nrm,
                               pts, sep, fid);
        if (cnt == 0 || face_sep > spec || face_sep < sep_e - spec) return cnt;
        // The edges touch first, but a face is within reach of this step: a tumbling box would
        // swing that face's corners in. Its face manifold goes in rows 4.. as a second manifold
        // of the pair, with its own normal (nrm[3:6]), so both features are guarded.
        i64 cnt2 = best_face_contact(ca, rota, ea, cb, rotb, eb, sep_a, ax_a, sep_b, ax_b, work,
                                     dx, dy, dz, spec, nrm + 3, pts + 4, sep + 4, fid + 4, poly);
        return cnt + 8 * cnt2;
    }
    return best_face_contact(ca, rota, ea, cb, rotb, eb, sep_a, ax_a, sep_b, ax_b, work, dx, dy,
                             dz, spec, nrm, pts, sep, fid, poly);
}

}  // namespace rb
