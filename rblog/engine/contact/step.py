"""The compiled world step with contacts: many steps per call, no Python between steps.

One step of ``dt`` (``h``) reads as a flat list of stages (Box2D v3's ``b2World_Step`` and
``b2SolverStage``; Brax's ``pipeline.step``)::

    1  kick             P += h (m g + F), L += h tau              (awake bodies; skipped w/o forces)
    2  broadphase       swept AABBs, sort-and-sweep, ground pairs  (broadphase.py)
    3  wake             sleeping islands an awake body may touch   (island.py)
    4  collide          narrowphase table -> manifolds, warm-start matching, sleeping carried
    5  prepare          effective masses, pre-solve gap velocities (solver.py)
    6  warm start       apply last step's impulses
    7  solve            sequential impulses, Coulomb friction, speculative targets; then one
                        sweep of the friction rows toward their anchors (solver.anchor_friction, when
                        ContactParams.static_friction_anchors is on)
    8  relax            split-impulse position correction on pseudo velocities (relax.py; the shift's
                        orbital angular momentum h v' x P is handed back to the spin)
    9  integrate        a body the solve and relax pushed: x += h (v + v'), momenta P, L rebuilt
                        from the solver's velocity changes; every other body flies exactly under
                        its constant force, x += h v - h^2 a / 2 (v after the kick). Rotation by
                        integrators.drift_rotation with the run's integrator (the body's L and its
                        current R, so gyroscopic motion is the integrator's own)
    10 restitution      bounce impact points (energy-consistent rule, restitution.py), P += J,
                        L += r x J
    11 store impulses   friction as world vectors for the next step
    12 project          narrowphase again at the end-of-step poses; points deeper than
                        projection_depth are pushed out by nonlinear Gauss-Seidel on positions
                        and orientations (project.py); the shift's orbital angular momentum
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

The restitution stage measures and sets bounce speeds with the exact flight's energy
(restitution.py), so a bounce between exact flights keeps apexes at e^(2n) h0. Torques are
kicks, as before.

Samples follow free.advance_free: after every ``stride``-th step and after the last step when
``sample_last``; a non-finite state stops the call and reports the first bad local step and body.

Why this module is long: the step is one compiled function whose stages are inlined wrappers
that must live beside it (numba inlines them into world_advance), and ``--profile`` times each
stage inside it (profile.py), which adds a clock read after every stage.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from rblog.engine.free import write_sample
from rblog.engine.rotation import load_mat, omega_world
from rblog.engine.exact import N_FLOW
from rblog.engine.integrators import (
    METHOD_EXACT, METHOD_EXACT4, drift_exact_anchored, drift_rotation, sync_quat, turn_within_bound,
)
from rblog.contract.trajectory import CONTACT_IMPACT, CONTACT_RESTING
from rblog.engine.contact.broadphase import body_aabbs, ground_pairs, sweep_and_prune
from rblog.engine.contact.collide import collide_pairs, grow_manifolds, grow_points, sort_manifolds
from rblog.engine.contact.island import find_root, update_sleep, wake_pushed, wake_touched
from rblog.engine.contact.manifold import (
    LOG_A, LOG_B, LOG_F, LOG_F_COLS, LOG_I_COLS, LOG_KIND, LOG_LN, LOG_N, LOG_P, LOG_S, LOG_STEP,
    MF_N, MI_A, MI_ACTIVE, MI_B, MI_COUNT, MI_REC_A, MI_REC_B, MI_START, PF_F, PF_IMPACT, PF_L1,
    PF_L2, PF_LN, PF_LP, PF_P, PF_SEND,
)
from rblog.engine.contact.narrowphase import collider_buffers
from rblog.engine.contact.project import PROJ_COLS, apply_projection, project_positions
from rblog.engine.contact.solver import (
    anchor_friction, load_bodies, prepare_contacts, solve_velocities, store_impulses, warm_start,
)
from rblog.engine.contact.relax import relax_positions
from rblog.engine.contact.restitution import restitution
from rblog.engine.profile import (
    P_BROADPHASE, P_COLLIDE, P_INTEGRATE, P_KICK, P_PROJECT, P_RELAX, P_RESTITUTION, P_SAMPLE,
    P_SLEEP, P_SOLVE, P_WAKE, ticks,
)

#: per-body model arrays the kernel reads (N rows each; ``iso`` marks isotropic inertia)
Bodies = namedtuple("Bodies", "geom size radius inv_mass inertia inv_inertia iso force torque "
                              "accel restitution friction group")
#: static geometry: static boxes (their AABBs precomputed) and the ground plane
Statics = namedtuple("Statics", "n_static pos rot ext e mu lo hi ground gn goff g_e g_mu")
#: stage switches and solver settings (see rblog.engine.constants.ContactParams)
Settings = namedtuple("Settings", "do_kick do_sleep iso_shortcut n_vel max_vel vel_tol sor n_pos slop "
                                  "beta max_speed "
                                  "margin e_threshold anchor sleep_speed sleep_time warm "
                                  "n_proj proj_depth anchors_on")

#: the changing state of the bodies, world frame (rblog.engine.state.State's arrays): position
#: (N, 3) m, linear_momentum (N, 3), quat_wxyz (N, 4), rotation (N, 3, 3), angular_momentum (N, 3).
#: The sample buffers are the same record with a leading sample axis (S, N, ...).
BodyState = namedtuple("BodyState", "position linear_momentum quat_wxyz rotation angular_momentum")
#: sleep state kept between calls: awake (N,) 0/1, timer (N,) s at rest, island_of (N,) island id
#: of a sleeping body (-1 awake), island_counter (1,) next island id
SleepState = namedtuple("SleepState", "awake timer island_of island_counter")
#: the contact cache kept between calls: the previous step's manifolds sorted by key (mi0, mf0,
#: pf0, pid0, n_man0, keys0, idx0), spare buffers for this step's (mi1, mf1, pf1, pid1), and the
#: broadphase's pair buffer. Any array may be reallocated (grown) by a call, which returns the
#: cache anew.
ContactCache = namedtuple("ContactCache", "mi0 mf0 pf0 pid0 n_man0 keys0 idx0 mi1 mf1 pf1 pid1 "
                                          "pairs")
#: per-call work arrays of the stages (rows N..N+M-1 of lo/hi: static boxes; row N of the solver
#: arrays: the static dummy with zero inverse mass). See make_scratch.
Scratch = namedtuple("Scratch", "lo hi reach in_contact bm bI bv bw bv0 bw0 pv pw p0 l0 l_drift "
                                "parent isl_time isl_sup nrm pts sep fid work poly blk hot dx_step "
                                "proj_dx proj_dth pushed push_root flow_c flow_ok")

# indices into the stats array the kernel accumulates
(ST_STEPS, ST_PAIRS, ST_MANIFOLDS, ST_POINTS, ST_AWAKE, ST_IMPACTS, ST_WOKEN, ST_SLEPT,
 ST_SWEEPS, ST_PROJECTED) = range(10)
N_STATS = 10


@njit(cache=True)
def _grow_log(log_i, log_f, need):
    if log_i.shape[0] >= need:
        return log_i, log_f
    cap = max(need, 2 * log_i.shape[0])
    li = np.zeros((cap, LOG_I_COLS), np.int64)
    lf = np.zeros((cap, LOG_F_COLS))
    for k in range(log_i.shape[0]):
        for c in range(LOG_I_COLS):
            li[k, c] = log_i[k, c]
        for c in range(LOG_F_COLS):
            lf[k, c] = log_f[k, c]
    return li, lf


@njit(cache=True)
def _store_momenta(i, bd, rotation, linear_momentum, angular_momentum, bv, bw, bv0, bw0, p0,
                   l0, iso_shortcut):
    """P = P0 + m (v - v0), L = L0 + I_world (w - w0): momenta change only by what the solver
    applied (exactly not at all without impulses)."""
    m = 1.0 / bd.inv_mass[i]
    for k in range(3):
        linear_momentum[i, k] = p0[i, k] + m * (bv[i, k] - bv0[i, k])
    dx, dy, dz = bw[i, 0] - bw0[i, 0], bw[i, 1] - bw0[i, 1], bw[i, 2] - bw0[i, 2]
    if iso_shortcut and bd.iso[i]:
        s = bd.inertia[i, 0]
        lx, ly, lz = s * dx, s * dy, s * dz
    else:
        lx, ly, lz = _inertia_world_times(bd, rotation, i, dx, dy, dz)
    angular_momentum[i, 0] = l0[i, 0] + lx
    angular_momentum[i, 1] = l0[i, 1] + ly
    angular_momentum[i, 2] = l0[i, 2] + lz


@njit(cache=True)
def _inertia_world_times(bd, rotation, i, x, y, z):
    """R diag(I_body) R^T (x, y, z) (rotation.omega_world with the inertia in place of its
    inverse)."""
    return omega_world(load_mat(rotation, i), bd.inertia[i, 0], bd.inertia[i, 1],
                       bd.inertia[i, 2], x, y, z)


@njit(cache=True)
def _drift(method, ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h):
    """integrators.drift_rotation behind a call boundary: it is inlined here once, and the world
    step calls this (compiling drift_rotation's four integrators into the large world step
    itself would double its compile time)."""
    drift_rotation(method, ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h)


@njit(cache=True)
def _drift_exact(quat_wxyz, rotation, angular_momentum, inv_inertia, i, h, an, flow_c, flow_ok):
    """integrators.drift_exact_anchored behind a call boundary (as :func:`_drift`): body i's
    exact flow from its anchor, its flow constants cached in row i for the call."""
    drift_exact_anchored(quat_wxyz, rotation, angular_momentum, inv_inertia, i, h,
                         an.anchor_quat_wxyz, an.anchor_L_world, an.anchor_steps, an.anchor_dt_s,
                         flow_c, i, flow_ok)


@njit(cache=True)
def _sync(method, quat_wxyz, rotation, i):
    sync_quat(method, quat_wxyz, rotation, i)


@njit(cache=True)
def _state_sum(i, position, linear_momentum, angular_momentum, rotation):
    """One sum that is non-finite when any of the body's state is (position, momenta, R)."""
    return (position[i, 0] + position[i, 1] + position[i, 2] + linear_momentum[i, 0]
            + linear_momentum[i, 1] + linear_momentum[i, 2] + angular_momentum[i, 0]
            + angular_momentum[i, 1] + angular_momentum[i, 2] + rotation[i, 0, 0]
            + rotation[i, 1, 1] + rotation[i, 2, 2] + rotation[i, 0, 1])


