"""Broadphase: swept AABBs and sort-and-sweep, N log N (the kernels: csrc/engine/broad_phase.cpp).

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

import numpy as np

from rblog.engine import _core
from rblog.engine.contact import narrowphase as _narrowphase  # noqa: F401  (sets the C++ constants)


def body_aabbs(geom, size, radius, inv_mass, inv_inertia, awake, position, linear_momentum,
               rotation, angular_momentum, h, margin, lo, hi, reach):
    """World AABBs of the dynamic bodies (rows 0..N-1 of lo, hi), swept over the step; reach
    (N,) how far any point of a body moves in it. In place."""
    _core.body_aabbs(geom, size, radius, inv_mass, inv_inertia, awake, position, linear_momentum,
                     rotation, angular_momentum, float(h), float(margin), lo, hi, reach)


def static_box_aabbs(position, rotation, half_extents, margin):
    """(lo, hi) of static boxes, grown by half the speculative distance (numpy, once)."""
    ext = np.einsum("mij,mj->mi", np.abs(rotation), half_extents) + 0.5 * margin
    return position - ext, position + ext


def sweep_and_prune(n_items, n_dyn, lo, hi, group, awake, pairs):
    """Candidate pairs (lo id, hi id) among items 0..n_items-1 whose AABBs overlap.

    Skips static-static pairs and pairs in different non-zero groups. Pairs of sleeping bodies
    are emitted too (the collide stage carries their manifolds over). Returns (pairs, count);
    ``pairs`` (K, 2) int64 is written in place, or a new, larger array when it was full."""
    return _core.sweep_and_prune(int(n_items), int(n_dyn), lo, hi, group, awake, pairs)


def ground_pairs(n_dyn, n_static, st, lo, hi, pairs, n_pairs):
    """Append (body, ground) for every body whose padded AABB reaches the plane (``st``: the
    world's Statics, its ground normal ``gn`` and offset ``goff``). Returns (pairs, n_pairs)."""
    return _core.ground_pairs(int(n_dyn), int(n_static), st.gn, float(st.goff), lo, hi, pairs,
                              int(n_pairs))
