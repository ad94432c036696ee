// The consistency analyzer's row passes (rblog/analyze/consistency.py): whether the logged
// channels agree with each other, per body and sample.
//
// * kinematic_rel: the rotation vector of R(k+1) R(k)^T over dt (the mean angular velocity over
//   the interval, world frame) against the logged world angular velocity. An integrator's mean
//   rate over an interval lies between the rates at its ends (explicit, semi-implicit, midpoint
//   alike) when nothing kicks the body inside it, so the mismatch is the distance d of the mean
//   rate from the segment [w(k), w(k+1)]. An engine may turn a body by up to corr (rad) per
//   interval without a velocity (split impulse, projection): that much of d dt is allowed on
//   top, rel = max(d dt - corr, 0) / (scale dt) with scale = max(|mean w|, |rate|), and an
//   interval turning less than corr cannot tell such a correction from a fault (unusable).
// * linear_rel: the same for (x(k+1) - x(k)) / dt against [v(k), v(k+1)], with an allowance
//   acc dt for a constant acceleration.
// * pointwise: per sample, ||R(q/|q|) - R||_F, ||R^T R - I||_F, |p - m v|, |p| and
//   |w - R diag(1/I) R^T L| / (|w| + |L| / I_min).
#include <algorithm>
#include <cmath>

#include "audit/audit.hpp"

