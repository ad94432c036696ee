// The free-body kernels (free.cpp): advance free bodies (no contacts) many steps per call.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "common/array.hpp"

namespace rb {

// The arguments of rblog.engine.free.advance_free_range, as views (shapes there).
struct FreeArgs {
    int ortho = 0;
    double dt = 0.0;
    i64 n_steps = 0, stride = 1;
    bool sample_last = false;
    i64 tile = 1;  // bodies stepped together (free.BODY_TILE, or 1 for sparse samples)
    V1<double> inv_mass;
    V2<double> inv_inertia, force_world, torque_world;
    V2<double> position, linear_momentum, quat_wxyz;
    V3<double> rotation;
    V2<double> angular_momentum;
    V3<double> out_position, out_linear_momentum, out_quat_wxyz;
    V4<double> out_rotation;
    V3<double> out_angular_momentum;
    // the FlowAnchors arrays (exact integrators)
    V2<double> a_q, a_l;
    V1<i64> a_n;
    V1<double> a_dt;
};

// (n_samples, bad_step, bad_body): samples written, the first local step (1-based) at which some
// body's state became non-finite or turned too far (-1 if none), and that body.
struct FreeResult {
    i64 n_samples = 0, bad_step = -1, bad_body = -1;
};

// Bodies b0 .. b1-1 by integrator `method`.
FreeResult advance_free_range(int method, const FreeArgs& a, i64 b0, i64 b1);

// Every range [b0, b1) of `ranges` as a task of the engine's pool; the serial kernel's reduction.
FreeResult advance_free(int method, const FreeArgs& a,
                        const std::vector<std::pair<i64, i64>>& ranges);

}  // namespace rb
