"""Compiled kernels that advance free bodies (no contacts) many steps per call.

Bodies are independent without contacts, so the loop runs over tiles of BODY_TILE bodies, steps
inside a tile: the tile's state stays in L1 for the whole block, and samples are written for
consecutive bodies. Each body's step is its integrator's ``step_body``
(rblog.engine.integrators, where every integrator's stages are written out and derived), except
under ``exact``/``exact4``, whose kernel writes the same step out in its own body
(:func:`_make_exact_kernel`: no array passes through an inlined function in its loop, so the loop
does no reference counting; through ``step_body`` the atomic increments and decrements were a
third of its time).

Samples are written after every ``stride``-th step (and after the last step of the block when
``sample_last``), so logging costs nothing between samples.

Threads: :func:`advance_free` splits the bodies into contiguous ranges, one per thread
(``numba.config.NUMBA_NUM_THREADS``: the environment variable NUMBA_NUM_THREADS, by default
every core; numba's own threading layer is not started, as starting it changes how the process
takes SIGINT), and runs the
compiled :func:`advance_free_range` on each from a pool of Python threads (the kernel releases
the GIL). A body's arithmetic does not depend on which range it is in, so the result is bitwise
the same for any thread count; one compiled specialisation serves every count.

Compilation: each integrator has its own kernel (:func:`range_kernel`, the integrator a constant
of the kernel), so a run compiles only the integrator it uses; the drifts are functions of their
own (rblog.engine.integrators), not inlined into the kernel by numba: a cold first run of a
free-body scene compiles in ~4 s instead of ~35 s (benchmarks/bench_firstrun.py).
"""

from __future__ import annotations

import math
import threading
from concurrent.futures import ThreadPoolExecutor

import numba
from numba import njit

import numpy as np

from rblog.engine.exact import FC_RJC, N_FLOW, flow_row
from rblog.engine.integrators import (
    METHOD_EXACT, METHOD_EXACT4, METHOD_NAMES, METHOD_SEED, YOSHIDA_W0, YOSHIDA_W1,
    anchor_constants, anchor_holds, anchored_quat, flight_exact, step_body, sync_quat,
    turn_within_bound_m,
)
from rblog.engine.rotation import quat_to_mat
from rblog.engine.state import new_anchors


#: bodies advanced together, steps inner: their state (~180 B each) stays in L1, and a sample's
#: writes for consecutive bodies share cache lines (a bodies-outer loop wrote each body's samples
#: a whole sample-row apart: one cache miss per channel per sample).
BODY_TILE = 32
#: ... but when samples are this many steps apart or more, the write pattern does not matter and
#: one body at a time (its position and momentum in registers for the whole block) is faster.
SPARSE_STRIDE = 8


@njit(cache=True, inline="always")
def write_sample(method, j, i, position, linear_momentum, quat_wxyz, rotation, angular_momentum,
                 out_position, out_linear_momentum, out_quat_wxyz, out_rotation,
                 out_angular_momentum):
    """Copy body i's state into sample row j of the out_* buffers (q synced from R first).
    Inlined into the stepping loops: a call per body-sample (array arguments and their reference
    counts) cost ~6x the copy itself."""
    if method == METHOD_SEED:  # the only integrator whose q is not current
        sync_quat(method, quat_wxyz, rotation, i)
    for a in range(3):
        out_position[j, i, a] = position[i, a]
        out_linear_momentum[j, i, a] = linear_momentum[i, a]
        out_angular_momentum[j, i, a] = angular_momentum[i, a]
        for b in range(3):
            out_rotation[j, i, a, b] = rotation[i, a, b]
    for a in range(4):
        out_quat_wxyz[j, i, a] = quat_wxyz[i, a]


#: below this many body-steps in a call, one thread (a thread hand-off costs ~50 us)
MIN_PARALLEL_BODY_STEPS = 200_000

_POOL: list = []
_POOL_LOCK = threading.Lock()