@njit(cache=True)
def make_scratch(n, st):
    """The stages' work arrays for N bodies and the scene's static boxes (allocated per call)."""
    ns = st.n_static
    lo = np.empty((n + ns, 3))
    hi = np.empty((n + ns, 3))
    for k in range(ns):
        for c in range(3):
            lo[n + k, c] = st.lo[k, c]
            hi[n + k, c] = st.hi[k, c]
    return Scratch(
        lo, hi, np.zeros(n + ns), np.zeros(n + 1, np.int64), np.zeros(n + 1), np.zeros((n + 1, 6)),
        np.zeros((n + 1, 3)), np.zeros((n + 1, 3)), np.zeros((n + 1, 3)), np.zeros((n + 1, 3)),
        np.zeros((n + 1, 3)), np.zeros((n + 1, 3)), np.zeros((n, 3)), np.zeros((n, 3)),
        np.zeros((n, 3)), np.zeros(n, np.int64), np.zeros(n), np.zeros(n, np.int64),
        *collider_buffers(), np.zeros((4, 5)), np.zeros(n + 1, np.int64), np.zeros((n + 1, 3)), np.zeros((n + 1, 3)),
        np.zeros((n + 1, 3)), np.zeros(n + 1, np.int64), np.zeros(n + 1, np.int64),
        np.empty((n, N_FLOW)), np.zeros(n, np.bool_))


