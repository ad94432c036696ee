"""The integrators: one registry, one compiled step per integrator, used by every kind of scene.

Frames: ``q`` (wxyz) and ``R`` map body-frame vectors to the world frame. Angular momentum ``L``
is world frame; ``inv_inertia`` is the diagonal of I_body^-1 (principal axes).

Why this module is long: every integrator's stages are written out here, beside the registry
and the one free step that inlines them all (:func:`step_body`), so that each is read in one place.

Everything here is ``numba.njit(inline="always")`` over scalars and tuples, so that a kernel
stepping N bodies allocates nothing per step. Drift functions update ``quat_wxyz[i]`` and
``rotation[i]`` of the state arrays in place and keep the two consistent (except under the notes'
own schemes with orthonormalization off, where the integrator's R is the point of interest).

Derivations
-----------
Notes' scheme (``seed``): omega = R I_b^-1 R^T L, R <- R + h [omega]x R, then orthonormalize.
det(I + h[omega]x) = 1 + h^2 |omega|^2, so without orthonormalization det R grows like
exp(h * integral |omega|^2 dt): the body "stretches".

Notes' scheme on the quaternion (``seed-quat``): q <- q + h/2 (0, omega) (x) q. Normalized
(the default), R = R(q) is a rotation and omega = R I_b^-1 R^T L. With ``orthonormalize =
"none"`` |q| grows by sqrt(1 + h^2 |omega|^2 / 4) a step, and R is the homogeneous matrix of q,
R v = q (x) v (x) q* = |q|^2 Q v (Q the rotation of q / |q|): the body is shown turned by Q and
enlarged |q|^2 times in every direction, the notes' "stretch"; ||R^T R - I||_F = sqrt(3)
(|q|^4 - 1) is logged. The notes' inertia I_world = R I_b R^T with that R is then |q|^4 Q I_b Q^T,
which is exactly the inertia of the enlarged body at unchanged mass (moments scale with length
squared), so omega = I_world^-1 L = R^-T I_b^-1 R^-1 L = |q|^-4 Q I_b^-1 Q^T L
(:func:`rblog.engine.rotation.omega_world_stretched`): a body that grows while L is conserved
turns slower, as a skater opening her arms, and its energy L.omega/2 falls as |q|^-4. (The
shortcut I_world^-1 = R I_b^-1 R^T holds only for an orthonormal R; applied to R = |q|^2 Q it
gave omega |q|^4 times too fast, a feedback that sped the stretch up: issue 19.) The rotation
rate of the body is still omega, since q' = 1/2 (0, omega) q turns q v q* at omega whatever |q|.
Only the stretch is unphysical for a rigid body; given the stretch, the rest is consistent.

Splitting (``splitting``): the free-body Hamiltonian H = sum_k Lb_k^2 / (2 I_k) (Lb = R^T L) is a
sum of three exactly solvable parts. The flow of part k over time s rotates the body about its own
axis k by theta = s Lb_k / I_k (q <- q (x) (cos theta/2, sin theta/2 e_k)) and rotates Lb by
-theta about e_k, leaving L = R Lb unchanged. Strang composition 1(h/2) 2(h/2) 3(h) 2(h/2) 1(h/2)
is second order, symplectic and time-reversible; |L| (world) is untouched and R stays a product of
exact rotations, so both invariants hold to round-off (McLachlan 1993; Dullweber, Leimkuhler &
McLachlan 1997).

RK4 (``rk4``): classical RK4 on Euler's equations for the body momentum Lb = R^T L, the attitude by
the fourth-order commutator-free Lie group method (CF4) driven by the stage angular velocities,
then q turned about an axis normal to L so that R^T L points along the RK4 Lb (see
:func:`drift_rk4`; until issue 17 it was RK4 on q alone with omega = R(q) I^-1 R(q)^T L, 7-40x
less accurate at equal dt).

Exact (``exact``): the closed-form torque-free flow (:mod:`rblog.engine.exact`: Jacobi elliptic
functions for the body momentum, Carlson's integrals for the attitude), to round-off at any h.
With forces and torques: Strang splitting kick(h/2) exact-flow(h) kick(h/2), second order; the
world torque is constant over a step, so the only error is the splitting of the momentum kick
from the rotation. ``exact4``: Yoshida's triple jump of that step (h w1, h w0, h w1 with
w1 = 1 / (2 - 2^(1/3)), w0 = 1 - 2 w1), fourth order; without torque both are exact, and both
take the flow over h in one evaluation. The flow is evaluated from a per-body anchor (q_a, L_a)
at the elapsed time n h (:func:`drift_exact_anchored`, rblog.engine.state.FlowAnchors), not as a
one-step map of the carried q, so the run's error is one evaluation's rounding at any step count
(a carried q's ~1e-16 a step, amplified ~1e4 by the saddle, cost the intermediate-axis box 1e-10
at dt 1e-2); a torque kick or contact impulse changes L and so starts a new anchor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from numba import njit

from rblog.engine.constants import MAX_ROTATION_PER_STEP_RAD
from rblog.engine._numba_legacy.exact import FC_RJC, flow_constants, flow_eval, flow_row, free_flow_quat
from rblog.engine._numba_legacy.rotation import (
    gram_schmidt, load_mat, mat_to_quat, normalize4, omega_world, omega_world_stretched, polar,
    quat_mul, quat_to_mat, store_mat,
)

# orthonormalization codes
ORTHO_NONE = 0
ORTHO_POLAR = 1
ORTHO_GRAM_SCHMIDT = 2
ORTHO_NORMALIZE = 3  # quaternion normalization (seed-quat, splitting, rk4)
ORTHO_CODES = {"none": ORTHO_NONE, "polar": ORTHO_POLAR, "gram-schmidt": ORTHO_GRAM_SCHMIDT,
               "normalize": ORTHO_NORMALIZE}


@dataclass(frozen=True)
class Integrator:
    """One entry of the registry.

    Attributes:
        name: what a scene's ``[sim] integrator`` and ``--integrator`` say.
        code: the METHOD_* code the compiled kernels branch on.
        ortho_allowed: the ``orthonormalize`` options it accepts; ortho_default: the default.
        order: global order of accuracy in dt (torque-free rotation).
        summary: one line for ``--explain`` and the docs.
    """

    name: str
    code: int
    ortho_allowed: tuple[str, ...]
    ortho_default: str
    order: int
    summary: str


# integrator codes used by the kernels
METHOD_SEED = 0
METHOD_SEED_QUAT = 1
METHOD_SPLITTING = 2
METHOD_RK4 = 3
METHOD_EXACT = 4
METHOD_EXACT4 = 5
#: Yoshida (1990) triple-jump weights of the fourth-order composition of a symmetric step
YOSHIDA_W1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
YOSHIDA_W0 = 1.0 - 2.0 * YOSHIDA_W1

#: The registry. To add an integrator: give it a code and an entry here, a ``drift_*`` for its
#: torque-free rotation over h with L fixed (dispatched by :func:`drift_rotation`, which the
#: contact step uses for every body), and its whole free step, translation and torque included,
#: in :func:`step_body` (the free-body kernel, rblog.engine.free). In scenes with contacts the
#: contact step kicks P and L and translates by symplectic Euler for every integrator (see
#: rblog.engine.contact.step), so a free body's flight there is first order whatever the
#: integrator (issue: exact ballistic flight in every scene).
REGISTRY = {
    "seed": Integrator("seed", METHOD_SEED, ("polar", "gram-schmidt", "none"), "polar", 1,
                       "the notes: symplectic Euler on P and L, R += h [omega]x R, orthonormalized"),
    "seed-quat": Integrator("seed-quat", METHOD_SEED_QUAT, ("normalize", "none"), "normalize", 1,
                            "the notes on the quaternion: q += h/2 (0, omega) q, normalized"),
    "splitting": Integrator("splitting", METHOD_SPLITTING, ("normalize",), "normalize", 2,
                            "Strang splitting into exact axis rotations (symplectic)"),
    "rk4": Integrator("rk4", METHOD_RK4, ("normalize",), "normalize", 4,
                      "RK4 on Euler's equations, CF4 attitude aligned to L; exact constant-force translation"),
    "exact": Integrator("exact", METHOD_EXACT, ("normalize",), "normalize", 2,
                        "exact torque-free flow (elliptic functions); Strang kicks for torque"),
    "exact4": Integrator("exact4", METHOD_EXACT4, ("normalize",), "normalize", 4,
                         "exact torque-free flow in Yoshida's 4th-order composition with torque kicks"),
}
#: views of the registry, by name
METHOD_CODES = {k: v.code for k, v in REGISTRY.items()}
METHOD_NAMES = {v.code: k for k, v in REGISTRY.items()}
ORTHO_ALLOWED = {k: (v.ortho_allowed, v.ortho_default) for k, v in REGISTRY.items()}

#: small helpers (scalars in, tuples out): inlined by numba into the drift that calls them
jit = njit(inline="always", cache=True)
#: an integrator's drift: compiled once as a function of its own, which LLVM then inlines into
#: each kernel (``forceinline``: the LLVM ``alwaysinline`` attribute). numba's own IR inliner,
#: which ran recursively at every call site, made compiling the free kernel cost ~31 s for the
#: six integrators (~19 s for rk4 alone); this way ~1 s each, and the kernels run as fast
#: (benchmarks/RESULTS.md, issue 18 first run).
drift_jit = njit(cache=True, forceinline=True)


# Exact flows of H_k = Lb_k^2 / (2 I_k) over time s, given s/I_k: rotate the body about its own
# axis k by theta = s Lb_k / I_k and Lb by -theta. Half-angle sine/cosine for the quaternion, the
# full angle's from the double-angle formulas: one sin/cos pair per sub-step.
@jit
def _flow_x(w, x, y, z, b0, b1, b2, s_inv_i):
    th = s_inv_i * b0
    ch, sh = math.cos(0.5 * th), math.sin(0.5 * th)
    c, sn = ch * ch - sh * sh, 2.0 * ch * sh
    return (ch * w - sh * x, ch * x + sh * w, ch * y + sh * z, ch * z - sh * y,
            b0, c * b1 + sn * b2, c * b2 - sn * b1)


@jit
def _flow_y(w, x, y, z, b0, b1, b2, s_inv_i):
    th = s_inv_i * b1
    ch, sh = math.cos(0.5 * th), math.sin(0.5 * th)
    c, sn = ch * ch - sh * sh, 2.0 * ch * sh
    return (ch * w - sh * y, ch * x - sh * z, ch * y + sh * w, ch * z + sh * x,
            c * b0 - sn * b2, b1, c * b2 + sn * b0)


@jit
def _flow_z(w, x, y, z, b0, b1, b2, s_inv_i):
    th = s_inv_i * b2
    ch, sh = math.cos(0.5 * th), math.sin(0.5 * th)
    c, sn = ch * ch - sh * sh, 2.0 * ch * sh
    return (ch * w - sh * z, ch * x + sh * y, ch * y - sh * x, ch * z + sh * w,
            c * b0 + sn * b1, c * b1 - sn * b0, b2)


@drift_jit
def drift_seed(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h):
    """The notes' drift: R += h [omega]x R with omega = R I^-1 R^T L, then orthonormalize."""
    lx = angular_momentum[i, 0]
    ly = angular_momentum[i, 1]
    lz = angular_momentum[i, 2]
    ii = inv_inertia[i]
    m = load_mat(rotation, i)
    ox, oy, oz = omega_world(m, ii[0], ii[1], ii[2], lx, ly, lz)
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    # R <- R + h [omega]x R
    n = (
        m00 + h * (-oz * m10 + oy * m20), m01 + h * (-oz * m11 + oy * m21),
        m02 + h * (-oz * m12 + oy * m22),
        m10 + h * (oz * m00 - ox * m20), m11 + h * (oz * m01 - ox * m21),
        m12 + h * (oz * m02 - ox * m22),
        m20 + h * (-oy * m00 + ox * m10), m21 + h * (-oy * m01 + ox * m11),
        m22 + h * (-oy * m02 + ox * m12),
    )
    if ortho == ORTHO_POLAR:
        n = polar(n)
    elif ortho == ORTHO_GRAM_SCHMIDT:
        n = gram_schmidt(n)
    store_mat(rotation, i, n)
    # the quaternion is derived from R only when logged (see integrators.sync_quat)