def _pool(n_threads: int) -> ThreadPoolExecutor:
    with _POOL_LOCK:
        if not _POOL or _POOL[0][0] < n_threads:
            if _POOL:
                _POOL.pop()[1].shutdown(wait=False)
            _POOL.append((n_threads, ThreadPoolExecutor(n_threads, "rblog-free")))
        return _POOL[0][1]


def body_ranges(n_bodies: int, n_threads: int) -> list[tuple[int, int]]:
    """Contiguous [b0, b1) ranges, one per thread, split on BODY_TILE boundaries."""
    tiles = -(-n_bodies // BODY_TILE)
    k = max(1, min(n_threads, tiles))
    cuts = [min(n_bodies, ((tiles * t) // k) * BODY_TILE) for t in range(k + 1)]
    return [(cuts[t], cuts[t + 1]) for t in range(k) if cuts[t + 1] > cuts[t]]


def advance_free(method, ortho, dt, n_steps, stride, sample_last,
                 inv_mass, inv_inertia, force_world, torque_world,
                 position, linear_momentum, quat_wxyz, rotation, angular_momentum,
                 out_position, out_linear_momentum, out_quat_wxyz, out_rotation,
                 out_angular_momentum, n_threads=None, anchors=None):
    """Advance all bodies ``n_steps`` steps of ``dt`` on ``n_threads`` threads (default
    ``numba.config.NUMBA_NUM_THREADS``); arguments and result as :func:`advance_free_range` over all
    bodies, bitwise the same for any thread count. ``anchors`` (rblog.engine.state.FlowAnchors,
    updated in place) carries the exact integrators' flow anchors from call to call, so a run
    gives the same result however it is split into calls; None: anchors for this call only."""
    n = position.shape[0]
    if anchors is None:
        anchors = new_anchors(n)
    if n_threads is None:
        n_threads = numba.config.NUMBA_NUM_THREADS
    ranges = body_ranges(n, n_threads) if n * n_steps >= MIN_PARALLEL_BODY_STEPS else [(0, n)]
    args = (method, ortho, dt, n_steps, stride, sample_last, inv_mass, inv_inertia, force_world,
            torque_world, position, linear_momentum, quat_wxyz, rotation, angular_momentum,
            out_position, out_linear_momentum, out_quat_wxyz, out_rotation, out_angular_momentum,
            anchors)
    if len(ranges) == 1:
        return advance_free_range(*args, 0, n)
    futures = [_pool(len(ranges)).submit(advance_free_range, *args, b0, b1) for b0, b1 in ranges]
    results = [f.result() for f in futures]
    # the serial kernel's reduction: most samples; the earliest bad step, first body on ties
    n_samples, bad_step, bad_body = 0, -1, -1
    for ns, bs, bb in results:
        n_samples = max(n_samples, ns)
        if bs >= 0 and (bad_step < 0 or bs < bad_step):
            bad_step, bad_body = bs, bb
    return n_samples, bad_step, bad_body


def advance_free_range(method, ortho, dt, n_steps, stride, sample_last,
                       inv_mass, inv_inertia, force_world, torque_world,
                       position, linear_momentum, quat_wxyz, rotation, angular_momentum,
                       out_position, out_linear_momentum, out_quat_wxyz, out_rotation,
                       out_angular_momentum, anchors, b0, b1):
    """Advance bodies b0 .. b1-1 by integrator ``method`` (the compiled kernel of
    :func:`range_kernel`; arguments and result documented there)."""
    return range_kernel(method)(ortho, dt, n_steps, stride, sample_last, inv_mass, inv_inertia,
                                force_world, torque_world, position, linear_momentum, quat_wxyz,
                                rotation, angular_momentum, out_position, out_linear_momentum,
                                out_quat_wxyz, out_rotation, out_angular_momentum, anchors, b0, b1)


_KERNELS: dict = {}


def range_kernel(method: int):
    """The free-body kernel of one integrator, made (not yet compiled) on first use.

    ``method`` is a constant of the kernel's closure, so numba prunes every other integrator's
    branch of :func:`~rblog.engine.integrators.step_body` before typing: a run compiles only its
    own integrator (the six together took ~31 s to compile, benchmarks/RESULTS.md). numba caches
    each closure under its own key (the closure's value is part of the cache index key)."""
    method = int(method)
    if method not in METHOD_NAMES:
        raise ValueError(f"unknown integrator code {method}")
    k = _KERNELS.get(method)
    if k is None:
        make = _make_exact_kernel if method in (METHOD_EXACT, METHOD_EXACT4) else _make_range_kernel
        k = _KERNELS[method] = make(method)
    return k


def _make_range_kernel(method: int):
    @njit(cache=True, nogil=True)
    def advance_free_range(ortho, dt, n_steps, stride, sample_last,
                           inv_mass, inv_inertia, force_world, torque_world,
                           position, linear_momentum, quat_wxyz, rotation, angular_momentum,
                           out_position, out_linear_momentum, out_quat_wxyz, out_rotation,
                           out_angular_momentum, an, b0, b1):
        """Advance bodies b0 .. b1-1 ``n_steps`` steps of ``dt``; write their samples.

        Args:
            ortho: an ORTHO_* code (the integrator, ``method``, is the closure's constant).
            inv_mass: (N,).  inv_inertia: (N, 3) diag(I_body^-1).
            force_world: (N, 3) total constant force incl. gravity (N).  torque_world: (N, 3) (N m).
            position, linear_momentum, quat_wxyz, rotation, angular_momentum: state, updated in place.
            out_*: (S, N, ...) sample buffers, S >= n_steps // stride + sample_last.
            an: rblog.engine.state.FlowAnchors, updated in place (exact integrators only).
            b0, b1: the body range (0, N for all).

        Returns:
            (n_samples, bad_step, bad_body): samples written, and the first local step (1-based) at
            which some body's state became non-finite (-1 if none) and that body. The caller keeps
            only samples taken before a bad step.
        """
        n_samples = 0
        bad_step = -1
        bad_body = -1
        # Sparse samples: one body at a time, position and momentum in registers for the block.
        # Dense samples: tiles of bodies, so that a sample's writes share cache lines.
        tile = 1 if stride >= SPARSE_STRIDE else BODY_TILE
        # the exact flow's constants of each body of a tile, computed from its anchor on its
        # first step in this call (a pure function of the anchor: the same in every split)
        fc = np.empty((tile, N_FLOW))
        fc_ok = np.zeros(tile, np.bool_)
        a_q, a_l, a_n, a_dt = an  # the FlowAnchors arrays, out of the tuple once
        for t0 in range(b0, b1, tile):
            t1 = min(t0 + tile, b1)
            fc_ok[:] = False
            j = 0
            if tile == 1:
                i = t0
                x, y, z = position[i, 0], position[i, 1], position[i, 2]
                px, py, pz = linear_momentum[i, 0], linear_momentum[i, 1], linear_momentum[i, 2]
                for s in range(1, n_steps + 1):
                    ok, x, y, z, px, py, pz = step_body(
                        method, ortho, dt, i, inv_mass, inv_inertia, force_world, torque_world,
                        quat_wxyz, rotation, angular_momentum, x, y, z, px, py, pz, a_q, a_l, a_n,
                        a_dt, fc, 0, fc_ok)
                    if not ok:
                        if bad_step < 0 or s < bad_step:
                            bad_step = s
                            bad_body = i
                        break
                    if s % stride == 0 or (sample_last and s == n_steps):
                        position[i, 0], position[i, 1], position[i, 2] = x, y, z
                        linear_momentum[i, 0], linear_momentum[i, 1], linear_momentum[i, 2] = px, py, pz
                        write_sample(method, j, i, position, linear_momentum, quat_wxyz, rotation,
                                      angular_momentum, out_position, out_linear_momentum,
                                      out_quat_wxyz, out_rotation, out_angular_momentum)
                        j += 1
                position[i, 0], position[i, 1], position[i, 2] = x, y, z
                linear_momentum[i, 0], linear_momentum[i, 1], linear_momentum[i, 2] = px, py, pz
            else:
                for s in range(1, n_steps + 1):
                    ok = True
                    for i in range(t0, t1):
                        ok, x, y, z, px, py, pz = step_body(
                            method, ortho, dt, i, inv_mass, inv_inertia, force_world, torque_world,
                            quat_wxyz, rotation, angular_momentum, position[i, 0], position[i, 1],
                            position[i, 2], linear_momentum[i, 0], linear_momentum[i, 1],
                            linear_momentum[i, 2], a_q, a_l, a_n, a_dt, fc, i - t0,
                            fc_ok)
                        position[i, 0], position[i, 1], position[i, 2] = x, y, z
                        linear_momentum[i, 0], linear_momentum[i, 1], linear_momentum[i, 2] = px, py, pz
                        if not ok:
                            if bad_step < 0 or s < bad_step:
                                bad_step = s
                                bad_body = i
                            break
                    if not ok:
                        break
                    if s % stride == 0 or (sample_last and s == n_steps):
                        for i in range(t0, t1):
                            write_sample(method, j, i, position, linear_momentum, quat_wxyz, rotation,
                                          angular_momentum, out_position, out_linear_momentum,
                                          out_quat_wxyz, out_rotation, out_angular_momentum)
                        j += 1
            if method == METHOD_SEED:  # the only integrator whose q is not current
                for i in range(t0, t1):
                    sync_quat(method, quat_wxyz, rotation, i)
            if j > n_samples:
                n_samples = j
        return n_samples, bad_step, bad_body

    return advance_free_range


def _make_exact_kernel(method: int):
    """The free-body kernel of ``exact`` / ``exact4``: :func:`_make_range_kernel`'s loops with the
    exact step written out in the kernel's own body rather than through ``step_body``.

    Why a kernel of its own: numba's inliner gives every inlined function's array arguments
    copies whose reference counts (two atomic operations each) its pruning pass could not
    remove from the exact step's branchy body: 26 atomic operations a body-step, a third of the
    exact kernel's time (~120 ns of ~390; benchmarks/RESULTS.md). Here the step touches only the
    kernel's own arrays and calls scalar functions (integrators.flight_exact, anchor_holds,
    anchored_quat, turn_within_bound_m, exact.flow_eval); arrays cross a call only where a new anchor's constants
    are computed (integrators.anchor_constants) and at samples. The arithmetic is the step's of
    integrators.step_body and drift_exact_anchored, operation for operation (the same bits:
    tests/engine/test_exact_anchored.py compares this kernel with the contact step's drift)."""

    @njit(cache=True, nogil=True)
    def advance_exact_range(ortho, dt, n_steps, stride, sample_last,
                            inv_mass, inv_inertia, force_world, torque_world,
                            position, linear_momentum, quat_wxyz, rotation, angular_momentum,
                            out_position, out_linear_momentum, out_quat_wxyz, out_rotation,
                            out_angular_momentum, an, b0, b1):
        """As :func:`_make_range_kernel`'s ``advance_free_range`` (same arguments and result)."""
        n_samples = 0
        bad_step = -1
        bad_body = -1
        tile = 1 if stride >= SPARSE_STRIDE else BODY_TILE
        # the flow constants of each body of a tile (see _make_range_kernel)
        fc = np.empty((tile, N_FLOW))
        fc_ok = np.zeros(tile, np.bool_)
        a_q, a_l, a_n, a_dt = an
        for t0 in range(b0, b1, tile):
            t1 = min(t0 + tile, b1)
            fc_ok[:] = False
            j = 0
            for s in range(1, n_steps + 1):
                ok = True
                for i in range(t0, t1):
                    r = i - t0
                    # translation: exact for a constant force (integrators.step_body)
                    im = inv_mass[i]
                    fx, fy, fz = force_world[i, 0], force_world[i, 1], force_world[i, 2]
                    tx, ty, tz = torque_world[i, 0], torque_world[i, 1], torque_world[i, 2]
                    x, y, z, px, py, pz = flight_exact(
                        dt, im, position[i, 0], position[i, 1], position[i, 2], linear_momentum[i, 0],
                        linear_momentum[i, 1], linear_momentum[i, 2], fx, fy, fz)
                    position[i, 0], position[i, 1], position[i, 2] = x, y, z
                    linear_momentum[i, 0], linear_momentum[i, 1], linear_momentum[i, 2] = px, py, pz
                    # rotation: Strang kick(h/2) flow(h) kick(h/2), with torque under exact4
                    # Yoshida's three of them (integrators._strang_exact, step_body)
                    k0, k1, k2 = inv_inertia[i, 0], inv_inertia[i, 1], inv_inertia[i, 2]
                    lx, ly, lz = angular_momentum[i, 0], angular_momentum[i, 1], angular_momentum[i, 2]
                    qw, qx, qy, qz = quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3]
                    torqued = tx != 0.0 or ty != 0.0 or tz != 0.0
                    n_sub = 3 if (method == METHOD_EXACT4 and torqued) else 1
                    for sub in range(n_sub):
                        h = dt
                        if n_sub == 3:
                            h = YOSHIDA_W0 * dt if sub == 1 else YOSHIDA_W1 * dt
                        hk = 0.5 * h
                        if torqued:
                            lx += hk * tx
                            ly += hk * ty
                            lz += hk * tz
                        # the anchor (integrators.drift_exact_anchored): kept while L is bitwise
                        # the anchor's and the step is the same
                        if not anchor_holds(a_n[i], a_dt[i], a_l[i, 0], a_l[i, 1], a_l[i, 2], h,
                                            lx, ly, lz):
                            a_q[i, 0], a_q[i, 1], a_q[i, 2], a_q[i, 3] = qw, qx, qy, qz
                            a_l[i, 0], a_l[i, 1], a_l[i, 2] = lx, ly, lz
                            a_n[i] = 0
                            a_dt[i] = h
                            fc_ok[r] = False
                        aw, ax, ay, az = a_q[i, 0], a_q[i, 1], a_q[i, 2], a_q[i, 3]
                        if not fc_ok[r]:
                            anchor_constants(fc, r, aw, ax, ay, az, lx, ly, lz, k0, k1, k2, h)
                            fc_ok[r] = True
                        n = a_n[i] + 1
                        qw, qx, qy, qz, rj_c = anchored_quat(flow_row(fc, r), aw, ax, ay, az,
                                                             n * abs(h), qw, qx, qy, qz)
                        if rj_c >= 0.0 and fc[r, FC_RJC] < 0.0:
                            fc[r, FC_RJC] = rj_c
                        a_n[i] = n
                        if torqued:
                            lx += hk * tx
                            ly += hk * ty
                            lz += hk * tz
                    angular_momentum[i, 0], angular_momentum[i, 1], angular_momentum[i, 2] = lx, ly, lz
                    quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3] = qw, qx, qy, qz
                    m = quat_to_mat(qw, qx, qy, qz)
                    rotation[i, 0, 0], rotation[i, 0, 1], rotation[i, 0, 2] = m[0], m[1], m[2]
                    rotation[i, 1, 0], rotation[i, 1, 1], rotation[i, 1, 2] = m[3], m[4], m[5]
                    rotation[i, 2, 0], rotation[i, 2, 1], rotation[i, 2, 2] = m[6], m[7], m[8]
                    # non-finite check and turn bound (integrators.step_body)
                    chk = x + y + z + px + py + pz + lx + ly + lz + m[0] + m[4] + m[8] + m[1]
                    ok = math.isfinite(chk) and turn_within_bound_m(dt, k0, k1, k2, lx, ly, lz, m)
                    if not ok:
                        if bad_step < 0 or s < bad_step:
                            bad_step = s
                            bad_body = i
                        break
                if not ok:
                    break
                if s % stride == 0 or (sample_last and s == n_steps):
                    for i in range(t0, t1):
                        write_sample(method, j, i, position, linear_momentum, quat_wxyz, rotation,
                                     angular_momentum, out_position, out_linear_momentum,
                                     out_quat_wxyz, out_rotation, out_angular_momentum)
                    j += 1
            if j > n_samples:
                n_samples = j
        return n_samples, bad_step, bad_body

    return advance_exact_range
