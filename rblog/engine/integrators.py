"""The integrators: one registry, one compiled step per integrator, used by every kind of scene.

Frames: ``q`` (wxyz) and ``R`` map body-frame vectors to the world frame. Angular momentum ``L``
is world frame; ``inv_inertia`` is the diagonal of I_body^-1 (principal axes).

Everything here is ``numba.njit(inline="always")`` over scalars and tuples, so that a kernel
stepping N bodies allocates nothing per step. Drift functions update ``quat_wxyz[i]`` and
``rotation[i]`` of the state arrays in place and keep the two consistent (except under the notes'
own schemes with orthonormalization off, where the integrator's R is the point of interest).

Derivations
-----------
Notes' scheme (``seed``): omega = R I_b^-1 R^T L, R <- R + h [omega]x R, then orthonormalize.
det(I + h[omega]x) = 1 + h^2 |omega|^2, so without orthonormalization det R grows like
exp(h * integral |omega|^2 dt): the body "stretches".

Splitting (``splitting``): the free-body Hamiltonian H = sum_k Lb_k^2 / (2 I_k) (Lb = R^T L) is a
sum of three exactly solvable parts. The flow of part k over time s rotates the body about its own
axis k by theta = s Lb_k / I_k (q <- q (x) (cos theta/2, sin theta/2 e_k)) and rotates Lb by
-theta about e_k, leaving L = R Lb unchanged. Strang composition 1(h/2) 2(h/2) 3(h) 2(h/2) 1(h/2)
is second order, symplectic and time-reversible; |L| (world) is untouched and R stays a product of
exact rotations, so both invariants hold to round-off (McLachlan 1993; Dullweber, Leimkuhler &
McLachlan 1997).

RK4 (``rk4``): classical RK4 on dq/dt = 1/2 (0, omega) (x) q with omega = R(q) I_b^-1 R(q)^T L,
followed by normalization of q.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from numba import njit

from rblog.engine.rotation import (
    gram_schmidt, load_mat, mat_to_quat, normalize4, omega_world, polar, quat_mul, quat_to_mat,
    store_mat,
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
                      "classical RK4 on q with L(t) = L + t tau; exact constant-force translation"),
}
#: views of the registry, by name
METHOD_CODES = {k: v.code for k, v in REGISTRY.items()}
ORTHO_ALLOWED = {k: (v.ortho_allowed, v.ortho_default) for k, v in REGISTRY.items()}

jit = njit(inline="always", cache=True)


@jit
def _qdot(w, x, y, z, m_inv, lx, ly, lz):
    """dq/dt = 1/2 (0, omega) (x) q with omega from the normalized q."""
    n = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    m = quat_to_mat(w * n, x * n, y * n, z * n)
    ox, oy, oz = omega_world(m, m_inv[0], m_inv[1], m_inv[2], lx, ly, lz)
    dw, dx, dy, dz = quat_mul(0.0, ox, oy, oz, w, x, y, z)
    return 0.5 * dw, 0.5 * dx, 0.5 * dy, 0.5 * dz


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


@jit
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


@jit
def drift_seed_quat(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h):
    """The notes' drift on the quaternion: q += h/2 (0, omega) (x) q, normalized unless ortho is none."""
    lx = angular_momentum[i, 0]
    ly = angular_momentum[i, 1]
    lz = angular_momentum[i, 2]
    ii = inv_inertia[i]
    w, x, y, z = quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3]
    m = load_mat(rotation, i)
    ox, oy, oz = omega_world(m, ii[0], ii[1], ii[2], lx, ly, lz)
    dw, dx, dy, dz = quat_mul(0.0, ox, oy, oz, w, x, y, z)
    w, x, y, z = w + 0.5 * h * dw, x + 0.5 * h * dx, y + 0.5 * h * dy, z + 0.5 * h * dz
    if ortho != ORTHO_NONE:
        w, x, y, z = normalize4(w, x, y, z)
    quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3] = w, x, y, z
    store_mat(rotation, i, quat_to_mat(w, x, y, z))


@jit
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
def drift_rk4(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h, tx=0.0, ty=0.0, tz=0.0):
    """Classical RK4 on q with L(t) = L + t * torque, then normalization."""
    lx = angular_momentum[i, 0]
    ly = angular_momentum[i, 1]
    lz = angular_momentum[i, 2]
    ii = inv_inertia[i]
    w, x, y, z = quat_wxyz[i, 0], quat_wxyz[i, 1], quat_wxyz[i, 2], quat_wxyz[i, 3]
    a = 0.5 * h
    mx, my, mz = lx + a * tx, ly + a * ty, lz + a * tz
    k1 = _qdot(w, x, y, z, ii, lx, ly, lz)
    k2 = _qdot(w + a * k1[0], x + a * k1[1], y + a * k1[2], z + a * k1[3], ii, mx, my, mz)
    k3 = _qdot(w + a * k2[0], x + a * k2[1], y + a * k2[2], z + a * k2[3], ii, mx, my, mz)
    k4 = _qdot(w + h * k3[0], x + h * k3[1], y + h * k3[2], z + h * k3[3], ii,
               lx + h * tx, ly + h * ty, lz + h * tz)
    g = h / 6.0
    w = w + g * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
    x = x + g * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
    y = y + g * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
    z = z + g * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3])
    w, x, y, z = normalize4(w, x, y, z)
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




@njit(inline="always")
def step_body(method, ortho, dt, i, inv_mass, inv_inertia, force_world, torque_world,
               quat_wxyz, rotation, angular_momentum, x, y, z, px, py, pz):
    """One step of free body i by integrator ``method``: orientation and L in place, position
    (x, y, z) and momentum (px, py, pz) passed and returned as scalars (so a caller may keep them
    in registers). Translation per integrator (the same scheme as :func:`drift_position`):
    ``seed``/``seed-quat`` symplectic Euler, ``splitting`` kick-drift-kick and ``rk4`` the exact
    constant-force step, which are the same map x += h v + h^2 a / 2, v += h a.
    Returns (ok, x, y, z, px, py, pz); ok is False if the state became non-finite."""
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
    elif method == METHOD_RK4:
        # translation: exact for a constant force; rotation: RK4 with L(t) = L + t tau
        hh = 0.5 * dt * dt * im
        x += dt * px * im + hh * fx
        y += dt * py * im + hh * fy
        z += dt * pz * im + hh * fz
        px += dt * fx
        py += dt * fy
        pz += dt * fz
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
    return math.isfinite(chk), x, y, z, px, py, pz
