"""Reference problems with exact answers, for ``rblog bench``, ``rblog stress`` and the tests.

A :class:`Problem` is an engine-neutral description of a scene (bodies, gravity, ground) plus its
exact answer and the error measures against it. rblog runs it from the TOML that
:meth:`Problem.scene_toml` writes; the peers (:mod:`rblog.study.peers`) build the same bodies in their
own formats. Every engine's run is reduced to :class:`Samples` (time, pose, velocities) and scored
by :meth:`Problem.evaluate`, so all engines are measured by the same code.

Derivations
-----------
Torque-free asymmetric body (Landau & Lifshitz, Mechanics, section 37). Principal moments
I1 < I2 < I3, body-frame angular velocity w, 2E = sum I_k w_k^2, L^2 = sum I_k^2 w_k^2. Euler's
equations I1 w1' = (I2 - I3) w2 w3 (and cyclic) are solved by Jacobi elliptic functions of
u = lam t + u0 with parameter m = k^2:

* L^2 > 2E I2 (the body turns about axis 3, the one of largest inertia):
    w1 = A1 cn u,  w2 = s A2 sn u,  w3 = s A3 dn u,
    A1^2 = (2E I3 - L^2) / (I1 (I3 - I1)),  A2^2 = (2E I3 - L^2) / (I2 (I3 - I2)),
    A3^2 = (L^2 - 2E I1) / (I3 (I3 - I1)),
    lam^2 = (I3 - I2)(L^2 - 2E I1) / (I1 I2 I3),  m = (I2 - I1)(2E I3 - L^2) / ((I3 - I2)(L^2 - 2E I1)).
* L^2 < 2E I2 (about axis 1): the same with axes 1 and 3 exchanged,
    w1 = s A1 dn u,  w2 = s A2 sn u,  w3 = A3 cn u,
    A2^2 = (L^2 - 2E I1) / (I2 (I2 - I1)),  lam^2 = (I2 - I1)(2E I3 - L^2) / (I1 I2 I3),
    m = (I3 - I2)(L^2 - 2E I1) / ((I2 - I1)(2E I3 - L^2))   (A1, A3 as above).

s = sign of the dn component at t = 0 (dn > 0 never changes sign); substituting into Euler's
equations (cn' = -sn dn, sn' = cn dn, dn' = -m sn cn) shows that the sn component carries the
same sign in both cases. The phase is u0 = F(phi0 | m), phi0 = atan2(sn u0, cn u0) read off the
initial sn and cn components (atan2 keeps it well conditioned where sn is near +-1, as in the
intermediate-axis case). Symmetric bodies (two equal moments) precess uniformly and are solved in
closed form too; an unsorted inertia is reduced to the sorted one by a permutation P of the axes
(for an odd P the reflected system is solved by -P w, which obeys the unreflected equations).

The orientation is closed-form too (Celledoni, Fasso, Safstrom & Zanna, SIAM J. Sci. Comput. 30(4),
2008): with Euler angles about the fixed world L, R(t) = R(0) M^T B(0)^T Rz(phi(t) - phi(0)) B(t) M,
where M relabels the axes so that axis 3' is the one Lb turns about (the dn component: axis 3 when
L^2 > 2E I2, axis 1 when below; a proper signed permutation), B = Rx(theta) Rz(psi) takes Lb'(t)
to |L| e3 (Lb' = |L| (sin theta sin psi, sin theta cos psi, cos theta)), and Landau's
dphi/dt = |L| (k1 Lb1'^2 + k2 Lb2'^2) / (Lb1'^2 + Lb2'^2) (k = 1/I in the M frame) becomes, with the
elliptic solution, |L| k3 + |L| (k1 - k3) / (1 + n sn^2 u), n = (k1 - k2) / (k2 - k3), so that

    phi(t) - phi(0) = |L| k3 t + |L| (k1 - k3) / lam * [Pi(-n; am u(t) | m) - Pi(-n; am u0 | m)],

the elliptic integral of the third kind, Pi(-n; phi | m) = S R_F(C^2, 1 - m S^2, 1)
- n/3 S^3 R_J(C^2, 1 - m S^2, 1, 1 + n S^2) (S = sin phi, C = cos phi, |phi| <= pi/2; DLMF 19.25.14)
and Pi(phi + pi) = Pi(phi) + 2 Pi(pi/2). Evaluated here with scipy (ellipj's continuous amplitude,
elliprf, elliprj) at each t directly, independently of the engine's compiled stepping kernel
(rblog.engine.exact). The DOP853 solution of q' = 1/2 q (x) (0, w_body(t)) at rtol 1e-13
(:meth:`TorqueFree.quat_wxyz_numeric`, ~1e-12 over tens of seconds) remains as the independent
cross-check (tests) and as the answer on the separatrix itself.

Free fall: x(t) = x0 + v0 t + g t^2 / 2, v(t) = v0 + g t; the rotation is torque-free (above).

Bouncing ball (no friction, no spin): a ball dropped from rest with its lowest point h0 above
the ground rebounds with speed e v at each impact, so the n-th apex is h_n = e^(2n) h0 and the
impacts are at t_1 = sqrt(2 h0 / g), t_(n+1) = t_n + 2 e^n sqrt(2 g h0) / g.

Two-sphere impact (head-on, frictionless, restitution e): with reduced mass mu = m1 m2 / (m1 + m2)
v1' = v1 - (1 + e) m2 (v1 - v2) / (m1 + m2),  v2' = v2 + (1 + e) m1 (v1 - v2) / (m1 + m2),
total momentum kept, kinetic energy lost 1/2 mu (1 - e^2) (v1 - v2)^2.

Resting box: a box placed exactly on the ground at rest stays there: position, orientation and
energy constant, velocity zero.

Why this module is long: it holds every exact or high-accuracy reference the tests and benchmarks
measure against (the torque-free body by Jacobi elliptic functions, ballistic flight, bounces,
head-on impacts), each beside its derivation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

#: Relative tolerance below which two principal moments count as equal (symmetric body).
SYMMETRIC_REL_TOL = 1e-12
#: Relative distance of L^2 from 2E I2 below which the motion counts as on the separatrix, where
#: the elliptic parameter is 1 and the phase is ill-defined: solved numerically there.
SEPARATRIX_REL_TOL = 1e-12
#: DOP853 tolerances of the orientation reference (relative, absolute on unit quaternions).
ORIENTATION_RTOL = 1e-13
ORIENTATION_ATOL = 1e-15

GRAVITY = 9.81


# ---- torque-free rigid body ------------------------------------------------------------------

def _perm_parity(p) -> int:
    p = list(p)
    sign = 1
    for i in range(len(p)):
        while p[i] != i:
            j = p[i]
            p[i], p[j] = p[j], p[i]
            sign = -sign
    return sign


@dataclass
class TorqueFree:
    """Exact torque-free motion of a rigid body.

    Attributes:
        inertia: (3,) principal moments (kg m^2), any order.
        omega0_body: (3,) body-frame angular velocity at t = 0 (rad/s).
        quat0_wxyz: (4,) orientation body -> world at t = 0.
    """

    inertia: np.ndarray
    omega0_body: np.ndarray
    quat0_wxyz: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))

    def __post_init__(self):
        self.inertia = np.asarray(self.inertia, float)
        self.omega0_body = np.asarray(self.omega0_body, float)
        q = np.asarray(self.quat0_wxyz, float)
        self.quat0_wxyz = q / np.linalg.norm(q)
        self._orient_cache: dict = {}

    # invariants
    @property
    def energy(self) -> float:
        """Rotational kinetic energy (J)."""
        return 0.5 * float(np.sum(self.inertia * self.omega0_body**2))

    @property
    def angular_momentum_body0(self) -> np.ndarray:
        return self.inertia * self.omega0_body

    @property
    def angular_momentum_world(self) -> np.ndarray:
        """(3,) the constant world-frame angular momentum."""
        return quat_to_matrix(self.quat0_wxyz) @ self.angular_momentum_body0

    @cached_property
    def case(self) -> str:
        """``"L2>2EI2"``, ``"L2<2EI2"`` (the two elliptic cases), ``"symmetric"``, ``"separatrix"``
        or ``"rest"``; for the sorted moments."""
        return self._solution[0]

    @cached_property
    def _solution(self):
        perm = np.argsort(self.inertia, kind="stable")
        j = self.inertia[perm]
        parity = _perm_parity(perm)
        # nu = parity * P w obeys Euler's equations with the sorted moments j
        nu0 = parity * self.omega0_body[perm]
        e2 = float(np.sum(j * nu0**2))
        l2 = float(np.sum((j * nu0) ** 2))
        scale = j[2]
        if e2 == 0.0:
            return ("rest", perm, parity, None)
        if abs(j[1] - j[0]) <= SYMMETRIC_REL_TOL * scale or abs(j[2] - j[1]) <= SYMMETRIC_REL_TOL * scale:
            return ("symmetric", perm, parity, (j, nu0))
        if abs(l2 - e2 * j[1]) <= SEPARATRIX_REL_TOL * l2:
            return ("separatrix", perm, parity, (j, nu0))
        j1, j2, j3 = j
        if l2 > e2 * j2:
            a1 = math.sqrt(max(e2 * j3 - l2, 0.0) / (j1 * (j3 - j1)))
            a2 = math.sqrt(max(e2 * j3 - l2, 0.0) / (j2 * (j3 - j2)))
            a3 = math.sqrt(max(l2 - e2 * j1, 0.0) / (j3 * (j3 - j1)))
            lam = math.sqrt((j3 - j2) * (l2 - e2 * j1) / (j1 * j2 * j3))
            m = (j2 - j1) * (e2 * j3 - l2) / ((j3 - j2) * (l2 - e2 * j1))
            s = 1.0 if nu0[2] >= 0 else -1.0
            phi0 = math.atan2(nu0[1] / (s * a2) if a2 > 0 else 0.0, nu0[0] / a1 if a1 > 0 else 1.0)
            return ("L2>2EI2", perm, parity, (lam, m, phi0, s, a1, a2, a3))
        a1 = math.sqrt(max(e2 * j3 - l2, 0.0) / (j1 * (j3 - j1)))
        a2 = math.sqrt(max(l2 - e2 * j1, 0.0) / (j2 * (j2 - j1)))
        a3 = math.sqrt(max(l2 - e2 * j1, 0.0) / (j3 * (j3 - j1)))
        lam = math.sqrt((j2 - j1) * (e2 * j3 - l2) / (j1 * j2 * j3))
        m = (j3 - j2) * (l2 - e2 * j1) / ((j2 - j1) * (e2 * j3 - l2))
        s = 1.0 if nu0[0] >= 0 else -1.0
        phi0 = math.atan2(nu0[1] / (s * a2) if a2 > 0 else 0.0, nu0[2] / a3 if a3 > 0 else 1.0)
        return ("L2<2EI2", perm, parity, (lam, m, phi0, s, a1, a2, a3))

    @property
    def elliptic_parameter(self) -> float | None:
        """m = k^2 of the elliptic solution (None for the non-elliptic cases)."""
        case, _, _, p = self._solution
        return p[1] if case in ("L2>2EI2", "L2<2EI2") else None

    @property
    def period(self) -> float | None:
        """Period of w_body(t) (s): 4 K(m) / lam (None for the non-elliptic cases)."""
        from scipy.special import ellipk

        case, _, _, p = self._solution
        if case not in ("L2>2EI2", "L2<2EI2"):
            return None
        return 4.0 * float(ellipk(p[1])) / p[0]

    def omega_body(self, t) -> np.ndarray:
        """(T, 3) exact body-frame angular velocity at times t (s)."""
        from scipy.special import ellipj, ellipkinc

        t = np.atleast_1d(np.asarray(t, float))
        case, perm, parity, p = self._solution
        if case == "rest":
            return np.zeros((len(t), 3))
        if case == "symmetric":
            j, nu0 = p
            nu = _symmetric_omega(j, nu0, t)
        elif case == "separatrix":
            j, nu0 = p
            nu = _euler_numeric(j, nu0, t)
        else:
            lam, m, phi0, s, a1, a2, a3 = p
            sn, cn, dn, _ = _ellipj_reduced(lam * t + ellipkinc(phi0, m), m)
            if case == "L2>2EI2":
                nu = np.stack([a1 * cn, s * a2 * sn, s * a3 * dn], -1)
            else:
                nu = np.stack([s * a1 * dn, s * a2 * sn, a3 * cn], -1)
        out = np.empty_like(nu)
        out[:, perm] = parity * nu
        return out

    def _dense_orientation(self, t_end: float):
        """DOP853 dense solution of q' = 1/2 q (x) (0, w_body(t)) on [0, t_end] (cached)."""
        from scipy.integrate import solve_ivp

        for (te, sol) in self._orient_cache.items():
            if te >= t_end:
                return sol

        def rhs(t, q):
            w = self.omega_body(t)[0]
            return 0.5 * np.array([
                -q[1] * w[0] - q[2] * w[1] - q[3] * w[2],
                q[0] * w[0] + q[2] * w[2] - q[3] * w[1],
                q[0] * w[1] + q[3] * w[0] - q[1] * w[2],
                q[0] * w[2] + q[1] * w[1] - q[2] * w[0],
            ])

        t_end = max(float(t_end), 1e-9)
        sol = solve_ivp(rhs, (0.0, t_end), self.quat0_wxyz, method="DOP853",
                        rtol=ORIENTATION_RTOL, atol=ORIENTATION_ATOL, dense_output=True)
        if not sol.success:  # pragma: no cover - smooth problem
            raise RuntimeError(f"orientation reference failed: {sol.message}")
        self._orient_cache = {t_end: sol.sol}
        return sol.sol

    def quat_wxyz_numeric(self, t) -> np.ndarray:
        """(T, 4) orientation by DOP853 at rtol 1e-13 on q' = 1/2 q (x) (0, w_body(t))."""
        t = np.atleast_1d(np.asarray(t, float))
        sol = self._dense_orientation(float(t.max()) if len(t) else 0.0)
        q = sol(t).T
        return q / np.linalg.norm(q, axis=1, keepdims=True)

    def quat_wxyz(self, t) -> np.ndarray:
        """(T, 4) orientation body -> world at times t (s), unit, scalar first: closed form (see
        the module docstring); DOP853 on the separatrix itself."""
        t = np.atleast_1d(np.asarray(t, float))
        r = self.rotation_closed_form(t)
        if r is None:
            return self.quat_wxyz_numeric(t)
        return _matrix_to_quat(r)

    def rotation_closed_form(self, t) -> np.ndarray | None:
        """(T, 3, 3) body -> world rotation by the closed form; None on the separatrix."""
        from scipy.special import ellipj, ellipkinc, elliprf, elliprj

        t = np.atleast_1d(np.asarray(t, float))
        case, perm, parity, p = self._solution
        r0 = quat_to_matrix(self.quat0_wxyz)
        lb0 = self.angular_momentum_body0
        w_world = r0 @ self.omega0_body
        if case == "separatrix":
            return None
        if case == "rest" or np.linalg.norm(np.cross(lb0, self.omega0_body)) <= 1e-15 * np.dot(lb0, self.omega0_body):
            # steady rotation (about a principal axis, or any axis of a sphere): R = exp(t [w]) R0
            return np.einsum("tij,jk->tik", _axis_angle_matrix(w_world, t), r0)
        j = self.inertia[perm]
        # sorted frame: nu = parity P w; working frame: axis 3' = the dn axis
        p_mat = np.zeros((3, 3))
        p_mat[np.arange(3), perm] = parity
        if case == "symmetric":
            j_, nu0 = p
            above = abs(j[1] - j[0]) <= abs(j[2] - j[1])  # axis 3 unique: it is the dn axis
            nu = _symmetric_omega(j_, nu0, t)
        else:
            above = case == "L2>2EI2"
            nu = self.omega_body(t)[:, perm] * parity
        order = [0, 1, 2] if above else [2, 1, 0]
        w_mat = np.zeros((3, 3))
        w_mat[np.arange(3), order] = [1.0, 1.0, 1.0 if above else -1.0]
        m_mat = w_mat @ p_mat  # body -> working, proper
        jw = j[order]
        k1, k2, k3 = 1.0 / jw
        lw = (j * nu) @ w_mat.T  # (T, 3) Lb' in the working frame
        ell = float(np.linalg.norm(lb0))
        if case == "symmetric":
            dphi = ell * k1 * t  # n = 0: uniform precession about L
        else:
            lam, m, phi0, s, a1, a2, a3 = p
            nn = (k1 - k2) / (k2 - k3)
            u0 = ellipkinc(phi0, m)
            _, _, _, ph = _ellipj_reduced(lam * t + u0, m)
            ph0 = _ellipj_reduced(np.array([u0]), m)[3][0]

            def pi3(phi):
                k = np.round(np.asarray(phi) / np.pi)
                phr = phi - k * np.pi
                sn, cn = np.sin(phr), np.cos(phr)
                d2 = 1.0 - m * sn * sn
                val = sn * elliprf(cn * cn, d2, 1.0) - nn / 3.0 * sn**3 * elliprj(cn * cn, d2, 1.0, 1.0 + nn * sn * sn)
                full = elliprf(0.0, 1.0 - m, 1.0) - nn / 3.0 * elliprj(0.0, 1.0 - m, 1.0, 1.0 + nn)
                return 2.0 * k * full + val

            dphi = ell * k3 * t + ell * (k1 - k3) / lam * (pi3(ph) - pi3(ph0))
        b_t = _euler_b(lw, ell)
        b_0 = _euler_b(lw[:1] * 0 + (m_mat @ lb0)[None], ell)[0]
        c, sn_ = np.cos(dphi), np.sin(dphi)
        rz = np.zeros((len(t), 3, 3))
        rz[:, 0, 0], rz[:, 0, 1], rz[:, 1, 0], rz[:, 1, 1], rz[:, 2, 2] = c, -sn_, sn_, c, 1.0
        left = r0 @ m_mat.T @ b_0.T
        # R(t) = left Rz(dphi) B(t) M as batched 3 x 3 products (numpy's unoptimized
        # four-operand einsum walks all 3^5 index sets per sample: 5 ms per 2,000 samples)
        return (left @ rz) @ b_t @ m_mat

    def omega_world(self, t) -> np.ndarray:
        """(T, 3) world-frame angular velocity."""
        r = quat_to_matrix(self.quat_wxyz(t))
        return np.einsum("tij,tj->ti", r, self.omega_body(t))


