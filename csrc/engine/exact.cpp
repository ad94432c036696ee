// The exact flow of the torque-free rigid body, compiled: Jacobi elliptic functions for the body
// angular momentum, Carlson's elliptic integrals for the attitude.
//
// After Celledoni, Fasso, Safstrom & Zanna, "The exact computation of the free rigid body motion and
// its use in splitting methods", SIAM J. Sci. Comput. 30(4) (2008): the body momentum by Jacobi's
// solution, the attitude by the reconstruction through the angle about the (fixed) world L, written
// with Carlson's R_F and R_J. The flow is evaluated from an anchor state (q_a, L_world) at the
// elapsed time t: :func:`flow_constants` computes once what depends on the anchor only (the axes'
// order and case, m, lam, the amplitudes, the anchor's phase and G, B0), :func:`flow_rotation` the
// rotation since the anchor at any t, q(t) = q_a (x) c(t). Stepping by evaluating from a fixed anchor
// at t = n h (rblog.engine.integrators.drift_exact_anchored) carries no state but the anchor, so
// the rounding of one step is not fed into the next (near the separatrix a carried q's rounding,
// ~1e-16 a step, was amplified ~1e4 by the saddle); :func:`free_flow_body` is the one-step map, the
// state itself as the anchor.
//
// Frames and symbols
// ------------------
// ``q`` (wxyz) maps body to world; L (world) is constant; Lb = R^T L (body); k_i = 1 / I_i (the
// diagonal of I^-1, any order). l = |L|, 2E = sum k_i Lb_i^2.
//
// Working frame. The axes are relabelled by a proper signed permutation M (v' = M v_body) so that
// axis 3' is the one about which Lb turns (its component never changes sign) and axis 2' is the
// intermediate one: with the moments sorted I_a <= I_b <= I_c, ``case A`` (l^2 >= 2E I_b) takes
// (a, b, c), ``case B`` (l^2 < 2E I_b) takes (c, b, a). In the working frame, with k1, k2, k3
// the inverse moments of axes 1', 2', 3' and (no cancellation: every term of P~, Q~ carries the
// same sign)
//
//     P~ = L1^2 (k1 - k3) + L2^2 (k2 - k3)     (= k3 (2E J3 - l^2))
//     Q~ = L2^2 (k1 - k2) + L3^2 (k1 - k3)     (= k1 (l^2 - 2E J1))
//     D~ = L1^2 (k2 - k1) + L3^2 (k2 - k3)     (= k2 (l^2 - 2E J2), the distance to the separatrix)
//
// the body momentum is (Landau & Lifshitz section 37, in these variables)
//
//     L1 = a1 cn u,  L2 = sigma a2 sn u,  L3 = s a3 dn u,   u = u0 + lam t,
//     a1^2 = P~ / (k1 - k3),  a2^2 = P~ / (k2 - k3),  a3^2 = Q~ / (k1 - k3),
//     lam^2 = (k2 - k3) Q~,  m = (k1 - k2) P~ / ((k2 - k3) Q~),  1 - m = (k1 - k3) D~ / ((k2 - k3) Q~),
//
// s = sign L3 and sigma = s (case A) or -s (case B) (substitute into Euler's equations). sn u0,
// cn u0, dn u0 are read off the state, and the state at u0 + lam h follows from the addition
// theorem, so the phase u0 itself is never needed. 1 - m is formed from D~ directly, so m near 1
// (the separatrix) loses nothing to cancellation.
//
// Attitude. With Euler angles about the world L (z-x-z: R = A^T Rz(phi) Rx(theta) Rz(psi) M,
// Lb' = l (sin theta sin psi, sin theta cos psi, cos theta)), Landau's dphi/dt =
// l (L1^2 k1 + L2^2 k2) / (L1^2 + L2^2) becomes, after substituting the solution,
//
//     dphi/dt = l k3 + l (k1 - k3) / (1 + n sn^2 u),   n = (k1 - k2) / (k2 - k3) >= 0,
//
// so phi(t + h) - phi(t) = l k3 h + l (k1 - k3) / lam * [Pi(-n; am u1 | m) - Pi(-n; am u0 | m)],
// the incomplete elliptic integral of the third kind, for |am| <= pi/2 (DLMF 19.25.14)
//
//     Pi(-n; phi | m) = S R_F(C^2, D^2, 1) - (n/3) S^3 R_J(C^2, D^2, 1, 1 + n S^2),
//
// S = sin phi = sn, C = cn, D = dn, and quasi-periodic beyond (Pi(phi + pi) = Pi(phi) + 2 Pi_c). As
// the first term integrates to lam h exactly, the step uses
// dphi = l k1 h - l (k1 - k3) n / lam * [G(am u1) - G(am u0)], G = S^3 R_J(...) / 3: the difference of
// the two ends is multiplied by n / lam, which stays bounded as a body nears symmetry (n -> 0 while
// the precession lam -> 0), where the first form would multiply round-off by 1 / lam. The
// step's rotation is then R(t+h) = R(t) M^T B0^T Rz(dphi) B1 M, with B = Rx(theta) Rz(psi) built from
// Lb' at either end (unnormalized half-angle quaternions, no trigonometric calls).
//
// Numerics. sn, cn, dn(r | m) by descending Landen transformations (A&S 16.12) until m < 1e-9, then
// the first-order expansion in m (A&S 16.13), after reducing the argument by the half period 2K (so
// every evaluation sees an argument in [0, 2K)); R_F, R_J by Carlson's duplication (Carlson 1995,
// DLMF 19.36.1-2) and the series of DLMF 19.36.1-2. Degenerate states are exact rotations: steady
// rotation about a principal axis (Lb x omega = 0 exactly: also every symmetric body with Lb in its
// isotropic plane, and the sphere), and negative h (the flow backward is the forward flow of -L).
//
// Why this module is long: the flow is one derivation (the elliptic functions with their Landen
// descent, Carlson's R_F and R_J, the attitude reconstruction, the per-anchor constants and their
// evaluation at any elapsed time); its parts share the case analysis (branches A and B, the
// separatrix, steady rotation) and the row layout of the cached constants, which would otherwise
// be passed between modules.
//
// (C++ port of rblog/engine/exact.py: the same formulas in the same operation order. The per-step
// pieces are inline in exact.hpp; here what runs once per anchor and the one-step maps.)
#include "engine/exact.hpp"

