// The energy analyzer's row pass (rblog/analyze/energy.py): drift over contact-free stretches.
#include <algorithm>
#include <cmath>
#include <limits>

#include "audit/audit.hpp"

namespace rb {
namespace audit {

// Energy drift over each contact-free stretch (maximal run of free intervals of one body; free
// (T-1, N)). For each stretch [k0, k1] of body b: scale = max(max KE, max U - min U, floor m); at
// every sample k, drift |E(k) - E(k0)| against drift_rel scale + m |a| dt (|v(k)| + |v(k0)|) / 2.
// Writes per stretch (while it fits): segs = (b, k0, k1, worst k), vals = (worst ratio of drift
// to allowed, its drift / scale, its allowed / scale, scale, least-squares slope of
// (E - E(k0)) / scale against t). Returns the number of stretches.
i64 free_drift(V2<bool> free, V1<double> t, V2<double> e, V2<double> ke, V2<double> u,
               V2<double> speed, V1<double> mass, V1<double> amag, double dt, double drift_rel,
               double floor, V2<i64> segs, V2<double> vals) {
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
            const i64 k1 = k;  // last sample of the stretch (intervals k0 .. k1 - 1)
            double kmax = 0.0;
            double umin = u(k0, b);
            double umax = u(k0, b);
            for (i64 j = k0; j < k1 + 1; ++j) {
                kmax = std::max(kmax, ke(j, b));
                umin = std::min(umin, u(j, b));
                umax = std::max(umax, u(j, b));
            }
            const double scale = std::max(std::max(kmax, umax - umin), floor * mass[b]);
            double best = -1.0;
            i64 kb = k0;
            double st = 0.0, sy = 0.0, stt = 0.0, sty = 0.0;
            for (i64 j = k0; j < k1 + 1; ++j) {
                const double d = e(j, b) - e(k0, b);
                const double allow =
                    drift_rel * scale + 0.5 * mass[b] * amag[b] * dt * (speed(j, b) + speed(k0, b));
                const double r = allow > 0 ? std::fabs(d) / allow
                                           : (d != 0 ? std::numeric_limits<double>::infinity() : 0.0);
                if (r > best) {
                    best = r;
                    kb = j;
                }
                const double tj = t[j] - t[k0];
                const double y = d / scale;
                st += tj;
                sy += y;
                stt += tj * tj;
                sty += tj * y;
            }
            const i64 npts = k1 - k0 + 1;
            const double den = npts * stt - st * st;
            if (cnt < cap) {
                const double d = e(kb, b) - e(k0, b);
                const double allow =
                    drift_rel * scale + 0.5 * mass[b] * amag[b] * dt * (speed(kb, b) + speed(k0, b));
                segs(cnt, 0) = b;
                segs(cnt, 1) = k0;
                segs(cnt, 2) = k1;
                segs(cnt, 3) = kb;
                vals(cnt, 0) = best;
                vals(cnt, 1) = std::fabs(d) / scale;
                vals(cnt, 2) = allow / scale;
                vals(cnt, 3) = scale;
                vals(cnt, 4) = den > 0 ? (npts * sty - st * sy) / den : 0.0;
            }
            cnt += 1;
        }
    }
    return cnt;
}

}  // namespace audit
}  // namespace rb
