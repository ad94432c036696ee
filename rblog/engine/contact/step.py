"""The compiled world step with contacts: many steps per call, no Python between steps.

One step of ``dt`` (``h``) reads as a flat list of stages (Box2D v3's ``b2World_Step`` and
``b2SolverStage``; Brax's ``pipeline.step``)::

    1  kick             P += h (m g + F), L += h tau              (awake bodies; skipped w/o forces)
    2  broadphase       swept AABBs, sort-and-sweep, ground pairs  (broadphase.py)
    3  wake             sleeping islands an awake body may touch   (island.py)
    4  collide          narrowphase table -> manifolds, warm-start matching, sleeping carried
    5  prepare          effective masses, pre-solve gap velocities (solver.py)
    6  warm start       apply last step's impulses
    7  solve            sequential impulses, Coulomb friction, speculative targets
    8  relax            split-impulse position correction on pseudo velocities (the shift's
                        orbital angular momentum h v' x P is handed back to the spin)
    9  integrate        x += h (v + v'), rotation by rotation.drift_rotation with the run's
                        integrator (the body's L and its current R, so gyroscopic motion is the
                        integrator's own); momenta P, L rebuilt from the solver's velocity changes
    10 restitution      bounce impact points (energy-consistent rule, solver.py), P += J, L += r x J
    11 store impulses   friction as world vectors for the next step
    12 project          narrowphase again at the end-of-step poses; points deeper than
                        projection_depth are pushed out by nonlinear Gauss-Seidel on positions
                        and orientations (project.py); the shift's orbital angular momentum
                        dx x P is handed back to the spin, as in 8
    13 sleep            rest timers, islands, put resting islands to sleep (island.py)

Translation is symplectic Euler (kick, then drift with the new velocity) for every integrator:
contact solvers need the velocity that the drift will use. Torques are kicks too.

Samples follow kernels.advance_free: after every ``stride``-th step and after the last step when
``sample_last``; a non-finite state stops the call and reports the first bad local step and body.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from rblog.engine.free import write_sample
from rblog.engine.rotation import load_mat, omega_world
from rblog.engine.integrators import drift_rotation, sync_quat
from rblog.contract.trajectory import CONTACT_IMPACT, CONTACT_RESTING
from rblog.engine.contact.broadphase import _grow_pairs, body_aabbs, sweep_and_prune
from rblog.engine.contact.collide import collide_pairs, grow_manifolds, grow_points, sort_manifolds
from rblog.engine.contact.island import update_sleep, wake_pushed, wake_touched
from rblog.engine.contact.manifold import (
    LOG_A, LOG_B, LOG_F, LOG_F_COLS, LOG_I_COLS, LOG_KIND, LOG_LN, LOG_N, LOG_P, LOG_S, LOG_STEP,
    MF_N, MI_COUNT, MI_REC_A, MI_REC_B, MI_START, PF_F, PF_IMPACT, PF_LN, PF_P, PF_SEND,
)
from rblog.engine.contact.narrowphase import MAX_CLIP_POINTS
from rblog.engine.contact.project import PROJ_COLS, project_positions
from rblog.engine.contact.solver import (
    load_bodies, prepare_contacts, relax_positions, restitution, solve_velocities,
    store_impulses, warm_start,
)

#: per-body model arrays the kernel reads (N rows each; ``iso`` marks isotropic inertia)
Bodies = namedtuple("Bodies", "geom size radius inv_mass inertia inv_inertia iso force torque "
                              "accel restitution friction group")
#: static geometry: static boxes (their AABBs precomputed) and the ground plane
Statics = namedtuple("Statics", "n_static pos rot ext e mu lo hi ground gn goff g_e g_mu")
#: stage switches and solver settings (see params.ContactParams)
Settings = namedtuple("Settings", "do_kick do_sleep iso_shortcut n_vel max_vel vel_tol sor n_pos slop "
                                  "beta max_speed "
                                  "margin e_threshold anchor sleep_speed sleep_time warm "
                                  "n_proj proj_depth")

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
def _ground_pairs(n_dyn, n_static, st, lo, hi, pairs, n_pairs):
    """Append (body, ground) for every body whose padded AABB reaches the plane."""
    gid = n_dyn + n_static
    gx, gy, gz = st.gn[0], st.gn[1], st.gn[2]
    for i in range(n_dyn):
        cx = 0.5 * (lo[i, 0] + hi[i, 0])
        cy = 0.5 * (lo[i, 1] + hi[i, 1])
        cz = 0.5 * (lo[i, 2] + hi[i, 2])
        ext = (abs(gx) * (hi[i, 0] - lo[i, 0]) + abs(gy) * (hi[i, 1] - lo[i, 1])
               + abs(gz) * (hi[i, 2] - lo[i, 2])) * 0.5
        if gx * cx + gy * cy + gz * cz - st.goff - ext > 0.0:
            continue
        if n_pairs == pairs.shape[0]:
            pairs = _grow_pairs(pairs)
        pairs[n_pairs, 0] = i
        pairs[n_pairs, 1] = gid
        n_pairs += 1
    return pairs, n_pairs


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
    """rotation.drift_rotation behind a call boundary: it is inlined here once, and the world
    step calls this (compiling drift_rotation's four integrators into the large world step
    itself would double its compile time)."""
    drift_rotation(method, ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h)


@njit(cache=True)
def _sync(method, quat_wxyz, rotation, i):
    sync_quat(method, quat_wxyz, rotation, i)


@njit(cache=True)
def _apply_projection(n_deep, ids, dx, dth, n, method, ortho, bd, iso_shortcut, position,
                      rotation, quat_wxyz, linear_momentum, angular_momentum, l_scratch):
    """Move the bodies of the project stage's points by their corrections: x += dx, the
    orientation by the rotation vector dth (through the run's integrator: a drift of unit
    duration with L = I_world dth), and L -= dx x P so that sum(x x P + L) stays exact."""
    for p in range(n_deep):
        for c in range(2):
            i = ids[p, c]
            if i >= n:
                continue
            ux, uy, uz = dx[i, 0], dx[i, 1], dx[i, 2]
            tx, ty, tz = dth[i, 0], dth[i, 1], dth[i, 2]
            if ux == 0.0 and uy == 0.0 and uz == 0.0 and tx == 0.0 and ty == 0.0 and tz == 0.0:
                continue  # no correction, or already applied (a body can have many points)
            position[i, 0] += ux
            position[i, 1] += uy
            position[i, 2] += uz
            qx, qy, qz = linear_momentum[i, 0], linear_momentum[i, 1], linear_momentum[i, 2]
            angular_momentum[i, 0] -= uy * qz - uz * qy
            angular_momentum[i, 1] -= uz * qx - ux * qz
            angular_momentum[i, 2] -= ux * qy - uy * qx
            if tx != 0.0 or ty != 0.0 or tz != 0.0:
                if iso_shortcut and bd.iso[i]:
                    s0 = bd.inertia[i, 0]
                    jx, jy, jz = s0 * tx, s0 * ty, s0 * tz
                else:
                    jx, jy, jz = _inertia_world_times(bd, rotation, i, tx, ty, tz)
                l_scratch[i, 0], l_scratch[i, 1], l_scratch[i, 2] = jx, jy, jz
                _drift(method, ortho, quat_wxyz, rotation, l_scratch, bd.inv_inertia, i, 1.0)
            for k in range(3):
                dx[i, k] = 0.0
                dth[i, k] = 0.0


@njit(cache=True)
def _state_sum(i, position, linear_momentum, angular_momentum, rotation):
    """One sum that is non-finite when any of the body's state is (position, momenta, R)."""
    return (position[i, 0] + position[i, 1] + position[i, 2] + linear_momentum[i, 0]
            + linear_momentum[i, 1] + linear_momentum[i, 2] + angular_momentum[i, 0]
            + angular_momentum[i, 1] + angular_momentum[i, 2] + rotation[i, 0, 0]
            + rotation[i, 1, 1] + rotation[i, 2, 2] + rotation[i, 0, 1])


