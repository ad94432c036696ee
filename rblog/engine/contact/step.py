"""The compiled world step with contacts: many steps per call, no Python between steps.

One step of ``dt`` (``h``) reads as a flat list of stages (Box2D v3's ``b2World_Step`` and
``b2SolverStage``; Brax's ``pipeline.step``)::

    1  kick             P += h (m g + F), L += h tau              (awake bodies; skipped w/o forces)
    2  broadphase       swept AABBs, sort-and-sweep, ground pairs  (broadphase.py)
    3  wake             sleeping islands an awake body may touch   (island.py)
    4  collide          narrowphase table -> manifolds, warm-start matching, sleeping carried
    5  prepare          effective masses, pre-solve gap velocities (contact_solver.cpp)
    6  warm start       apply last step's impulses
    7  solve            sequential impulses, Coulomb friction, speculative targets; then one
                        sweep of the friction rows toward their anchors (solver.anchor_friction, when
                        ContactParams.static_friction_anchors is on)
    8  relax            split-impulse position correction on pseudo velocities (relax.cpp; the shift's
                        orbital angular momentum h v' x P is handed back to the spin)
    9  integrate        a body the solve and relax pushed: x += h (v + v'), momenta P, L rebuilt
                        from the solver's velocity changes; every other body flies exactly under
                        its constant force, x += h v - h^2 a / 2 (v after the kick). Rotation by
                        integrators.drift_rotation with the run's integrator (the body's L and its
                        current R, so gyroscopic motion is the integrator's own)
    10 restitution      bounce impact points (energy-consistent rule, restitution.cpp), P += J,
                        L += r x J
    11 store impulses   friction as world vectors for the next step
    12 project          narrowphase again at the end-of-step poses; points deeper than
                        projection_depth are pushed out by nonlinear Gauss-Seidel on positions
                        and orientations (project.cpp); the shift's orbital angular momentum
                        dx x P is handed back to the spin, as in 8
    13 sleep            rest timers, islands, put resting islands to sleep (island.py)

Translation (stage 9; mark_pushed sorts the bodies after the solve). A body that no contact
pushes in a step (no manifold, or only manifolds whose accumulated impulses all ended at zero: a
speculative contact that was not reached, a pair moving apart) moves exactly under its constant
acceleration a = g + F/m: with v the velocity after the kick, x += h v - h^2 a / 2 =
h v_start + h^2 a / 2, so free flight lies on the parabola to round-off in every scene, as in
the free-body kernel. A body that contacts push moves with its solved velocity, x += h (v + v')
(v' the relax stage's pseudo velocity), since the velocity solve predicts every gap at the end
of the step as s + h w (w the solved gap rate):

* in an island of pushing contacts that touches static geometry (the ground, a static box, a
  sleeping body), by symplectic Euler, exactly that: a body resting on a contact must move by h
  times its velocity so that v = 0 means still (the exact flight's term would lift it by
  |g| h^2 / 2 each step, and the solver would answer with a downward velocity |g| h / 2 at rest);
* in an island away from static geometry (bodies colliding in the air), by that plus the exact
  flight's - h^2 a / 2, the same term a free body gets: under uniform gravity it moves the whole
  island alike, so the gaps the solver predicted inside it hold, and every body of a group that
  only pushes itself flies by one scheme. Mixing symplectic and exact bodies in such a group
  would change its angular momentum about its centre of mass by O(h^2 |g| |P|) a step (5.6e-6
  relative on samples/mixed.toml; both schemes alone keep it exactly).

Exact motion on one static surface (ContactParams.exact_contact_motion, off by default; the PGS
solve only). Symplectic Euler's x += h v_new is first order under a constant contact force:
a box sliding to a stop falls short of v0^2 / (2 mu g) by about h v0 / 2, a ball rolling down
a slope lags s = a t^2 / 2 by a relative h / t. The trapezoid x += h (v_start + v_new) / 2 is
exact for constant acceleration, and it is applied where the force is constant over the step
and the gaps the solve predicted stay as predicted: a body whose one pushing manifold is
against static geometry, with no point struck this step (mark_exact; an impact's impulse is
not spread over the step, and bodies pushing each other keep the one-scheme rule above). There
it is applied to the tangential displacement only (the normal one stays h w_n, the solve's
s + h w_n) and to the part of the turn that moves no contact point along the normal; a stop or
reversal of the tangential velocity inside the step gets the kinetic-friction closed form
(exact_correction). The log's velocities stay the solver's: the step's mean velocity is their
average, which the consistency analyzer's interval test accepts (it lies on the segment
between the sampled velocities).

The restitution stage measures and sets bounce speeds with the exact flight's energy
(restitution.cpp), so a bounce between exact flights keeps apexes at e^(2n) h0. Torques are
applied as kicks.

Samples follow free.advance_free: after every ``stride``-th step and after the last step when
``sample_last``; a non-finite state stops the call and reports the first bad local step and body.

The step is C++ (csrc/engine/world_step.cpp, whose header comment carries this text; the stages
of the list above are its functions in namespace rb::step, the solver's in contact_solver.cpp,
relax.cpp, restitution.cpp, project.cpp). This module keeps the records' definitions, the stats
indices and the stages as Python callables (each a thin call into ``_core``, for tests);
:func:`world_advance` runs the whole call in C++ with the GIL released.
"""

