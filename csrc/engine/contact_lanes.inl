// The group kernel of the velocity solve (contact_lanes.hpp), one template for the scalar and the
// wide builds. Included inside an anonymous namespace by contact_lanes.cpp and
// contact_lanes_avx2.cpp, so that nothing compiled with -mavx2 can be linked in place of the
// portable code (every function here has internal linkage; only raw pointers, no views).
//
// The formulas and their order are contact_solver.cpp's (solve_velocities, lu_solve; the
// impulse and the friction update are one template for both: constraint_row.hpp's impulse_row,
// friction.hpp's friction_update): read them there; here each `if` on a lane's value is a select
// (W<T>::sel) and a loop with a lane-dependent length runs to the group's longest with the
// shorter lanes masked.

#pragma GCC diagnostic ignored "-Wpsabi"  // (internal, inlined: no ABI crosses a TU)
typedef double d4 __attribute__((vector_size(32)));
typedef long long m4 __attribute__((vector_size(32)));

template <class T>
struct W;

// one lane: T = double, masks are bools, lane l of the group's arrays
template <>
struct W<double> {
    typedef bool M;
    static constexpr int width = 1;
    static double ld(const double* p, int l) { return p[l]; }
    static void st(double* p, int l, double x) { p[l] = x; }
    static double splat(double x) { return x; }
    static double sel(M m, double a, double b) { return m ? a : b; }
    static M mand(M a, M b) { return a && b; }
    static M mor(M a, M b) { return a || b; }
    static M mnot(M a) { return !a; }
    static bool any(M m) { return m; }
    static bool all(M m) { return m; }
    static bool lane(M m, int) { return m; }
    static M from(const bool* b, int l) { return b[l]; }
    static double vabs(double x) { return std::fabs(x); }
    static double vsqrt(double x) { return std::sqrt(x); }
    // a body's three numbers at vel + 8 rows[l] + off (off 0: v, 4: w)
    static void gather3(const double* vel, const i64* rows, int off, int l, double* o) {
        const double* p = vel + rows[l] * 8 + off;
        o[0] = p[0];
        o[1] = p[1];
        o[2] = p[2];
    }
    static void scatter3(double* vel, const i64* rows, int off, int l, const double* x, M m) {
        if (!m) return;
        double* p = vel + rows[l] * 8 + off;
        p[0] = x[0];
        p[1] = x[1];
        p[2] = x[2];
    }
};

