// Writing a collider's output rows (narrowphase.cpp's conventions: normal from b into a, one row
// per point: its world position, gap, feature id), for every collider file: a point type is any
// struct with x, y, z (capsule.cpp's V, convex::Vec).
#pragma once

#include "engine/collision.hpp"

namespace rb {

// Row k of a manifold: point p (world, m), gap s (m, < 0 penetration), feature id f.
template <class P>
inline void put(Pts pts, double* sep, i64* fid, i64 k, const P& p, double s, i64 f) {
    pts[k][0] = p.x;
    pts[k][1] = p.y;
    pts[k][2] = p.z;
    sep[k] = s;
    fid[k] = f;
}
// The manifold's unit normal n (world, from b into a) into nrm[0:3].
template <class P>
inline void put_normal(double* nrm, const P& n) {
    nrm[0] = n.x;
    nrm[1] = n.y;
    nrm[2] = n.z;
}

}  // namespace rb
