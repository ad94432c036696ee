"""Collisions and resting contact: broadphase, narrowphase table, sequential-impulse solver.

Modules, one per stage (Box2D v3's file split; every tolerance is in rblog.engine.constants): ``broadphase``
(swept AABBs, sort-and-sweep), ``narrowphase`` (colliders and the shape-pair table),
``collide`` (manifolds and warm-start matching), ``solver`` (prepare, warm start, solve, relax,
restitution, store), ``island`` (sleeping), ``step`` (the compiled world step), ``world``
(:class:`ContactWorld`, what the simulator calls), ``measure`` (penetration audits).
"""

from rblog.engine.constants import ContactParams
from rblog.engine.contact.world import ContactWorld

__all__ = ["ContactParams", "ContactWorld"]
