// The tunneling analyzer's row pass (rblog/analyze/tunneling.py): closest approach of two centres
// on the straight relative path between samples.
#include <algorithm>
#include <cmath>
#include <limits>

#include "audit/audit.hpp"

namespace rb {
namespace audit {

// For pairs (k, a, b): thr - (closest approach of the centres on the straight relative path from
// sample k to k+1), thr = thr_part[a] + thr_part[b]; -inf when they are closer than thr at either
// sample (already overlapping: penetration's business, not tunneling).
void chord_overlap(V3<double> position, V1<i64> k, V1<i64> a, V1<i64> b, V1<double> thr_part,
                   V1<double> out) {
    for (i64 r = 0; r < k.n0; ++r) {
        const i64 kk = k[r], ia = a[r], ib = b[r];
        const double thr = thr_part[ia] + thr_part[ib];
        const double d00 = position(kk, ia, 0) - position(kk, ib, 0);
        const double d01 = position(kk, ia, 1) - position(kk, ib, 1);
        const double d02 = position(kk, ia, 2) - position(kk, ib, 2);
        const double e0 = position(kk + 1, ia, 0) - position(kk + 1, ib, 0) - d00;
        const double e1 = position(kk + 1, ia, 1) - position(kk + 1, ib, 1) - d01;
        const double e2 = position(kk + 1, ia, 2) - position(kk + 1, ib, 2) - d02;
        const double n0 = d00 * d00 + d01 * d01 + d02 * d02;
        const double n1 = (d00 + e0) * (d00 + e0) + (d01 + e1) * (d01 + e1) + (d02 + e2) * (d02 + e2);
        if (n0 < thr * thr || n1 < thr * thr) {
            out[r] = -std::numeric_limits<double>::infinity();
            continue;
        }
        const double den = e0 * e0 + e1 * e1 + e2 * e2;
        double s = 0.0;
        if (den > 0) s = std::min(1.0, std::max(0.0, -(d00 * e0 + d01 * e1 + d02 * e2) / den));
        const double c0 = d00 + s * e0, c1 = d01 + s * e1, c2 = d02 + s * e2;
        out[r] = thr - std::sqrt(c0 * c0 + c1 * c1 + c2 * c2);
    }
}

}  // namespace audit
}  // namespace rb
