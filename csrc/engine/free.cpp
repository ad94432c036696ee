// Kernels that advance free bodies (no contacts) many steps per call (rblog/engine/free.py keeps
// the Python entry points, BODY_TILE, SPARSE_STRIDE, MIN_PARALLEL_BODY_STEPS and body_ranges).
//
// Bodies are independent without contacts, so the loop runs over tiles of BODY_TILE bodies, steps
// inside a tile: the tile's state stays in L1 for the whole block, and samples are written for
// consecutive bodies. When samples are SPARSE_STRIDE or more steps apart, bodies are stepped
// several at a time with their whole state in registers for the block: four (AVX2, chosen at
// run time) or two (SSE2) per vector, one body in each lane (lanes.hpp), the rest one at a time.
// A body's step is written once, over its value type T (double, or a lane vector): a Body<T> of
// its state, step<METHOD, T> calling the stages of integrators.hpp, and run_bodies<METHOD, T> the
// loop over the block, so a lane does the one body's operations in its order and the bits do not
// depend on the width (tests/engine/test_free_lanes.py). Under exact / exact4 the step is
// exact_step (advance_exact_range; the arithmetic of integrators.step_body + drift_exact_anchored,
// operation for operation: tests/engine/test_exact_anchored.py compares the two bit for bit), and
// exact_lanes evaluates the flow of torque-free bodies in lanes.
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

// ---- a body's state in registers: one body (T = double) or one in each lane of a vector ------

// Rows i .. i + W - 1 (W the lanes of T), column c of v.
template <class T>
inline T gather(V2<double> v, i64 i, int c) {
    T r;
    for (int l = 0; l < lanes_of<T>(); ++l) set_lane(r, l, v(i + l, c));
    return r;
}

// columns 0, 1, 2 of v
template <class T>
inline void gather3(V2<double> v, i64 i, T& c0, T& c1, T& c2) {
    c0 = gather<T>(v, i, 0); c1 = gather<T>(v, i, 1); c2 = gather<T>(v, i, 2);
}

// Bodies i .. i + W - 1 from the state arrays, q too unless with_q is false; store_body the
// reverse.
template <class T>
inline Body<T> load_body(const FreeArgs& a, i64 i, bool with_q) {
    Body<T> b;
    gather3(a.position, i, b.x, b.y, b.z);
    gather3(a.linear_momentum, i, b.px, b.py, b.pz);
    gather3(a.angular_momentum, i, b.lx, b.ly, b.lz);
    for (int c = 0; c < 4; ++c) b.q[c] = with_q ? gather<T>(a.quat_wxyz, i, c) : T{};
    for (int c = 0; c < 9; ++c)
        for (int l = 0; l < lanes_of<T>(); ++l) set_lane(b.m[c], l, a.rotation.row(i + l)[c]);
    return b;
}

template <class T>
inline void store_body(const FreeArgs& a, i64 i, const Body<T>& b, bool with_q) {
    V2<double> pos = a.position, mom = a.linear_momentum, L = a.angular_momentum, Q = a.quat_wxyz;
    for (int l = 0; l < lanes_of<T>(); ++l) {
        const i64 k = i + l;
        pos(k, 0) = lane(b.x, l); pos(k, 1) = lane(b.y, l); pos(k, 2) = lane(b.z, l);
        mom(k, 0) = lane(b.px, l); mom(k, 1) = lane(b.py, l); mom(k, 2) = lane(b.pz, l);
        L(k, 0) = lane(b.lx, l); L(k, 1) = lane(b.ly, l); L(k, 2) = lane(b.lz, l);
        if (with_q)
            for (int c = 0; c < 4; ++c) Q(k, c) = lane(b.q[c], l);
        double* r = a.rotation.row(k);
        for (int c = 0; c < 9; ++c) r[c] = lane(b.m[c], l);
    }
}

// Their constants over the call.
template <class T>
inline BodyParams<T> load_params(const FreeArgs& a, i64 i) {
    BodyParams<T> p;
    for (int l = 0; l < lanes_of<T>(); ++l) set_lane(p.im, l, a.inv_mass[i + l]);
    gather3(a.force_world, i, p.fx, p.fy, p.fz);
    gather3(a.torque_world, i, p.tx, p.ty, p.tz);
    gather3(a.inv_inertia, i, p.k0, p.k1, p.k2);
    p.torqued = (p.tx != 0.0) | (p.ty != 0.0) | (p.tz != 0.0);
    return p;
}

