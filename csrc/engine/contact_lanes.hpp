// The velocity solve over the colours of the constraint graph, four manifolds at a time (Box2D
// v3's contact_solver.c: b2ContactConstraintSIMD, b2GatherBodies / b2ScatterBodies).
//
// After warm starting, each set of the colouring (constraint_graph.hpp: the overflow set, then
// the colours; a colour's manifolds reordered by the last solve's hot marks, so that the lanes
// a late sweep visits share groups) is packed into groups of four manifolds, struct-of-arrays
// over the four lanes (WideGroup): the per-step constants a sweep reads (normal and tangents, anchors, effective
// masses, LU factors of the normal block, the speculative targets, the bodies' inverse masses and
// world inverse inertias) and the accumulated impulses. A sweep then reads each group with
// vector loads and gathers only the eight body velocities; the impulses go back to the point
// rows (pf) once, after the solve.
//
// Three kernels solve a group, all made from one template (contact_lanes.inl), so that every
// lane does the scalar code's operations in the scalar code's order (IEEE add, sub, mul, div and
// sqrt round alike in every lane and in scalar code; no fused multiply-add, -ffp-contract=off;
// branches become selects that pick one of two values, never a different operation): the
// scalar kernel solves the four lanes one after another; the wide kernel all four at once, in
// 256-bit registers with AVX2 (contact_lanes_avx2.cpp, compiled with -mavx2, called only when
// the processor has AVX2) or, forced (PATH_SSE2), in pairs of 128-bit ones. Without AVX2 the
// scalar kernel runs: GCC's lowering of the 4-wide vector types to SSE2 pairs measured 2.2x
// slower than the scalar kernel on the 500-box pile (6.5 s against 2.9 s of CPU for 300 steps;
// AVX2: 2.0 s), so that path is only a check that the portable vector code gives the same bits.
// A lane's result is bitwise the same in all three; tests/engine/contact/test_solver_lanes.py compares logs with the scalar path
// forced (_core.set_solver_path, RBLOG_SOLVER_PATH=scalar).
//
// A lane with fewer points than the group's most, or whose manifold a sweep skips (it touches no
// body that changed, see solve_velocities), computes what the others do and keeps none of it
// (select). The overflow set is solved by the scalar kernel, one manifold after another.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/array.hpp"
#include "engine/manifold.hpp"

namespace rb {

// Four manifolds of one colour, lane j = manifold m[j]. Point slots beyond a lane's count, and
// lanes beyond the colour's end (on = 0), hold zeros.
struct alignas(32) WideGroup {
    i64 m[4], a[4], b[4];  // manifold, solver rows of body a and b (row N: the static dummy)
    i64 n_pts;             // most points of any lane
    i64 pad_[3];
    double on[4];          // 1: the lane holds a manifold
    double cnt[4];         // its point count
    double luok[4];        // lu_ok
    double om[4];          // over-relaxation of the normal increments (sor or 1)
    double mu[4];
    double ma[4], mb[4];   // inverse masses
    double a6[6][4], b6[6][4];           // world inverse inertias (xx, yy, zz, xy, xz, yz)
    double n[3][4], t1[3][4], t2[3][4];  // normal (b into a) and tangents, world
    double lu[16][4], piv[4][4];         // lu, piv
    double ra[4][3][4], rb[4][3][4];     // [point][axis][lane] anchors
    double target[4][4];                 // speculative target gap velocity (0 or -s / h)
    double nmass[4][4];
    double tk[4][3][4];                  // k11, k12, k22
    double det[4][4];                    // k11 k22 - k12^2 (friction_update_k's det0)
    double ln[4][4], l1[4][4], l2[4][4]; // accumulated impulses
};

// A body's velocities during the solve: v and w (world) each padded to four doubles, so that a
// group reads or writes one body's three numbers with one 256-bit load or store (and four bodies'
// with four plus a 4x4 transpose).
struct alignas(32) BodyVel {
    double v[4];  // vx, vy, vz, 0
    double w[4];  // wx, wy, wz, 0
};

// The packed sets of one step: groups of set s are [set_group[s], set_group[s + 1]); vel (N+1,)
// the bodies' velocities while the sweeps run (copied from and back to the solver's bv, bw).
struct SolverLanes {
    std::vector<WideGroup> groups;
    std::vector<i64> set_group;
    std::vector<BodyVel> vel;
    std::vector<i64> order;  // the manifolds in lane order, set by set (pack_lanes)
    std::vector<uint64_t> keys;  // (pack_lanes' sort keys)
};

// Which kernel the wide sets use (set_solver_path): 0 the best the processor has (AVX2, else
// scalar), 1 scalar, 2 the 128-bit pairs.
enum SolverPath : int { PATH_AUTO = 0, PATH_SCALAR = 1, PATH_SSE2 = 2 };
void set_solver_path(int path);
int solver_path();             // as set
const char* solver_kernel();   // the kernel the wide sets run: "avx2", "sse2" or "scalar"

// What the kernels read besides a group: body velocities (SolverLanes::vel as doubles, 8 a
// body: v at 8 i, w at 8 i + 4) in place, the hot marks (N+1,), and the solve's parameters.
struct LaneCtx {
    double* vel;
    i64* hot;
    i64 dummy;  // the static dummy's row (N): never written
    i64 it, min_iter;
    double tol;
    i64 newton_iters;
    double newton_tol;
    double tol1;  // 1 + newton_tol
};

// Solve groups [g0, g1) once (one sweep's visit), the scalar kernel (lanes one after another) or
// the wide one; *change: the largest velocity change (max with what it held), *visits: manifolds
// visited (added to).
void solve_groups_scalar(WideGroup* g, i64 g0, i64 g1, const LaneCtx& cx, double* change,
                         i64* visits);
void solve_groups_wide(WideGroup* g, i64 g0, i64 g1, const LaneCtx& cx, double* change,
                       i64* visits);
// Pack the sets of g (the colouring of mi's active manifolds) into lanes.groups after the warm
// start: bm, bI the solver bodies, degree (N+1,) active manifolds per body (over-relaxation where
// a dynamic body has more than one), inv_h, sor as solve_velocities.
struct ConstraintGraph;
void pack_lanes(V1<ManifoldHead> mi, V1<Manifold> mf, V1<ContactPoint> pf,
                const ConstraintGraph& g, V1<double> bm,
                V2<double> bI, V1<i64> degree, V1<i64> last_hot, double inv_h, double sor,
                SolverLanes& lanes);
// The accumulated impulses back to the point rows (ln, l1, l2).
void unpack_lanes(V1<ManifoldHead> mi, V1<ContactPoint> pf, const SolverLanes& lanes);

// (the AVX2 build of solve_groups_wide, contact_lanes_avx2.cpp; call only with AVX2)
void solve_groups_avx2(WideGroup* g, i64 g0, i64 g1, const LaneCtx& cx, double* change,
                       i64* visits);

}  // namespace rb
