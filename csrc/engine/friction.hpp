// The Coulomb-cone friction update of a contact point: one template for one point
// (contact_solver.cpp's anchor pass, soft_step.cpp's soft step) and for four in SIMD lanes
// (contact_lanes.inl's velocity solve).
#pragma once

#include <cmath>

#include "common/array.hpp"
#include "engine/constraint_row.hpp"

namespace rb {

// Accumulated friction impulse (t1, t2) after one Gauss-Seidel update of a point, in the lanes
// of T where `on` (Lw: the lanes' traits, ScalarLane or contact_lanes.inl's W<d4>; the
// others come out as if on, their values unused).
//
// Sticking: the impulse that zeroes the slip, lambda = o - K^-1 vt. When that leaves the Coulomb
// disc |lambda| <= fmax, the point slides and the impulse is the *maximum-dissipation* one: the
// minimiser of the kinetic energy 1/2 (lambda - c)^T K (lambda - c) on the circle |lambda| = fmax,
// lambda = (K + g I)^-1 K c with g >= 0 found by Newton on 1/|lambda(g)| = 1/fmax
// (More-Sorensen's secular equation). The slip after the impulse is then -g lambda: friction
// opposes the sliding velocity exactly, which a radial projection of the unconstrained impulse
// does not do when K couples the two tangents (off-centre points). A singular K or fmax <= 0
// gives zero. Lane-wise, each `if` on a value is a select and the Newton loop runs while some
// lane has not met its bound (a lane that has keeps its values).
//
// friction_update_k takes the point's constants of the step from the caller: det0 = k11 k22 -
// k12^2 (the tangent block's determinant, by the same operations) and tol1 = 1 + newton_tol, so
// that the velocity solve computes them once a step instead of once a sweep (same bits).
template <class T, class Lw>
inline void friction_update_k(typename Lw::M on, const T& k11, const T& k12, const T& k22,
                              const T& det0, const T& o1, const T& o2, const T& vt1, const T& vt2,
                              const T& fmax, i64 newton_iters, const T& tol1, T& out1, T& out2) {
    typedef typename Lw::M M;
    const T zero = Lw::splat(0.0);
    M none = Lw::mor(det0 <= zero, fmax <= zero);
    // K c = K o - vt  (c: the sticking impulse)
    T kc1 = k11 * o1 + k12 * o2 - vt1;
    T kc2 = k12 * o1 + k22 * o2 - vt2;
    T g = zero;
    T l1 = (k22 * kc1 - k12 * kc2) / det0;
    T l2 = (k11 * kc2 - k12 * kc1) / det0;
    T nl = Lw::vsqrt(l1 * l1 + l2 * l2);
    M inside = nl <= fmax;
    M act = Lw::mand(on, Lw::mnot(Lw::mor(none, inside)));
    const T one = Lw::splat(1.0);
    const T bound = fmax * tol1;
    T inv_fmax = zero;  // (f below: constant over the Newton steps)
    if (Lw::any(act)) inv_fmax = one / fmax;
    for (i64 it = 0; it < newton_iters && Lw::any(act); ++it) {
        T a = k11 + g;
        T d = k22 + g;
        T det = a * d - k12 * k12;
        T n1 = (d * kc1 - k12 * kc2) / det;
        T n2 = (a * kc2 - k12 * kc1) / det;
        T nn = Lw::vsqrt(n1 * n1 + n2 * n2);
        l1 = Lw::sel(act, n1, l1);
        l2 = Lw::sel(act, n2, l2);
        nl = Lw::sel(act, nn, nl);
        act = Lw::mand(act, Lw::mnot(nn <= bound));
        // (every lane within its bound: the step below would change no lane's g, and the loop
        // would stop at its test; leaving now gives the same bits)
        if (!Lw::any(act)) break;
        T m1 = (d * n1 - k12 * n2) / det;
        T m2 = (a * n2 - k12 * n1) / det;
        // f(g) = 1/fmax - 1/|l|,  f'(g) = -(l . (K + g I)^-1 l) / |l|^3
        T f = inv_fmax - one / nn;
        T fp = -(n1 * m1 + n2 * m2) / (nn * nn * nn);
        g = Lw::sel(act, g - f / fp, g);
    }
    T sc = fmax / nl;
    T s1 = l1 * sc, s2 = l2 * sc;
    out1 = Lw::sel(none, zero, Lw::sel(inside, l1, s1));
    out2 = Lw::sel(none, zero, Lw::sel(inside, l2, s2));
}

template <class T, class Lw>
inline void friction_update(typename Lw::M on, const T& k11, const T& k12, const T& k22,
                            const T& o1, const T& o2, const T& vt1, const T& vt2, const T& fmax,
                            i64 newton_iters, double newton_tol, T& out1, T& out2) {
    const T det0 = k11 * k22 - k12 * k12;
    friction_update_k<T, Lw>(on, k11, k12, k22, det0, o1, o2, vt1, vt2, fmax, newton_iters,
                             Lw::splat(1.0 + newton_tol), out1, out2);
}

// friction_update of one point.
inline void friction_impulse(double k11, double k12, double k22, double o1, double o2, double vt1,
                             double vt2, double fmax, i64 newton_iters, double newton_tol,
                             double& out1, double& out2) {
    friction_update<double, ScalarLane>(true, k11, k12, k22, o1, o2, vt1, vt2, fmax, newton_iters,
                                        newton_tol, out1, out2);
}

}  // namespace rb
