"""Every tolerance and default of the engine, with its unit and what it trades off.

The engine's numerical modules import from here; nothing else in the engine hard-codes a
threshold. (The analyzers keep their own defaults in :mod:`rblog.analyze.tolerances`: an audit
must not inherit the choices of the engine it audits.)

Two kinds live here: fixed constants (integrators, run loop, logging, scene validation) and
:class:`ContactParams`, the contact pipeline's settings a scene may override.

Contact settings
----------------
Every tolerance and setting of the contact pipeline, with its unit and what it trades off.

A scene may override any of them in an optional ``[contact]`` TOML table whose keys are the field
names of :class:`ContactParams` (for example ``velocity_iterations = 12``). Lengths are in metres,
speeds in m/s, times in seconds. The defaults are tuned for bodies of 1 cm to 1 m under Earth
gravity at dt = 1e-3 to 1e-2 s; Box2D v3's ``constants.h`` is the model (its ``B2_LINEAR_SLOP``
is 5 mm for games; rblog audits penetration, so its slop is 50x smaller).
"""

from __future__ import annotations

import math

from dataclasses import asdict, dataclass, fields

# --- integrators -----------------------------------------------------------------------------
#: Newton iterations of the polar decomposition R <- (R + R^-T)/2 stop when the largest entry of
#: the last update is below this (dimensionless). Newton converges quadratically, so the iterate
#: is then within ~POLAR_TOL^2 = 1e-16 (round-off) of orthonormal; a smaller value costs one more
#: iteration (~15 ns per body-step) and buys nothing.
POLAR_TOL = 1e-8
#: Cap on polar Newton iterations. Converges quadratically: from ||R^T R - I|| = 1e-4 it takes 2.
POLAR_MAX_ITER = 12

# --- exact free flow (engine/exact.py) ---------------------------------------------------------
#: Descending Landen transformations of sn, cn, dn stop once the parameter m is below this
#: (dimensionless); the base then uses the expansion to first order in m, whose error O(m^2) is
#: then below 1e-18 over the reduced argument (< 2K).
LANDEN_BASE_PARAMETER = 1e-9
#: Cap on Landen levels: from m = 1 - 1e-300 (the closest double below the separatrix) it takes 11.
LANDEN_MAX_LEVELS = 12
#: Carlson duplication stops when the arguments agree to this (relative); then the series (seventh
#: order for R_F, fifth for R_J; DLMF 19.36.1-2). Measured against scipy's elliprj over 20,000
#: random arguments of the exact flow's kind: 1.8e-15 relative at 0.008 (5.0 duplications on
#: average), 1.2e-15 at 0.004 (5.5), 1.1e-13 at 0.015 (4.5): each duplication costs ~12 ns a pair.
CARLSON_SERIES_TOL = 0.008

# --- run loop ---------------------------------------------------------------------------------
#: A run is split into blocks that each run in one compiled call; a block holds at most this many
#: logged samples (fewer blocks: less per-block work in the recorders) ...
BLOCK_MAX_SAMPLES = 4096
#: ... and at most this many body-samples, which bounds a block's memory whatever the body count:
#: ~420 bytes per body-sample (state and derived channels, float64) = ~14 MB per block; the run
#: holds at most ~4 blocks at once (stepping, queued, being written).
BLOCK_MAX_BODY_SAMPLES = 32_768
#: ... and at most this many body-steps, so that progress and Ctrl-C are seen every ~50 ms.
BLOCK_MAX_BODY_STEPS = 2_000_000
#: A progress bar is shown when the run is expected to last longer than this (seconds, wall).
PROGRESS_MIN_WALL_S = 1.0

# --- logging ----------------------------------------------------------------------------------
#: Default logging rate when neither --log-every nor --log-rate is given (samples per simulated
#: second). 100 Hz plays back smoothly in the viewers and resolves bounces at dt = 1e-3.
DEFAULT_LOG_RATE_HZ = 100.0

# --- scene validation -------------------------------------------------------------------------
#: Tolerance on |q| for a quaternion given in a scene: it is normalized, but one far from unit
#: length is probably a typo (a zero quaternion is rejected).
QUAT_MIN_NORM = 1e-9


