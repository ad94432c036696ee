"""Project stage: a nonlinear (NGS) position pass on fresh contact geometry after the drift.

The velocity solve works on the manifolds of the start of the step and their first-order gap
rates. A box that tumbles or is struck hard within the step can bring a feature into contact
that none of those manifolds holds: a corner swinging over the edge of the box below, an
incident edge sliding past the rim of a reference face (the deepest point then lies on a clip
point that did not exist at the start), or a pair whose clipped face was empty at the start.
Such a feature is unconstrained for the step and ends it up to ~|v| h deep (1 mm at 1 m/s and
dt = 1 ms in the 500-box pile).

This stage runs the narrowphase again at the end-of-step configuration, first with a *negative*
speculative distance ``-depth``, so only points deeper than ``depth`` come back (the separating
axis test rejects every other pair on its first axis, which keeps the pass cheap). Around the
bodies of those points it gathers every contact of the bodies and of their neighbours (two
rings, see project_positions), and pushes all gathered points to ``s >= -depth`` by
Gauss-Seidel on position-level impulses (Box2D v2's ``SolvePositionConstraints``, Catto's
"nonlinear Gauss-Seidel", on fresh geometry). The neighbours hold: a body pushed out of one
overlap is not pushed into the body under it. Per point k, per sweep::

    lambda_k += max(-(s_k + n . (dx_a + dth_a x r_a - dx_b - dth_b x r_b) + depth) / K_k, -lambda_k)
    dx_a += m_a^-1 lambda n,  dth_a += I_a^-1 (r_a x lambda n)   (b gets the negatives)

with K_k the point's effective inverse mass (as in the velocity solve), clamped accumulated
``lambda >= 0`` (pushes only). There is no cap on the push per step (unlike the split
impulses' ``max_correction_speed``): an overlap that a step made is undone in that step, up to
the ~2 mm that a box struck at 2 m/s can make in 1 ms; a scene that starts with overlaps has
them pushed out to ``depth`` in its first step, without any velocity.

Only positions and orientations move; the momenta P and L are untouched (but for the hand-back
below), so the pass injects no momentum, and no kinetic energy into isotropic bodies (for
others the turned inertia changes the spin energy by O(|dth|) of it, as the split-impulse
pseudo spin does); the next step's contacts, at the corrected depth, stop the approach. The
pair's impulses are equal and opposite at one point, so its centre of mass stays put; the
world step hands the orbital change ``dx x P`` back to the spin, as after the split-impulse
shift, so that ``sum(x x P + L)`` stays exact.

Shapes and frames: ``pairs`` (K, 2) shape ids (bodies, static boxes, ground; see broadphase),
``position`` (N, 3) and ``rotation`` (N, 3, 3) body -> world at the end of the step;
corrections ``dx`` and ``dth`` are (N+1, 3) world displacements and rotation vectors (row N:
the static dummy, which stands for static geometry and sleeping bodies and never moves).

C++: csrc/engine/project.cpp.
"""

from __future__ import annotations

from rblog.engine import _core
from rblog.engine.constants import PROJECTION_RINGS
from rblog.engine.contact import narrowphase as _narrowphase  # noqa: F401  (sets the C++ constants)

#: columns of the point rows the world step allocates for this stage (project.hpp's PJ_*)
PROJ_COLS = _core.PROJ_COLS


def project_positions(pairs, n_pairs, n_dyn, n_static, geom, size, inv_mass, inv_inertia, iso,
                      iso_shortcut, awake, position, rotation, sb_pos, sb_rot, sb_ext, gn, goff,
                      depth, n_iter, rows, ids, dx, dth):
    """Find the bodies with points deeper than ``depth``, gather the contacts around them (the
    bodies' and their neighbours', PROJECTION_RINGS rings), and Gauss-Seidel every gathered
    point to ``s >= -depth``.

    ``rows`` (R, PROJ_COLS) / ``ids`` (R, 2) are scratch point rows (copied, grown when full);
    ``dx``/``dth`` (N+1, 3) receive each body's correction (zeroed here for the bodies of the
    gathered points; read them only for those). Returns (number of gathered points, rows, ids);
    the number is 0 when nothing is deeper than ``depth``.
    """
    return _core.project_positions(pairs, int(n_pairs), int(n_dyn), int(n_static), geom, size,
                                   inv_mass, inv_inertia, iso, bool(iso_shortcut), awake,
                                   position, rotation, sb_pos, sb_rot, sb_ext, gn, float(goff),
                                   float(depth), int(n_iter), rows, ids, dx, dth,
                                   int(PROJECTION_RINGS))


def apply_projection(n_deep, ids, dx, dth, n, method, ortho, bd, iso_shortcut, position,
                     rotation, quat_wxyz, linear_momentum, angular_momentum, l_scratch,
                     anchor_steps):
    """Move the bodies of the project stage's points by their corrections: x += dx, the
    orientation by the rotation vector dth (through the run's integrator: a drift of unit
    duration with L = I_world dth), and L -= dx x P so that sum(x x P + L) stays exact. A moved
    body's exact-flow anchor is dropped (anchor_steps -1, see rblog.engine.state.FlowAnchors)."""
    _core.apply_projection(int(n_deep), ids, dx, dth, int(n), int(method), int(ortho), bd,
                           bool(iso_shortcut), position, rotation, quat_wxyz, linear_momentum,
                           angular_momentum, l_scratch, anchor_steps)
