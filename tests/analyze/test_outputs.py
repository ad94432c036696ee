"""Outputs that mean what they say (issue 30): no negative "worst" without a sign convention, and a
consistency finding whose cause another analyzer explains says so."""

from __future__ import annotations

import numpy as np

from rblog.analyze import check

from test_analyze import bouncing_ball


def _res(traj):
    return {r.analyzer: r for r in check(traj)}


def test_tunneling_worst_is_a_crossing_depth_and_the_closest_approach_a_clearance():
    """Before: "pass tunneling worst -0.0499 m (tol 0 m)", the height of the lowest centre,
    negated. Now the worst is the deepest crossing (>= 0: none here), and the closest approach is
    a positive clearance in the reason: the lowest centre height over the samples (after the
    first), computed here from the logged positions (the ground is z = 0)."""
    traj, _ = bouncing_ball()
    tun = _res(traj)["tunneling"]
    assert tun.passed and tun.worst_value == 0.0
    lowest = float(traj.position[1:, 0, 2].min())
    assert lowest >= 0.1 - 1e-12  # the ball's radius: its centre never gets lower
    assert tun.stats["closest_clearance_m"] == lowest
    assert f"{lowest:.3g} m above the ground" in tun.reason, tun.reason


def test_tunneling_crossing_is_a_positive_depth():
    """The other direction: a frame dropped through the ground is a crossing of positive depth:
    the centre ends 0.05 m below the plane (planted)."""
    traj, t_imp = bouncing_ball()
    k = int(np.searchsorted(traj.t, t_imp[0])) + 1
    traj.position[k, 0, 2] = -0.05
    tun = _res(traj)["tunneling"]
    assert not tun.passed and abs(tun.worst_value - 0.05) < 1e-12
    assert "closest approach" not in tun.reason