@drift_jit
def drift_seed_quat(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h):
    """The notes' drift on the quaternion: q += h/2 (0, omega) (x) q, normalized unless ortho is
    none. Without normalization R = |q|^2 Q and omega = (R I_body R^T)^-1 L (module docstring)."""
    lx = angular_momentum[i, 0]
    ly = angular_momentum[i, 1]
    lz = angular_momentum[i, 2]
    ii = inv_inertia[i]
    w, x, y, z = quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3]
    m = load_mat(rotation, i)
    if ortho == ORTHO_NONE:
        ox, oy, oz = omega_world_stretched(m, ii[0], ii[1], ii[2], lx, ly, lz)
    else:
        ox, oy, oz = omega_world(m, ii[0], ii[1], ii[2], lx, ly, lz)
    dw, dx, dy, dz = quat_mul(0.0, ox, oy, oz, w, x, y, z)
    w, x, y, z = w + 0.5 * h * dw, x + 0.5 * h * dx, y + 0.5 * h * dy, z + 0.5 * h * dz
    if ortho != ORTHO_NONE:
        w, x, y, z = normalize4(w, x, y, z)
    quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3] = w, x, y, z
    store_mat(rotation, i, quat_to_mat(w, x, y, z))


@drift_jit
def drift_splitting(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h):
    """Strang splitting 1(h/2) 2(h/2) 3(h) 2(h/2) 1(h/2) of the free rotation into exact axis rotations."""
    lx = angular_momentum[i, 0]
    ly = angular_momentum[i, 1]
    lz = angular_momentum[i, 2]
    ii = inv_inertia[i]
    w, x, y, z = quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3]
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = load_mat(rotation, i)
    # body-frame angular momentum Lb = R^T L
    b0 = m00 * lx + m10 * ly + m20 * lz
    b1 = m01 * lx + m11 * ly + m21 * lz
    b2 = m02 * lx + m12 * ly + m22 * lz
    hh = 0.5 * h
    w, x, y, z, b0, b1, b2 = _flow_x(w, x, y, z, b0, b1, b2, hh * ii[0])
    w, x, y, z, b0, b1, b2 = _flow_y(w, x, y, z, b0, b1, b2, hh * ii[1])
    w, x, y, z, b0, b1, b2 = _flow_z(w, x, y, z, b0, b1, b2, h * ii[2])
    w, x, y, z, b0, b1, b2 = _flow_y(w, x, y, z, b0, b1, b2, hh * ii[1])
    w, x, y, z, b0, b1, b2 = _flow_x(w, x, y, z, b0, b1, b2, hh * ii[0])
    w, x, y, z = normalize4(w, x, y, z)
    quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3] = w, x, y, z
    store_mat(rotation, i, quat_to_mat(w, x, y, z))


