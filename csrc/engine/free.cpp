// Kernels that advance free bodies (no contacts) many steps per call (rblog/engine/free.py keeps
// the Python entry points, BODY_TILE, SPARSE_STRIDE, MIN_PARALLEL_BODY_STEPS and body_ranges).
//
// Bodies are independent without contacts, so the loop runs over tiles of BODY_TILE bodies, steps
// inside a tile: the tile's state stays in L1 for the whole block, and samples are written for
// consecutive bodies. When samples are SPARSE_STRIDE or more steps apart, bodies are stepped
// several at a time with their whole state in registers for the block: four (AVX2, chosen at
// run time) or two (SSE2) per vector, one body in each lane (lanes.hpp; seed_lanes, rk4_lanes,
// quat_lanes, and exact_lanes for torque-free bodies under exact / exact4), every lane doing the
// scalar step's operations in its order, so the bits do not depend on the width
// (tests/engine/test_free_lanes.py); the rest one body at a time. Each body's step is its
// integrator's step_body below (the stages in integrators.hpp), except under exact / exact4,
// whose kernel writes the same step out in its own body (advance_exact_range; the arithmetic of
// step_body + drift_exact_anchored, operation for operation: tests/engine/test_exact_anchored.py
// compares the two bit for bit).
//
// Samples are written after every stride-th step (and after the last step of the block when
// sample_last), so logging costs nothing between samples.
//
// Each integrator has its own instantiation of the kernel (a template on the METHOD_* code), so
// the step is compiled into the loop with no dispatch inside it.
//
// Threads: advance_free runs contiguous BODY_TILE-aligned body ranges (free.body_ranges) as tasks
// of the engine's pool (rb::pool()). A body's arithmetic does not depend on which range it is in,
// so the result is bitwise the same for any thread count.
#include "engine/free.hpp"

#if defined(__x86_64__) && defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wpsabi"  // d4 arguments of the AVX2 kernels (all inlined)
#endif

#include <atomic>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>

#include "engine/bind.hpp"
#include "engine/integrators.hpp"
#include "engine/lanes.hpp"

#if defined(__x86_64__) && defined(__GNUC__)
#define RB_FREE_AVX2 1
#else
#define RB_FREE_AVX2 0
#endif