namespace rb {

// (R_F(x, y, z), R_J(x, y, z, p)) for x, y, z >= 0 (at most one zero), p > 0, by one shared
// duplication (DLMF 19.36.1-2; Carlson, Numer. Algorithms 10 (1995)): the x, y, z sequence is the
// same for both. Stops when the arguments agree to CARLSON_SERIES_TOL relative, then the series
// (seventh order for R_F, fifth for R_J; measured error <= 1.8e-15 relative).
void carlson_rf_rj(double x, double y, double z, double p, double& rf_out, double& rj_out) {
    const double a0f = (x + y + z) / 3.0;
    const double a0j = (x + y + z + 2.0 * p) / 5.0;
    double af = a0f;
    double aj = a0j;
    const double delta = (p - x) * (p - y) * (p - z);
    double qf = std::fabs(a0f - x);
    qf = pymax(qf, std::fabs(a0f - y));
    qf = pymax(qf, std::fabs(a0f - z));
    double qj = std::fabs(a0j - x);
    qj = pymax(qj, std::fabs(a0j - y));
    qj = pymax(qj, std::fabs(a0j - z));
    qj = pymax(qj, std::fabs(a0j - p));
    double xn = x, yn = y, zn = z, pn = p;
    double fac = 1.0;  // 4^-n
    double s = 0.0;
    double e_fac = delta;  // 4^-3n delta
    const double tol = free_constants.carlson_series_tol;
    for (int it = 0; it < 40; ++it) {
        if (fac * qf <= tol * af && fac * qj <= tol * aj) break;
        const double sx = std::sqrt(xn), sy = std::sqrt(yn), sz = std::sqrt(zn), sp = std::sqrt(pn);
        const double lam = sx * sy + sy * sz + sz * sx;
        const double d = (sp + sx) * (sp + sy) * (sp + sz);
        s += fac * rc1(e_fac / (d * d)) / d;
        fac *= 0.25;
        e_fac *= 1.0 / 64.0;
        xn = 0.25 * (xn + lam);
        yn = 0.25 * (yn + lam);
        zn = 0.25 * (zn + lam);
        pn = 0.25 * (pn + lam);
        af = 0.25 * (af + lam);
        aj = 0.25 * (aj + lam);
    }
    // R_F series
    const double xf = (a0f - x) * fac / af;
    const double yf = (a0f - y) * fac / af;
    const double zf = -xf - yf;
    const double e2 = xf * yf - zf * zf;
    const double e3 = xf * yf * zf;
    rf_out = (1.0 - e2 / 10.0 + e3 / 14.0 + e2 * e2 / 24.0 - 3.0 * e2 * e3 / 44.0
              - 5.0 * e2 * e2 * e2 / 208.0 + 3.0 * e3 * e3 / 104.0 + e2 * e2 * e3 / 16.0) / std::sqrt(af);
    // R_J series
    rj_out = rj_series(a0j, x, y, z, p, fac, aj) + 6.0 * s;
}

template <class T>
static inline void swap2(T& a, T& b) { T t = a; a = b; b = t; }

void flow_constants(double* row, double b0, double b1, double b2, double k0, double k1, double k2) {
    double* fc = row;
    // steady rotation (Lb parallel to omega): the rotation is exp(t omega)
    if (b1 * b2 * (k2 - k1) == 0.0 && b2 * b0 * (k0 - k2) == 0.0 && b0 * b1 * (k1 - k0) == 0.0) {
        const double w0 = b0 * k0, w1 = b1 * k1, w2 = b2 * k2;
        fc[FC_STEADY] = 1.0;
        fc[FC_W0] = w0; fc[FC_W1] = w1; fc[FC_W2] = w2;
        fc[FC_WN] = std::sqrt(w0 * w0 + w1 * w1 + w2 * w2);
        fc[FC_B0] = b0; fc[FC_B1] = b1; fc[FC_B2] = b2;
        return;
    }
    // sort the axes by inertia: ia (smallest I, largest k), ib, ic
    int ia = 0, ib = 1, ic = 2;
    double ka = k0, kb = k1, kc = k2;
    double la = b0, lb = b1, lc = b2;
    if (ka < kb) { swap2(ia, ib); swap2(ka, kb); swap2(la, lb); }
    if (kb < kc) { swap2(ib, ic); swap2(kb, kc); swap2(lb, lc); }
    if (ka < kb) { swap2(ia, ib); swap2(ka, kb); swap2(la, lb); }
    // parity of (ia, ib, ic) as a permutation of (0, 1, 2)
    const double par = (ib - ia) * (ic - ia) * (ic - ib) > 0 ? 1.0 : -1.0;
    const double d_t = la * la * (kb - ka) + lc * lc * (kb - kc);  // k_b (l^2 - 2E I_b)
    int i1, i2, i3;
    double kk1, kk2, kk3, l1, l2, l3, sgn3, case_sign;
    if (d_t >= 0.0) {  // case A: axis 3' = c
        i1 = ia; i2 = ib; i3 = ic;
        kk1 = ka; kk2 = kb; kk3 = kc;
        l1 = la; l2 = lb; l3 = lc * par;
        sgn3 = par;
        case_sign = 1.0;
    } else {  // case B: axis 3' = a
        i1 = ic; i2 = ib; i3 = ia;
        kk1 = kc; kk2 = kb; kk3 = ka;
        l1 = lc; l2 = lb; l3 = -la * par;
        sgn3 = -par;
        case_sign = -1.0;
    }
    const double ell = std::sqrt(l1 * l1 + l2 * l2 + l3 * l3);
    const double d13 = kk1 - kk3;
    const double d23 = kk2 - kk3;
    const double d12 = kk1 - kk2;
    const double p_t = l1 * l1 * d13 + l2 * l2 * d23;
    const double q_t = l2 * l2 * d12 + l3 * l3 * d13;
    double m = d12 * p_t / (d23 * q_t);
    double m1 = d13 * d_t / (d23 * q_t);
    if (m1 < 0.0) m1 = 0.0;  // rounding on the separatrix
    if (m > 1.0) m = 1.0;
    const double amp1 = std::sqrt(p_t / d13);
    const double amp2 = std::sqrt(p_t / d23);
    const double amp3 = std::sqrt(q_t / d13);
    const double s = l3 >= 0.0 ? 1.0 : -1.0;
    const double sigma = s * case_sign;
    const double cn0 = l1 / amp1;
    const double sn0 = sigma * l2 / amp2;
    const double dn0 = std::fabs(l3) / amp3;
    const double nn = d12 / d23;
    double g0 = 0.0;
    if (nn != 0.0) {
        const double s_red0 = cn0 >= 0.0 ? sn0 : -sn0;
        const double s20 = s_red0 * s_red0;
        g0 = s_red0 * s20 * carlson_rj1(cn0 * cn0, dn0 * dn0, 1.0 + nn * s20) / 3.0;
    }
    double aw, ax, ay, az;
    euler_quat(l1, l2, l3, ell, aw, ax, ay, az);
    fc[FC_STEADY] = 0.0;
    fc[FC_I1] = static_cast<double>(i1);
    fc[FC_I2] = static_cast<double>(i2);
    fc[FC_I3] = static_cast<double>(i3);
    fc[FC_SGN3] = sgn3;
    fc[FC_K1] = kk1;
    fc[FC_ELL] = ell;
    fc[FC_D13] = d13;
    fc[FC_M] = m; fc[FC_M1] = m1;
    fc[FC_LAM] = std::sqrt(d23 * q_t);
    fc[FC_AMP1] = amp1; fc[FC_AMP2] = amp2; fc[FC_AMP3] = amp3;
    fc[FC_N] = nn;
    fc[FC_SIGMA] = sigma; fc[FC_S] = s;
    fc[FC_SN0] = sn0; fc[FC_CN0] = cn0; fc[FC_DN0] = dn0;
    fc[FC_G0] = g0;
    fc[FC_AW] = aw; fc[FC_AX] = ax; fc[FC_AY] = ay; fc[FC_AZ] = az;
    fc[FC_RJC] = -1.0;
    if (m1 > 0.0) {
        const Landen d = landen_descent(m, m1);
        fc[FC_LEV] = static_cast<double>(d.lev);
        fc[FC_SCALE] = d.scale;
        fc[FC_MB] = d.m;
        for (int k = 0; k < N_LANDEN; ++k) fc[FC_MU0 + k] = d.mu[k];
    }
}

// flow_rotation_scaled normalized (cw >= 0).
void flow_rotation(V2<double> fc, i64 r, double t, double out[7]) {
    double* row = fc.row(r);
    const FlowOut f = flow_eval(row, t);
    if (f.rj_c >= 0.0 && row[FC_RJC] < 0.0) row[FC_RJC] = f.rj_c;
    double nc = 1.0 / std::sqrt(f.cw * f.cw + f.c0 * f.c0 + f.c1 * f.c1 + f.c2 * f.c2);
    if (f.cw < 0.0) nc = -nc;
    out[0] = f.cw * nc; out[1] = f.c0 * nc; out[2] = f.c1 * nc; out[3] = f.c2 * nc;
    out[4] = f.o0; out[5] = f.o1; out[6] = f.o2;
}

void free_flow_body(double b0, double b1, double b2, double k0, double k1, double k2, double h,
                    double out[7]) {
    double flip = 1.0;
    if (h < 0.0) {  // the backward flow is the forward flow of -L (Euler's equations are quadratic)
        flip = -1.0;
        b0 = -b0; b1 = -b1; b2 = -b2; h = -h;
    }
    double row[N_FLOW];
    flow_constants(row, b0, b1, b2, k0, k1, k2);
    flow_rotation(V2<double>{row, 1, N_FLOW}, 0, h, out);
    out[4] = flip * out[4]; out[5] = flip * out[5]; out[6] = flip * out[6];
}

void free_flow_quat(double w, double x, double y, double z, double lx, double ly, double lz,
                    double k0, double k1, double k2, double h, double out[4]) {
    // Lb = R^T L
    const double r00 = w * w + x * x - y * y - z * z;
    const double r01 = 2.0 * (x * y - w * z);
    const double r02 = 2.0 * (x * z + w * y);
    const double r10 = 2.0 * (x * y + w * z);
    const double r11 = w * w - x * x + y * y - z * z;
    const double r12 = 2.0 * (y * z - w * x);
    const double r20 = 2.0 * (x * z - w * y);
    const double r21 = 2.0 * (y * z + w * x);
    const double r22 = w * w - x * x - y * y + z * z;
    const double b0 = r00 * lx + r10 * ly + r20 * lz;
    const double b1 = r01 * lx + r11 * ly + r21 * lz;
    const double b2 = r02 * lx + r12 * ly + r22 * lz;
    double c[7];
    free_flow_body(b0, b1, b2, k0, k1, k2, h, c);
    const double cw = c[0], cx = c[1], cy = c[2], cz = c[3];
    const double qw = w * cw - x * cx - y * cy - z * cz;
    const double qx = w * cx + x * cw + y * cz - z * cy;
    const double qy = w * cy - x * cz + y * cw + z * cx;
    const double qz = w * cz + x * cy - y * cx + z * cw;
    const double n = 1.0 / std::sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
    out[0] = qw * n; out[1] = qx * n; out[2] = qy * n; out[3] = qz * n;
}

}  // namespace rb