@jit
def _mul_exp(w, x, y, z, vx, vy, vz):
    """q (x) exp(v): q followed by the body-frame rotation by |v| about v (series below 1e-4 rad)."""
    a2 = vx * vx + vy * vy + vz * vz
    if a2 < 1e-8:
        c = 1.0 - a2 / 8.0 + a2 * a2 / 384.0
        sf = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0  # sin(a/2) / a
    else:
        a = math.sqrt(a2)
        c = math.cos(0.5 * a)
        sf = math.sin(0.5 * a) / a
    return quat_mul(w, x, y, z, c, sf * vx, sf * vy, sf * vz)


@jit
def _torque_body(w, x, y, z, tx, ty, tz):
    """R(q)^T tau for a unit q."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = quat_to_mat(w, x, y, z)
    return (m00 * tx + m10 * ty + m20 * tz, m01 * tx + m11 * ty + m21 * tz,
            m02 * tx + m12 * ty + m22 * tz)


@jit
def _euler_rhs(b0, b1, b2, k0, k1, k2, t0, t1, t2):
    """dLb/dt = Lb x omega + tau_body, omega = I^-1 Lb (Euler's equations, body frame)."""
    w0, w1, w2 = k0 * b0, k1 * b1, k2 * b2
    return b1 * w2 - b2 * w1 + t0, b2 * w0 - b0 * w2 + t1, b0 * w1 - b1 * w0 + t2


@drift_jit
def drift_rk4(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h, tx=0.0, ty=0.0, tz=0.0):
    """Classical RK4 on Euler's equations for the body momentum Lb, the attitude by the fourth-order
    commutator-free Lie group method driven by the stage angular velocities, then q turned
    (minimally, about an axis normal to L) so that R^T L points along the RK4 Lb.

    L (world) is read at the start of the step; the world torque (tx, ty, tz) is constant over the
    step (the caller adds h tau to L). Why not RK4 on q alone (the former scheme, with
    omega = R(q) I^-1 R(q)^T L): there Lb = R(q)^T L is slaved to q, so q's stage errors feed every
    stage's omega; Euler's equations are quadratic in Lb and RK4 integrates them with a smaller
    error constant, and the final turn hands that accuracy to q (benchmarks/RESULTS.md, issue 17).

    Stages (k = I^-1, tau_b(q) = R(q)^T tau):
        Lb1 = R^T L;               w_i = k Lb_i;  d_i = Lb_i x w_i + tau_b(q_i)
        Lb2 = Lb1 + h/2 d1, q2 = q + h/2 q'(q, w1);  Lb3 = Lb1 + h/2 d2, q3 = q + h/2 q'(q2, w2)
        Lb4 = Lb1 + h d3,   q4 = q + h q'(q3, w3);   Lb' = Lb1 + h/6 (d1 + 2 d2 + 2 d3 + d4)
        (q'(q, w) = 1/2 q (x) (0, w): the classical stages of the coupled (q, Lb) system)
        q' = q exp(h B1) exp(h B2),  B1 = w1/4 + (w2 + w3)/6 - w4/12,  B2 = -w1/12 + (w2 + w3)/6 + w4/4
    (Celledoni, Marthinsen & Owren, FGCS 19 (2003), CF4 for q' = q w(t)), then the turn taking
    R(q')^T (L + h tau) to the direction of Lb'. The stage attitudes q_i only serve the torque.
    """
    lx = angular_momentum[i, 0]
    ly = angular_momentum[i, 1]
    lz = angular_momentum[i, 2]
    k0, k1, k2 = inv_inertia[i, 0], inv_inertia[i, 1], inv_inertia[i, 2]
    w, x, y, z = quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3]
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = load_mat(rotation, i)
    a0 = m00 * lx + m10 * ly + m20 * lz
    a1 = m01 * lx + m11 * ly + m21 * lz
    a2 = m02 * lx + m12 * ly + m22 * lz
    torqued = tx != 0.0 or ty != 0.0 or tz != 0.0
    hh = 0.5 * h
    # stage 1
    e0, e1, e2 = 0.0, 0.0, 0.0
    if torqued:
        e0, e1, e2 = m00 * tx + m10 * ty + m20 * tz, m01 * tx + m11 * ty + m21 * tz, m02 * tx + m12 * ty + m22 * tz
    d10, d11, d12 = _euler_rhs(a0, a1, a2, k0, k1, k2, e0, e1, e2)
    w10, w11, w12 = k0 * a0, k1 * a1, k2 * a2
    # stage 2
    b0, b1, b2 = a0 + hh * d10, a1 + hh * d11, a2 + hh * d12
    if torqued:  # classical stage attitude q2 = q + h/2 q'(q, w1)
        k1q = quat_mul(w, x, y, z, 0.0, 0.5 * w10, 0.5 * w11, 0.5 * w12)
        q2 = normalize4(w + hh * k1q[0], x + hh * k1q[1], y + hh * k1q[2], z + hh * k1q[3])
        e0, e1, e2 = _torque_body(q2[0], q2[1], q2[2], q2[3], tx, ty, tz)
    d20, d21, d22 = _euler_rhs(b0, b1, b2, k0, k1, k2, e0, e1, e2)
    w20, w21, w22 = k0 * b0, k1 * b1, k2 * b2
    # stage 3
    b0, b1, b2 = a0 + hh * d20, a1 + hh * d21, a2 + hh * d22
    if torqued:  # q3 = q + h/2 q'(q2, w2)
        k2q = quat_mul(q2[0], q2[1], q2[2], q2[3], 0.0, 0.5 * w20, 0.5 * w21, 0.5 * w22)
        q3 = normalize4(w + hh * k2q[0], x + hh * k2q[1], y + hh * k2q[2], z + hh * k2q[3])
        e0, e1, e2 = _torque_body(q3[0], q3[1], q3[2], q3[3], tx, ty, tz)
    d30, d31, d32 = _euler_rhs(b0, b1, b2, k0, k1, k2, e0, e1, e2)
    w30, w31, w32 = k0 * b0, k1 * b1, k2 * b2
    # stage 4
    b0, b1, b2 = a0 + h * d30, a1 + h * d31, a2 + h * d32
    if torqued:  # q4 = q + h q'(q3, w3)
        k3q = quat_mul(q3[0], q3[1], q3[2], q3[3], 0.0, 0.5 * w30, 0.5 * w31, 0.5 * w32)
        q4 = normalize4(w + h * k3q[0], x + h * k3q[1], y + h * k3q[2], z + h * k3q[3])
        e0, e1, e2 = _torque_body(q4[0], q4[1], q4[2], q4[3], tx, ty, tz)
    d40, d41, d42 = _euler_rhs(b0, b1, b2, k0, k1, k2, e0, e1, e2)
    w40, w41, w42 = k0 * b0, k1 * b1, k2 * b2
    g = h / 6.0
    n0 = a0 + g * (d10 + 2.0 * d20 + 2.0 * d30 + d40)
    n1 = a1 + g * (d11 + 2.0 * d21 + 2.0 * d31 + d41)
    n2 = a2 + g * (d12 + 2.0 * d22 + 2.0 * d32 + d42)
    # attitude: CF4
    c1, c2, c3 = 1.0 / 4.0, 1.0 / 6.0, -1.0 / 12.0
    w, x, y, z = _mul_exp(w, x, y, z, h * (c1 * w10 + c2 * (w20 + w30) + c3 * w40),
                          h * (c1 * w11 + c2 * (w21 + w31) + c3 * w41),
                          h * (c1 * w12 + c2 * (w22 + w32) + c3 * w42))
    w, x, y, z = _mul_exp(w, x, y, z, h * (c3 * w10 + c2 * (w20 + w30) + c1 * w40),
                          h * (c3 * w11 + c2 * (w21 + w31) + c1 * w41),
                          h * (c3 * w12 + c2 * (w22 + w32) + c1 * w42))
    w, x, y, z = normalize4(w, x, y, z)
    # turn q so that R^T L_end is along Lb': the rotation c with c u = v (u, v unit), q <- q c^-1
    ex, ey, ez = lx + h * tx, ly + h * ty, lz + h * tz
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = quat_to_mat(w, x, y, z)
    u0 = m00 * ex + m10 * ey + m20 * ez
    u1 = m01 * ex + m11 * ey + m21 * ez
    u2 = m02 * ex + m12 * ey + m22 * ez
    nu = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    nv = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if nu > 0.0 and nv > 0.0:
        iu, iv = 1.0 / nu, 1.0 / nv
        u0, u1, u2 = u0 * iu, u1 * iu, u2 * iu
        v0, v1, v2 = n0 * iv, n1 * iv, n2 * iv
        cw = 1.0 + u0 * v0 + u1 * v1 + u2 * v2
        cx, cy, cz = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
        w, x, y, z = quat_mul(w, x, y, z, cw, -cx, -cy, -cz)
    w, x, y, z = normalize4(w, x, y, z)
    quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3] = w, x, y, z
    store_mat(rotation, i, quat_to_mat(w, x, y, z))