// four lanes: T = d4 (GCC vector extension; AVX2 or two SSE2 halves), masks 0 / -1 per lane
template <>
struct W<d4> {
    typedef m4 M;
    static constexpr int width = 4;
    static d4 ld(const double* p, int) {
        d4 r;
        std::memcpy(&r, p, sizeof r);
        return r;
    }
    static void st(double* p, int, d4 x) { std::memcpy(p, &x, sizeof x); }
    static d4 splat(double x) { return d4{x, x, x, x}; }
    static d4 sel(M m, d4 a, d4 b) { return m ? a : b; }
    static M mand(M a, M b) { return a & b; }
    static M mor(M a, M b) { return a | b; }
    static M mnot(M a) { return ~a; }
#ifdef __AVX__
    static bool any(M m) { return __builtin_ia32_movmskpd256((d4)m) != 0; }
    static bool all(M m) { return __builtin_ia32_movmskpd256((d4)m) == 15; }
#else
    static bool any(M m) { return (m[0] | m[1] | m[2] | m[3]) != 0; }
    static bool all(M m) { return (m[0] & m[1] & m[2] & m[3]) != 0; }
#endif
    static bool lane(M m, int j) { return m[j] != 0; }
    static M from(const bool* b, int) {
        return M{b[0] ? -1LL : 0LL, b[1] ? -1LL : 0LL, b[2] ? -1LL : 0LL, b[3] ? -1LL : 0LL};
    }
    static d4 vabs(d4 x) {
        m4 bits;
        std::memcpy(&bits, &x, sizeof x);
        bits &= 0x7fffffffffffffffLL;
        d4 r;
        std::memcpy(&r, &bits, sizeof r);
        return r;
    }
    static d4 vsqrt(d4 x) {
#ifdef __AVX__
        return __builtin_ia32_sqrtpd256(x);
#else
        return d4{std::sqrt(x[0]), std::sqrt(x[1]), std::sqrt(x[2]), std::sqrt(x[3])};
#endif
    }
    // the four lanes' bodies: four rows (x, y, z, 0) loaded and transposed into x, y, z
    static void gather3(const double* vel, const i64* rows, int off, int, d4* o) {
        d4 r0, r1, r2, r3;
        std::memcpy(&r0, vel + rows[0] * 8 + off, sizeof r0);
        std::memcpy(&r1, vel + rows[1] * 8 + off, sizeof r1);
        std::memcpy(&r2, vel + rows[2] * 8 + off, sizeof r2);
        std::memcpy(&r3, vel + rows[3] * 8 + off, sizeof r3);
        d4 t0 = __builtin_shuffle(r0, r1, m4{0, 4, 2, 6});  // x0 x1 z0 z1
        d4 t1 = __builtin_shuffle(r0, r1, m4{1, 5, 3, 7});  // y0 y1 . .
        d4 t2 = __builtin_shuffle(r2, r3, m4{0, 4, 2, 6});  // x2 x3 z2 z3
        d4 t3 = __builtin_shuffle(r2, r3, m4{1, 5, 3, 7});  // y2 y3 . .
        o[0] = __builtin_shuffle(t0, t2, m4{0, 1, 4, 5});
        o[1] = __builtin_shuffle(t1, t3, m4{0, 1, 4, 5});
        o[2] = __builtin_shuffle(t0, t2, m4{2, 3, 6, 7});
    }
    // the transpose back, and each row stored where lane j of m is set
    static void scatter3(double* vel, const i64* rows, int off, int, const d4* x, M m) {
        const d4 zero = {0.0, 0.0, 0.0, 0.0};
        d4 u0 = __builtin_shuffle(x[0], x[1], m4{0, 4, 2, 6});  // x0 y0 x2 y2
        d4 u1 = __builtin_shuffle(x[0], x[1], m4{1, 5, 3, 7});  // x1 y1 x3 y3
        d4 u2 = __builtin_shuffle(x[2], zero, m4{0, 4, 2, 6});  // z0 0 z2 0
        d4 u3 = __builtin_shuffle(x[2], zero, m4{1, 5, 3, 7});  // z1 0 z3 0
        d4 r[4] = {__builtin_shuffle(u0, u2, m4{0, 1, 4, 5}), __builtin_shuffle(u1, u3, m4{0, 1, 4, 5}),
                   __builtin_shuffle(u0, u2, m4{2, 3, 6, 7}), __builtin_shuffle(u1, u3, m4{2, 3, 6, 7})};
        for (int j = 0; j < 4; ++j)
            if (m[j]) std::memcpy(vel + rows[j] * 8 + off, &r[j], sizeof r[j]);
    }
};

// constraint_row.hpp's impulse_row on the group's lanes. (The inverse inertias are read from the
// group where they are used, not held in locals: the kernel has more live values than a
// processor has vector registers, and a value read from memory folds into the multiply instead
// of being spilled and reloaded.)
template <class T>
inline void lane_impulse(typename W<T>::M on, const WideGroup& gr, int l, const T* ra,
                         const T* rb, const T& px, const T& py, const T& pz, T* va, T* wa, T* vb,
                         T* wb) {
    typedef W<T> w;
    if (!w::any(on)) return;
    impulse_row<T, w>(
        on, w::ld(gr.ma, l), [&](int k) { return w::ld(gr.a6[k], l); }, w::ld(gr.mb, l),
        [&](int k) { return w::ld(gr.b6[k], l); }, ra, rb, px, py, pz, va, wa, vb, wb);
}

