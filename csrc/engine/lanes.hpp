// Two bodies in the two lanes of a 128-bit vector (GCC/Clang vector extensions: SSE2 on x86-64,
// NEON on aarch64). Every lane does exactly the scalar code's operations in the scalar code's
// order (IEEE add, sub, mul, div and sqrt are lane-wise the same roundings; no fused multiply-add,
// -ffp-contract=off), so a body's result is bitwise the one of the scalar kernel; only the
// latency of the two bodies' dependency chains overlaps. (One exception, of no consequence: the
// NaNs of a body whose state has gone bad may differ in their sign bit, which IEEE leaves open and
// the compiler may change by rewriting (-a) * b as -(a * b); the run stops at that body's bad
// step and keeps only the samples before it.) Used by the free kernel's sparse path (free.cpp):
// seed, seed-quat, splitting and rk4 (sin and cos called per lane). free.cpp built with
// -DRB_FREE_NO_LANES runs the scalar path only, to compare the two.
#pragma once

#include <cmath>

namespace rb {

typedef double d2 __attribute__((vector_size(16)));
typedef long long m2 __attribute__((vector_size(16)));  // lane masks (0 or -1)

inline d2 splat(double v) { return d2{v, v}; }
inline d2 vsqrt(d2 a) { return d2{std::sqrt(a[0]), std::sqrt(a[1])}; }
inline d2 vabs(d2 a) { return d2{std::fabs(a[0]), std::fabs(a[1])}; }
// Python's max(a, b) lane-wise: a unless b > a (rotation.hpp py_max)
inline d2 vpymax(d2 a, d2 b) { return b > a ? b : a; }
inline bool any(m2 m) { return (m[0] | m[1]) != 0; }
inline bool all_set(m2 m) { return (m[0] & m[1]) != 0; }  // both lanes set

}  // namespace rb