@drift_jit
def drift_exact(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h):
    """The exact torque-free rotation over h (L world fixed), to round-off for any h."""
    ii = inv_inertia[i]
    w, x, y, z = free_flow_quat(quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3],
                                angular_momentum[i, 0], angular_momentum[i, 1],
                                angular_momentum[i, 2], ii[0], ii[1], ii[2], h)
    quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3] = w, x, y, z
    store_mat(rotation, i, quat_to_mat(w, x, y, z))


@njit(cache=True)
def anchor_constants(fc, r, aw, ax, ay, az, lx, ly, lz, k0, k1, k2, h):
    """Row r of ``fc``: the flow constants of the anchor (q_a, L), for steps of h."""
    # Lb = R(q_a)^T L at the anchor; backward in time, the forward flow of -Lb
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = quat_to_mat(aw, ax, ay, az)
    sg = 1.0 if h >= 0.0 else -1.0
    flow_constants(fc, r, sg * (m00 * lx + m10 * ly + m20 * lz),
                   sg * (m01 * lx + m11 * ly + m21 * lz), sg * (m02 * lx + m12 * ly + m22 * lz),
                   k0, k1, k2)


@jit
def anchored_quat(c, aw, ax, ay, az, t, pw, px, py, pz):
    """q(t) = q_a (x) c(t), unit: the flow at the elapsed time t >= 0 from the anchor q_a whose
    flow constants are the tuple c (exact.flow_row), with the sign that keeps it nearest the
    previous q (pw, px, py, pz): the logged q stays continuous. Returns (w, x, y, z, rj_c), rj_c
    the row's FC_RJC as exact.flow_eval returns it (the caller stores it). Scalars only (see
    exact.flow_eval: no reference counting)."""
    cw, cx, cy, cz, _, _, _, rj_c = flow_eval(c, t)
    w, x, y, z = quat_mul(aw, ax, ay, az, cw, cx, cy, cz)
    s = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    if w * pw + x * px + y * py + z * pz < 0.0:
        s = -s
    return w * s, x * s, y * s, z * s, rj_c


