// Per-stage timing of the contact step (rblog/engine/profile.py, as Box2D's b2Profile).
//
// A stage is timed with the CPU's cycle counter (rdtsc on x86-64, what numba's
// llvm.readcyclecounter read; a steady clock in nanoseconds elsewhere). profile.py measures the
// counter's rate once against time.perf_counter (_core.ticks). The step reads the counter only
// when its profile array is not empty, so an unprofiled run pays one branch per stage.
//
// The stage indices mirror profile.py's P_* (their home; profile.py checks N_PROF against
// _core.N_PROF at import).
#pragma once

#include <chrono>
#include <cstdint>

#if defined(__x86_64__) || defined(_M_X64)
#include <x86intrin.h>
#endif

#include "common/array.hpp"

namespace rb {

enum ProfileStage : int {
    P_KICK = 0, P_BROADPHASE, P_WAKE, P_COLLIDE, P_COLOUR, P_SOLVE, P_RELAX, P_INTEGRATE, P_RESTITUTION,
    P_PROJECT, P_SLEEP, P_SAMPLE, N_PROF
};

// The cycle counter (int64 ticks).
inline i64 ticks() {
#if defined(__x86_64__) || defined(_M_X64)
    return static_cast<i64>(__rdtsc());
#else
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
#endif
}

// Add the ticks since t0 to stage k of the profile; returns now.
inline i64 lap(V1<i64> prof, int k, i64 t0) {
    i64 t = ticks();
    prof[k] += t - t0;
    return t;
}

}  // namespace rb
