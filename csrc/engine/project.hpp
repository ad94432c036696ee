// The project stage (project.cpp, whose header has the derivation; bound as
// _core.project_positions and _core.apply_projection): a nonlinear position pass on fresh contact
// geometry after the drift. project_positions' grown buffers are Buf2& grown in place, its
// per-call work arrays (ring, done) and PROJECTION_RINGS (rings) come last.
#pragma once

#include <cstddef>

#include <vector>

#include "common/array.hpp"
#include "engine/collision.hpp"
#include "engine/records.hpp"

namespace rb {

// columns of the projection's point rows
constexpr i64 PJ_N = 0;   // normal from b into a (3)
constexpr i64 PJ_RA = 3;  // anchor on a (3): point - x_a
constexpr i64 PJ_RB = 6;  // anchor on b (3): point - x_b (0 for static)
constexpr i64 PJ_S = 9;   // separation at the end of the step (m), before this pass
constexpr i64 PJ_K = 10;  // 1 / effective inverse mass along the normal
constexpr i64 PJ_L = 11;  // accumulated position impulse (kg m)
constexpr i64 PROJ_COLS = 12;

i64 project_positions(V2<i64> pairs, i64 n_pairs, i64 n_dyn, i64 n_static, const Geoms& gm,
                      V1<double> inv_mass, V2<double> inv_inertia, V1<i64> iso,
                      bool iso_shortcut, V1<i64> awake, V2<double> position, V3<double> rotation,
                      V2<double> sb_pos, V3<double> sb_rot, V2<double> sb_ext, V1<double> gn,
                      double goff, double depth, i64 n_iter, Buf2<double>& rows, Buf2<i64>& ids,
                      ColliderBuffers& buf, V2<double> dx, V2<double> dth, i64 rings,
                      Buf2<i64>& ring, std::vector<char>& done);

void apply_projection(i64 n_deep, V2<i64> ids, V2<double> dx, V2<double> dth, i64 n, int method,
                      int ortho, const Bodies& bd, bool iso_shortcut, V2<double> position,
                      V3<double> rotation, V2<double> quat_wxyz, V2<double> linear_momentum,
                      V2<double> angular_momentum, V2<double> l_scratch, V1<i64> anchor_steps);

}  // namespace rb
