"""The exact torque-free integrator (rblog.engine.exact, ``exact`` / ``exact4``) against the closed-form
reference (rblog.study.reference.TorqueFree, scipy's elliptic functions evaluated at each t), which
is itself cross-checked here against an independent DOP853 solution at rtol 1e-13."""

from __future__ import annotations

import math

import numpy as np
import pytest

scipy_special = pytest.importorskip("scipy.special")
from scipy.integrate import solve_ivp  # noqa: E402

from rblog.engine.exact import carlson_rf_rj, free_flow_quat, sncndn  # noqa: E402
from rblog.engine.integrators import METHOD_CODES, REGISTRY, drift_rotation  # noqa: E402
from rblog.study.reference import TorqueFree, quat_to_matrix, rotation_angle_between  # noqa: E402


def _run(q0, l_world, k, h, n_steps, stride):
    """Step the exact flow n_steps times, recording q every stride steps (first row: q0)."""
    out = np.empty((n_steps // stride + 1, 4))
    w, x, y, z = q0[0], q0[1], q0[2], q0[3]
    out[0] = q0
    j = 1
    for s in range(1, n_steps + 1):
        w, x, y, z = free_flow_quat(w, x, y, z, l_world[0], l_world[1], l_world[2],
                                    k[0], k[1], k[2], h)
        if s % stride == 0:
            out[j, 0], out[j, 1], out[j, 2], out[j, 3] = w, x, y, z
            j += 1
    return out


def _errors(tf: TorqueFree, dt: float, duration: float, samples: int = 50):
    """(omega error relative to |w0|, attitude error rad), max over samples, of the exact
    integrator at step dt against the closed-form reference."""
    n = int(round(duration / dt))
    stride = max(1, n // samples)
    k = 1.0 / tf.inertia
    q = _run(tf.quat0_wxyz, tf.angular_momentum_world, k, dt, n, stride)
    t = np.arange(len(q)) * stride * dt
    r = quat_to_matrix(q)
    w_num = k * np.einsum("tji,j->ti", r, tf.angular_momentum_world)  # I^-1 R^T L
    w_err = np.max(np.linalg.norm(w_num - tf.omega_body(t), axis=1)) / np.linalg.norm(tf.omega0_body)
    a_err = np.max(rotation_angle_between(q, tf.quat_wxyz(t)))
    return float(w_err), float(a_err)


Q0 = np.array([0.8, 0.3, -0.4, 0.34]) / np.linalg.norm([0.8, 0.3, -0.4, 0.34])
# (name, inertia, omega0 body, duration, expected case of the reference)
BODIES = [
    ("generic, L^2 < 2E I2", (1.0, 1.5, 2.2), (1.4, 0.5, 0.7), 10.0, "L2<2EI2"),
    ("intermediate box, L^2 > 2E I2", (1.0, 2.0, 3.0), (0.05, 2.0, 0.05), 20.0, "L2>2EI2"),
    ("unsorted inertia", (2.2, 1.0, 1.5), (0.3, -1.2, 0.8), 10.0, "L2<2EI2"),
    ("oblate symmetric", (1.0, 1.0, 2.0), (0.4, 0.3, 1.0), 10.0, "symmetric"),
    ("prolate symmetric", (2.0, 1.0, 2.0), (0.4, 0.3, 1.0), 10.0, "symmetric"),
]


def test_reference_closed_form_matches_dop853():
    """The closed-form attitude agrees with DOP853 (rtol 1e-13) on every case used below.
    Measured: <= 4.2e-13 rad over 20 s (the DOP853 solution's own error)."""
    t = np.linspace(0.0, 20.0, 201)
    for _, inertia, w0, _, case in BODIES + [("near separatrix", (1.0, 2.0, 3.0),
                                              (0.05, 2.0, 0.05 * (1 - 1e-6)), 20.0, None)]:
        tf = TorqueFree(inertia, w0, Q0)
        if case:
            assert tf.case == case
        err = rotation_angle_between(tf.quat_wxyz(t), tf.quat_wxyz_numeric(t)).max()
        assert err < 1.5e-12, (inertia, w0, err)


def test_sncndn_against_scipy():
    """sn, cn, dn (argument reduced by the half period) against scipy.special.ellipj where
    scipy is accurate (1 - m >= 1e-3; nearer 1 its approximation fails at large u).
    Measured: <= 2.8e-14 at u = 150 (~eps u), <= 4e-15 for u <= 7."""
    for m1 in (0.999, 0.5, 0.1, 1e-2, 1e-3):
        m = 1.0 - m1
        for u in (0.0, 1e-6, 0.3, 1.0, 2.5, 7.0, 33.0, 150.0):
            sn, cn, dn, j, big_k = sncndn(u, m, m1)
            s_ref, c_ref, d_ref, _ = scipy_special.ellipj(u, m)
            sg = -1.0 if j % 2 else 1.0
            assert big_k == pytest.approx(scipy_special.ellipk(m), rel=1e-14)
            tol = 1e-15 * (5.0 + u)  # the argument's own rounding, ~eps u, moves the phase
            assert abs(sg * sn - s_ref) < tol and abs(sg * cn - c_ref) < tol
            assert abs(dn - d_ref) < tol
    # m = 1: sn = tanh, cn = dn = sech; and near it the identities hold to round-off
    sn, cn, dn, j, big_k = sncndn(3.0, 1.0, 0.0)
    assert (sn, cn, dn, j, big_k) == pytest.approx((math.tanh(3.0), 1 / math.cosh(3.0),
                                                    1 / math.cosh(3.0), 0, math.inf))
    for m1 in (1e-9, 1e-12, 1e-30):
        sn, cn, dn, _, _ = sncndn(2.0, 1.0 - m1, m1)
        assert sn * sn + cn * cn == pytest.approx(1.0, abs=1e-15)
        assert dn * dn == pytest.approx(cn * cn + m1 * sn * sn, abs=1e-15)
        assert sn == pytest.approx(math.tanh(2.0), abs=1e-8)  # O(1 - m) away from m = 1


def test_carlson_against_scipy():
    """R_F and R_J against scipy.special.elliprf / elliprj (measured <= 1.3e-15 relative)."""
    rng = np.random.default_rng(1)
    for _ in range(500):
        x, y = rng.uniform(0.0, 1.0, 2)
        p = 1.0 + rng.uniform(0.0, 20.0) * rng.uniform()
        rf, rj = carlson_rf_rj(x, y, 1.0, p)
        assert rf == pytest.approx(scipy_special.elliprf(x, y, 1.0), rel=5e-15)
        assert rj == pytest.approx(scipy_special.elliprj(x, y, 1.0, p), rel=5e-15)
    rf, rj = carlson_rf_rj(0.0, 1e-12, 1.0, 3.0)  # complete integrals near m = 1
    assert rf == pytest.approx(scipy_special.elliprf(0.0, 1e-12, 1.0), rel=5e-15)
    assert rj == pytest.approx(scipy_special.elliprj(0.0, 1e-12, 1.0, 3.0), rel=5e-15)


@pytest.mark.parametrize("name, inertia, w0, duration, case", BODIES, ids=[b[0] for b in BODIES])
@pytest.mark.parametrize("dt", [1.0, 0.1, 1e-2])
def test_exact_flow_against_reference(name, inertia, w0, duration, case, dt):
    """Errors at round-off at every step size, both branches, symmetric bodies, unsorted axes.
    Measured (max over the cases and dt): omega 1.7e-11 and angle 1.5e-11 on the intermediate box
    at dt = 1e-2 (its near-separatrix motion amplifies the storage round-off of q, ~1e-16 a step:
    the energy's random walk moves the flip times), <= 3e-13 on the others."""
    tf = TorqueFree(inertia, w0, Q0)
    assert tf.case == case
    w_err, a_err = _errors(tf, dt, duration)
    bound = 6e-11 if "intermediate" in name else 1.5e-12
    assert w_err < bound and a_err < bound, (w_err, a_err)


@pytest.mark.parametrize("delta", [1e-3, 1e-5])
def test_exact_flow_near_separatrix(delta):
    """The intermediate box moved towards the separatrix: w3 = w1 / sqrt(3) (1 + delta) puts
    1 - m at 1.25e-6 (delta 1e-3) and 1.25e-8 (1e-5); the motion lingers at the saddle, where
    errors grow like exp(lam t) (x1e5 by t = 10 s). scipy's ellipj takes m, not 1 - m, so the
    closed-form reference is off by eps / (1 - m) amplified (1.1e-9 at t = 10 s, delta 1e-3): omega
    is checked against Euler's equations by DOP853 at rtol 1e-13 instead (against mpmath at 32
    digits that solution is within 5e-14 at t = 10 s and 8.5e-12 at 20 s). Measured (delta 1e-3):
    one step to t = 10 s 8e-12 (the rounding of L = R0 I w0, amplified; 1.7e-13 against mpmath
    from the identity, whose L is unrounded), dt = 0.1 <= 2e-11 (storage round-off amplified)."""
    inertia = (1.0, 2.0, 3.0)
    w0 = (0.05, 2.0, 0.05 / math.sqrt(3.0) * (1 + delta))
    tf = TorqueFree(inertia, w0, Q0)
    assert tf.case == "L2>2EI2" and 1.0 - tf.elliptic_parameter < 2e-3 * delta

    def euler(_, w):
        return [(inertia[1] - inertia[2]) / inertia[0] * w[1] * w[2],
                (inertia[2] - inertia[0]) / inertia[1] * w[2] * w[0],
                (inertia[0] - inertia[1]) / inertia[2] * w[0] * w[1]]

    sol = solve_ivp(euler, (0.0, 20.0), w0, method="DOP853", rtol=1e-13, atol=1e-16,
                    dense_output=True)
    k = 1.0 / tf.inertia
    lw = tf.angular_momentum_world
    for t_end, dt in ((10.0, 10.0), (10.0, 0.1), (20.0, 0.1)):
        n = int(round(t_end / dt))
        q = _run(tf.quat0_wxyz, lw, k, dt, n, n)[-1]
        w_num = k * (quat_to_matrix(q).T @ lw)
        err = np.linalg.norm(w_num - sol.sol(t_end)) / np.linalg.norm(w0)
        assert err < (5e-11 if dt == t_end else 2e-10), (t_end, dt, err)
        # the attitude against the closed form, within what scipy's m costs it
        assert rotation_angle_between(q, tf.quat_wxyz(t_end)[0]) < 1e-8


def test_exact_flow_at_1000_rad_per_s():
    """A generic body spinning at 1,000 rad/s: 0.2 s (~32 turns) at dt 1e-4..1e-2, and one step of
    0.2 s. Measured: <= 1.6e-13 relative omega, <= 2e-13 rad."""
    w0 = 1000.0 * np.array([1.4, 0.5, 0.7]) / np.linalg.norm([1.4, 0.5, 0.7])
    tf = TorqueFree((1.0, 1.5, 2.2), w0, Q0)
    t = np.linspace(0.0, 0.2, 41)
    assert rotation_angle_between(tf.quat_wxyz(t), tf.quat_wxyz_numeric(t)).max() < 1e-12
    for dt in (1e-4, 1e-3, 1e-2, 0.2):
        w_err, a_err = _errors(tf, dt, 0.2, samples=20)
        assert w_err < 1e-12 and a_err < 1e-12, (dt, w_err, a_err)


def test_exact_flow_backward_and_steady():
    """The flow over -h undoes the flow over h; steady rotation about a principal axis (and any
    axis of a sphere) is the rotation exp(h omega), including the unstable intermediate axis."""
    k = np.array([1.0, 1 / 1.5, 1 / 2.2])
    lw = np.array([1.4, 0.75, 1.54])
    q = free_flow_quat(*Q0, *lw, *k, 0.7)
    back = free_flow_quat(*q, *lw, *k, -0.7)
    assert rotation_angle_between(np.array(back), Q0) < 2e-13  # measured 6e-14
    for inertia, w in (((1.0, 2.0, 3.0), (0.0, 2.0, 0.0)), ((1.0, 1.0, 1.0), (0.3, -0.2, 0.5)),
                       ((1.0, 1.0, 2.0), (0.3, -0.2, 0.0))):
        inertia, w = np.asarray(inertia), np.asarray(w)
        lw = quat_to_matrix(Q0) @ (inertia * w)
        q = free_flow_quat(*Q0, *lw, *(1 / inertia), 1.3)
        ang = 1.3 * np.linalg.norm(w)
        axis = w / np.linalg.norm(w)
        qw = np.concatenate([[math.cos(ang / 2)], math.sin(ang / 2) * axis])
        expect = np.array([Q0[0] * qw[0] - Q0[1:] @ qw[1:],
                           *(Q0[0] * qw[1:] + qw[0] * Q0[1:] + np.cross(Q0[1:], qw[1:]))])
        assert rotation_angle_between(np.array(q), expect) < 2e-13  # measured 6e-14


def test_registry_and_drift_rotation_dispatch():
    """``exact`` and ``exact4`` are in the registry, pass scene validation, and drift_rotation
    (what the contact step calls) advances a body by the exact flow."""
    from rblog.engine.scene import parse_scene

    for name in ("exact", "exact4"):
        assert name in REGISTRY
        parse_scene("[sim]\ndt = 0.01\nduration = 0.1\nintegrator = \"%s\"\n[[body]]\nshape = \"sphere\"\n"
                    "radius = 0.1\nmass = 1.0\n" % name, "<t>")
    tf = TorqueFree((1.0, 1.5, 2.2), (1.4, 0.5, 0.7), Q0)
    quat = Q0[None].copy()
    rot = quat_to_matrix(Q0)[None].copy()
    lw = tf.angular_momentum_world[None].copy()
    inv = (1.0 / tf.inertia)[None]
    for _ in range(50):
        drift_rotation(METHOD_CODES["exact"], 3, quat, rot, lw, inv, 0, 0.02)
    assert rotation_angle_between(quat[0], tf.quat_wxyz(1.0)[0]) < 1e-13
    np.testing.assert_allclose(rot[0], quat_to_matrix(quat[0]), atol=1e-15)


def _torqued_reference(inertia, w0, torque, t_end):
    """(q, L) at t_end under a constant world torque: DOP853 at rtol 1e-13 on q' = 1/2 (0, w) q,
    w = R I^-1 R^T L, L' = tau."""
    k = 1.0 / np.asarray(inertia)
    l0 = quat_to_matrix(Q0) @ (np.asarray(inertia) * np.asarray(w0))

    def rhs(_, y):
        q, lw = y[:4], y[4:]
        r = quat_to_matrix(q)
        w = r @ (k * (r.T @ lw))
        return np.concatenate([0.5 * np.array([-w @ q[1:], *(q[0] * w + np.cross(w, q[1:]))]), torque])

    sol = solve_ivp(rhs, (0, t_end), np.concatenate([Q0, l0]), method="DOP853", rtol=1e-13, atol=1e-14)
    return sol.y[:4, -1] / np.linalg.norm(sol.y[:4, -1])


def test_torque_splitting_orders():
    """With a constant world torque, ``exact`` (Strang) converges at order 2, ``exact4`` (Yoshida)
    and ``rk4`` at order 4 (slopes of the attitude error against dt, DOP853 reference)."""
    from rblog.engine.runner import simulate
    from rblog.engine.scene import parse_scene

    inertia, w0, torque, t_end = (1.0, 1.5, 2.2), (1.4, 0.5, 0.7), np.array([0.3, -0.2, 0.5]), 2.0
    q_ref = _torqued_reference(inertia, w0, torque, t_end)
    scene = ("[sim]\ndt = {dt}\nduration = 2.0\ngravity = [0, 0, 0]\n[[body]]\nshape = \"box\"\n"
             "half_extents = [0.3, 0.2, 0.1]\nmass = 1.0\ninertia_diag = [1.0, 1.5, 2.2]\n"
             f"quat_wxyz = {[float(v) for v in Q0]}\nangular_velocity_body = [1.4, 0.5, 0.7]\n"
             "torque = [0.3, -0.2, 0.5]\n")
    for name, order in (("exact", 2), ("exact4", 4), ("rk4", 4)):
        errs = []
        for dt in (0.04, 0.02):
            traj, _ = simulate(parse_scene(scene.format(dt=dt), "<t>"), integrator=name,
                               log_every=10**9)
            errs.append(float(rotation_angle_between(traj.quat_wxyz[-1, 0], q_ref)))
        slope = math.log2(errs[0] / errs[1])
        assert abs(slope - order) < 0.3, (name, errs, slope)
