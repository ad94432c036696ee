// The velocity solve's lanes (contact_lanes.hpp): packing the colouring's sets into groups of
// four manifolds, the scalar and the portable wide kernels, and the choice between them.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include "engine/constraint_graph.hpp"
#include "engine/contact_lanes.hpp"
#include "engine/friction.hpp"
#include "engine/manifold.hpp"

namespace rb {

namespace {
#include "engine/contact_lanes.inl"

// RBLOG_SOLVER_PATH=scalar|sse2 forces a path at import (the tests' and benchmarks' switch)
int initial_path() {
    const char* e = std::getenv("RBLOG_SOLVER_PATH");
    if (e && std::strcmp(e, "scalar") == 0) return PATH_SCALAR;
    if (e && std::strcmp(e, "sse2") == 0) return PATH_SSE2;
    return PATH_AUTO;
}

int g_path = initial_path();

// the scalar kernel on a group's four lanes, one after another (NP: solve_group's)
template <int NP>
void solve_lanes_scalar(WideGroup& g, const LaneCtx& cx, double* change, i64* visits) {
    for (int l = 0; l < 4; ++l) solve_group<double, NP>(g, l, cx, change, visits);
}

bool has_avx2() {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
    static const bool yes = __builtin_cpu_supports("avx2");
    return yes;
#else
    return false;
#endif
}

}  // namespace

void set_solver_path(int path) { g_path = path; }
int solver_path() { return g_path; }

const char* solver_kernel() {
    if (g_path == PATH_SSE2) return "sse2";
    if (g_path == PATH_AUTO && has_avx2()) return "avx2";
    return "scalar";
}

void solve_groups_scalar(WideGroup* g, i64 g0, i64 g1, const LaneCtx& cx, double* change,
                         i64* visits) {
    // (a group's point count as a constant, as solve_groups_avx2)
    for (i64 k = g0; k < g1; ++k) {
        switch (g[k].n_pts) {
            case 1: solve_lanes_scalar<1>(g[k], cx, change, visits); break;
            case 2: solve_lanes_scalar<2>(g[k], cx, change, visits); break;
            case 3: solve_lanes_scalar<3>(g[k], cx, change, visits); break;
            case 4: solve_lanes_scalar<4>(g[k], cx, change, visits); break;
            default: solve_lanes_scalar<0>(g[k], cx, change, visits); break;
        }
    }
}

void solve_groups_wide(WideGroup* g, i64 g0, i64 g1, const LaneCtx& cx, double* change,
                       i64* visits) {
    if (g_path == PATH_SSE2) {
        for (i64 k = g0; k < g1; ++k) solve_group<d4>(g[k], 0, cx, change, visits);
        return;
    }
    if (g_path == PATH_AUTO && has_avx2()) {
        solve_groups_avx2(g, g0, g1, cx, change, visits);
        return;
    }
    solve_groups_scalar(g, g0, g1, cx, change, visits);
}

void pack_lanes(V1<ManifoldHead> mi, V1<Manifold> mf, V1<ContactPoint> pf,
                const ConstraintGraph& g, V1<double> bm,
                V2<double> bI, V1<i64> degree, V1<i64> last_hot, double inv_h, double sor,
                SolverLanes& lanes) {
    i64 n_sets = g.n_sets();
    // each colour's manifolds in lane order (set 0 keeps the graph's order: its manifolds are
    // solved one after another, so their order is the result's)
    std::vector<i64>& order = lanes.order;
    order.assign(g.order.begin(), g.order.end());
    std::vector<uint64_t>& keys = lanes.keys;
    for (i64 s = 1; s < n_sets; ++s) {
        i64 k0 = g.set_start[s], k1 = g.set_start[s + 1];
        if (k1 - k0 <= 4) continue;
        // the manifolds whose bodies the last solve kept hot the longest first (the last sweep
        // that changed one of them, so about the last it would visit them), then by point count,
        // most first: the lanes a late sweep visits share groups, and lanes of one length do.
        // Key: the sweep's complement (20 bits) and the count's (12) above the position in the
        // colour (32 bits): distinct keys, so the order is one (sweeps <= 30, counts <= 4).
        keys.resize((size_t)(k1 - k0));
        for (i64 k = k0; k < k1; ++k) {
            i64 m = g.order[k];
            i64 ha = last_hot[mi[m].a], hb = last_hot[mi[m].b];
            uint64_t late = (uint64_t)(ha > hb ? ha : hb), cnt = (uint64_t)mi[m].count;
            uint64_t hi = (0xfffffu - (late & 0xfffffu)) << 12 | (0xfffu - (cnt & 0xfffu));
            keys[(size_t)(k - k0)] = hi << 32 | (uint64_t)(k - k0);
        }
        std::sort(keys.begin(), keys.end());
        for (i64 k = k0; k < k1; ++k)
            order[(size_t)k] = g.order[(size_t)(k0 + (i64)(keys[(size_t)(k - k0)] & 0xffffffffu))];
    }
    lanes.set_group.assign(n_sets + 1, 0);
    i64 n_groups = 0;
    for (i64 s = 0; s < n_sets; ++s) {
        lanes.set_group[s] = n_groups;
        n_groups += (g.set_start[s + 1] - g.set_start[s] + 3) / 4;
    }
    lanes.set_group[n_sets] = n_groups;
    if ((i64)lanes.groups.size() < n_groups) lanes.groups.resize(n_groups);
    const i64 dummy = bm.n0 - 1;
    for (i64 s = 0; s < n_sets; ++s) {
        i64 k0 = g.set_start[s], k1 = g.set_start[s + 1];
        for (i64 q = lanes.set_group[s]; q < lanes.set_group[s + 1]; ++q) {
            WideGroup& gr = lanes.groups[q];
            std::memset(&gr, 0, sizeof gr);
            gr.n_pts = 0;
            for (int j = 0; j < 4; ++j) {
                i64 k = k0 + 4 * (q - lanes.set_group[s]) + j;
                if (k >= k1) {
                    gr.m[j] = -1;
                    gr.a[j] = dummy;
                    gr.b[j] = dummy;
                    continue;
                }
                i64 m = order[k];
                i64 ia = mi[m].a, ib = mi[m].b;
                i64 start = mi[m].start, cnt = mi[m].count;
                gr.m[j] = m;
                gr.a[j] = ia;
                gr.b[j] = ib;
                if (cnt > gr.n_pts) gr.n_pts = cnt;
                double ma = bm[ia], mb = bm[ib];
                gr.on[j] = 1.0;
                gr.cnt[j] = (double)cnt;
                gr.luok[j] = mf[m].lu_ok;
                gr.om[j] = ((ma > 0.0 && degree[ia] > 1) || (mb > 0.0 && degree[ib] > 1)) ? sor : 1.0;
                gr.mu[j] = mf[m].mu;
                gr.ma[j] = ma;
                gr.mb[j] = mb;
                for (int c = 0; c < 6; ++c) {
                    gr.a6[c][j] = bI(ia, c);
                    gr.b6[c][j] = bI(ib, c);
                }
                for (int c = 0; c < 3; ++c) {
                    gr.n[c][j] = mf[m].normal[c];
                    gr.t1[c][j] = mf[m].t1[c];
                    gr.t2[c][j] = mf[m].t2[c];
                }
                for (int c = 0; c < 16; ++c) gr.lu[c][j] = mf[m].lu[c];
                for (int c = 0; c < 4; ++c) gr.piv[c][j] = mf[m].piv[c];
                for (i64 i = 0; i < cnt; ++i) {
                    const ContactPoint& q_ = pf[start + i];
                    for (int c = 0; c < 3; ++c) {
                        gr.ra[i][c][j] = q_.ra[c];
                        gr.rb[i][c][j] = q_.rb[c];
                        gr.tk[i][c][j] = q_.tangent_k[c];
                    }
                    gr.det[i][j] = q_.tangent_k[0] * q_.tangent_k[2] -
                                   q_.tangent_k[1] * q_.tangent_k[1];
                    double sep = q_.s;
                    // speculative: the gap may close within the step, not more
                    gr.target[i][j] = sep > 0.0 ? -sep * inv_h : 0.0;
                    gr.nmass[i][j] = q_.normal_mass;
                    gr.ln[i][j] = q_.ln;
                    gr.l1[i][j] = q_.l1;
                    gr.l2[i][j] = q_.l2;
                }
            }
        }
    }
}

void unpack_lanes(V1<ManifoldHead> mi, V1<ContactPoint> pf, const SolverLanes& lanes) {
    i64 n_groups = lanes.set_group.empty() ? 0 : lanes.set_group.back();
    for (i64 q = 0; q < n_groups; ++q) {
        const WideGroup& gr = lanes.groups[q];
        for (int j = 0; j < 4; ++j) {
            i64 m = gr.m[j];
            if (m < 0) continue;
            i64 start = mi[m].start, cnt = mi[m].count;
            for (i64 i = 0; i < cnt; ++i) {
                ContactPoint& q_ = pf[start + i];
                q_.ln = gr.ln[i][j];
                q_.l1 = gr.l1[i][j];
                q_.l2 = gr.l2[i][j];
            }
        }
    }
}

}  // namespace rb