namespace rb {
namespace audit {

// rel[k, n] (T-1, N): distance of the rotation vector of R(k+1) R(k)^T over dt from the segment
// [w(k), w(k+1)], less the correction allowance corr / dt, relative to max(|mean w|, |rate|);
// NaN where the interval is not usable (turns less than max(min_angle, corr) or more than
// 1.5 rad, or w jumps by more than smooth_frac of it).
void kinematic_rel(V4<double> rot, V3<double> omega, V1<double> dts, double min_angle,
                   double smooth_frac, double corr, V2<double> rel) {
    const i64 n_k = rel.n0, n_b = rel.n1;
    for (i64 k = 0; k < n_k; ++k) {
        const double h = dts[k];
        for (i64 b = 0; b < n_b; ++b) {
            double tx, ty, tz;
            interval_rotvec(rot, k + 1, k, b, tx, ty, tz);
            double rx = tx / h, ry = ty / h, rz = tz / h;
            const double* w0 = &omega(k, b, 0);
            const double* w1 = &omega(k + 1, b, 0);
            double ux = w1[0] - w0[0], uy = w1[1] - w0[1], uz = w1[2] - w0[2];
            double mx = 0.5 * (w0[0] + w1[0]), my = 0.5 * (w0[1] + w1[1]),
                   mz = 0.5 * (w0[2] + w1[2]);
            double scale = std::max(std::sqrt(mx * mx + my * my + mz * mz),
                                    std::sqrt(rx * rx + ry * ry + rz * rz));
            double jump = std::sqrt(ux * ux + uy * uy + uz * uz);
            if (!(scale * h > std::max(min_angle, corr) && scale * h < 1.5 &&
                  jump <= smooth_frac * scale)) {
                rel(k, b) = std::nan("");
                continue;
            }
            double uu = ux * ux + uy * uy + uz * uz;
            double t = 0.0;
            if (uu > 0) {
                t = ((rx - w0[0]) * ux + (ry - w0[1]) * uy + (rz - w0[2]) * uz) / uu;
                t = std::min(1.0, std::max(0.0, t));
            }
            double ex = rx - (w0[0] + t * ux), ey = ry - (w0[1] + t * uy),
                   ez = rz - (w0[2] + t * uz);
            rel(k, b) = std::max(std::sqrt(ex * ex + ey * ey + ez * ez) - corr / h, 0.0) / scale;
        }
    }
}

// rel[k, n]: distance of (x(k+1) - x(k)) / dt from the segment [v(k), v(k+1)], relative to
// max(|mean v|, |rate|) + acc dt + corr / dt; NaN where not usable (moves less than min_move, or
// v jumps by more than smooth_frac of it plus acc dt).
void linear_rel(V3<double> pos, V3<double> vel, V1<double> dts, double min_move,
                double smooth_frac, V1<double> acc, double corr, V2<double> rel) {
    const i64 n_k = rel.n0, n_b = rel.n1;
    for (i64 k = 0; k < n_k; ++k) {
        const double h = dts[k];
        for (i64 b = 0; b < n_b; ++b) {
            const double* x0 = &pos(k, b, 0);
            const double* x1 = &pos(k + 1, b, 0);
            const double* v0 = &vel(k, b, 0);
            const double* v1 = &vel(k + 1, b, 0);
            double rx = (x1[0] - x0[0]) / h, ry = (x1[1] - x0[1]) / h, rz = (x1[2] - x0[2]) / h;
            double ux = v1[0] - v0[0], uy = v1[1] - v0[1], uz = v1[2] - v0[2];
            double mx = 0.5 * (v0[0] + v1[0]), my = 0.5 * (v0[1] + v1[1]),
                   mz = 0.5 * (v0[2] + v1[2]);
            double scale = std::max(std::sqrt(mx * mx + my * my + mz * mz),
                                    std::sqrt(rx * rx + ry * ry + rz * rz));
            double uu = ux * ux + uy * uy + uz * uz;
            if (!(scale * h > min_move && std::sqrt(uu) <= smooth_frac * scale + acc[b] * h)) {
                rel(k, b) = std::nan("");
                continue;
            }
            double t = 0.0;
            if (uu > 0) {
                t = ((rx - v0[0]) * ux + (ry - v0[1]) * uy + (rz - v0[2]) * uz) / uu;
                t = std::min(1.0, std::max(0.0, t));
            }
            double ex = rx - (v0[0] + t * ux), ey = ry - (v0[1] + t * uy),
                   ez = rz - (v0[2] + t * uz);
            rel(k, b) = std::sqrt(ex * ex + ey * ey + ez * ez) / (scale + acc[b] * h + corr / h);
        }
    }
}

// Per sample and body: ||R(q/|q|) - R||_F, ||R^T R - I||_F, |p - m v|, |p|,
// |w - R diag(1/I) R^T L| / (|w| + |L| / I_min) and that scale. quat (T, N, 4) wxyz.
void pointwise(V3<double> quat, V4<double> rot, V3<double> mom, V3<double> vel, V3<double> omega,
               V3<double> lw, V1<double> mass, V2<double> inertia, V2<double> err_qm,
               V2<double> ortho, V2<double> dp, V2<double> p_mag, V2<double> rel_l,
               V2<double> l_scale) {
    const i64 n_t = err_qm.n0, n_b = err_qm.n1;
    double rq[3][3];
    for (i64 k = 0; k < n_t; ++k) {
        // Output rows, restrict-qualified (they never alias the inputs): the inputs are loaded
        // once per body instead of again after each store.
        double* __restrict__ o_err = err_qm.row(k);
        double* __restrict__ o_ortho = ortho.row(k);
        double* __restrict__ o_dp = dp.row(k);
        double* __restrict__ o_pmag = p_mag.row(k);
        double* __restrict__ o_rel = rel_l.row(k);
        double* __restrict__ o_scale = l_scale.row(k);
        for (i64 b = 0; b < n_b; ++b) {
            const double* __restrict__ q = &quat(k, b, 0);
            double nq = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
            if (nq == 0.0) nq = 1.0;
            double w = q[0] / nq, x = q[1] / nq, y = q[2] / nq, z = q[3] / nq;
            rq[0][0] = 1 - 2 * (y * y + z * z);
            rq[0][1] = 2 * (x * y - w * z);
            rq[0][2] = 2 * (x * z + w * y);
            rq[1][0] = 2 * (x * y + w * z);
            rq[1][1] = 1 - 2 * (x * x + z * z);
            rq[1][2] = 2 * (y * z - w * x);
            rq[2][0] = 2 * (x * z - w * y);
            rq[2][1] = 2 * (y * z + w * x);
            rq[2][2] = 1 - 2 * (x * x + y * y);
            const double* __restrict__ r = &rot(k, b, 0, 0);  // r[3 i + j] = R_ij
            double e = 0.0;
            double g = 0.0;
            for (int i = 0; i < 3; ++i) {
                for (int j = 0; j < 3; ++j) {
                    double d = rq[i][j] - r[3 * i + j];
                    e += d * d;
                    double gij = r[i] * r[j] + r[3 + i] * r[3 + j] + r[6 + i] * r[6 + j];
                    if (i == j) gij -= 1.0;
                    g += gij * gij;
                }
            }
            o_err[b] = std::sqrt(e);
            o_ortho[b] = std::sqrt(g);
            const double m = mass[b];
            const double* __restrict__ p = &mom(k, b, 0);
            const double* __restrict__ v = &vel(k, b, 0);
            double a0 = p[0] - m * v[0], a1 = p[1] - m * v[1], a2 = p[2] - m * v[2];
            o_dp[b] = std::sqrt(a0 * a0 + a1 * a1 + a2 * a2);
            o_pmag[b] = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
            const double* __restrict__ l_ = &lw(k, b, 0);
            const double* __restrict__ om = &omega(k, b, 0);
            double b0 = (r[0] * l_[0] + r[3] * l_[1] + r[6] * l_[2]) / inertia(b, 0);
            double b1 = (r[1] * l_[0] + r[4] * l_[1] + r[7] * l_[2]) / inertia(b, 1);
            double b2 = (r[2] * l_[0] + r[5] * l_[1] + r[8] * l_[2]) / inertia(b, 2);
            double c0 = om[0] - (r[0] * b0 + r[1] * b1 + r[2] * b2);
            double c1 = om[1] - (r[3] * b0 + r[4] * b1 + r[5] * b2);
            double c2 = om[2] - (r[6] * b0 + r[7] * b1 + r[8] * b2);
            double imin = std::min(inertia(b, 0), std::min(inertia(b, 1), inertia(b, 2)));
            double sc = std::sqrt(om[0] * om[0] + om[1] * om[1] + om[2] * om[2]) +
                        std::sqrt(l_[0] * l_[0] + l_[1] * l_[1] + l_[2] * l_[2]) / imin;
            o_scale[b] = sc;
            o_rel[b] = std::sqrt(c0 * c0 + c1 * c1 + c2 * c2) / std::max(sc, 1e-300);
        }
    }
}

}  // namespace audit
}  // namespace rb