# ---- the stages, in step order ----------------------------------------------------------------
# Each is a small function of the model records (bd, st, cfg), the state record (x) and the work
# arrays (sc); inlined into the step, callable on its own.

@njit(inline="always")
def kick(bd, awake, x, h):
    """1 kick: P += h (m g + F), L += h tau for awake bodies (world frame)."""
    for i in range(x.position.shape[0]):
        if awake[i]:
            for k in range(3):
                x.linear_momentum[i, k] += h * bd.force[i, k]
                x.angular_momentum[i, k] += h * bd.torque[i, k]


@njit(inline="always")
def broadphase(bd, st, margin, awake, x, h, sc, pairs):
    """2 broadphase: AABBs (of awake bodies swept over the step, padded by ``margin``),
    sort-and-sweep, and (body, ground) pairs. Returns (pairs, n_pairs)."""
    n = x.position.shape[0]
    body_aabbs(bd.geom, bd.size, bd.radius, bd.inv_mass, bd.inv_inertia, awake, x.position,
               x.linear_momentum, x.rotation, x.angular_momentum, h, margin, sc.lo, sc.hi,
               sc.reach)
    pairs, n_pairs = sweep_and_prune(n + st.n_static, n, sc.lo, sc.hi, bd.group, awake, pairs)
    if st.ground:
        pairs, n_pairs = ground_pairs(n, st.n_static, st, sc.lo, sc.hi, pairs, n_pairs)
    return pairs, n_pairs


