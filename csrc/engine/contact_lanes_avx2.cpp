// The wide kernel of the velocity solve built for AVX2 (CMakeLists.txt compiles this file alone
// with -mavx2; no FMA: -mfma is not given and -ffp-contract=off holds). contact_lanes.cpp calls it
// only when the processor has AVX2 (__builtin_cpu_supports). The kernel's template sits in an
// anonymous namespace here, so none of its AVX2 code can stand in for the portable build's.
#include <cmath>
#include <cstring>

#include "engine/contact_lanes.hpp"
#include "engine/friction.hpp"

namespace rb {

namespace {
#include "engine/contact_lanes.inl"
}  // namespace

void solve_groups_avx2(WideGroup* g, i64 g0, i64 g1, const LaneCtx& cx, double* change,
                       i64* visits) {
    for (i64 k = g0; k < g1; ++k) {
        switch (g[k].n_pts) {
            case 1: solve_group<d4, 1>(g[k], 0, cx, change, visits); break;
            case 2: solve_group<d4, 2>(g[k], 0, cx, change, visits); break;
            case 3: solve_group<d4, 3>(g[k], 0, cx, change, visits); break;
            case 4: solve_group<d4, 4>(g[k], 0, cx, change, visits); break;
            default: solve_group<d4>(g[k], 0, cx, change, visits); break;
        }
    }
}

}  // namespace rb
