// Manifold reduction (rblog/engine/contact/manifold.py: reduce_manifold, same steps and order).
//
// A clipped face contact can leave up to eight points; the solver takes four. The four kept are
// chosen as Gregorius proposes (GDC 2015), each among the *touching* points first (within
// MANIFOLD_TOUCH_BAND_M of the deepest) and among all points only when no touching point is
// left that adds length or area:
//
//   1. the deepest point;
//   2. the point farthest from it;
//   3. the point making the largest |triangle area| with 1 and 2, measured about the normal
//      (n . ((p1 - p0) x (pj - p0))), and its sign fixes the triangle's orientation;
//   4. the point farthest outside that triangle: the most negative signed area (orientation
//      times n . (edge x (pj - edge start))) over the triangle's three edges.
//
// Areas below AREA_EPS (m^2) add nothing (collinear points). Choosing touching points first
// keeps both ends of a level edge that lies on a face when the rest of the clipped polygon is
// speculative (the 500-box pile: see test_box_box_reduction_keeps_every_touching_end...).
#include "engine/collision.hpp"

#include <cmath>

namespace rb {

i64 reduce_manifold(const double* nrm, double (*pts)[3], double* sep, i64* fid, i64 count) {
    if (count <= MAX_MANIFOLD_POINTS) return count;
    const double nx = nrm[0], ny = nrm[1], nz = nrm[2];
    // 1: deepest
    i64 best = 0;
    for (i64 j = 1; j < count; ++j)
        if (sep[j] < sep[best]) best = j;
    swap_point(pts, sep, fid, 0, best);
    const double touch = sep[0] + collision_constants().manifold_touch_band_m;
    // 2: farthest from point 0 (touching first)
    best = -1;
    double bd = 0.0;
    for (int pass = 0; pass < 2; ++pass) {
        const bool only_touching = pass == 0;
        for (i64 j = 1; j < count; ++j) {
            if (only_touching && sep[j] > touch) continue;
            double dx = pts[j][0] - pts[0][0], dy = pts[j][1] - pts[0][1],
                   dz = pts[j][2] - pts[0][2];
            double d = dx * dx + dy * dy + dz * dz;
            if (d > bd) {
                bd = d;
                best = j;
            }
        }
        if (best >= 0) break;
    }
    swap_point(pts, sep, fid, 1, best > 1 ? best : 1);
    // 3: largest |triangle area| with 0, 1 (measured about the normal; touching first)
    const double ax = pts[1][0] - pts[0][0], ay = pts[1][1] - pts[0][1],
                 az = pts[1][2] - pts[0][2];
    best = -1;
    double ba = AREA_EPS;
    double sgn = 1.0;
    for (int pass = 0; pass < 2; ++pass) {
        const bool only_touching = pass == 0;
        for (i64 j = 2; j < count; ++j) {
            if (only_touching && sep[j] > touch) continue;
            double bx = pts[j][0] - pts[0][0], by = pts[j][1] - pts[0][1],
                   bz = pts[j][2] - pts[0][2];
            double area = nx * (ay * bz - az * by) + ny * (az * bx - ax * bz) +
                          nz * (ax * by - ay * bx);
            if (std::fabs(area) > ba) {
                ba = std::fabs(area);
                best = j;
                sgn = area >= 0.0 ? 1.0 : -1.0;
            }
        }
        if (best >= 0) break;
    }
    swap_point(pts, sep, fid, 2, best > 2 ? best : 2);
    // 4: the point farthest outside the triangle (most negative signed area over its edges;
    // touching first)
    best = -1;
    ba = -AREA_EPS;
    for (int pass = 0; pass < 2; ++pass) {
        const bool only_touching = pass == 0;
        for (i64 j = 3; j < count; ++j) {
            if (only_touching && sep[j] > touch) continue;
            double worst = 0.0;
            for (int e = 0; e < 3; ++e) {
                int i0 = e;
                int i1 = (e + 1) % 3;
                double ex = pts[i1][0] - pts[i0][0], ey = pts[i1][1] - pts[i0][1],
                       ez = pts[i1][2] - pts[i0][2];
                double qx = pts[j][0] - pts[i0][0], qy = pts[j][1] - pts[i0][1],
                       qz = pts[j][2] - pts[i0][2];
                double area = sgn * (nx * (ey * qz - ez * qy) + ny * (ez * qx - ex * qz) +
                                     nz * (ex * qy - ey * qx));
                if (area < worst) worst = area;
            }
            if (worst < ba) {
                ba = worst;
                best = j;
            }
        }
        if (best >= 0) break;
    }
    swap_point(pts, sep, fid, 3, best > 3 ? best : 3);
    return MAX_MANIFOLD_POINTS;
}

}  // namespace rb