@njit(inline="always")
def wake(bd, st, cfg, sl, x, h, sc, pairs, n_pairs):
    """3 wake: sleeping islands that an awake body may touch within the step. Returns islands
    woken."""
    return wake_touched(
        pairs, n_pairs, x.position.shape[0], st.n_static, bd.geom, bd.size, sl.awake, sl.timer,
        sl.island_of, x.position, x.rotation, sc.reach, cfg.margin, cfg.slop, st.pos, st.rot,
        st.ext, st.gn, st.goff, x.linear_momentum, x.angular_momentum, bd.force, bd.torque, h,
        cfg.do_kick, sc.nrm, sc.pts, sc.sep, sc.fid, sc.work, sc.poly, bd.inv_mass, bd.accel,
        bd.radius, bd.inv_inertia)


@njit(inline="always")
def collide(bd, st, cfg, awake, x, sc, pairs, n_pairs, c):
    """4 collide: the narrowphase table over the candidate pairs into this step's buffers (c.mi1,
    ...), matching last step's manifolds (c.mi0, ...) for warm starting. Returns (mi1, mf1, pf1,
    pid1, n_man, n_pts); the buffers may have grown."""
    mi1, mf1 = grow_manifolds(c.mi1, c.mf1, 2 * n_pairs)
    pf1, pid1 = grow_points(c.pf1, c.pid1, 8 * n_pairs)
    n_man, n_pts = collide_pairs(
        pairs, n_pairs, x.position.shape[0], st.n_static, bd.geom, bd.size, awake, x.position,
        x.rotation, sc.reach, cfg.margin, bd.restitution, bd.friction, bd.accel, st.pos, st.rot,
        st.ext, st.e, st.mu, st.gn, st.goff, st.g_e, st.g_mu, c.mi0, c.mf0, c.pf0, c.pid0,
        c.keys0, c.idx0, c.n_man0, mi1, mf1, pf1, pid1, cfg.warm, cfg.anchor, sc.nrm, sc.pts,
        sc.sep, sc.fid, sc.work, sc.poly)
    return mi1, mf1, pf1, pid1, n_man, n_pts


@njit(inline="always")
def prepare(bd, cfg, x, sc, mi, mf, pf, n_man, h):
    """5 prepare: load the bodies in contact into the solver arrays; effective masses and
    pre-solve gap velocities of every point."""
    load_bodies(mi, n_man, x.position.shape[0], cfg.iso_shortcut, bd.iso, bd.inv_mass,
                bd.inv_inertia, x.rotation, x.linear_momentum, x.angular_momentum, sc.in_contact,
                sc.bm, sc.bI, sc.bv, sc.bw, sc.bv0, sc.bw0, sc.pv, sc.pw, sc.p0, sc.l0)
    prepare_contacts(mi, mf, pf, n_man, sc.bm, sc.bI, sc.bv, sc.bw, h)


@njit(inline="always")
def mark_pushed(mi, pf, n_man, n, sc):
    """Sort the awake bodies by how they move this step (``sc.pushed``, read by stage 9):

    * 0: no contact pushed it (no manifold, or manifolds whose accumulated normal, friction and
      pseudo impulses all ended at zero): it flies exactly;
    * 1: pushed, within a group of bodies that pushing contacts connect (an island of this
      step) that touches no static geometry: it moves by the solver's velocity plus the same
      exact-flight term as a free body, so that every body away from static geometry flies
      alike (one scheme inside any group of bodies that only push each other);
    * 2: pushed, in an island that some static contact pushes: symplectic Euler (resting
      contact).
    """
    pushed, root = sc.pushed, sc.push_root
    for i in range(n + 1):
        pushed[i] = 0
        root[i] = i
    for m in range(n_man):
        if not mi[m, MI_ACTIVE]:
            continue
        start = mi[m, MI_START]
        push = False
        for p in range(start, start + mi[m, MI_COUNT]):
            if (pf[p, PF_LN] != 0.0 or pf[p, PF_L1] != 0.0 or pf[p, PF_L2] != 0.0
                    or pf[p, PF_LP] != 0.0):
                push = True
                break
        if not push:
            continue
        a, b = mi[m, MI_A], mi[m, MI_B]
        pushed[a] = 1
        pushed[b] = 1
        ra, rb = find_root(root, a), find_root(root, b)
        if ra != rb:  # the static dummy (row n) joins the island it pushes: no self-root
            if ra == n:
                root[rb] = ra
            else:
                root[ra] = rb
    # an island that holds the static dummy touches static geometry
    for i in range(n):
        if pushed[i] and find_root(root, i) == find_root(root, n):
            pushed[i] = 2