# --- reliability: interrupts, crash-safe logs, input sanity --------------------------------------
#: One compiled call runs at most about this much wall time (s): the run loop sizes each call
#: from the wall time per step it measured on the previous one, and checks for Ctrl-C / SIGTERM
#: between calls, so a signal is answered within ~this (plus closing the logs). Each call's
#: samples go to the recorders at once, so a killed run loses at most ~this + the writers'
#: FLUSH_EVERY_S.
CALL_WALL_BUDGET_S = 0.03
#: A call is at most this many times longer (in steps) than the previous one, so that one
#: fast measurement (a call of a few steps) cannot size a call far past the budget.
CALL_GROWTH_MAX = 4.0
#: The most steps a run may take (dt too small for its duration, e.g. dt = 1e-300).
MAX_RUN_STEPS = 10**12
#: A scene quaternion whose norm is off 1 by more than this is normalised with a warning
#: (likely a typo); within it, silently (round-off from hand-written decimals, 1e-6 covers
#: 7-digit values).
QUAT_NORM_WARN_TOL = 1e-6
#: A free body that turns more than this in one step (rad, |omega| dt) has diverged: the run stops
#: as for a non-finite state (exit 3, logs kept up to the step before). Above pi per step the
#: samples alias (a turn by theta and by theta - 2 pi look alike), but the exact and splitting
#: flows stay accurate there, so pi is not the bound; at 1e6 rad the angle's round-off alone
#: (theta 2^-53 ~ 1e-10 rad per step) starts to add up over a run, and no physical body turns
#: 160,000 times in one step. A torque of 1e40 N m on a 1 kg, 0.1 m sphere at dt = 1e-3 s turns
#: it 2.5e36 rad in the first step; the notes' spinner of tests/conftest.py turns 100 rad.
MAX_ROTATION_PER_STEP_RAD = 1e6
#: The most bodies a scene may hold (each costs ~2 kB in the body table, state and one block).
MAX_BODIES = 10_000_000
#: Approximate bytes of memory per body while loading and running a scene, for the "needs N GB"
#: message: peak resident memory of a free-body run measured 1.9 kB per body at 100,000 bodies
#: and 2.8 kB at 10,000 (benchmarks/bench_memory.py; generators expand straight into arrays).
BYTES_PER_BODY_ESTIMATE = 2_000
#: Approximate bytes of memory per pair of bodies whose bounding spheres overlap at the start of
#: a run (manifolds, solver rows and scratch the first steps hold for it), for the scene's memory
#: check (rblog.engine.scene_checks): peak resident memory of `rblog run --duration 0.01` (both
#: logs) of samples/box_stack.toml's boxes in a column 1 mm apart measured 1.57 GB at 1,000 boxes
#: (499,500 pairs counted) and 0.53 GB at 500 boxes 2 mm apart (124,750): 2.9 kB per pair.
BYTES_PER_PAIR_ESTIMATE = 3_000
#: The deepest nesting of arrays and tables a scene may have (a scene needs 4: the document, a
#: [[generator]] array, its table, a vector); Python's TOML parser recurses and fails near 1,000.
MAX_NESTING = 32
#: Bodies that start interpenetrating deeper than this (m) are reported with a warning (the
#: solver pushes them apart violently in the first steps). Bodies stacked exactly touching
#: measure ~1e-16 m.
OVERLAP_WARN_DEPTH_M = 1e-6
#: At most this many bounding-sphere candidates are measured for the overlap warning (each is a
#: narrowphase call on a two-body model); the rest are counted, not measured.
OVERLAP_CHECK_MAX_PAIRS = 256


