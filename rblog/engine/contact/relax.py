"""Stage 8 of the contact step: split-impulse position correction (relax).

Position correction by split impulses (Catto 2006; Bullet's split impulse): a second Gauss-Seidel
pass on *pseudo velocities* (v', w') pushes penetrating points apart with target
``vn' = min(beta * (-(s + slop)) / h, max_speed)``; positions move by h (v + v') and the pseudo
velocities are then discarded. Real momenta never see the correction, so it injects neither
momentum nor kinetic energy (the pseudo impulses are also equal and opposite, so the pair's
centre of mass does not move either). C++: csrc/engine/relax.cpp.
"""

from __future__ import annotations

from rblog.engine import _core


def relax_positions(mi, mf, pf, n_man, bm, bI, pv, pw, inv_h, n_iter, slop, beta, max_speed):
    """Split impulses: Gauss-Seidel on pseudo velocities that remove penetration beyond slop."""
    _core.relax_positions(mi, mf, pf, int(n_man), bm, bI, pv, pw, float(inv_h), int(n_iter),
                          float(slop), float(beta), float(max_speed))