def _ellipj_reduced(u, m):
    """scipy's ellipj with the argument first reduced by the period 4K (its phase loses ~eps u x
    2^levels at large u near m = 1); the amplitude is returned continuous (am(u + 4K) = am + 2 pi)."""
    from scipy.special import ellipj, ellipk

    u = np.asarray(u, float)
    p4 = 4.0 * float(ellipk(m))
    n = np.round(u / p4)
    sn, cn, dn, ph = ellipj(u - n * p4, m)
    return sn, cn, dn, ph + 2.0 * np.pi * n


def _euler_b(lw, ell):
    """(T, 3, 3) B = Rx(theta) Rz(psi) with B Lb' = |L| e3, Lb' = |L| (st sp, st cp, ct)."""
    rho = np.hypot(lw[:, 0], lw[:, 1])
    th = np.arctan2(rho, lw[:, 2])
    ps = np.arctan2(lw[:, 0], lw[:, 1])
    ct, st, cp, sp = np.cos(th), np.sin(th), np.cos(ps), np.sin(ps)
    one, zero = np.ones_like(ct), np.zeros_like(ct)
    rx = np.stack([np.stack([one, zero, zero], -1), np.stack([zero, ct, -st], -1),
                   np.stack([zero, st, ct], -1)], -2)
    rzp = np.stack([np.stack([cp, -sp, zero], -1), np.stack([sp, cp, zero], -1),
                    np.stack([zero, zero, one], -1)], -2)
    return rx @ rzp