// One sweep's visit of group gr (solve_velocities' loop body for its four manifolds): lane l for
// T = double, all four for T = d4. NP > 0: the group's n_pts as a constant, so that the compiler
// unrolls the loops over the points (the AVX2 kernel's instances, solve_groups_avx2; the
// operations and their order are those of NP = 0, the count read from the group).
template <class T, int NP = 0>
inline void solve_group(WideGroup& gr, int l, const LaneCtx& cx, double* change, i64* visits) {
    typedef W<T> w;
    typedef typename W<T>::M M;
    const int j0 = w::width == 1 ? l : 0, j1 = w::width == 1 ? l + 1 : 4;
    // which lanes this sweep visits: past min_iter, those with a body a previous sweep changed
    bool vb_[4] = {false, false, false, false};
    bool any_visit = false;
    for (int j = j0; j < j1; ++j) {
        i64 ia = gr.a[j], ib = gr.b[j];
        vb_[j] = gr.on[j] != 0.0 &&
                 !(cx.it > cx.min_iter && cx.hot[ia] < cx.it - 1 && cx.hot[ib] < cx.it - 1);
        if (vb_[j]) {
            *visits += 1;
            any_visit = true;
        }
    }
    if (!any_visit) return;
    const M vis = w::from(vb_, l);
    const T zero = w::splat(0.0);
    const T tol = w::splat(cx.tol);
    const T tol1 = w::splat(cx.tol1);
    T chg = zero;
    M mark = vis & w::mnot(vis);  // all false
    const T om = w::ld(gr.om, l);
    T nv[3], t1[3], t2[3];
    for (int k = 0; k < 3; ++k) {
        nv[k] = w::ld(gr.n[k], l);
        t1[k] = w::ld(gr.t1[k], l);
        t2[k] = w::ld(gr.t2[k], l);
    }
    const T mu = w::ld(gr.mu, l), cnt = w::ld(gr.cnt, l);
    T va[3], wa[3], vb[3], wb[3];
    w::gather3(cx.vel, gr.a, 0, l, va);
    w::gather3(cx.vel, gr.a, 4, l, wa);
    w::gather3(cx.vel, gr.b, 0, l, vb);
    w::gather3(cx.vel, gr.b, 4, l, wb);
    const int np = NP > 0 ? NP : (int)gr.n_pts;
    M pt[4];  // point slot i exists in the lane
    for (int i = 0; i < 4; ++i) pt[i] = w::splat((double)i) < cnt;
    // non-penetration: the manifold's points together (block), else one by one
    M block = w::mand(vis, w::mand(w::splat(1.0) < cnt, zero < w::ld(gr.luok, l)));
    M solved = block & w::mnot(block);
    if (w::any(block)) {
        T rhs[4];
        for (int i = 0; i < np; ++i) {
            T ra[3], rb[3];
            for (int k = 0; k < 3; ++k) {
                ra[k] = w::ld(gr.ra[i][k], l);
                rb[k] = w::ld(gr.rb[i][k], l);
            }
            T dvx, dvy, dvz;
            gap_velocity<T, W<T>>(va, wa, vb, wb, ra, rb, dvx, dvy, dvz);
            T vn = dvx * nv[0] + dvy * nv[1] + dvz * nv[2];
            rhs[i] = w::ld(gr.target[i], l) - vn;
        }
        lu_solve_rows<T, w>(
            np, pt, [&](int k) { return w::ld(gr.lu[k], l); },
            [&](int c) { return w::ld(gr.piv[c], l); }, rhs);
        M ok = block;
        for (int i = 0; i < np; ++i)
            ok = w::mand(ok, w::mnot(w::mand(pt[i], w::ld(gr.ln[i], l) + om * rhs[i] < zero)));
        solved = ok;
        if (w::any(ok)) {
            for (int i = 0; i < np; ++i) {
                M on = w::mand(ok, pt[i]);
                T d = om * rhs[i];
                T ln = w::ld(gr.ln[i], l);
                w::st(gr.ln[i], l, w::sel(on, ln + d, ln));
                M moved = w::mand(on, d != zero);
                T dv = w::vabs(d) / w::ld(gr.nmass[i], l);
                chg = w::sel(w::mand(moved, dv > chg), dv, chg);
                mark = w::mor(mark, w::mand(moved, dv > tol));
                T ra[3], rb[3];
                for (int k = 0; k < 3; ++k) {
                    ra[k] = w::ld(gr.ra[i][k], l);
                    rb[k] = w::ld(gr.rb[i][k], l);
                }
                lane_impulse<T>(on, gr, l, ra, rb, d * nv[0], d * nv[1], d * nv[2], va,
                                wa, vb, wb);
            }
        }
    }
    M single = w::mand(vis, w::mnot(solved));
    if (w::any(single)) {
        // the lanes whose over-relaxed increment pulled a loaded point below zero this visit
        M unload = single & w::mnot(single);  // all false
        for (int i = 0; i < np; ++i) {
            M on = w::mand(single, pt[i]);
            T ra[3], rb[3];
            for (int k = 0; k < 3; ++k) {
                ra[k] = w::ld(gr.ra[i][k], l);
                rb[k] = w::ld(gr.rb[i][k], l);
            }
            // relative normal velocity at the contact (a minus b)
            T dvx, dvy, dvz;
            gap_velocity<T, W<T>>(va, wa, vb, wb, ra, rb, dvx, dvy, dvz);
            T vn = dvx * nv[0] + dvy * nv[1] + dvz * nv[2];
            // clamp the accumulated impulse
            T old = w::ld(gr.ln[i], l);
            T nw = old + om * w::ld(gr.nmass[i], l) * (w::ld(gr.target[i], l) - vn);
            unload = w::mor(unload, w::mand(on, w::mand(zero < old, nw < zero)));
            nw = w::sel(nw < zero, zero, nw);
            w::st(gr.ln[i], l, w::sel(on, nw, old));
            T d = nw - old;
            M moved = w::mand(on, d != zero);
            T dv = w::vabs(d) / w::ld(gr.nmass[i], l);
            chg = w::sel(w::mand(moved, dv > chg), dv, chg);
            mark = w::mor(mark, w::mand(moved, dv > tol));
            lane_impulse<T>(on, gr, l, ra, rb, d * nv[0], d * nv[1], d * nv[2], va, wa,
                            vb, wb);
        }
        // Safeguarded SOR: a manifold whose over-relaxed normal update clamped a loaded point
        // to zero is solved by plain Gauss-Seidel (om = 1) for the rest of this solve. Projected
        // SOR converges on the normal rows alone (symmetric positive definite, Cryer 1971), but
        // the Coulomb rows make the problem unsymmetric (their bound is mu lambda_n): a sliding
        // corner over-relaxed by 1.6 can overshoot (vn > 0), lose its load to the clamp in the
        // next sweep, and with it its friction, back to where the solve started: a cycle of two
        // sweeps that never converges and, on an even sweep cap, ends with the contact
        // unloaded while it approaches at 0.5 m/s (tests/engine/contact/test_sor_safeguard.py).
        // (Measured on samples/pile.toml seeds 1-12: this rule 11 clean; firing only where plain
        // Gauss-Seidel would have kept the load 3 of the first 9, several creeping boxes each.)
        if (w::any(unload)) w::st(gr.om, l, w::sel(unload, w::splat(1.0), om));
    }
    // friction
    M fric = w::mand(vis, zero < mu);
    if (w::any(fric)) {
        for (int i = 0; i < np; ++i) {
            M on = w::mand(fric, pt[i]);
            T ra[3], rb[3];
            for (int k = 0; k < 3; ++k) {
                ra[k] = w::ld(gr.ra[i][k], l);
                rb[k] = w::ld(gr.rb[i][k], l);
            }
            T dvx, dvy, dvz;
            gap_velocity<T, W<T>>(va, wa, vb, wb, ra, rb, dvx, dvy, dvz);
            T vt1 = dvx * t1[0] + dvy * t1[1] + dvz * t1[2];
            T vt2 = dvx * t2[0] + dvy * t2[1] + dvz * t2[2];
            T k11 = w::ld(gr.tk[i][0], l), k12 = w::ld(gr.tk[i][1], l), k22 = w::ld(gr.tk[i][2], l);
            T o1 = w::ld(gr.l1[i], l), o2 = w::ld(gr.l2[i], l);
            T n1, n2;
            friction_update_k<T, W<T>>(on, k11, k12, k22, w::ld(gr.det[i], l), o1, o2, vt1, vt2,
                                       mu * w::ld(gr.ln[i], l), cx.newton_iters, tol1, n1, n2);
            w::st(gr.l1[i], l, w::sel(on, n1, o1));
            w::st(gr.l2[i], l, w::sel(on, n2, o2));
            T d1 = n1 - o1;
            T d2 = n2 - o2;
            T dv = w::vabs(d1) * k11 + w::vabs(d2) * k22;
            chg = w::sel(w::mand(on, dv > chg), dv, chg);
            mark = w::mor(mark, w::mand(on, dv > tol));
            T px = d1 * t1[0] + d2 * t2[0];
            T py = d1 * t1[1] + d2 * t2[1];
            T pz = d1 * t1[2] + d2 * t2[2];
            lane_impulse<T>(on, gr, l, ra, rb, px, py, pz, va, wa, vb, wb);
        }
    }
    // scatter the velocities of the visited lanes' bodies (never the static dummy's: it does not
    // move, and the lanes of a colour all touch it), the hot marks, the largest change
    bool a_dyn[4] = {false, false, false, false}, b_dyn[4] = {false, false, false, false};
    for (int j = j0; j < j1; ++j) {
        a_dyn[j] = gr.a[j] != cx.dummy;
        b_dyn[j] = gr.b[j] != cx.dummy;
    }
    M wa_on = w::mand(vis, w::from(a_dyn, l));
    M wb_on = w::mand(vis, w::from(b_dyn, l));
    w::scatter3(cx.vel, gr.a, 0, l, va, wa_on);
    w::scatter3(cx.vel, gr.a, 4, l, wa, wa_on);
    w::scatter3(cx.vel, gr.b, 0, l, vb, wb_on);
    w::scatter3(cx.vel, gr.b, 4, l, wb, wb_on);
    for (int j = j0; j < j1; ++j) {
        int jj = w::width == 1 ? 0 : j;
        if (w::lane(mark, jj)) {
            // the static dummy (zero inverse mass) never turns hot
            if (gr.ma[j] > 0.0) cx.hot[gr.a[j]] = cx.it;
            if (gr.mb[j] > 0.0) cx.hot[gr.b[j]] = cx.it;
        }
        double cj;
        std::memcpy(&cj, reinterpret_cast<const double*>(&chg) + jj, sizeof cj);
        if (cj > *change) *change = cj;
    }
}
