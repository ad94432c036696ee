// Writing a collider's output rows (narrowphase.cpp's conventions: normal from b into a, one row
// per point: its world position, gap, feature id), for every collider file: a point type is any
// struct with x, y, z (capsule.cpp's V, convex::Vec).
#pragma once

#include <cmath>

#include "engine/collision.hpp"
#include "engine/manifold.hpp"

namespace rb {

// Row k of a manifold: point p (world, m), gap s (m, < 0 penetration), feature id f.
template <class P>
inline void put(Pts pts, double* sep, i64* fid, i64 k, const P& p, double s, i64 f) {
    pts[k][0] = p.x;
    pts[k][1] = p.y;
    pts[k][2] = p.z;
    sep[k] = s;
    fid[k] = f;
}
// The manifold's unit normal n (world, from b into a) into nrm[0:3].
template <class P>
inline void put_normal(double* nrm, const P& n) {
    nrm[0] = n.x;
    nrm[1] = n.y;
    nrm[2] = n.z;
}

// The gaps reduce_manifold compares, rounded to this (the true gaps kept): a level face's points
// are equally deep to round-off, and which four it keeps must not change from step to step
// (warm starting).
constexpr double GAP_QUANTUM_M = 1e-9;

// reduce_manifold over P[0:count) (world, m) in the given order, with gaps S rounded to
// GAP_QUANTUM_M and every touching point's (within the touch band of the deepest) set to the
// deepest's: the first point kept is the first touching one in that order, not whichever the
// rocking of a face at rest makes nanometres deeper this step (the same four from step to step).
// ids[0:n) are the kept points' indices into P; returns n. N bounds count.
template <i64 N>
inline i64 reduce_quantized(const double* nrm, const double (*P)[3], const double* S, i64 count,
                            i64* ids) {
    double Q[N], P2[N][3];
    double lo = INFINITY;
    for (i64 k = 0; k < count; ++k) lo = std::fmin(lo, S[k]);
    const double touch = lo + collision_constants().manifold_touch_band_m;
    const double lo_q = std::round(lo / GAP_QUANTUM_M) * GAP_QUANTUM_M;
    for (i64 k = 0; k < count; ++k) {
        Q[k] = S[k] <= touch ? lo_q : std::round(S[k] / GAP_QUANTUM_M) * GAP_QUANTUM_M;
        ids[k] = k;
        for (int c = 0; c < 3; ++c) P2[k][c] = P[k][c];
    }
    return reduce_manifold(nrm, P2, Q, ids, count);
}

}  // namespace rb