def _axis_angle_matrix(w, t):
    """(T, 3, 3) exp(t [w]x) (Rodrigues)."""
    wn = float(np.linalg.norm(w))
    if wn == 0.0:
        return np.tile(np.eye(3), (len(t), 1, 1))
    a = w / wn
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    th = wn * np.asarray(t, float)
    return (np.eye(3)[None] + np.sin(th)[:, None, None] * k[None]
            + (1 - np.cos(th))[:, None, None] * (k @ k)[None])


def _matrix_to_quat(r) -> np.ndarray:
    """(T, 3, 3) rotations -> (T, 4) unit quaternions wxyz (Shepperd), w >= 0: the log contract's
    vectorized conversion (a loop over samples here cost ~30 ms per 2,000 samples, half of a
    sweep variant's time)."""
    from rblog.contract.orientation import matrix_to_quat

    return matrix_to_quat(np.asarray(r, float))


def _symmetric_omega(j, nu0, t):
    """Uniform precession of a symmetric body (sorted moments j, two of them equal)."""
    scale = j[2]
    if abs(j[2] - j[0]) <= SYMMETRIC_REL_TOL * scale:  # sphere-like: constant
        return np.tile(nu0, (len(t), 1))
    if abs(j[1] - j[0]) <= SYMMETRIC_REL_TOL * scale:  # axis 3 is the symmetry axis
        om = (j[2] - j[0]) / j[0] * nu0[2]
        c, s = np.cos(om * t), np.sin(om * t)
        return np.stack([c * nu0[0] - s * nu0[1], s * nu0[0] + c * nu0[1], np.full_like(t, nu0[2])], -1)
    om = (j[2] - j[0]) / j[1] * nu0[0]  # axis 1 is the symmetry axis
    c, s = np.cos(om * t), np.sin(om * t)
    return np.stack([np.full_like(t, nu0[0]), c * nu0[1] + s * nu0[2], -s * nu0[1] + c * nu0[2]], -1)