@njit(inline="always")
def integrate_positions(method, ortho, bd, cfg, awake, x, sc, h, an):
    """9 integrate: move every awake body over the step (how: ``sc.pushed``, see mark_pushed).
    A body that a contact pushed (solve or relax) moves with the solver's velocity,
    x += h (v + v'), its momenta rebuilt from the solver's velocity changes, and when its island
    touches no static geometry, by - h^2 a / 2 more (the exact flight's term); every other body
    flies exactly under its constant acceleration a, x += h v - h^2 a / 2 with v after the kick
    (a body whose manifolds all ended without impulse gets its start-of-solve momenta back
    bitwise: warm starting applies and withdraws impulses, which leaves round-off). Rotation by
    the run's integrator (integrators.drift_rotation) with the body's L, plus the pseudo spin of
    the relax stage. The exact integrators rotate from the body's flow anchor (``an``, a
    rblog.engine.state.FlowAnchors; a new one whenever the L it drifts with changed)."""
    n = x.position.shape[0]
    for i in range(n):
        if not awake[i]:
            continue
        im = bd.inv_mass[i]
        for k in range(3):
            sc.l_drift[i, k] = x.angular_momentum[i, k]
        pushed = sc.in_contact[i] and sc.pushed[i] != 0
        if pushed:
            _store_momenta(i, bd, x.rotation, x.linear_momentum, x.angular_momentum, sc.bv, sc.bw,
                           sc.bv0, sc.bw0, sc.p0, sc.l0, cfg.iso_shortcut)
            # the exact-flight term, for islands away from static geometry
            fly = 0.5 * h if sc.pushed[i] == 1 else 0.0
            for k in range(3):
                sc.dx_step[i, k] = h * (x.linear_momentum[i, k] * im + sc.pv[i, k]
                                        - fly * bd.accel[i, k])
                x.position[i, k] += sc.dx_step[i, k]
                sc.l_drift[i, k] = x.angular_momentum[i, k]
            if sc.pw[i, 0] != 0.0 or sc.pw[i, 1] != 0.0 or sc.pw[i, 2] != 0.0:
                # rotate by L + I_world w' so the pseudo spin goes through the integrator
                if cfg.iso_shortcut and bd.iso[i]:
                    s0 = bd.inertia[i, 0]
                    jx, jy, jz = s0 * sc.pw[i, 0], s0 * sc.pw[i, 1], s0 * sc.pw[i, 2]
                else:
                    jx, jy, jz = _inertia_world_times(bd, x.rotation, i, sc.pw[i, 0],
                                                      sc.pw[i, 1], sc.pw[i, 2])
                sc.l_drift[i, 0] += jx
                sc.l_drift[i, 1] += jy
                sc.l_drift[i, 2] += jz
        else:
            if sc.in_contact[i]:
                # untouched by the solve: the momenta and solver velocities it started with
                for k in range(3):
                    x.linear_momentum[i, k] = sc.p0[i, k]
                    x.angular_momentum[i, k] = sc.l0[i, k]
                    sc.l_drift[i, k] = sc.l0[i, k]
                    sc.bv[i, k] = sc.bv0[i, k]
                    sc.bw[i, k] = sc.bw0[i, k]
            # exact flight under constant force: x += h v_start + h^2 a / 2
            for k in range(3):
                d = h * (x.linear_momentum[i, k] * im - 0.5 * h * bd.accel[i, k])
                x.position[i, k] += d
                sc.dx_step[i, k] = d
        if method == METHOD_EXACT or method == METHOD_EXACT4:
            _drift_exact(x.quat_wxyz, x.rotation, sc.l_drift, bd.inv_inertia, i, h, an,
                         sc.flow_c, sc.flow_ok)
        else:
            _drift(method, ortho, x.quat_wxyz, x.rotation, sc.l_drift, bd.inv_inertia, i, h)
        if pushed and (sc.pv[i, 0] != 0.0 or sc.pv[i, 1] != 0.0 or sc.pv[i, 2] != 0.0):
            # the pseudo shift h v' moved the body's momentum line: give the orbital change back
            # to its spin so that sum(x x P + L) stays exact
            sx, sy, sz = h * sc.pv[i, 0], h * sc.pv[i, 1], h * sc.pv[i, 2]
            qx, qy, qz = x.linear_momentum[i, 0], x.linear_momentum[i, 1], x.linear_momentum[i, 2]
            x.angular_momentum[i, 0] -= sy * qz - sz * qy
            x.angular_momentum[i, 1] -= sz * qx - sx * qz
            x.angular_momentum[i, 2] -= sx * qy - sy * qx


