"""The integrators: one registry, one compiled step per integrator, used by every kind of scene.

Frames: ``q`` (wxyz) and ``R`` map body-frame vectors to the world frame. Angular momentum ``L``
is world frame; ``inv_inertia`` is the diagonal of I_body^-1 (principal axes).

The registry and the METHOD_* / ORTHO_* codes live here; every integrator's stages are C++
(csrc/engine/integrators.hpp, inline, so that the free-body kernel, templated on the integrator,
and the contact step compile them into their loops; the derivations below are also written
there). The functions below call them through rblog.engine._core with the arguments the Python
(numba) versions had. Drift functions update ``quat_wxyz[i]`` and ``rotation[i]`` of the
state arrays in place and keep the two consistent (except under the notes' own schemes with
orthonormalization off, where the integrator's R is the point of interest).

Derivations
-----------
Notes' scheme (``seed``): omega = R I_b^-1 R^T L, R <- R + h [omega]x R, then orthonormalize.
det(I + h[omega]x) = 1 + h^2 |omega|^2, so without orthonormalization det R grows like
exp(h * integral |omega|^2 dt): the body "stretches".

Notes' scheme on the quaternion (``seed-quat``): q <- q + h/2 (0, omega) (x) q. Normalized
(the default), R = R(q) is a rotation and omega = R I_b^-1 R^T L. With ``orthonormalize =
"none"`` |q| grows by sqrt(1 + h^2 |omega|^2 / 4) a step, and R is the homogeneous matrix of q,
R v = q (x) v (x) q* = |q|^2 Q v (Q the rotation of q / |q|): the body is shown turned by Q and
enlarged |q|^2 times in every direction, the notes' "stretch"; ||R^T R - I||_F = sqrt(3)
(|q|^4 - 1) is logged. The notes' inertia I_world = R I_b R^T with that R is then |q|^4 Q I_b Q^T,
which is exactly the inertia of the enlarged body at unchanged mass (moments scale with length
squared), so omega = I_world^-1 L = R^-T I_b^-1 R^-1 L = |q|^-4 Q I_b^-1 Q^T L
(rotation.hpp, omega_world_stretched): a body that grows while L is conserved
turns slower, as a skater opening her arms, and its energy L.omega/2 falls as |q|^-4. (The
shortcut I_world^-1 = R I_b^-1 R^T holds only for an orthonormal R; applied to R = |q|^2 Q it
would give omega |q|^4 times too fast, a feedback that speeds the stretch up.) The rotation
rate of the body is still omega, since q' = 1/2 (0, omega) q turns q v q* at omega whatever |q|.
Only the stretch is unphysical for a rigid body; given the stretch, the rest is consistent.

Splitting (``splitting``): the free-body Hamiltonian H = sum_k Lb_k^2 / (2 I_k) (Lb = R^T L) is a
sum of three exactly solvable parts. The flow of part k over time s rotates the body about its own
axis k by theta = s Lb_k / I_k (q <- q (x) (cos theta/2, sin theta/2 e_k)) and rotates Lb by
-theta about e_k, leaving L = R Lb unchanged. Strang composition 1(h/2) 2(h/2) 3(h) 2(h/2) 1(h/2)
is second order, symplectic and time-reversible; |L| (world) is untouched and R stays a product of
exact rotations, so both invariants hold to round-off (McLachlan 1993; Dullweber, Leimkuhler &
McLachlan 1997).

RK4 (``rk4``): classical RK4 on Euler's equations for the body momentum Lb = R^T L, the attitude by
the fourth-order commutator-free Lie group method (CF4) driven by the stage angular velocities,
then q turned about an axis normal to L so that R^T L points along the RK4 Lb (see
csrc/engine/integrators.hpp, drift_rk4; RK4 on q alone, with omega = R(q) I^-1 R(q)^T L, is 7-40x
less accurate at equal dt).

Exact (``exact``): the closed-form torque-free flow (:mod:`rblog.engine.exact`: Jacobi elliptic
functions for the body momentum, Carlson's integrals for the attitude), to round-off at any h.
With forces and torques: Strang splitting kick(h/2) exact-flow(h) kick(h/2), second order; the
world torque is constant over a step, so the only error is the splitting of the momentum kick
from the rotation. ``exact4``: Yoshida's triple jump of that step (h w1, h w0, h w1 with
w1 = 1 / (2 - 2^(1/3)), w0 = 1 - 2 w1), fourth order; without torque both are exact, and both
take the flow over h in one evaluation. The flow is evaluated from a per-body anchor (q_a, L_a)
at the elapsed time n h (:func:`drift_exact_anchored`, rblog.engine.state.FlowAnchors), not as a
one-step map of the carried q, so the run's error is one evaluation's rounding at any step count
(a carried q's ~1e-16 a step, amplified ~1e4 by the saddle, cost the intermediate-axis box 1e-10
at dt 1e-2); a torque kick or contact impulse changes L and so starts a new anchor.
"""

from __future__ import annotations

from rblog.engine import _core

# the registry (names, codes, options; rblog/engine/registry.py, importable without the core)
from rblog.engine.registry import (  # noqa: F401  (re-exported)
    METHOD_CODES, METHOD_EXACT, METHOD_EXACT4, METHOD_NAMES, METHOD_RK4, METHOD_SEED,
    METHOD_SEED_QUAT, METHOD_SPLITTING, ORTHO_ALLOWED, ORTHO_CODES, ORTHO_GRAM_SCHMIDT,
    ORTHO_NONE, ORTHO_NORMALIZE, ORTHO_POLAR, REGISTRY, YOSHIDA_W0, YOSHIDA_W1, Integrator,
)

# the C++ kernels compute the Yoshida weights the same way (integrators.hpp): the same bits
assert (_core.YOSHIDA_W1, _core.YOSHIDA_W0) == (YOSHIDA_W1, YOSHIDA_W0)

#: drift_rotation(method, ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h,
#: tx=0.0, ty=0.0, tz=0.0): advance body i's orientation over h with L (world) held fixed, by the
#: integrator ``method`` (METHOD_* / ORTHO_* codes; quat_wxyz (N, 4) and rotation (N, 3, 3) updated
#: in place, angular_momentum (N, 3) world frame and inv_inertia (N, 3) read). The torque is used
#: only by rk4, whose stages see L(t) = L + t * torque; the exact integrators take the one-step
#: exact map here.
drift_rotation = _core.drift_rotation
#: drift_exact_anchored(quat_wxyz, rotation, angular_momentum, inv_inertia, i, h, anchor_quat_wxyz,
#: anchor_L_world, anchor_steps, anchor_dt_s, fc, r, fc_ok): the exact torque-free rotation over h
#: evaluated from body i's flow anchor (the arrays of a rblog.engine.state.FlowAnchors) at the
#: elapsed time (anchor_steps + 1) h; a new anchor when L or h changed. Row r of fc ((rows,
#: exact.N_FLOW)) caches the anchor's flow constants, fc_ok[r] (bool) says they are current.
drift_exact_anchored = _core.drift_exact_anchored
#: sync_quat(method, quat_wxyz, rotation, i): q[i] made to describe R[i] for seed (its polar
#: factor); no-op for the others
sync_quat = _core.sync_quat
#: turn_within_bound(dt, i, inv_inertia, rotation, angular_momentum) -> bool: False when body i
#: turns more than MAX_ROTATION_PER_STEP_RAD in a step of dt (the run has diverged)
turn_within_bound = _core.turn_within_bound

