"""The notes' quaternion scheme without normalization (``seed-quat``, ``orthonormalize = "none"``):
what it shows must be the notes' "stretch", computed consistently (issue 19).

|q| grows each step; R is the homogeneous matrix of q, R = |q|^2 Q, the body turned by Q and
enlarged |q|^2 times; I_world = R I_body R^T (the notes) and omega = I_world^-1 L = |q|^-4 Q
I_body^-1 Q^T L (rblog.engine.integrators, module docstring). Before, omega was R I^-1 R^T L =
|q|^4 times the rigid value: the stretched body spun faster and faster.

References, none of them rblog's own output: for an isotropic body the scheme reduces to a
scalar recurrence (below); for a general body, the scheme written again in numpy with
``np.linalg.inv(R I R^T)`` and scipy's rotation matrix.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from rblog.engine.runner import simulate
from rblog.engine.scene import parse_scene


def _scene(inertia, omega_body, dt, duration, axis=(1.0, 2.0, 3.0), angle_deg=40.0):
    i0, i1, i2 = map(float, inertia)
    w0, w1, w2 = map(float, omega_body)
    return parse_scene(f"""
[sim]
dt = {dt!r}
duration = {duration!r}
gravity = [0.0, 0.0, 0.0]
integrator = "seed-quat"
orthonormalize = "none"
[[body]]
name = "box"
shape = "box"
half_extents = [0.3, 0.2, 0.1]
mass = 1.0
inertia_diag = [{i0!r}, {i1!r}, {i2!r}]
axis_angle = {{ axis = [{axis[0]!r}, {axis[1]!r}, {axis[2]!r}], angle_deg = {angle_deg!r} }}
angular_velocity_body = [{w0!r}, {w1!r}, {w2!r}]
""", "stretch.toml")


def test_isotropic_body_stretches_and_slows_as_the_scalar_recurrence():
    """Isotropic body (I = I0 1), torque-free, L fixed along u: omega_n = Omega_n u with
    Omega_n = |L| / (I0 rho_n^4), rho_n = |q_n|. Each step left-multiplies q by
    (1, h Omega_n / 2 u); these commute (same axis), so q_n = rho_n (cos phi_n, sin phi_n u) (x) q_0
    with rho_{n+1} = rho_n sqrt(1 + (h Omega_n / 2)^2), phi_{n+1} = phi_n + atan(h Omega_n / 2).
    The logged R is rho^2 Rot(u, 2 phi) R_0, its ||R^T R - I||_F = sqrt(3) (rho^4 - 1), the logged
    omega Omega_n u and the rotational energy |L|^2 / (2 I0 rho^4)."""
    i0, wb, h, n_steps = 2.0, np.array([1.0, 2.0, 2.0]), 1e-2, 2000
    scene = _scene((i0, i0, i0), wb, h, h * n_steps)
    traj, summary = simulate(scene, log_every=1)
    assert summary.orthonormalize == "none"
    q0 = Rotation.from_rotvec(np.radians(40.0) * np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0))
    u = q0.apply(wb / np.linalg.norm(wb))
    l_norm = i0 * np.linalg.norm(wb)
    rho, phi = np.empty(n_steps + 1), np.empty(n_steps + 1)
    rho[0], phi[0] = 1.0, 0.0
    for n in range(n_steps):
        a = 0.5 * h * l_norm / (i0 * rho[n] ** 4)
        rho[n + 1] = rho[n] * math.sqrt(1.0 + a * a)
        phi[n + 1] = phi[n] + math.atan(a)
    rho, phi = rho[traj.step], phi[traj.step]
    # the stretch: |q| grows (rho_2000 = 1.137: the body is rho^2 = 1.29 times larger), and is
    # logged; measured relative errors 2.0e-12 (|q| - 1) and 1.6e-12 (ortho), from the
    # cancellation in rho - 1 early on
    assert rho[-1] > 1.13
    np.testing.assert_allclose(traj.quat_norm_error[:, 0], rho - 1.0, rtol=1e-11, atol=1e-15)
    np.testing.assert_allclose(traj.ortho_error[:, 0], math.sqrt(3.0) * (rho**4 - 1.0),
                               rtol=1e-11, atol=1e-15)
    expected_r = (rho[:, None, None] ** 2
                  * (Rotation.from_rotvec((2.0 * phi)[:, None] * u) * q0).as_matrix())
    # measured 1.1e-13 after 2000 steps
    np.testing.assert_allclose(traj.rotation[:, 0], expected_r, rtol=0, atol=5e-13)
    # omega = I_world^-1 L: slower as the body grows (before: rho^8 times this); measured
    # 1.0e-14 of |omega| and 1.3e-14 relative on the energy
    omega_expected = (l_norm / (i0 * rho**4))[:, None] * u
    np.testing.assert_allclose(traj.angular_velocity[:, 0], omega_expected, rtol=0,
                               atol=1e-13 * np.max(np.abs(omega_expected)))
    np.testing.assert_allclose(traj.energy_rotational[:, 0], l_norm**2 / (2.0 * i0 * rho**4),
                               rtol=1e-13)


def _numpy_scheme(inertia, q0_wxyz, l_world, h, n_steps):
    """The notes' quaternion scheme, unnormalized, written again: R = |q|^2 Q (scipy), omega =
    inv(R I R^T) L, q += h/2 (0, omega) (x) q. Returns q (n+1, 4) and omega (n+1, 3)."""
    inertia = np.diag(inertia)
    q = np.array(q0_wxyz, float)
    qs, ws = [], []
    for _ in range(n_steps + 1):
        n2 = q @ q
        r = n2 * Rotation.from_quat(q, scalar_first=True).as_matrix()
        w = np.linalg.solve(r @ inertia @ r.T, l_world)
        qs.append(q.copy())
        ws.append(w)
        pw, px, py, pz = 0.0, *w
        dq = np.array([pw * q[0] - px * q[1] - py * q[2] - pz * q[3],
                       pw * q[1] + px * q[0] + py * q[3] - pz * q[2],
                       pw * q[2] - px * q[3] + py * q[0] + pz * q[1],
                       pw * q[3] + px * q[2] - py * q[1] + pz * q[0]])
        q = q + 0.5 * h * dq
    return np.array(qs), np.array(ws)


def test_tumbling_body_matches_the_scheme_written_in_numpy():
    """Asymmetric body (the tumbling box's I = 1, 2, 3, spun near its middle axis): the engine's
    q and the logged omega against the scheme rewritten with numpy's inverse of R I R^T."""
    inertia, wb, h, n_steps = (1.0, 2.0, 3.0), np.array([0.05, 2.0, 0.05]), 1e-2, 500
    traj, _ = simulate(_scene(inertia, wb, h, h * n_steps), log_every=1)
    q0 = traj.quat_wxyz[0, 0]
    l_world = traj.angular_momentum[0, 0]
    np.testing.assert_allclose(l_world, Rotation.from_quat(q0, scalar_first=True).apply(
        np.array(inertia) * wb), rtol=1e-14)
    q_ref, w_ref = _numpy_scheme(inertia, q0, l_world, h, n_steps)
    assert np.linalg.norm(q_ref[-1]) > 1.02  # it did stretch (|q| = 1.025 at t = 5 s)
    # measured max |dq| 1.6e-14, |d omega| 2.1e-14 rad/s over 500 steps
    np.testing.assert_allclose(traj.quat_wxyz[:, 0], q_ref, rtol=0, atol=1e-13)
    np.testing.assert_allclose(traj.angular_velocity[:, 0], w_ref, rtol=0, atol=1e-13)
    # L is conserved exactly (torque-free: nothing touches it)
    np.testing.assert_array_equal(traj.angular_momentum[:, 0], np.tile(l_world, (n_steps + 1, 1)))
