"""Collide stage: narrowphase over the candidate pairs into manifold records, with warm starting.

For each candidate pair (lower shape id a, higher id b):

* neither side awake (sleeping or static): the previous step's manifold is carried over
  unchanged (inactive: not solved, still logged);
* otherwise the collider from the narrowphase table runs with a speculative distance of
  ``margin + reach_a + reach_b``; each new point takes over the impulses of the previous step's
  point with the same feature id (or, failing that, the nearest one within
  ``anchor_distance``), normal impulse as is and friction projected on the new tangents;
* the manifold keeps its friction anchor, the pose of a in b's frame when the pair started
  sticking (contact_solver.cpp, "Friction anchor"), whatever its points do (a one-point contact that
  becomes a face keeps it), and every point gets its drift from it: where a's material point at
  the contact is now, minus where the anchor pose puts it (a sphere's pair, which rolls, has
  none).

Materials combine as restitution max(e_a, e_b) and friction sqrt(mu_a mu_b) (the analyzers use
the same rule).

The stage is C++ (csrc/engine/collide.cpp, collide_pairs); this module keeps its documentation
and :func:`tangent_basis` for Python callers.
"""

from __future__ import annotations

from rblog.engine import _core


def tangent_basis(nx, ny, nz):
    """Unit t1, t2 with (t1, t2, n) right-handed, a deterministic function of n (so the basis,
    and warm starting, stay put while the normal does): (t1x, t1y, t1z, t2x, t2y, t2z)."""
    return _core.tangent_basis(float(nx), float(ny), float(nz))
