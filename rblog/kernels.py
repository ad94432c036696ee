"""Compiled kernels that advance free bodies (no contacts) many steps per call.

Bodies are independent without contacts, so the loop runs over tiles of BODY_TILE bodies, steps
inside a tile: the tile's state stays in L1 for the whole block, and samples are written for
consecutive bodies. The stages of one step, per integrator:

* ``seed`` / ``seed-quat`` (the lecture notes): P += h F; x += h P/m; L += h tau; rotate.
* ``splitting``: kick half (P, L), drift (x += h P/m, exact-axis-rotation splitting), kick half.
* ``rk4``: x, P exactly for a constant force (RK4 is exact there); RK4 on (q, L) with L(t) = L + t tau.

Samples are written after every ``stride``-th step (and after the last step of the block when
``sample_last``), so logging costs nothing between samples.
"""

from __future__ import annotations

import math

from numba import njit

from .rotation import (
    METHOD_RK4,
    METHOD_SEED,
    METHOD_SPLITTING,
    drift_rk4,
    drift_seed,
    drift_seed_quat,
    drift_splitting,
    sync_quat,
)


#: bodies advanced together, steps inner: their state (~180 B each) stays in L1, and a sample's
#: writes for consecutive bodies share cache lines (a bodies-outer loop wrote each body's samples
#: a whole sample-row apart: one cache miss per channel per sample).
BODY_TILE = 32
#: ... but when samples are this many steps apart or more, the write pattern does not matter and
#: one body at a time (its position and momentum in registers for the whole block) is faster.
SPARSE_STRIDE = 8


