"""Compiled kernels that advance free bodies (no contacts) many steps per call.

Bodies are independent without contacts, so the loop runs over tiles of BODY_TILE bodies, steps
inside a tile: the tile's state stays in L1 for the whole block, and samples are written for
consecutive bodies. Each body's step is its integrator's ``step_body``
(rblog.engine.integrators, where every integrator's stages are written out and derived).

Samples are written after every ``stride``-th step (and after the last step of the block when
``sample_last``), so logging costs nothing between samples.
"""

from __future__ import annotations

from numba import njit

from rblog.engine.integrators import step_body, sync_quat, METHOD_SEED


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


@njit(cache=True, nogil=True)
def advance_free(method, ortho, dt, n_steps, stride, sample_last,
                 inv_mass, inv_inertia, force_world, torque_world,
                 position, linear_momentum, quat_wxyz, rotation, angular_momentum,
                 out_position, out_linear_momentum, out_quat_wxyz, out_rotation,
                 out_angular_momentum):
    """Advance all bodies ``n_steps`` steps of ``dt``; write samples.

    Args:
        method, ortho: rotation.METHOD_* / ORTHO_* codes.
        inv_mass: (N,).  inv_inertia: (N, 3) diag(I_body^-1).
        force_world: (N, 3) total constant force incl. gravity (N).  torque_world: (N, 3) (N m).
        position, linear_momentum, quat_wxyz, rotation, angular_momentum: state, updated in place.
        out_*: (S, N, ...) sample buffers, S >= n_steps // stride + sample_last.

    Returns:
        (n_samples, bad_step, bad_body): samples written, and the first local step (1-based) at
        which some body's state became non-finite (-1 if none) and that body. The caller keeps
        only samples taken before a bad step.
    """
    n_bodies = position.shape[0]
    n_samples = 0
    bad_step = -1
    bad_body = -1
    # Sparse samples: one body at a time, position and momentum in registers for the block.
    # Dense samples: tiles of bodies, so that a sample's writes share cache lines.
    tile = 1 if stride >= SPARSE_STRIDE else BODY_TILE
    for t0 in range(0, n_bodies, tile):
        t1 = min(t0 + tile, n_bodies)
        j = 0
        if tile == 1:
            i = t0
            x, y, z = position[i, 0], position[i, 1], position[i, 2]
            px, py, pz = linear_momentum[i, 0], linear_momentum[i, 1], linear_momentum[i, 2]
            for s in range(1, n_steps + 1):
                ok, x, y, z, px, py, pz = step_body(
                    method, ortho, dt, i, inv_mass, inv_inertia, force_world, torque_world,
                    quat_wxyz, rotation, angular_momentum, x, y, z, px, py, pz)
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
                        linear_momentum[i, 2])
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
        for i in range(t0, t1):
            sync_quat(method, quat_wxyz, rotation, i)
        if j > n_samples:
            n_samples = j
    return n_samples, bad_step, bad_body
