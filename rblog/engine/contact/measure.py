"""Penetration audits: the narrowphase run on a given configuration, nothing else.

``separations`` measures any state (rblog's, or another engine's converted to rblog's model) with
the same geometry code, so penetration statistics of two engines are comparable.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rblog.engine.contact.narrowphase import COLLIDE_TABLE, collide, manifold_part
from rblog.engine.contact.step import BodyState, broadphase, make_scratch
from rblog.engine.contact.collide import pair_geometry


@njit(cache=True)
def _pair_min_separations(bd, st, position, rotation, margin):
    n = position.shape[0]
    ns = st.n_static
    sc = make_scratch(n, st)
    zeros = np.zeros((n, 3))
    x = BodyState(position, zeros, np.zeros((n, 4)), rotation, zeros)  # at rest: boxes unswept
    pairs, n_pairs = broadphase(bd, st, margin, np.zeros(n, np.int64), x, 0.0, sc,
                                np.zeros((max(16, 4 * n), 2), np.int64))
    out = np.empty(n_pairs)
    nrm, pts, sep, fid, work, poly = sc.nrm, sc.pts, sc.sep, sc.fid, sc.work, sc.poly
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
        n1, _ = manifold_part(res, 0)
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


