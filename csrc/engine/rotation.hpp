// Rotation math on scalars (rblog/engine/rotation.py, the same formulas in the same order).
// A matrix is a row-major 9-array (Mat3), a quaternion (w, x, y, z) a Quat, a vector a Vec3.
//
// Frames: q (wxyz, scalar first) and R map body-frame vectors to the world frame
// (v_world = R v_body). Angular momentum L is world frame; inv_inertia is the diagonal of
// I_body^-1 (principal axes), so omega = R diag(1/I) R^T L, as in the lecture notes.
// Everything is inline over scalars and small arrays, so a kernel stepping N bodies allocates
// nothing per step. (The analyzers keep their own geometry on purpose: an audit must not share
// the code it audits.)
#pragma once

#include <array>
#include <cmath>

#include "common/array.hpp"
#include "engine/free_constants.hpp"
#include "engine/lanes.hpp"

namespace rb {

// In T = double (one body) or a lane vector of lanes.hpp (a body per lane: the same operations in
// the same order, so each lane gets the one body's bits).
template <class T>
using Mat3T = std::array<T, 9>;  // row-major: m00 m01 m02 m10 ... m22
template <class T>
using QuatT = std::array<T, 4>;  // w x y z
template <class T>
using Vec3T = std::array<T, 3>;
using Mat3 = Mat3T<double>;
using Quat = QuatT<double>;
using Vec3 = Vec3T<double>;

// Hamilton product a (x) b.
template <class T>
inline QuatT<T> quat_mul(T aw, T ax, T ay, T az, T bw, T bx, T by, T bz) {
    return {aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw};
}

// Rotation matrix (row-major) of q. For |q| != 1 it returns |q|^2 times a rotation (the
// homogeneous form), so an unnormalized quaternion shows up as a scaled R.
template <class T>
inline Mat3T<T> quat_to_mat(T w, T x, T y, T z) {
    return {w * w + x * x - y * y - z * z, 2.0 * (x * y - w * z),         2.0 * (x * z + w * y),
            2.0 * (x * y + w * z),         w * w - x * x + y * y - z * z, 2.0 * (y * z - w * x),
            2.0 * (x * z - w * y),         2.0 * (y * z + w * x),         w * w - x * x - y * y + z * z};
}

inline void store_mat(V3<double> rotation, i64 i, const Mat3& m) {
    double* r = rotation.row(i);
    for (int k = 0; k < 9; ++k) r[k] = m[k];
}

inline Mat3 load_mat(V3<double> rotation, i64 i) {
    const double* r = rotation.row(i);
    return {r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]};
}

// Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method, w >= 0). For a matrix
// that is not exactly orthonormal it returns the normalized quaternion of the
// nearest-by-construction rotation, which is what a logger can show.
inline Quat mat_to_quat(const Mat3& m) {
    const double m00 = m[0], m01 = m[1], m02 = m[2], m10 = m[3], m11 = m[4], m12 = m[5],
                 m20 = m[6], m21 = m[7], m22 = m[8];
    const double tr = m00 + m11 + m22;
    double s, w, x, y, z;
    if (tr > 0.0) {
        s = std::sqrt(tr + 1.0) * 2.0;
        w = 0.25 * s; x = (m21 - m12) / s; y = (m02 - m20) / s; z = (m10 - m01) / s;
    } else if (m00 > m11 && m00 > m22) {
        s = std::sqrt(1.0 + m00 - m11 - m22) * 2.0;
        w = (m21 - m12) / s; x = 0.25 * s; y = (m01 + m10) / s; z = (m02 + m20) / s;
    } else if (m11 > m22) {
        s = std::sqrt(1.0 + m11 - m00 - m22) * 2.0;
        w = (m02 - m20) / s; x = (m01 + m10) / s; y = 0.25 * s; z = (m12 + m21) / s;
    } else {
        s = std::sqrt(1.0 + m22 - m00 - m11) * 2.0;
        w = (m10 - m01) / s; x = (m02 + m20) / s; y = (m12 + m21) / s; z = 0.25 * s;
    }
    double n = std::sqrt(w * w + x * x + y * y + z * z);
    if (w < 0.0) n = -n;
    return {w / n, x / n, y / n, z / n};
}