// One step of a body (of each lane's) by integrator METHOD (not the exact ones). Translation:
// seed / seed-quat symplectic Euler, splitting kick-drift-kick and rk4 the exact constant-force
// step (the same map x += h v + h^2 a / 2, v += h a) (integrators.step_body).
template <int METHOD, class T>
inline void step(int ortho, Body<T>& b, const BodyParams<T>& p, double dt) {
    if (METHOD == METHOD_SPLITTING) {
        // kick half, drift, kick half
        const double hh = 0.5 * dt;
        b.px += hh * p.fx; b.py += hh * p.fy; b.pz += hh * p.fz;
        b.lx += hh * p.tx; b.ly += hh * p.ty; b.lz += hh * p.tz;
        b.x += dt * b.px * p.im; b.y += dt * b.py * p.im; b.z += dt * b.pz * p.im;
        drift_splitting(b, p, dt);
        b.px += hh * p.fx; b.py += hh * p.fy; b.pz += hh * p.fz;
        b.lx += hh * p.tx; b.ly += hh * p.ty; b.lz += hh * p.tz;
    } else if (METHOD == METHOD_RK4) {
        // translation: exact for a constant force; rotation: RK4 with L(t) = L + t tau
        flight_exact(dt, p.im, b.x, b.y, b.z, b.px, b.py, b.pz, p.fx, p.fy, p.fz);
        drift_rk4(b, p, dt);
        b.lx += dt * p.tx; b.ly += dt * p.ty; b.lz += dt * p.tz;
    } else {
        // the notes: forward Euler on P and L, then x and R from the new values
        b.px += dt * p.fx; b.py += dt * p.fy; b.pz += dt * p.fz;
        b.x += dt * b.px * p.im; b.y += dt * b.py * p.im; b.z += dt * b.pz * p.im;
        b.lx += dt * p.tx; b.ly += dt * p.ty; b.lz += dt * p.tz;
        if (METHOD == METHOD_SEED)
            drift_seed(ortho, b, p, dt);
        else
            drift_seed_quat(ortho, b, p, dt);
    }
}

// After a step: whether each body's state is finite and it turned at most
// MAX_ROTATION_PER_STEP_RAD (turn_within_bound_m, its cheap bound first), ok[l] per lane (set
// only when some lane is not; the common case decided by two lane-wise tests: x - x is 0 exactly
// when x is finite, NaN otherwise). One sum covers position, momenta and part of the rotation.
template <class T>
inline bool step_ok(bool ok[], double dt, const Body<T>& b, const BodyParams<T>& p,
                    const T& kmax_dt) {
    const T chk = b.x + b.y + b.z + b.px + b.py + b.pz + b.lx + b.ly + b.lz + b.m[0] + b.m[4]
                  + b.m[8] + b.m[1];
    const double lim = free_constants.max_rotation_per_step_rad;
    const double lim2 = lim * lim;
    const mask_of<T> cheap = (b.lx * b.lx + b.ly * b.ly + b.lz * b.lz) * (kmax_dt * kmax_dt) <= lim2;
    const mask_of<T> fine = cheap & ((chk - chk) == T{});
    if (all_set(fine)) return true;
    bool all = true;
    for (int l = 0; l < lanes_of<T>(); ++l) {
        ok[l] = std::isfinite(lane(chk, l));
        if (ok[l] && !lane(cheap, l)) {
            Mat3 ml;
            for (int c = 0; c < 9; ++c) ml[c] = lane(b.m[c], l);
            ok[l] = turn_within_bound_m(dt, lane(p.k0, l), lane(p.k1, l), lane(p.k2, l),
                                        lane(b.lx, l), lane(b.ly, l), lane(b.lz, l), ml);
        }
        all = all && ok[l];
    }
    return all;
}