@jit
def anchor_holds(steps, anchor_dt, a0, a1, a2, h, lx, ly, lz):
    """Whether a body's flow anchor (its anchor_steps, anchor_dt_s and anchor_L_world a) still
    serves a step of h with world momentum L: set, the same step, L bitwise the anchor's."""
    return steps >= 0 and anchor_dt == h and a0 == lx and a1 == ly and a2 == lz


@jit
def drift_exact_anchored(quat_wxyz, rotation, angular_momentum, inv_inertia, i, h, anchor_quat_wxyz,
                         anchor_L_world, anchor_steps, anchor_dt_s, fc, r, fc_ok):
    """The exact torque-free rotation over h (L world fixed), evaluated from body i's anchor
    (the arrays of a rblog.engine.state.FlowAnchors, passed one by one: taking an array out of a
    tuple inside the loop costs a reference count each time) at the elapsed time
    (anchor_steps + 1) h: no rounding is carried from step to step (see rblog.engine.exact).

    The anchor is valid while anchor_steps >= 0, L equals anchor_L_world bitwise and h equals
    anchor_dt_s; otherwise the current (q, L) becomes the anchor (so a torque kick or a contact
    impulse, which change L, start a new one). Row r of ``fc`` ((rows, exact.N_FLOW)) caches the
    anchor's flow constants within a call: ``fc_ok[r]`` says they are the current anchor's (the
    caller clears it when the row is given to another body); a new anchor recomputes them.
    Inlined into the contact step (numba's inliner). The free-body kernel of the exact
    integrators does the same arithmetic written out in its own body (rblog.engine.free.
    _make_exact_kernel; bitwise equal, tests/engine/test_exact_anchored.py): an inlined
    function's array arguments become copies whose reference counts (atomic operations) numba
    does not always prune, and here they cost ~26 a step. The flow itself takes scalars only
    (:func:`anchored_quat`, exact.flow_eval)."""
    lx, ly, lz = angular_momentum[i, 0], angular_momentum[i, 1], angular_momentum[i, 2]
    if not anchor_holds(anchor_steps[i], anchor_dt_s[i], anchor_L_world[i, 0], anchor_L_world[i, 1],
                        anchor_L_world[i, 2], h, lx, ly, lz):
        for k in range(4):
            anchor_quat_wxyz[i, k] = quat_wxyz[i, k]
        anchor_L_world[i, 0], anchor_L_world[i, 1], anchor_L_world[i, 2] = lx, ly, lz
        anchor_steps[i] = 0
        anchor_dt_s[i] = h
        fc_ok[r] = False
    aw, ax, ay, az = (anchor_quat_wxyz[i, 0], anchor_quat_wxyz[i, 1],
                      anchor_quat_wxyz[i, 2], anchor_quat_wxyz[i, 3])
    if not fc_ok[r]:
        anchor_constants(fc, r, aw, ax, ay, az, lx, ly, lz, inv_inertia[i, 0], inv_inertia[i, 1],
                          inv_inertia[i, 2], h)
        fc_ok[r] = True
    n = anchor_steps[i] + 1
    w, x, y, z, rj_c = anchored_quat(flow_row(fc, r), aw, ax, ay, az, n * abs(h), quat_wxyz[i, 0],
                                     quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3])
    if rj_c >= 0.0 and fc[r, FC_RJC] < 0.0:
        fc[r, FC_RJC] = rj_c
    anchor_steps[i] = n
    quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3] = w, x, y, z
    store_mat(rotation, i, quat_to_mat(w, x, y, z))


