// Several bodies in the lanes of one vector (GCC/Clang vector extensions): d2, two bodies in 128
// bits (SSE2 on x86-64, NEON on aarch64), and d4, four bodies in 256 bits (AVX2, x86-64 only,
// chosen at run time: free_lanes below). Every lane does exactly the scalar code's operations in
// the scalar code's order (IEEE add, sub, mul, div and sqrt are lane-wise the same roundings; no
// fused multiply-add: -ffp-contract=off, and the AVX2 code is built for "avx2" without "fma"), so
// a body's result is bitwise the one of the scalar kernel whatever the width; only the latency of
// the bodies' dependency chains overlaps. (One exception, of no consequence: the NaNs of a body
// whose state has gone bad may differ in their sign bit, which IEEE leaves open and the compiler
// may change by rewriting (-a) * b as -(a * b); the run stops at that body's bad step and keeps
// only the samples before it.) Used by the free kernel's sparse path (free.cpp): the stages of
// integrators.hpp are templates over double and these vectors (sin, cos and the per-body branches
// of the small-angle series per lane), so one text serves both. free.cpp built with
// -DRB_FREE_NO_LANES runs the scalar path only, to compare the two; _core.set_free_lanes(2)
// forces the two-lane path on an AVX2 machine (tests/engine/test_threads.py compares them).
#pragma once

#include <cmath>

#if defined(__x86_64__) && defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wpsabi"  // d4 arguments of the AVX2 kernels (all inlined)
#endif

namespace rb {

typedef double d2 __attribute__((vector_size(16)));
typedef long long m2 __attribute__((vector_size(16)));  // lane masks (0 or -1)
typedef double d4 __attribute__((vector_size(32)));
typedef long long m4 __attribute__((vector_size(32)));

// lanes of a vector type, and its mask type (what a lane-wise comparison gives)
template <class V>
constexpr int lanes_of() { return static_cast<int>(sizeof(V) / sizeof(double)); }
template <class V>
using mask_of = decltype(V{} < V{});

// Lane l of a value (a vector's lane, or the double itself: one body is one lane), read and set.
template <class V>
inline double lane(const V& v, int l) { return v[l]; }
inline double lane(double v, int) { return v; }
inline bool lane(bool m, int) { return m; }
template <class V>
inline void set_lane(V& v, int l, double x) { v[l] = x; }
inline void set_lane(double& v, int, double x) { v = x; }

template <class V>
inline V splat_v(double v) {
    V r;
    for (int l = 0; l < lanes_of<V>(); ++l) set_lane(r, l, v);
    return r;
}
inline d2 splat(double v) { return splat_v<d2>(v); }

// f (a function of a double) lane by lane
template <class V, class F>
inline V per_lane(V a, F f) {
    V r;
    for (int l = 0; l < lanes_of<V>(); ++l) set_lane(r, l, f(lane(a, l)));
    return r;
}
template <class V>
inline V vsqrt(V a) { return per_lane(a, [](double x) { return std::sqrt(x); }); }
template <class V>
inline V vabs(V a) { return per_lane(a, [](double x) { return std::fabs(x); }); }
// sine and cosine lane by lane, of each lane in one loop (one sincos call a lane)
template <class V>
inline void vsincos(V a, V& s, V& c) {
    for (int l = 0; l < lanes_of<V>(); ++l) {
        const double x = lane(a, l);
        set_lane(s, l, std::sin(x));
        set_lane(c, l, std::cos(x));
    }
}
// one body (T = double, its mask bool): the same helpers, so a template serves both
inline double vsqrt(double a) { return std::sqrt(a); }
inline double vabs(double a) { return std::fabs(a); }
inline bool any(bool m) { return m; }
inline bool all_set(bool m) { return m; }
// a and not b, lane-wise; every lane set
inline bool and_not(bool a, bool b) { return a && !b; }
template <class M>
inline M and_not(M a, M b) { return a & ~b; }
template <class T>
inline mask_of<T> all_lanes() {
    const T z = T{};
    return z == z;
}
// Python's max(a, b) lane-wise: a unless b > a (rotation.hpp py_max)
template <class V>
inline V vpymax(V a, V b) { return b > a ? b : a; }
template <class M>
inline bool any(M m) {
    static_assert(sizeof(M) >= 16, "a lane mask (a bool goes to the overload above)");
    long long r = 0;
    for (int l = 0; l < static_cast<int>(sizeof(M) / sizeof(long long)); ++l) r |= m[l];
    return r != 0;
}
template <class M>
inline bool all_set(M m) {  // every lane set
    static_assert(sizeof(M) >= 16, "a lane mask (a bool goes to the overload above)");
    long long r = -1;
    for (int l = 0; l < static_cast<int>(sizeof(M) / sizeof(long long)); ++l) r &= m[l];
    return r != 0;
}

#if defined(__x86_64__) && defined(__GNUC__)
// the same from the lanes' sign bits (masks are 0 or -1) by movmskpd, the four-lane masks folded
// to two lanes first: a few instructions, inlined into the SSE2 and the AVX2 kernels alike
inline bool any(m2 m) { return __builtin_ia32_movmskpd((d2)m) != 0; }
inline bool all_set(m2 m) { return __builtin_ia32_movmskpd((d2)m) == 3; }
inline bool any(m4 m) {
    const m2 o = __builtin_shufflevector(m, m, 0, 1) | __builtin_shufflevector(m, m, 2, 3);
    return __builtin_ia32_movmskpd((d2)o) != 0;
}
inline bool all_set(m4 m) {
    const m2 o = __builtin_shufflevector(m, m, 0, 1) & __builtin_shufflevector(m, m, 2, 3);
    return __builtin_ia32_movmskpd((d2)o) == 3;
}
#endif

// The widest lane count this process uses for the free kernel's sparse path: 4 when the CPU has
// AVX2 (x86-64), else 2; set_free_lanes changes it (2, or 4 when supported). free.cpp.
int free_lanes();
void set_free_lanes(int lanes);

}  // namespace rb
