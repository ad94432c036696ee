// The integrators' compiled side (rblog/engine/integrators.py keeps the registry, the METHOD_* /
// ORTHO_* codes and the docs; the same codes here). Owner: the free-body port.
//
// Frames: q (wxyz) and R map body-frame vectors to the world frame. Angular momentum L is world
// frame; inv_inertia is the diagonal of I_body^-1 (principal axes). Drift functions update
// quat_wxyz[i] and rotation[i] of the state arrays in place and keep the two consistent (except
// under the notes' own schemes with orthonormalization off, where the integrator's R is the point
// of interest). Every integrator's stages are written out here, inline, once over the value type
// (a Body<T>, T = double or a lane vector of lanes.hpp), so that the free-body kernel (free.cpp,
// templated on the integrator and T) and the contact step compile them into their loops; the non-inline entry points the contact step calls (drift_rotation,
// drift_exact_anchored, sync_quat, turn_within_bound, write_sample) are in integrators.cpp.
//
// Derivations
// -----------
// Notes' scheme (``seed``): omega = R I_b^-1 R^T L, R <- R + h [omega]x R, then orthonormalize.
// det(I + h[omega]x) = 1 + h^2 |omega|^2, so without orthonormalization det R grows like
// exp(h * integral |omega|^2 dt): the body "stretches".
//
// Notes' scheme on the quaternion (``seed-quat``): q <- q + h/2 (0, omega) (x) q. Normalized
// (the default), R = R(q) is a rotation and omega = R I_b^-1 R^T L. With ``orthonormalize =
// "none"`` |q| grows by sqrt(1 + h^2 |omega|^2 / 4) a step, and R is the homogeneous matrix of q,
// R v = q (x) v (x) q* = |q|^2 Q v (Q the rotation of q / |q|): the body is shown turned by Q and
// enlarged |q|^2 times in every direction, the notes' "stretch"; ||R^T R - I||_F = sqrt(3)
// (|q|^4 - 1) is logged. The notes' inertia I_world = R I_b R^T with that R is then |q|^4 Q I_b Q^T,
// which is exactly the inertia of the enlarged body at unchanged mass (moments scale with length
// squared), so omega = I_world^-1 L = R^-T I_b^-1 R^-1 L = |q|^-4 Q I_b^-1 Q^T L
// (:func:`rblog.engine.rotation.omega_world_stretched`): a body that grows while L is conserved
// turns slower, as a skater opening her arms, and its energy L.omega/2 falls as |q|^-4. (The
// shortcut I_world^-1 = R I_b^-1 R^T holds only for an orthonormal R; applied to R = |q|^2 Q it
// would give omega |q|^4 times too fast, a feedback that speeds the stretch up.) The rotation
// rate of the body is still omega, since q' = 1/2 (0, omega) q turns q v q* at omega whatever |q|.
// Only the stretch is unphysical for a rigid body; given the stretch, the rest is consistent.
//
// Splitting (``splitting``): the free-body Hamiltonian H = sum_k Lb_k^2 / (2 I_k) (Lb = R^T L) is a
// sum of three exactly solvable parts. The flow of part k over time s rotates the body about its own
// axis k by theta = s Lb_k / I_k (q <- q (x) (cos theta/2, sin theta/2 e_k)) and rotates Lb by
// -theta about e_k, leaving L = R Lb unchanged. Strang composition 1(h/2) 2(h/2) 3(h) 2(h/2) 1(h/2)
// is second order, symplectic and time-reversible; |L| (world) is untouched and R stays a product of
// exact rotations, so both invariants hold to round-off (McLachlan 1993; Dullweber, Leimkuhler &
// McLachlan 1997).
//
// RK4 (``rk4``): classical RK4 on Euler's equations for the body momentum Lb = R^T L, the attitude by
// the fourth-order commutator-free Lie group method (CF4) driven by the stage angular velocities,
// then q turned about an axis normal to L so that R^T L points along the RK4 Lb (see
// :func:`drift_rk4`; RK4 on q alone, with omega = R(q) I^-1 R(q)^T L, is 7-40x
// less accurate at equal dt).
//
// Exact (``exact``): the closed-form torque-free flow (:mod:`rblog.engine.exact`: Jacobi elliptic
// functions for the body momentum, Carlson's integrals for the attitude), to round-off at any h.
// With forces and torques: Strang splitting kick(h/2) exact-flow(h) kick(h/2), second order; the
// world torque is constant over a step, so the only error is the splitting of the momentum kick
// from the rotation. ``exact4``: Yoshida's triple jump of that step (h w1, h w0, h w1 with
// w1 = 1 / (2 - 2^(1/3)), w0 = 1 - 2 w1), fourth order; without torque both are exact, and both
// take the flow over h in one evaluation. The flow is evaluated from a per-body anchor (q_a, L_a)
// at the elapsed time n h (:func:`drift_exact_anchored`, rblog.engine.state.FlowAnchors), not as a
// one-step map of the carried q, so the run's error is one evaluation's rounding at any step count
// (a carried q's ~1e-16 a step, amplified ~1e4 by the saddle, cost the intermediate-axis box 1e-10
// at dt 1e-2); a torque kick or contact impulse changes L and so starts a new anchor.
//
#pragma once