@njit(inline="always")
def project(method, ortho, bd, st, cfg, awake, x, sc, pairs, n_pairs, rows, ids, an):
    """12 project: narrowphase again at the end-of-step poses; points deeper than
    projection_depth are pushed out (project.py) and the bodies moved (a moved body's flow
    anchor is dropped: its attitude changed other than by the flow). Returns (n_deep, rows,
    ids)."""
    n = x.position.shape[0]
    n_deep, rows, ids = project_positions(
        pairs, n_pairs, n, st.n_static, bd.geom, bd.size, bd.inv_mass, bd.inv_inertia, bd.iso,
        cfg.iso_shortcut, awake, x.position, x.rotation, st.pos, st.rot, st.ext, st.gn, st.goff,
        cfg.proj_depth, cfg.n_proj, rows, ids, sc.nrm, sc.pts, sc.sep, sc.fid, sc.work, sc.poly,
        sc.proj_dx, sc.proj_dth)
    if n_deep > 0:
        apply_projection(n_deep, ids, sc.proj_dx, sc.proj_dth, n, method, ortho, bd,
                          cfg.iso_shortcut, x.position, x.rotation, x.quat_wxyz,
                          x.linear_momentum, x.angular_momentum, sc.l_drift, an.anchor_steps)
    return n_deep, rows, ids


@njit(inline="always")
def sleep_stage(bd, cfg, sl, x, sc, mi, mf, pf, n_man, h, n_awake):
    """13 sleep: wake what this step pushed on (when some bodies slept at the step's start,
    ``n_awake`` < N), advance rest timers, put resting islands to sleep. Returns (islands woken,
    bodies put to sleep)."""
    n = x.position.shape[0]
    woken = 0
    if n_awake < n:
        woken = wake_pushed(mi, mf, pf, n_man, n, sl.awake, sl.timer, sl.island_of, x.position,
                            x.linear_momentum, x.angular_momentum, bd.force, bd.torque, h)
    slept = update_sleep(n, mi, pf, n_man, sl.awake, sl.timer, sl.island_of, sl.island_counter,
                         x.linear_momentum, x.angular_momentum, bd.inv_mass, bd.inv_inertia,
                         bd.radius, h, cfg.sleep_speed, cfg.sleep_time, sc.parent, sc.isl_time,
                         sc.isl_sup)
    return woken, slept


@njit(inline="always")
def first_diverged(awake, x, inv_inertia, h):
    """The first awake body whose state is not finite or that turns more than
    MAX_ROTATION_PER_STEP_RAD in a step of h (integrators.turn_within_bound), or -1: the run has
    diverged there (a torque of 1e40 N m on a resting box, say), though its state may be finite."""
    for i in range(x.position.shape[0]):
        if awake[i] and (not math.isfinite(_state_sum(i, x.position, x.linear_momentum,
                                                      x.angular_momentum, x.rotation))
                         or not turn_within_bound(h, i, inv_inertia, x.rotation,
                                                  x.angular_momentum)):
            return i
    return -1


@njit(inline="always")
def record_contacts(s, mi, mf, pf, n_man, log_i, log_f, n_log):
    """The contact rows of step s: every point that pushed or touches (trajectory.Contacts).
    Returns (log_i, log_f, n_log); the log may have grown."""
    need = n_log
    for m in range(n_man):
        need += mi[m, MI_COUNT]
    log_i, log_f = _grow_log(log_i, log_f, need)
    for m in range(n_man):
        start = mi[m, MI_START]
        for p in range(start, start + mi[m, MI_COUNT]):
            if pf[p, PF_LN] <= 0.0 and pf[p, PF_SEND] > 0.0:
                continue
            log_i[n_log, LOG_STEP] = s
            log_i[n_log, LOG_A] = mi[m, MI_REC_A]
            log_i[n_log, LOG_B] = mi[m, MI_REC_B]
            log_i[n_log, LOG_KIND] = CONTACT_IMPACT if pf[p, PF_IMPACT] > 0.0 else CONTACT_RESTING
            for k in range(3):
                log_f[n_log, LOG_P + k] = pf[p, PF_P + k]
                log_f[n_log, LOG_N + k] = mf[m, MF_N + k]
                log_f[n_log, LOG_F + k] = pf[p, PF_F + k]
            log_f[n_log, LOG_S] = pf[p, PF_SEND]
            log_f[n_log, LOG_LN] = pf[p, PF_LN]
            n_log += 1
    return log_i, log_f, n_log


