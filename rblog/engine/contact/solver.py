"""Contact solver: sequential impulses (projected Gauss-Seidel) with accumulated-impulse clamping.

Stages, in the order the world step calls them (Box2D v3's ``b2SolverStage``):
``prepare_contacts`` (bodies loaded first) -> ``warm_start`` -> ``solve_velocities`` ->
``anchor_friction`` (with ContactParams.static_friction_anchors) -> ``relax_positions`` (split
impulses) -> [integrate positions, in step.py] -> ``restitution`` -> [project: fresh narrowphase
and nonlinear position pass, in project.py].

The stages are C++ (csrc/engine/contact_solver.cpp, whose header comment holds the derivations:
the gap velocity and effective mass, Coulomb friction by maximum dissipation, over-relaxation,
speculative targets, the friction anchor). These functions call them one by one (the tests
test them so); the tolerances they read (FRICTION_NEWTON_ITERS, FRICTION_NEWTON_TOL, BLOCK_REG,
FRICTION_ANCHOR_RATE, FRICTION_ANCHOR_SLIDE_FRAC) come from rblog.engine.constants, their one home,
at each call (the world step passes them through its Settings record).

Position correction by split impulses (stage 8) is in :mod:`rblog.engine.contact.relax`.
Restitution (the bounce after positions moved) is in :mod:`rblog.engine.contact.restitution`.
"""

from __future__ import annotations

from rblog.engine import _core
from rblog.engine import constants as _c


def prepare_contacts(mi, mf, pf, n_man, bm, bI, bv, bw, h):
    """Effective masses, and the gap velocity before the step (for restitution)."""
    _core.prepare_contacts(mi, mf, pf, int(n_man), bm, bI, bv, bw, float(h),
                           float(_c.FRICTION_ANCHOR_RATE), float(_c.BLOCK_REG))


def warm_start(mi, mf, pf, n_man, bm, bI, bv, bw):
    """Apply the impulses carried over from the previous step."""
    _core.warm_start(mi, mf, pf, int(n_man), bm, bI, bv, bw)


def solve_velocities(mi, mf, pf, n_man, bm, bI, bv, bw, inv_h, min_iter, max_iter, tol, hot,
                     degree, sor):
    """Sequential impulses: per manifold, the normal rows, then friction (Box2D v3 order), at
    least ``min_iter`` sweeps, then until the largest velocity change is below ``tol`` (m/s), at
    most ``max_iter``; normal increments over-relaxed by ``sor`` where a body touches more than
    one thing (``degree``); the manifolds in the order of their constraint-graph colouring
    (csrc/engine/constraint_graph.hpp). Returns the full-sweep equivalents (at least 1)."""
    return _core.solve_velocities(mi, mf, pf, int(n_man), bm, bI, bv, bw, float(inv_h),
                                  int(min_iter), int(max_iter), float(tol), hot, degree,
                                  float(sor), int(_c.FRICTION_NEWTON_ITERS),
                                  float(_c.FRICTION_NEWTON_TOL))


def anchor_friction(mi, mf, pf, n_man, bm, bI, bv, bw):
    """The anchor pass (after the velocity solve, before relax): one Gauss-Seidel sweep of the
    friction rows of loaded points with the anchors' targets (slip rate -FRICTION_ANCHOR_RATE D
    / h, clamped to the Coulomb disc)."""
    _core.anchor_friction(mi, mf, pf, int(n_man), bm, bI, bv, bw,
                          int(_c.FRICTION_NEWTON_ITERS), float(_c.FRICTION_NEWTON_TOL))


def store_impulses(mi, mf, pf, n_man):
    """Friction impulses as world vectors, so the next step can project them on its tangents;
    a manifold keeps its friction anchor while some loaded point sticks (friction strictly inside
    its cone): an impact, or a manifold none of whose points sticks, drops it."""
    _core.store_impulses(mi, mf, pf, int(n_man), float(_c.FRICTION_ANCHOR_SLIDE_FRAC))
