// The records every contact stage reads (Box2D v3's b2StepContext, b2BodyState and
// b2ContactConstraint): the step's context (its length and the run's settings), the solver's
// bodies and the step's contact constraints. A stage is stage(context, constraints, bodies).
//
// Views only: the arrays belong to the world step's Scratch and ContactCache (records.hpp) or to
// the Python caller.
#pragma once

#include <cstddef>  // size_t, which common/array.hpp uses

#include "common/array.hpp"
#include "engine/manifold.hpp"

namespace nanobind {
class handle;
}

namespace rb {

// Stage switches, then the solver settings spelled as rblog.engine.constants.ContactParams's
// fields (resolved for the run: step.py's Settings says how), then the module-level solver
// tolerances of rblog.engine.constants, spelled as the constants in lower case, so that the C++
// stages hold no second copy of them.
struct Settings {
    bool do_kick = false, do_sleep = false, iso_shortcut = false;
    i64 velocity_iterations = 0, max_velocity_iterations = 0;
    double velocity_tolerance = 0.0, over_relaxation = 1.0;
    i64 position_iterations = 0;
    double allowed_penetration = 0.0, position_correction_rate = 0.0, max_correction_speed = 0.0;
    double speculative_distance = 0.0, restitution_threshold = 0.0;
    double friction_anchor_distance = 0.0, sleep_speed = 0.0, sleep_time = 0.0;
    bool warm_starting = false;
    i64 projection_iterations = 0;
    double projection_depth = 0.0;
    bool static_friction_anchors = false;
    bool exact_contact_motion = false;     // stage 9's exact motion on one static surface
    i64 friction_newton_iters = 0;          // FRICTION_NEWTON_ITERS
    double friction_newton_tol = 0.0;       // FRICTION_NEWTON_TOL
    double block_reg = 0.0;                 // BLOCK_REG
    double friction_anchor_rate = 0.0;      // FRICTION_ANCHOR_RATE
    double friction_anchor_slide_frac = 0.0;  // FRICTION_ANCHOR_SLIDE_FRAC
    i64 projection_rings = 0;               // PROJECTION_RINGS
    // ContactParams.solver == "soft_step" (soft_step.cpp), its substeps, contact_hertz (Hz, inf
    // for None) and contact_damping_ratio
    bool soft_step = false;
    i64 substeps = 1;
    double contact_hertz = 0.0, contact_damping_ratio = 0.0;
    static Settings from_py(nanobind::handle r);  // records.hpp
};

// What every stage of one step reads: the step and the settings.
struct StepContext {
    double h = 0.0;      // s, the step
    double inv_h = 0.0;  // 1/s
    const Settings& settings;
};

// The solver's bodies (N+1 rows; row N the static dummy, zero inverse mass and velocity, standing
// for the ground, static boxes and sleeping bodies): world frame.
struct SolverBodies {
    V1<double> inv_mass;     // (N+1,) 1/kg
    V2<double> inv_inertia;  // (N+1, 6) world inverse inertia (xx, yy, zz, xy, xz, yz)
    V2<double> v;            // (N+1, 3) velocity, m/s (or the relax stage's pseudo velocity)
    V2<double> w;            // (N+1, 3) angular velocity, rad/s (or its pseudo twin)
};

// The step's contact constraints (manifold.hpp's records): per manifold its head mi[m] (pair
// key, bodies, its points pf[start .. start + count)) and its frame and solver data mf[m]
// (normal, tangents, coefficients, the normal block's factors, the friction anchor); per point
// pf[p] (anchors, separation, effective masses, impulses). The first n_man manifolds are used.
struct ContactConstraints {
    V1<ManifoldHead> mi;
    V1<Manifold> mf;
    V1<ContactPoint> pf;
    i64 n_man = 0;
};

}  // namespace rb