@njit(inline="always")
def lap(prof, k, t0):
    """Add the ticks since ``t0`` to stage k of the profile; returns now."""
    t = ticks()
    prof[k] += t - t0
    return t


# ---- the step ---------------------------------------------------------------------------------

@njit(cache=True, nogil=True)
def world_advance(bd, st, cfg, method, ortho, dt, n_steps, stride, sample_last, x, out, sl, c,
                  log_i, log_f, stats, prof, an):
    """Advance ``n_steps`` steps of ``dt`` with contacts; write samples and contact rows.

    Args:
        bd, st, cfg: the model records (Bodies, Statics, Settings).
        method, ortho: integrators.METHOD_* / ORTHO_* codes.
        n_steps, stride, sample_last: as free.advance_free (a sample after every stride-th step,
            and after the last one when sample_last).
        x: BodyState, updated in place.  out: BodyState of (S, N, ...) sample buffers.
        sl: SleepState, updated in place.  c: ContactCache.
        log_i, log_f: contact rows (manifold.LOG_* columns).  stats: (N_STATS,) counters.
        prof: (profile.N_PROF,) int64 cycle counts per stage, added to; empty: not profiled.
        an: rblog.engine.state.FlowAnchors, updated in place (the exact integrators' anchors).

    Returns (n_samples, bad_step, bad_body, n_log, log_i, log_f, cache): bad_step is the first
    local step (1-based) at which some body's state became non-finite (-1 if none); the log and
    the cache may have been reallocated to grow.
    """
    n = x.position.shape[0]
    h = dt
    inv_h = 1.0 / dt
    sc = make_scratch(n, st)
    proj_rows = np.zeros((64, PROJ_COLS))  # project stage: gathered points (project.py)
    proj_ids = np.zeros((64, 2), np.int64)
    mi0, mf0, pf0, pid0, n_man0, keys0, idx0 = c.mi0, c.mf0, c.pf0, c.pid0, c.n_man0, c.keys0, c.idx0
    mi1, mf1, pf1, pid1, pairs = c.mi1, c.mf1, c.pf1, c.pid1, c.pairs
    n_log = 0
    n_samples = 0
    # garbage in: a non-finite state handed to this call is reported at its first step
    for i in range(n):
        if not math.isfinite(_state_sum(i, x.position, x.linear_momentum, x.angular_momentum,
                                        x.rotation)):
            return (0, 1, i, 0, log_i, log_f, ContactCache(mi0, mf0, pf0, pid0, n_man0, keys0,
                                                           idx0, mi1, mf1, pf1, pid1, pairs))
    do_prof = prof.shape[0] > 0
    t = 0
    for s in range(1, n_steps + 1):
        n_awake = 0
        for i in range(n):
            n_awake += sl.awake[i] != 0
        if n_awake > 0:
            stats[ST_STEPS] += 1
            stats[ST_AWAKE] += n_awake
            if do_prof:
                t = ticks()
            if cfg.do_kick:
                kick(bd, sl.awake, x, h)                                                  # 1
            if do_prof:
                t = lap(prof, P_KICK, t)
            pairs, n_pairs = broadphase(bd, st, cfg.margin, sl.awake, x, h, sc, pairs)    # 2
            stats[ST_PAIRS] += n_pairs
            if do_prof:
                t = lap(prof, P_BROADPHASE, t)
            if n_awake < n:
                stats[ST_WOKEN] += wake(bd, st, cfg, sl, x, h, sc, pairs, n_pairs)        # 3
            if do_prof:
                t = lap(prof, P_WAKE, t)
            mi1, mf1, pf1, pid1, n_man, n_pts = collide(                                  # 4
                bd, st, cfg, sl.awake, x, sc, pairs, n_pairs,
                ContactCache(mi0, mf0, pf0, pid0, n_man0, keys0, idx0, mi1, mf1, pf1, pid1, pairs))
            stats[ST_MANIFOLDS] += n_man
            stats[ST_POINTS] += n_pts
            if do_prof:
                t = lap(prof, P_COLLIDE, t)
            prepare(bd, cfg, x, sc, mi1, mf1, pf1, n_man, h)                              # 5
            if cfg.warm:
                warm_start(mi1, mf1, pf1, n_man, sc.bm, sc.bI, sc.bv, sc.bw)              # 6
            stats[ST_SWEEPS] += solve_velocities(                                         # 7
                mi1, mf1, pf1, n_man, sc.bm, sc.bI, sc.bv, sc.bw, inv_h, cfg.n_vel, cfg.max_vel,
                cfg.vel_tol, sc.blk, sc.hot, sc.in_contact, cfg.sor)
            if cfg.anchors_on:
                anchor_friction(mi1, mf1, pf1, n_man, sc.bm, sc.bI, sc.bv, sc.bw)          # 7b
            if do_prof:
                t = lap(prof, P_SOLVE, t)
            if cfg.n_pos > 0:
                relax_positions(mi1, mf1, pf1, n_man, sc.bm, sc.bI, sc.pv, sc.pw, inv_h,   # 8
                                cfg.n_pos, cfg.slop, cfg.beta, cfg.max_speed)
            mark_pushed(mi1, pf1, n_man, n, sc)
            if do_prof:
                t = lap(prof, P_RELAX, t)
            integrate_positions(method, ortho, bd, cfg, sl.awake, x, sc, h, an)           # 9
            if do_prof:
                t = lap(prof, P_INTEGRATE, t)
            stats[ST_IMPACTS] += restitution(                                             # 10
                mi1, mf1, pf1, n_man, sc.bm, sc.bI, sc.bv, sc.bw, sc.pv, sc.pw, h,
                cfg.e_threshold, cfg.n_vel, sc.dx_step, x.linear_momentum, x.angular_momentum)
            store_impulses(mi1, mf1, pf1, n_man)                                          # 11
            # this step's manifolds become "previous"
            keys0 = np.empty(max(n_man, 1), np.int64)
            idx0 = np.empty(max(n_man, 1), np.int64)
            sort_manifolds(mi1, n_man, keys0, idx0)
            mi0, mi1 = mi1, mi0
            mf0, mf1 = mf1, mf0
            pf0, pf1 = pf1, pf0
            pid0, pid1 = pid1, pid0
            n_man0 = n_man
            if do_prof:
                t = lap(prof, P_RESTITUTION, t)
            if cfg.n_proj > 0:
                n_deep, proj_rows, proj_ids = project(                                    # 12
                    method, ortho, bd, st, cfg, sl.awake, x, sc, pairs, n_pairs, proj_rows,
                    proj_ids, an)
                stats[ST_PROJECTED] += n_deep
            if do_prof:
                t = lap(prof, P_PROJECT, t)
            if cfg.do_sleep:
                woken, slept = sleep_stage(bd, cfg, sl, x, sc, mi0, mf0, pf0, n_man0, h,      # 13
                                           n_awake)
                stats[ST_WOKEN] += woken
                stats[ST_SLEPT] += slept
            bad = first_diverged(sl.awake, x, bd.inv_inertia, h)
            if do_prof:
                t = lap(prof, P_SLEEP, t)
            if bad >= 0:
                return (n_samples, s, bad, n_log, log_i, log_f,
                        ContactCache(mi0, mf0, pf0, pid0, n_man0, keys0, idx0, mi1, mf1, pf1,
                                     pid1, pairs))
        if s % stride == 0 or (sample_last and s == n_steps):
            if do_prof:
                t = ticks()
            for i in range(n):
                write_sample(method, n_samples, i, x.position, x.linear_momentum, x.quat_wxyz,
                             x.rotation, x.angular_momentum, out.position, out.linear_momentum,
                             out.quat_wxyz, out.rotation, out.angular_momentum)
            n_samples += 1
            log_i, log_f, n_log = record_contacts(s, mi0, mf0, pf0, n_man0, log_i, log_f, n_log)
            if do_prof:
                t = lap(prof, P_SAMPLE, t)
    for i in range(n):
        _sync(method, x.quat_wxyz, x.rotation, i)
    return (n_samples, -1, -1, n_log, log_i, log_f,
            ContactCache(mi0, mf0, pf0, pid0, n_man0, keys0, idx0, mi1, mf1, pf1, pid1, pairs))