@njit(cache=True)
def drift_rotation(method, ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h,
                   tx=0.0, ty=0.0, tz=0.0):
    """Advance body i's orientation over h with L (world) held fixed, by the integrator ``method``.

    The applied torque (tx, ty, tz) (world, constant over the step) is used only by RK4, whose
    stages see L(t) = L + t * torque; the other methods take torque as kicks around this drift.

    Args:
        method, ortho: METHOD_* and ORTHO_* codes.
        quat_wxyz: (N, 4), rotation: (N, 3, 3) updated in place for body i.
        angular_momentum: (N, 3) world frame, read only.  inv_inertia: (N, 3) diag(I_body^-1).
    """
    if method == METHOD_SEED:
        drift_seed(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h)
    elif method == METHOD_SEED_QUAT:
        drift_seed_quat(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h)
    elif method == METHOD_SPLITTING:
        drift_splitting(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h)
    elif method == METHOD_EXACT or method == METHOD_EXACT4:
        drift_exact(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h)
    else:
        drift_rk4(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h, tx, ty, tz)


@njit(cache=True)
def sync_quat(method, quat_wxyz, rotation, i):
    """Make q[i] describe R[i] for the integrator that advances R (seed); no-op for the others."""
    if method == METHOD_SEED:
        # the rotation part of R (its polar factor): without orthonormalization R = s Q drifts
        # in scale, and Shepperd's formula assumes unit scale. Divide out the largest entry
        # first so that a huge (but finite) R does not overflow in the cofactors.
        m = load_mat(rotation, i)
        big = 0.0
        for v in m:
            big = max(big, abs(v))
        if big > 0.0 and math.isfinite(big):
            inv = 1.0 / big
            m = (m[0] * inv, m[1] * inv, m[2] * inv, m[3] * inv, m[4] * inv, m[5] * inv,
                 m[6] * inv, m[7] * inv, m[8] * inv)
        w, x, y, z = mat_to_quat(polar(m))
        quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3] = w, x, y, z




