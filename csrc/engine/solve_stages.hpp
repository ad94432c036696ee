// The velocity solve's task layer: its sweeps over the sets of the constraint graph's colouring
// (constraint_graph.hpp), on the engine's task pool or on the calling thread, and the choice
// between the two (solve_stages.cpp). The solve's math, what a visit of a set's groups does, is
// contact_solver.cpp's and contact_lanes.inl's; this file only schedules it.
#pragma once

#include <cstddef>  // size_t, which common/array.hpp uses

#include <functional>

#include "common/array.hpp"

namespace rb {

// The sets of one solve: set s holds the groups [set_group[s], set_group[s + 1]) (set 0 the
// overflow set, visited one manifold after another; then the colours, whose groups share no
// dynamic body); at least min_iter sweeps, then until a sweep's largest velocity change is at
// most tol (m/s), at most max_iter.
struct SweepPlan {
    i64 n_sets;
    const i64* set_group;  // (n_sets + 1,)
    i64 min_iter, max_iter;
    double tol;
};

struct SweepCount {
    i64 sweeps = 0;  // sweeps run
    i64 visits = 0;  // manifold visits, summed
};

// visit(sweep, s, g0, g1, change, visits): visit groups [g0, g1) of set s in sweep `sweep` (from
// 1), raising *change to the largest velocity change it makes and adding its manifold visits to
// *visits. Two visits of one set's groups must touch disjoint bodies: then the results are the
// same whichever thread runs which.
using VisitFn = std::function<void(i64, i64, i64, i64, double*, i64*)>;

// The sweeps of one solve, threaded when the pool has threads, the colours hold
// MIN_THREADED_GROUPS groups or more and the measured choice says so, else on this thread.
SweepCount run_sweeps(const SweepPlan& p, const VisitFn& visit);

// RBLOG_THREAD_HANDOVER's switch (_core.set_thread_fallback): false keeps every eligible solve
// threaded
void set_thread_fallback(bool on);

}  // namespace rb
