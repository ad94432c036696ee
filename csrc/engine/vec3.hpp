// A plain 3-vector for the narrowphase's closed-form colliders (capsule.cpp, polytope.cpp): value
// semantics, the arithmetic the derivations are written in (a + b, a - b, s a, dot, cross). The
// operators sit in rb::vec, found by argument-dependent lookup.
#pragma once

namespace rb::vec {

struct V {
    double x, y, z;
};
inline V operator+(V a, V b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V operator-(V a, V b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline V operator*(double s, V a) { return {s * a.x, s * a.y, s * a.z}; }
inline double dot(V a, V b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline V cross(V a, V b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

}  // namespace rb::vec
