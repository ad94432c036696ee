// The integrator registry's compiled side (rblog/engine/integrators.py keeps the registry, the
// METHOD_* / ORTHO_* codes and the docs; the same codes here). Owner: the free-body port.
// The contact step uses drift_rotation, drift_exact_anchored, sync_quat and turn_within_bound;
// their arguments mirror the Python functions', in the same order.
#pragma once

#include "common/array.hpp"
#include "engine/rotation.hpp"

namespace rb {

enum Ortho : int { ORTHO_NONE = 0, ORTHO_POLAR = 1, ORTHO_GRAM_SCHMIDT = 2, ORTHO_NORMALIZE = 3 };
enum Method : int {
    METHOD_SEED = 0, METHOD_SEED_QUAT = 1, METHOD_SPLITTING = 2, METHOD_RK4 = 3,
    METHOD_EXACT = 4, METHOD_EXACT4 = 5
};

// Body i's orientation over h with L (world) fixed, by `method` (not the exact ones: those go
// through drift_exact_anchored). tx, ty, tz: torque (rk4 only).
void drift_rotation(int method, int ortho, V2<double> quat_wxyz, V3<double> rotation,
                    V2<double> angular_momentum, V2<double> inv_inertia, i64 i, double h,
                    double tx = 0.0, double ty = 0.0, double tz = 0.0);

// The exact torque-free rotation of body i over h from its flow anchor (integrators.py).
// fc: (rows, N_FLOW) flow constants cache, r its row for this body, fc_ok (rows,) bool.
void drift_exact_anchored(V2<double> quat_wxyz, V3<double> rotation, V2<double> angular_momentum,
                          V2<double> inv_inertia, i64 i, double h, V2<double> anchor_quat_wxyz,
                          V2<double> anchor_L_world, V1<i64> anchor_steps, V1<double> anchor_dt_s,
                          V2<double> fc, i64 r, V1<bool> fc_ok);

// q[i] made to describe R[i] for the integrator that advances R (seed); no-op for the others.
void sync_quat(int method, V2<double> quat_wxyz, V3<double> rotation, i64 i);

// False when body i turns more than MAX_ROTATION_PER_STEP_RAD in a step of dt.
bool turn_within_bound(double dt, i64 i, V2<double> inv_inertia, V3<double> rotation,
                       V2<double> angular_momentum);

// Copy body i's state into sample row j of the out_* buffers (q synced from R first for seed).
void write_sample(int method, i64 j, i64 i, V2<double> position, V2<double> linear_momentum,
                  V2<double> quat_wxyz, V3<double> rotation, V2<double> angular_momentum,
                  V3<double> out_position, V3<double> out_linear_momentum,
                  V3<double> out_quat_wxyz, V4<double> out_rotation,
                  V3<double> out_angular_momentum);

// exact.N_FLOW: columns of a flow-constants row.
constexpr i64 N_FLOW = 41;

}  // namespace rb
