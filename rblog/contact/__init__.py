"""Collisions and resting contact: broadphase, narrowphase table, sequential-impulse solver.

Modules, one per stage (Box2D v3's file split): ``params`` (every tolerance), ``broadphase``
(swept AABBs, sort-and-sweep), ``narrowphase`` (colliders and the shape-pair table),
``collide`` (manifolds and warm-start matching), ``solver`` (prepare, warm start, solve, relax,
restitution, store), ``island`` (sleeping), ``step`` (the compiled world step), ``world``
(:class:`ContactWorld`, what the simulator calls), ``measure`` (penetration audits).
"""

from .params import ContactParams
from .world import ContactWorld

__all__ = ["ContactParams", "ContactWorld"]