@jit
def _strang_exact(quat_wxyz, rotation, angular_momentum, inv_inertia, i, h, tx, ty, tz, a_q, a_l,
                  a_n, a_dt, fc, r, fc_ok):
    """Kick L by tau h/2, the exact free flow over h (from the anchor), kick by tau h/2 (h may be
    negative). A kick changes L, so with torque every flow starts from a new anchor."""
    hh = 0.5 * h
    if tx != 0.0 or ty != 0.0 or tz != 0.0:
        angular_momentum[i, 0] += hh * tx
        angular_momentum[i, 1] += hh * ty
        angular_momentum[i, 2] += hh * tz
        drift_exact_anchored(quat_wxyz, rotation, angular_momentum, inv_inertia, i, h, a_q, a_l,
                             a_n, a_dt, fc, r, fc_ok)
        angular_momentum[i, 0] += hh * tx
        angular_momentum[i, 1] += hh * ty
        angular_momentum[i, 2] += hh * tz
    else:
        drift_exact_anchored(quat_wxyz, rotation, angular_momentum, inv_inertia, i, h, a_q, a_l,
                             a_n, a_dt, fc, r, fc_ok)


@jit
def turn_within_bound(dt, i, inv_inertia, rotation, angular_momentum):
    """False when body i turns more than MAX_ROTATION_PER_STEP_RAD in a step of dt (rad): the
    run has diverged (a torque of 1e40 N m, say), though its state is still finite
    (:func:`turn_within_bound_m` of the body's k, L and R)."""
    return turn_within_bound_m(dt, inv_inertia[i, 0], inv_inertia[i, 1], inv_inertia[i, 2],
                               angular_momentum[i, 0], angular_momentum[i, 1],
                               angular_momentum[i, 2], load_mat(rotation, i))


@jit
def turn_within_bound_m(dt, k0, k1, k2, lx, ly, lz, m):
    """:func:`turn_within_bound` from scalars: inverse moments k, world L and R (row-major
    9-tuple). The turn is |omega| dt with omega = R diag(k) R^T L (k = 1/I_body). For an
    orthonormal R, |omega| <= max(k) |L|, so that cheap bound is tested first and the exact value
    only above it (never in a sane run). An overflowing |L| or omega compares as too large (inf
    or NaN)."""
    kmax_dt = max(k0, max(k1, k2)) * dt
    lim2 = MAX_ROTATION_PER_STEP_RAD * MAX_ROTATION_PER_STEP_RAD
    if (lx * lx + ly * ly + lz * lz) * (kmax_dt * kmax_dt) <= lim2:
        return True
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    w0 = (m00 * lx + m10 * ly + m20 * lz) * k0 * dt
    w1 = (m01 * lx + m11 * ly + m21 * lz) * k1 * dt
    w2 = (m02 * lx + m12 * ly + m22 * lz) * k2 * dt
    return w0 * w0 + w1 * w1 + w2 * w2 <= lim2


@jit
def flight_exact(dt, im, x, y, z, px, py, pz, fx, fy, fz):
    """Position and momentum after dt under the constant force f (inverse mass im): the exact
    map x += h v + h^2 a / 2, v += h a (kick-drift-kick is the same map). Returns
    (x, y, z, px, py, pz)."""
    hh = 0.5 * dt * dt * im
    return (x + (dt * px * im + hh * fx), y + (dt * py * im + hh * fy),
            z + (dt * pz * im + hh * fz), px + dt * fx, py + dt * fy, pz + dt * fz)


