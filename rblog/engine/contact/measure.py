"""Penetration audits: the narrowphase run on a given configuration, nothing else.

``separations`` measures any state (rblog's, or another engine's converted to rblog's model) with
the same geometry code, so penetration statistics of two engines are comparable.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rblog.engine.contact.broadphase import body_aabbs, ground_pairs, sweep_and_prune
from rblog.engine.contact.narrowphase import COLLIDE_TABLE, MAX_CLIP_POINTS, collide
from rblog.engine.contact.collide import pair_geometry


@njit(cache=True)
def _pair_min_separations(bd, st, position, rotation, margin):
    n = position.shape[0]
    ns = st.n_static
    lo = np.empty((n + ns, 3))
    hi = np.empty((n + ns, 3))
    for k in range(ns):
        for c in range(3):
            lo[n + k, c] = st.lo[k, c]
            hi[n + k, c] = st.hi[k, c]
    reach = np.zeros(n + ns)
    asleep = np.zeros(n, np.int64)
    zeros = np.zeros((n, 3))
    body_aabbs(bd.geom, bd.size, bd.radius, bd.inv_mass, bd.inv_inertia, asleep, position,
               zeros, rotation, zeros, 0.0, margin, lo, hi, reach)
    pairs = np.zeros((max(16, 4 * n), 2), np.int64)
    pairs, n_pairs = sweep_and_prune(n + ns, n, lo, hi, bd.group, asleep, pairs)
    if st.ground:
        pairs, n_pairs = ground_pairs(n, ns, st, lo, hi, pairs, n_pairs)
    out = np.empty(n_pairs)
    nrm = np.zeros(6)
    pts = np.zeros((MAX_CLIP_POINTS, 3))
    sep = np.zeros(MAX_CLIP_POINTS)
    fid = np.zeros(MAX_CLIP_POINTS, np.int64)
    work = np.zeros(32)
    poly = np.zeros((2, 2 * MAX_CLIP_POINTS, 4))
    count = 0
    for k in range(n_pairs):
        a = pairs[k, 0]
        b = pairs[k, 1]
        gb, cb, rotb, sb = pair_geometry(a, b, n, ns, bd.geom, bd.size, position, rotation,
                                         st.pos, st.rot, st.ext)
        ga = bd.geom[a]
        code = COLLIDE_TABLE[min(ga, gb), max(ga, gb)]
        res = collide(code, ga > gb, position[a], rotation[a], bd.size[a], cb, rotb, sb, st.gn,
                      st.goff, margin, nrm, pts, sep, fid, work, poly)
        n1 = res % 8
        if n1 == 0:
            continue
        # the first manifold holds the pair's separating-axis normal (an edge contact's
        # second, face manifold measures along another direction, conservatively)
        smin = sep[0]
        for q in range(1, n1):
            smin = min(smin, sep[q])
        out[count] = smin
        count += 1
    return out[:count]


def separations(world, position, rotation, margin: float = 0.0) -> np.ndarray:
    """Least separation (m, < 0 penetration) of every touching pair of shapes (bodies, static
    boxes, ground) at this configuration, for the model of ``world`` (a ContactWorld)."""
    position = np.ascontiguousarray(position, float)
    rotation = np.ascontiguousarray(rotation, float)
    return _pair_min_separations(world._bodies, world._statics, position, rotation, float(margin))


def max_penetration(world, position, rotation) -> float:
    """Deepest penetration (m, >= 0) between any two shapes at this configuration."""
    s = separations(world, position, rotation)
    return float(max(0.0, -s.min())) if len(s) else 0.0