from __future__ import annotations

from collections import namedtuple

from rblog.contract.trajectory import CONTACT_IMPACT, CONTACT_RESTING
from rblog.engine import _core
from rblog.engine import constants as _constants
from rblog.engine.contact import narrowphase as _narrowphase  # noqa: F401  (sets the C++ constants)

#: per-body model arrays the kernel reads (N rows each; ``iso`` marks isotropic inertia), after
#: the bodies' geoms (G rows each; csrc/engine/collision.hpp Geoms): ``geom`` (G,) engine GEOM_*
#: code, ``size`` (G, 3), ``geom_body`` (G,) owner body, ``geom_offset`` (G,) 1 when the geom sits
#: at ``geom_pos`` (G, 3, body frame, m) turned by ``geom_rot`` (G, 3, 3, geom -> body), 0 when its
#: frame is the body's; ``geom_radius`` (G,) its farthest point from the body's centre of mass
#: (m). One-shape bodies: G = N, geom i = body i, offset 0.
Bodies = namedtuple("Bodies", "geom size geom_body geom_offset geom_pos geom_rot geom_radius "
                              "radius inv_mass inertia inv_inertia iso force torque "
                              "accel restitution friction group")
#: static geometry: static boxes (their AABBs precomputed) and the ground plane
Statics = namedtuple("Statics", "n_static pos rot ext e mu lo hi ground gn goff g_e g_mu")
#: stage switches, then the solver settings spelled as rblog.engine.constants.ContactParams's
#: fields (resolved for the run: ``max_velocity_iterations`` at least ``velocity_iterations``,
#: ``restitution_threshold`` the step's value (ContactParams.restitution_threshold_at),
#: ``substeps`` the step's (ContactParams.substeps_at), ``contact_hertz`` inf for None,
#: ``soft_step``: ContactParams.solver == "soft_step"), then the module-level solver tolerances
#: of rblog.engine.constants the C++ stages read, spelled as the constants in lower case
#: (:func:`solver_constants`), so that C++ holds no second copy of them
Settings = namedtuple("Settings", "do_kick do_sleep iso_shortcut velocity_iterations "
                                  "max_velocity_iterations velocity_tolerance over_relaxation "
                                  "position_iterations allowed_penetration "
                                  "position_correction_rate max_correction_speed "
                                  "speculative_distance restitution_threshold "
                                  "friction_anchor_distance sleep_speed sleep_time warm_starting "
                                  "projection_iterations projection_depth static_friction_anchors "
                                  "exact_contact_motion "
                                  "friction_newton_iters friction_newton_tol block_reg "
                                  "friction_anchor_rate friction_anchor_slide_frac "
                                  "projection_rings soft_step substeps contact_hertz "
                                  "contact_damping_ratio")