# --- narrowphase (box-box) -------------------------------------------------------------------
# Box-box axis preference (Gregorius): an edge axis replaces the best face axis only when its
# separation exceeds the face's by (1 - EDGE_REL_TOL) |face separation| + AXIS_ABS_TOL; face B
# replaces face A only when it exceeds it by (1 - FACE_REL_TOL) |sep A| + AXIS_ABS_TOL. (Gregorius
# writes rel * sep + abs, which is right for overlaps only; |sep| keeps it right for gaps.) Prevents flip-flopping between nearly
# equal axes, which would change the manifold (and lose warm starting) every step.
#: m. A face manifold's clipped polygon can have up to eight vertices; the reduction to four keeps
#: the points touching first: those within this of the deepest (a face tilted by up to 1 mrad
#: over a 0.1 m box, a resting contact's spread of depths: a few allowed_penetration). Only when
#: fewer than four touch are the speculative ones (up to speculative_distance above) used, for
#: area. Reducing by area over all of them drops touching points for far speculative ones: a box
#: lying on another with its lowest edge level and 50 um deep kept one end of that edge (a corner
#: 2.7 mm above and two others took the other slots), and turned about that single point.
MANIFOLD_TOUCH_BAND_M = 1e-4
EDGE_REL_TOL = 0.90
FACE_REL_TOL = 0.98
AXIS_ABS_TOL = 1e-5  # m
#: edge axes a_i x b_j shorter than this (sin of the angle between the edges) are skipped:
#: parallel edges are covered by the face axes.
EDGE_PARALLEL_TOL = 1e-6

# --- narrowphase (cylinder pairs: GJK + EPA, csrc/common/convex.hpp) -------------------------
#: m. GJK stops when the distance of two convex cores is known to within this (the gap between
#: its upper bound |v| and lower bound v.w/|v|); EPA when the depth is (the gain of the support
#: along the nearest face's normal). A cylinder's curved side makes both the error (a polytope
#: pair ends on its exact feature). csrc/engine/cylinder.cpp then takes the separating axis of
#: largest gap among GJK/EPA's normal and the pair's face and axis-cross directions, exact along
#: each, so a face contact's gap and normal are exact and a curved one is GJK/EPA's to ~this.
#: 1e-10 m: five orders below the contact's resolution (allowed_penetration 5e-5 m).
CONVEX_GJK_TOL_M = 1e-10
CONVEX_EPA_TOL_M = 1e-10
#: iteration cap of GJK and of EPA each; a pair that hits it keeps the best bound found (the
#: separating-axis pass above then makes its gap a lower bound, never deeper than the truth).
CONVEX_MAX_ITER = 200


# --- contact solver internals ----------------------------------------------------------------
#: Newton iterations of the sliding-friction impulse (converges from below in 3-5)
FRICTION_NEWTON_ITERS = 8
#: relative tolerance on |lambda| = mu lambda_n that ends them
FRICTION_NEWTON_TOL = 1e-12
#: relative diagonal regularisation of a manifold's normal block: four coplanar points have a
#: rank-3 block (one self-equilibrated load pattern costs nothing); the regularised solve picks
#: the smallest impulses, which keeps symmetric loads symmetric.
BLOCK_REG = 1e-9
# Static-friction anchor (csrc/engine/contact_solver.cpp, "Friction anchor"; ContactParams.static_friction_anchors).
# A pair whose friction stays strictly inside the Coulomb cone sticks, and static friction then
# forbids any net slip; a velocity solve stopped after a finite number of sweeps leaves a
# residual slip e (m/s) that, steady, adds up step after step (a twisting support at 7.5e-4 m/s
# creeps 0.36 mm in 0.48 s). The anchor is the pose of body a in body b's frame when the pair
# started sticking; every contact point's drift D is where a's material point there is now minus
# where that pose puts it (collide.py), and the friction rows target the slip rate
# -FRICTION_ANCHOR_RATE D / h instead of 0, so the drift obeys D' = (1 - rate) D + h e: it settles
# at h e / rate (sub-micrometre) and the slip velocity at 0, whatever the solve leaves.
#: fraction of the anchor's drift the friction rows take back per step (dimensionless, (0, 1]).
#: Higher is tighter; above 1 the drift would overshoot each step. Measured on samples/pile.toml
#: with every step logged: 0.8 leaves 0.118 mm of creep but makes resting contacts oscillate at
#: up to 2.7 mm/s (jitter; 1.07 mm/s without anchors), 0.5 leaves 0.050 mm and 1.85 mm/s.
FRICTION_ANCHOR_RATE = 0.5
#: m. A pair one of whose points has drifted this far (tangentially) is re-anchored where it is:
#: such a slip is one the solve let through while the pair was struck, and pulling it back would
#: act as a spring (at most FRICTION_ANCHOR_RATE x this / h = 2.5 cm/s of bias at dt = 1e-3 s).
#: Equal to the default allowed_penetration, the contact's resolution; steady drifts are ~1e-6 m.
FRICTION_ANCHOR_MAX_DRIFT_M = 5e-5
#: a point whose friction impulse reaches (1 - this) mu lambda_n slides (the sliding impulse
#: lands on the cone to round-off, see solver._friction_impulse); a manifold none of whose loaded
#: points sticks drops its anchor.
FRICTION_ANCHOR_SLIDE_FRAC = 1e-6
#: relative tolerance under which principal moments count as equal (isotropic inertia)
ISOTROPIC_RTOL = 1e-12
#: rings of contacts gathered around a deep point: the contacts of its bodies (1) and of their
#: neighbours (2), which hold the bodies that the projection pushes on
PROJECTION_RINGS = 2