// The cheap turn bound's max(k) dt, a constant of the body.
template <class T>
inline T kmax_dt_of(const BodyParams<T>& p, double dt) {
    return vpymax(p.k0, vpymax(p.k1, p.k2)) * dt;
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

// sample_due for the steps s = s_begin, s_begin + 1, ... in turn, without an integer division per
// step: due at the next multiple of stride, and at the last step when sample_last.
struct SampleClock {
    i64 next, stride, last;
    SampleClock(const FreeArgs& a, i64 s_begin)
        : next((s_begin + a.stride - 1) / a.stride * a.stride), stride(a.stride),
          last(a.sample_last ? a.n_steps : -1) {}
    bool due(i64 s) {
        if (s == next) {
            next += stride;
            return true;
        }
        return s == last;
    }
};

// Bodies i .. i + W - 1 by METHOD, one in each of the W lanes of T (T = double: body i alone),
// from step s_begin on, samples from row j on, the whole state in registers for the block (the
// arrays written when a sample is due and at the end): the sparse path of advance_range. When a
// lane's state goes bad at step s, every lane has taken step s (as the tiled loop would); the
// others then go on alone from s + 1. The samples of each body in j_out, their bad steps
// (-1: none) in fail_out.
template <int METHOD, class T>
inline void run_bodies(const FreeArgs& a, i64 i, i64 s_begin, i64 j, i64 j_out[],
                       i64 fail_out[]) {
    constexpr int W = lanes_of<T>();
    constexpr bool with_q = METHOD != METHOD_SEED;  // (seed's q is derived from R when logged)
    const double dt = a.dt;
    Body<T> b = load_body<T>(a, i, with_q);
    const BodyParams<T> p = load_params<T>(a, i);
    const T kmax_dt = kmax_dt_of(p, dt);
    bool ok[W];
    for (int l = 0; l < W; ++l) ok[l] = true;
    SampleClock clock(a, s_begin);
    i64 s = s_begin;
    for (; s <= a.n_steps; ++s) {
        step<METHOD>(a.ortho, b, p, dt);
        if (!step_ok(ok, dt, b, p, kmax_dt)) break;
        if (clock.due(s)) {
            store_body(a, i, b, with_q);
            for (int l = 0; l < W; ++l) sample<METHOD>(a, j, i + l);
            j += 1;
        }
    }
    store_body(a, i, b, with_q);
    for (int l = 0; l < W; ++l) {
        j_out[l] = j;
        fail_out[l] = s > a.n_steps ? -1 : s;
        if constexpr (W > 1)
            if (s <= a.n_steps && ok[l]) run_bodies<METHOD, double>(a, i + l, s + 1, j, j_out + l,
                                                                    fail_out + l);
    }
}

// One step of free body i of the state arrays by METHOD (the tiled path of advance_range);
// false if its state became non-finite or it turned too far (integrators.step_body).
template <int METHOD>
inline bool step_body(const FreeArgs& a, i64 i) {
    constexpr bool with_q = METHOD != METHOD_SEED;
    Body<double> b = load_body<double>(a, i, with_q);
    const BodyParams<double> p = load_params<double>(a, i);
    step<METHOD>(a.ortho, b, p, a.dt);
    store_body(a, i, b, with_q);
    bool ok[1];
    return step_ok(ok, a.dt, b, p, kmax_dt_of(p, a.dt));
}

#if RB_FREE_AVX2
// run_bodies on four bodies, compiled for AVX2 (without FMA): everything it calls is inlined into
// it (flatten), so the whole kernel, its one-body tail included, is built for that target. Called
// only when the CPU has AVX2 (free_lanes() == 4).
template <int METHOD>
__attribute__((target("avx2"), flatten, noinline)) void run_lanes4(const FreeArgs& a, i64 i,
                                                                   i64 j_out[4],
                                                                   i64 fail_out[4]) {
    run_bodies<METHOD, d4>(a, i, 1, 0, j_out, fail_out);
}
#endif

// The same on two bodies (SSE2) and on one: the stages inlined into the loop (flatten), their
// vectors in registers rather than passed through memory.
template <int METHOD>
__attribute__((flatten, noinline)) void run_lanes2(const FreeArgs& a, i64 i, i64 j_out[2],
                                                   i64 fail_out[2]) {
    run_bodies<METHOD, d2>(a, i, 1, 0, j_out, fail_out);
}

template <int METHOD>
__attribute__((flatten, noinline)) void run_one(const FreeArgs& a, i64 i, i64& j, i64& fail) {
    run_bodies<METHOD, double>(a, i, 1, 0, &j, &fail);
}

// The tiled path: bodies t0 .. t1-1 each step in turn (their state stays in L1), samples after
// the due steps; returns the samples written, the first bad step and its body (-1: none). Its
// stages inlined into it (flatten), as run_lanes2.
template <int METHOD>
__attribute__((flatten, noinline)) i64 advance_tile(const FreeArgs& a, i64 t0, i64 t1,
                                                    i64& bad_step, i64& bad_body) {
    i64 j = 0;
    for (i64 s = 1; s <= a.n_steps; ++s) {
        for (i64 i = t0; i < t1; ++i)
            if (!step_body<METHOD>(a, i)) {
                bad_step = s;
                bad_body = i;
                return j;
            }
        if (sample_due(a, s)) {
            for (i64 i = t0; i < t1; ++i) sample<METHOD>(a, j, i);
            j += 1;
        }
    }
    return j;
}

// Bodies b0 .. b1-1, n_steps steps of dt, samples written (advance_free_range's contract).
template <int METHOD>
FreeResult advance_range(const FreeArgs& a, i64 b0, i64 b1) {
    FreeResult res;
    const i64 tile = a.tile;
    auto fail = [&](i64 s, i64 i) {
        if (s >= 0 && (res.bad_step < 0 || s < res.bad_step)) {
            res.bad_step = s;
            res.bad_body = i;
        }
    };
#ifndef RB_FREE_NO_LANES  // (defined: the scalar path only, to compare the lanes against it)
    if (tile == 1) {
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
            run_lanes2<METHOD>(a, i, js, fs);
            collect(i, 2, js, fs);
        }
        for (; i < b1; ++i) {
            i64 js[1], fs[1];
            run_one<METHOD>(a, i, js[0], fs[0]);
            collect(i, 1, js, fs);
        }
        return res;
    }
#endif
    for (i64 t0 = b0; t0 < b1; t0 += tile) {
        const i64 t1 = t0 + tile < b1 ? t0 + tile : b1;
        i64 j = 0;
        if (tile == 1) {
            i64 fs;
            run_one<METHOD>(a, t0, j, fs);
            fail(fs, t0);
        } else {
            i64 bad_step = -1, bad_body = -1;
            j = advance_tile<METHOD>(a, t0, t1, bad_step, bad_body);
            fail(bad_step, bad_body);
        }
        if (METHOD == METHOD_SEED)  // the only integrator whose q is not current
            for (i64 i = t0; i < t1; ++i) sync_quat_seed(a.quat_wxyz, a.rotation, i);
        if (j > res.n_samples) res.n_samples = j;
    }
    return res;
}

