// The soft step (soft_step.cpp): Box2D v3's sub-stepped contact solve, the world step's stages 6-8
// when ContactParams.solver is "soft_step". Shapes and frames as contact_solver.hpp.
#pragma once

#include <cstddef>  // size_t, which common/array.hpp uses

#include "common/array.hpp"
#include "engine/step_context.hpp"

namespace rb {

// Box2D v3's b2Softness (solver.h, b2MakeSoft): a contact as a spring of `hertz` with damping
// ratio `zeta`, stepped by implicit Euler over h. bias_rate (1/s) turns a separation into a
// target velocity; mass_scale and impulse_scale soften the impulse (see soft_step.cpp).
struct Softness {
    double bias_rate, mass_scale, impulse_scale;
};
Softness make_soft(double hertz, double zeta, double h);

// Stages 6-8 as Box2D v3's b2SolverStage loop over `substeps` substeps of h / substeps: gravity
// (and the applied forces) are kicked per substep, and per substep the bodies' velocities are
// warm-started, solved with the soft bias, their positions integrated (into per-body
// displacements only) and relaxed without bias. On return ln, l1, l2 hold the step's
// total impulses (the sum over the substeps, as the PGS solve's accumulated impulses), bv/bw the
// end velocities and pv/pw the difference between the substeps' mean velocity and the end one,
// so that stage 9's x += h (v + v') moves every pushed body by the substeps' displacement.
//
// settings: substeps, contact_hertz (capped at a quarter of the substep rate),
// contact_damping_ratio, max_correction_speed (the push-out speed's cap, m/s),
// static_friction_anchors, friction_newton_iters, friction_newton_tol. pv, pw: (N+1, 3) pseudo
// velocities; in_contact: (N+1,) active manifolds per body (load_bodies); accel: (N, 3) g + F/m;
// torque: (N, 3) applied torque (world); do_kick: the kick stage ran (its h a and h I^-1 tau are
// taken back out of b.v/b.w and applied per substep). Returns the manifold sweeps made (2 a
// substep).
i64 soft_solve(const StepContext& ctx, const ContactConstraints& c, const SolverBodies& b,
               V2<double> pv, V2<double> pw, V1<i64> in_contact, V2<double> accel,
               V2<double> torque, bool do_kick);

// Between mark_pushed and stage 9: the pseudo velocity of a pushed body of an island away from
// static geometry (pushed == 1, see world_step.cpp's mark_pushed) loses the substeps' own lag
// behind the end velocity under the constant acceleration a, pv += h a (substeps - 1) /
// (2 substeps) (a free body's substeps move it h v_end - h^2 a (substeps - 1) / (2 substeps)).
// Stage 9's exact-flight term - h^2 a / 2 then moves the body by the substeps' displacement
// minus h^2 a / (2 substeps), each substep's exact flight, so that such an island's centre of
// mass stays on the exact parabola; and the orbital hand-back h v' x P sees only what the
// contacts' timing within the step moved, as with the PGS solve's relax stage. pv: (N+1, 3).
void soft_island_flight(V1<i64> awake, V1<i64> in_contact, V1<i64> pushed, V2<double> accel,
                        V2<double> pv, double h, i64 substeps);

}  // namespace rb