# --- restitution threshold ------------------------------------------------------------------
# Which impacts bounce. At the start of every step the kick adds the velocity a h (a = g + F/m,
# m/s^2; h = dt, s) to every body, and for a body at rest on a contact the velocity solve takes
# exactly that back: the contact's approach speed before the solve is |a_n| h, and after the
# solve what the solver leaves unconverged, at most ``velocity_tolerance`` (m/s). Resting contact
# must never count as an impact (each "bounce" off a kick would make the body chatter), so the
# threshold must exceed |a| h + velocity_tolerance; the restitution stage measures the approach
# speed from the step's flight energy, u^2 = w0^2 - 2 a_n s0 (csrc/engine/restitution.cpp), which for a
# resting point (s0 <= 0, w0 the leftover) is at most the leftover, and for a point hovering a
# distance d above its contact is the real free-fall speed sqrt(2 |a| d). The margin of a second
# kick: an impact at u = 2 |a| h with e <= 1 flies for 2 e u / |a| <= 4 h, a bounce of a few steps
# that the speculative contact (which holds a body within a step of its contact) cannot resolve
# anyway, so it is taken as resting; every slower impact is one. Hence
#     restitution_threshold = RESTITUTION_THRESHOLD_KICKS |a|max h + velocity_tolerance   (m/s)
# with |a|max the largest external acceleration over the bodies: 0.0197 m/s under Earth gravity
# at dt = 1e-3 s, 0.196 m/s at dt = 1e-2 s (a ball dropped from 2 cm lands at 0.63 m/s and
# bounces at both). Box2D's fixed 1 m/s swallows every bounce off a drop below 5 cm.

#: Kicks of one step (|a|max h) in the derived restitution threshold (dimensionless; see above).
#: 1 would sit exactly on a resting body's pre-solve approach speed; higher values end bounce
#: sequences earlier (the last bounce flies at most 2 e u / |a| <= 2 KICKS h).
RESTITUTION_THRESHOLD_KICKS = 2.0


def restitution_threshold(dt: float, accel_max: float, velocity_tolerance: float) -> float:
    """The derived restitution threshold (m/s): RESTITUTION_THRESHOLD_KICKS |a|max dt plus the
    velocity solve's tolerance (see the block above). dt: s; accel_max: m/s^2, the largest
    |g + F/m| over the bodies; velocity_tolerance: m/s (ContactParams.velocity_tolerance)."""
    return RESTITUTION_THRESHOLD_KICKS * float(accel_max) * float(dt) + float(velocity_tolerance)


# --- contact pipeline ----------------------------------------------------------------------
#: ContactParams.solver's values: the projected Gauss-Seidel solve, Box2D v3's soft step
CONTACT_SOLVERS = ("pgs", "soft_step")