// A body's flow anchor (rblog.engine.state.FlowAnchors): q_a, L_a, its steps so far and its dt.
struct Anchor {
    double aw, ax, ay, az, l0, l1, l2;
    i64 n;
    double dt;
};

inline Anchor load_anchor(const FreeArgs& a, i64 i) {
    return {a.a_q(i, 0), a.a_q(i, 1), a.a_q(i, 2), a.a_q(i, 3), a.a_l(i, 0), a.a_l(i, 1),
            a.a_l(i, 2), a.a_n[i], a.a_dt[i]};
}

inline void store_anchor(const FreeArgs& a, i64 i, const Anchor& an) {
    V2<double> a_q = a.a_q, a_l = a.a_l;
    V1<i64> a_n = a.a_n;
    V1<double> a_dt = a.a_dt;
    a_q(i, 0) = an.aw; a_q(i, 1) = an.ax; a_q(i, 2) = an.ay; a_q(i, 3) = an.az;
    a_l(i, 0) = an.l0; a_l(i, 1) = an.l1; a_l(i, 2) = an.l2;
    a_n[i] = an.n;
    a_dt[i] = an.dt;
}

// One step of a body by exact / exact4 (integrators.step_body, _strang_exact and
// drift_exact_anchored, operation for operation): translation exact for a constant force;
// rotation Strang kick(h/2) flow(h) kick(h/2), with torque under exact4 Yoshida's three of them
// (weights w1, w0). The flow from the anchor, kept while L is bitwise the anchor's and the step
// is the same; row: its flow constants, row_ok whether they are the anchor's.
template <int METHOD>
inline void exact_step(Body<double>& b, const BodyParams<double>& p, Anchor& an, double* row,
                       bool& row_ok, double dt, double w1, double w0) {
    flight_exact(dt, p.im, b.x, b.y, b.z, b.px, b.py, b.pz, p.fx, p.fy, p.fz);
    const int n_sub = (METHOD == METHOD_EXACT4 && p.torqued) ? 3 : 1;
    for (int sub = 0; sub < n_sub; ++sub) {
        double h = dt;
        if (n_sub == 3) h = sub == 1 ? w0 * dt : w1 * dt;
        const double hk = 0.5 * h;
        if (p.torqued) {
            b.lx += hk * p.tx; b.ly += hk * p.ty; b.lz += hk * p.tz;
        }
        if (!anchor_holds(an.n, an.dt, an.l0, an.l1, an.l2, h, b.lx, b.ly, b.lz)) {
            an = {b.q[0], b.q[1], b.q[2], b.q[3], b.lx, b.ly, b.lz, 0, h};
            row_ok = false;
        }
        if (!row_ok) {
            anchor_constants(row, an.aw, an.ax, an.ay, an.az, b.lx, b.ly, b.lz, p.k0, p.k1, p.k2, h);
            row_ok = true;
        }
        const i64 n = an.n + 1;
        double rj_c;
        b.q = anchored_quat(row, an.aw, an.ax, an.ay, an.az, static_cast<double>(n) * std::fabs(h),
                            b.q[0], b.q[1], b.q[2], b.q[3], rj_c);
        if (rj_c >= 0.0 && row[FC_RJC] < 0.0) row[FC_RJC] = rj_c;
        an.n = n;
        if (p.torqued) {
            b.lx += hk * p.tx; b.ly += hk * p.ty; b.lz += hk * p.tz;
        }
    }
    b.m = quat_to_mat(b.q[0], b.q[1], b.q[2], b.q[3]);
}