def _euler_numeric(j, nu0, t):
    """Euler's equations by DOP853 at tight tolerance (the separatrix fallback)."""
    from scipy.integrate import solve_ivp

    def rhs(_, w):
        return [(j[1] - j[2]) / j[0] * w[1] * w[2], (j[2] - j[0]) / j[1] * w[2] * w[0],
                (j[0] - j[1]) / j[2] * w[0] * w[1]]

    order = np.argsort(t)
    sol = solve_ivp(rhs, (0.0, max(float(t.max()), 1e-9)), nu0, method="DOP853",
                    rtol=ORIENTATION_RTOL, atol=1e-15, t_eval=t[order])
    out = np.empty((len(t), 3))
    out[order] = sol.y.T
    return out


# ---- small rotation helpers (numpy) ------------------------------------------------------------

def quat_to_matrix(q_wxyz) -> np.ndarray:
    """(..., 4) wxyz -> (..., 3, 3), normalizing first (rblog.engine.rotation.quat_to_matrix_np)."""
    from rblog.engine.rotation import quat_to_matrix_np

    q = np.asarray(q_wxyz, float)
    return quat_to_matrix_np(q / np.linalg.norm(q, axis=-1, keepdims=True))


def rotation_angle_between(qa_wxyz, qb_wxyz) -> np.ndarray:
    """(...,) angle (rad, in [0, pi]) of the rotation taking orientation a to orientation b."""
    qa = np.asarray(qa_wxyz, float)
    qb = np.asarray(qb_wxyz, float)
    qa = qa / np.linalg.norm(qa, axis=-1, keepdims=True)
    qb = qb / np.linalg.norm(qb, axis=-1, keepdims=True)
    w = np.abs(np.sum(qa * qb, axis=-1))
    # |vector part of conj(a) (x) b| = sqrt(1 - w^2), computed without cancellation
    aw, ax, ay, az = np.moveaxis(qa, -1, 0)
    bw, bx, by, bz = np.moveaxis(qb, -1, 0)
    vx = aw * bx - ax * bw - ay * bz + az * by
    vy = aw * by + ax * bz - ay * bw - az * bx
    vz = aw * bz - ax * by + ay * bx - az * bw
    return 2.0 * np.arctan2(np.sqrt(vx * vx + vy * vy + vz * vz), w)


def _box_inertia(mass, half_extents):
    a, b, c = np.asarray(half_extents, float) ** 2
    return mass / 3.0 * np.array([b + c, a + c, a + b])


# ---- closed-form answers of the contact problems -------------------------------------------------

def bouncing_ball_apexes(h0: float, e: float, n: int, g: float = GRAVITY):
    """Exact apex heights h_k = e^(2k) h0 (k = 1..n, lowest point above the ground, m) and the
    times of the impacts t_1..t_(n+1) and of the apexes (s)."""
    v = math.sqrt(2.0 * g * h0)
    impacts = [math.sqrt(2.0 * h0 / g)]
    apex_t = []
    for k in range(1, n + 1):
        vk = e**k * v
        apex_t.append(impacts[-1] + vk / g)
        impacts.append(impacts[-1] + 2.0 * vk / g)
    heights = [e ** (2 * k) * h0 for k in range(1, n + 1)]
    return np.array(heights), np.array(impacts), np.array(apex_t)


