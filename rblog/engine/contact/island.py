"""Sleeping: islands of touching bodies at rest stop being simulated until touched (Box2D's
``island.c`` / ``solver_set.c``, with union-find islands rebuilt each step).

A body is *resting* while its speed (the larger of |v| and |omega| * bounding radius) stays
below ``sleep_speed``; its timer counts how long. An island is a connected set of awake bodies
linked by touching manifolds (a point with a positive impulse or a closed gap). An island goes to
sleep when every member has rested for ``sleep_time`` and it touches something (the ground, a
static box, a sleeping body, or another body): its momenta are zeroed and the step skips it.

An awake body wakes a sleeping island when its motion (before this step's force kick) can close
the gap to a member within the step; the island's bodies then get this step's kick and rejoin the
solve. A sleeping body that an awake one pushes on anyway (it stood in as a static body in this
step's solve) wakes after the step. Sleeping bodies keep their manifolds (carried over), so their resting contacts still
appear in the contact log.
"""

from __future__ import annotations

import math

from numba import njit

from rblog.engine.contact.manifold import (
    MF_N, MI_A, MI_ACTIVE, MI_B, MI_COUNT, MI_REC_A, MI_REC_B, MI_START, PF_F, PF_LN, PF_LWS, PF_P,
    PF_SEND,
)
from rblog.engine.contact.narrowphase import collide
from rblog.engine.contact.collide import pair_geometry
from rblog.engine.contact.narrowphase import COLLIDE_TABLE


@njit(cache=True)
def find_root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True)
def update_sleep(n_dyn, mi, pf, n_man, awake, sleep_timer, island_of, island_counter,
                 linear_momentum, angular_momentum, inv_mass, inv_inertia, radius, h,
                 sleep_speed, sleep_time, parent, island_min_time, island_supported):
    """Advance rest timers, build islands, put islands at rest to sleep. Returns how many
    bodies fell asleep."""
    for i in range(n_dyn):
        parent[i] = i
        island_supported[i] = 0
        island_min_time[i] = math.inf
        if not awake[i]:
            continue
        im = inv_mass[i]
        px, py, pz = linear_momentum[i, 0], linear_momentum[i, 1], linear_momentum[i, 2]
        v = math.sqrt(px * px + py * py + pz * pz) * im
        lx, ly, lz = angular_momentum[i, 0], angular_momentum[i, 1], angular_momentum[i, 2]
        w = math.sqrt(lx * lx + ly * ly + lz * lz) * max(
            inv_inertia[i, 0], max(inv_inertia[i, 1], inv_inertia[i, 2]))
        speed = max(v, w * radius[i])
        if speed < sleep_speed:
            sleep_timer[i] += h
        else:
            sleep_timer[i] = 0.0
    # islands: union the bodies of touching manifolds
    any_ready = False
    for i in range(n_dyn):
        if awake[i] and sleep_timer[i] >= sleep_time:
            any_ready = True
            break
    if not any_ready:
        return 0
    for m in range(n_man):
        if not mi[m, MI_ACTIVE]:
            continue
        touching = False
        start = mi[m, MI_START]
        for p in range(start, start + mi[m, MI_COUNT]):
            if pf[p, PF_LWS] > 0.0 or pf[p, PF_SEND] <= 0.0:
                touching = True
                break
        if not touching:
            continue
        a = mi[m, MI_A]
        b = mi[m, MI_B]
        if a < n_dyn:
            island_supported[a] = 1
        if b < n_dyn:
            island_supported[b] = 1
        if a < n_dyn and b < n_dyn:
            ra = find_root(parent, a)
            rb = find_root(parent, b)
            if ra != rb:
                parent[max(ra, rb)] = min(ra, rb)
    for i in range(n_dyn):
        if not awake[i]:
            continue
        r = find_root(parent, i)
        island_min_time[r] = min(island_min_time[r], sleep_timer[i])
        if island_supported[i]:
            island_supported[r] = 1
    n_slept = 0
    base = island_counter[0]
    for i in range(n_dyn):
        if not awake[i]:
            continue
        r = find_root(parent, i)
        if island_min_time[r] >= sleep_time and island_supported[r]:
            awake[i] = 0
            island_of[i] = base + r
            for k in range(3):
                linear_momentum[i, k] = 0.0
                angular_momentum[i, k] = 0.0
            n_slept += 1
    island_counter[0] = base + n_dyn
    return n_slept


@njit(cache=True)
def wake_island(island, n_dyn, awake, sleep_timer, island_of, linear_momentum,
                angular_momentum, force, torque, h, do_kick):
    """Wake every body of a sleeping island, giving it this step's force kick."""
    for j in range(n_dyn):
        if awake[j] or island_of[j] != island:
            continue
        awake[j] = 1
        sleep_timer[j] = 0.0
        island_of[j] = -1
        if do_kick:
            for k in range(3):
                linear_momentum[j, k] += h * force[j, k]
                angular_momentum[j, k] += h * torque[j, k]