#include <cmath>

#include "common/array.hpp"
#include "engine/exact.hpp"
#include "engine/free_constants.hpp"
#include "engine/rotation.hpp"

namespace rb {

enum Ortho : int { ORTHO_NONE = 0, ORTHO_POLAR = 1, ORTHO_GRAM_SCHMIDT = 2, ORTHO_NORMALIZE = 3 };
enum Method : int {
    METHOD_SEED = 0, METHOD_SEED_QUAT = 1, METHOD_SPLITTING = 2, METHOD_RK4 = 3,
    METHOD_EXACT = 4, METHOD_EXACT4 = 5
};

// Yoshida (1990) triple-jump weights (integrators.YOSHIDA_W1 / W0; the Python module checks at
// import that these are its values bit for bit).
inline double yoshida_w1() { return 1.0 / (2.0 - std::pow(2.0, 1.0 / 3.0)); }
inline double yoshida_w0() { return 1.0 - 2.0 * yoshida_w1(); }

// ---- the declared entry points (integrators.cpp) --------------------------------------------

// Body i's orientation over h with L (world) fixed, by `method` (the exact ones by the one-step
// exact map). tx, ty, tz: torque (rk4 only).
void drift_rotation(int method, int ortho, V2<double> quat_wxyz, V3<double> rotation,
                    V2<double> angular_momentum, V2<double> inv_inertia, i64 i, double h,
                    double tx = 0.0, double ty = 0.0, double tz = 0.0);

// The exact torque-free rotation of body i over h from its flow anchor (integrators.py).
// fc: (rows, N_FLOW) flow constants cache, r its row for this body, fc_ok (rows,) bool.
void drift_exact_anchored(V2<double> quat_wxyz, V3<double> rotation, V2<double> angular_momentum,
                          V2<double> inv_inertia, i64 i, double h, V2<double> anchor_quat_wxyz,
                          V2<double> anchor_L_world, V1<i64> anchor_steps, V1<double> anchor_dt_s,
                          V2<double> fc, i64 r, V1<bool> fc_ok);

// q[i] made to describe R[i] for the integrator that advances R (seed); no-op for the others.
void sync_quat(int method, V2<double> quat_wxyz, V3<double> rotation, i64 i);

// False when body i turns more than MAX_ROTATION_PER_STEP_RAD in a step of dt.
bool turn_within_bound(double dt, i64 i, V2<double> inv_inertia, V3<double> rotation,
                       V2<double> angular_momentum);

// Copy body i's state into sample row j of the out_* buffers (q synced from R first for seed).
void write_sample(int method, i64 j, i64 i, V2<double> position, V2<double> linear_momentum,
                  V2<double> quat_wxyz, V3<double> rotation, V2<double> angular_momentum,
                  V3<double> out_position, V3<double> out_linear_momentum,
                  V3<double> out_quat_wxyz, V4<double> out_rotation,
                  V3<double> out_angular_momentum);

// ---- inline stages ---------------------------------------------------------------------------

inline void store_quat(V2<double> quat_wxyz, i64 i, double w, double x, double y, double z) {
    double* q = quat_wxyz.row(i);
    q[0] = w; q[1] = x; q[2] = y; q[3] = z;
}

// ---- the stages over one body's state in registers -------------------------------------------
//
// T = double for one body, or a lane vector of lanes.hpp (d2, d4) for a body in each lane. Every
// stage is written once, over T: a lane does the one body's operations in its order, so its bits
// are the one body's whatever the width. A branch on a per-body condition is written
// `if (any(c)) { ...; v = c ? new : v; }`: for double a plain branch (the select folds away), for
// a vector the branch's values taken in the lanes where c holds.

// A body's changing state: position and linear momentum, angular momentum L (world), q (wxyz)
// and R (row-major). Under seed q is not current (sync_quat_seed derives it from R).
template <class T>
struct Body {
    T x, y, z, px, py, pz, lx, ly, lz;
    QuatT<T> q;
    Mat3T<T> m;
};

// A body's constants over a call: inverse mass, world force and torque, inverse principal
// moments k = 1/I_body; torqued: some torque component is nonzero.
template <class T>
struct BodyParams {
    T im, fx, fy, fz, tx, ty, tz, k0, k1, k2;
    mask_of<T> torqued;
};

// Body i's attitude and L (and its inverse moments) from the state arrays; the rest zero.
inline void load_rotation(Body<double>& b, BodyParams<double>& p, V2<double> quat_wxyz,
                          V3<double> rotation, V2<double> angular_momentum,
                          V2<double> inv_inertia, i64 i) {
    b.lx = angular_momentum(i, 0); b.ly = angular_momentum(i, 1); b.lz = angular_momentum(i, 2);
    b.q = {quat_wxyz(i, 0), quat_wxyz(i, 1), quat_wxyz(i, 2), quat_wxyz(i, 3)};
    b.m = load_mat(rotation, i);
    p.k0 = inv_inertia(i, 0); p.k1 = inv_inertia(i, 1); p.k2 = inv_inertia(i, 2);
}

// Exact flow of H_k = Lb_k^2 / (2 I_k) over time s about body axis AX (0, 1, 2), given
// s_inv_i = s/I_k: rotate the body about its own axis k by theta = s Lb_k / I_k and Lb by -theta.
// Half-angle sine/cosine for the quaternion, the full angle's from the double-angle formulas: one
// sin/cos pair per sub-step.
template <int AX, class T>
inline void flow(QuatT<T>& q, T& b0, T& b1, T& b2, T s_inv_i) {
    const T th = s_inv_i * (AX == 0 ? b0 : AX == 1 ? b1 : b2);
    T sh, ch;
    vsincos(0.5 * th, sh, ch);
    const T c = ch * ch - sh * sh, sn = 2.0 * ch * sh;
    const T w = q[0], x = q[1], y = q[2], z = q[3];
    if (AX == 0) {
        q = {ch * w - sh * x, ch * x + sh * w, ch * y + sh * z, ch * z - sh * y};
        const T n1 = c * b1 + sn * b2, n2 = c * b2 - sn * b1;
        b1 = n1; b2 = n2;
    } else if (AX == 1) {
        q = {ch * w - sh * y, ch * x - sh * z, ch * y + sh * w, ch * z + sh * x};
        const T n0 = c * b0 - sn * b2, n2 = c * b2 + sn * b0;
        b0 = n0; b2 = n2;
    } else {
        q = {ch * w - sh * z, ch * x + sh * y, ch * y - sh * x, ch * z + sh * w};
        const T n0 = c * b0 + sn * b1, n1 = c * b1 - sn * b0;
        b0 = n0; b1 = n1;
    }
}

// The notes' drift: R += h [omega]x R with omega = R I^-1 R^T L, then orthonormalize.
// (The quaternion is derived from R only when logged: sync_quat.)
template <class T>
inline void drift_seed(int ortho, Body<T>& b, const BodyParams<T>& p, double h) {
    const Vec3T<T> o = omega_world(b.m, p.k0, p.k1, p.k2, b.lx, b.ly, b.lz);
    const T ox = o[0], oy = o[1], oz = o[2];
    const T m00 = b.m[0], m01 = b.m[1], m02 = b.m[2], m10 = b.m[3], m11 = b.m[4], m12 = b.m[5],
            m20 = b.m[6], m21 = b.m[7], m22 = b.m[8];
    // R <- R + h [omega]x R
    Mat3T<T> n = {m00 + h * (-oz * m10 + oy * m20), m01 + h * (-oz * m11 + oy * m21),
                  m02 + h * (-oz * m12 + oy * m22),
                  m10 + h * (oz * m00 - ox * m20), m11 + h * (oz * m01 - ox * m21),
                  m12 + h * (oz * m02 - ox * m22),
                  m20 + h * (-oy * m00 + ox * m10), m21 + h * (-oy * m01 + ox * m11),
                  m22 + h * (-oy * m02 + ox * m12)};
    if (ortho == ORTHO_POLAR)
        n = polar(n);
    else if (ortho == ORTHO_GRAM_SCHMIDT)
        n = gram_schmidt(n);
    b.m = n;
}

// The notes' drift on the quaternion: q += h/2 (0, omega) (x) q, normalized unless ortho is none.
// Without normalization R = |q|^2 Q and omega = (R I_body R^T)^-1 L (header comment).
template <class T>
inline void drift_seed_quat(int ortho, Body<T>& b, const BodyParams<T>& p, double h) {
    T w = b.q[0], x = b.q[1], y = b.q[2], z = b.q[3];
    const Vec3T<T> o = ortho == ORTHO_NONE
                           ? omega_world_stretched(b.m, p.k0, p.k1, p.k2, b.lx, b.ly, b.lz)
                           : omega_world(b.m, p.k0, p.k1, p.k2, b.lx, b.ly, b.lz);
    const QuatT<T> d = quat_mul(splat_v<T>(0.0), o[0], o[1], o[2], w, x, y, z);
    w = w + 0.5 * h * d[0]; x = x + 0.5 * h * d[1]; y = y + 0.5 * h * d[2]; z = z + 0.5 * h * d[3];
    b.q = ortho != ORTHO_NONE ? normalize4(w, x, y, z) : QuatT<T>{w, x, y, z};
    b.m = quat_to_mat(b.q[0], b.q[1], b.q[2], b.q[3]);
}

// Strang splitting 1(h/2) 2(h/2) 3(h) 2(h/2) 1(h/2) of the free rotation into exact axis rotations.
template <class T>
inline void drift_splitting(Body<T>& b, const BodyParams<T>& p, double h) {
    const Mat3T<T>& m = b.m;
    // body-frame angular momentum Lb = R^T L
    T b0 = m[0] * b.lx + m[3] * b.ly + m[6] * b.lz;
    T b1 = m[1] * b.lx + m[4] * b.ly + m[7] * b.lz;
    T b2 = m[2] * b.lx + m[5] * b.ly + m[8] * b.lz;
    const double hh = 0.5 * h;
    QuatT<T> q = b.q;
    flow<0>(q, b0, b1, b2, hh * p.k0);
    flow<1>(q, b0, b1, b2, hh * p.k1);
    flow<2>(q, b0, b1, b2, h * p.k2);
    flow<1>(q, b0, b1, b2, hh * p.k1);
    flow<0>(q, b0, b1, b2, hh * p.k0);
    b.q = normalize4(q[0], q[1], q[2], q[3]);
    b.m = quat_to_mat(b.q[0], b.q[1], b.q[2], b.q[3]);
}

// The coefficients of exp(u) and exp(v), the body-frame rotations by |u| about u and |v| about v:
// c = cos(|u|/2), s = sin(|u|/2) / |u| (the series below 1e-4 rad), so q (x) exp(u) =
// q (x) (c, s u). Both pairs first, each lane's branch apart, the sine-cosine calls back to back
// (the lanes' state live across them is spilled and reloaded once, not per call).
template <class T>
inline void exp_coefs(const Vec3T<T>& u, const Vec3T<T>& v, T& cu, T& su, T& cv, T& sv) {
    constexpr int W = lanes_of<T>();
    const T a2u = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    const T a2v = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    double cc[2 * W], ss[2 * W], s2s[2 * W];
    for (int l = 0; l < W; ++l) {
        s2s[l] = lane(a2u, l);
        s2s[W + l] = lane(a2v, l);
    }
    for (int l = 0; l < 2 * W; ++l) {
        const double a2 = s2s[l];
        if (a2 < 1e-8) {
            cc[l] = 1.0 - a2 / 8.0 + a2 * a2 / 384.0;
            ss[l] = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0;  // sin(a/2) / a
        } else {
            const double a = std::sqrt(a2);
            cc[l] = std::cos(0.5 * a);
            ss[l] = std::sin(0.5 * a) / a;
        }
    }
    for (int l = 0; l < W; ++l) {
        set_lane(cu, l, cc[l]); set_lane(su, l, ss[l]);
        set_lane(cv, l, cc[W + l]); set_lane(sv, l, ss[W + l]);
    }
}

// R(q)^T tau for a unit q.
template <class T>
inline Vec3T<T> torque_body(const QuatT<T>& q, T tx, T ty, T tz) {
    const Mat3T<T> m = quat_to_mat(q[0], q[1], q[2], q[3]);
    return {m[0] * tx + m[3] * ty + m[6] * tz, m[1] * tx + m[4] * ty + m[7] * tz,
            m[2] * tx + m[5] * ty + m[8] * tz};
}

// dLb/dt = Lb x omega + tau_body, omega = I^-1 Lb (Euler's equations, body frame).
template <class T>
inline Vec3T<T> euler_rhs(T b0, T b1, T b2, T k0, T k1, T k2, T t0, T t1, T t2) {
    const T w0 = k0 * b0, w1 = k1 * b1, w2 = k2 * b2;
    return {b1 * w2 - b2 * w1 + t0, b2 * w0 - b0 * w2 + t1, b0 * w1 - b1 * w0 + t2};
}

// One classical RK4 stage attitude q + c (q_s (x) (0, w/2)) for the torque (the torqued lanes'),
// the torque in the body frame e at it taken in those lanes.
template <class T>
inline QuatT<T> stage_attitude(const QuatT<T>& q, const QuatT<T>& q_s, T w0, T w1, T w2, double c,
                               const BodyParams<T>& p, T& e0, T& e1, T& e2) {
    const QuatT<T> k = quat_mul(q_s[0], q_s[1], q_s[2], q_s[3], splat_v<T>(0.0), 0.5 * w0,
                                0.5 * w1, 0.5 * w2);
    const QuatT<T> r = normalize4(q[0] + c * k[0], q[1] + c * k[1], q[2] + c * k[2], q[3] + c * k[3]);
    const Vec3T<T> e = torque_body(r, p.tx, p.ty, p.tz);
    e0 = p.torqued ? e[0] : e0; e1 = p.torqued ? e[1] : e1; e2 = p.torqued ? e[2] : e2;
    return r;
}

// Classical RK4 on Euler's equations for the body momentum Lb, the attitude by the fourth-order
// commutator-free Lie group method driven by the stage angular velocities, then q turned
// (minimally, about an axis normal to L) so that R^T L points along the RK4 Lb.
//
// L (world) is read at the start of the step; the world torque (tx, ty, tz) is constant over the
// step (the caller adds h tau to L). Stages (k = I^-1, tau_b(q) = R(q)^T tau):
//     Lb1 = R^T L;               w_i = k Lb_i;  d_i = Lb_i x w_i + tau_b(q_i)
//     Lb2 = Lb1 + h/2 d1, q2 = q + h/2 q'(q, w1);  Lb3 = Lb1 + h/2 d2, q3 = q + h/2 q'(q2, w2)
//     Lb4 = Lb1 + h d3,   q4 = q + h q'(q3, w3);   Lb' = Lb1 + h/6 (d1 + 2 d2 + 2 d3 + d4)
//     (q'(q, w) = 1/2 q (x) (0, w): the classical stages of the coupled (q, Lb) system)
//     q' = q exp(h B1) exp(h B2),  B1 = w1/4 + (w2 + w3)/6 - w4/12,  B2 = -w1/12 + (w2 + w3)/6 + w4/4
// (Celledoni, Marthinsen & Owren, FGCS 19 (2003), CF4 for q' = q w(t)), then the turn taking
// R(q')^T (L + h tau) to the direction of Lb'. The stage attitudes q_i only serve the torque.
template <class T>
inline void drift_rk4(Body<T>& b, const BodyParams<T>& p, double h) {
    const T k0 = p.k0, k1 = p.k1, k2 = p.k2;
    const QuatT<T> q = b.q;
    Mat3T<T> m = b.m;
    const T a0 = m[0] * b.lx + m[3] * b.ly + m[6] * b.lz;
    const T a1 = m[1] * b.lx + m[4] * b.ly + m[7] * b.lz;
    const T a2 = m[2] * b.lx + m[5] * b.ly + m[8] * b.lz;
    const bool any_torqued = any(p.torqued);
    const double hh = 0.5 * h;
    // stage 1
    const T zero = splat_v<T>(0.0);
    T e0 = zero, e1 = zero, e2 = zero;
    if (any_torqued) {
        e0 = p.torqued ? m[0] * p.tx + m[3] * p.ty + m[6] * p.tz : zero;
        e1 = p.torqued ? m[1] * p.tx + m[4] * p.ty + m[7] * p.tz : zero;
        e2 = p.torqued ? m[2] * p.tx + m[5] * p.ty + m[8] * p.tz : zero;
    }
    const Vec3T<T> d1 = euler_rhs(a0, a1, a2, k0, k1, k2, e0, e1, e2);
    const T w10 = k0 * a0, w11 = k1 * a1, w12 = k2 * a2;
    // stage 2
    T b0 = a0 + hh * d1[0], b1 = a1 + hh * d1[1], b2 = a2 + hh * d1[2];
    QuatT<T> q2 = q, q3 = q;
    if (any_torqued)  // classical stage attitude q2 = q + h/2 q'(q, w1)
        q2 = stage_attitude(q, q, w10, w11, w12, hh, p, e0, e1, e2);
    const Vec3T<T> d2 = euler_rhs(b0, b1, b2, k0, k1, k2, e0, e1, e2);
    const T w20 = k0 * b0, w21 = k1 * b1, w22 = k2 * b2;
    // stage 3
    b0 = a0 + hh * d2[0]; b1 = a1 + hh * d2[1]; b2 = a2 + hh * d2[2];
    if (any_torqued)  // q3 = q + h/2 q'(q2, w2)
        q3 = stage_attitude(q, q2, w20, w21, w22, hh, p, e0, e1, e2);
    const Vec3T<T> d3 = euler_rhs(b0, b1, b2, k0, k1, k2, e0, e1, e2);
    const T w30 = k0 * b0, w31 = k1 * b1, w32 = k2 * b2;
    // stage 4
    b0 = a0 + h * d3[0]; b1 = a1 + h * d3[1]; b2 = a2 + h * d3[2];
    if (any_torqued)  // q4 = q + h q'(q3, w3)
        stage_attitude(q, q3, w30, w31, w32, h, p, e0, e1, e2);
    const Vec3T<T> d4 = euler_rhs(b0, b1, b2, k0, k1, k2, e0, e1, e2);
    const T w40 = k0 * b0, w41 = k1 * b1, w42 = k2 * b2;
    const double g = h / 6.0;
    const T n0 = a0 + g * (d1[0] + 2.0 * d2[0] + 2.0 * d3[0] + d4[0]);
    const T n1 = a1 + g * (d1[1] + 2.0 * d2[1] + 2.0 * d3[1] + d4[1]);
    const T n2 = a2 + g * (d1[2] + 2.0 * d2[2] + 2.0 * d3[2] + d4[2]);
    // attitude: CF4, r = q (x) exp(u) (x) exp(v)
    const double c1 = 1.0 / 4.0, c2 = 1.0 / 6.0, c3 = -1.0 / 12.0;
    const Vec3T<T> u = {h * (c1 * w10 + c2 * (w20 + w30) + c3 * w40),
                        h * (c1 * w11 + c2 * (w21 + w31) + c3 * w41),
                        h * (c1 * w12 + c2 * (w22 + w32) + c3 * w42)};
    const Vec3T<T> v = {h * (c3 * w10 + c2 * (w20 + w30) + c1 * w40),
                        h * (c3 * w11 + c2 * (w21 + w31) + c1 * w41),
                        h * (c3 * w12 + c2 * (w22 + w32) + c1 * w42)};
    T cu, su, cv, sv;
    exp_coefs(u, v, cu, su, cv, sv);
    QuatT<T> r = quat_mul(q[0], q[1], q[2], q[3], cu, su * u[0], su * u[1], su * u[2]);
    r = quat_mul(r[0], r[1], r[2], r[3], cv, sv * v[0], sv * v[1], sv * v[2]);
    r = normalize4(r[0], r[1], r[2], r[3]);
    // turn r so that R^T L_end is along Lb': the rotation c with c u = v (u, v unit), r <- r c^-1
    const T ex = b.lx + h * p.tx, ey = b.ly + h * p.ty, ez = b.lz + h * p.tz;
    m = quat_to_mat(r[0], r[1], r[2], r[3]);
    T u0 = m[0] * ex + m[3] * ey + m[6] * ez;
    T u1 = m[1] * ex + m[4] * ey + m[7] * ez;
    T u2 = m[2] * ex + m[5] * ey + m[8] * ez;
    const T nu = vsqrt(u0 * u0 + u1 * u1 + u2 * u2);
    const T nv = vsqrt(n0 * n0 + n1 * n1 + n2 * n2);
    const mask_of<T> turn = (nu > 0.0) & (nv > 0.0);
    if (any(turn)) {
        const T iu = 1.0 / nu, iv = 1.0 / nv;
        u0 = u0 * iu; u1 = u1 * iu; u2 = u2 * iu;
        const T v0 = n0 * iv, v1 = n1 * iv, v2 = n2 * iv;
        const T cw = 1.0 + u0 * v0 + u1 * v1 + u2 * v2;
        const T cx = u1 * v2 - u2 * v1, cy = u2 * v0 - u0 * v2, cz = u0 * v1 - u1 * v0;
        const QuatT<T> t = quat_mul(r[0], r[1], r[2], r[3], cw, -cx, -cy, -cz);
        for (int k = 0; k < 4; ++k) r[k] = turn ? t[k] : r[k];
    }
    b.q = normalize4(r[0], r[1], r[2], r[3]);
    b.m = quat_to_mat(b.q[0], b.q[1], b.q[2], b.q[3]);
}

// The array forms (body i of the state arrays; the contact step's drift_rotation): the drift
// d(b, p) of body i's attitude and L, q stored too unless with_q is false (seed: from R on demand).
template <class D>
inline void drift_arrays(D d, bool with_q, V2<double> quat_wxyz, V3<double> rotation,
                         V2<double> angular_momentum, V2<double> inv_inertia, i64 i) {
    Body<double> b{};
    BodyParams<double> p{};
    load_rotation(b, p, quat_wxyz, rotation, angular_momentum, inv_inertia, i);
    d(b, p);
    if (with_q) store_quat(quat_wxyz, i, b.q[0], b.q[1], b.q[2], b.q[3]);
    store_mat(rotation, i, b.m);
}

inline void drift_seed(int ortho, V2<double> quat_wxyz, V3<double> rotation,
                       V2<double> angular_momentum, V2<double> inv_inertia, i64 i, double h) {
    drift_arrays([&](Body<double>& b, BodyParams<double>& p) { drift_seed(ortho, b, p, h); },
                 false, quat_wxyz, rotation, angular_momentum, inv_inertia, i);
}

inline void drift_seed_quat(int ortho, V2<double> quat_wxyz, V3<double> rotation,
                            V2<double> angular_momentum, V2<double> inv_inertia, i64 i, double h) {
    drift_arrays([&](Body<double>& b, BodyParams<double>& p) { drift_seed_quat(ortho, b, p, h); },
                 true, quat_wxyz, rotation, angular_momentum, inv_inertia, i);
}

inline void drift_splitting(int ortho, V2<double> quat_wxyz, V3<double> rotation,
                            V2<double> angular_momentum, V2<double> inv_inertia, i64 i, double h) {
    (void)ortho;
    drift_arrays([&](Body<double>& b, BodyParams<double>& p) { drift_splitting(b, p, h); }, true,
                 quat_wxyz, rotation, angular_momentum, inv_inertia, i);
}

inline void drift_rk4(int ortho, V2<double> quat_wxyz, V3<double> rotation,
                      V2<double> angular_momentum, V2<double> inv_inertia, i64 i, double h,
                      double tx = 0.0, double ty = 0.0, double tz = 0.0) {
    (void)ortho;
    drift_arrays(
        [&](Body<double>& b, BodyParams<double>& p) {
            p.tx = tx; p.ty = ty; p.tz = tz;
            p.torqued = tx != 0.0 || ty != 0.0 || tz != 0.0;
            drift_rk4(b, p, h);
        },
        true, quat_wxyz, rotation, angular_momentum, inv_inertia, i);
}

// The exact torque-free rotation over h (L world fixed), to round-off for any h (one-step map).
inline void drift_exact(int ortho, V2<double> quat_wxyz, V3<double> rotation,
                        V2<double> angular_momentum, V2<double> inv_inertia, i64 i, double h) {
    (void)ortho;
    const double* ii = inv_inertia.row(i);
    double q[4];
    free_flow_quat(quat_wxyz(i, 0), quat_wxyz(i, 1), quat_wxyz(i, 2), quat_wxyz(i, 3),
                   angular_momentum(i, 0), angular_momentum(i, 1), angular_momentum(i, 2), ii[0],
                   ii[1], ii[2], h, q);
    store_quat(quat_wxyz, i, q[0], q[1], q[2], q[3]);
    store_mat(rotation, i, quat_to_mat(q[0], q[1], q[2], q[3]));
}

// Row r of fc: the flow constants of the anchor (q_a, L), for steps of h.
inline void anchor_constants(double* row, double aw, double ax, double ay, double az, double lx,
                             double ly, double lz, double k0, double k1, double k2, double h) {
    // Lb = R(q_a)^T L at the anchor; backward in time, the forward flow of -Lb
    const Mat3 m = quat_to_mat(aw, ax, ay, az);
    const double sg = h >= 0.0 ? 1.0 : -1.0;
    flow_constants(row, sg * (m[0] * lx + m[3] * ly + m[6] * lz),
                   sg * (m[1] * lx + m[4] * ly + m[7] * lz), sg * (m[2] * lx + m[5] * ly + m[8] * lz),
                   k0, k1, k2);
}

// q(t) = q_a (x) c(t), unit: the flow at the elapsed time t >= 0 from the anchor q_a whose flow
// constants are the row c, with the sign that keeps it nearest the previous q (pw, px, py, pz):
// the logged q stays continuous. rj_c: the row's FC_RJC as flow_eval returns it (the caller
// stores it).
// q_a (x) c, normalized, with the sign nearest prev (lane-wise for a vector T).
template <class T>
inline QuatT<T> anchored_turn(T aw, T ax, T ay, T az, T cw, T c0, T c1, T c2,
                              const QuatT<T>& prev) {
    const QuatT<T> q = quat_mul(aw, ax, ay, az, cw, c0, c1, c2);
    const T w = q[0], x = q[1], y = q[2], z = q[3];
    T s = 1.0 / vsqrt(w * w + x * x + y * y + z * z);
    s = w * prev[0] + x * prev[1] + y * prev[2] + z * prev[3] < 0.0 ? -s : s;
    return {w * s, x * s, y * s, z * s};
}

inline Quat anchored_quat(const double* c, double aw, double ax, double ay, double az, double t,
                          double pw, double px, double py, double pz, double& rj_c) {
    const FlowOut f = flow_eval(c, t);
    rj_c = f.rj_c;
    return anchored_turn(aw, ax, ay, az, f.cw, f.c0, f.c1, f.c2, Quat{pw, px, py, pz});
}

// Whether a body's flow anchor still serves a step of h with world momentum L: set, the same
// step, L bitwise the anchor's.
inline bool anchor_holds(i64 steps, double anchor_dt, double a0, double a1, double a2, double h,
                         double lx, double ly, double lz) {
    return steps >= 0 && anchor_dt == h && a0 == lx && a1 == ly && a2 == lz;
}

// turn_within_bound from scalars: inverse moments k, world L and R (row-major). The turn is
// |omega| dt with omega = R diag(k) R^T L (k = 1/I_body). For an orthonormal R,
// |omega| <= max(k) |L|, so that cheap bound is tested first and the exact value only above it
// (never in a sane run). An overflowing |L| or omega compares as too large (inf or NaN).
inline bool turn_within_bound_m(double dt, double k0, double k1, double k2, double lx, double ly,
                                double lz, const Mat3& m) {
    const double kmax_dt = py_max(k0, py_max(k1, k2)) * dt;
    const double lim = free_constants.max_rotation_per_step_rad;
    const double lim2 = lim * lim;
    if ((lx * lx + ly * ly + lz * lz) * (kmax_dt * kmax_dt) <= lim2) return true;
    const double w0 = (m[0] * lx + m[3] * ly + m[6] * lz) * k0 * dt;
    const double w1 = (m[1] * lx + m[4] * ly + m[7] * lz) * k1 * dt;
    const double w2 = (m[2] * lx + m[5] * ly + m[8] * lz) * k2 * dt;
    return w0 * w0 + w1 * w1 + w2 * w2 <= lim2;
}

// Position and momentum after dt under the constant force f (inverse mass im): the exact map
// x += h v + h^2 a / 2, v += h a (kick-drift-kick is the same map).
template <class T>
inline void flight_exact(double dt, T im, T& x, T& y, T& z, T& px, T& py, T& pz, T fx, T fy, T fz) {
    const T hh = 0.5 * dt * dt * im;
    x = x + (dt * px * im + hh * fx);
    y = y + (dt * py * im + hh * fy);
    z = z + (dt * pz * im + hh * fz);
    px = px + dt * fx;
    py = py + dt * fy;
    pz = pz + dt * fz;
}

// Inline body of sync_quat for seed: q[i] from the polar factor of R[i] (the largest entry
// divided out first so that a huge but finite R does not overflow in the cofactors).
inline void sync_quat_seed(V2<double> quat_wxyz, V3<double> rotation, i64 i) {
    Mat3 m = load_mat(rotation, i);
    double big = 0.0;
    for (int k = 0; k < 9; ++k) big = py_max(big, std::fabs(m[k]));
    if (big > 0.0 && std::isfinite(big)) {
        const double inv = 1.0 / big;
        for (int k = 0; k < 9; ++k) m[k] = m[k] * inv;
    }
    const Quat q = mat_to_quat(polar(m));
    store_quat(quat_wxyz, i, q[0], q[1], q[2], q[3]);
}

// Inline body of write_sample.
template <int METHOD>
inline void write_sample_t(i64 j, i64 i, V2<double> position, V2<double> linear_momentum,
                           V2<double> quat_wxyz, V3<double> rotation, V2<double> angular_momentum,
                           V3<double> out_position, V3<double> out_linear_momentum,
                           V3<double> out_quat_wxyz, V4<double> out_rotation,
                           V3<double> out_angular_momentum) {
    if (METHOD == METHOD_SEED) sync_quat_seed(quat_wxyz, rotation, i);  // q not current
    for (int a = 0; a < 3; ++a) {
        out_position(j, i, a) = position(i, a);
        out_linear_momentum(j, i, a) = linear_momentum(i, a);
        out_angular_momentum(j, i, a) = angular_momentum(i, a);
        for (int b = 0; b < 3; ++b) out_rotation(j, i, a, b) = rotation(i, a, b);
    }
    for (int a = 0; a < 4; ++a) out_quat_wxyz(j, i, a) = quat_wxyz(i, a);
}

}  // namespace rb