def two_sphere_velocities(m1, m2, v1, v2, e):
    """Exact velocities after a head-on frictionless impact (along the line of centres)."""
    m = m1 + m2
    d = v1 - v2
    return v1 - (1.0 + e) * m2 * d / m, v2 + (1.0 + e) * m1 * d / m


# ---- engine-neutral problems -----------------------------------------------------------------

@dataclass
class BodySpec:
    """One body, world frame, SI units. ``size``: radius (sphere) or half-extents (box)."""

    name: str
    shape: str
    size: tuple
    mass: float
    inertia: tuple | None = None  # principal moments; None: from the shape
    position: tuple = (0.0, 0.0, 0.0)
    quat_wxyz: tuple = (1.0, 0.0, 0.0, 0.0)
    velocity: tuple = (0.0, 0.0, 0.0)
    omega_body: tuple = (0.0, 0.0, 0.0)
    restitution: float = 0.5
    friction: float = 0.5
    torque: tuple = (0.0, 0.0, 0.0)  # constant applied torque, world frame (N m)

    @property
    def inertia_diag(self) -> np.ndarray:
        if self.inertia is not None:
            return np.asarray(self.inertia, float)
        if self.shape == "sphere":
            return np.full(3, 0.4 * self.mass * self.size[0] ** 2)
        return _box_inertia(self.mass, self.size)

    @property
    def omega_world(self) -> np.ndarray:
        return quat_to_matrix(np.asarray(self.quat_wxyz, float)) @ np.asarray(self.omega_body, float)

    def toml(self) -> str:
        f = lambda v: "[" + ", ".join(repr(float(x)) for x in v) + "]"
        lines = ["[[body]]", f'name = "{self.name}"', f'shape = "{self.shape}"']
        if self.shape == "sphere":
            lines.append(f"radius = {float(self.size[0])!r}")
        else:
            lines.append(f"half_extents = {f(self.size)}")
        lines += [f"mass = {float(self.mass)!r}"]
        if self.inertia is not None:
            lines.append(f"inertia_diag = {f(self.inertia)}")
        lines += [f"position = {f(self.position)}", f"quat_wxyz = {f(self.quat_wxyz)}",
                  f"velocity = {f(self.velocity)}", f"angular_velocity_body = {f(self.omega_body)}",
                  f"restitution = {float(self.restitution)!r}",
                  f"friction = {float(self.friction)!r}"]
        if any(self.torque):
            lines.append(f"torque = {f(self.torque)}")
        return "\n".join(lines)


@dataclass
class Samples:
    """What an engine's run is reduced to before scoring. T samples of N bodies, world frame.

    Attributes:
        t: (T,) s.  position: (T, N, 3) m.  quat_wxyz: (T, N, 4) body -> world.
        velocity: (T, N, 3) m/s.  omega_world: (T, N, 3) rad/s.
        energy: (T,) total energy (J), if the engine reports its own; else computed.
        angular_momentum: (T, N, 3) world spin angular momentum, if the engine reports it.
        ortho_error: (T, N) ||R^T R - I||_F of the engine's rotation, if it holds a matrix.
    """

    t: np.ndarray
    position: np.ndarray
    quat_wxyz: np.ndarray
    velocity: np.ndarray
    omega_world: np.ndarray
    energy: np.ndarray | None = None
    angular_momentum: np.ndarray | None = None
    ortho_error: np.ndarray | None = None

    @staticmethod
    def from_trajectory(traj) -> "Samples":
        """From an rblog :class:`~rblog.contract.trajectory.Trajectory` (its own energy and L)."""
        return Samples(traj.t, traj.position, traj.quat_wxyz, traj.velocity, traj.angular_velocity,
                       traj.total_energy, traj.angular_momentum, traj.ortho_error)