@njit(cache=True)
def wake_touched(pairs, n_pairs, n_dyn, n_static, geom, size, awake, sleep_timer, island_of,
                 position, rotation, reach, margin, slop, sb_pos, sb_rot, sb_ext, gn, goff,
                 linear_momentum, angular_momentum, force, torque, h, do_kick,
                 nrm, pts, sep, fid, work, poly, inv_mass, accel, radius, inv_inertia):
    """Wake the sleeping islands that an awake body will reach within this step, by its motion
    before this step's force kick (a body resting beside a sleeper does not wake it; one that
    pushes on it wakes it after the solve, see wake_pushed). Returns the islands woken."""
    n_woken = 0
    for k in range(n_pairs):
        a = pairs[k, 0]
        b = pairs[k, 1]
        if b >= n_dyn:
            continue
        if (awake[a] != 0) == (awake[b] != 0):
            continue
        sleeper = b if awake[a] else a
        mover = a if awake[a] else b
        im = inv_mass[mover]
        vx = linear_momentum[mover, 0] * im
        vy = linear_momentum[mover, 1] * im
        vz = linear_momentum[mover, 2] * im
        if do_kick:
            vx -= h * accel[mover, 0]
            vy -= h * accel[mover, 1]
            vz -= h * accel[mover, 2]
        lx, ly, lz = (angular_momentum[mover, 0], angular_momentum[mover, 1],
                      angular_momentum[mover, 2])
        wmax = math.sqrt(lx * lx + ly * ly + lz * lz) * max(
            inv_inertia[mover, 0], max(inv_inertia[mover, 1], inv_inertia[mover, 2]))
        close = h * (math.sqrt(vx * vx + vy * vy + vz * vz) + wmax * radius[mover])
        if close <= slop:
            # a (nearly) resting neighbour: if it does push, wake_pushed wakes the island
            continue
        gb, cb, rotb, sb = pair_geometry(a, b, n_dyn, n_static, geom, size, position, rotation,
                                         sb_pos, sb_rot, sb_ext)
        ga = geom[a]
        code = COLLIDE_TABLE[min(ga, gb), max(ga, gb)]
        spec = margin + reach[a] + reach[b]
        res = collide(code, ga > gb, position[a], rotation[a], size[a], cb, rotb, sb, gn, goff,
                      spec, nrm, pts, sep, fid, work, poly)
        for q in range(8):
            if (q < 4 and q >= res % 8) or (q >= 4 and q - 4 >= res // 8):
                continue
            if sep[q] < close:
                n_woken += 1
                wake_island(island_of[sleeper], n_dyn, awake, sleep_timer, island_of,
                            linear_momentum, angular_momentum, force, torque, h, do_kick)
                break
    return n_woken


@njit(cache=True)
def wake_pushed(mi, mf, pf, n_man, n_dyn, awake, sleep_timer, island_of, position,
                linear_momentum, angular_momentum, force, torque, h):
    """Wake the sleeping islands that an awake body pushed on in this step's solve. Returns the
    islands woken.

    A sleeper stood in as static in this step's solve (solver index = the static dummy), so the
    impulses its awake neighbours received from it were applied to them alone. Each is handed to
    the sleeper now, equal and opposite at the same contact point: J on body a is
    ``lambda_n n + f`` (normal impulse, world friction impulse), the sleeper gets -J if it is b
    (+J if a) into P, and (p - x) x (-J) into L. Linear momentum and angular momentum about any
    point are then conserved exactly, as between two awake bodies; from the next step on the
    island moves (no kick now: it joins the next step's)."""
    n_woken = 0
    for m in range(n_man):
        if not mi[m, MI_ACTIVE]:
            continue
        a = mi[m, MI_REC_A]
        b = mi[m, MI_REC_B]
        sleeper = -1
        sign = 0.0
        if mi[m, MI_A] == n_dyn and a >= 0:
            sleeper, sign = a, 1.0
        elif b >= 0 and mi[m, MI_B] == n_dyn:
            sleeper, sign = b, -1.0
        if sleeper < 0:
            continue
        pushed = False
        nx, ny, nz = mf[m, MF_N], mf[m, MF_N + 1], mf[m, MF_N + 2]
        start = mi[m, MI_START]
        for p in range(start, start + mi[m, MI_COUNT]):
            ln = pf[p, PF_LN]
            if ln <= 0.0:
                continue
            pushed = True
            jx = sign * (ln * nx + pf[p, PF_F])
            jy = sign * (ln * ny + pf[p, PF_F + 1])
            jz = sign * (ln * nz + pf[p, PF_F + 2])
            rx = pf[p, PF_P] - position[sleeper, 0]
            ry = pf[p, PF_P + 1] - position[sleeper, 1]
            rz = pf[p, PF_P + 2] - position[sleeper, 2]
            linear_momentum[sleeper, 0] += jx
            linear_momentum[sleeper, 1] += jy
            linear_momentum[sleeper, 2] += jz
            angular_momentum[sleeper, 0] += ry * jz - rz * jy
            angular_momentum[sleeper, 1] += rz * jx - rx * jz
            angular_momentum[sleeper, 2] += rx * jy - ry * jx
        if pushed and not awake[sleeper]:
            n_woken += 1
            wake_island(island_of[sleeper], n_dyn, awake, sleep_timer, island_of,
                        linear_momentum, angular_momentum, force, torque, h, False)
    return n_woken
