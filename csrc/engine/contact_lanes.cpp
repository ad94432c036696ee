// The velocity solve's lanes (contact_lanes.hpp): packing the colouring's sets into groups of
// four manifolds, the scalar and the portable wide kernels, and the choice between them.
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "engine/constraint_graph.hpp"
#include "engine/contact_lanes.hpp"
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
    for (i64 k = g0; k < g1; ++k)
        for (int l = 0; l < 4; ++l) solve_group<double>(g[k], l, cx, change, visits);
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

namespace {

// A group with at least this many lanes visited is solved where it is; one with fewer gives its
// visited lanes to the dense groups (copying a lane in and its impulses back costs about a
// quarter of a group's visit, measured below in solve_set_dense's comment).
#ifndef DENSE_KEEP
#define DENSE_KEEP 3
#endif
constexpr int DENSE_KEEP_LANES = DENSE_KEEP;

// WideGroup from `on` to its end is rows of four doubles, [row][lane]
constexpr std::size_t ROW0 = offsetof(WideGroup, on);
constexpr std::size_t N_ROWS = (sizeof(WideGroup) - ROW0) / (4 * sizeof(double));
static_assert(ROW0 % 32 == 0 && (sizeof(WideGroup) - ROW0) % 32 == 0, "WideGroup rows");
constexpr std::size_t ROW_LN = (offsetof(WideGroup, ln) - ROW0) / 32;
constexpr std::size_t N_IMPULSE_ROWS = 12;  // ln, l1, l2: [4][4] each, contiguous
static_assert(offsetof(WideGroup, l2) + sizeof(WideGroup::l2) ==
                  offsetof(WideGroup, ln) + N_IMPULSE_ROWS * 32, "ln, l1, l2 contiguous");

inline double* rows(WideGroup& g) { return reinterpret_cast<double*>(reinterpret_cast<char*>(&g) + ROW0); }
inline const double* rows(const WideGroup& g) {
    return reinterpret_cast<const double*>(reinterpret_cast<const char*>(&g) + ROW0);
}

long long g_stat_groups = 0, g_stat_lanes = 0, g_stat_dense = 0, g_stat_moved = 0;
struct StatPrint {
    ~StatPrint() {
        if (std::getenv("RBLOG_DENSE_STATS"))
            std::fprintf(stderr, "tail: group visits %lld (in place), lanes %lld, dense groups %lld, moved lanes %lld\n",
                         g_stat_groups, g_stat_lanes, g_stat_dense, g_stat_moved);
    }
} g_stat_print;

}  // namespace

void solve_set_dense(SolverLanes& lanes, i64 g0, i64 g1, const LaneCtx& cx, double* change,
                     i64* visits) {
    WideGroup* g = lanes.groups.data();
    if (cx.it <= cx.min_iter || std::strcmp(solver_kernel(), "scalar") == 0) {
        solve_groups_wide(g, g0, g1, cx, change, visits);
        return;
    }
    std::vector<i64>& src = lanes.dense_src;
    src.clear();
    const i64 prev = cx.it - 1;
    for (i64 q = g0; q < g1; ++q) {
        const WideGroup& gr = g[q];
        int v = 0;
        bool vis[4];
        for (int j = 0; j < 4; ++j) {
            vis[j] = gr.on[j] != 0.0 && !(cx.hot[gr.a[j]] < prev && cx.hot[gr.b[j]] < prev);
            v += vis[j];
        }
        if (v == 0) continue;
        if (v >= DENSE_KEEP_LANES) {
            g_stat_groups += 1;
            g_stat_lanes += v;
            solve_groups_wide(g, q, q + 1, cx, change, visits);
            continue;
        }
        for (int j = 0; j < 4; ++j)
            if (vis[j]) src.push_back(q * 4 + j);
    }
    const i64 n_src = (i64)src.size();
    if (n_src == 0) return;
    const i64 n_dense = (n_src + 3) / 4;
    if ((i64)lanes.dense.size() < n_dense) lanes.dense.resize(n_dense);
    WideGroup* d = lanes.dense.data();
    g_stat_dense += n_dense;
    g_stat_moved += n_src;
    const i64 dummy = cx.dummy;
    for (i64 k = 0; k < n_dense; ++k) {
        WideGroup& dg = d[k];
        dg.n_pts = 0;
        double* dr = rows(dg);
        for (int j = 0; j < 4; ++j) {
            i64 t = 4 * k + j;
            if (t >= n_src) {
                dg.m[j] = -1;
                dg.a[j] = dummy;
                dg.b[j] = dummy;
                for (std::size_t r = 0; r < N_ROWS; ++r) dr[4 * r + j] = 0.0;
                continue;
            }
            const WideGroup& sg = g[src[t] / 4];
            const int sj = (int)(src[t] % 4);
            dg.m[j] = sg.m[sj];
            dg.a[j] = sg.a[sj];
            dg.b[j] = sg.b[sj];
            if ((i64)sg.cnt[sj] > dg.n_pts) dg.n_pts = (i64)sg.cnt[sj];
            const double* sr = rows(sg);
            for (std::size_t r = 0; r < N_ROWS; ++r) dr[4 * r + j] = sr[4 * r + sj];
        }
    }
    solve_groups_wide(d, 0, n_dense, cx, change, visits);
    for (i64 t = 0; t < n_src; ++t) {
        double* sr = rows(g[src[t] / 4]);
        const int sj = (int)(src[t] % 4);
        const double* dr = rows(d[t / 4]);
        const int j = (int)(t % 4);
        for (std::size_t r = ROW_LN; r < ROW_LN + N_IMPULSE_ROWS; ++r) sr[4 * r + sj] = dr[4 * r + j];
    }
}