@dataclass
class Problem:
    """A reference problem: bodies, world, how long, and the exact answer.

    Attributes:
        name: short id (``torque-free-intermediate``).  title: one line for tables.
        bodies: the bodies.  gravity: (3,) m/s^2.  duration: s.
        ground: None, or dict(height, restitution, friction) for the plane z = height.
        contacts: True when the problem needs the contact engine.
        primary: the error key plotted and ranked (see :meth:`evaluate`).
        conservative: energy and |L| are invariants (drifts are errors).
        sample_rate: logged samples per simulated second (s^-1); 0 logs every step.
        extend_for_timing: the motion can be run longer to time it (free bodies only).
        needs: the optional modules its exact answer is computed with (``scipy``: elliptic
            functions, DOP853), so that ``rblog bench`` can say what is missing before it runs.
    """

    name: str
    title: str
    bodies: list[BodySpec]
    gravity: tuple = (0.0, 0.0, 0.0)
    duration: float = 10.0
    ground: dict | None = None
    contacts: bool = False
    primary: str = "angle_rad"
    conservative: bool = True
    sample_rate: float = 100.0
    extend_for_timing: bool = True
    params: dict = field(default_factory=dict)
    needs: tuple = ()
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    # -- scene --
    def scene_toml(self, dt: float, duration: float | None = None) -> str:
        """rblog scene text of this problem at step ``dt``."""
        f = lambda v: "[" + ", ".join(repr(float(x)) for x in v) + "]"
        lines = ["[sim]", f"dt = {float(dt)!r}", f"duration = {float(duration or self.duration)!r}",
                 f"gravity = {f(self.gravity)}", ""]
        if self.ground is not None:
            g = self.ground
            lines += ["[ground]", f"height = {float(g.get('height', 0.0))!r}",
                      f"restitution = {float(g.get('restitution', 0.5))!r}",
                      f"friction = {float(g.get('friction', 0.5))!r}", ""]
        for b in self.bodies:
            lines += [b.toml(), ""]
        return "\n".join(lines)

    def log_every(self, dt: float) -> int:
        if self.sample_rate <= 0:
            return 1
        return max(1, int(round(1.0 / (self.sample_rate * dt))))

    @cached_property
    def torque_free(self) -> list[TorqueFree]:
        """The exact rotation of every body (valid while it touches nothing); cached, so the
        orientation reference is integrated once per problem."""
        return [TorqueFree(b.inertia_diag, b.omega_body, b.quat_wxyz) for b in self.bodies]

    @property
    def masses(self) -> np.ndarray:
        return np.array([b.mass for b in self.bodies])

    # -- invariants --
    def energy(self, s: Samples) -> np.ndarray:
        """(T,) kinetic + gravitational energy (potential zero at z = ground height or 0)."""
        if s.energy is not None:
            return np.asarray(s.energy)
        m = self.masses
        inertia = np.stack([b.inertia_diag for b in self.bodies])
        r = quat_to_matrix(s.quat_wxyz)
        wb = np.einsum("tnji,tnj->tni", r, s.omega_world)
        ke = 0.5 * np.einsum("n,tni->t", m, s.velocity**2) + 0.5 * np.einsum("ni,tni->t", inertia, wb**2)
        pe = -np.einsum("n,tni,i->t", m, s.position, np.asarray(self.gravity, float))
        return ke + pe

    def spin_momentum(self, s: Samples) -> np.ndarray:
        """(T, N, 3) world spin angular momentum of each body."""
        if s.angular_momentum is not None:
            return np.asarray(s.angular_momentum)
        inertia = np.stack([b.inertia_diag for b in self.bodies])
        r = quat_to_matrix(s.quat_wxyz)
        wb = np.einsum("tnji,tnj->tni", r, s.omega_world)
        return np.einsum("tnij,tnj->tni", r, inertia[None] * wb)

    def energy_scale(self) -> float:
        """|E| to divide energy errors by: kinetic + potential above the ground (J), > 0."""
        ke = sum(0.5 * b.mass * float(np.dot(b.velocity, b.velocity))
                 + 0.5 * float(np.sum(b.inertia_diag * np.asarray(b.omega_body, float) ** 2))
                 for b in self.bodies)
        g = np.asarray(self.gravity, float)
        base = self.ground.get("height", 0.0) if self.ground is not None else 0.0
        pe = sum(b.mass * abs(float(np.dot(g, np.asarray(b.position, float) - [0, 0, base])))
                 for b in self.bodies) if self.ground is not None else 0.0
        e = ke + pe
        if self.ground is None and e == 0.0:
            e = abs(float(self.energy(_initial_samples(self))[0]))
        return e if e > 0 else 1.0

    def invariants(self, s: Samples) -> dict:
        """Drift of energy, |L| per body and orthonormality over the samples."""
        e = self.energy(s)
        out = {"energy_drift_rel": None, "energy_growth_rel": None,
               "angular_momentum_drift_rel": None, "momentum_drift_rel": None,
               "ortho_error_max": None if s.ortho_error is None else float(np.max(s.ortho_error))}
        scale = self.energy_scale()
        out["energy_growth_rel"] = float((e[-1] - e[0]) / scale)
        if self.conservative:
            out["energy_drift_rel"] = float(np.max(np.abs(e - e[0])) / scale)
            lw = np.linalg.norm(self.spin_momentum(s), axis=-1)
            has = lw[0] > 0
            if np.any(has):
                out["angular_momentum_drift_rel"] = float(np.max(np.abs(lw[:, has] - lw[0, has]) / lw[0, has]))
        p = np.einsum("n,tni->ti", self.masses, s.velocity)
        if not np.any(self.gravity) and np.linalg.norm(p[0]) > 0:
            out["momentum_drift_rel"] = float(np.max(np.linalg.norm(p - p[0], axis=-1)) / np.linalg.norm(p[0]))
        return out

    # -- errors --
    def evaluate(self, s: Samples) -> dict:
        """Errors against the exact answer (keys by problem kind; ``primary`` is among them)."""
        return _EVALUATORS[self.params.get("kind", "free")](self, s)


def _initial_samples(p: Problem) -> Samples:
    b = p.bodies
    arr = lambda k: np.array([[getattr(x, k) for x in b]], float)
    return Samples(np.zeros(1), arr("position"), arr("quat_wxyz"), arr("velocity"),
                   np.array([[x.omega_world for x in b]]))


def _eval_free(p: Problem, s: Samples) -> dict:
    """Free bodies: angular velocity (body frame, relative to |w0|), orientation angle,
    position and velocity against the exact motion."""
    t = np.asarray(s.t, float)
    g = np.asarray(p.gravity, float)
    w_err, a_err, x_err, v_err = 0.0, 0.0, 0.0, 0.0
    for i, (b, tf) in enumerate(zip(p.bodies, p.torque_free)):
        w_exact = tf.omega_body(t)
        q_exact = tf.quat_wxyz(t)
        r = quat_to_matrix(s.quat_wxyz[:, i])
        w_num = np.einsum("tji,tj->ti", r, s.omega_world[:, i])  # R^T w_world
        scale = max(np.linalg.norm(b.omega_body), 1e-300)
        w_err = max(w_err, float(np.max(np.linalg.norm(w_num - w_exact, axis=-1))) / scale)
        a_err = max(a_err, float(np.max(rotation_angle_between(s.quat_wxyz[:, i], q_exact))))
        x0, v0 = np.asarray(b.position, float), np.asarray(b.velocity, float)
        x_exact = x0 + v0 * t[:, None] + 0.5 * g * t[:, None] ** 2
        v_exact = v0 + g * t[:, None]
        x_err = max(x_err, float(np.max(np.linalg.norm(s.position[:, i] - x_exact, axis=-1))))
        vs = max(np.linalg.norm(v0), np.linalg.norm(g) * t[-1], 1e-300)
        v_err = max(v_err, float(np.max(np.linalg.norm(s.velocity[:, i] - v_exact, axis=-1))) / vs)
    return {"omega_rel": w_err, "angle_rad": a_err, "position_m": x_err, "velocity_rel": v_err}


def _parabola_peak(t, z, k):
    """Vertex of the parabola through samples k-1, k, k+1 (exact for ballistic flight); z[k]
    itself where k is not an interior local maximum or the vertex falls outside the bracket."""
    if k <= 0 or k >= len(z) - 1 or z[k] < z[k - 1] or z[k] < z[k + 1]:
        return float(z[k])
    t0, t1, t2 = t[k - 1] - t[k], 0.0, t[k + 1] - t[k]
    z0, z1, z2 = z[k - 1] - z[k], 0.0, z[k + 1] - z[k]
    # z - z[k] = a s^2 + b s through (t0, z0), (0, 0), (t2, z2) with s = time - t[k]
    den = t0 * t2 * (t0 - t2)
    if den == 0.0:
        return float(z[k])
    a = (z0 * t2 - z2 * t0) / den
    b = (z2 * t0 * t0 - z0 * t2 * t2) / den
    if a >= 0.0:
        return float(z[k])
    s = -b / (2.0 * a)
    if not (t0 <= s <= t2):
        return float(z[k])
    return float(z[k] - b * b / (4.0 * a))


