"""Broadphase: swept AABBs and sort-and-sweep, N log N.

Shape ids: dynamic bodies ``0..N-1``, static boxes ``N..N+M-1``, the ground ``N+M``. A pair is
always (lower id, higher id), so a dynamic body is ``a`` and static geometry is ``b``.

Each awake body's box is its world AABB grown by half the speculative distance and swept along
its displacement over the step (``h v``, and ``h |omega| rho`` for rotation, capped at the
bounding sphere): two bodies whose boxes do not overlap cannot come within the speculative
distance during the step. ``reach`` is how far any point of the body can move in the step; the
narrowphase keeps points closer than ``speculative_distance + reach_a + reach_b``.

Collision groups: bodies in different non-zero groups never collide; group 0 collides with
everything, and static geometry (ground, static boxes) collides with every body.

The sweep runs along the axis where the AABB centres spread most; the sort is a stable argsort
(deterministic for a given state).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rblog.engine.contact.narrowphase import GEOM_SPHERE


@njit(cache=True)
def body_aabbs(geom, size, radius, inv_mass, inv_inertia, awake, position, linear_momentum,
               rotation, angular_momentum, h, margin, lo, hi, reach):
    """World AABBs of the dynamic bodies (rows 0..N-1 of lo, hi), swept over the step."""
    n = position.shape[0]
    pad = 0.5 * margin
    for i in range(n):
        if geom[i] == GEOM_SPHERE:
            ex = ey = ez = size[i, 0]
        else:
            r = rotation[i]
            e0, e1, e2 = size[i, 0], size[i, 1], size[i, 2]
            ex = abs(r[0, 0]) * e0 + abs(r[0, 1]) * e1 + abs(r[0, 2]) * e2
            ey = abs(r[1, 0]) * e0 + abs(r[1, 1]) * e1 + abs(r[1, 2]) * e2
            ez = abs(r[2, 0]) * e0 + abs(r[2, 1]) * e1 + abs(r[2, 2]) * e2
        dx = dy = dz = 0.0
        rho = 0.0
        if awake[i]:
            im = inv_mass[i]
            dx = h * linear_momentum[i, 0] * im
            dy = h * linear_momentum[i, 1] * im
            dz = h * linear_momentum[i, 2] * im
            if geom[i] != GEOM_SPHERE:
                # |omega| <= |L| max(1/I): a cheap bound; a rotating box stays in its sphere
                lx, ly, lz = angular_momentum[i, 0], angular_momentum[i, 1], angular_momentum[i, 2]
                wmax = math.sqrt(lx * lx + ly * ly + lz * lz) * max(
                    inv_inertia[i, 0], max(inv_inertia[i, 1], inv_inertia[i, 2]))
                rho = min(h * wmax * radius[i], radius[i])
                ex = min(ex + rho, radius[i])
                ey = min(ey + rho, radius[i])
                ez = min(ez + rho, radius[i])
            reach[i] = math.sqrt(dx * dx + dy * dy + dz * dz) + rho
        else:
            reach[i] = 0.0
        x, y, z = position[i, 0], position[i, 1], position[i, 2]
        lo[i, 0] = x - ex - pad + min(dx, 0.0)
        lo[i, 1] = y - ey - pad + min(dy, 0.0)
        lo[i, 2] = z - ez - pad + min(dz, 0.0)
        hi[i, 0] = x + ex + pad + max(dx, 0.0)
        hi[i, 1] = y + ey + pad + max(dy, 0.0)
        hi[i, 2] = z + ez + pad + max(dz, 0.0)


def static_box_aabbs(position, rotation, half_extents, margin):
    """(lo, hi) of static boxes, grown by half the speculative distance (numpy, once)."""
    ext = np.einsum("mij,mj->mi", np.abs(rotation), half_extents) + 0.5 * margin
    return position - ext, position + ext


@njit(cache=True)
def _grow_pairs(pairs):
    out = np.empty((2 * pairs.shape[0] + 16, 2), np.int64)
    for k in range(pairs.shape[0]):
        out[k, 0] = pairs[k, 0]
        out[k, 1] = pairs[k, 1]
    return out


@njit(cache=True)
def sweep_and_prune(n_items, n_dyn, lo, hi, group, awake, pairs):
    """Candidate pairs (lo id, hi id) among items 0..n_items-1 whose AABBs overlap.

    Skips static-static pairs and pairs in different non-zero groups. Pairs of sleeping bodies
    are emitted too (the collide stage carries their manifolds over). Returns (pairs, count);
    ``pairs`` is reallocated when full."""
    if n_items < 2:
        return pairs, 0
    # sweep axis: largest spread of the centres
    best_axis = 0
    best_var = -1.0
    for ax in range(3):
        s = 0.0
        s2 = 0.0
        for i in range(n_items):
            c = 0.5 * (lo[i, ax] + hi[i, ax])
            s += c
            s2 += c * c
        var = s2 - s * s / n_items
        if var > best_var:
            best_var = var
            best_axis = ax
    ax1 = (best_axis + 1) % 3
    ax2 = (best_axis + 2) % 3
    keys = np.empty(n_items)
    for i in range(n_items):
        keys[i] = lo[i, best_axis]
    order = np.argsort(keys, kind="mergesort")
    count = 0
    for ii in range(n_items):
        i = order[ii]
        hi_i = hi[i, best_axis]
        for jj in range(ii + 1, n_items):
            j = order[jj]
            # written as "not overlapping" so that a NaN box never pairs with anything
            if not lo[j, best_axis] <= hi_i:
                break
            if i >= n_dyn and j >= n_dyn:
                continue
            if not (lo[j, ax1] <= hi[i, ax1] and lo[i, ax1] <= hi[j, ax1]):
                continue
            if not (lo[j, ax2] <= hi[i, ax2] and lo[i, ax2] <= hi[j, ax2]):
                continue
            a = min(i, j)
            b = max(i, j)
            if b < n_dyn:
                ga = group[a]
                gb = group[b]
                if ga != 0 and gb != 0 and ga != gb:
                    continue
            if count == pairs.shape[0]:
                pairs = _grow_pairs(pairs)
            pairs[count, 0] = a
            pairs[count, 1] = b
            count += 1
    return pairs, count


@njit(cache=True)
def ground_pairs(n_dyn, n_static, st, lo, hi, pairs, n_pairs):
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
