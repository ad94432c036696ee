// The Coulomb-cone friction update of one contact point (contact_solver.cpp's velocity solve and
// anchor pass, soft_step.cpp's soft step); contact_lanes.inl has the same formulas lane-wise.
#pragma once

#include <cmath>

#include "common/array.hpp"

namespace rb {

// Accumulated friction impulse (t1, t2) after one Gauss-Seidel update of a point.
//
// Sticking: the impulse that zeroes the slip, lambda = o - K^-1 vt. When that leaves the Coulomb
// disc |lambda| <= fmax, the point slides and the impulse is the *maximum-dissipation* one: the
// minimiser of the kinetic energy 1/2 (lambda - c)^T K (lambda - c) on the circle |lambda| = fmax,
// lambda = (K + g I)^-1 K c with g >= 0 found by Newton on 1/|lambda(g)| = 1/fmax
// (More-Sorensen's secular equation). The slip after the impulse is then -g lambda: friction
// opposes the sliding velocity exactly, which a radial projection of the unconstrained impulse
// does not do when K couples the two tangents (off-centre points).
inline void friction_impulse(double k11, double k12, double k22, double o1, double o2, double vt1,
                             double vt2, double fmax, i64 newton_iters, double newton_tol,
                             double& out1, double& out2) {
    double det0 = k11 * k22 - k12 * k12;
    if (det0 <= 0.0 || fmax <= 0.0) {
        out1 = 0.0;
        out2 = 0.0;
        return;
    }
    // K c = K o - vt  (c: the sticking impulse)
    double kc1 = k11 * o1 + k12 * o2 - vt1;
    double kc2 = k12 * o1 + k22 * o2 - vt2;
    double g = 0.0;
    double l1 = (k22 * kc1 - k12 * kc2) / det0;
    double l2 = (k11 * kc2 - k12 * kc1) / det0;
    double nl = std::sqrt(l1 * l1 + l2 * l2);
    if (nl <= fmax) {
        out1 = l1;
        out2 = l2;
        return;
    }
    for (i64 it = 0; it < newton_iters; ++it) {
        double a = k11 + g;
        double d = k22 + g;
        double det = a * d - k12 * k12;
        l1 = (d * kc1 - k12 * kc2) / det;
        l2 = (a * kc2 - k12 * kc1) / det;
        nl = std::sqrt(l1 * l1 + l2 * l2);
        if (nl <= fmax * (1.0 + newton_tol)) break;
        double m1 = (d * l1 - k12 * l2) / det;
        double m2 = (a * l2 - k12 * l1) / det;
        // f(g) = 1/fmax - 1/|l|,  f'(g) = -(l . (K + g I)^-1 l) / |l|^3
        double f = 1.0 / fmax - 1.0 / nl;
        double fp = -(l1 * m1 + l2 * m2) / (nl * nl * nl);
        g -= f / fp;
    }
    double sc = fmax / nl;
    out1 = l1 * sc;
    out2 = l2 * sc;
}

}  // namespace rb