def find_apexes(t, z, n: int, min_height: float) -> list[float]:
    """The first n apex heights of a bouncing body's lowest point z(t) after its first impact:
    interior local maxima higher than ``min_height``, each refined by a parabola through the
    samples around it."""
    z = np.asarray(z, float)
    dz = np.diff(z)
    # first impact: the first local minimum (falling, then not falling)
    falls = np.nonzero((dz[:-1] < 0) & (dz[1:] >= 0))[0]
    if len(falls) == 0:
        return []
    start = falls[0] + 1
    peaks = [k for k in range(start + 1, len(z) - 1)
             if z[k] >= z[k - 1] and z[k] > z[k + 1] and z[k] > min_height]
    return [_parabola_peak(t, z, k) for k in peaks[:n]]


def _eval_bounce(p: Problem, s: Samples) -> dict:
    """Apex heights after each bounce against e^(2n) h0 (max abs error, m); a bounce that never
    came counts as an error of its whole exact height."""
    b = p.bodies[0]
    r = b.size[0]
    base = p.ground.get("height", 0.0)
    h0 = b.position[2] - r - base
    e = p.params["e"]
    n = p.params["bounces"]
    heights, _, _ = bouncing_ball_apexes(h0, e, n, -p.gravity[2])
    z = s.position[:, 0, 2] - r - base
    measured = find_apexes(np.asarray(s.t), z, n, min_height=0.01 * h0)
    errs = [abs(m - h) for m, h in zip(measured, heights)] + list(heights[len(measured):])
    return {"apex_m": float(max(errs)), "apex_measured_m": measured,
            "apex_exact_m": heights.tolist(), "penetration_max_m": max(0.0, -float(np.min(z)))}


def _eval_two_sphere(p: Problem, s: Samples) -> dict:
    """Velocities after the impact against the exact ones (relative to the approach speed)."""
    b1, b2 = p.bodies
    e = p.params["e"]
    v1, v2 = b1.velocity[0], b2.velocity[0]
    u1, u2 = two_sphere_velocities(b1.mass, b2.mass, v1, v2, e)
    vf = s.velocity[-1]
    exact = np.array([[u1, 0, 0], [u2, 0, 0]])
    err = float(np.max(np.linalg.norm(vf - exact, axis=-1))) / abs(v1 - v2)
    mu = b1.mass * b2.mass / (b1.mass + b2.mass)
    ke0 = 0.5 * (b1.mass * v1**2 + b2.mass * v2**2)
    ke_exact = ke0 - 0.5 * mu * (1 - e**2) * (v1 - v2) ** 2
    ke = 0.5 * np.einsum("n,ni->", p.masses, vf**2)
    return {"velocity_rel": err, "energy_after_rel": float(abs(ke - ke_exact) / ke0)}


def _eval_resting(p: Problem, s: Samples) -> dict:
    """A resting box must not move: max displacement (m), speed (m/s), tilt (rad)."""
    x0 = np.array([b.position for b in p.bodies], float)
    q0 = np.array([b.quat_wxyz for b in p.bodies], float)
    disp = float(np.max(np.linalg.norm(s.position - x0[None], axis=-1)))
    speed = float(np.max(np.linalg.norm(s.velocity, axis=-1)))
    tilt = float(np.max(rotation_angle_between(s.quat_wxyz, q0[None])))
    return {"position_m": disp, "speed_m_s": speed, "angle_rad": tilt}


def torqued_reference(b: BodySpec, t_end: float):
    """Dense solution (t -> (q wxyz, L world)) of a free body under a constant world torque:
    q' = 1/2 (0, w) (x) q, w = R I^-1 R^T L, L' = tau, by DOP853 at rtol 1e-13 (no closed form;
    its error, ~1e-12 over 10 s, is below every integrator measured on it but exact/exact4 at the
    smallest steps)."""
    from scipy.integrate import solve_ivp

    k = 1.0 / b.inertia_diag
    tau = np.asarray(b.torque, float)
    q0 = np.asarray(b.quat_wxyz, float)
    q0 = q0 / np.linalg.norm(q0)
    l0 = quat_to_matrix(q0) @ (b.inertia_diag * np.asarray(b.omega_body, float))

    def rhs(_, y):
        q, lw = y[:4], y[4:]
        r = quat_to_matrix(q)
        w = r @ (k * (r.T @ lw))
        return np.concatenate([0.5 * np.array([-w @ q[1:], *(q[0] * w + np.cross(w, q[1:]))]), tau])

    sol = solve_ivp(rhs, (0.0, t_end), np.concatenate([q0, l0]), method="DOP853",
                    rtol=ORIENTATION_RTOL, atol=ORIENTATION_ATOL, dense_output=True)
    if not sol.success:  # pragma: no cover - smooth problem
        raise RuntimeError(f"torqued reference failed: {sol.message}")
    return sol.sol


def _eval_torqued(p: Problem, s: Samples) -> dict:
    """A body under a constant world torque: body-frame angular velocity (relative to its largest
    exact magnitude) and attitude against the DOP853 reference."""
    t = np.asarray(s.t, float)
    w_err, a_err = 0.0, 0.0
    for i, b in enumerate(p.bodies):
        key = ("torqued", i, float(t[-1]))
        if key not in p._cache:
            p._cache[key] = torqued_reference(b, float(t[-1]))
        y = p._cache[key](t).T
        q_ex = y[:, :4] / np.linalg.norm(y[:, :4], axis=1, keepdims=True)
        r_ex = quat_to_matrix(q_ex)
        w_ex = np.einsum("tji,tj->ti", r_ex, y[:, 4:]) / b.inertia_diag
        r = quat_to_matrix(s.quat_wxyz[:, i])
        w_num = np.einsum("tji,tj->ti", r, s.omega_world[:, i])
        scale = float(np.max(np.linalg.norm(w_ex, axis=1)))
        w_err = max(w_err, float(np.max(np.linalg.norm(w_num - w_ex, axis=1))) / scale)
        a_err = max(a_err, float(np.max(rotation_angle_between(s.quat_wxyz[:, i], q_ex))))
    return {"omega_rel": w_err, "angle_rad": a_err}