// omega = R diag(inv_i) R^T L for R given row-major.
template <class T>
inline Vec3T<T> omega_world(const Mat3T<T>& m, T inv_i0, T inv_i1, T inv_i2, T lx, T ly, T lz) {
    const T m00 = m[0], m01 = m[1], m02 = m[2], m10 = m[3], m11 = m[4], m12 = m[5], m20 = m[6],
            m21 = m[7], m22 = m[8];
    const T b0 = (m00 * lx + m10 * ly + m20 * lz) * inv_i0;
    const T b1 = (m01 * lx + m11 * ly + m21 * lz) * inv_i1;
    const T b2 = (m02 * lx + m12 * ly + m22 * lz) * inv_i2;
    return {m00 * b0 + m01 * b1 + m02 * b2, m10 * b0 + m11 * b1 + m12 * b2,
            m20 * b0 + m21 * b1 + m22 * b2};
}

// omega = I_world^-1 L with I_world = R I_body R^T, for an R that need not be orthonormal
// (row-major, invertible): omega = R^-T diag(inv_i) R^-1 L.
// The cofactor matrix C of the 3x3 matrix a (row-major; R^-1 = C^T / det R) and det a =
// a_0j C_0j, in a's value type (double, or a lane vector of lanes.hpp).
template <class T>
struct Cofactors {
    T c00, c01, c02, c10, c11, c12, c20, c21, c22, det;
};

template <class T>
inline Cofactors<T> cofactors(T a00, T a01, T a02, T a10, T a11, T a12, T a20, T a21, T a22) {
    Cofactors<T> c;
    c.c00 = a11 * a22 - a12 * a21;
    c.c01 = a12 * a20 - a10 * a22;
    c.c02 = a10 * a21 - a11 * a20;
    c.c10 = a02 * a21 - a01 * a22;
    c.c11 = a00 * a22 - a02 * a20;
    c.c12 = a01 * a20 - a00 * a21;
    c.c20 = a01 * a12 - a02 * a11;
    c.c21 = a02 * a10 - a00 * a12;
    c.c22 = a00 * a11 - a01 * a10;
    c.det = a00 * c.c00 + a01 * c.c01 + a02 * c.c02;
    return c;
}

// With C the cofactor matrix of R (R^-1 = C^T / det R, R^-T = C / det R):
// omega = C diag(inv_i) C^T L / det(R)^2. For an orthonormal R, C = R and det R = 1, and this is
// omega_world; for the scaled rotation R = s Q of an unnormalised quaternion (s = |q|^2) it is
// omega_world(Q) / s^2 (see integrators.hpp, seed-quat).
template <class T>
inline Vec3T<T> omega_world_stretched(const Mat3T<T>& m, T inv_i0, T inv_i1, T inv_i2, T lx, T ly,
                                      T lz) {
    const Cofactors<T> c = cofactors(m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]);
    const T c00 = c.c00, c01 = c.c01, c02 = c.c02, c10 = c.c10, c11 = c.c11, c12 = c.c12,
            c20 = c.c20, c21 = c.c21, c22 = c.c22;
    const T f = 1.0 / (c.det * c.det);
    const T b0 = (c00 * lx + c10 * ly + c20 * lz) * inv_i0 * f;
    const T b1 = (c01 * lx + c11 * ly + c21 * lz) * inv_i1 * f;
    const T b2 = (c02 * lx + c12 * ly + c22 * lz) * inv_i2 * f;
    return {c00 * b0 + c01 * b1 + c02 * b2, c10 * b0 + c11 * b1 + c12 * b2,
            c20 * b0 + c21 * b1 + c22 * b2};
}

// Python's max(a, b) for floats: a unless b > a (so a NaN b is skipped, a NaN a kept).
inline double py_max(double a, double b) { return b > a ? b : a; }