// Body i of exact / exact4 alone from step s_begin on, samples from row j on (the sparse path of
// advance_exact_range, tile 1): its state, anchor and flow-constant validity in locals for the
// whole block (the arrays written when a sample is due and at the end). The flow constants are
// recomputed from the anchor on the first step (a pure function of it, so a start at s_begin > 1
// continues bit for bit). Returns the samples written; fail_step the step at which the state
// went bad (-1 if none).
template <int METHOD>
i64 exact_single(const FreeArgs& a, i64 i, double* row, i64 s_begin, i64 j, i64& fail_step) {
    const double dt = a.dt;
    const double w1 = yoshida_w1(), w0 = yoshida_w0();
    Body<double> b = load_body<double>(a, i, true);
    const BodyParams<double> p = load_params<double>(a, i);
    const double kmax_dt = kmax_dt_of(p, dt);
    Anchor an = load_anchor(a, i);
    bool row_ok = false;
    SampleClock clock(a, s_begin);
    fail_step = -1;
    for (i64 s = s_begin; s <= a.n_steps; ++s) {
        exact_step<METHOD>(b, p, an, row, row_ok, dt, w1, w0);
        bool ok[1];
        if (!step_ok(ok, dt, b, p, kmax_dt)) {
            fail_step = s;
            break;
        }
        if (clock.due(s)) {
            store_body(a, i, b, true);
            sample<METHOD>(a, j, i);
            j += 1;
        }
    }
    store_body(a, i, b, true);
    store_anchor(a, i, an);
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
    V2<double> L = a.angular_momentum, Q = a.quat_wxyz;
    V2<double> a_q = a.a_q, a_l = a.a_l;
    V1<i64> a_n = a.a_n;
    V1<double> a_dt = a.a_dt;
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
    Body<V> b = load_body<V>(a, i, true);
    const BodyParams<V> p = load_params<V>(a, i);
    const V kmax_dt = kmax_dt_of(p, dt);
    const double habs = std::fabs(h);
    auto store = [&]() {
        store_body(a, i, b, true);
        for (int l = 0; l < W; ++l) {
            const i64 k = i + l;
            a_q(k, 0) = aw[l]; a_q(k, 1) = ax[l]; a_q(k, 2) = ay[l]; a_q(k, 3) = az[l];
            a_l(k, 0) = al[l][0]; a_l(k, 1) = al[l][1]; a_l(k, 2) = al[l][2];
            a_n[k] = static_cast<i64>(nf[l]);
            a_dt[k] = adt[l];
        }
    };
    i64 j = 0;
    bool ok[W];
    for (int l = 0; l < W; ++l) ok[l] = true;
    SampleClock clock(a, 1);
    i64 s = 1;
    for (; s <= a.n_steps; ++s) {
        flight_exact(dt, p.im, b.x, b.y, b.z, b.px, b.py, b.pz, p.fx, p.fy, p.fz);
        // anchored_quat at n |h|
        nf = nf + 1.0;
        V cw, c0, c1, c2;
        flow_eval_lanes(f, rows, rjc, nf * habs, cw, c0, c1, c2);
        b.q = anchored_turn(aw, ax, ay, az, cw, c0, c1, c2, b.q);
        b.m = quat_to_mat(b.q[0], b.q[1], b.q[2], b.q[3]);
        if (!step_ok(ok, dt, b, p, kmax_dt)) break;
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

// The kernel of exact / exact4: advance_range's loops with exact_step.
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
                Body<double> b = load_body<double>(a, i, true);
                const BodyParams<double> p = load_params<double>(a, i);
                Anchor an = load_anchor(a, i);
                bool row_ok = fc_ok[r];
                exact_step<METHOD>(b, p, an, fc.data() + r * N_FLOW, row_ok, dt, w1, w0);
                fc_ok[r] = row_ok;
                store_body(a, i, b, true);
                store_anchor(a, i, an);
                bool ok1[1];
                ok = step_ok(ok1, dt, b, p, kmax_dt_of(p, dt));
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
