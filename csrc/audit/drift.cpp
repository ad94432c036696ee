// The drift analyzer's row pass (rblog/analyze/drift.py): rigidity of the logged rotation.
#include <algorithm>
#include <cmath>

#include "audit/audit.hpp"

namespace rb {
namespace audit {

// Per sample and body (rot (T, N, 3, 3), quat (T, N, 4)): out[0] ||R^T R - I||_F, out[1]
// |det R - 1|, out[2] ||q| - 1|, out[3] the largest relative change of a body-fixed distance,
// max(sigma_max - 1, 1 - sigma_min) with sigma the singular values of R (sigma^2 = eigenvalues of
// G = R^T R, closed form for a symmetric 3x3 matrix: Smith's trigonometric method on E = G - I,
// and sqrt(1 + l) - 1 written without cancellation).
void rigidity(V4<double> rot, V3<double> quat, V3<double> out) {
    const i64 t_n = rot.n0, n = rot.n1;
    const double pi = 3.141592653589793;  // math.pi
    const i64 plane = t_n * n;  // out[k] is the (T, N) plane at out.p + k * T * N
    for (i64 t = 0; t < t_n; ++t) {
        // Row pointers, restrict-qualified (the outputs never alias the inputs): the inputs are
        // loaded once per body instead of again after each store.
        const double* __restrict__ rrow = &rot(t, 0, 0, 0);
        const double* __restrict__ qrow = &quat(t, 0, 0);
        double* __restrict__ o0 = out.p + t * n;
        double* __restrict__ o1 = o0 + plane;
        double* __restrict__ o2 = o1 + plane;
        double* __restrict__ o3 = o2 + plane;
        for (i64 b = 0; b < n; ++b) {
            const double* __restrict__ r = rrow + 9 * b;  // r[3 i + j] = R_ij
            const double e00 = r[0] * r[0] + r[3] * r[3] + r[6] * r[6] - 1.0;
            const double e11 = r[1] * r[1] + r[4] * r[4] + r[7] * r[7] - 1.0;
            const double e22 = r[2] * r[2] + r[5] * r[5] + r[8] * r[8] - 1.0;
            const double e01 = r[0] * r[1] + r[3] * r[4] + r[6] * r[7];
            const double e02 = r[0] * r[2] + r[3] * r[5] + r[6] * r[8];
            const double e12 = r[1] * r[2] + r[4] * r[5] + r[7] * r[8];
            const double off = e01 * e01 + e02 * e02 + e12 * e12;
            o0[b] = std::sqrt(e00 * e00 + e11 * e11 + e22 * e22 + 2.0 * off);
            const double det = (r[0] * (r[4] * r[8] - r[5] * r[7]) -
                                r[1] * (r[3] * r[8] - r[5] * r[6]) +
                                r[2] * (r[3] * r[7] - r[4] * r[6]));
            o1[b] = std::fabs(det - 1.0);
            const double* __restrict__ q = qrow + 4 * b;
            o2[b] =
                std::fabs(std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]) - 1.0);
            // eigenvalues of E = G - I (Smith's trigonometric method)
            const double qm = (e00 + e11 + e22) / 3.0;
            const double a00 = e00 - qm, a11 = e11 - qm, a22 = e22 - qm;
            const double p = std::sqrt((a00 * a00 + a11 * a11 + a22 * a22 + 2.0 * off) / 6.0);
            double lmax, lmin;
            if (p > 0.0) {
                const double detb = (a00 * (a11 * a22 - e12 * e12) - e01 * (e01 * a22 - e12 * e02) +
                                     e02 * (e01 * e12 - a11 * e02));
                double c = detb / (2.0 * p * p * p);
                c = std::min(1.0, std::max(-1.0, c));
                const double phi = std::acos(c) / 3.0;
                lmax = qm + 2.0 * p * std::cos(phi);
                lmin = qm + 2.0 * p * std::cos(phi + 2.0 * pi / 3.0);
            } else {
                lmax = qm;
                lmin = qm;
            }
            // sqrt(1 + l) - 1 without cancellation
            const double up = lmax > -1.0 ? lmax / (1.0 + std::sqrt(1.0 + lmax)) : -1.0;
            const double dn = lmin > -1.0 ? lmin / (1.0 + std::sqrt(1.0 + lmin)) : -1.0;
            o3[b] = std::max(std::fabs(up), std::fabs(dn));
        }
    }
}

}  // namespace audit
}  // namespace rb