@njit(inline="always")
def step_body(method, ortho, dt, i, inv_mass, inv_inertia, force_world, torque_world,
               quat_wxyz, rotation, angular_momentum, x, y, z, px, py, pz, a_q, a_l, a_n, a_dt,
               fc, r, fc_ok):
    """One step of free body i by integrator ``method``: orientation and L in place, position
    (x, y, z) and momentum (px, py, pz) passed and returned as scalars (so a caller may keep them
    in registers). Translation per integrator (the same scheme as :func:`drift_position`):
    ``seed``/``seed-quat`` symplectic Euler, ``splitting`` kick-drift-kick and ``rk4`` the exact
    constant-force step, which are the same map x += h v + h^2 a / 2, v += h a.
    ``exact``/``exact4`` evaluate the flow from body i's anchor (a_q, a_l, a_n, a_dt: the arrays
    of a rblog.engine.state.FlowAnchors; flow constants cached in row r of ``fc``, see
    :func:`drift_exact_anchored`); the other integrators ignore them.
    Returns (ok, x, y, z, px, py, pz); ok is False if the state became non-finite or the body
    turned more than MAX_ROTATION_PER_STEP_RAD in the step (:func:`turn_within_bound`)."""
    im = inv_mass[i]
    fx, fy, fz = force_world[i, 0], force_world[i, 1], force_world[i, 2]
    tx, ty, tz = torque_world[i, 0], torque_world[i, 1], torque_world[i, 2]
    if method == METHOD_SPLITTING:
        # kick half, drift, kick half
        hh = 0.5 * dt
        px += hh * fx
        py += hh * fy
        pz += hh * fz
        angular_momentum[i, 0] += hh * tx
        angular_momentum[i, 1] += hh * ty
        angular_momentum[i, 2] += hh * tz
        x += dt * px * im
        y += dt * py * im
        z += dt * pz * im
        drift_splitting(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, dt)
        px += hh * fx
        py += hh * fy
        pz += hh * fz
        angular_momentum[i, 0] += hh * tx
        angular_momentum[i, 1] += hh * ty
        angular_momentum[i, 2] += hh * tz
    elif method == METHOD_EXACT or method == METHOD_EXACT4:
        # translation: exact for a constant force (kick-drift-kick is that map)
        x, y, z, px, py, pz = flight_exact(dt, im, x, y, z, px, py, pz, fx, fy, fz)
        # rotation: Strang kick(h/2) exact(h) kick(h/2), or Yoshida's triple jump of it (without
        # torque both are the exact flow over h)
        if method == METHOD_EXACT or (tx == 0.0 and ty == 0.0 and tz == 0.0):
            _strang_exact(quat_wxyz, rotation, angular_momentum, inv_inertia, i, dt, tx, ty, tz,
                          a_q, a_l, a_n, a_dt, fc, r, fc_ok)
        else:
            _strang_exact(quat_wxyz, rotation, angular_momentum, inv_inertia, i,
                          YOSHIDA_W1 * dt, tx, ty, tz, a_q, a_l, a_n, a_dt, fc, r, fc_ok)
            _strang_exact(quat_wxyz, rotation, angular_momentum, inv_inertia, i,
                          YOSHIDA_W0 * dt, tx, ty, tz, a_q, a_l, a_n, a_dt, fc, r, fc_ok)
            _strang_exact(quat_wxyz, rotation, angular_momentum, inv_inertia, i,
                          YOSHIDA_W1 * dt, tx, ty, tz, a_q, a_l, a_n, a_dt, fc, r, fc_ok)
    elif method == METHOD_RK4:
        # translation: exact for a constant force; rotation: RK4 with L(t) = L + t tau
        x, y, z, px, py, pz = flight_exact(dt, im, x, y, z, px, py, pz, fx, fy, fz)
        drift_rk4(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, dt, tx, ty, tz)
        angular_momentum[i, 0] += dt * tx
        angular_momentum[i, 1] += dt * ty
        angular_momentum[i, 2] += dt * tz
    else:
        # the notes: forward Euler on P and L, then x and R from the new values
        px += dt * fx
        py += dt * fy
        pz += dt * fz
        x += dt * px * im
        y += dt * py * im
        z += dt * pz * im
        angular_momentum[i, 0] += dt * tx
        angular_momentum[i, 1] += dt * ty
        angular_momentum[i, 2] += dt * tz
        if method == METHOD_SEED:
            drift_seed(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, dt)
        else:
            drift_seed_quat(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, dt)
    # non-finite check: one sum covers position, momenta and part of the rotation
    chk = (x + y + z + px + py + pz + angular_momentum[i, 0] + angular_momentum[i, 1]
           + angular_momentum[i, 2] + rotation[i, 0, 0] + rotation[i, 1, 1] + rotation[i, 2, 2]
           + rotation[i, 0, 1])
    ok = math.isfinite(chk) and turn_within_bound(dt, i, inv_inertia, rotation, angular_momentum)
    return ok, x, y, z, px, py, pz
