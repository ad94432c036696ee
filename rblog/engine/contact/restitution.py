"""Stage 10 of the contact step: restitution, the bounce of impact points after positions moved.

Restitution (Box2D v3): after positions are integrated, points that were hit (solve impulse > 0)
while approaching faster than the threshold get a normal velocity set from the approach velocity
measured *before* the solve. rblog sharpens Box2D's rule with the flight's energy: a body that no
contact pushes flies exactly under its constant acceleration (step.py, stage 9), so between
contacts the gap s, its rate w and the relative normal acceleration a of the external forces
(gravity) keep ``E = w^2/2 - a s`` exactly (at every step boundary). The approach speed at
contact is therefore ``u = sqrt(2 E) = sqrt(w0^2 - 2 a s0)`` from the start-of-step gap s0 and
rate w0 (before the kick), and the rebound rate w+ is chosen so that the post-impact state at the
end-of-step gap s1 has energy e^2 E: ``w+^2/2 - a s1 = e^2 u^2/2``, i.e.
``w+ = sqrt(e^2 u^2 + 2 a s1)``. The exact flight after the bounce keeps that energy, so the
apex is e^2 times the drop height: bounce apexes e^(2n) h0 to round-off plus the sampling of the
apex (a rule that ignored the gravity over the step would be ~1% off at dt = 1e-3). Without
external acceleration this is w+ = e |w0|.

C++: csrc/engine/restitution.cpp.
"""

from __future__ import annotations

from rblog.engine import _core


def restitution(mi, mf, pf, n_man, bm, bI, bv, bw, pv, pw, h, threshold, n_iter, dx,
                linear_momentum, angular_momentum):
    """Store the solve's impulses for warm starting, estimate end-of-step gaps, then bounce.

    A point bounces when its solve impulse is positive (it was hit), the gap was closing at the
    start of the step, and its impact speed u exceeds ``threshold``. Returns the number of
    impact points.

    Bounces come after the positions moved (dx: (N+1, 3) each body's displacement this step).
    Between two bodies the impulse is applied at one point that moved with them, the midpoint
    p + (dx_a + dx_b)/2, so that both anchors end at the same point: otherwise the pair's angular
    momentum would change by h (v_a - v_b) x J. The bounce impulses go straight into the momenta
    (P += J, L += r x J), since the orientations have already moved on."""
    return _core.restitution(mi, mf, pf, int(n_man), bm, bI, bv, bw, pv, pw, float(h),
                             float(threshold), int(n_iter), dx, linear_momentum, angular_momentum)