void pack_lanes(V2<i64> mi, V2<double> mf, V2<double> pf, const ConstraintGraph& g, V1<double> bm,
                V2<double> bI, V1<i64> degree, double inv_h, double sor, SolverLanes& lanes) {
    i64 n_sets = g.n_sets();
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
                i64 m = g.order[k];
                i64 ia = mi(m, MI_A), ib = mi(m, MI_B);
                i64 start = mi(m, MI_START), cnt = mi(m, MI_COUNT);
                gr.m[j] = m;
                gr.a[j] = ia;
                gr.b[j] = ib;
                if (cnt > gr.n_pts) gr.n_pts = cnt;
                double ma = bm[ia], mb = bm[ib];
                gr.on[j] = 1.0;
                gr.cnt[j] = (double)cnt;
                gr.luok[j] = mf(m, MF_LUOK);
                gr.om[j] = ((ma > 0.0 && degree[ia] > 1) || (mb > 0.0 && degree[ib] > 1)) ? sor : 1.0;
                gr.mu[j] = mf(m, MF_MU);
                gr.ma[j] = ma;
                gr.mb[j] = mb;
                for (int c = 0; c < 6; ++c) {
                    gr.a6[c][j] = bI(ia, c);
                    gr.b6[c][j] = bI(ib, c);
                }
                for (int c = 0; c < 3; ++c) {
                    gr.n[c][j] = mf(m, MF_N + c);
                    gr.t1[c][j] = mf(m, MF_T1 + c);
                    gr.t2[c][j] = mf(m, MF_T2 + c);
                }
                for (int c = 0; c < 16; ++c) gr.lu[c][j] = mf(m, MF_LU + c);
                for (int c = 0; c < 4; ++c) gr.piv[c][j] = mf(m, MF_PIV + c);
                for (i64 i = 0; i < cnt; ++i) {
                    const double* q_ = pf.row(start + i);
                    for (int c = 0; c < 3; ++c) {
                        gr.ra[i][c][j] = q_[PF_RA + c];
                        gr.rb[i][c][j] = q_[PF_RB + c];
                        gr.tk[i][c][j] = q_[PF_TK + c];
                    }
                    double sep = q_[PF_S];
                    // speculative: the gap may close within the step, not more
                    gr.target[i][j] = sep > 0.0 ? -sep * inv_h : 0.0;
                    gr.nmass[i][j] = q_[PF_NMASS];
                    gr.ln[i][j] = q_[PF_LN];
                    gr.l1[i][j] = q_[PF_L1];
                    gr.l2[i][j] = q_[PF_L2];
                }
            }
        }
    }
}

void unpack_lanes(V2<i64> mi, V2<double> pf, const SolverLanes& lanes) {
    i64 n_groups = lanes.set_group.empty() ? 0 : lanes.set_group.back();
    for (i64 q = 0; q < n_groups; ++q) {
        const WideGroup& gr = lanes.groups[q];
        for (int j = 0; j < 4; ++j) {
            i64 m = gr.m[j];
            if (m < 0) continue;
            i64 start = mi(m, MI_START), cnt = mi(m, MI_COUNT);
            for (i64 i = 0; i < cnt; ++i) {
                double* q_ = pf.row(start + i);
                q_[PF_LN] = gr.ln[i][j];
                q_[PF_L1] = gr.l1[i][j];
                q_[PF_L2] = gr.l2[i][j];
            }
        }
    }
}

}  // namespace rb