def solver_constants() -> dict:
    """The Settings fields that come from rblog.engine.constants (read when called, so a test
    that patches a constant sees it in the next world it builds)."""
    c = _constants
    return dict(friction_newton_iters=int(c.FRICTION_NEWTON_ITERS),
                friction_newton_tol=float(c.FRICTION_NEWTON_TOL), block_reg=float(c.BLOCK_REG),
                friction_anchor_rate=float(c.FRICTION_ANCHOR_RATE),
                friction_anchor_slide_frac=float(c.FRICTION_ANCHOR_SLIDE_FRAC),
                projection_rings=int(c.PROJECTION_RINGS))


#: the changing state of the bodies, world frame (rblog.engine.state.State's arrays): position
#: (N, 3) m, linear_momentum (N, 3), quat_wxyz (N, 4), rotation (N, 3, 3), angular_momentum (N, 3).
#: The sample buffers are the same record with a leading sample axis (S, N, ...).
BodyState = namedtuple("BodyState", "position linear_momentum quat_wxyz rotation angular_momentum")
#: sleep state kept between calls: awake (N,) 0/1, timer (N,) s at rest, island_of (N,) island id
#: of a sleeping body (-1 awake), island_counter (1,) next island id
SleepState = namedtuple("SleepState", "awake timer island_of island_counter")
#: the contact cache kept between calls, a C++ object (csrc/engine/records.hpp): the previous
#: step's manifolds sorted by key (mi0, mf0, pf0, pid0, n_man0, keys0, idx0), spare buffers for
#: this step's (mi1, mf1, pf1, pid1), and the broadphase's pair buffer, each read as a numpy view
#: of the live buffer (a call may grow them: read them again after it); ``ContactCache(cap_m,
#: cap_p)`` has room for cap_m manifolds and cap_p points.
ContactCache = _core.ContactCache
#: per-call work arrays of the stages (rows N..N+M-1 of lo/hi: static boxes; row N of the solver
#: arrays: the static dummy with zero inverse mass), a C++ object whose fields read as numpy
#: views. See make_scratch.
Scratch = _core.Scratch

# indices into the stats array the kernel accumulates
(ST_STEPS, ST_PAIRS, ST_MANIFOLDS, ST_POINTS, ST_AWAKE, ST_IMPACTS, ST_WOKEN, ST_SLEPT,
 ST_SWEEPS, ST_PROJECTED) = range(10)
N_STATS = 10
# the C++ step mirrors these (world_step.hpp); they must agree
if (_core.N_STATS, _core.CONTACT_IMPACT, _core.CONTACT_RESTING) != (
        N_STATS, CONTACT_IMPACT, CONTACT_RESTING):
    raise ImportError("rblog.engine._core is out of step with contact/step.py (N_STATS, "
                      "CONTACT_*): rebuild it (pip install -e .)")


def make_scratch(n, st, n_geoms=None):
    """The stages' work arrays for N bodies with ``n_geoms`` geoms (None: one a body) and the
    scene's static boxes."""
    return _core.make_scratch(int(n), st, -1 if n_geoms is None else int(n_geoms))


# ---- the stages, in step order (world_step.cpp, namespace rb::step) ----------------------------
# Each is a function of the model records (bd, st, cfg), the state record (x) and the work
# arrays (sc); callable on its own.

def kick(bd, awake, x, h):
    """1 kick: P += h (m g + F), L += h tau for awake bodies (world frame)."""
    _core.stage_kick(bd, awake, x, float(h))


def broadphase(bd, st, margin, awake, x, h, sc, pairs):
    """2 broadphase: AABBs (of awake bodies swept over the step, padded by ``margin``),
    sort-and-sweep, and (body, ground) pairs. Returns (pairs, n_pairs) (pairs: a new array,
    grown as needed)."""
    return _core.stage_broadphase(bd, st, float(margin), awake, x, float(h), sc, pairs)


def collide(bd, st, cfg, awake, x, sc, pairs, n_pairs, c):
    """4 collide: the narrowphase table over the candidate pairs into this step's buffers (c.mi1,
    ...), matching last step's manifolds (c.mi0, ...) for warm starting. Returns (n_man, n_pts);
    the cache's buffers may have grown."""
    return _core.stage_collide(bd, st, cfg, awake, x, sc, pairs, int(n_pairs), c)