_EVALUATORS = {"torqued": _eval_torqued, "free": _eval_free, "bounce": _eval_bounce, "two_sphere": _eval_two_sphere,
               "resting": _eval_resting}


# ---- the problems ------------------------------------------------------------------------------

def torque_free_intermediate() -> Problem:
    """The intermediate-axis (Dzhanibekov) box of samples/tumbling_box.toml: flips every ~8 s."""
    return Problem(
        "torque-free-intermediate", "torque-free box, intermediate axis (I=1,2,3; w0=0.05,2,0.05)",
        [BodySpec("box", "box", (0.3, 0.2, 0.1), 1.0, (1.0, 2.0, 3.0), (0.0, 0.0, 1.0),
                  omega_body=(0.05, 2.0, 0.05))],
        duration=20.0, primary="angle_rad", params={"kind": "free"}, needs=("scipy",))


def torque_free_generic() -> Problem:
    """A generic asymmetric body tumbling far from every axis (L^2 < 2E I2)."""
    return Problem(
        "torque-free-generic", "torque-free body, generic (I=1,1.5,2.2; w0=1.4,0.5,0.7)",
        [BodySpec("body", "box", (0.3, 0.2, 0.1), 1.0, (1.0, 1.5, 2.2), (0.0, 0.0, 0.0),
                  omega_body=(1.4, 0.5, 0.7))],
        duration=10.0, primary="angle_rad", params={"kind": "free"}, needs=("scipy",))


def free_fall() -> Problem:
    """samples/free_fall.toml: a tossed, spinning box under gravity (parabola + torque-free)."""
    return Problem(
        "free-fall", "free fall, tossed spinning box (samples/free_fall.toml)",
        [BodySpec("box", "box", (0.2, 0.1, 0.05), 8.0, None, (0.0, 0.0, 10.0),
                  velocity=(1.0, 0.0, 5.0), omega_body=(0.5, 3.0, 1.0))],
        gravity=(0.0, 0.0, -GRAVITY), duration=2.0, primary="position_m", params={"kind": "free"},
        needs=("scipy",))


def bouncing_ball(e: float = 0.8, h0: float = 1.0, bounces: int = 3) -> Problem:
    """A frictionless ball dropped from h0 onto the ground: apexes e^(2n) h0."""
    r = 0.1
    _, impacts, _ = bouncing_ball_apexes(h0, e, bounces)
    return Problem(
        "bouncing-ball", f"bouncing ball, e={e:g}, h0={h0:g} m: apex heights e^(2n) h0",
        [BodySpec("ball", "sphere", (r,), 1.0, None, (0.0, 0.0, h0 + r), restitution=e,
                  friction=0.0)],
        gravity=(0.0, 0.0, -GRAVITY), ground={"height": 0.0, "restitution": e, "friction": 0.0},
        duration=float(impacts[-1] + 0.05), contacts=True, primary="apex_m", conservative=False,
        sample_rate=0, extend_for_timing=False, params={"kind": "bounce", "e": e, "bounces": bounces})


def two_sphere_impact(m_ratio: float = 3.0, e: float = 0.7) -> Problem:
    """Head-on impact of two spheres (masses 1 and m_ratio), no gravity, restitution e."""
    r = 0.1
    return Problem(
        "two-sphere-impact", f"two-sphere head-on impact, masses 1:{m_ratio:g}, e={e:g}",
        [BodySpec("a", "sphere", (r,), 1.0, None, (-0.5, 0.0, 0.0), velocity=(2.0, 0.0, 0.0),
                  restitution=e, friction=0.0),
         BodySpec("b", "sphere", (r,), float(m_ratio), None, (0.5, 0.0, 0.0),
                  velocity=(-1.0, 0.0, 0.0), restitution=e, friction=0.0)],
        duration=1.0, contacts=True, primary="velocity_rel", conservative=False,
        extend_for_timing=False, params={"kind": "two_sphere", "e": e})


def resting_box() -> Problem:
    """A box placed exactly on the ground at rest: it must stay put."""
    return Problem(
        "resting-box", "resting box on the ground (must not move)",
        [BodySpec("box", "box", (0.5, 0.3, 0.2), 10.0, None, (0.0, 0.0, 0.2), restitution=0.5,
                  friction=0.5)],
        gravity=(0.0, 0.0, -GRAVITY), ground={"height": 0.0, "restitution": 0.5, "friction": 0.5},
        duration=2.0, contacts=True, primary="position_m", conservative=True,
        extend_for_timing=False, params={"kind": "resting"})


def torqued_body() -> Problem:
    """The generic body under a constant world torque (no closed form: DOP853 reference). Where
    splitting order shows: exact (Strang) is second order here, exact4 and rk4 fourth."""
    return Problem(
        "torqued-body", "generic body, constant world torque (0.3,-0.2,0.5) N m (DOP853 reference)",
        [BodySpec("body", "box", (0.3, 0.2, 0.1), 1.0, (1.0, 1.5, 2.2), (0.0, 0.0, 0.0),
                  omega_body=(1.4, 0.5, 0.7), torque=(0.3, -0.2, 0.5))],
        duration=10.0, primary="angle_rad", conservative=False, params={"kind": "torqued"},
        needs=("scipy",))


#: every reference problem, by name, in table order
PROBLEMS = {
    p().name: p for p in (torque_free_intermediate, torque_free_generic, torqued_body, free_fall,
                          bouncing_ball,
                          two_sphere_impact, resting_box)
}


def get_problem(name: str) -> Problem:
    return PROBLEMS[name]()


def contact_engine_status() -> tuple[bool, str]:
    """(available, reason): whether rblog's contact engine can be imported."""
    try:
        from rblog.engine import constants as _p  # noqa: F401
        from rblog.engine.contact import world as _w  # noqa: F401
    except Exception as e:  # ImportError now; anything the engine raises while loading
        return False, f"contact engine not available ({type(e).__name__}: {e})"
    return True, ""


__all__ = ["TorqueFree", "Problem", "BodySpec", "Samples", "PROBLEMS", "get_problem",
           "bouncing_ball_apexes", "two_sphere_velocities", "rotation_angle_between",
           "quat_to_matrix", "contact_engine_status"]