// Nearest rotation to m (orthogonal polar factor) by Newton's iteration R <- (R + R^-T)/2, at
// most POLAR_MAX_ITER iterations, stopping when the largest entry of the update is <= POLAR_TOL
// (quadratic convergence: the new iterate is then within ~d^2 of the limit). T = double for one
// matrix, or a lane vector of lanes.hpp for W matrices (drift_seed over lanes): a lane stops
// (keeps its iterate) once its own update is <= tol, so each lane gets the one-matrix bits.
template <class T>
inline std::array<T, 9> polar(const std::array<T, 9>& m) {
    using M = mask_of<T>;
    T a00 = m[0], a01 = m[1], a02 = m[2], a10 = m[3], a11 = m[4], a12 = m[5], a20 = m[6],
      a21 = m[7], a22 = m[8];
    const int max_iter = free_constants.polar_max_iter;
    const double tol = free_constants.polar_tol;
    M active = all_lanes<T>();
    for (int it = 0; it < max_iter; ++it) {
        // R^-T = cof(R) / det(R)
        const Cofactors<T> c = cofactors(a00, a01, a02, a10, a11, a12, a20, a21, a22);
        const T f = 0.5 / c.det;
        const T n00 = 0.5 * a00 + f * c.c00;
        const T n01 = 0.5 * a01 + f * c.c01;
        const T n02 = 0.5 * a02 + f * c.c02;
        const T n10 = 0.5 * a10 + f * c.c10;
        const T n11 = 0.5 * a11 + f * c.c11;
        const T n12 = 0.5 * a12 + f * c.c12;
        const T n20 = 0.5 * a20 + f * c.c20;
        const T n21 = 0.5 * a21 + f * c.c21;
        const T n22 = 0.5 * a22 + f * c.c22;
        T d = vabs(n00 - a00);
        d = vpymax(d, vabs(n01 - a01));
        d = vpymax(d, vabs(n02 - a02));
        d = vpymax(d, vabs(n10 - a10));
        d = vpymax(d, vabs(n11 - a11));
        d = vpymax(d, vabs(n12 - a12));
        d = vpymax(d, vabs(n20 - a20));
        d = vpymax(d, vabs(n21 - a21));
        d = vpymax(d, vabs(n22 - a22));
        if (all_set(active)) {  // the common case: no lane has stopped yet
            a00 = n00; a01 = n01; a02 = n02; a10 = n10; a11 = n11; a12 = n12;
            a20 = n20; a21 = n21; a22 = n22;
        } else {
            a00 = active ? n00 : a00; a01 = active ? n01 : a01; a02 = active ? n02 : a02;
            a10 = active ? n10 : a10; a11 = active ? n11 : a11; a12 = active ? n12 : a12;
            a20 = active ? n20 : a20; a21 = active ? n21 : a21; a22 = active ? n22 : a22;
        }
        active = and_not(active, d <= tol);
        if (!any(active)) break;
    }
    return {a00, a01, a02, a10, a11, a12, a20, a21, a22};
}

// Orthonormalize the columns of m in order (x axis kept, y made orthogonal, z = x cross y).
template <class T>
inline Mat3T<T> gram_schmidt(const Mat3T<T>& m) {
    const T m00 = m[0], m01 = m[1], m10 = m[3], m11 = m[4], m20 = m[6], m21 = m[7];
    T n = vsqrt(m00 * m00 + m10 * m10 + m20 * m20);
    const T x0 = m00 / n, x1 = m10 / n, x2 = m20 / n;
    const T d = x0 * m01 + x1 * m11 + x2 * m21;
    T y0 = m01 - d * x0, y1 = m11 - d * x1, y2 = m21 - d * x2;
    n = vsqrt(y0 * y0 + y1 * y1 + y2 * y2);
    y0 = y0 / n; y1 = y1 / n; y2 = y2 / n;
    const T z0 = x1 * y2 - x2 * y1, z1 = x2 * y0 - x0 * y2, z2 = x0 * y1 - x1 * y0;
    return {x0, y0, z0, x1, y1, z1, x2, y2, z2};
}

template <class T>
inline QuatT<T> normalize4(T w, T x, T y, T z) {
    const T n = 1.0 / vsqrt(w * w + x * x + y * y + z * z);
    return {w * n, x * n, y * n, z * n};
}

}  // namespace rb
