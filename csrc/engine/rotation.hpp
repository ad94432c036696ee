// Rotation math on scalars (rblog/engine/rotation.py, the same formulas in the same order).
// A matrix is a row-major 9-array (Mat3), a quaternion (w, x, y, z) a Quat, a vector a Vec3.
// Implemented inline here (owner: the free-body port); until then, declarations only.
#pragma once

#include <array>
#include <cmath>

#include "common/array.hpp"

namespace rb {

using Mat3 = std::array<double, 9>;  // row-major: m00 m01 m02 m10 ... m22
using Quat = std::array<double, 4>;  // w x y z
using Vec3 = std::array<double, 3>;

inline Quat quat_mul(double aw, double ax, double ay, double az, double bw, double bx, double by, double bz);
inline Mat3 quat_to_mat(double w, double x, double y, double z);
inline void store_mat(V3<double> rotation, i64 i, const Mat3& m);
inline Mat3 load_mat(V3<double> rotation, i64 i);
inline Quat mat_to_quat(const Mat3& m);
inline Vec3 omega_world(const Mat3& m, double inv_i0, double inv_i1, double inv_i2, double lx, double ly, double lz);
inline Vec3 omega_world_stretched(const Mat3& m, double inv_i0, double inv_i1, double inv_i2, double lx, double ly, double lz);
inline Mat3 polar(const Mat3& m);
inline Mat3 gram_schmidt(const Mat3& m);
inline Quat normalize4(double w, double x, double y, double z);

}  // namespace rb