namespace rb {

namespace {

int detect_free_lanes() {
#if RB_FREE_AVX2
    __builtin_cpu_init();  // (this runs as a static initializer, maybe before libgcc's own)
    return __builtin_cpu_supports("avx2") ? 4 : 2;
#else
    return 2;
#endif
}

std::atomic<int> g_free_lanes{detect_free_lanes()};

}  // namespace

int free_lanes() { return g_free_lanes.load(std::memory_order_relaxed); }

void set_free_lanes(int lanes) {
    if (lanes != 2 && !(lanes == 4 && detect_free_lanes() == 4))
        throw std::invalid_argument("free kernel lanes: 2, or 4 on a CPU with AVX2; got "
                                    + std::to_string(lanes));
    g_free_lanes.store(lanes, std::memory_order_relaxed);
}

namespace {

// One step of free body i by integrator METHOD (not the exact ones): orientation and L in place,
// position (x, y, z) and momentum (px, py, pz) in registers. Translation: seed / seed-quat
// symplectic Euler, splitting kick-drift-kick and rk4 the exact constant-force step (the same map
// x += h v + h^2 a / 2, v += h a). Returns false if the state became non-finite or the body
// turned more than MAX_ROTATION_PER_STEP_RAD in the step (integrators.step_body).
template <int METHOD>
inline bool step_body(const FreeArgs& a, i64 i, double& x, double& y, double& z, double& px,
                      double& py, double& pz) {
    const double dt = a.dt;
    const int ortho = a.ortho;
    V2<double> L = a.angular_momentum;
    const double im = a.inv_mass[i];
    const double fx = a.force_world(i, 0), fy = a.force_world(i, 1), fz = a.force_world(i, 2);
    const double tx = a.torque_world(i, 0), ty = a.torque_world(i, 1), tz = a.torque_world(i, 2);
    if (METHOD == METHOD_SPLITTING) {
        // kick half, drift, kick half
        const double hh = 0.5 * dt;
        px += hh * fx; py += hh * fy; pz += hh * fz;
        L(i, 0) += hh * tx; L(i, 1) += hh * ty; L(i, 2) += hh * tz;
        x += dt * px * im; y += dt * py * im; z += dt * pz * im;
        drift_splitting(ortho, a.quat_wxyz, a.rotation, L, a.inv_inertia, i, dt);
        px += hh * fx; py += hh * fy; pz += hh * fz;
        L(i, 0) += hh * tx; L(i, 1) += hh * ty; L(i, 2) += hh * tz;
    } else if (METHOD == METHOD_RK4) {
        // translation: exact for a constant force; rotation: RK4 with L(t) = L + t tau
        flight_exact(dt, im, x, y, z, px, py, pz, fx, fy, fz);
        drift_rk4(ortho, a.quat_wxyz, a.rotation, L, a.inv_inertia, i, dt, tx, ty, tz);
        L(i, 0) += dt * tx; L(i, 1) += dt * ty; L(i, 2) += dt * tz;
    } else {
        // the notes: forward Euler on P and L, then x and R from the new values
        px += dt * fx; py += dt * fy; pz += dt * fz;
        x += dt * px * im; y += dt * py * im; z += dt * pz * im;
        L(i, 0) += dt * tx; L(i, 1) += dt * ty; L(i, 2) += dt * tz;
        if (METHOD == METHOD_SEED)
            drift_seed(ortho, a.quat_wxyz, a.rotation, L, a.inv_inertia, i, dt);
        else
            drift_seed_quat(ortho, a.quat_wxyz, a.rotation, L, a.inv_inertia, i, dt);
    }
    // non-finite check: one sum covers position, momenta and part of the rotation
    const double* r = a.rotation.row(i);
    const double chk = x + y + z + px + py + pz + L(i, 0) + L(i, 1) + L(i, 2) + r[0] + r[4] + r[8]
                       + r[1];
    return std::isfinite(chk) && turn_within_bound(dt, i, a.inv_inertia, a.rotation, L);
}

template <int METHOD>
inline void sample(const FreeArgs& a, i64 j, i64 i) {
    write_sample_t<METHOD>(j, i, a.position, a.linear_momentum, a.quat_wxyz, a.rotation,
                           a.angular_momentum, a.out_position, a.out_linear_momentum,
                           a.out_quat_wxyz, a.out_rotation, a.out_angular_momentum);
}

inline bool sample_due(const FreeArgs& a, i64 s) {
    return s % a.stride == 0 || (a.sample_last && s == a.n_steps);
}

// sample_due for the steps s = 1, 2, ... in turn, without an integer division per step (the lane
// kernels' loops): due at the next multiple of stride, and at the last step when sample_last.
struct SampleClock {
    i64 next, stride, last;
    explicit SampleClock(const FreeArgs& a)
        : next(a.stride), stride(a.stride), last(a.sample_last ? a.n_steps : -1) {}
    bool due(i64 s) {
        if (s == next) {
            next += stride;
            return true;
        }
        return s == last;
    }
};

// Body i alone from step s_begin on (its position and momentum in registers), samples from row
// j on: the sparse path of advance_range. Returns the samples written; fail_step the step at
// which the body's state went bad (-1 if none).
template <int METHOD>
i64 single_body(const FreeArgs& a, i64 i, i64 s_begin, i64 j, i64& fail_step) {
    V2<double> pos = a.position, mom = a.linear_momentum;
    fail_step = -1;
    double x = pos(i, 0), y = pos(i, 1), z = pos(i, 2);
    double px = mom(i, 0), py = mom(i, 1), pz = mom(i, 2);
    for (i64 s = s_begin; s <= a.n_steps; ++s) {
        if (!step_body<METHOD>(a, i, x, y, z, px, py, pz)) {
            fail_step = s;
            break;
        }
        if (sample_due(a, s)) {
            pos(i, 0) = x; pos(i, 1) = y; pos(i, 2) = z;
            mom(i, 0) = px; mom(i, 1) = py; mom(i, 2) = pz;
            sample<METHOD>(a, j, i);
            j += 1;
        }
    }
    pos(i, 0) = x; pos(i, 1) = y; pos(i, 2) = z;
    mom(i, 0) = px; mom(i, 1) = py; mom(i, 2) = pz;
    return j;
}

// The end of a lane-wise step_body: the non-finite check (``chk``, the sum of the step's state,
// lane by lane) and turn_within_bound_m, its cheap bound first, per lane; ok[l] set per lane
// unless every lane is ok, which is returned (the common case decided by two lane-wise tests:
// x - x is 0 exactly when x is finite, NaN otherwise). Shared by the lane kernels below.
template <class V, class M = mask_of<V>>
inline bool lanes_ok(bool ok[], double dt, const V& chk, const V m[9], const V& lx,
                     const V& ly, const V& lz, const V& k0, const V& k1, const V& k2,
                     const V& kmax_dt, double lim2) {
    const M cheap = (lx * lx + ly * ly + lz * lz) * (kmax_dt * kmax_dt) <= lim2;
    if (all_set(cheap & ((chk - chk) == V{}))) return true;
    bool all = true;
    for (int l = 0; l < lanes_of<V>(); ++l) {
        ok[l] = std::isfinite(chk[l]);
        if (ok[l] && !cheap[l]) {
            const Mat3 ml = {m[0][l], m[1][l], m[2][l], m[3][l], m[4][l], m[5][l], m[6][l],
                             m[7][l], m[8][l]};
            ok[l] = turn_within_bound_m(dt, k0[l], k1[l], k2[l], lx[l], ly[l], lz[l], ml);
        }
        all = all && ok[l];
    }
    return all;
}

// After a lane kernel's loop stopped at step s with j samples (its state stored): every lane ran
// to the end, or a lane went bad at s (its bad step), or another lane did and this one goes on
// alone (single_body) from s + 1.
template <int METHOD, int W>
inline void finish_lanes(const FreeArgs& a, i64 i, i64 s, i64 j, const bool ok[W], i64 j_out[W],
                         i64 fail_out[W]) {
    for (int l = 0; l < W; ++l) {
        const i64 b = i + l;
        if (s > a.n_steps) {
            j_out[l] = j;
            fail_out[l] = -1;
        } else if (!ok[l]) {
            j_out[l] = j;
            fail_out[l] = s;
        } else {
            j_out[l] = single_body<METHOD>(a, b, s + 1, j, fail_out[l]);
        }
    }
}

// Bodies i .. i + W - 1 of seed (ortho polar or none) in the W lanes of V (lanes.hpp), state in
// registers: step_body<METHOD_SEED> and drift_seed / polar / turn_within_bound_m lane by lane,
// operation for operation. When a lane's state goes bad at step s, every lane has taken step s
// (as the scalar loop would); the others then go on alone (single_body) from s + 1.
// Returns the samples of each body in j_out, their bad steps in fail_out.
template <class V, class M = mask_of<V>>
inline void seed_lanes(const FreeArgs& a, i64 i, i64 j_out[], i64 fail_out[]) {
    constexpr int W = lanes_of<V>();
    const double dt = a.dt;
    const int ortho = a.ortho;
    V2<double> pos = a.position, mom = a.linear_momentum, L = a.angular_momentum;
    V3<double> R = a.rotation;
    auto ld = [i](V2<double> v, int c) {
        V r;
        for (int l = 0; l < W; ++l) r[l] = v(i + l, c);
        return r;
    };
    V im;
    for (int l = 0; l < W; ++l) im[l] = a.inv_mass[i + l];
    const V fx = ld(a.force_world, 0), fy = ld(a.force_world, 1),
             fz = ld(a.force_world, 2);
    const V tx = ld(a.torque_world, 0), ty = ld(a.torque_world, 1),
             tz = ld(a.torque_world, 2);
    const V k0 = ld(a.inv_inertia, 0), k1 = ld(a.inv_inertia, 1),
             k2 = ld(a.inv_inertia, 2);
    // turn_within_bound_m's cheap bound, a constant of the body
    const V kmax_dt = vpymax(k0, vpymax(k1, k2)) * dt;
    const double lim = free_constants.max_rotation_per_step_rad;
    const double lim2 = lim * lim;
    V x = ld(pos, 0), y = ld(pos, 1), z = ld(pos, 2);
    V px = ld(mom, 0), py = ld(mom, 1), pz = ld(mom, 2);
    V lx = ld(L, 0), ly = ld(L, 1), lz = ld(L, 2);
    V m[9];
    for (int c = 0; c < 9; ++c)
        for (int l = 0; l < W; ++l) m[c][l] = R.row(i + l)[c];
    auto store = [&]() {
        for (int l = 0; l < W; ++l) {
            const i64 b = i + l;
            pos(b, 0) = x[l]; pos(b, 1) = y[l]; pos(b, 2) = z[l];
            mom(b, 0) = px[l]; mom(b, 1) = py[l]; mom(b, 2) = pz[l];
            L(b, 0) = lx[l]; L(b, 1) = ly[l]; L(b, 2) = lz[l];
            for (int c = 0; c < 9; ++c) R.row(b)[c] = m[c][l];
        }
    };
    i64 j = 0;
    bool ok[W];
    for (int l = 0; l < W; ++l) ok[l] = true;
    SampleClock clock(a);
    i64 s = 1;
    for (; s <= a.n_steps; ++s) {
        // the notes: forward Euler on P and L, then x and R from the new values
        px += dt * fx; py += dt * fy; pz += dt * fz;
        x += dt * px * im; y += dt * py * im; z += dt * pz * im;
        lx += dt * tx; ly += dt * ty; lz += dt * tz;
        // drift_seed: omega = R I^-1 R^T L (omega_world), R <- R + h [omega]x R
        const V m00 = m[0], m01 = m[1], m02 = m[2], m10 = m[3], m11 = m[4], m12 = m[5],
                 m20 = m[6], m21 = m[7], m22 = m[8];
        const V b0 = (m00 * lx + m10 * ly + m20 * lz) * k0;
        const V b1 = (m01 * lx + m11 * ly + m21 * lz) * k1;
        const V b2 = (m02 * lx + m12 * ly + m22 * lz) * k2;
        const V ox = m00 * b0 + m01 * b1 + m02 * b2;
        const V oy = m10 * b0 + m11 * b1 + m12 * b2;
        const V oz = m20 * b0 + m21 * b1 + m22 * b2;
        const double h = dt;
        V a00 = m00 + h * (-oz * m10 + oy * m20), a01 = m01 + h * (-oz * m11 + oy * m21),
           a02 = m02 + h * (-oz * m12 + oy * m22),
           a10 = m10 + h * (oz * m00 - ox * m20), a11 = m11 + h * (oz * m01 - ox * m21),
           a12 = m12 + h * (oz * m02 - ox * m22),
           a20 = m20 + h * (-oy * m00 + ox * m10), a21 = m21 + h * (-oy * m01 + ox * m11),
           a22 = m22 + h * (-oy * m02 + ox * m12);
        if (ortho == ORTHO_POLAR) {  // rotation.hpp polar, lane-wise
            const std::array<V, 9> p = polar(std::array<V, 9>{a00, a01, a02, a10, a11, a12,
                                                               a20, a21, a22});
            a00 = p[0]; a01 = p[1]; a02 = p[2]; a10 = p[3]; a11 = p[4]; a12 = p[5];
            a20 = p[6]; a21 = p[7]; a22 = p[8];
        }
        m[0] = a00; m[1] = a01; m[2] = a02; m[3] = a10; m[4] = a11; m[5] = a12;
        m[6] = a20; m[7] = a21; m[8] = a22;
        // non-finite check and turn bound (step_body, turn_within_bound_m)
        if (!lanes_ok(ok, dt, x + y + z + px + py + pz + lx + ly + lz + m[0] + m[4] + m[8] + m[1], m,
                 lx, ly, lz, k0, k1, k2, kmax_dt, lim2))
            break;
        if (clock.due(s)) {
            store();
            for (int l = 0; l < W; ++l) sample<METHOD_SEED>(a, j, i + l);
            j += 1;
        }
    }
    store();
    finish_lanes<METHOD_SEED, W>(a, i, s, j, ok, j_out, fail_out);
}

// ---- rk4, W bodies in the lanes of V (integrators.hpp drift_rk4, lane by lane) -------------

template <class V>
struct QV {
    V w, x, y, z;
};

template <class V>
inline QV<V> qmul2(V aw, V ax, V ay, V az, V bw, V bx, V by, V bz) {
    return {aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw};
}

template <class V>
inline QV<V> normalize2(V w, V x, V y, V z) {
    const V n = 1.0 / vsqrt(w * w + x * x + y * y + z * z);
    return {w * n, x * n, y * n, z * n};
}

template <class V>
inline void mat2(const QV<V>& q, V m[9]) {
    const V w = q.w, x = q.x, y = q.y, z = q.z;
    m[0] = w * w + x * x - y * y - z * z; m[1] = 2.0 * (x * y - w * z); m[2] = 2.0 * (x * z + w * y);
    m[3] = 2.0 * (x * y + w * z); m[4] = w * w - x * x + y * y - z * z; m[5] = 2.0 * (y * z - w * x);
    m[6] = 2.0 * (x * z - w * y); m[7] = 2.0 * (y * z + w * x); m[8] = w * w - x * x - y * y + z * z;
}

// mul_exp's coefficients (cos |v|/2, sin(|v|/2) / |v|, or the small-angle series) of two
// vectors u and v lane-wise, the scalar branch per lane; the four sine-cosine calls back to back,
// so that the state live across them is spilled and reloaded once per step, not per call.
template <class V>
inline void exp_coefs2(V ux, V uy, V uz, V vx, V vy, V vz, V& cu, V& su, V& cv,
                       V& sv) {
    constexpr int W = lanes_of<V>();
    const V a2u = ux * ux + uy * uy + uz * uz;
    const V a2v = vx * vx + vy * vy + vz * vz;
    double cc[2 * W], ss[2 * W], s2s[2 * W];
    for (int l = 0; l < W; ++l) {
        s2s[l] = a2u[l];
        s2s[W + l] = a2v[l];
    }
    for (int l = 0; l < 2 * W; ++l) {
        const double s2 = s2s[l];
        if (s2 < 1e-8) {
            cc[l] = 1.0 - s2 / 8.0 + s2 * s2 / 384.0;
            ss[l] = 0.5 - s2 / 48.0 + s2 * s2 / 3840.0;
        } else {
            const double an = std::sqrt(s2);
            cc[l] = std::cos(0.5 * an);
            ss[l] = std::sin(0.5 * an) / an;
        }
    }
    for (int l = 0; l < W; ++l) {
        cu[l] = cc[l]; su[l] = ss[l];
        cv[l] = cc[W + l]; sv[l] = ss[W + l];
    }
}

// R(q)^T tau lane-wise (torque_body)
template <class V>
inline void torque_body2(const QV<V>& q, V tx, V ty, V tz, V& e0, V& e1, V& e2) {
    V m[9];
    mat2(q, m);
    e0 = m[0] * tx + m[3] * ty + m[6] * tz;
    e1 = m[1] * tx + m[4] * ty + m[7] * tz;
    e2 = m[2] * tx + m[5] * ty + m[8] * tz;
}

// Bodies i .. i + W - 1 of rk4 in the lanes of V, state (position, momentum, L, q, R) in
// registers: step_body<METHOD_RK4> (flight_exact, drift_rk4, the torque kick, the checks) lane by
// lane, operation for operation; lane-dependent branches (torque, the small-angle series, the
// final turn) by per-lane selection of the scalar branch's values. As seed_lanes otherwise.
template <class V, class M = mask_of<V>>
inline void rk4_lanes(const FreeArgs& a, i64 i, i64 j_out[], i64 fail_out[]) {
    constexpr int W = lanes_of<V>();
    const double dt = a.dt;
    V2<double> pos = a.position, mom = a.linear_momentum, L = a.angular_momentum, Q = a.quat_wxyz;
    V3<double> R = a.rotation;
    auto ld = [i](V2<double> v, int c) {
        V r;
        for (int l = 0; l < W; ++l) r[l] = v(i + l, c);
        return r;
    };
    V im;
    for (int l = 0; l < W; ++l) im[l] = a.inv_mass[i + l];
    const V fx = ld(a.force_world, 0), fy = ld(a.force_world, 1),
             fz = ld(a.force_world, 2);
    const V tx = ld(a.torque_world, 0), ty = ld(a.torque_world, 1),
             tz = ld(a.torque_world, 2);
    const V k0 = ld(a.inv_inertia, 0), k1 = ld(a.inv_inertia, 1),
             k2 = ld(a.inv_inertia, 2);
    const M torqued = (tx != 0.0) | (ty != 0.0) | (tz != 0.0);
    const bool any_torqued = any(torqued);
    const V kmax_dt = vpymax(k0, vpymax(k1, k2)) * dt;
    const double lim = free_constants.max_rotation_per_step_rad;
    const double lim2 = lim * lim;
    const V zero = splat_v<V>(0.0);
    V x = ld(pos, 0), y = ld(pos, 1), z = ld(pos, 2);
    V px = ld(mom, 0), py = ld(mom, 1), pz = ld(mom, 2);
    V lx = ld(L, 0), ly = ld(L, 1), lz = ld(L, 2);
    QV<V> q = {ld(Q, 0), ld(Q, 1), ld(Q, 2), ld(Q, 3)};
    V m[9];
    for (int c = 0; c < 9; ++c)
        for (int l = 0; l < W; ++l) m[c][l] = R.row(i + l)[c];
    auto store = [&]() {
        for (int l = 0; l < W; ++l) {
            const i64 b = i + l;
            pos(b, 0) = x[l]; pos(b, 1) = y[l]; pos(b, 2) = z[l];
            mom(b, 0) = px[l]; mom(b, 1) = py[l]; mom(b, 2) = pz[l];
            L(b, 0) = lx[l]; L(b, 1) = ly[l]; L(b, 2) = lz[l];
            Q(b, 0) = q.w[l]; Q(b, 1) = q.x[l]; Q(b, 2) = q.y[l]; Q(b, 3) = q.z[l];
            for (int c = 0; c < 9; ++c) R.row(b)[c] = m[c][l];
        }
    };
    const double h = dt, hh = 0.5 * h;
    const double hh_flight = 0.5 * dt * dt;
    const double g = h / 6.0;
    const double c1 = 1.0 / 4.0, c2 = 1.0 / 6.0, c3 = -1.0 / 12.0;
    i64 j = 0;
    bool ok[W];
    for (int l = 0; l < W; ++l) ok[l] = true;
    SampleClock clock(a);
    i64 s = 1;
    for (; s <= a.n_steps; ++s) {
        // translation: exact for a constant force (flight_exact)
        const V hf = hh_flight * im;
        x = x + (dt * px * im + hf * fx);
        y = y + (dt * py * im + hf * fy);
        z = z + (dt * pz * im + hf * fz);
        px = px + dt * fx; py = py + dt * fy; pz = pz + dt * fz;
        // drift_rk4
        const V a0 = m[0] * lx + m[3] * ly + m[6] * lz;
        const V a1 = m[1] * lx + m[4] * ly + m[7] * lz;
        const V a2 = m[2] * lx + m[5] * ly + m[8] * lz;
        V e0 = zero, e1 = zero, e2 = zero;
        if (any_torqued) {
            e0 = torqued ? m[0] * tx + m[3] * ty + m[6] * tz : zero;
            e1 = torqued ? m[1] * tx + m[4] * ty + m[7] * tz : zero;
            e2 = torqued ? m[2] * tx + m[5] * ty + m[8] * tz : zero;
        }
        // stage 1 (euler_rhs)
        V w0 = k0 * a0, w1 = k1 * a1, w2 = k2 * a2;
        const V d10 = a1 * w2 - a2 * w1 + e0, d11 = a2 * w0 - a0 * w2 + e1, d12 = a0 * w1 - a1 * w0 + e2;
        const V w10 = k0 * a0, w11 = k1 * a1, w12 = k2 * a2;
        // stage 2
        V b0 = a0 + hh * d10, b1 = a1 + hh * d11, b2 = a2 + hh * d12;
        QV<V> q2 = q, q3 = q;
        if (any_torqued) {
            const QV<V> k1q = qmul2(q.w, q.x, q.y, q.z, zero, 0.5 * w10, 0.5 * w11, 0.5 * w12);
            q2 = normalize2(q.w + hh * k1q.w, q.x + hh * k1q.x, q.y + hh * k1q.y, q.z + hh * k1q.z);
            V f0, f1, f2;
            torque_body2(q2, tx, ty, tz, f0, f1, f2);
            e0 = torqued ? f0 : e0; e1 = torqued ? f1 : e1; e2 = torqued ? f2 : e2;
        }
        w0 = k0 * b0; w1 = k1 * b1; w2 = k2 * b2;
        const V d20 = b1 * w2 - b2 * w1 + e0, d21 = b2 * w0 - b0 * w2 + e1, d22 = b0 * w1 - b1 * w0 + e2;
        const V w20 = k0 * b0, w21 = k1 * b1, w22 = k2 * b2;
        // stage 3
        b0 = a0 + hh * d20; b1 = a1 + hh * d21; b2 = a2 + hh * d22;
        if (any_torqued) {
            const QV<V> k2q = qmul2(q2.w, q2.x, q2.y, q2.z, zero, 0.5 * w20, 0.5 * w21, 0.5 * w22);
            q3 = normalize2(q.w + hh * k2q.w, q.x + hh * k2q.x, q.y + hh * k2q.y, q.z + hh * k2q.z);
            V f0, f1, f2;
            torque_body2(q3, tx, ty, tz, f0, f1, f2);
            e0 = torqued ? f0 : e0; e1 = torqued ? f1 : e1; e2 = torqued ? f2 : e2;
        }
        w0 = k0 * b0; w1 = k1 * b1; w2 = k2 * b2;
        const V d30 = b1 * w2 - b2 * w1 + e0, d31 = b2 * w0 - b0 * w2 + e1, d32 = b0 * w1 - b1 * w0 + e2;
        const V w30 = k0 * b0, w31 = k1 * b1, w32 = k2 * b2;
        // stage 4
        b0 = a0 + h * d30; b1 = a1 + h * d31; b2 = a2 + h * d32;
        if (any_torqued) {
            const QV<V> k3q = qmul2(q3.w, q3.x, q3.y, q3.z, zero, 0.5 * w30, 0.5 * w31, 0.5 * w32);
            const QV<V> q4 = normalize2(q.w + h * k3q.w, q.x + h * k3q.x, q.y + h * k3q.y, q.z + h * k3q.z);
            V f0, f1, f2;
            torque_body2(q4, tx, ty, tz, f0, f1, f2);
            e0 = torqued ? f0 : e0; e1 = torqued ? f1 : e1; e2 = torqued ? f2 : e2;
        }
        w0 = k0 * b0; w1 = k1 * b1; w2 = k2 * b2;
        const V d40 = b1 * w2 - b2 * w1 + e0, d41 = b2 * w0 - b0 * w2 + e1, d42 = b0 * w1 - b1 * w0 + e2;
        const V w40 = k0 * b0, w41 = k1 * b1, w42 = k2 * b2;
        const V n0 = a0 + g * (d10 + 2.0 * d20 + 2.0 * d30 + d40);
        const V n1 = a1 + g * (d11 + 2.0 * d21 + 2.0 * d31 + d41);
        const V n2 = a2 + g * (d12 + 2.0 * d22 + 2.0 * d32 + d42);
        // attitude: CF4
        // r = mul_exp(mul_exp(q, u), v): both exponents depend on the stages only, so their
        // coefficients come first (exp_coefs2), then the two products
        const V ux = h * (c1 * w10 + c2 * (w20 + w30) + c3 * w40),
                 uy = h * (c1 * w11 + c2 * (w21 + w31) + c3 * w41),
                 uz = h * (c1 * w12 + c2 * (w22 + w32) + c3 * w42);
        const V vx = h * (c3 * w10 + c2 * (w20 + w30) + c1 * w40),
                 vy = h * (c3 * w11 + c2 * (w21 + w31) + c1 * w41),
                 vz = h * (c3 * w12 + c2 * (w22 + w32) + c1 * w42);
        V cu, su, cv, sv;
        exp_coefs2(ux, uy, uz, vx, vy, vz, cu, su, cv, sv);
        QV<V> r = qmul2(q.w, q.x, q.y, q.z, cu, su * ux, su * uy, su * uz);
        r = qmul2(r.w, r.x, r.y, r.z, cv, sv * vx, sv * vy, sv * vz);
        r = normalize2(r.w, r.x, r.y, r.z);
        // turn q so that R^T L_end is along Lb'
        const V ex = lx + h * tx, ey = ly + h * ty, ez = lz + h * tz;
        mat2(r, m);
        V u0 = m[0] * ex + m[3] * ey + m[6] * ez;
        V u1 = m[1] * ex + m[4] * ey + m[7] * ez;
        V u2 = m[2] * ex + m[5] * ey + m[8] * ez;
        const V nu = vsqrt(u0 * u0 + u1 * u1 + u2 * u2);
        const V nv = vsqrt(n0 * n0 + n1 * n1 + n2 * n2);
        const M turn = (nu > 0.0) & (nv > 0.0);
        if (any(turn)) {
            const V iu = 1.0 / nu, iv = 1.0 / nv;
            u0 = u0 * iu; u1 = u1 * iu; u2 = u2 * iu;
            const V v0 = n0 * iv, v1 = n1 * iv, v2 = n2 * iv;
            const V cw = 1.0 + u0 * v0 + u1 * v1 + u2 * v2;
            const V cx = u1 * v2 - u2 * v1, cy = u2 * v0 - u0 * v2, cz = u0 * v1 - u1 * v0;
            const QV<V> t = qmul2(r.w, r.x, r.y, r.z, cw, -cx, -cy, -cz);
            r.w = turn ? t.w : r.w; r.x = turn ? t.x : r.x;
            r.y = turn ? t.y : r.y; r.z = turn ? t.z : r.z;
        }
        q = normalize2(r.w, r.x, r.y, r.z);
        mat2(q, m);
        // the torque kick
        lx += dt * tx; ly += dt * ty; lz += dt * tz;
        // non-finite check and turn bound
        if (!lanes_ok(ok, dt, x + y + z + px + py + pz + lx + ly + lz + m[0] + m[4] + m[8] + m[1], m,
                 lx, ly, lz, k0, k1, k2, kmax_dt, lim2))
            break;
        if (clock.due(s)) {
            store();
            for (int l = 0; l < W; ++l) sample<METHOD_RK4>(a, j, i + l);
            j += 1;
        }
    }
    store();
    finish_lanes<METHOD_RK4, W>(a, i, s, j, ok, j_out, fail_out);
}

// ---- seed-quat (normalized) and splitting, two bodies in the lanes of V --------------------

// One lane-wise sub-flow of the splitting (integrators.hpp flow_x / flow_y / flow_z): axis `ax`,
// s_inv_i = s / I_k per lane; the half-angle sine and cosine per lane (scalar calls).
template <int AX, class V>
inline void flow2(QV<V>& q, V& b0, V& b1, V& b2, V s_inv_i) {
    const V th = s_inv_i * (AX == 0 ? b0 : AX == 1 ? b1 : b2);
    V ch, sh;
    for (int l = 0; l < lanes_of<V>(); ++l) {
        ch[l] = std::cos(0.5 * th[l]);
        sh[l] = std::sin(0.5 * th[l]);
    }
    const V c = ch * ch - sh * sh, sn = 2.0 * ch * sh;
    const V w = q.w, x = q.x, y = q.y, z = q.z;
    if (AX == 0) {
        q = {ch * w - sh * x, ch * x + sh * w, ch * y + sh * z, ch * z - sh * y};
        const V n1 = c * b1 + sn * b2, n2 = c * b2 - sn * b1;
        b1 = n1; b2 = n2;
    } else if (AX == 1) {
        q = {ch * w - sh * y, ch * x - sh * z, ch * y + sh * w, ch * z + sh * x};
        const V n0 = c * b0 - sn * b2, n2 = c * b2 + sn * b0;
        b0 = n0; b2 = n2;
    } else {
        q = {ch * w - sh * z, ch * x + sh * y, ch * y - sh * x, ch * z + sh * w};
        const V n0 = c * b0 + sn * b1, n1 = c * b1 - sn * b0;
        b0 = n0; b1 = n1;
    }
}

// Bodies i .. i + W - 1 of seed-quat (ortho normalize) or splitting in the lanes of V, state in
// registers: step_body<METHOD> with drift_seed_quat / drift_splitting lane by lane, operation for
// operation. As seed_lanes otherwise.
template <int METHOD, class V, class M = mask_of<V>>
inline void quat_lanes(const FreeArgs& a, i64 i, i64 j_out[], i64 fail_out[]) {
    constexpr int W = lanes_of<V>();
    const double dt = a.dt;
    V2<double> pos = a.position, mom = a.linear_momentum, L = a.angular_momentum, Q = a.quat_wxyz;
    V3<double> R = a.rotation;
    auto ld = [i](V2<double> v, int c) {
        V r;
        for (int l = 0; l < W; ++l) r[l] = v(i + l, c);
        return r;
    };
    V im;
    for (int l = 0; l < W; ++l) im[l] = a.inv_mass[i + l];
    const V fx = ld(a.force_world, 0), fy = ld(a.force_world, 1),
             fz = ld(a.force_world, 2);
    const V tx = ld(a.torque_world, 0), ty = ld(a.torque_world, 1),
             tz = ld(a.torque_world, 2);
    const V k0 = ld(a.inv_inertia, 0), k1 = ld(a.inv_inertia, 1),
             k2 = ld(a.inv_inertia, 2);
    const V kmax_dt = vpymax(k0, vpymax(k1, k2)) * dt;
    const double lim = free_constants.max_rotation_per_step_rad;
    const double lim2 = lim * lim;
    V x = ld(pos, 0), y = ld(pos, 1), z = ld(pos, 2);
    V px = ld(mom, 0), py = ld(mom, 1), pz = ld(mom, 2);
    V lx = ld(L, 0), ly = ld(L, 1), lz = ld(L, 2);
    QV<V> q = {ld(Q, 0), ld(Q, 1), ld(Q, 2), ld(Q, 3)};
    V m[9];
    for (int c = 0; c < 9; ++c)
        for (int l = 0; l < W; ++l) m[c][l] = R.row(i + l)[c];
    auto store = [&]() {
        for (int l = 0; l < W; ++l) {
            const i64 b = i + l;
            pos(b, 0) = x[l]; pos(b, 1) = y[l]; pos(b, 2) = z[l];
            mom(b, 0) = px[l]; mom(b, 1) = py[l]; mom(b, 2) = pz[l];
            L(b, 0) = lx[l]; L(b, 1) = ly[l]; L(b, 2) = lz[l];
            Q(b, 0) = q.w[l]; Q(b, 1) = q.x[l]; Q(b, 2) = q.y[l]; Q(b, 3) = q.z[l];
            for (int c = 0; c < 9; ++c) R.row(b)[c] = m[c][l];
        }
    };
    const double h = dt, hh = 0.5 * dt;
    const V zero = splat_v<V>(0.0);
    i64 j = 0;
    bool ok[W];
    for (int l = 0; l < W; ++l) ok[l] = true;
    SampleClock clock(a);
    i64 s = 1;
    for (; s <= a.n_steps; ++s) {
        if (METHOD == METHOD_SPLITTING) {
            // kick half, drift, kick half
            px += hh * fx; py += hh * fy; pz += hh * fz;
            lx += hh * tx; ly += hh * ty; lz += hh * tz;
            x += dt * px * im; y += dt * py * im; z += dt * pz * im;
            // drift_splitting: Lb = R^T L, 1(h/2) 2(h/2) 3(h) 2(h/2) 1(h/2), normalized
            V b0 = m[0] * lx + m[3] * ly + m[6] * lz;
            V b1 = m[1] * lx + m[4] * ly + m[7] * lz;
            V b2 = m[2] * lx + m[5] * ly + m[8] * lz;
            flow2<0>(q, b0, b1, b2, hh * k0);
            flow2<1>(q, b0, b1, b2, hh * k1);
            flow2<2>(q, b0, b1, b2, h * k2);
            flow2<1>(q, b0, b1, b2, hh * k1);
            flow2<0>(q, b0, b1, b2, hh * k0);
            q = normalize2(q.w, q.x, q.y, q.z);
            mat2(q, m);
            px += hh * fx; py += hh * fy; pz += hh * fz;
            lx += hh * tx; ly += hh * ty; lz += hh * tz;
        } else {
            // the notes: forward Euler on P and L, then x and q from the new values
            px += dt * fx; py += dt * fy; pz += dt * fz;
            x += dt * px * im; y += dt * py * im; z += dt * pz * im;
            lx += dt * tx; ly += dt * ty; lz += dt * tz;
            // drift_seed_quat (normalized): omega_world, q += h/2 (0, omega) (x) q
            const V b0 = (m[0] * lx + m[3] * ly + m[6] * lz) * k0;
            const V b1 = (m[1] * lx + m[4] * ly + m[7] * lz) * k1;
            const V b2 = (m[2] * lx + m[5] * ly + m[8] * lz) * k2;
            const V ox = m[0] * b0 + m[1] * b1 + m[2] * b2;
            const V oy = m[3] * b0 + m[4] * b1 + m[5] * b2;
            const V oz = m[6] * b0 + m[7] * b1 + m[8] * b2;
            const QV<V> d = qmul2(zero, ox, oy, oz, q.w, q.x, q.y, q.z);
            q = normalize2(q.w + 0.5 * h * d.w, q.x + 0.5 * h * d.x, q.y + 0.5 * h * d.y,
                           q.z + 0.5 * h * d.z);
            mat2(q, m);
        }
        if (!lanes_ok(ok, dt, x + y + z + px + py + pz + lx + ly + lz + m[0] + m[4] + m[8] + m[1], m,
                 lx, ly, lz, k0, k1, k2, kmax_dt, lim2))
            break;
        if (clock.due(s)) {
            store();
            for (int l = 0; l < W; ++l) sample<METHOD>(a, j, i + l);
            j += 1;
        }
    }
    store();
    finish_lanes<METHOD, W>(a, i, s, j, ok, j_out, fail_out);
}

// W bodies from i by METHOD's lane kernel.
template <int METHOD, class V>
inline void run_lanes(const FreeArgs& a, i64 i, i64 j_out[], i64 fail_out[]) {
    if (METHOD == METHOD_SEED)
        seed_lanes<V>(a, i, j_out, fail_out);
    else if (METHOD == METHOD_RK4)
        rk4_lanes<V>(a, i, j_out, fail_out);
    else
        quat_lanes<METHOD, V>(a, i, j_out, fail_out);
}

#if RB_FREE_AVX2
// run_lanes on four bodies, compiled for AVX2 (without FMA): everything it calls is inlined into
// it (flatten), so the whole kernel, its one-body tail included, is built for that target. Called
// only when the CPU has AVX2 (free_lanes() == 4).
template <int METHOD>
__attribute__((target("avx2"), flatten, noinline)) void run_lanes4(const FreeArgs& a, i64 i,
                                                                   i64 j_out[4],
                                                                   i64 fail_out[4]) {
    run_lanes<METHOD, d4>(a, i, j_out, fail_out);
}
#endif

// Bodies b0 .. b1-1, n_steps steps of dt, samples written (advance_free_range's contract).
template <int METHOD>
FreeResult advance_range(const FreeArgs& a, i64 b0, i64 b1) {
    FreeResult res;
    const i64 tile = a.tile;
    V2<double> pos = a.position, mom = a.linear_momentum;
    auto fail = [&](i64 s, i64 i) {
        if (s >= 0 && (res.bad_step < 0 || s < res.bad_step)) {
            res.bad_step = s;
            res.bad_body = i;
        }
    };
#ifndef RB_FREE_NO_LANES  // (defined: the scalar path only, to compare the lanes against it)
    if (tile == 1 && ((METHOD == METHOD_SEED && (a.ortho == ORTHO_POLAR || a.ortho == ORTHO_NONE))
                      || (METHOD == METHOD_SEED_QUAT && a.ortho != ORTHO_NONE)
                      || METHOD == METHOD_SPLITTING || METHOD == METHOD_RK4)) {
        // sparse samples: bodies four (AVX2) or two at a time in the lanes of a vector, then
        // two, then the odd one (a body's bits do not depend on the lanes it ran in)
        i64 i = b0;
        auto collect = [&](i64 i0, int w, const i64* js, const i64* fs) {
            for (int l = 0; l < w; ++l) {
                fail(fs[l], i0 + l);
                if (METHOD == METHOD_SEED) sync_quat_seed(a.quat_wxyz, a.rotation, i0 + l);
                if (js[l] > res.n_samples) res.n_samples = js[l];
            }
        };
#if RB_FREE_AVX2
        if (free_lanes() == 4) {
            for (; i + 3 < b1; i += 4) {
                i64 js[4], fs[4];
                run_lanes4<METHOD>(a, i, js, fs);
                collect(i, 4, js, fs);
            }
        }
#endif
        for (; i + 1 < b1; i += 2) {
            i64 js[2], fs[2];
            run_lanes<METHOD, d2>(a, i, js, fs);
            collect(i, 2, js, fs);
        }
        for (; i < b1; ++i) {
            i64 fs;
            const i64 j = single_body<METHOD>(a, i, 1, 0, fs);
            fail(fs, i);
            if (METHOD == METHOD_SEED) sync_quat_seed(a.quat_wxyz, a.rotation, i);
            if (j > res.n_samples) res.n_samples = j;
        }
        return res;
    }
#endif
    for (i64 t0 = b0; t0 < b1; t0 += tile) {
        const i64 t1 = t0 + tile < b1 ? t0 + tile : b1;
        i64 j = 0;
        if (tile == 1) {
            i64 fs;
            j = single_body<METHOD>(a, t0, 1, 0, fs);
            fail(fs, t0);
        } else {
            for (i64 s = 1; s <= a.n_steps; ++s) {
                bool ok = true;
                for (i64 i = t0; i < t1; ++i) {
                    double x = pos(i, 0), y = pos(i, 1), z = pos(i, 2);
                    double px = mom(i, 0), py = mom(i, 1), pz = mom(i, 2);
                    ok = step_body<METHOD>(a, i, x, y, z, px, py, pz);
                    pos(i, 0) = x; pos(i, 1) = y; pos(i, 2) = z;
                    mom(i, 0) = px; mom(i, 1) = py; mom(i, 2) = pz;
                    if (!ok) {
                        fail(s, i);
                        break;
                    }
                }
                if (!ok) break;
                if (sample_due(a, s)) {
                    for (i64 i = t0; i < t1; ++i) sample<METHOD>(a, j, i);
                    j += 1;
                }
            }
        }
        if (METHOD == METHOD_SEED)  // the only integrator whose q is not current
            for (i64 i = t0; i < t1; ++i) sync_quat_seed(a.quat_wxyz, a.rotation, i);
        if (j > res.n_samples) res.n_samples = j;
    }
    return res;
}

// Body i of exact / exact4 alone from step s_begin on, samples from row j on (the sparse path of
// advance_exact_range, tile 1): its state, anchor and flow-constant validity in locals for the
// whole block (the arrays written when a sample is due and at the end), the step exactly
// advance_exact_range's. The flow constants are recomputed from the anchor on the first step
// (a pure function of it, so a start at s_begin > 1 continues bit for bit). Returns the samples
// written; fail_step the step at which the state went bad (-1 if none).
template <int METHOD>
i64 exact_single(const FreeArgs& a, i64 i, double* row, i64 s_begin, i64 j, i64& fail_step) {
    const double dt = a.dt;
    const double w1 = yoshida_w1(), w0 = yoshida_w0();
    V2<double> pos = a.position, mom = a.linear_momentum, L = a.angular_momentum, Q = a.quat_wxyz;
    V3<double> R = a.rotation;
    V2<double> a_q = a.a_q, a_l = a.a_l;
    V1<i64> a_n = a.a_n;
    V1<double> a_dt = a.a_dt;
    const double im = a.inv_mass[i];
    const double fx = a.force_world(i, 0), fy = a.force_world(i, 1), fz = a.force_world(i, 2);
    const double tx = a.torque_world(i, 0), ty = a.torque_world(i, 1), tz = a.torque_world(i, 2);
    const double k0 = a.inv_inertia(i, 0), k1 = a.inv_inertia(i, 1), k2 = a.inv_inertia(i, 2);
    const bool torqued = tx != 0.0 || ty != 0.0 || tz != 0.0;
    const int n_sub = (METHOD == METHOD_EXACT4 && torqued) ? 3 : 1;
    double x = pos(i, 0), y = pos(i, 1), z = pos(i, 2);
    double px = mom(i, 0), py = mom(i, 1), pz = mom(i, 2);
    double lx = L(i, 0), ly = L(i, 1), lz = L(i, 2);
    double qw = Q(i, 0), qx = Q(i, 1), qy = Q(i, 2), qz = Q(i, 3);
    double aw = a_q(i, 0), ax = a_q(i, 1), ay = a_q(i, 2), az = a_q(i, 3);
    double al0 = a_l(i, 0), al1 = a_l(i, 1), al2 = a_l(i, 2);
    i64 an = a_n[i];
    double adt = a_dt[i];
    bool row_ok = false;
    Mat3 m{};
    bool stepped = false;
    auto store = [&]() {
        pos(i, 0) = x; pos(i, 1) = y; pos(i, 2) = z;
        mom(i, 0) = px; mom(i, 1) = py; mom(i, 2) = pz;
        L(i, 0) = lx; L(i, 1) = ly; L(i, 2) = lz;
        Q(i, 0) = qw; Q(i, 1) = qx; Q(i, 2) = qy; Q(i, 3) = qz;
        store_mat(R, i, m);
    };
    fail_step = -1;
    for (i64 s = s_begin; s <= a.n_steps; ++s) {
        flight_exact(dt, im, x, y, z, px, py, pz, fx, fy, fz);
        for (int sub = 0; sub < n_sub; ++sub) {
            double h = dt;
            if (n_sub == 3) h = sub == 1 ? w0 * dt : w1 * dt;
            const double hk = 0.5 * h;
            if (torqued) {
                lx += hk * tx; ly += hk * ty; lz += hk * tz;
            }
            if (!anchor_holds(an, adt, al0, al1, al2, h, lx, ly, lz)) {
                aw = qw; ax = qx; ay = qy; az = qz;
                al0 = lx; al1 = ly; al2 = lz;
                an = 0;
                adt = h;
                row_ok = false;
            }
            if (!row_ok) {
                anchor_constants(row, aw, ax, ay, az, lx, ly, lz, k0, k1, k2, h);
                row_ok = true;
            }
            const i64 n = an + 1;
            double rj_c;
            const Quat q = anchored_quat(row, aw, ax, ay, az, static_cast<double>(n) * std::fabs(h),
                                         qw, qx, qy, qz, rj_c);
            qw = q[0]; qx = q[1]; qy = q[2]; qz = q[3];
            if (rj_c >= 0.0 && row[FC_RJC] < 0.0) row[FC_RJC] = rj_c;
            an = n;
            if (torqued) {
                lx += hk * tx; ly += hk * ty; lz += hk * tz;
            }
        }
        m = quat_to_mat(qw, qx, qy, qz);
        stepped = true;
        const double chk = x + y + z + px + py + pz + lx + ly + lz + m[0] + m[4] + m[8] + m[1];
        if (!(std::isfinite(chk) && turn_within_bound_m(dt, k0, k1, k2, lx, ly, lz, m))) {
            fail_step = s;
            break;
        }
        if (sample_due(a, s)) {
            store();
            sample<METHOD>(a, j, i);
            j += 1;
        }
    }
    if (stepped) store();
    a_q(i, 0) = aw; a_q(i, 1) = ax; a_q(i, 2) = ay; a_q(i, 3) = az;
    a_l(i, 0) = al0; a_l(i, 1) = al1; a_l(i, 2) = al2;
    a_n[i] = an;
    a_dt[i] = adt;
    return j;
}

// ---- exact / exact4, W torque-free bodies in the lanes of V ----------------------------------
//
// Without torque a body's step is flight_exact and the flow from its anchor at the elapsed time
// n h (n_sub = 1 under exact4 too), and the anchor, taken (or kept) on the first step, holds for
// the whole call (L and h do not change). exact_lanes evaluates flow_eval's general case (exact.hpp:
// m1 > 0, not steady) for W such bodies at once, lane by lane the scalar code's operations in its
// order: the Landen levels, the Carlson duplications and the branches by per-lane masks, sin,
// cos, atan / atanh and the integer phase per lane. Bodies with torque, or whose flow is steady
// or on the separatrix, go through exact_single.

// A row's constants for flow_eval, gathered lane-wise (products the scalar code forms left to
// right from them each step are formed once here: the same roundings).
template <class V>
struct FlowLanes {
    V kk1, m, m1, lam, nn, amp1, sig_amp2, s_amp3, sn0, cn0, dn0, g0, ax, ay, az, aw, sgn3;
    V scale, mb, kb, two_kb, ell, ell_k1, phase_c, sg0, s_red0, c_mb25, c_mb5;
    V mu[N_LANDEN];
    int lev[lanes_of<V>()], i1[lanes_of<V>()], i2[lanes_of<V>()], max_lev;
};

template <class V>
inline void gather_flow(FlowLanes<V>& f, const double rows[][N_FLOW]) {
    constexpr int W = lanes_of<V>();
    f.max_lev = 0;
    for (int l = 0; l < W; ++l) {
        const double* c = rows[l];
        f.kk1[l] = c[FC_K1]; f.ell[l] = c[FC_ELL]; f.m[l] = c[FC_M]; f.m1[l] = c[FC_M1];
        f.lam[l] = c[FC_LAM]; f.nn[l] = c[FC_N]; f.amp1[l] = c[FC_AMP1];
        f.sig_amp2[l] = c[FC_SIGMA] * c[FC_AMP2];
        f.s_amp3[l] = c[FC_S] * c[FC_AMP3];
        f.sn0[l] = c[FC_SN0]; f.cn0[l] = c[FC_CN0]; f.dn0[l] = c[FC_DN0]; f.g0[l] = c[FC_G0];
        f.aw[l] = c[FC_AW]; f.ax[l] = -c[FC_AX]; f.ay[l] = -c[FC_AY]; f.az[l] = -c[FC_AZ];
        f.sgn3[l] = c[FC_SGN3];
        f.i1[l] = static_cast<int>(c[FC_I1]); f.i2[l] = static_cast<int>(c[FC_I2]);
        f.lev[l] = static_cast<int>(c[FC_LEV]);
        if (f.lev[l] > f.max_lev) f.max_lev = f.lev[l];
        f.scale[l] = c[FC_SCALE]; f.mb[l] = c[FC_MB];
        for (int k = 0; k < N_LANDEN; ++k) f.mu[k][l] = c[FC_MU0 + k];
        // sncndn_landen's K of the base parameter, flow_eval's dphi coefficients
        const double kb = HALF_PI * (1.0 + 0.25 * c[FC_MB]);
        f.kb[l] = kb; f.two_kb[l] = 2.0 * kb;
        f.c_mb25[l] = 0.25 * c[FC_MB]; f.c_mb5[l] = 0.5 * c[FC_MB];
        f.ell_k1[l] = c[FC_ELL] * c[FC_K1];
        f.phase_c[l] = c[FC_ELL] * c[FC_D13] * c[FC_N] / c[FC_LAM];
        const double sg0 = c[FC_CN0] >= 0.0 ? 1.0 : -1.0;
        f.sg0[l] = sg0; f.s_red0[l] = sg0 * c[FC_SN0];
    }
}

// carlson_rj1 lane-wise for the lanes of `act` (the others' result is not used)
template <class V, class M = mask_of<V>>
inline V carlson_rj1_lanes(V x, V y, V p, M act) {
    constexpr int W = lanes_of<V>();
    const V one = splat_v<V>(1.0);
    const V a0 = (x + y + 1.0 + 2.0 * p) / 5.0;
    V q = vabs(a0 - x);
    q = vpymax(q, vabs(a0 - y));
    q = vpymax(q, vabs(a0 - 1.0));
    q = vpymax(q, vabs(a0 - p));
    V e = (p - x) * (p - y) * (p - 1.0);
    V xa = x, ya = y, za = one, pa = p, aa = a0;
    V fac = one;
    V s = splat_v<V>(0.0);
    const double tol = free_constants.carlson_series_tol;
    for (int it = 0; it < 40; ++it) {
        act = act & ~(fac * q <= tol * aa);
        if (!any(act)) break;
        const V sx = vsqrt(xa), sy = vsqrt(ya), sz = vsqrt(za), sp = vsqrt(pa);
        const V la = sx * sy + sy * sz + sz * sx;
        const V da = (sp + sx) * (sp + sy) * (sp + sz);
        // rc1(t): its series near 0, atan / atanh per lane beyond
        const V t = e / (da * da);
        V r = 1.0 + t * (-1.0 / 3.0 + t * (0.2 + t * (-1.0 / 7.0 + t * (1.0 / 9.0 + t * (-1.0 / 11.0)))));
        const M far = act & ~(vabs(t) < 1e-3);
        if (any(far))
            for (int l = 0; l < W; ++l)
                if (far[l]) r[l] = rc1(t[l]);
        const V s_n = s + fac * r / da;
        const V fac_n = fac * 0.25;
        const V e_n = e * (1.0 / 64.0);
        const V xa_n = 0.25 * (xa + la), ya_n = 0.25 * (ya + la), za_n = 0.25 * (za + la);
        const V pa_n = 0.25 * (pa + la), aa_n = 0.25 * (aa + la);
        s = act ? s_n : s; fac = act ? fac_n : fac; e = act ? e_n : e;
        xa = act ? xa_n : xa; ya = act ? ya_n : ya; za = act ? za_n : za;
        pa = act ? pa_n : pa; aa = act ? aa_n : aa;
    }
    return rj_series(a0, x, y, one, p, fac, aa) + 6.0 * s;
}

// flow_eval's general case lane-wise at the elapsed times t: (cw, c0, c1, c2) of each lane, and
// rjc[l] (the row's FC_RJC) filled when a lane first needs it.
template <class V, class M = mask_of<V>>
inline void flow_eval_lanes(const FlowLanes<V>& f, const double rows[][N_FLOW], double rjc[], V t,
                            V& ow, V& o0, V& o1, V& o2) {
    constexpr int W = lanes_of<V>();
    const V zero = splat_v<V>(0.0), one = splat_v<V>(1.0);
    // sncndn_landen(tau = lam t)
    const V tau = f.lam * t;
    V v = tau / f.scale;
    const V vq = v / f.two_kb;
    i64 j[W];
    V jd;
    for (int l = 0; l < W; ++l) {
        j[l] = static_cast<i64>(vq[l]);
        jd[l] = static_cast<double>(j[l]);
    }
    v -= f.two_kb * jd;
    const M neg = v < 0.0;
    if (any(neg)) {  // rounding at the boundary
        v = neg ? v + f.two_kb : v;
        for (int l = 0; l < W; ++l)
            if (neg[l]) j[l] -= 1;
    }
    V sv, cv;
    for (int l = 0; l < W; ++l) {
        sv[l] = std::sin(v[l]);
        cv[l] = std::cos(v[l]);
    }
    const V corr = f.c_mb25 * (v - sv * cv);
    V snr = sv - corr * cv;
    V cnr = cv + corr * sv;
    V dnr = 1.0 - f.c_mb5 * sv * sv;
    for (int k = f.max_lev - 1; k >= 0; --k) {
        M up;
        for (int l = 0; l < W; ++l) up[l] = f.lev[l] > k ? -1 : 0;
        V s2 = snr, c2 = cnr, d2_ = dnr;
        landen_up(s2, c2, d2_, f.mu[k]);
        snr = up ? s2 : snr; cnr = up ? c2 : cnr; dnr = up ? d2_ : dnr;
    }
    // the addition theorem (flow_eval)
    const V m = f.m, sn0 = f.sn0, cn0 = f.cn0, dn0 = f.dn0;
    const V gc = cnr > 0.0 ? snr * snr / (1.0 + cnr) : 1.0 - cnr;
    const V gd = m * snr * snr / (1.0 + dnr);
    const V mu_ = m * sn0 * sn0 * snr * snr;
    const V den = 1.0 / (1.0 - mu_);
    const V gam = gc + gd - gc * gd;
    const V sn1 = sn0 + (snr * cn0 * dn0 - sn0 * gam + sn0 * mu_) * den;
    const V cn1 = cn0 + (-cn0 * gc - sn0 * snr * dn0 * dnr + cn0 * mu_) * den;
    const V dn1 = vsqrt(cn1 * cn1 + f.m1 * sn1 * sn1);
    // reduced amplitudes at both ends
    const V sg0 = f.sg0, s_red0 = f.s_red0;
    const M same = sg0 * cn1 >= 0.0;
    const V s_red1 = same ? sg0 * sn1 : -sg0 * sn1;
    const M wrap_up = s_red1 - s_red0 < -1.0, wrap_down = s_red1 - s_red0 > 1.0;
    const M has_n = f.nn != 0.0;
    V dg = zero;
    if (any(has_n)) {
        const V s21 = s_red1 * s_red1;
        const V rj = carlson_rj1_lanes(cn1 * cn1, dn1 * dn1, 1.0 + f.nn * s21, has_n);
        dg = has_n ? s_red1 * s21 * rj / 3.0 - f.g0 : zero;
    }
    V sj;
    for (int l = 0; l < W; ++l) {
        const i64 e = same[l] ? (wrap_up[l] ? 2 : 0) : (wrap_down[l] ? -1 : 1);
        const i64 halfs = j[l] + e;
        if (halfs != 0 && has_n[l]) {
            if (rjc[l] < 0.0) rjc[l] = carlson_rj1(0.0, rows[l][FC_M1], 1.0 + rows[l][FC_N]);
            dg[l] += 2.0 * static_cast<double>(halfs) * rjc[l] / 3.0;
        }
        sj[l] = (j[l] & 1) ? -1.0 : 1.0;
    }
    const V dphi = f.ell_k1 * t - f.phase_c * dg;
    // the momentum at u0 + tau
    const V n1_ = f.amp1 * cn1 * sj;
    const V n2_ = f.sig_amp2 * sn1 * sj;
    const V n3_ = f.s_amp3 * dn1;
    // euler_quat(n1_, n2_, n3_, ell)
    const V rho = vsqrt(n1_ * n1_ + n2_ * n2_);
    const M p3 = n3_ >= 0.0, p2 = n2_ >= 0.0;
    const V xw = p3 ? f.ell + n3_ : rho, xx = p3 ? rho : f.ell - n3_;
    const V zw = p2 ? rho + n2_ : n1_, zz = p2 ? n1_ : rho - n2_;
    const V bw = xw * zw, bx = xx * zw, by = -xx * zz, bz = xw * zz;
    const V hd = 0.5 * dphi;
    V ch, sh;
    for (int l = 0; l < W; ++l) {
        ch[l] = std::cos(hd[l]);
        sh[l] = std::sin(hd[l]);
    }
    // conj(B0) (x) rz, then (x) B1
    const V aw = f.aw, ax = f.ax, ay = f.ay, az = f.az;
    const V tw = aw * ch - ax * 0.0 - ay * 0.0 - az * sh;
    const V tx = aw * 0.0 + ax * ch + ay * sh - az * 0.0;
    const V ty = aw * 0.0 - ax * sh + ay * ch + az * 0.0;
    const V tz = aw * sh + ax * 0.0 - ay * 0.0 + az * ch;
    ow = tw * bw - tx * bx - ty * by - tz * bz;
    const V cx = tw * bx + tx * bw + ty * bz - tz * by;
    const V cy = tw * by - tx * bz + ty * bw + tz * bx;
    const V cz = tw * bz + tx * by - ty * bx + tz * bw;
    const V czs = cz * f.sgn3;
    // back to the body frame, per lane
    for (int l = 0; l < W; ++l) {
        double cc[3] = {0.0, 0.0, 0.0};
        cc[f.i1[l]] = cx[l];
        cc[f.i2[l]] = cy[l];
        cc[3 - f.i1[l] - f.i2[l]] = czs[l];
        o0[l] = cc[0]; o1[l] = cc[1]; o2[l] = cc[2];
    }
    (void)one;
}

// Bodies i .. i + W - 1 of exact / exact4, none of them torqued, in the lanes of V: exact_single's
// step lane by lane. Returns false (nothing written) when a lane's flow is not flow_eval's general
// case; else the samples of each body in j_out, their bad steps in fail_out (a lane going bad
// at step s: the others go on alone, exact_single from s + 1).
template <int METHOD, class V, class M = mask_of<V>>
inline bool exact_lanes(const FreeArgs& a, i64 i, i64 j_out[], i64 fail_out[]) {
    constexpr int W = lanes_of<V>();
    const double dt = a.dt, h = dt;
    V2<double> pos = a.position, mom = a.linear_momentum, L = a.angular_momentum, Q = a.quat_wxyz;
    V3<double> R = a.rotation;
    V2<double> a_q = a.a_q, a_l = a.a_l;
    V1<i64> a_n = a.a_n;
    V1<double> a_dt = a.a_dt;
    auto ld = [i](V2<double> v, int c) {
        V r;
        for (int l = 0; l < W; ++l) r[l] = v(i + l, c);
        return r;
    };
    if (a.n_steps < 1) return false;
    // the first step's anchor of each lane (exact_single's, kept for the call) and its constants
    double rows[W][N_FLOW];
    V aw, ax, ay, az;
    V nf;  // the anchor's steps so far, as a double (exact: far below 2^53)
    i64 an[W];
    double al[W][3], adt[W];
    for (int l = 0; l < W; ++l) {
        const i64 b = i + l;
        const double lx = L(b, 0), ly = L(b, 1), lz = L(b, 2);
        an[l] = a_n[b];
        adt[l] = a_dt[b];
        for (int c = 0; c < 3; ++c) al[l][c] = a_l(b, c);
        if (anchor_holds(a_n[b], a_dt[b], a_l(b, 0), a_l(b, 1), a_l(b, 2), h, lx, ly, lz)) {
            aw[l] = a_q(b, 0); ax[l] = a_q(b, 1); ay[l] = a_q(b, 2); az[l] = a_q(b, 3);
        } else {
            aw[l] = Q(b, 0); ax[l] = Q(b, 1); ay[l] = Q(b, 2); az[l] = Q(b, 3);
            al[l][0] = lx; al[l][1] = ly; al[l][2] = lz;
            an[l] = 0;
            adt[l] = h;
        }
        anchor_constants(rows[l], aw[l], ax[l], ay[l], az[l], lx, ly, lz, a.inv_inertia(b, 0),
                         a.inv_inertia(b, 1), a.inv_inertia(b, 2), h);
        if (rows[l][FC_STEADY] != 0.0 || !(rows[l][FC_M1] > 0.0)) return false;
        nf[l] = static_cast<double>(an[l]);
    }
    FlowLanes<V> f;
    gather_flow(f, rows);
    double rjc[W];
    for (int l = 0; l < W; ++l) rjc[l] = rows[l][FC_RJC];
    V im;
    for (int l = 0; l < W; ++l) im[l] = a.inv_mass[i + l];
    const V fx = ld(a.force_world, 0), fy = ld(a.force_world, 1), fz = ld(a.force_world, 2);
    const V k0 = ld(a.inv_inertia, 0), k1 = ld(a.inv_inertia, 1), k2 = ld(a.inv_inertia, 2);
    const V kmax_dt = vpymax(k0, vpymax(k1, k2)) * dt;
    const double lim = free_constants.max_rotation_per_step_rad;
    const double lim2 = lim * lim;
    const double habs = std::fabs(h);
    const double hh_flight = 0.5 * dt * dt;
    V x = ld(pos, 0), y = ld(pos, 1), z = ld(pos, 2);
    V px = ld(mom, 0), py = ld(mom, 1), pz = ld(mom, 2);
    const V lx = ld(L, 0), ly = ld(L, 1), lz = ld(L, 2);
    QV<V> q = {ld(Q, 0), ld(Q, 1), ld(Q, 2), ld(Q, 3)};
    V m[9];
    auto store = [&]() {
        for (int l = 0; l < W; ++l) {
            const i64 b = i + l;
            pos(b, 0) = x[l]; pos(b, 1) = y[l]; pos(b, 2) = z[l];
            mom(b, 0) = px[l]; mom(b, 1) = py[l]; mom(b, 2) = pz[l];
            Q(b, 0) = q.w[l]; Q(b, 1) = q.x[l]; Q(b, 2) = q.y[l]; Q(b, 3) = q.z[l];
            for (int c = 0; c < 9; ++c) R.row(b)[c] = m[c][l];
            a_q(b, 0) = aw[l]; a_q(b, 1) = ax[l]; a_q(b, 2) = ay[l]; a_q(b, 3) = az[l];
            a_l(b, 0) = al[l][0]; a_l(b, 1) = al[l][1]; a_l(b, 2) = al[l][2];
            a_n[b] = static_cast<i64>(nf[l]);
            a_dt[b] = adt[l];
        }
    };
    i64 j = 0;
    bool ok[W];
    for (int l = 0; l < W; ++l) ok[l] = true;
    SampleClock clock(a);
    i64 s = 1;
    for (; s <= a.n_steps; ++s) {
        // flight_exact
        const V hf = hh_flight * im;
        x = x + (dt * px * im + hf * fx);
        y = y + (dt * py * im + hf * fy);
        z = z + (dt * pz * im + hf * fz);
        px = px + dt * fx; py = py + dt * fy; pz = pz + dt * fz;
        // anchored_quat at n |h|
        nf = nf + 1.0;
        V cw, c0, c1, c2;
        flow_eval_lanes(f, rows, rjc, nf * habs, cw, c0, c1, c2);
        const QV<V> r = qmul2(aw, ax, ay, az, cw, c0, c1, c2);
        V sc = 1.0 / vsqrt(r.w * r.w + r.x * r.x + r.y * r.y + r.z * r.z);
        const M flip = r.w * q.w + r.x * q.x + r.y * q.y + r.z * q.z < 0.0;
        sc = flip ? -sc : sc;
        q = {r.w * sc, r.x * sc, r.y * sc, r.z * sc};
        mat2(q, m);
        if (!lanes_ok(ok, dt, x + y + z + px + py + pz + lx + ly + lz + m[0] + m[4] + m[8] + m[1], m,
                      lx, ly, lz, k0, k1, k2, kmax_dt, lim2))
            break;
        if (clock.due(s)) {
            store();
            for (int l = 0; l < W; ++l) sample<METHOD>(a, j, i + l);
            j += 1;
        }
    }
    store();
    for (int l = 0; l < W; ++l) {
        if (s > a.n_steps) {
            j_out[l] = j;
            fail_out[l] = -1;
        } else if (!ok[l]) {
            j_out[l] = j;
            fail_out[l] = s;
        } else {
            double row[N_FLOW];
            j_out[l] = exact_single<METHOD>(a, i + l, row, s + 1, j, fail_out[l]);
        }
    }
    return true;
}

#if RB_FREE_AVX2
template <int METHOD>
__attribute__((target("avx2"), flatten, noinline)) bool exact_lanes4(const FreeArgs& a, i64 i,
                                                                     i64 j_out[4],
                                                                     i64 fail_out[4]) {
    return exact_lanes<METHOD, d4>(a, i, j_out, fail_out);
}
#endif

// The kernel of exact / exact4: advance_range's loops with the exact step written out
// (integrators.step_body, _strang_exact and drift_exact_anchored, operation for operation).
// The flow constants of each body of a tile are computed from its anchor on its first step in
// this call (a pure function of the anchor: the same in every split).
template <int METHOD>
FreeResult advance_exact_range(const FreeArgs& a, i64 b0, i64 b1) {
    FreeResult res;
    const i64 tile = a.tile;
    const double dt = a.dt;
    const double w1 = yoshida_w1(), w0 = yoshida_w0();
    std::vector<double> fc(static_cast<size_t>(tile * N_FLOW));
    std::unique_ptr<bool[]> fc_ok(new bool[static_cast<size_t>(tile)]());
    V2<double> pos = a.position, mom = a.linear_momentum, L = a.angular_momentum, Q = a.quat_wxyz;
    V3<double> R = a.rotation;
    V2<double> a_q = a.a_q, a_l = a.a_l;
    V1<i64> a_n = a.a_n;
    V1<double> a_dt = a.a_dt;
    if (tile == 1) {  // sparse samples: torque-free bodies W at a time, the others one by one
        auto collect = [&](i64 b, i64 j, i64 fs) {
            if (fs >= 0 && (res.bad_step < 0 || fs < res.bad_step)) {
                res.bad_step = fs;
                res.bad_body = b;
            }
            if (j > res.n_samples) res.n_samples = j;
        };
        auto torque_free = [&](i64 b, i64 w) {
            for (i64 k = b; k < b + w; ++k)
                if (a.torque_world(k, 0) != 0.0 || a.torque_world(k, 1) != 0.0
                    || a.torque_world(k, 2) != 0.0)
                    return false;
            return true;
        };
        (void)torque_free;  // (unused when built with RB_FREE_NO_LANES)
        i64 i = b0;
        while (i < b1) {
            i64 js[4], fs[4];
            int w = 1;
#ifndef RB_FREE_NO_LANES
#if RB_FREE_AVX2
            if (free_lanes() == 4 && i + 4 <= b1 && torque_free(i, 4)
                && exact_lanes4<METHOD>(a, i, js, fs))
                w = 4;
            else
#endif
            if (i + 2 <= b1 && torque_free(i, 2) && exact_lanes<METHOD, d2>(a, i, js, fs))
                w = 2;
#endif
            if (w == 1) {
                js[0] = exact_single<METHOD>(a, i, fc.data(), 1, 0, fs[0]);
            }
            for (int l = 0; l < w; ++l) collect(i + l, js[l], fs[l]);
            i += w;
        }
        return res;
    }
    for (i64 t0 = b0; t0 < b1; t0 += tile) {
        const i64 t1 = t0 + tile < b1 ? t0 + tile : b1;
        for (i64 r = 0; r < tile; ++r) fc_ok[r] = false;
        i64 j = 0;
        for (i64 s = 1; s <= a.n_steps; ++s) {
            bool ok = true;
            for (i64 i = t0; i < t1; ++i) {
                const i64 r = i - t0;
                double* row = fc.data() + r * N_FLOW;
                // translation: exact for a constant force (integrators.step_body)
                const double im = a.inv_mass[i];
                const double fx = a.force_world(i, 0), fy = a.force_world(i, 1), fz = a.force_world(i, 2);
                const double tx = a.torque_world(i, 0), ty = a.torque_world(i, 1), tz = a.torque_world(i, 2);
                double x = pos(i, 0), y = pos(i, 1), z = pos(i, 2);
                double px = mom(i, 0), py = mom(i, 1), pz = mom(i, 2);
                flight_exact(dt, im, x, y, z, px, py, pz, fx, fy, fz);
                pos(i, 0) = x; pos(i, 1) = y; pos(i, 2) = z;
                mom(i, 0) = px; mom(i, 1) = py; mom(i, 2) = pz;
                // rotation: Strang kick(h/2) flow(h) kick(h/2), with torque under exact4
                // Yoshida's three of them
                const double k0 = a.inv_inertia(i, 0), k1 = a.inv_inertia(i, 1), k2 = a.inv_inertia(i, 2);
                double lx = L(i, 0), ly = L(i, 1), lz = L(i, 2);
                double qw = Q(i, 0), qx = Q(i, 1), qy = Q(i, 2), qz = Q(i, 3);
                const bool torqued = tx != 0.0 || ty != 0.0 || tz != 0.0;
                const int n_sub = (METHOD == METHOD_EXACT4 && torqued) ? 3 : 1;
                for (int sub = 0; sub < n_sub; ++sub) {
                    double h = dt;
                    if (n_sub == 3) h = sub == 1 ? w0 * dt : w1 * dt;
                    const double hk = 0.5 * h;
                    if (torqued) {
                        lx += hk * tx; ly += hk * ty; lz += hk * tz;
                    }
                    // the anchor (drift_exact_anchored): kept while L is bitwise the anchor's and
                    // the step is the same
                    if (!anchor_holds(a_n[i], a_dt[i], a_l(i, 0), a_l(i, 1), a_l(i, 2), h, lx, ly, lz)) {
                        a_q(i, 0) = qw; a_q(i, 1) = qx; a_q(i, 2) = qy; a_q(i, 3) = qz;
                        a_l(i, 0) = lx; a_l(i, 1) = ly; a_l(i, 2) = lz;
                        a_n[i] = 0;
                        a_dt[i] = h;
                        fc_ok[r] = false;
                    }
                    const double aw = a_q(i, 0), ax = a_q(i, 1), ay = a_q(i, 2), az = a_q(i, 3);
                    if (!fc_ok[r]) {
                        anchor_constants(row, aw, ax, ay, az, lx, ly, lz, k0, k1, k2, h);
                        fc_ok[r] = true;
                    }
                    const i64 n = a_n[i] + 1;
                    double rj_c;
                    const Quat q = anchored_quat(row, aw, ax, ay, az,
                                                 static_cast<double>(n) * std::fabs(h), qw, qx, qy,
                                                 qz, rj_c);
                    qw = q[0]; qx = q[1]; qy = q[2]; qz = q[3];
                    if (rj_c >= 0.0 && row[FC_RJC] < 0.0) row[FC_RJC] = rj_c;
                    a_n[i] = n;
                    if (torqued) {
                        lx += hk * tx; ly += hk * ty; lz += hk * tz;
                    }
                }
                L(i, 0) = lx; L(i, 1) = ly; L(i, 2) = lz;
                Q(i, 0) = qw; Q(i, 1) = qx; Q(i, 2) = qy; Q(i, 3) = qz;
                const Mat3 m = quat_to_mat(qw, qx, qy, qz);
                store_mat(R, i, m);
                // non-finite check and turn bound (integrators.step_body)
                const double chk = x + y + z + px + py + pz + lx + ly + lz + m[0] + m[4] + m[8] + m[1];
                ok = std::isfinite(chk) && turn_within_bound_m(dt, k0, k1, k2, lx, ly, lz, m);
                if (!ok) {
                    if (res.bad_step < 0 || s < res.bad_step) {
                        res.bad_step = s;
                        res.bad_body = i;
                    }
                    break;
                }
            }
            if (!ok) break;
            if (sample_due(a, s)) {
                for (i64 i = t0; i < t1; ++i) sample<METHOD>(a, j, i);
                j += 1;
            }
        }
        if (j > res.n_samples) res.n_samples = j;
    }
    return res;
}

}  // namespace

FreeResult advance_free_range(int method, const FreeArgs& a, i64 b0, i64 b1) {
    switch (method) {
        case METHOD_SEED: return advance_range<METHOD_SEED>(a, b0, b1);
        case METHOD_SEED_QUAT: return advance_range<METHOD_SEED_QUAT>(a, b0, b1);
        case METHOD_SPLITTING: return advance_range<METHOD_SPLITTING>(a, b0, b1);
        case METHOD_RK4: return advance_range<METHOD_RK4>(a, b0, b1);
        case METHOD_EXACT: return advance_exact_range<METHOD_EXACT>(a, b0, b1);
        case METHOD_EXACT4: return advance_exact_range<METHOD_EXACT4>(a, b0, b1);
        default: throw std::invalid_argument("unknown integrator code " + std::to_string(method));
    }
}

FreeResult advance_free(int method, const FreeArgs& a,
                        const std::vector<std::pair<i64, i64>>& ranges) {
    if (ranges.size() == 1) return advance_free_range(method, a, ranges[0].first, ranges[0].second);
    std::vector<FreeResult> results(ranges.size());
    pool().parallel_for(static_cast<i64>(ranges.size()), [&](i64 t) {
        results[static_cast<size_t>(t)] =
            advance_free_range(method, a, ranges[static_cast<size_t>(t)].first,
                               ranges[static_cast<size_t>(t)].second);
    });
    // the serial kernel's reduction: most samples; the earliest bad step, first body on ties
    FreeResult out;
    for (const FreeResult& r : results) {
        if (r.n_samples > out.n_samples) out.n_samples = r.n_samples;
        if (r.bad_step >= 0 && (out.bad_step < 0 || r.bad_step < out.bad_step)) {
            out.bad_step = r.bad_step;
            out.bad_body = r.bad_body;
        }
    }
    return out;
}

}  // namespace rb