@njit(inline="always")
def _step_body(method, ortho, dt, i, inv_mass, inv_inertia, force_world, torque_world,
               quat_wxyz, rotation, angular_momentum, x, y, z, px, py, pz):
    """One step of body i: orientation and L in place, position (x, y, z) and momentum
    (px, py, pz) passed and returned as scalars (so a caller may keep them in registers).
    Returns (ok, x, y, z, px, py, pz); ok is False if the state became non-finite."""
    im = inv_mass[i]
    fx, fy, fz = force_world[i, 0], force_world[i, 1], force_world[i, 2]
    tx, ty, tz = torque_world[i, 0], torque_world[i, 1], torque_world[i, 2]
    if method == METHOD_SPLITTING:
        # kick half, drift, kick half
        hh = 0.5 * dt
        px += hh * fx
        py += hh * fy
        pz += hh * fz
        angular_momentum[i, 0] += hh * tx
        angular_momentum[i, 1] += hh * ty
        angular_momentum[i, 2] += hh * tz
        x += dt * px * im
        y += dt * py * im
        z += dt * pz * im
        drift_splitting(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, dt)
        px += hh * fx
        py += hh * fy
        pz += hh * fz
        angular_momentum[i, 0] += hh * tx
        angular_momentum[i, 1] += hh * ty
        angular_momentum[i, 2] += hh * tz
    elif method == METHOD_RK4:
        # translation: exact for a constant force; rotation: RK4 with L(t) = L + t tau
        hh = 0.5 * dt * dt * im
        x += dt * px * im + hh * fx
        y += dt * py * im + hh * fy
        z += dt * pz * im + hh * fz
        px += dt * fx
        py += dt * fy
        pz += dt * fz
        drift_rk4(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, dt, tx, ty, tz)
        angular_momentum[i, 0] += dt * tx
        angular_momentum[i, 1] += dt * ty
        angular_momentum[i, 2] += dt * tz
    else:
        # the notes: forward Euler on P and L, then x and R from the new values
        px += dt * fx
        py += dt * fy
        pz += dt * fz
        x += dt * px * im
        y += dt * py * im
        z += dt * pz * im
        angular_momentum[i, 0] += dt * tx
        angular_momentum[i, 1] += dt * ty
        angular_momentum[i, 2] += dt * tz
        if method == METHOD_SEED:
            drift_seed(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, dt)
        else:
            drift_seed_quat(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, dt)
    # non-finite check: one sum covers position, momenta and part of the rotation
    chk = (x + y + z + px + py + pz + angular_momentum[i, 0] + angular_momentum[i, 1]
           + angular_momentum[i, 2] + rotation[i, 0, 0] + rotation[i, 1, 1] + rotation[i, 2, 2]
           + rotation[i, 0, 1])
    return math.isfinite(chk), x, y, z, px, py, pz


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
                ok, x, y, z, px, py, pz = _step_body(
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
                    ok, x, y, z, px, py, pz = _step_body(
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


@njit(cache=True, nogil=True)
def derive_channels(mass, inv_inertia, gravity, position, linear_momentum, quat_wxyz, rotation,
                    angular_momentum, velocity, omega, e_trans, e_rot, e_pot, ortho, qnorm,
                    total_p, total_l, total_e):
    """Derived channels of T samples x N bodies (see trajectory.derive), written into the outputs.

    omega = R diag(inv_inertia) R^T L with the logged R; e_pot = -m g.x; ortho = ||R^T R - I||_F;
    qnorm = |q| - 1. Totals per sample: total_p (T, 3) = sum P, total_l (T, 3) = sum x cross P + L
    (about the world origin), total_e (T,) = sum of the three energies. Inputs (T, N, ...) float64
    C-contiguous; outputs preallocated alike.
    """
    n_t, n_b = position.shape[0], position.shape[1]
    for t in range(n_t):
        sp0 = sp1 = sp2 = sl0 = sl1 = sl2 = se = 0.0
        for i in range(n_b):
            m = mass[i]
            px, py, pz = linear_momentum[t, i, 0], linear_momentum[t, i, 1], linear_momentum[t, i, 2]
            velocity[t, i, 0] = px / m
            velocity[t, i, 1] = py / m
            velocity[t, i, 2] = pz / m
            e_trans[t, i] = 0.5 * (px * px + py * py + pz * pz) / m
            e_pot[t, i] = -m * (gravity[0] * position[t, i, 0] + gravity[1] * position[t, i, 1]
                                + gravity[2] * position[t, i, 2])
            r = rotation[t, i]
            lx, ly, lz = angular_momentum[t, i, 0], angular_momentum[t, i, 1], angular_momentum[t, i, 2]
            b0 = (r[0, 0] * lx + r[1, 0] * ly + r[2, 0] * lz) * inv_inertia[i, 0]
            b1 = (r[0, 1] * lx + r[1, 1] * ly + r[2, 1] * lz) * inv_inertia[i, 1]
            b2 = (r[0, 2] * lx + r[1, 2] * ly + r[2, 2] * lz) * inv_inertia[i, 2]
            ox = r[0, 0] * b0 + r[0, 1] * b1 + r[0, 2] * b2
            oy = r[1, 0] * b0 + r[1, 1] * b1 + r[1, 2] * b2
            oz = r[2, 0] * b0 + r[2, 1] * b1 + r[2, 2] * b2
            omega[t, i, 0] = ox
            omega[t, i, 1] = oy
            omega[t, i, 2] = oz
            e_rot[t, i] = 0.5 * (lx * ox + ly * oy + lz * oz)
            acc = 0.0
            for a in range(3):
                for b in range(3):
                    g = r[0, a] * r[0, b] + r[1, a] * r[1, b] + r[2, a] * r[2, b]
                    if a == b:
                        g -= 1.0
                    acc += g * g
            ortho[t, i] = math.sqrt(acc)
            q = quat_wxyz[t, i]
            qnorm[t, i] = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]) - 1.0
            x0, x1, x2 = position[t, i, 0], position[t, i, 1], position[t, i, 2]
            sp0 += px
            sp1 += py
            sp2 += pz
            sl0 += x1 * pz - x2 * py + lx
            sl1 += x2 * px - x0 * pz + ly
            sl2 += x0 * py - x1 * px + lz
            se += e_trans[t, i] + e_rot[t, i] + e_pot[t, i]
        total_p[t, 0] = sp0
        total_p[t, 1] = sp1
        total_p[t, 2] = sp2
        total_l[t, 0] = sl0
        total_l[t, 1] = sl1
        total_l[t, 2] = sl2
        total_e[t] = se