@dataclass
class ContactParams:
    """Settings of collision detection and the contact solver.

    Attributes:
        velocity_iterations: minimum Gauss-Seidel sweeps over all contact points per step in the
            velocity solve (sequential impulses with accumulated-impulse clamping).
        max_velocity_iterations: cap on the sweeps. After the minimum, sweeping goes on until
            the largest velocity change of a sweep is below ``velocity_tolerance``. A load has to
            travel through a stack of n bodies, which takes ~n^2 plain Gauss-Seidel sweeps the
            first time and ~n over-relaxed ones (see ``over_relaxation``); warm starting then
            keeps it converged with a few. A pile with ~3,000 contact points being struck all
            the time needs ~90 sweeps to reach the tolerance, so the cap sets its cost: 30 sweeps
            run the 500-box pile 3.5x faster than 200, with the same penetration (the project
            stage bounds it) and the 10-box stack still within 0.1 mm. Lower caps are faster in
            piles but let tall stacks sink until they converge. The cap also sets how far resting
            boxes creep while a pile settles: up to 1.3 mm over ~2 s at 30 sweeps, under 0.8 mm
            converged (300 sweeps, tolerance 1e-6 m/s, 5-6x the run time; measured 2026-11, in
            `git log -p benchmarks/RESULTS.md`).
        velocity_tolerance: m/s. Convergence test of the velocity solve (see above). Smaller
            values give exacter resting contact (no sinking, no creep) for more sweeps.
        over_relaxation: successive over-relaxation factor of the normal impulses, in (0, 2)
            (ODE's quickstep uses 1.3; projected SOR converges for any value in the range on
            the normal rows alone, not with the friction rows coupled to them). Applied to the
            manifolds whose bodies touch something else; a manifold on its own is solved
            exactly by one update and is never relaxed. 1.0 is plain Gauss-Seidel. Safeguard: a
            manifold whose over-relaxed update clamps a loaded point to zero is solved by plain
            Gauss-Seidel for the rest of the step (a sliding corner at 1.6 otherwise cycled
            between loaded and unloaded every sweep; csrc/engine/contact_lanes.inl).
            Higher values move loads through stacks in fewer sweeps (10-box stack capped at 30
            sweeps: its top sinks 0.06 mm at 1.6, 0.22 mm at 1.5, 0.38 mm at 1.3 and 5 mm,
            sliding sideways, at 1.0).
        position_iterations: sweeps of the position correction (split impulses on pseudo
            velocities, which move bodies but are thrown away, so no momentum or energy is ever
            injected). 0 turns position correction off.
        allowed_penetration: m. Penetration left uncorrected (Box2D's linear slop). Larger values
            avoid pushing bodies apart and back again; smaller values keep bodies closer to the
            surface. Resting bodies sit at most this deep.
        position_correction_rate: fraction of the penetration beyond ``allowed_penetration``
            removed per step by the split-impulse pass (Baumgarte factor, in (0, 1]). Higher values
            fix penetration faster but overshoot where many contacts interact.
        max_correction_speed: m/s. Cap on the pseudo velocity that removes penetration, so a deep
            overlap is resolved over several steps instead of popping bodies apart (the project
            stage has no such cap: see ``projection_depth``).
        speculative_distance: m. Contact points are generated while the surfaces are closer
            than this plus the distance the pair can close in one step (relative speed times dt),
            so fast bodies cannot tunnel through thin geometry. Larger values cost more contact
            points; smaller values can miss contacts of rotating boxes.
        restitution_threshold: m/s, or None (the default) for the value derived from the
            step: ``RESTITUTION_THRESHOLD_KICKS |a|max dt + velocity_tolerance`` (see
            :func:`restitution_threshold`; 0.0197 m/s under Earth gravity at dt = 1e-3 s, 0.196
            m/s at 1e-2 s). Impacts slower than this (normal approach speed) are treated as
            inelastic. A value given in the scene is used as is: lower values let resting
            bodies chatter; higher values swallow gentle bounces (Box2D v3 uses a fixed 1 m/s,
            which keeps a ball dropped from 5 cm from bouncing at all).
        friction_anchor_distance: m. A new contact point takes over the warm-start impulses of a
            point of the previous step when their feature ids match or, failing that, when they
            lie within this distance. Too small loses warm starting when manifolds shift; too
            large mixes up neighbouring points.
        sleep: let bodies at rest sleep: an island of touching bodies whose speeds all stay
            below ``sleep_speed`` for ``sleep_time`` stops being integrated and solved until an
            awake body touches it. Only islands in contact with something sleep (a body drifting
            slowly through empty space keeps moving).
        sleep_speed: m/s. Speed below which a body counts as resting: the larger of its
            centre-of-mass speed and its angular speed times its bounding radius. Higher values
            freeze slow creeping earlier (Box2D v3 uses 5 cm/s; rblog audits motion, so 5 mm/s).
        sleep_time: s. How long an island must stay below ``sleep_speed`` before it sleeps.
        warm_starting: start each step's solve from the previous step's impulses (matched by
            feature id). Turning it off is only useful to demonstrate why it exists.
        static_friction_anchors: run the anchor pass after the velocity solve (contact_solver.cpp,
            "Friction anchor"): a sticking pair keeps the pose it stuck at, and its points' friction
            rows take back half their drift from it per step. On by default: the
            velocity solve stops at ``velocity_tolerance`` (1e-4 m/s), and a sticking contact's
            leftover slip of that order adds up to the analyzer's 0.1 mm of creep within a second
            or two; the anchor closes that loop over steps whatever the sweep count or order.
            Measured on samples/pile.toml at seeds 1-12 (`rblog check`; benchmarks/RESULTS.md,
            "Contact solver: the loose pile", 2026-11-28): on, 11 of 12 seeds clean on the
            coloured solve; off, 5 of 12 (29 findings, creep up to 0.475 mm, measured with the
            colours in increasing order). Off, the earlier trajectories come back.
            Seed 5's finding (box132 "creeps 0.155 mm on the ground") is no creep: box182
            strikes it twice between samples (steps 794 and 814), it slides 99.96 and 51 um and
            stops before the next sample, and its slow slip is 5.9 um. The same runs logged at
            every step (the same physics: seed 5's shared samples compared bit for bit) read at
            most 16.5 um of creep at seed 5 and 39.2 um at seeds 1-12.
            The 500-box pile of tests/engine/contact/test_contact.py at dt 2e-3 stays within
            0.22-0.26 mm of penetration with it on (seeds 0-2; 0.5 mm allowed).
        exact_contact_motion: move a body whose one pushing contact is static geometry (the
            ground, a static box, a sleeping body) on a face, or rolling on it (a sphere, a
            capsule, a cylinder), struck by no impact in the step, exactly
            under its constant contact force: tangentially by the trapezoid h (v_start + v_end)
            / 2 instead of symplectic Euler's h v_end, its turn likewise about the axes that
            move no contact point along the normal, a stop inside the step by kinetic
            friction's closed form (csrc/engine/world_step.cpp, "Exact motion on one static
            surface"). A pair held by its friction anchor keeps symplectic Euler. Off, a box
            sliding to rest stops about h v0 / 2 short of v0^2 / (2 mu g) (1 mm at 2 m/s, dt
            1e-3) and a ball rolling down a slope is ahead of a t^2 / 2 by h / t relative. The
            PGS solve only (``solver = "soft_step"`` moves bodies by its substeps). A body at
            rest as far as the solve can tell (its speeds within ``velocity_tolerance``) keeps
            symplectic Euler. Off by default: on, `rblog check` flags samples/pile.toml at 2 of
            seeds 1-12 (6: a box creeping 0.100 mm on another; 12: a box jittering 2.39 mm/s on
            the ground), where the default is clean at all 12; at seeds 13-24 on flags 1 (18: a
            jitter of 4.2 mm/s), off 5 (creeps of 0.101-0.194 mm, a jitter of 2.13 mm/s). The
            findings at seeds 6 and 12 are not the rule's: no body within two contact rings of
            the flagged ones is moved by it while they are flagged (it changed the pile's
            trajectory before); seed 18's box455 is, in 42 of the 180 steps (benchmarks/RESULTS.md, "Contact solver: the loose pile"). The
            500-box pile of bench_pile.py costs 1.05x the CPU time with it on.
        projection_iterations: Gauss-Seidel sweeps of the project stage (project.cpp): after the
            positions moved, the narrowphase runs again at the end-of-step poses and every
            point deeper than ``projection_depth`` is pushed out to that depth by moving
            positions and orientations (no velocity changes). It catches features that were not
            in the step's manifolds (a tumbling box's corner swinging over an edge, a pair
            struck within the step). 0 turns the stage off.
        projection_depth: m. Penetration the project stage leaves (its target depth), and the
            depth below which it does nothing. It must exceed the resting depth of the
            split-impulse pass (a few ``allowed_penetration``), so that resting contacts are
            left to the velocity and split-impulse passes and only fast, unforeseen overlaps
            are projected. A deeper overlap is pushed out to this depth in one step, without
            any velocity: a scene that starts overlapping is separated in its first step.
        solver: the velocity solve, one of :data:`CONTACT_SOLVERS`. ``"pgs"`` (the default):
            projected Gauss-Seidel swept to ``velocity_tolerance`` (over-relaxed, block LU per
            manifold), then the friction anchors' pass and the split-impulse relax stage.
            ``"soft_step"``: Box2D v3's soft step (csrc/engine/soft_step.cpp): ``substeps``
            substeps of dt / substeps, each a warm start, one sweep of soft contacts (springs of
            ``contact_hertz``; a manifold's normal rows through its block, as the PGS solve),
            the positions moved, one rigid relax sweep; fixed cost, no convergence test; with
            ``static_friction_anchors`` the soft sweeps' friction rows aim at the anchors' slip
            rate. ``velocity_iterations``, ``max_velocity_iterations``, ``velocity_tolerance``,
            ``over_relaxation``, ``position_iterations`` and ``position_correction_rate`` are
            the PGS solve's and do nothing under the soft step; ``max_correction_speed`` caps
            both solves' push-out speed. Measured against the PGS solve (2026-11-28, the 500-box
            pile from its 1 s state, 4 substeps, the soft sweeps scalar): 1.25x fewer
            instructions a step, samples/pile.toml's checks clean at seeds 1-3; it does not pass
            every closed-form contact test: a 10-box stack at dt = 1e-2 topples below 8
            substeps (its springs' sag, see ``contact_hertz``; ``max_substep`` = 2.5e-4 keeps
            it), the 10-box stack at dt 1e-3 x 4 wanders sideways after ~10 s (1 mm at 12 s,
            growing from round-off), and the tests of exact rolling, of overlaps pushed out
            without velocity and of a zero resting depth fail by construction.
        substeps: the soft step's substeps per step (Box2D v3 uses 4). More substeps make
            stiffer contacts possible (see ``contact_hertz``) and cost one solve and one relax
            sweep each.
        contact_hertz: Hz, or None (the default) for the stiffest the substeps resolve: the
            soft step's contact spring frequency f, used as min(f, substep rate / 4) (Box2D v3's
            cap; twice that against static geometry). A load W per point holds a resting contact
            W / (m (2 pi f)^2) deep (soft_step.cpp, "Resting depth"): Box2D's 30 Hz lets a 1 kg
            cube sink 0.07 mm into the ground and a 10-box stack's contacts about a millimetre,
            so rblog's gates want the cap (1 kHz at dt = 1e-3 with 4 substeps).
        max_substep: s, or None (the default): the longest substep of the soft step. Given, a
            step of dt takes max(substeps, ceil(dt / max_substep)) substeps. A resting contact's
            depth depends on the substep's length only (the spring's cap is a quarter of its
            rate, see ``contact_hertz``): a 10-box stack sags 23 um at 0.25 ms substeps whether
            dt is 1e-3 (4 substeps) or 1e-2 (40), and topples at dt = 1e-2 with 4 (measured
            2026-11-28).
        contact_damping_ratio: the soft contacts' damping ratio (Box2D v3's default 10: heavily
            over-damped, so a push-out does not bounce).
    """

    velocity_iterations: int = 4
    max_velocity_iterations: int = 30
    velocity_tolerance: float = 1e-4
    over_relaxation: float = 1.6
    position_iterations: int = 3
    allowed_penetration: float = 5e-5
    position_correction_rate: float = 0.8
    max_correction_speed: float = 1.0
    speculative_distance: float = 0.01
    restitution_threshold: float | None = None
    friction_anchor_distance: float = 0.005
    sleep: bool = True
    sleep_speed: float = 0.005
    sleep_time: float = 0.5
    warm_starting: bool = True
    static_friction_anchors: bool = True
    exact_contact_motion: bool = False
    projection_iterations: int = 4
    projection_depth: float = 2e-4
    solver: str = "pgs"
    substeps: int = 4
    contact_hertz: float | None = None
    contact_damping_ratio: float = 10.0
    max_substep: float | None = None

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Raise ValueError naming the field when a value is out of its range."""
        checks = {
            "velocity_iterations": self.velocity_iterations >= 1,
            "max_velocity_iterations": self.max_velocity_iterations >= 1,
            "velocity_tolerance": self.velocity_tolerance >= 0.0,
            "over_relaxation": 0.0 < self.over_relaxation < 2.0,
            "position_iterations": self.position_iterations >= 0,
            "allowed_penetration": self.allowed_penetration >= 0.0,
            "position_correction_rate": 0.0 < self.position_correction_rate <= 1.0,
            "max_correction_speed": self.max_correction_speed > 0.0,
            "speculative_distance": self.speculative_distance >= 0.0,
            "restitution_threshold": (self.restitution_threshold is None
                                      or self.restitution_threshold >= 0.0),
            "friction_anchor_distance": self.friction_anchor_distance >= 0.0,
            "sleep_speed": self.sleep_speed >= 0.0,
            "sleep_time": self.sleep_time >= 0.0,
            "projection_iterations": self.projection_iterations >= 0,
            "projection_depth": self.projection_depth > 0.0,
            "solver": self.solver in CONTACT_SOLVERS,
            "substeps": self.substeps >= 1,
            "contact_hertz": self.contact_hertz is None or self.contact_hertz > 0.0,
            "contact_damping_ratio": self.contact_damping_ratio >= 0.0,
            "max_substep": self.max_substep is None or self.max_substep > 0.0,
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f"contact.{name} = {getattr(self, name)!r} is out of range")
        for name in ("velocity_iterations", "max_velocity_iterations", "position_iterations",
                     "projection_iterations", "substeps"):
            if int(getattr(self, name)) != getattr(self, name):
                raise ValueError(f"contact.{name} must be an integer")

    def substeps_at(self, dt: float) -> int:
        """The soft step's substeps in a step of ``dt`` (s): ``substeps``, or more when
        ``max_substep`` asks for shorter ones."""
        n = int(self.substeps)
        if self.max_substep is not None:
            # (less 1e-9: a quotient meant to be whole, 1e-2 / 2.5e-4 = 40.000000000000004,
            # stays whole)
            n = max(n, int(math.ceil(float(dt) / float(self.max_substep) - 1e-9)))
        return n

    def restitution_threshold_at(self, dt: float, accel_max: float) -> float:
        """The restitution threshold (m/s) of a run at step ``dt`` (s) whose largest external
        acceleration |g + F/m| over the bodies is ``accel_max`` (m/s^2): the scene's value
        when it gave one, else :func:`restitution_threshold`."""
        if self.restitution_threshold is not None:
            return float(self.restitution_threshold)
        return restitution_threshold(dt, accel_max, self.velocity_tolerance)

    @classmethod
    def from_dict(cls, table: dict) -> "ContactParams":
        """Build from a ``[contact]`` table; unknown keys raise ValueError listing the known ones."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(table) - known)
        if unknown:
            raise ValueError(f"unknown contact setting(s) {unknown}; known: {sorted(known)}")
        return cls(**table)

    def to_dict(self) -> dict:
        return asdict(self)
