// The momentum analyzer's row passes (rblog/analyze/momentum.py): the friction cone of the
// inferred contact impulses, and momentum drift over free flights.
#include <algorithm>
#include <cmath>

#include "audit/audit.hpp"

namespace rb {
namespace audit {

// Per row r (body i[r] over interval k[r], inferred impulse jv[r], normal nrm[r]): the normal and
// tangential impulse jn, jt (N s) and the cone excess max(jt - mu jn, -jn) / |J|, zeroed where it
// is not above the floor floor_ns + res_eps m (max |v| + |a| dt) (the log's impulse resolution).
// The arithmetic in the order of the numpy it once replaced (einsum's (p0 + p2) + p1, norm's
// sequential sum), so reports stay bit-identical; tiny keeps |J| + tiny above 0.
void cone_kernel(V2<double> jv, V2<double> nrm, V1<double> mu, V1<double> mass, V2<double> speed,
                 V1<double> accel_norm, V1<double> dts, V1<i64> k, V1<i64> i, double floor_ns,
                 double res_eps, double tiny, V1<double> jn, V1<double> jt, V1<double> excess) {
    const double nan = std::nan("");
    for (i64 r = 0; r < k.n0; ++r) {
        const i64 kr = k[r], b = i[r];
        const double j0 = jv(r, 0), j1 = jv(r, 1), j2 = jv(r, 2);
        const double n0 = nrm(r, 0), n1 = nrm(r, 1), n2 = nrm(r, 2);
        const double jnr = (j0 * n0 + j2 * n2) + j1 * n1;  // normal impulse
        const double t0 = j0 - jnr * n0, t1 = j1 - jnr * n1, t2 = j2 - jnr * n2;
        const double jtr = std::sqrt((t0 * t0 + t1 * t1) + t2 * t2);  // tangential
        const double jm = std::sqrt((j0 * j0 + j1 * j1) + j2 * j2) + tiny;
        const double a = jtr - mu[r] * jnr, c = -jnr;
        const double ex_ns = (a != a || c != c) ? nan : (a >= c ? a : c);
        const double s0 = speed(kr, b), s1 = speed(kr + 1, b);
        const double sp = (s0 != s0 || s1 != s1) ? nan : (s0 >= s1 ? s0 : s1);
        const double floor = floor_ns + res_eps * mass[b] * (sp + accel_norm[b] * dts[kr]);
        jn[r] = jnr;
        jt[r] = jtr;
        excess[r] = ex_ns > floor ? ex_ns / jm : 0.0;
    }
}

// Momentum drift over each free flight (maximal run of free intervals of one body; free
// (T-1, N)). For flight [k0, k1] of body b, at every sample k: |P(k) - P(k0) - force (t_k - t_k0)|
// against the scale m max|v| + p_floor, and |L(k) - L(k0) - tau (t_k - t_k0)| against max|L| +
// l_floor. Writes per flight (while it fits): segs = (b, k0, k1, worst k linear, worst k angular),
// vals = (linear rel, its scale, its drift, angular rel, scale, drift). Returns the number of
// flights.
i64 flight_drift(V2<bool> free, V1<double> t, V3<double> p, V3<double> l, V2<double> speed,
                 V1<double> mass, V2<double> force, V2<double> tau, V1<double> p_floor,
                 V1<double> l_floor, V2<i64> segs, V2<double> vals) {
    const i64 kn = free.n0, n = free.n1;
    const i64 cap = segs.n0;
    i64 cnt = 0;
    for (i64 b = 0; b < n; ++b) {
        i64 k = 0;
        while (k < kn) {
            if (!free(k, b)) {
                k += 1;
                continue;
            }
            const i64 k0 = k;
            while (k < kn && free(k, b)) k += 1;
            const i64 k1 = k;
            // one pass: the largest drifts and the largest |v|, |L| (squared until the end)
            double v2 = speed(k0, b) * speed(k0, b);
            double l2 = l(k0, b, 0) * l(k0, b, 0) + l(k0, b, 1) * l(k0, b, 1) +
                        l(k0, b, 2) * l(k0, b, 2);
            double dp2 = 0.0, dl2 = 0.0;
            i64 kp = k0, kl = k0;
            for (i64 j = k0 + 1; j < k1 + 1; ++j) {
                const double dt = t[j] - t[k0];
                double dp = 0.0, dl = 0.0, lj = 0.0;
                for (int d = 0; d < 3; ++d) {
                    const double x = p(j, b, d) - p(k0, b, d) - force(b, d) * dt;
                    const double y = l(j, b, d) - l(k0, b, d) - tau(b, d) * dt;
                    dp += x * x;
                    dl += y * y;
                    lj += l(j, b, d) * l(j, b, d);
                }
                v2 = std::max(v2, speed(j, b) * speed(j, b));
                l2 = std::max(l2, lj);
                if (dp > dp2) {
                    dp2 = dp;
                    kp = j;
                }
                if (dl > dl2) {
                    dl2 = dl;
                    kl = j;
                }
            }
            const double ps = mass[b] * std::sqrt(v2) + p_floor[b];
            const double ls = std::sqrt(l2) + l_floor[b];
            const double dp_max = std::sqrt(dp2);
            const double dl_max = std::sqrt(dl2);
            if (cnt < cap) {
                segs(cnt, 0) = b;
                segs(cnt, 1) = k0;
                segs(cnt, 2) = k1;
                segs(cnt, 3) = kp;
                segs(cnt, 4) = kl;
                vals(cnt, 0) = dp_max / ps;
                vals(cnt, 1) = ps;
                vals(cnt, 2) = dp_max;
                vals(cnt, 3) = dl_max / ls;
                vals(cnt, 4) = ls;
                vals(cnt, 5) = dl_max;
            }
            cnt += 1;
        }
    }
    return cnt;
}

}  // namespace audit
}  // namespace rb
