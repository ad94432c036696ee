// The constraint row's impulse, one template for one body pair (T = double) and for four pairs in
// the lanes of a vector (contact_lanes.inl's velocity solve, T = d4). Every lane does the scalar
// operations in the scalar order (no fused multiply-add: -ffp-contract=off), so a pair's result is
// bitwise the same on either path.
#pragma once

#include <cmath>

namespace rb {

// One lane's traits (contact_lanes.inl's W<d4> has the same for four): T = double, masks bools.
struct ScalarLane {
    typedef bool M;
    static double splat(double x) { return x; }
    static double sel(M m, double a, double b) { return m ? a : b; }
    static M mand(M a, M b) { return a && b; }
    static M mor(M a, M b) { return a || b; }
    static M mnot(M a) { return !a; }
    static bool any(M m) { return m; }
    static bool all(M m) { return m; }
    static double vsqrt(double x) { return std::sqrt(x); }
};

// +P on body a at anchor r_a, -P on body b at r_b: velocity changes m^-1 P and I_world^-1 (r x P),
// so the pair's linear momentum and its angular momentum about any point are unchanged to
// round-off. ma/mb inverse masses (0 for the static dummy), a6(k)/b6(k) the world inverse
// inertias' components (xx, yy, zz, xy, xz, yz), ra/rb the anchors and p the impulse (world,
// N s); the velocities va, wa, vb, wb (3 each) change in the lanes where `on` (Lw: the lanes'
// traits). When every lane is on the selects are left out: sel(on, x, y) is x then, so the bits
// are the same either way.
template <class T, class Lw, class A6, class B6>
inline void impulse_row(typename Lw::M on, const T& ma, const A6& a6, const T& mb, const B6& b6,
                        const T* ra, const T* rb, const T& px, const T& py, const T& pz, T* va,
                        T* wa, T* vb, T* wb) {
    if (!Lw::any(on)) return;
    T cx = ra[1] * pz - ra[2] * py, cy = ra[2] * px - ra[0] * pz, cz = ra[0] * py - ra[1] * px;
    T ex = a6(0) * cx + a6(3) * cy + a6(4) * cz;
    T ey = a6(3) * cx + a6(1) * cy + a6(5) * cz;
    T ez = a6(4) * cx + a6(5) * cy + a6(2) * cz;
    T dx = rb[1] * pz - rb[2] * py, dy = rb[2] * px - rb[0] * pz, dz = rb[0] * py - rb[1] * px;
    T fx = b6(0) * dx + b6(3) * dy + b6(4) * dz;
    T fy = b6(3) * dx + b6(1) * dy + b6(5) * dz;
    T fz = b6(4) * dx + b6(5) * dy + b6(2) * dz;
    if (Lw::all(on)) {
        va[0] = va[0] + ma * px;
        va[1] = va[1] + ma * py;
        va[2] = va[2] + ma * pz;
        wa[0] = wa[0] + ex;
        wa[1] = wa[1] + ey;
        wa[2] = wa[2] + ez;
        vb[0] = vb[0] - mb * px;
        vb[1] = vb[1] - mb * py;
        vb[2] = vb[2] - mb * pz;
        wb[0] = wb[0] - fx;
        wb[1] = wb[1] - fy;
        wb[2] = wb[2] - fz;
        return;
    }
    va[0] = Lw::sel(on, va[0] + ma * px, va[0]);
    va[1] = Lw::sel(on, va[1] + ma * py, va[1]);
    va[2] = Lw::sel(on, va[2] + ma * pz, va[2]);
    wa[0] = Lw::sel(on, wa[0] + ex, wa[0]);
    wa[1] = Lw::sel(on, wa[1] + ey, wa[1]);
    wa[2] = Lw::sel(on, wa[2] + ez, wa[2]);
    vb[0] = Lw::sel(on, vb[0] - mb * px, vb[0]);
    vb[1] = Lw::sel(on, vb[1] - mb * py, vb[1]);
    vb[2] = Lw::sel(on, vb[2] - mb * pz, vb[2]);
    wb[0] = Lw::sel(on, wb[0] - fx, wb[0]);
    wb[1] = Lw::sel(on, wb[1] - fy, wb[1]);
    wb[2] = Lw::sel(on, wb[2] - fz, wb[2]);
}

// the velocity of a's material point at a + r_a relative to b's at b + r_b:
// v_a + w_a x r_a - v_b - w_b x r_b. (Lw: the lanes' traits, unused but in the instance's name:
// the lanes' templates are instantiated with contact_lanes.inl's internal W<d4>, so an AVX2
// instance never stands in for the portable build's; see contact_lanes_avx2.cpp.)
template <class T, class Lw>
inline void gap_velocity(const T* va, const T* wa, const T* vb, const T* wb, const T* ra,
                         const T* rb, T& dvx, T& dvy, T& dvz) {
    dvx = va[0] + wa[1] * ra[2] - wa[2] * ra[1] - vb[0] - wb[1] * rb[2] + wb[2] * rb[1];
    dvy = va[1] + wa[2] * ra[0] - wa[0] * ra[2] - vb[1] - wb[2] * rb[0] + wb[0] * rb[2];
    dvz = va[2] + wa[0] * ra[1] - wa[1] * ra[0] - vb[2] - wb[0] * rb[1] + wb[1] * rb[0];
}

// Solve K x = b in place for a manifold's normal block (x: np values, row i used where pt[i];
// prepare_contacts' factor_block made the factors): piv(c) the row exchanged with row c
// (piv), lu(k) the 4 x 4 row-major factors (lu: the multipliers below the diagonal, U on
// and above). Each step acts in the lanes that have its rows.
template <class T, class Lw, class Lu, class Piv>
inline void lu_solve_rows(int np, const typename Lw::M* pt, const Lu& lu, const Piv& piv, T* x) {
    typedef typename Lw::M M;
    for (int c = 0; c < np; ++c) {
        M cm = pt[c];
        T pc = piv(c);
        T xc = x[c];
        T nc = xc;
        for (int r = c + 1; r < np; ++r) {
            M sw = Lw::mand(cm, pc == Lw::splat((double)r));
            nc = Lw::sel(sw, x[r], nc);
            x[r] = Lw::sel(sw, xc, x[r]);
        }
        x[c] = nc;
        for (int r = c + 1; r < np; ++r) x[r] = Lw::sel(pt[r], x[r] - lu(4 * r + c) * x[c], x[r]);
    }
    for (int c = np - 1; c >= 0; --c) {
        T v = x[c];
        for (int k = c + 1; k < np; ++k) v = Lw::sel(pt[k], v - lu(4 * c + k) * x[k], v);
        x[c] = Lw::sel(pt[c], v / lu(5 * c), x[c]);
    }
}

}  // namespace rb
