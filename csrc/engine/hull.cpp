// The process's hull table (hull.hpp) and the hull - plane collider (narrowphase.cpp's
// conventions: normal from b into a, sep < 0 penetration, points midway between the surfaces).
//
// * hull - plane (closed form): the hull's lowest points along the plane normal are among its
//   vertices, and every vertex's gap n . (x + R v) - off is exact; the vertices within spec are
//   the manifold (feature id: the vertex index, a material point, so warm starting follows it),
//   more than four reduced in vertex order by reduce_quantized (collider_points.hpp: the
//   touching vertices count as equally deep, so a face at rest keeps the same four every step).
#include "engine/hull.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <mutex>

#include "common/errors.hpp"
#include "engine/collider_points.hpp"
#include "engine/collision.hpp"
#include "engine/polytope.hpp"

namespace rb {

namespace {
std::atomic<const Hull*> g_hulls[MAX_HULLS];
std::atomic<i64> g_count{0};
std::mutex g_mutex;                            // registration only
std::vector<std::unique_ptr<Hull>> g_owned;    // the hulls, never freed
struct Pt {
    double x, y, z;
};
}  // namespace

i64 hull_count() { return g_count.load(std::memory_order_acquire); }

const Hull& hull_of(const double* size) {
    const i64 id = static_cast<i64>(size[0]);
    const Hull* h = (id >= 0 && id < MAX_HULLS) ? g_hulls[id].load(std::memory_order_acquire)
                                                : nullptr;
    if (h == nullptr) throw Error("RblogError", "a hull size row names no registered hull");
    return *h;
}

i64 register_hull(V2<double> vert, V2<double> fnrm, V1<double> foff, V1<i64> fstart,
                  V1<i64> fvert) {
    const i64 nv = vert.n0, nf = fnrm.n0;
    if (vert.n1 != 3 || fnrm.n1 != 3 || foff.n0 != nf || fstart.n0 != nf + 1 || nv < 4 ||
        nf < 4 || fstart[0] != 0 || fstart[nf] != fvert.n0)
        throw Error("RblogError", "register_hull: vertices (V, 3), normals (F, 3), offsets (F,), "
                                  "starts (F + 1,) over the face loops");
    auto h = std::make_unique<Hull>();
    h->nv = nv;
    h->nf = nf;
    h->vert.assign(vert.p, vert.p + 3 * nv);
    h->fnrm.assign(fnrm.p, fnrm.p + 3 * nf);
    h->foff.assign(foff.p, foff.p + nf);
    h->fstart.assign(fstart.p, fstart.p + nf + 1);
    h->fvert.assign(fvert.p, fvert.p + fvert.n0);
    for (i64 f = 0; f < nf; ++f) {
        const i64 m = fstart[f + 1] - fstart[f];
        if (m < 3 || m > HULL_MAX_FACE_VERTICES)
            throw Error("RblogError", "register_hull: a face with fewer than 3 or more than "
                                      "HULL_MAX_FACE_VERTICES vertices");
        h->max_face = std::max(h->max_face, m);
    }
    for (i64 k = 0; k < fvert.n0; ++k)
        if (fvert[k] < 0 || fvert[k] >= nv)
            throw Error("RblogError", "register_hull: a face vertex index out of range");
    for (i64 v = 0; v < nv; ++v) {
        double r2 = 0;
        for (int c = 0; c < 3; ++c) {
            const double x = h->vert[3 * v + c];
            h->ext[c] = std::max(h->ext[c], std::fabs(x));
            r2 += x * x;
        }
        h->radius = std::max(h->radius, std::sqrt(r2));
    }
    // edge directions, one per parallel class (the cross products with another shape's axes
    // are separating-axis candidates)
    for (i64 f = 0; f < nf; ++f) {
        const i64 s = fstart[f], m = fstart[f + 1] - s;
        for (i64 k = 0; k < m; ++k) {
            const double* a = &h->vert[3 * fvert[s + k]];
            const double* b = &h->vert[3 * fvert[s + (k + 1) % m]];
            double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
            const double l = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            if (!(l > 0)) continue;
            for (double& x : d) x /= l;
            bool seen = false;
            for (i64 e = 0; e < h->ne && !seen; ++e) {
                const double* u = &h->edir[3 * e];
                const double cx = u[1] * d[2] - u[2] * d[1], cy = u[2] * d[0] - u[0] * d[2],
                             cz = u[0] * d[1] - u[1] * d[0];
                seen = cx * cx + cy * cy + cz * cz <= 1e-18;
            }
            if (!seen) {
                h->edir.insert(h->edir.end(), d, d + 3);
                h->ne += 1;
            }
        }
    }
    polytope_edges(nf, h->fstart.data(), h->fvert.data(), h->fnrm.data(), h->edge, h->ecross);
    h->n_edge = static_cast<i64>(h->edge.size() / 4);
    h->vert_soa = by_coordinate(h->vert);
    h->fnrm_soa = by_coordinate(h->fnrm);
    h->ecross_soa = by_coordinate(h->ecross);
    h->fopp = opposite_faces(nf, h->fnrm.data());
    {
        EdgeClasses ec = edge_classes(h->ecross);
        h->cstart = std::move(ec.cstart);
        h->cedge = std::move(ec.cedge);
        h->crep = std::move(ec.crep);
        h->esign = std::move(ec.esign);
    }
    std::lock_guard<std::mutex> lock(g_mutex);
    const i64 n = g_count.load(std::memory_order_relaxed);
    for (i64 id = 0; id < n; ++id) {
        const Hull& o = *g_owned[id];
        if (o.vert == h->vert && o.fnrm == h->fnrm && o.foff == h->foff &&
            o.fstart == h->fstart && o.fvert == h->fvert)
            return id;
    }
    if (n >= MAX_HULLS) throw Error("RblogError", "more than MAX_HULLS distinct hulls");
    g_hulls[n].store(h.get(), std::memory_order_release);
    g_owned.push_back(std::move(h));
    g_count.store(n + 1, std::memory_order_release);
    return n;
}

i64 collide_hull_plane(const double* ca, M3 rota, const double* sa, const double* pn,
                       double poff, double spec, double* nrm, Pts pts, double* sep, i64* fid) {
    const Hull& hl = hull_of(sa);
    // the plane normal in the body frame, the centre's height
    const double nlx = rota(0, 0) * pn[0] + rota(1, 0) * pn[1] + rota(2, 0) * pn[2];
    const double nly = rota(0, 1) * pn[0] + rota(1, 1) * pn[1] + rota(2, 1) * pn[2];
    const double nlz = rota(0, 2) * pn[0] + rota(1, 2) * pn[1] + rota(2, 2) * pn[2];
    const double hc = pn[0] * ca[0] + pn[1] * ca[1] + pn[2] * ca[2] - poff;
    if (hc - hl.radius > spec) return 0;
    i64 count = 0;
    double least = INFINITY;
    for (i64 v = 0; v < hl.nv; ++v) {
        const double* p = &hl.vert[3 * v];
        const double s = hc + nlx * p[0] + nly * p[1] + nlz * p[2];
        least = std::min(least, s);
    }
    if (least > spec) return 0;
    // the candidates: every vertex within spec (at most MAX_CLIP_POINTS kept, deepest first
    // when more: a face at rest has at most HULL_MAX_FACE_VERTICES)
    constexpr i64 CAP = HULL_MAX_FACE_VERTICES;
    double P[CAP][3], S[CAP];
    i64 F[CAP];
    for (i64 v = 0; v < hl.nv; ++v) {
        const double* p = &hl.vert[3 * v];
        const double s = hc + nlx * p[0] + nly * p[1] + nlz * p[2];
        if (s > spec) continue;
        i64 k = count;
        if (count == CAP) {  // full: replace the shallowest kept one if this is deeper
            k = 0;
            for (i64 j = 1; j < CAP; ++j)
                if (S[j] > S[k]) k = j;
            if (!(s < S[k])) continue;
        } else {
            ++count;
        }
        for (int c = 0; c < 3; ++c)
            P[k][c] = ca[c] + rota(c, 0) * p[0] + rota(c, 1) * p[1] + rota(c, 2) * p[2] -
                      0.5 * s * pn[c];
        S[k] = s;
        F[k] = v;
    }
    // vertex order (a round-off-independent order for the reduction)
    for (i64 k = 1; k < count; ++k)
        for (i64 j = k; j > 0 && F[j] < F[j - 1]; --j) swap_point(P, S, F, j, j - 1);
    nrm[0] = pn[0];
    nrm[1] = pn[1];
    nrm[2] = pn[2];
    if (count <= MAX_MANIFOLD_POINTS) {
        for (i64 k = 0; k < count; ++k) {
            put(pts, sep, fid, k, Pt{P[k][0], P[k][1], P[k][2]}, S[k], F[k]);
        }
        return count;
    }
    i64 ids[CAP];
    const i64 n = reduce_quantized<CAP>(nrm, P, S, count, ids);
    for (i64 k = 0; k < n; ++k) {
        const i64 j = ids[k];
        put(pts, sep, fid, k, Pt{P[j][0], P[j][1], P[j][2]}, S[j], F[j]);
    }
    return n;
}

}  // namespace rb
