// The exact flow of the torque-free rigid body: Jacobi elliptic functions for the body angular
// momentum, Carlson's elliptic integrals for the attitude (rblog/engine/exact.py: the same
// formulas in the same order; the derivation is in exact.cpp's header comment).
//
// The flow is evaluated from an anchor state (q_a, L_world) at the elapsed time t:
// flow_constants computes once what depends on the anchor only (a row of N_FLOW doubles, the FC_*
// columns below), flow_eval the rotation since the anchor at any t, q(t) = q_a (x) c(t).
// The per-step pieces (sncndn_landen, carlson_rj1, flow_eval) are inline here so that the exact
// integrators' kernel (free.cpp) evaluates the flow without a call.
#pragma once

#include <cmath>
#include <limits>

#include "common/array.hpp"
#include "engine/free_constants.hpp"

namespace rb {

constexpr double HALF_PI = 0.5 * 3.141592653589793;  // exact.py: 0.5 * math.pi

// Columns of a row of flow constants (mirrored from rblog/engine/exact.py, their home; the Python
// module checks at import that N_FLOW and FC_RJC agree). A steady rotation (FC_STEADY = 1) keeps
// the body-frame omega in FC_W0..FC_W2, |omega| in FC_WN and Lb in FC_B0..FC_B2.
constexpr int FC_STEADY = 0;
constexpr int FC_I1 = 1, FC_I2 = 2, FC_I3 = 3;  // the body axes of working axes 1', 2', 3'
constexpr int FC_W0 = 1, FC_W1 = 2, FC_W2 = 3, FC_WN = 4;
constexpr int FC_B0 = 5, FC_B1 = 6, FC_B2 = 7;
constexpr int FC_SGN3 = 4;   // sign of axis 3' against its body axis (general case)
constexpr int FC_K1 = 5;     // k1 (inverse moment of axis 1')
constexpr int FC_ELL = 6;    // l = |L|
constexpr int FC_D13 = 7;    // k1 - k3
constexpr int FC_M = 8, FC_M1 = 9;  // parameter m and 1 - m
constexpr int FC_LAM = 10;   // phase rate lam (1/s)
constexpr int FC_AMP1 = 11, FC_AMP2 = 12, FC_AMP3 = 13;  // amplitudes of L1, L2, L3
constexpr int FC_N = 14;     // n = (k1 - k2) / (k2 - k3)
constexpr int FC_SIGMA = 15, FC_S = 16;  // sign of L2's sn, sign of L3
constexpr int FC_SN0 = 17, FC_CN0 = 18, FC_DN0 = 19;  // sn, cn, dn at the anchor's phase u0
constexpr int FC_G0 = 20;    // G(am u0) at the anchor (reduced amplitude)
constexpr int FC_AW = 21, FC_AX = 22, FC_AY = 23, FC_AZ = 24;  // B0, unnormalized
constexpr int FC_RJC = 25;   // R_J(0, 1 - m, 1, 1 + n), -1 until first needed
constexpr int FC_LEV = 26, FC_SCALE = 27, FC_MB = 28;  // the Landen descent of m (m1 > 0 only)
constexpr int FC_MU0 = 29;   // its mu_0 .. mu_11 in FC_MU0 .. FC_MU0 + 11
constexpr int N_LANDEN = 12; // mu slots (LANDEN_MAX_LEVELS is at most this)
constexpr i64 N_FLOW = 41;
static_assert(FC_MU0 + N_LANDEN == N_FLOW, "flow row layout");

// The descending Landen transformations of a parameter (landen_descent).
struct Landen {
    int lev = 0;
    double scale = 1.0;
    double m = 0.0;  // the base parameter
    double mu[N_LANDEN] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
};

// sn r, cn r, dn r, j, K with u = 2 K j + r (sncndn).
struct SnCnDn {
    double sn, cn, dn;
    i64 j;
    double big_k;
};

// The flow since the anchor (flow_eval): c (a positive multiple of the rotation's quaternion in
// the body frame), the body momentum at t, and the row's FC_RJC (the caller stores it).
struct FlowOut {
    double cw, c0, c1, c2, o0, o1, o2, rj_c;
};

// One descending Landen step from b = sqrt(1 - m): (mu, b') with m' = mu^2,
// b' = sqrt(1 - m') = 2 sqrt(b) / (1 + b) (no cancellation).
inline void landen_down(double b, double& mu, double& b_next) {
    mu = (1.0 - b) / (1.0 + b);
    b_next = 2.0 * std::sqrt(b) / (1.0 + b);
}

// sn, cn, dn at parameter m from those at m' = mu^2, argument scaled by 1 + mu (A&S 16.12.2-4);
// 1 - mu sn^2 written as (1 - mu) + mu cn^2 so that dn keeps its relative accuracy.
// (T: double, or a vector of doubles for the free kernel's lanes: the same operations lane-wise.)
template <class T>
inline void landen_up(T& sn, T& cn, T& dn, T mu) {
    const T den = 1.0 / (1.0 + mu * sn * sn);
    const T s = (1.0 + mu) * sn * den;
    const T c = cn * dn * den;
    const T d = ((1.0 - mu) + mu * cn * cn) * den;
    sn = s; cn = c; dn = d;
}

// The descending Landen transformations of parameter m = 1 - m1 > 0 (m1 > 0) down to a parameter
// below LANDEN_BASE_PARAMETER (at most LANDEN_MAX_LEVELS levels; mu_k = 0 beyond),
// scale = prod(1 + mu_k). A function of m only: computed once per anchor (flow_constants).
inline Landen landen_descent(double m, double m1) {
    Landen d;
    double b = std::sqrt(m1);
    const double base = free_constants.landen_base_parameter;
    const int max_levels = free_constants.landen_max_levels;
    while (m >= base && d.lev < max_levels) {
        double mu;
        landen_down(b, mu, b);
        d.scale *= 1.0 + mu;
        d.mu[d.lev < N_LANDEN - 1 ? d.lev : N_LANDEN - 1] = mu;
        m = mu * mu;
        d.lev += 1;
    }
    d.m = m;
    return d;
}

// sncndn from a descent (m its base parameter, mu its 12 slots).
inline SnCnDn sncndn_landen(double u, int lev, double scale, double m, const double* mu) {
    // base: parameter m < 1e-9, A&S 16.13 to first order in m (error O(m^2))
    const double kb = HALF_PI * (1.0 + 0.25 * m);  // K(m) to first order
    const double big_k = scale * kb;
    double v = u / scale;
    i64 j = static_cast<i64>(v / (2.0 * kb));
    v -= 2.0 * kb * static_cast<double>(j);
    if (v < 0.0) {  // rounding at the boundary
        v += 2.0 * kb;
        j -= 1;
    }
    const double sv = std::sin(v), cv = std::cos(v);
    const double corr = 0.25 * m * (v - sv * cv);
    double sn = sv - corr * cv;
    double cn = cv + corr * sv;
    double dn = 1.0 - 0.5 * m * sv * sv;
    // back up the levels, deepest first
    for (int k = N_LANDEN - 1; k >= 0; --k)
        if (lev > k) landen_up(sn, cn, dn, mu[k]);
    return {sn, cn, dn, j, big_k};
}

// Jacobi sn, cn, dn of u >= 0 at parameter m = 1 - m1, with the argument reduced by the half
// period: (sn r, cn r, dn r, j, K) where u = 2 K j + r, 0 <= r < 2K (so sn u = (-1)^j sn r,
// cn u = (-1)^j cn r, dn u = dn r). K = inf (j = 0) when m1 = 0.
inline SnCnDn sncndn(double u, double m, double m1) {
    if (m1 <= 0.0) {  // m = 1: sn = tanh, cn = dn = sech, no period
        const double t = std::tanh(u);
        const double c = u < 700.0 ? 1.0 / std::cosh(u) : 0.0;
        return {t, c, c, 0, std::numeric_limits<double>::infinity()};
    }
    const Landen d = landen_descent(m, m1);
    return sncndn_landen(u, d.lev, d.scale, d.m, d.mu);
}

// Carlson's R_C(1, 1 + t) for t > -1: atan(sqrt t)/sqrt t, atanh(sqrt -t)/sqrt -t, series near 0.
inline double rc1(double t) {
    if (std::fabs(t) < 1e-3)
        return 1.0 + t * (-1.0 / 3.0 + t * (0.2 + t * (-1.0 / 7.0 + t * (1.0 / 9.0 + t * (-1.0 / 11.0)))));
    if (t > 0.0) {
        const double r = std::sqrt(t);
        return std::atan(r) / r;
    }
    const double r = std::sqrt(-t);
    return std::atanh(r) / r;
}

// Python's max(a, b) for floats: a unless b > a.
inline double pymax(double a, double b) { return b > a ? b : a; }

// sqrt of a double, or lane-wise of a vector of doubles (the free kernel's lanes).
inline double sqrt_t(double a) { return std::sqrt(a); }
template <class V>
inline V sqrt_t(V a) {
    V r;
    for (int l = 0; l < static_cast<int>(sizeof(V) / sizeof(double)); ++l) r[l] = std::sqrt(a[l]);
    return r;
}

// The fifth-order series of R_J after the duplications (DLMF 19.36.2), times 4^-n A^-3/2.
// (T as landen_up's.)
template <class T>
inline T rj_series(T a0, T x, T y, T z, T p, T fac, T a) {
    const T xj = (a0 - x) * fac / a;
    const T yj = (a0 - y) * fac / a;
    const T zj = (a0 - z) * fac / a;
    const T pj = -0.5 * (xj + yj + zj);
    const T f2 = xj * yj + xj * zj + yj * zj - 3.0 * pj * pj;
    const T f3 = xj * yj * zj + 2.0 * f2 * pj + 4.0 * pj * pj * pj;
    const T f4 = (2.0 * xj * yj * zj + f2 * pj + 3.0 * pj * pj * pj) * pj;
    const T f5 = xj * yj * zj * pj * pj;
    const T ser = (1.0 - 3.0 * f2 / 14.0 + f3 / 6.0 + 9.0 * f2 * f2 / 88.0 - 3.0 * f4 / 22.0
                   - 9.0 * f2 * f3 / 52.0 + 3.0 * f5 / 26.0);
    return fac * ser / (a * sqrt_t(a));
}

// R_J(x, y, 1, p) alone (x, y >= 0, at most one zero; p > 0): the R_J half of carlson_rf_rj,
// same duplication and stopping rule.
inline double carlson_rj1(double x, double y, double p) {
    const double a0 = (x + y + 1.0 + 2.0 * p) / 5.0;
    double q = std::fabs(a0 - x);
    q = pymax(q, std::fabs(a0 - y));
    q = pymax(q, std::fabs(a0 - 1.0));
    q = pymax(q, std::fabs(a0 - p));
    double e = (p - x) * (p - y) * (p - 1.0);
    double xa = x, ya = y, za = 1.0, pa = p, aa = a0;
    double fac = 1.0;
    double s = 0.0;
    const double tol = free_constants.carlson_series_tol;
    for (int it = 0; it < 40; ++it) {
        if (fac * q <= tol * aa) break;
        const double sx = std::sqrt(xa), sy = std::sqrt(ya), sz = std::sqrt(za), sp = std::sqrt(pa);
        const double la = sx * sy + sy * sz + sz * sx;
        const double da = (sp + sx) * (sp + sy) * (sp + sz);
        s += fac * rc1(e / (da * da)) / da;
        fac *= 0.25;
        e *= 1.0 / 64.0;
        xa = 0.25 * (xa + la); ya = 0.25 * (ya + la); za = 0.25 * (za + la);
        pa = 0.25 * (pa + la); aa = 0.25 * (aa + la);
    }
    return rj_series(a0, x, y, 1.0, p, fac, aa) + 6.0 * s;
}

// A positive multiple of the quaternion of B = Rx(theta) Rz(psi), B Lb' = l e3 (exact.py,
// _euler_quat: unnormalized half-angle forms, no cancellation either way).
inline void euler_quat(double l1, double l2, double l3, double ell, double& qw, double& qx,
                       double& qy, double& qz) {
    const double rho = std::sqrt(l1 * l1 + l2 * l2);
    double xw, xx, zw, zz;
    if (l3 >= 0.0) { xw = ell + l3; xx = rho; } else { xw = rho; xx = ell - l3; }
    if (l2 >= 0.0) { zw = rho + l2; zz = l1; } else { zw = l1; zz = rho - l2; }
    // (xw, xx, 0, 0) (x) (zw, 0, 0, zz)
    qw = xw * zw; qx = xx * zw; qy = -xx * zz; qz = xw * zz;
}

// The flow from a row of constants c (flow_constants) at the elapsed time t >= 0: the rotation
// since the anchor (a positive multiple of its quaternion, in the body frame), the body momentum
// at t, and the row's FC_RJC (computed here the first time a half period is crossed; the caller
// stores it). Reads the row only.
inline FlowOut flow_eval(const double* c, double t) {
    if (c[FC_STEADY] != 0.0) {
        const double w0 = c[FC_W0], w1 = c[FC_W1], w2 = c[FC_W2], wn = c[FC_WN];
        const double b0 = c[FC_B0], b1 = c[FC_B1], b2 = c[FC_B2];
        if (wn == 0.0) return {1.0, 0.0, 0.0, 0.0, b0, b1, b2, -1.0};
        const double half = 0.5 * t * wn;
        const double sf = std::sin(half) / wn;
        return {std::cos(half), sf * w0, sf * w1, sf * w2, b0, b1, b2, -1.0};
    }
    const double kk1 = c[FC_K1], ell = c[FC_ELL], d13 = c[FC_D13];
    const double m = c[FC_M], m1 = c[FC_M1], lam = c[FC_LAM], nn = c[FC_N];
    const double amp1 = c[FC_AMP1], amp2 = c[FC_AMP2], amp3 = c[FC_AMP3];
    const double sigma = c[FC_SIGMA], s = c[FC_S];
    const double sn0 = c[FC_SN0], cn0 = c[FC_CN0], dn0 = c[FC_DN0];
    // advance the phase by tau = lam t: functions of r, tau = 2 K j + r
    const double tau = lam * t;
    SnCnDn e_;
    if (m1 <= 0.0)  // on the separatrix
        e_ = sncndn(tau, m, m1);
    else  // sncndn with the row's Landen descent
        e_ = sncndn_landen(tau, static_cast<int>(c[FC_LEV]), c[FC_SCALE], c[FC_MB], c + FC_MU0);
    const double snr = e_.sn, cnr = e_.cn, dnr = e_.dn, big_k = e_.big_k;
    const i64 j = e_.j;
    // addition theorem (A&S 16.17) written for the increments (1 - cn r and 1 - dn r from sn r)
    const double gc = cnr > 0.0 ? snr * snr / (1.0 + cnr) : 1.0 - cnr;  // 1 - cn r
    const double gd = m * snr * snr / (1.0 + dnr);                          // 1 - dn r
    const double mu_ = m * sn0 * sn0 * snr * snr;
    const double den = 1.0 / (1.0 - mu_);
    const double gam = gc + gd - gc * gd;  // 1 - cn r dn r
    const double sn1 = sn0 + (snr * cn0 * dn0 - sn0 * gam + sn0 * mu_) * den;
    const double cn1 = cn0 + (-cn0 * gc - sn0 * snr * dn0 * dnr + cn0 * mu_) * den;
    // dn from the identity dn^2 = cn^2 + (1 - m) sn^2: positive, no cancellation
    const double dn1 = std::sqrt(cn1 * cn1 + m1 * sn1 * sn1);
    // the integral of 1 / (1 + n sn^2) over [u0, u0 + r]: reduced amplitudes at both ends
    const double sg0 = cn0 >= 0.0 ? 1.0 : -1.0;
    const double s_red0 = sg0 * sn0;
    i64 e;
    double s_red1;
    if (sg0 * cn1 >= 0.0) {
        e = 0;
        s_red1 = sg0 * sn1;
        if (s_red1 - s_red0 < -1.0) e = 2;  // wrapped past 3 pi / 2 by rounding
    } else {
        e = 1;
        s_red1 = -sg0 * sn1;
        if (s_red1 - s_red0 > 1.0) e = -1;  // came back below -pi / 2 by rounding
    }
    // G(phi) = S^3 R_J(C^2, D^2, 1, 1 + n S^2) / 3 (|phi| <= pi/2), the anchor's end G0 a constant
    double rj_c = c[FC_RJC];
    double dg = 0.0;
    if (nn != 0.0) {
        const double s21 = s_red1 * s_red1;
        dg = s_red1 * s21 * carlson_rj1(cn1 * cn1, dn1 * dn1, 1.0 + nn * s21) / 3.0 - c[FC_G0];
    }
    if (big_k == std::numeric_limits<double>::infinity()) e = 0;  // separatrix: never leaves
    const i64 halfs = j + e;
    if (halfs != 0 && nn != 0.0) {
        if (rj_c < 0.0) rj_c = carlson_rj1(0.0, m1, 1.0 + nn);
        dg += 2.0 * static_cast<double>(halfs) * rj_c / 3.0;
    }
    // dphi = l k3 t + l (k1 - k3) / lam * (tau - n dg)
    const double dphi = ell * kk1 * t - ell * d13 * nn / lam * dg;
    // the momentum at u0 + tau
    const double sj = (j & 1) ? -1.0 : 1.0;
    const double n1_ = amp1 * cn1 * sj;
    const double n2_ = sigma * amp2 * sn1 * sj;
    const double n3_ = s * amp3 * dn1;
    // rotation since the anchor in the working frame: B0^T Rz(dphi) B1
    double bw, bx, by, bz;
    euler_quat(n1_, n2_, n3_, ell, bw, bx, by, bz);
    const double ch = std::cos(0.5 * dphi), sh = std::sin(0.5 * dphi);
    // conj(B0) (x) rz  (exact._qmul, the Hamilton product)
    const double aw = c[FC_AW], ax = -c[FC_AX], ay = -c[FC_AY], az = -c[FC_AZ];
    const double tw = aw * ch - ax * 0.0 - ay * 0.0 - az * sh;
    const double tx = aw * 0.0 + ax * ch + ay * sh - az * 0.0;
    const double ty = aw * 0.0 - ax * sh + ay * ch + az * 0.0;
    const double tz = aw * sh + ax * 0.0 - ay * 0.0 + az * ch;
    const double cw = tw * bw - tx * bx - ty * by - tz * bz;
    const double cx = tw * bx + tx * bw + ty * bz - tz * by;
    const double cy = tw * by - tx * bz + ty * bw + tz * bx;
    const double cz = tw * bz + tx * by - ty * bx + tz * bw;
    // back to the body frame: v_body[i_k] = s_k v'_k, s = (1, 1, sgn3)
    const double sgn3 = c[FC_SGN3];
    const int i1 = static_cast<int>(c[FC_I1]), i2 = static_cast<int>(c[FC_I2]);
    double cc[3] = {0.0, 0.0, 0.0}, oo[3] = {0.0, 0.0, 0.0};
    cc[i1] = cx; oo[i1] = n1_;
    cc[i2] = cy; oo[i2] = n2_;
    cc[3 - i1 - i2] = cz * sgn3; oo[3 - i1 - i2] = n3_ * sgn3;
    return {cw, cc[0], cc[1], cc[2], oo[0], oo[1], oo[2], rj_c};
}

// (R_F(x, y, z), R_J(x, y, z, p)) by one shared duplication (exact.cpp).
void carlson_rf_rj(double x, double y, double z, double p, double& rf, double& rj);

// Row `row` (N_FLOW doubles): the constants of the torque-free flow forward in time of a body
// whose body-frame momentum at the anchor is Lb = (b0, b1, b2), inverse principal moments
// (k0, k1, k2) (any order). (The flow backward is the forward flow of -Lb.)
void flow_constants(double* row, double b0, double b1, double b2, double k0, double k1, double k2);
inline void flow_constants(V2<double> fc, i64 r, double b0, double b1, double b2, double k0,
                           double k1, double k2) {
    flow_constants(fc.row(r), b0, b1, b2, k0, k1, k2);
}

// The flow over t >= 0 from row r of fc: the unit quaternion c (cw >= 0) of the rotation since
// the anchor (body frame) and the body momentum at t; may fill the row's FC_RJC.
void flow_rotation(V2<double> fc, i64 r, double t, double out[7]);

// The exact torque-free motion over h of a body with body momentum Lb and inverse moments k: the
// body itself as the anchor. out: (cw, cx, cy, cz, n0, n1, n2).
void free_flow_body(double b0, double b1, double b2, double k0, double k1, double k2, double h,
                    double out[7]);

// q(t + h) (unit, wxyz) of the torque-free body with orientation q (unit, body -> world), world
// angular momentum L and inverse principal moments k.
void free_flow_quat(double w, double x, double y, double z, double lx, double ly, double lz,
                    double k0, double k1, double k2, double h, double out[4]);

}  // namespace rb
