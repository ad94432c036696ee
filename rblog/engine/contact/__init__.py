"""Collisions and resting contact: broadphase, narrowphase table, sequential-impulse solver.

Modules, one per stage of the step (Box2D v3's file split; every tolerance is in
rblog.engine.constants):

* ``world``: :class:`ContactWorld`, what the run loop calls; builds the model records.
* ``step``: the compiled world step, a flat list of named stages over those records.
* ``broadphase``: swept AABBs, sort-and-sweep, ground pairs (stage 2).
* ``narrowphase``: the shape-pair collider table and the simple colliders; ``box_box``: the
  separating-axis box-box collider; ``manifold``: the contact records' dtypes.
* ``collide``: manifolds and warm-start matching (stage 4).
* the solver's stages are C++ only (csrc/engine/contact_solver.cpp: prepare, warm start,
  velocity solve with friction, store (5-7, 11); relax.cpp: split impulses (8); restitution.cpp:
  the bounce (10)), called one by one from Python through ``rblog.engine._core`` in the tests.
* the project stage is C++ only too (csrc/engine/project.cpp: nonlinear position projection of
  deep points (12)); ``island``: sleeping (3, 13).
* ``measure``: penetration audits with the engine's own geometry (benchmarks, tests).
"""

from rblog.engine.constants import ContactParams
from rblog.engine.contact.world import ContactWorld

__all__ = ["ContactParams", "ContactWorld"]
