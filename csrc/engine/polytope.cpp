// Polytope - polytope contact (hull - hull, box - hull): the separating-axis test of Gregorius
// (GDC 2013, "The Separating Axis Test between Convex Polyhedra"), Box2D v3's b2CollidePolygons
// and Jolt's manifold between two faces, in 3-D.
//
// Everything is computed in b's frame: a's vertices x = R v + t and face planes (R n, off + R n .
// t), R = R_b^T R_a, t = R_b^T (c_a - c_b). For a unit axis u the separation of the two convex
// solids along it is g(u) = min_b u . x_b - max_a u . x_a; the signed distance is max_u g(u),
// and for two overlapping polytopes the maximum is reached at a face normal of either or at the
// cross product of an edge of each (the separating-axis theorem), so:
//
// * face query: for a's face f (plane n . x = d in b's frame) g = min_v n . x_b,v - d, and the
//   same for b's faces against a's vertices; the largest of each side is kept.
// * edge query: only the edge pairs that build a face of the Minkowski difference A - B can
//   carry the maximum: their arcs on the Gauss map (a's edge between normals a, b; b's edge
//   between c, d, negated: C = -c, D = -d) cross, Gregorius' IsMinkowskiFace(a, b, C, D):
//     C.(b x a) D.(b x a) < 0,  a.(D x C) b.(D x C) < 0,  C.(b x a) b.(D x C) > 0,
//   with b x a and D x C = d x c precomputed per edge (PolytopeView::ecross). For such a pair g is the
//   gap of the two edge lines along u = e_a x e_b (oriented away from a's centre, which is inside
//   a): u . (p_b - p_a). Edges within EDGE_PARALLEL_TOL (sin) of parallel are skipped: their
//   axis is a face normal's too.
// * Any g above spec ends the pair (g bounds the distance from below: apart by more than spec).
// * Axis choice as box - box (box_box.cpp, the same tolerances): b's face replaces a's when
//   g_b > g_a + (1 - FACE_REL_TOL) |g_a| + AXIS_ABS_TOL, an edge pair wins when g_e > g_face +
//   (1 - EDGE_REL_TOL) |g_face| + AXIS_ABS_TOL, so manifolds do not flip between nearly equal
//   axes from step to step (a face chosen over a slightly better edge reports that face's gap:
//   deeper than the true one by at most that band).
// * Edge query skipped: the face manifold is built first (spec >= 0), and from it a bound of
//   the signed distance, which bounds every edge pair's g. Apart (g_face >= 0): each point's
//   ends (an incident face point, its projection in the reference face) lie on the two
//   surfaces, its gap apart: the least gap. Overlapping: a ball of radius r = min over both
//   polytopes' faces of off - n . x about the centroid x of the touching points (gap <= 0)
//   lies in both solids when r > 0, and no translation shorter than 2 r parts them: -2 r (a
//   face resting level on another: r is half its depth). Below the edge threshold no edge
//   pair can be chosen: the query is skipped and the manifold is the one it would have kept.
// * Face manifold: the reference face (the chosen face, normal n from its polytope towards the
//   other) and the incident face (the other polytope's face most anti-parallel to n); the
//   incident loop clipped to the reference face's side planes (Sutherland - Hodgman: at most the
//   two loops' vertex counts together), each point's gap z = n . x - d to the reference plane,
//   kept while z <= spec and moved half its gap back towards the reference face (the midpoint
//   between the surfaces). Every point's gap is at least g. The most anti-parallel face need
//   not hold the incident polytope's deepest vertex (the face nearest -n on the Gauss map is
//   not always one of that vertex's faces): when no clipped point is as deep as g, that vertex
//   joins if it lies in the reference face's prism (always so when the face realizes the
//   signed distance: the Minkowski difference's face is the reference face minus that vertex),
//   not when it hangs beside the face (a box over a table's edge: its deepest corner is in the
//   air, no contact); the least gap is then above g. An apart pair's g is a lower bound of its
//   distance (its closest features may be a vertex or an edge end on both, as box - box's).
//   More than four points: reduce_quantized (collider_points.hpp: the touching points count as
//   equally deep, so a face at rest keeps the same four every step). Normal (from b into
//   a): -n when the reference face is a's, n when b's. A face manifold left empty (a face kept
//   over a slightly better edge pair, the faces not meeting) gives way to that edge pair's
//   contact.
// * Edge contact: one point midway between the closest points of the two edges (clamped to the
//   segments), gap u . (q_b - q_a) (>= g_e), normal -u. When a face is also within reach of
//   the step (g_face <= spec and g_face >= g_e - spec) its face manifold goes in rows 4.. as the
//   pair's second manifold (normal nrm[3:6]), as box - box does: a tumbling polytope would swing
//   that face's corners in.
//
// Feature ids (stable per feature pair, for warm starting): a face point
// ((side 2^16 + ref face) 2^16 + incident face) 2^14 + clip id, side 0 when the reference face is
// a's; the clip id is the incident loop position k (0..63) of a vertex, 64 + 64 label + p for
// the point where the polygon edge `label` (incident edge k: k, reference side plane q: 64 + q)
// crosses reference side plane p, FID_DEEPEST for the deepest vertex; an edge point
// 2^50 + 2^20 edge_a + edge_b.
#include "engine/polytope.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <utility>

