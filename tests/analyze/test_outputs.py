"""Outputs that mean what they say (issue 30): no negative "worst" without a sign convention, and a
consistency finding whose cause another analyzer explains says so."""

from __future__ import annotations

import numpy as np
import pytest

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


def _polar(r):
    """The rotation nearest r (…, 3, 3): U V^T of its SVD (independent of the analyzer's)."""
    u, _, vt = np.linalg.svd(r)
    return u @ vt


def _seed_without_orthonormalization(spin=None, duration=None):
    """rblog's notes scheme without orthonormalization on the tumbling box at dt = 10 ms (issue
    30's run: ||R^T R - I||_F reaches 1.63 in 20 s); ``spin``: its body-frame omega_y (rad/s,
    2 in the sample) and ``duration`` (s) instead of the sample's."""
    import rblog
    from rblog.engine.scene import parse_scene

    text = (REPO / "samples" / "tumbling_box.toml").read_text()
    if spin is not None:
        text = text.replace("angular_velocity_body = [0.05, 2.0, 0.05]",
                            f"angular_velocity_body = [0.05, {spin!r}, 0.05]")
    if duration is not None:
        text = text.replace("duration = 20.0", f"duration = {duration!r}")
    traj, _ = rblog.simulate(parse_scene(text), integrator="seed", orthonormalize="none", dt=0.01)
    return traj


REPO = __import__("pathlib").Path(__file__).resolve().parents[2]


def test_consistency_names_a_stretched_rotation_not_a_logging_bug():
    """Before: "angular_velocity does not turn the logged orientation (wrong frame, sign, unit
    ...)" for a run whose only fault is the stretched R the drift analyzer reports. The box spun
    at 4 rad/s for 9 s (R stretched by up to 5.35; the analyzer's median for R itself 0.110):
    issue 30's run at 2 rad/s (stretch 1.63) turns within the kinematic check's correction
    allowance (1e-3 rad per interval on top of the relative mismatch: median 0.076), so it makes
    no kinematic finding to explain. Measured here independently: the rotation part of R (polar
    factor, numpy SVD) turns at the logged world angular velocity to a median relative mismatch
    of 7.4e-3 (scipy's rotation vectors of P(k+1) P(k)^T / dt against the mean logged w)."""
    from scipy.spatial.transform import Rotation

    traj = _seed_without_orthonormalization(spin=4.0, duration=9.0)
    rot = np.asarray(traj.rotation)[:, 0]
    stretch = np.linalg.norm(np.swapaxes(rot, -1, -2) @ rot - np.eye(3), axis=(-2, -1)).max()
    assert stretch > 5.0  # measured 5.35
    p = _polar(rot)
    rate = Rotation.from_matrix(p[1:] @ np.swapaxes(p[:-1], -1, -2)).as_rotvec() / np.diff(traj.t)[:, None]
    w = np.asarray(traj.angular_velocity)[:, 0]
    mean_w = 0.5 * (w[1:] + w[:-1])
    mismatch = np.median(np.linalg.norm(rate - mean_w, axis=1) / np.linalg.norm(mean_w, axis=1))
    # measured 7.4e-3 (the midpoint rule's (|w| dt)^2): the rotation part is not a logging fault
    assert mismatch < 1e-2
    res = _res(traj)
    assert not res["drift"].passed  # the stretch is drift's finding
    (f,) = [f for f in res["consistency"].findings if "orientation" in f.message]
    assert f.message.startswith("R is not orthonormal") and "see drift" in f.message, f.message
    assert "wrong frame" not in f.message


def test_consistency_still_names_a_logging_bug_under_a_stretched_rotation():
    """The other direction: the same stretched run with the angular velocity logged in the body
    frame (polar(R)^T w: a real logging bug on top of the stretch) is not excused by it."""
    traj = _seed_without_orthonormalization()
    p = _polar(np.asarray(traj.rotation))
    traj.angular_velocity = np.ascontiguousarray(
        np.einsum("tnji,tnj->tni", p, np.asarray(traj.angular_velocity)))
    msgs = [f.message for f in _res(traj)["consistency"].findings if "orientation" in f.message]
    assert msgs and "turns at angular_velocity (median" not in msgs[0], msgs


def test_drift_growth_is_described_by_the_better_fit():
    """Issue 31: the drift finding quoted an "e-folding rate" for a drift that grows linearly.
    R scaled by (1 + eps t): ||R^T R - I||_F = sqrt(3) ((1 + eps t)^2 - 1), linear to 1e-3 over
    the 3 s (eps = 1e-3): "growing linearly", no e-folding rate. R scaled by exp(2 t): det R - 1 =
    exp(6 t) - 1 (the worst metric against its tolerance) grows exponentially; its e-folding rate
    tends to 6/s (d/dt log(exp(6 t) - 1) = 6 / (1 - exp(-6 t)), 6.00 at t > 1 s)."""
    from test_analyze import symmetric_top

    d = _res_only(symmetric_top(stretch=lambda t: 1 + 1e-3 * t))
    msg = d.findings[0].message
    assert "growing linearly" in msg and "e-folding" not in msg, msg
    assert d.stats["worst_growth_exponential"] == 0.0
    d = _res_only(symmetric_top(stretch=lambda t: np.exp(2.0 * t)))
    msg = d.findings[0].message
    assert "growing exponentially (e-folding rate" in msg, msg
    assert d.stats["worst_log_growth_rate_per_s"] == pytest.approx(6.0, rel=1e-3)


def _res_only(traj):
    (d,) = check(traj, only=["drift"])
    assert not d.passed
    return d
