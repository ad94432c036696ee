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
step's solve) wakes after the step. Sleeping bodies keep their manifolds (carried over), so their
resting contacts still appear in the contact log.

The kernels are C++ (csrc/engine/island.cpp: update_sleep, wake_touched, wake_pushed).
"""

from __future__ import annotations