#include "engine/collider_points.hpp"
#include "engine/vec3.hpp"

namespace rb {

namespace {

using vec::V;
inline V at(const double* p, i64 k) { return {p[3 * k], p[3 * k + 1], p[3 * k + 2]}; }
inline V rot(M3 r, V v) {  // r v
    return {r(0, 0) * v.x + r(0, 1) * v.y + r(0, 2) * v.z,
            r(1, 0) * v.x + r(1, 1) * v.y + r(1, 2) * v.z,
            r(2, 0) * v.x + r(2, 1) * v.y + r(2, 2) * v.z};
}

// out[k] = n . (x_k, y_k, z_k) over m points by coordinate (soa: (3, m)); an elementwise loop,
// which vectorizes
inline void dots(V n, const double* __restrict soa, i64 m, double* __restrict out) {
    const double *x = soa, *y = soa + m, *z = soa + 2 * m;
    for (i64 k = 0; k < m; ++k) out[k] = n.x * x[k] + n.y * y[k] + n.z * z[k];
}
// max_k d[k] (as least)
inline double most(const double* d, i64 m) {
    double hi0 = -INFINITY, hi1 = -INFINITY;
    i64 k = 0;
    for (; k + 1 < m; k += 2) {
        hi0 = std::max(hi0, d[k]);
        hi1 = std::max(hi1, d[k + 1]);
    }
    if (k < m) hi0 = std::max(hi0, d[k]);
    return std::max(hi0, hi1);
}
// min_k d[k] (two running minima, even and odd k: min is exact, so the order is free)
inline double least(const double* d, i64 m) {
    double lo0 = INFINITY, lo1 = INFINITY;
    i64 k = 0;
    for (; k + 1 < m; k += 2) {
        lo0 = std::min(lo0, d[k]);
        lo1 = std::min(lo1, d[k + 1]);
    }
    if (k < m) lo0 = std::min(lo0, d[k]);
    return std::min(lo0, lo1);
}

constexpr i64 FID_DEEPEST = (1 << 14) - 1;
constexpr i64 FID_EDGE = i64(1) << 50;
// clipped polygon room: an incident loop clipped by a reference loop (each <=
// HULL_MAX_FACE_VERTICES) has at most their vertex counts together, and the deepest vertex
constexpr i64 CAP = 2 * HULL_MAX_FACE_VERTICES + 1;

// the polytopes in b's frame: a's vertices, normals and offsets moved there (b's own arrays)
struct Frame {
    const double* vert;
    const double* fnrm;
    const double* foff;
    const PolytopeView* p;
};

struct Scratch {
    std::vector<double> va, na, da, cd, ad;  // a's vertices, normals, offsets; the edge query's dots
    std::vector<double> va_soa, tmp;         // a's vertices by coordinate; dots
    std::vector<i64> pass, pass2;            // b's edges that pass the Gauss-map tests
};

// Face manifold of reference face fr of R against I (both in b's frame); g: the pair's
// separation along that face's normal, scale: a length of the pair (round-off). side 0: R is a.
// Returns the points written (<= 4).
i64 face_contact(const Frame& R, i64 fr, const Frame& I, int side, double g, double spec,
                 const double* cb, M3 rotb, double scale, double* nrm, Pts pts, double* sep,
                 i64* fid) {
    const V n = at(R.fnrm, fr);
    const double d = R.foff[fr];
    // incident face: the most anti-parallel to n
    i64 fi = 0;
    double least = INFINITY;
    for (i64 f = 0; f < I.p->nf; ++f) {
        const double c = dot(at(I.fnrm, f), n);
        if (c < least) {
            least = c;
            fi = f;
        }
    }
    // the incident loop, (point, id, label of its outgoing edge)
    double X[2][CAP][3];
    i64 id[2][CAP], lab[2][CAP];
    i64 m = 0;
    {
        const i64 s0 = I.p->fstart[fi], s1 = I.p->fstart[fi + 1];
        for (i64 k = s0; k < s1; ++k) {
            const V x = at(I.vert, I.p->fvert[k]);
            X[0][m][0] = x.x;
            X[0][m][1] = x.y;
            X[0][m][2] = x.z;
            id[0][m] = k - s0;
            lab[0][m] = k - s0;
            ++m;
        }
    }
    int cur = 0;
    const i64 r0 = R.p->fstart[fr], rm = R.p->fstart[fr + 1] - r0;
    for (i64 p = 0; p < rm && m > 0; ++p) {
        const V a = at(R.vert, R.p->fvert[r0 + p]);
        const V b = at(R.vert, R.p->fvert[r0 + (p + 1) % rm]);
        const V sp = cross(b - a, n);  // outward side-plane normal (the loop runs ccw about n)
        const double off = dot(sp, a);
        const int nx = 1 - cur;
        i64 k2 = 0;
        for (i64 i = 0; i < m; ++i) {
            const i64 j = (i + 1) % m;
            const V xi{X[cur][i][0], X[cur][i][1], X[cur][i][2]};
            const V xj{X[cur][j][0], X[cur][j][1], X[cur][j][2]};
            const double di = dot(sp, xi) - off, dj = dot(sp, xj) - off;
            if (di <= 0.0) {
                for (int c = 0; c < 3; ++c) X[nx][k2][c] = X[cur][i][c];
                id[nx][k2] = id[cur][i];
                lab[nx][k2] = lab[cur][i];
                ++k2;
            }
            if ((di <= 0.0) != (dj <= 0.0)) {
                const V x = xi + (di / (di - dj)) * (xj - xi);
                X[nx][k2][0] = x.x;
                X[nx][k2][1] = x.y;
                X[nx][k2][2] = x.z;
                id[nx][k2] = 64 + 64 * lab[cur][i] + p;
                // leaving: the new point's edge runs along plane p; entering: along edge i's
                lab[nx][k2] = di <= 0.0 ? 64 + p : lab[cur][i];
                ++k2;
            }
        }
        m = k2;
        cur = nx;
    }
    double P[CAP][3], S[CAP];
    i64 F[CAP];
    i64 count = 0;
    const i64 base = ((i64(side) * 65536 + (fr & 0xffff)) * 65536 + (fi & 0xffff)) * 16384;
    auto add = [&](V x, double z, i64 f) {
        const V w = V{cb[0], cb[1], cb[2]} + rot(rotb, x - (0.5 * z) * n);
        P[count][0] = w.x;
        P[count][1] = w.y;
        P[count][2] = w.z;
        S[count] = z;
        F[count] = base + f;
        ++count;
    };
    double zmin = INFINITY;
    for (i64 k = 0; k < m; ++k) {
        const V x{X[cur][k][0], X[cur][k][1], X[cur][k][2]};
        const double z = dot(n, x) - d;
        zmin = std::min(zmin, z);
        if (z <= spec) add(x, z, id[cur][k]);
    }
    if (!(zmin <= g + 1e-12 * scale)) {
        // the incident face misses I's deepest vertex: that vertex joins when it lies in the
        // reference face's prism (module comment), not when it hangs beside the face
        i64 vb = 0;
        double lo = INFINITY;
        for (i64 v = 0; v < I.p->nv; ++v) {
            const double z = dot(n, at(I.vert, v));
            if (z < lo) {
                lo = z;
                vb = v;
            }
        }
        const V x = at(I.vert, vb);
        bool inside = lo - d <= spec;
        for (i64 p = 0; p < rm && inside; ++p) {
            const V a = at(R.vert, R.p->fvert[r0 + p]);
            const V b = at(R.vert, R.p->fvert[r0 + (p + 1) % rm]);
            inside = dot(cross(b - a, n), x - a) <= 0.0;
        }
        if (inside) add(x, lo - d, FID_DEEPEST);
    }
    const V nw = rot(rotb, n);
    const V nm = side == 0 ? -1.0 * nw : nw;
    put_normal(nrm, nm);
    if (count <= MAX_MANIFOLD_POINTS) {
        for (i64 k = 0; k < count; ++k) put(pts, sep, fid, k, V{P[k][0], P[k][1], P[k][2]}, S[k], F[k]);
        return count;
    }
    i64 ids[CAP];
    const i64 nk = reduce_quantized<CAP>(nrm, P, S, count, ids);
    for (i64 k = 0; k < nk; ++k) {
        const i64 j = ids[k];
        put(pts, sep, fid, k, V{P[j][0], P[j][1], P[j][2]}, S[j], F[j]);
    }
    return nk;
}

}  // namespace

void polytope_edges(i64 nf, const i64* fstart, const i64* fvert, const double* fnrm,
                    std::vector<i64>& edge, std::vector<double>& ecross) {
    std::map<std::pair<i64, i64>, std::pair<i64, i64>> seen;  // (v0, v1) -> (f0, row or -1)
    std::vector<std::array<i64, 4>> rows;
    for (i64 f = 0; f < nf; ++f) {
        const i64 s = fstart[f], m = fstart[f + 1] - s;
        for (i64 k = 0; k < m; ++k) {
            const i64 a = fvert[s + k], b = fvert[s + (k + 1) % m];
            auto twin = seen.find({b, a});
            if (twin != seen.end() && twin->second.second < 0) {
                rows.push_back({b, a, twin->second.first, f});
                twin->second.second = static_cast<i64>(rows.size()) - 1;
            } else {
                seen[{a, b}] = {f, -1};
            }
        }
    }
    for (const auto& r : rows) {
        edge.insert(edge.end(), r.begin(), r.end());
        const V c = cross(at(fnrm, r[3]), at(fnrm, r[2]));
        ecross.insert(ecross.end(), {c.x, c.y, c.z});
    }
}

std::vector<i64> opposite_faces(i64 nf, const double* fnrm) {
    std::vector<i64> opp(nf, -1);
    for (i64 f = 0; f < nf; ++f)
        for (i64 g = 0; g < nf && opp[f] < 0; ++g)
            if (fnrm[3 * g] == -fnrm[3 * f] && fnrm[3 * g + 1] == -fnrm[3 * f + 1] &&
                fnrm[3 * g + 2] == -fnrm[3 * f + 2])
                opp[f] = g;
    return opp;
}

EdgeClasses edge_classes(const std::vector<double>& ecross) {
    const i64 ne = static_cast<i64>(ecross.size() / 3);
    std::vector<i64> cls(ne, -1);
    std::vector<double> sg(ne, 1.0);
    std::vector<i64> first;  // each class's first edge
    for (i64 e = 0; e < ne; ++e) {
        const V u = at(ecross.data(), e);
        for (size_t k = 0; k < first.size() && cls[e] < 0; ++k) {
            const V r = at(ecross.data(), first[k]);
            const V c = cross(u, r);
            if (dot(c, c) <= 1e-18 * dot(u, u) * dot(r, r)) {
                cls[e] = static_cast<i64>(k);
                sg[e] = dot(u, r) < 0.0 ? -1.0 : 1.0;
            }
        }
        if (cls[e] < 0) {
            cls[e] = static_cast<i64>(first.size());
            first.push_back(e);
        }
    }
    EdgeClasses out;
    out.cstart.push_back(0);
    for (size_t k = 0; k < first.size(); ++k) {
        for (i64 e = 0; e < ne; ++e)
            if (cls[e] == static_cast<i64>(k)) {
                out.cedge.push_back(e);
                out.esign.push_back(sg[e]);
            }
        out.cstart.push_back(static_cast<i64>(out.cedge.size()));
        const V r = at(ecross.data(), first[k]);
        out.crep.insert(out.crep.end(), {r.x, r.y, r.z});
    }
    return out;
}

std::vector<double> by_coordinate(const std::vector<double>& rows) {
    const size_t n = rows.size() / 3;
    std::vector<double> out(rows.size());
    for (size_t k = 0; k < n; ++k)
        for (size_t c = 0; c < 3; ++c) out[c * n + k] = rows[3 * k + c];
    return out;
}

PolytopeView hull_view(const Hull& h) {
    return {h.nv,           h.nf,          h.n_edge,      h.vert.data(),   h.fnrm.data(),
            h.foff.data(),  h.fstart.data(), h.fvert.data(), h.edge.data(), h.ecross.data(),
            h.radius,       {h.ext[0], h.ext[1], h.ext[2]}, h.vert_soa.data(), h.fnrm_soa.data(),
            h.ecross_soa.data(), h.fopp.data(),
            static_cast<i64>(h.cstart.size()) - 1, h.cstart.data(), h.cedge.data(),
            h.crep.data(),  h.esign.data()};
}

PolytopeView box_view(const double* e, double* vert, double* foff) {
    // faces -x, +x, -y, +y, -z, +z, each loop ccw about its outward normal
    static const double FN[18] = {-1, 0, 0, 1, 0, 0, 0, -1, 0, 0, 1, 0, 0, 0, -1, 0, 0, 1};
    static const i64 FS[7] = {0, 4, 8, 12, 16, 20, 24};
    static const i64 FOPP[6] = {1, 0, 3, 2, 5, 4};
    static const i64 FV[24] = {0, 4, 6, 2, 1, 3, 7, 5, 0, 1, 5, 4,
                               2, 6, 7, 3, 0, 2, 3, 1, 4, 5, 7, 6};
    struct Edges {
        std::vector<i64> edge;
        std::vector<double> ecross, ecross_soa, fnrm_soa;
        EdgeClasses ec;
        Edges() {
            polytope_edges(6, FS, FV, FN, edge, ecross);
            ec = edge_classes(ecross);
            ecross_soa = by_coordinate(ecross);
            fnrm_soa = by_coordinate(std::vector<double>(FN, FN + 18));
        }
    };
    static const Edges E;
    for (int k = 0; k < 8; ++k) {
        vert[3 * k] = (k & 1) ? e[0] : -e[0];
        vert[3 * k + 1] = (k & 2) ? e[1] : -e[1];
        vert[3 * k + 2] = (k & 4) ? e[2] : -e[2];
    }
    for (int k = 0; k < 8; ++k)
        for (int c = 0; c < 3; ++c) vert[24 + 8 * c + k] = vert[3 * k + c];
    for (int f = 0; f < 6; ++f) foff[f] = e[f / 2];
    const double r = std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
    return {8,         6,           static_cast<i64>(E.edge.size() / 4),
            vert,      FN,          foff,
            FS,        FV,          E.edge.data(),
            E.ecross.data(), r,     {e[0], e[1], e[2]},
            vert + 24, E.fnrm_soa.data(), E.ecross_soa.data(), FOPP,
            static_cast<i64>(E.ec.cstart.size()) - 1, E.ec.cstart.data(), E.ec.cedge.data(),
            E.ec.crep.data(), E.ec.esign.data()};
}

i64 collide_polytopes(const PolytopeView& A, const double* ca, M3 rota, const PolytopeView& B,
                      const double* cb, M3 rotb, double spec, double* nrm, Pts pts, double* sep,
                      i64* fid) {
    const CollisionConstants& cc = collision_constants();
    // a in b's frame: t = R_b^T (c_a - c_b), R = R_b^T R_a
    const V dw{ca[0] - cb[0], ca[1] - cb[1], ca[2] - cb[2]};
    const V t{rotb(0, 0) * dw.x + rotb(1, 0) * dw.y + rotb(2, 0) * dw.z,
              rotb(0, 1) * dw.x + rotb(1, 1) * dw.y + rotb(2, 1) * dw.z,
              rotb(0, 2) * dw.x + rotb(1, 2) * dw.y + rotb(2, 2) * dw.z};
    if (std::sqrt(dot(t, t)) - A.radius - B.radius > spec) return 0;
    double Rm[9];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            Rm[3 * i + j] = rotb(0, i) * rota(0, j) + rotb(1, i) * rota(1, j) +
                            rotb(2, i) * rota(2, j);
    const M3 R(Rm);
    // the boxes around them (PolytopeView::ext), their six face axes: cheaper than the
    // polytopes' and a lower bound of their separation (most candidate pairs end here)
    for (int i = 0; i < 3; ++i) {
        const double tb = i == 0 ? t.x : (i == 1 ? t.y : t.z);
        const double ta = Rm[i] * t.x + Rm[3 + i] * t.y + Rm[6 + i] * t.z;  // (R^T t)_i
        double rb = B.ext[i], ra = A.ext[i];
        for (int j = 0; j < 3; ++j) {
            rb += std::fabs(Rm[3 * i + j]) * A.ext[j];
            ra += std::fabs(Rm[3 * j + i]) * B.ext[j];
        }
        if (std::fabs(tb) - rb > spec || std::fabs(ta) - ra > spec) return 0;
    }
    thread_local Scratch sc;
    sc.va.resize(3 * A.nv);
    sc.va_soa.resize(3 * A.nv);
    sc.na.resize(3 * A.nf);
    sc.da.resize(A.nf);
    sc.cd.resize(B.nf);
    sc.tmp.resize(std::max(A.nv, B.nv));
    for (i64 v = 0; v < A.nv; ++v) {
        const V x = rot(R, at(A.vert, v)) + t;
        sc.va[3 * v] = sc.va_soa[v] = x.x;
        sc.va[3 * v + 1] = sc.va_soa[A.nv + v] = x.y;
        sc.va[3 * v + 2] = sc.va_soa[2 * A.nv + v] = x.z;
    }
    for (i64 f = 0; f < A.nf; ++f) {
        const V n = rot(R, at(A.fnrm, f));
        sc.na[3 * f] = n.x;
        sc.na[3 * f + 1] = n.y;
        sc.na[3 * f + 2] = n.z;
        sc.da[f] = A.foff[f] + dot(n, t);
    }
    const Frame FA{sc.va.data(), sc.na.data(), sc.da.data(), &A};
    const Frame FB{B.vert, B.fnrm, B.foff, &B};
    double* tmp = sc.tmp.data();
    // face queries: a's face f (n . x = d in b's frame) g = min over b's vertices of n . x - d,
    // and b's faces against a's vertices; a face and its exact opposite from one set of dots
    // (min n . x for n, -max n . x for -n); the largest g, ties to the lower face index
    auto face_query = [&](const PolytopeView& P, const double* nrm_p, const double* off_p,
                          const double* soa_q, i64 nv_q, double& best, i64& arg) -> bool {
        best = -INFINITY;
        arg = 0;
        auto take = [&](i64 f, double s) {
            if (s > best || (s == best && f < arg)) {
                best = s;
                arg = f;
            }
        };
        for (i64 f = 0; f < P.nf; ++f) {
            const i64 o = P.fopp[f];
            if (o >= 0 && o < f) continue;
            dots(at(nrm_p, f), soa_q, nv_q, tmp);
            const double s = least(tmp, nv_q) - off_p[f];
            if (s > spec) return false;
            take(f, s);
            if (o < 0) continue;
            const double so = -most(tmp, nv_q) - off_p[o];
            if (so > spec) return false;
            take(o, so);
        }
        return true;
    };
    double sep_a, sep_b;
    i64 fa, fb;
    if (!face_query(A, FA.fnrm, FA.foff, B.vert_soa, B.nv, sep_a, fa)) return 0;
    if (!face_query(B, B.fnrm, B.foff, sc.va_soa.data(), A.nv, sep_b, fb)) return 0;
    const double scale = A.radius + B.radius;
    auto best_face = [&](double* n_out, Pts p_out, double* s_out, i64* f_out) -> i64 {
        if (sep_b > sep_a + (1.0 - cc.face_rel_tol) * std::fabs(sep_a) + cc.axis_abs_tol)
            return face_contact(FB, fb, FA, 1, sep_b, spec, cb, rotb, scale, n_out, p_out, s_out,
                                f_out);
        return face_contact(FA, fa, FB, 0, sep_a, spec, cb, rotb, scale, n_out, p_out, s_out,
                            f_out);
    };
    const double face_sep = std::max(sep_a, sep_b);
    // an edge pair is chosen only when its separation exceeds edge_thr (module comment)
    const double edge_thr = face_sep + (1.0 - cc.edge_rel_tol) * std::fabs(face_sep) +
                            cc.axis_abs_tol;
    // the face manifold first, and a bound of the signed distance from it (module comment):
    // at most edge_thr, no edge pair can be chosen and the edge query is skipped. The margin
    // covers the planes' own error: a merged face's vertices lie up to FACE_COPLANAR_RTOL (1e-9,
    // rblog/engine/hull.py) of the hull's size off its plane
    // (not in the project stage's pass, spec < 0: a pair that reaches here is mostly parted by
    // an edge pair, which the edge query finds without the manifold)
    i64 n_face = spec >= 0.0 ? best_face(nrm, pts, sep, fid) : -1;
    if (n_face > 0) {
        double bound = INFINITY;
        if (face_sep >= 0.0) {
            // apart: each point's ends lie on the two surfaces, its gap apart
            for (i64 q = 0; q < n_face; ++q) bound = std::min(bound, sep[q]);
        } else {
            // overlapping: -2 r, r the radius of a ball about the touching points' centroid
            // that lies in both polytopes
            V xw{0.0, 0.0, 0.0};
            i64 k = 0;
            for (i64 q = 0; q < n_face; ++q) {
                if (!(sep[q] <= 0.0)) continue;
                xw = xw + V{pts[q][0] - cb[0], pts[q][1] - cb[1], pts[q][2] - cb[2]};
                ++k;
            }
            if (k > 0) {
                xw = (1.0 / double(k)) * xw;
                const V x{rotb(0, 0) * xw.x + rotb(1, 0) * xw.y + rotb(2, 0) * xw.z,
                          rotb(0, 1) * xw.x + rotb(1, 1) * xw.y + rotb(2, 1) * xw.z,
                          rotb(0, 2) * xw.x + rotb(1, 2) * xw.y + rotb(2, 2) * xw.z};
                double r = INFINITY;
                for (i64 f = 0; f < A.nf; ++f)
                    r = std::min(r, FA.foff[f] - dot(at(FA.fnrm, f), x));
                for (i64 f = 0; f < B.nf; ++f)
                    r = std::min(r, FB.foff[f] - dot(at(FB.fnrm, f), x));
                bound = -2.0 * r;
            }
        }
        if (bound + 1e-8 * scale < edge_thr) return n_face;
    }
    // edge query over the pairs that build a face of the Minkowski difference: ad[f ne_b + j] =
    // a's normal f . (d x c) of b's edge j, cd[f] = b's normal f . (b x a) of a's edge class
    sc.ad.resize(A.nf * B.ne);
    sc.pass.resize(B.ne);
    for (i64 f = 0; f < A.nf; ++f) dots(at(FA.fnrm, f), B.ecross_soa, B.ne, &sc.ad[f * B.ne]);
    double sep_e = -INFINITY;
    i64 eab = -1, ebb = -1;
    V ue{0, 0, 0};
    const double ptol2 = cc.edge_parallel_tol * cc.edge_parallel_tol;
    // IsMinkowskiFace(a, b, -c, -d): (-c.(b x a)) (-d.(b x a)) < 0, a.(d x c) b.(d x c) < 0,
    // (-c.(b x a)) b.(d x c) > 0. The first test is one per class of a's parallel edges (their
    // b x a are multiples of one vector: cd = b's normals . R crep, its sign times esign); the
    // pairs that pass are listed without a branch (about half pass the first test: a branch on
    // it would be mispredicted half the time)
    sc.pass2.resize(B.ne);
    for (i64 c = 0; c < A.nc; ++c) {
        dots(rot(R, at(A.crep, c)), B.fnrm_soa, B.nf, sc.cd.data());
        i64 n1 = 0;
        for (i64 j = 0; j < B.ne; ++j) {
            const i64* eb = B.edge + 4 * j;
            sc.pass[n1] = j;
            n1 += sc.cd[eb[2]] * sc.cd[eb[3]] < 0.0;
        }
        if (n1 == 0) continue;
        for (i64 m = A.cstart[c]; m < A.cstart[c + 1]; ++m) {
            const i64 i = A.cedge[m];
            const double sg = A.esign[m];
            const i64* ea = A.edge + 4 * i;
            const double* ada = &sc.ad[ea[2] * B.ne];
            const double* adb = &sc.ad[ea[3] * B.ne];
            i64 n2 = 0;
            for (i64 k = 0; k < n1; ++k) {
                const i64 j = sc.pass[k];
                const double cba = sg * sc.cd[B.edge[4 * j + 2]], bdc = adb[j];
                sc.pass2[n2] = j;
                n2 += std::max(ada[j] * bdc, cba * bdc) < 0.0;
            }
            if (n2 == 0) continue;
            const V p1 = at(FA.vert, ea[0]);
            const V e1 = at(FA.vert, ea[1]) - p1;
            const double l1 = dot(e1, e1);
            for (i64 k = 0; k < n2; ++k) {
                const i64 j = sc.pass2[k];
                const i64* eb = B.edge + 4 * j;
                const V p2 = at(B.vert, eb[0]);
                const V e2 = at(B.vert, eb[1]) - p2;
                V u = cross(e1, e2);
                const double uu = dot(u, u);
                if (uu < ptol2 * l1 * dot(e2, e2)) continue;
                const double lu = std::sqrt(uu);
                u = (dot(u, p1 - t) < 0.0 ? -1.0 / lu : 1.0 / lu) * u;
                const double s = dot(u, p2 - p1);
                if (s > spec) return 0;
                if (s > sep_e) {
                    sep_e = s;
                    eab = i;
                    ebb = j;
                    ue = u;
                }
            }
        }
    }
    const bool edge_best = eab >= 0 && sep_e > edge_thr;
    if (!edge_best) {
        const i64 n = n_face >= 0 ? n_face : best_face(nrm, pts, sep, fid);
        // a face kept over a slightly better edge pair whose faces do not meet (the clipped
        // polygon empty): the edges' contact
        if (n > 0 || eab < 0) return n;
    }
    // edge contact: closest points of the two segments
    const i64* ea = A.edge + 4 * eab;
    const i64* eb = B.edge + 4 * ebb;
    const V p1 = at(FA.vert, ea[0]), d1 = at(FA.vert, ea[1]) - p1;
    const V p2 = at(B.vert, eb[0]), d2 = at(B.vert, eb[1]) - p2;
    const V r = p1 - p2;
    const double aa = dot(d1, d1), ee = dot(d2, d2), ff = dot(d2, r), cc1 = dot(d1, r),
                 bb = dot(d1, d2);
    const double den = aa * ee - bb * bb;
    auto clamp01 = [](double x) { return std::min(std::max(x, 0.0), 1.0); };
    double s1 = den > 0.0 ? clamp01((bb * ff - cc1 * ee) / den) : 0.0;
    double s2 = (bb * s1 + ff) / ee;
    if (s2 < 0.0 || s2 > 1.0) {
        s2 = clamp01(s2);
        s1 = clamp01((bb * s2 - cc1) / aa);
    }
    const V qa = p1 + s1 * d1, qb = p2 + s2 * d2;
    const double g = dot(ue, qb - qa);
    if (g > spec) return 0;
    const V nw = rot(rotb, ue);
    put_normal(nrm, -1.0 * nw);
    put(pts, sep, fid, 0, V{cb[0], cb[1], cb[2]} + rot(rotb, 0.5 * (qa + qb)), g,
        FID_EDGE + (i64(eab) << 20) + ebb);
    if (face_sep > spec || face_sep < sep_e - spec) return 1;
    // the edges touch first, but a face is within reach of this step (module comment)
    const i64 n2 = best_face(nrm + 3, pts + 4, sep + 4, fid + 4);
    return 1 + 8 * n2;
}

}  // namespace rb