def prepare(bd, cfg, x, sc, mi, mf, pf, n_man, h):
    """5 prepare: load the bodies in contact into the solver arrays; effective masses and
    pre-solve gap velocities of every point."""
    _core.stage_prepare(bd, cfg, x, sc, mi, mf, pf, int(n_man), float(h))


def integrate_positions(method, ortho, bd, cfg, awake, x, sc, h, an):
    """9 integrate: move every awake body over the step, as ``sc.pushed`` says (set by the
    compiled step: 0, no contact pushed it (no manifold, or manifolds whose impulses all ended
    at zero); 1, pushed, in an island of this step that touches no static geometry; 2, pushed, in
    an island that some static contact pushes).
    A body that a contact pushed (solve or relax) moves with the solver's velocity,
    x += h (v + v'), its momenta rebuilt from the solver's velocity changes, and when its island
    touches no static geometry, by - h^2 a / 2 more (the exact flight's term); every other body
    flies exactly under its constant acceleration a, x += h v - h^2 a / 2 with v after the kick
    (a body whose manifolds all ended without impulse gets its start-of-solve momenta back
    bitwise: warm starting applies and withdraws impulses, which leaves round-off). Rotation by
    the run's integrator (integrators.drift_rotation) with the body's L, plus the pseudo spin of
    the relax stage. The exact integrators rotate from the body's flow anchor (``an``, a
    rblog.engine.state.FlowAnchors; a new one whenever the L it drifts with changed)."""
    _core.stage_integrate_positions(int(method), int(ortho), bd, cfg, awake, x, sc, float(h), an)


def first_diverged(awake, x, inv_inertia, h):
    """The first awake body whose state is not finite or that turns more than
    MAX_ROTATION_PER_STEP_RAD in a step of h (integrators.turn_within_bound), or -1: the run has
    diverged there (a torque of 1e40 N m on a resting box, say), though its state may be finite."""
    return _core.stage_first_diverged(awake, x, inv_inertia, float(h))


# ---- the step ---------------------------------------------------------------------------------

def world_advance(bd, st, cfg, method, ortho, dt, n_steps, stride, sample_last, x, out, sl, c,
                  stats, prof, an, impulses=None):
    """Advance ``n_steps`` steps of ``dt`` with contacts; write samples and contact rows (C++,
    the GIL released for the whole call).

    Args:
        bd, st, cfg: the model records (Bodies, Statics, Settings).
        method, ortho: integrators.METHOD_* / ORTHO_* codes.
        n_steps, stride, sample_last: as free.advance_free (a sample after every stride-th step,
            and after the last one when sample_last).
        x: BodyState, updated in place.  out: BodyState of (S, N, ...) sample buffers.
        sl: SleepState, updated in place.  c: ContactCache, updated in place.
        stats: (N_STATS,) int64 counters, added to.
        prof: (profile.N_PROF,) int64 cycle counts per stage, added to; empty: not profiled.
        an: rblog.engine.state.FlowAnchors, updated in place (the exact integrators' anchors).
        impulses: the per-interval contact impulses (an object with ``acc`` (N, 6), ``start``
            (N, 6), ``kicked`` (N,) int64, kept across calls, and ``out`` (S, N, 6): linear and
            angular (about the COM) world contact impulse summed over each sample's interval;
            csrc/engine/impulses.cpp), or None.

    Returns (n_samples, bad_step, bad_body, log_i, log_f): bad_step is the first local step
    (1-based) at which some body's state became non-finite (-1 if none); log_i (K, LOG_I_COLS)
    int64 and log_f (K, LOG_F_COLS) float64 are the call's contact rows (manifold.log_rows).
    """
    return _core.world_advance(bd, st, cfg, int(method), int(ortho), float(dt), int(n_steps),
                               int(stride), bool(sample_last), x, out, sl, c, stats, prof, an,
                               () if impulses is None else impulses)