@njit(cache=True, nogil=True)
def world_advance(bd, st, cfg, method, ortho, dt, n_steps, stride, sample_last,
                  position, linear_momentum, quat_wxyz, rotation, angular_momentum,
                  out_position, out_linear_momentum, out_quat_wxyz, out_rotation,
                  out_angular_momentum,
                  awake, sleep_timer, island_of, island_counter,
                  mi0, mf0, pf0, pid0, n_man0, keys0, idx0, mi1, mf1, pf1, pid1,
                  pairs, log_i, log_f, stats):
    """Advance ``n_steps`` steps of ``dt`` with contacts; write samples and contact rows.

    Args mirror kernels.advance_free for the state and samples. ``awake``, ``sleep_timer``,
    ``island_of``, ``island_counter`` are the sleep state; (mi0, mf0, pf0, pid0, n_man0, keys0,
    idx0) the previous step's manifolds sorted by key; (mi1, ...) spare buffers; ``pairs`` the
    broadphase buffer; ``log_i``/``log_f`` contact rows; ``stats`` (N_STATS,) counters.

    Returns (n_samples, bad_step, bad_body, n_log, log_i, log_f, mi0, mf0, pf0, pid0, n_man0,
    keys0, idx0, mi1, mf1, pf1, pid1, pairs); arrays may have been reallocated to grow.
    """
    n = position.shape[0]
    ns = st.n_static
    h = dt
    inv_h = 1.0 / dt
    # per-call scratch
    lo = np.empty((n + ns, 3))
    hi = np.empty((n + ns, 3))
    for k in range(ns):
        for c in range(3):
            lo[n + k, c] = st.lo[k, c]
            hi[n + k, c] = st.hi[k, c]
    reach = np.zeros(n + ns)
    in_contact = np.zeros(n + 1, np.int64)
    bm = np.zeros(n + 1)
    bI = np.zeros((n + 1, 6))
    bv = np.zeros((n + 1, 3))
    bw = np.zeros((n + 1, 3))
    bv0 = np.zeros((n + 1, 3))
    bw0 = np.zeros((n + 1, 3))
    pv = np.zeros((n + 1, 3))
    pw = np.zeros((n + 1, 3))
    p0 = np.zeros((n, 3))
    l0 = np.zeros((n, 3))
    l_drift = np.zeros((n, 3))
    parent = np.zeros(n, np.int64)
    isl_time = np.zeros(n)
    isl_sup = np.zeros(n, np.int64)
    nrm = np.zeros(6)
    pts = np.zeros((MAX_CLIP_POINTS, 3))
    sep = np.zeros(MAX_CLIP_POINTS)
    fid = np.zeros(MAX_CLIP_POINTS, np.int64)
    work = np.zeros(32)
    poly = np.zeros((2, 2 * MAX_CLIP_POINTS, 4))
    blk = np.zeros((4, 5))
    hot = np.zeros(n + 1, np.int64)
    dx_step = np.zeros((n + 1, 3))  # displacement this step (row n: the static dummy, 0)
    proj_rows = np.zeros((64, PROJ_COLS))  # project stage: gathered points (project.py)
    proj_ids = np.zeros((64, 2), np.int64)
    proj_dx = np.zeros((n + 1, 3))
    proj_dth = np.zeros((n + 1, 3))
    n_man = n_man0
    n_log = 0
    n_samples = 0
    # garbage in: a non-finite state handed to this call is reported at its first step
    for i in range(n):
        if not math.isfinite(_state_sum(i, position, linear_momentum, angular_momentum,
                                        rotation)):
            return (0, 1, i, 0, log_i, log_f, mi0, mf0, pf0, pid0, n_man0, keys0, idx0, mi1,
                    mf1, pf1, pid1, pairs)
    for s in range(1, n_steps + 1):
        n_awake = 0
        for i in range(n):
            n_awake += awake[i] != 0
        if n_awake > 0:
            stats[ST_STEPS] += 1
            stats[ST_AWAKE] += n_awake
            # 1 kick: external forces (gravity, applied force and torque)
            if cfg.do_kick:
                for i in range(n):
                    if awake[i]:
                        for k in range(3):
                            linear_momentum[i, k] += h * bd.force[i, k]
                            angular_momentum[i, k] += h * bd.torque[i, k]
            # 2 broadphase
            body_aabbs(bd.geom, bd.size, bd.radius, bd.inv_mass, bd.inv_inertia, awake, position,
                       linear_momentum, rotation, angular_momentum, h, cfg.margin, lo, hi, reach)
            pairs, n_pairs = sweep_and_prune(n + ns, n, lo, hi, bd.group, awake, pairs)
            if st.ground:
                pairs, n_pairs = _ground_pairs(n, ns, st, lo, hi, pairs, n_pairs)
            stats[ST_PAIRS] += n_pairs
            # 3 wake sleeping islands that an awake body may touch
            if n_awake < n:
                stats[ST_WOKEN] += wake_touched(
                    pairs, n_pairs, n, ns, bd.geom, bd.size, awake, sleep_timer, island_of,
                    position, rotation, reach, cfg.margin, cfg.slop, st.pos, st.rot, st.ext,
                    st.gn, st.goff, linear_momentum, angular_momentum, bd.force, bd.torque, h,
                    cfg.do_kick, nrm, pts, sep, fid, work, poly, bd.inv_mass, bd.accel, bd.radius,
                    bd.inv_inertia)
            # 4 collide: narrowphase into this step's buffers, warm starting from the last
            mi1, mf1 = grow_manifolds(mi1, mf1, 2 * n_pairs)
            pf1, pid1 = grow_points(pf1, pid1, 8 * n_pairs)
            n_man, n_pts = collide_pairs(
                pairs, n_pairs, n, ns, bd.geom, bd.size, awake, position, rotation, reach,
                cfg.margin, bd.restitution, bd.friction, bd.accel, st.pos, st.rot, st.ext, st.e,
                st.mu, st.gn, st.goff, st.g_e, st.g_mu, mi0, mf0, pf0, pid0, keys0, idx0, n_man0,
                mi1, mf1, pf1, pid1, cfg.warm, cfg.anchor, nrm, pts, sep, fid, work, poly)
            stats[ST_MANIFOLDS] += n_man
            stats[ST_POINTS] += n_pts
            # 5 prepare
            load_bodies(mi1, n_man, n, cfg.iso_shortcut, bd.iso, bd.inv_mass, bd.inv_inertia,
                        rotation, linear_momentum, angular_momentum, in_contact, bm, bI, bv, bw,
                        bv0, bw0, pv, pw, p0, l0)
            prepare_contacts(mi1, mf1, pf1, n_man, bm, bI, bv, bw, h)
            # 6 warm start
            if cfg.warm:
                warm_start(mi1, mf1, pf1, n_man, bm, bI, bv, bw)
            # 7 solve
            stats[ST_SWEEPS] += solve_velocities(mi1, mf1, pf1, n_man, bm, bI, bv, bw, inv_h,
                                                 cfg.n_vel, cfg.max_vel, cfg.vel_tol, blk, hot,
                                                 in_contact, cfg.sor)
            # 8 relax: split-impulse position correction
            if cfg.n_pos > 0:
                relax_positions(mi1, mf1, pf1, n_man, bm, bI, pv, pw, inv_h, cfg.n_pos, cfg.slop,
                                cfg.beta, cfg.max_speed)
            # 9 integrate positions
            for i in range(n):
                if not awake[i]:
                    continue
                im = bd.inv_mass[i]
                for k in range(3):
                    l_drift[i, k] = angular_momentum[i, k]
                if in_contact[i]:
                    _store_momenta(i, bd, rotation, linear_momentum, angular_momentum, bv, bw,
                                   bv0, bw0, p0, l0, cfg.iso_shortcut)
                    for k in range(3):
                        dx_step[i, k] = h * (linear_momentum[i, k] * im + pv[i, k])
                        position[i, k] += dx_step[i, k]
                        l_drift[i, k] = angular_momentum[i, k]
                    if pw[i, 0] != 0.0 or pw[i, 1] != 0.0 or pw[i, 2] != 0.0:
                        # rotate by L + I_world w' so the pseudo spin goes through the integrator
                        if cfg.iso_shortcut and bd.iso[i]:
                            s0 = bd.inertia[i, 0]
                            jx, jy, jz = s0 * pw[i, 0], s0 * pw[i, 1], s0 * pw[i, 2]
                        else:
                            jx, jy, jz = _inertia_world_times(bd, rotation, i, pw[i, 0],
                                                              pw[i, 1], pw[i, 2])
                        l_drift[i, 0] += jx
                        l_drift[i, 1] += jy
                        l_drift[i, 2] += jz
                else:
                    for k in range(3):
                        position[i, k] += h * linear_momentum[i, k] * im
                _drift(method, ortho, quat_wxyz, rotation, l_drift, bd.inv_inertia, i, h)
                if in_contact[i] and (pv[i, 0] != 0.0 or pv[i, 1] != 0.0 or pv[i, 2] != 0.0):
                    # the pseudo shift h v' moved the body's momentum line: give the orbital
                    # change back to its spin so that sum(x x P + L) stays exact
                    sx, sy, sz = h * pv[i, 0], h * pv[i, 1], h * pv[i, 2]
                    qx, qy, qz = linear_momentum[i, 0], linear_momentum[i, 1], linear_momentum[i, 2]
                    angular_momentum[i, 0] -= sy * qz - sz * qy
                    angular_momentum[i, 1] -= sz * qx - sx * qz
                    angular_momentum[i, 2] -= sx * qy - sy * qx
            # 10 restitution (also records the solve's impulses for warm starting)
            n_imp = restitution(mi1, mf1, pf1, n_man, bm, bI, bv, bw, pv, pw, h,
                                cfg.e_threshold, cfg.n_vel, dx_step, linear_momentum,
                                angular_momentum)
            stats[ST_IMPACTS] += n_imp
            # 11 store impulses
            store_impulses(mi1, mf1, pf1, n_man)
            # this step's manifolds become "previous"
            keys0 = np.empty(max(n_man, 1), np.int64)
            idx0 = np.empty(max(n_man, 1), np.int64)
            sort_manifolds(mi1, n_man, keys0, idx0)
            mi0, mi1 = mi1, mi0
            mf0, mf1 = mf1, mf0
            pf0, pf1 = pf1, pf0
            pid0, pid1 = pid1, pid0
            n_man0 = n_man
            # 12 project: points deeper than projection_depth at the end-of-step poses
            if cfg.n_proj > 0:
                n_deep, proj_rows, proj_ids = project_positions(
                    pairs, n_pairs, n, ns, bd.geom, bd.size, bd.inv_mass, bd.inv_inertia, bd.iso,
                    cfg.iso_shortcut, awake, position, rotation, st.pos, st.rot, st.ext, st.gn,
                    st.goff, cfg.proj_depth, cfg.n_proj, proj_rows, proj_ids, nrm, pts, sep, fid,
                    work, poly, proj_dx, proj_dth)
                stats[ST_PROJECTED] += n_deep
                if n_deep > 0:
                    _apply_projection(n_deep, proj_ids, proj_dx, proj_dth, n, method, ortho, bd,
                                      cfg.iso_shortcut, position, rotation, quat_wxyz,
                                      linear_momentum, angular_momentum, l_drift)
            # 13 sleep (and wake what was pushed on)
            if cfg.do_sleep and n_awake < n:
                stats[ST_WOKEN] += wake_pushed(mi0, pf0, n_man0, n, awake, sleep_timer, island_of,
                                               linear_momentum, angular_momentum, bd.force,
                                               bd.torque, h)
            if cfg.do_sleep:
                stats[ST_SLEPT] += update_sleep(
                    n, mi0, pf0, n_man0, awake, sleep_timer, island_of, island_counter,
                    linear_momentum, angular_momentum, bd.inv_mass, bd.inv_inertia, bd.radius, h,
                    cfg.sleep_speed, cfg.sleep_time, parent, isl_time, isl_sup)
            # non-finite check: one sum covers position, momenta and the rotation's diagonal
            for i in range(n):
                if not awake[i]:
                    continue
                if not math.isfinite(_state_sum(i, position, linear_momentum, angular_momentum,
                                                rotation)):
                    return (n_samples, s, i, n_log, log_i, log_f, mi0, mf0, pf0, pid0, n_man0,
                            keys0, idx0, mi1, mf1, pf1, pid1, pairs)
        if s % stride == 0 or (sample_last and s == n_steps):
            j = n_samples
            for i in range(n):
                write_sample(method, j, i, position, linear_momentum, quat_wxyz, rotation,
                             angular_momentum, out_position, out_linear_momentum, out_quat_wxyz,
                             out_rotation, out_angular_momentum)
            n_samples += 1
            # contacts of this step: points that pushed or touch
            need = n_log
            for m in range(n_man0):
                need += mi0[m, MI_COUNT]
            log_i, log_f = _grow_log(log_i, log_f, need)
            for m in range(n_man0):
                start = mi0[m, MI_START]
                for p in range(start, start + mi0[m, MI_COUNT]):
                    if pf0[p, PF_LN] <= 0.0 and pf0[p, PF_SEND] > 0.0:
                        continue
                    log_i[n_log, LOG_STEP] = s
                    log_i[n_log, LOG_A] = mi0[m, MI_REC_A]
                    log_i[n_log, LOG_B] = mi0[m, MI_REC_B]
                    log_i[n_log, LOG_KIND] = CONTACT_IMPACT if pf0[p, PF_IMPACT] > 0.0 else CONTACT_RESTING
                    for k in range(3):
                        log_f[n_log, LOG_P + k] = pf0[p, PF_P + k]
                        log_f[n_log, LOG_N + k] = mf0[m, MF_N + k]
                        log_f[n_log, LOG_F + k] = pf0[p, PF_F + k]
                    log_f[n_log, LOG_S] = pf0[p, PF_SEND]
                    log_f[n_log, LOG_LN] = pf0[p, PF_LN]
                    n_log += 1
    if n > 0:
        for i in range(n):
            _sync(method, quat_wxyz, rotation, i)
    return (n_samples, -1, -1, n_log, log_i, log_f, mi0, mf0, pf0, pid0, n_man0, keys0, idx0,
            mi1, mf1, pf1, pid1, pairs)
