"""The exact flow of the torque-free rigid body, compiled: Jacobi elliptic functions for the body
angular momentum, Carlson's elliptic integrals for the attitude.

After Celledoni, Fasso, Safstrom & Zanna, "The exact computation of the free rigid body motion and
its use in splitting methods", SIAM J. Sci. Comput. 30(4) (2008): the body momentum by Jacobi's
solution, the attitude by the reconstruction through the angle about the (fixed) world L, written
with Carlson's R_F and R_J. The flow is evaluated from an anchor state (q_a, L_world) at the
elapsed time t: :func:`flow_constants` computes once what depends on the anchor only (the axes'
order and case, m, lam, the amplitudes, the anchor's phase and G, B0), :func:`flow_rotation` the
rotation since the anchor at any t, q(t) = q_a (x) c(t). Stepping by evaluating from a fixed anchor
at t = n h (rblog.engine.integrators.drift_exact_anchored) carries no state but the anchor, so
the rounding of one step is not fed into the next (near the separatrix a carried q's rounding,
~1e-16 a step, was amplified ~1e4 by the saddle); :func:`free_flow_body` is the one-step map, the
state itself as the anchor.

Frames and symbols
------------------
``q`` (wxyz) maps body to world; L (world) is constant; Lb = R^T L (body); k_i = 1 / I_i (the
diagonal of I^-1, any order). l = |L|, 2E = sum k_i Lb_i^2.

Working frame. The axes are relabelled by a proper signed permutation M (v' = M v_body) so that
axis 3' is the one about which Lb turns (its component never changes sign) and axis 2' is the
intermediate one: with the moments sorted I_a <= I_b <= I_c, ``case A`` (l^2 >= 2E I_b) takes
(a, b, c), ``case B`` (l^2 < 2E I_b) takes (c, b, a). In the working frame, with k1, k2, k3
the inverse moments of axes 1', 2', 3' and (no cancellation: every term of P~, Q~ carries the
same sign)

    P~ = L1^2 (k1 - k3) + L2^2 (k2 - k3)     (= k3 (2E J3 - l^2))
    Q~ = L2^2 (k1 - k2) + L3^2 (k1 - k3)     (= k1 (l^2 - 2E J1))
    D~ = L1^2 (k2 - k1) + L3^2 (k2 - k3)     (= k2 (l^2 - 2E J2), the distance to the separatrix)

the body momentum is (Landau & Lifshitz section 37, in these variables)

    L1 = a1 cn u,  L2 = sigma a2 sn u,  L3 = s a3 dn u,   u = u0 + lam t,
    a1^2 = P~ / (k1 - k3),  a2^2 = P~ / (k2 - k3),  a3^2 = Q~ / (k1 - k3),
    lam^2 = (k2 - k3) Q~,  m = (k1 - k2) P~ / ((k2 - k3) Q~),  1 - m = (k1 - k3) D~ / ((k2 - k3) Q~),

s = sign L3 and sigma = s (case A) or -s (case B) (substitute into Euler's equations). sn u0,
cn u0, dn u0 are read off the state, and the state at u0 + lam h follows from the addition
theorem, so the phase u0 itself is never needed. 1 - m is formed from D~ directly, so m near 1
(the separatrix) loses nothing to cancellation.

Attitude. With Euler angles about the world L (z-x-z: R = A^T Rz(phi) Rx(theta) Rz(psi) M,
Lb' = l (sin theta sin psi, sin theta cos psi, cos theta)), Landau's dphi/dt =
l (L1^2 k1 + L2^2 k2) / (L1^2 + L2^2) becomes, after substituting the solution,

    dphi/dt = l k3 + l (k1 - k3) / (1 + n sn^2 u),   n = (k1 - k2) / (k2 - k3) >= 0,

so phi(t + h) - phi(t) = l k3 h + l (k1 - k3) / lam * [Pi(-n; am u1 | m) - Pi(-n; am u0 | m)],
the incomplete elliptic integral of the third kind, for |am| <= pi/2 (DLMF 19.25.14)

    Pi(-n; phi | m) = S R_F(C^2, D^2, 1) - (n/3) S^3 R_J(C^2, D^2, 1, 1 + n S^2),

S = sin phi = sn, C = cn, D = dn, and quasi-periodic beyond (Pi(phi + pi) = Pi(phi) + 2 Pi_c). As
the first term integrates to lam h exactly, the step uses
dphi = l k1 h - l (k1 - k3) n / lam * [G(am u1) - G(am u0)], G = S^3 R_J(...) / 3: the difference of
the two ends is multiplied by n / lam, which stays bounded as a body nears symmetry (n -> 0 while
the precession lam -> 0), where the first form would multiply round-off by 1 / lam. The
step's rotation is then R(t+h) = R(t) M^T B0^T Rz(dphi) B1 M, with B = Rx(theta) Rz(psi) built from
Lb' at either end (unnormalized half-angle quaternions, no trigonometric calls).

Numerics. sn, cn, dn(r | m) by descending Landen transformations (A&S 16.12) until m < 1e-9, then
the first-order expansion in m (A&S 16.13), after reducing the argument by the half period 2K (so
every evaluation sees an argument in [0, 2K)); R_F, R_J by Carlson's duplication (Carlson 1995,
DLMF 19.36.1-2) and the series of DLMF 19.36.1-2. Degenerate states are exact rotations: steady
rotation about a principal axis (Lb x omega = 0 exactly: also every symmetric body with Lb in its
isotropic plane, and the sphere), and negative h (the flow backward is the forward flow of -L).

Why this module is long: the flow is one derivation (the elliptic functions with their Landen
descent, Carlson's R_F and R_J, the attitude reconstruction, the per-anchor constants and their
evaluation at any elapsed time); its parts share the case analysis (branches A and B, the
separatrix, steady rotation) and the row layout of the cached constants, which would otherwise
be passed between modules.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rblog.engine.constants import (
    CARLSON_SERIES_TOL, LANDEN_BASE_PARAMETER, LANDEN_MAX_LEVELS,
)

jit = njit(inline="always", cache=True)

HALF_PI = 0.5 * math.pi


@jit
def _landen_down(b):
    """One descending Landen step from b = sqrt(1 - m): (mu, b') with m' = mu^2,
    b' = sqrt(1 - m') = 2 sqrt(b) / (1 + b) (no cancellation)."""
    mu = (1.0 - b) / (1.0 + b)
    return mu, 2.0 * math.sqrt(b) / (1.0 + b)


@jit
def _landen_up(sn, cn, dn, mu):
    """sn, cn, dn at parameter m from those at m' = mu^2, argument scaled by 1 + mu (A&S 16.12.2-4);
    1 - mu sn^2 written as (1 - mu) + mu cn^2 so that dn keeps its relative accuracy."""
    den = 1.0 / (1.0 + mu * sn * sn)
    return ((1.0 + mu) * sn * den, cn * dn * den, ((1.0 - mu) + mu * cn * cn) * den)


@jit
def landen_descent(m, m1):
    """The descending Landen transformations of parameter m = 1 - m1 > 0 (m1 > 0) down to a
    parameter below LANDEN_BASE_PARAMETER: (lev, scale, m_base, mu_0 .. mu_11), lev levels
    (at most LANDEN_MAX_LEVELS; mu_k = 0 beyond), scale = prod(1 + mu_k). A function of m only:
    the exact flow computes it once per anchor (flow_constants)."""
    b = math.sqrt(m1)
    mu0 = mu1 = mu2 = mu3 = mu4 = mu5 = mu6 = mu7 = mu8 = mu9 = mu10 = mu11 = 0.0
    scale = 1.0
    lev = 0
    while m >= LANDEN_BASE_PARAMETER and lev < LANDEN_MAX_LEVELS:
        mu, b = _landen_down(b)
        scale *= 1.0 + mu
        if lev == 0:
            mu0 = mu
        elif lev == 1:
            mu1 = mu
        elif lev == 2:
            mu2 = mu
        elif lev == 3:
            mu3 = mu
        elif lev == 4:
            mu4 = mu
        elif lev == 5:
            mu5 = mu
        elif lev == 6:
            mu6 = mu
        elif lev == 7:
            mu7 = mu
        elif lev == 8:
            mu8 = mu
        elif lev == 9:
            mu9 = mu
        elif lev == 10:
            mu10 = mu
        else:
            mu11 = mu
        m = mu * mu
        lev += 1
    return lev, scale, m, mu0, mu1, mu2, mu3, mu4, mu5, mu6, mu7, mu8, mu9, mu10, mu11


@jit
def sncndn_landen(u, lev, scale, m, mu0, mu1, mu2, mu3, mu4, mu5, mu6, mu7, mu8, mu9, mu10, mu11):
    """:func:`sncndn` from the descent of :func:`landen_descent` (m its base parameter)."""
    # base: parameter m < 1e-9, A&S 16.13 to first order in m (error O(m^2))
    kb = HALF_PI * (1.0 + 0.25 * m)  # K(m) to first order
    big_k = scale * kb
    v = u / scale
    j = int(v / (2.0 * kb))
    v -= 2.0 * kb * j
    if v < 0.0:  # rounding at the boundary
        v += 2.0 * kb
        j -= 1
    sv, cv = math.sin(v), math.cos(v)
    corr = 0.25 * m * (v - sv * cv)
    sn = sv - corr * cv
    cn = cv + corr * sv
    dn = 1.0 - 0.5 * m * sv * sv
    # back up the levels, deepest first (a level with mu = 0 was never taken and is skipped)
    if lev > 11:
        sn, cn, dn = _landen_up(sn, cn, dn, mu11)
    if lev > 10:
        sn, cn, dn = _landen_up(sn, cn, dn, mu10)
    if lev > 9:
        sn, cn, dn = _landen_up(sn, cn, dn, mu9)
    if lev > 8:
        sn, cn, dn = _landen_up(sn, cn, dn, mu8)
    if lev > 7:
        sn, cn, dn = _landen_up(sn, cn, dn, mu7)
    if lev > 6:
        sn, cn, dn = _landen_up(sn, cn, dn, mu6)
    if lev > 5:
        sn, cn, dn = _landen_up(sn, cn, dn, mu5)
    if lev > 4:
        sn, cn, dn = _landen_up(sn, cn, dn, mu4)
    if lev > 3:
        sn, cn, dn = _landen_up(sn, cn, dn, mu3)
    if lev > 2:
        sn, cn, dn = _landen_up(sn, cn, dn, mu2)
    if lev > 1:
        sn, cn, dn = _landen_up(sn, cn, dn, mu1)
    if lev > 0:
        sn, cn, dn = _landen_up(sn, cn, dn, mu0)
    return sn, cn, dn, j, big_k


@jit
def sncndn(u, m, m1):
    """Jacobi sn, cn, dn of u >= 0 at parameter m = 1 - m1, with the argument reduced by the half
    period: returns (sn r, cn r, dn r, j, K) where u = 2 K j + r, 0 <= r < 2K (so
    sn u = (-1)^j sn r, cn u = (-1)^j cn r, dn u = dn r). K = inf (j = 0) when m1 = 0."""
    if m1 <= 0.0:  # m = 1: sn = tanh, cn = dn = sech, no period
        t = math.tanh(u)
        c = 1.0 / math.cosh(u) if u < 700.0 else 0.0
        return t, c, c, 0, math.inf
    # descending Landen: parameters mu_1..mu_L (at most LANDEN_MAX_LEVELS), scale prod(1 + mu)
    lev, scale, mb, mu0, mu1, mu2, mu3, mu4, mu5, mu6, mu7, mu8, mu9, mu10, mu11 = landen_descent(m, m1)
    return sncndn_landen(u, lev, scale, mb, mu0, mu1, mu2, mu3, mu4, mu5, mu6, mu7, mu8, mu9, mu10,
                         mu11)


@jit
def _rc1(t):
    """Carlson's R_C(1, 1 + t) for t > -1: atan(sqrt t)/sqrt t, atanh(sqrt -t)/sqrt -t, series
    near 0."""
    if abs(t) < 1e-3:
        return 1.0 + t * (-1.0 / 3.0 + t * (0.2 + t * (-1.0 / 7.0 + t * (1.0 / 9.0 + t * (-1.0 / 11.0)))))
    if t > 0.0:
        r = math.sqrt(t)
        return math.atan(r) / r
    r = math.sqrt(-t)
    return math.atanh(r) / r


@jit
def carlson_rf_rj(x, y, z, p):
    """(R_F(x, y, z), R_J(x, y, z, p)) for x, y, z >= 0 (at most one zero), p > 0, by one shared
    duplication (DLMF 19.36.1-2; Carlson, Numer. Algorithms 10 (1995)): the x, y, z sequence is the
    same for both. Stops when the arguments agree to CARLSON_SERIES_TOL relative, then the series
    (seventh order for R_F, fifth for R_J; measured error <= 1.8e-15 relative, see the constant)."""
    a0f = (x + y + z) / 3.0
    a0j = (x + y + z + 2.0 * p) / 5.0
    af = a0f
    aj = a0j
    delta = (p - x) * (p - y) * (p - z)
    qf = max(abs(a0f - x), abs(a0f - y), abs(a0f - z))
    qj = max(abs(a0j - x), abs(a0j - y), abs(a0j - z), abs(a0j - p))
    xn, yn, zn, pn = x, y, z, p
    fac = 1.0  # 4^-n
    s = 0.0
    e_fac = delta  # 4^-3n delta
    for _ in range(40):
        if fac * qf <= CARLSON_SERIES_TOL * af and fac * qj <= CARLSON_SERIES_TOL * aj:
            break
        sx, sy, sz, sp = math.sqrt(xn), math.sqrt(yn), math.sqrt(zn), math.sqrt(pn)
        lam = sx * sy + sy * sz + sz * sx
        d = (sp + sx) * (sp + sy) * (sp + sz)
        s += fac * _rc1(e_fac / (d * d)) / d
        fac *= 0.25
        e_fac *= 1.0 / 64.0
        xn = 0.25 * (xn + lam)
        yn = 0.25 * (yn + lam)
        zn = 0.25 * (zn + lam)
        pn = 0.25 * (pn + lam)
        af = 0.25 * (af + lam)
        aj = 0.25 * (aj + lam)
    # R_F series
    xf = (a0f - x) * fac / af
    yf = (a0f - y) * fac / af
    zf = -xf - yf
    e2 = xf * yf - zf * zf
    e3 = xf * yf * zf
    rf = (1.0 - e2 / 10.0 + e3 / 14.0 + e2 * e2 / 24.0 - 3.0 * e2 * e3 / 44.0
          - 5.0 * e2 * e2 * e2 / 208.0 + 3.0 * e3 * e3 / 104.0 + e2 * e2 * e3 / 16.0) / math.sqrt(af)
    # R_J series
    xj = (a0j - x) * fac / aj
    yj = (a0j - y) * fac / aj
    zj = (a0j - z) * fac / aj
    pj = -0.5 * (xj + yj + zj)
    f2 = xj * yj + xj * zj + yj * zj - 3.0 * pj * pj
    f3 = xj * yj * zj + 2.0 * f2 * pj + 4.0 * pj * pj * pj
    f4 = (2.0 * xj * yj * zj + f2 * pj + 3.0 * pj * pj * pj) * pj
    f5 = xj * yj * zj * pj * pj
    ser = (1.0 - 3.0 * f2 / 14.0 + f3 / 6.0 + 9.0 * f2 * f2 / 88.0 - 3.0 * f4 / 22.0
           - 9.0 * f2 * f3 / 52.0 + 3.0 * f5 / 26.0)
    rj = fac * ser / (aj * math.sqrt(aj)) + 6.0 * s
    return rf, rj


@jit
def _rj_series(a0, x, y, z, p, fac, a):
    """The fifth-order series of R_J after the duplications (DLMF 19.36.2), times 4^-n A^-3/2."""
    xj = (a0 - x) * fac / a
    yj = (a0 - y) * fac / a
    zj = (a0 - z) * fac / a
    pj = -0.5 * (xj + yj + zj)
    f2 = xj * yj + xj * zj + yj * zj - 3.0 * pj * pj
    f3 = xj * yj * zj + 2.0 * f2 * pj + 4.0 * pj * pj * pj
    f4 = (2.0 * xj * yj * zj + f2 * pj + 3.0 * pj * pj * pj) * pj
    f5 = xj * yj * zj * pj * pj
    ser = (1.0 - 3.0 * f2 / 14.0 + f3 / 6.0 + 9.0 * f2 * f2 / 88.0 - 3.0 * f4 / 22.0
           - 9.0 * f2 * f3 / 52.0 + 3.0 * f5 / 26.0)
    return fac * ser / (a * math.sqrt(a))


@jit
def _euler_quat(l1, l2, l3, ell):
    """A positive multiple of the quaternion of B = Rx(theta) Rz(psi), B Lb' = l e3, with
    Lb' = l (sin theta sin psi, sin theta cos psi, cos theta). Each factor is the unnormalized
    half-angle form (1 + cos, sin) times a positive scale, or (sin, 1 - cos) where cos < 0 (no
    cancellation either way): qz(psi) ~ (rho + L2, 0, 0, L1) or (L1, 0, 0, rho - L2) and
    qx(theta) ~ (l + L3, rho, 0, 0) or (rho, l - L3, 0, 0), rho = |(L1, L2)|. The step's rotation is
    normalized once, at the end (the sign of a quaternion is immaterial)."""
    rho = math.sqrt(l1 * l1 + l2 * l2)
    if l3 >= 0.0:
        xw, xx = ell + l3, rho
    else:
        xw, xx = rho, ell - l3
    if l2 >= 0.0:
        zw, zz = rho + l2, l1
    else:
        zw, zz = l1, rho - l2
    # (xw, xx, 0, 0) (x) (zw, 0, 0, zz)
    return xw * zw, xx * zw, -xx * zz, xw * zz


@jit
def _qmul(aw, ax, ay, az, bw, bx, by, bz):
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


#: Columns of a row of flow constants (:func:`flow_constants`): everything the flow from an anchor
#: state needs that does not depend on the elapsed time. A steady rotation (FC_STEADY = 1) keeps
#: the body-frame omega in FC_W0..FC_W2, |omega| in FC_WN and Lb in FC_B0..FC_B2 (columns 1-7
#: reused).
FC_STEADY = 0
FC_I1, FC_I2, FC_I3 = 1, 2, 3  # the body axes of working axes 1', 2', 3' (as floats)
FC_W0, FC_W1, FC_W2, FC_WN = 1, 2, 3, 4
FC_B0, FC_B1, FC_B2 = 5, 6, 7
FC_SGN3 = 4  # sign of axis 3' against its body axis (general case)
FC_K1 = 5  # k1 (inverse moment of axis 1')
FC_ELL = 6  # l = |L|
FC_D13 = 7  # k1 - k3
FC_M, FC_M1 = 8, 9  # parameter m and 1 - m
FC_LAM = 10  # phase rate lam (1/s)
FC_AMP1, FC_AMP2, FC_AMP3 = 11, 12, 13  # amplitudes a1, a2, a3 of L1, L2, L3 (kg m^2/s)
FC_N = 14  # n = (k1 - k2) / (k2 - k3)
FC_SIGMA, FC_S = 15, 16  # sign of L2's sn, sign of L3
FC_SN0, FC_CN0, FC_DN0 = 17, 18, 19  # sn, cn, dn at the anchor's phase u0
FC_G0 = 20  # G(am u0) = S^3 R_J(C^2, D^2, 1, 1 + n S^2) / 3 at the anchor (reduced amplitude)
FC_AW, FC_AX, FC_AY, FC_AZ = 21, 22, 23, 24  # B0 (the anchor's Euler rotation), unnormalized
FC_RJC = 25  # R_J(0, 1 - m, 1, 1 + n) (the half period's share), -1 until first needed
FC_LEV, FC_SCALE, FC_MB = 26, 27, 28  # the Landen descent of m (landen_descent; m1 > 0 only)
FC_MU0 = 29  # its mu_0 .. mu_11 in FC_MU0 .. FC_MU0 + 11
N_FLOW = 41
assert FC_MU0 + 12 == N_FLOW  # flow_row lists the columns one by one


@njit(cache=True)
def carlson_rj1(x, y, p):
    """R_J(x, y, 1, p) alone (x, y >= 0, at most one zero; p > 0): the R_J half of
    :func:`carlson_rf_rj`, same duplication and stopping rule."""
    a0 = (x + y + 1.0 + 2.0 * p) / 5.0
    q = max(abs(a0 - x), abs(a0 - y), abs(a0 - 1.0), abs(a0 - p))
    e = (p - x) * (p - y) * (p - 1.0)
    xa, ya, za, pa, aa = x, y, 1.0, p, a0
    fac = 1.0
    s = 0.0
    for _ in range(40):
        if fac * q <= CARLSON_SERIES_TOL * aa:
            break
        sx, sy, sz, sp = math.sqrt(xa), math.sqrt(ya), math.sqrt(za), math.sqrt(pa)
        la = sx * sy + sy * sz + sz * sx
        da = (sp + sx) * (sp + sy) * (sp + sz)
        s += fac * _rc1(e / (da * da)) / da
        fac *= 0.25
        e *= 1.0 / 64.0
        xa, ya, za, pa, aa = 0.25 * (xa + la), 0.25 * (ya + la), 0.25 * (za + la), 0.25 * (pa + la), 0.25 * (aa + la)
    return _rj_series(a0, x, y, 1.0, p, fac, aa) + 6.0 * s


@njit(cache=True)
def flow_constants(fc, r, b0, b1, b2, k0, k1, k2):
    """Row r of ``fc`` ((rows, N_FLOW) float64): the constants of the torque-free flow forward in
    time of a body whose body-frame momentum at the anchor is Lb = (b0, b1, b2), with inverse
    principal moments (k0, k1, k2) (any order). :func:`flow_rotation` then evaluates the flow
    from the anchor at any elapsed time. (The flow backward is the forward flow of -Lb.)"""
    # steady rotation (Lb parallel to omega): the rotation is exp(t omega)
    if b1 * b2 * (k2 - k1) == 0.0 and b2 * b0 * (k0 - k2) == 0.0 and b0 * b1 * (k1 - k0) == 0.0:
        w0, w1, w2 = b0 * k0, b1 * k1, b2 * k2
        fc[r, FC_STEADY] = 1.0
        fc[r, FC_W0], fc[r, FC_W1], fc[r, FC_W2] = w0, w1, w2
        fc[r, FC_WN] = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        fc[r, FC_B0], fc[r, FC_B1], fc[r, FC_B2] = b0, b1, b2
        return
    # sort the axes by inertia: ia (smallest I, largest k), ib, ic
    ia, ib, ic = 0, 1, 2
    ka, kb, kc = k0, k1, k2
    la, lb, lc = b0, b1, b2
    if ka < kb:
        ia, ib, ka, kb, la, lb = ib, ia, kb, ka, lb, la
    if kb < kc:
        ib, ic, kb, kc, lb, lc = ic, ib, kc, kb, lc, lb
    if ka < kb:
        ia, ib, ka, kb, la, lb = ib, ia, kb, ka, lb, la
    # parity of (ia, ib, ic) as a permutation of (0, 1, 2)
    par = 1.0 if (ib - ia) * (ic - ia) * (ic - ib) > 0 else -1.0
    d_t = la * la * (kb - ka) + lc * lc * (kb - kc)  # k_b (l^2 - 2E I_b)
    if d_t >= 0.0:  # case A: axis 3' = c
        i1, i2, i3 = ia, ib, ic
        kk1, kk2, kk3 = ka, kb, kc
        l1, l2, l3 = la, lb, lc * par
        sgn3 = par
        case_sign = 1.0
    else:  # case B: axis 3' = a
        i1, i2, i3 = ic, ib, ia
        kk1, kk2, kk3 = kc, kb, ka
        l1, l2, l3 = lc, lb, -la * par
        sgn3 = -par
        case_sign = -1.0
    ell = math.sqrt(l1 * l1 + l2 * l2 + l3 * l3)
    d13 = kk1 - kk3
    d23 = kk2 - kk3
    d12 = kk1 - kk2
    p_t = l1 * l1 * d13 + l2 * l2 * d23
    q_t = l2 * l2 * d12 + l3 * l3 * d13
    m = d12 * p_t / (d23 * q_t)
    m1 = d13 * d_t / (d23 * q_t)
    if m1 < 0.0:  # rounding on the separatrix
        m1 = 0.0
    if m > 1.0:
        m = 1.0
    amp1 = math.sqrt(p_t / d13)
    amp2 = math.sqrt(p_t / d23)
    amp3 = math.sqrt(q_t / d13)
    s = 1.0 if l3 >= 0.0 else -1.0
    sigma = s * case_sign
    cn0 = l1 / amp1
    sn0 = sigma * l2 / amp2
    dn0 = abs(l3) / amp3
    nn = d12 / d23
    g0 = 0.0
    if nn != 0.0:
        s_red0 = sn0 if cn0 >= 0.0 else -sn0
        s20 = s_red0 * s_red0
        g0 = s_red0 * s20 * carlson_rj1(cn0 * cn0, dn0 * dn0, 1.0 + nn * s20) / 3.0
    aw, ax, ay, az = _euler_quat(l1, l2, l3, ell)
    fc[r, FC_STEADY] = 0.0
    fc[r, FC_I1], fc[r, FC_I2], fc[r, FC_I3] = float(i1), float(i2), float(i3)
    fc[r, FC_SGN3] = sgn3
    fc[r, FC_K1] = kk1
    fc[r, FC_ELL] = ell
    fc[r, FC_D13] = d13
    fc[r, FC_M], fc[r, FC_M1] = m, m1
    fc[r, FC_LAM] = math.sqrt(d23 * q_t)
    fc[r, FC_AMP1], fc[r, FC_AMP2], fc[r, FC_AMP3] = amp1, amp2, amp3
    fc[r, FC_N] = nn
    fc[r, FC_SIGMA], fc[r, FC_S] = sigma, s
    fc[r, FC_SN0], fc[r, FC_CN0], fc[r, FC_DN0] = sn0, cn0, dn0
    fc[r, FC_G0] = g0
    fc[r, FC_AW], fc[r, FC_AX], fc[r, FC_AY], fc[r, FC_AZ] = aw, ax, ay, az
    fc[r, FC_RJC] = -1.0
    if m1 > 0.0:
        (lev, scale, mb, mu0, mu1, mu2, mu3, mu4, mu5, mu6, mu7, mu8, mu9, mu10,
         mu11) = landen_descent(m, m1)
        fc[r, FC_LEV], fc[r, FC_SCALE], fc[r, FC_MB] = float(lev), scale, mb
        mu = FC_MU0
        fc[r, mu], fc[r, mu + 1], fc[r, mu + 2], fc[r, mu + 3] = mu0, mu1, mu2, mu3
        fc[r, mu + 4], fc[r, mu + 5], fc[r, mu + 6], fc[r, mu + 7] = mu4, mu5, mu6, mu7
        fc[r, mu + 8], fc[r, mu + 9], fc[r, mu + 10], fc[r, mu + 11] = mu8, mu9, mu10, mu11


@njit(cache=True)
def flow_rotation(fc, r, t):
    """The torque-free flow over the elapsed time t >= 0 from the anchor of row r of ``fc``
    (:func:`flow_constants`).

    Returns (cw, cx, cy, cz, n0, n1, n2): the unit quaternion c (cw >= 0) of the body's rotation
    since the anchor in its own frame (q(t) = q_anchor (x) c) and the body momentum at t. May
    fill the row's FC_RJC (computed the first time a half period is crossed).
    """
    cw, c0, c1, c2, o0, o1, o2 = flow_rotation_scaled(fc, r, t)
    nc = 1.0 / math.sqrt(cw * cw + c0 * c0 + c1 * c1 + c2 * c2)
    if cw < 0.0:
        nc = -nc
    return cw * nc, c0 * nc, c1 * nc, c2 * nc, o0, o1, o2


@jit
def flow_row(fc, r):
    """Row r of ``fc`` ((rows, N_FLOW)) as a tuple of N_FLOW floats, for :func:`flow_eval`."""
    return (fc[r, 0], fc[r, 1], fc[r, 2], fc[r, 3], fc[r, 4], fc[r, 5], fc[r, 6], fc[r, 7],
            fc[r, 8], fc[r, 9], fc[r, 10], fc[r, 11], fc[r, 12], fc[r, 13], fc[r, 14], fc[r, 15],
            fc[r, 16], fc[r, 17], fc[r, 18], fc[r, 19], fc[r, 20], fc[r, 21], fc[r, 22], fc[r, 23],
            fc[r, 24], fc[r, 25], fc[r, 26], fc[r, 27], fc[r, 28], fc[r, 29], fc[r, 30], fc[r, 31],
            fc[r, 32], fc[r, 33], fc[r, 34], fc[r, 35], fc[r, 36], fc[r, 37], fc[r, 38], fc[r, 39],
            fc[r, 40])


@njit(cache=True)
def flow_rotation_scaled(fc, r, t):
    """:func:`flow_rotation` with c a positive multiple of the rotation's quaternion (not
    normalized: a caller that normalizes q_anchor (x) c anyway saves a square root). May fill
    the row's FC_RJC (:func:`flow_eval`)."""
    cw, c0, c1, c2, o0, o1, o2, rj_c = flow_eval(flow_row(fc, r), t)
    if rj_c >= 0.0 and fc[r, FC_RJC] < 0.0:
        fc[r, FC_RJC] = rj_c
    return cw, c0, c1, c2, o0, o1, o2


@njit(cache=True)
def flow_eval(c, t):
    """The flow of :func:`flow_rotation_scaled` from a row of constants passed as a tuple
    (:func:`flow_row`): a function of scalars only, so that calling it per step costs no
    reference counting (an array argument costs two atomic operations per call, ~12 ns, and
    numba's pruning of them fails in large inlined bodies: they were a third of the exact
    kernel's time, benchmarks/RESULTS.md).

    Returns (cw, c0, c1, c2, o0, o1, o2, rj_c): as :func:`flow_rotation_scaled`, and the row's
    FC_RJC (computed here the first time a half period is crossed; the caller stores it)."""
    if c[FC_STEADY] != 0.0:
        w0, w1, w2, wn = c[FC_W0], c[FC_W1], c[FC_W2], c[FC_WN]
        b0, b1, b2 = c[FC_B0], c[FC_B1], c[FC_B2]  # constant
        if wn == 0.0:
            return 1.0, 0.0, 0.0, 0.0, b0, b1, b2, -1.0
        half = 0.5 * t * wn
        sf = math.sin(half) / wn
        return math.cos(half), sf * w0, sf * w1, sf * w2, b0, b1, b2, -1.0
    kk1, ell, d13 = c[FC_K1], c[FC_ELL], c[FC_D13]
    m, m1, lam, nn = c[FC_M], c[FC_M1], c[FC_LAM], c[FC_N]
    amp1, amp2, amp3 = c[FC_AMP1], c[FC_AMP2], c[FC_AMP3]
    sigma, s = c[FC_SIGMA], c[FC_S]
    sn0, cn0, dn0 = c[FC_SN0], c[FC_CN0], c[FC_DN0]
    # advance the phase by tau = lam t: functions of r, tau = 2 K j + r
    tau = lam * t
    if m1 <= 0.0:  # on the separatrix
        snr, cnr, dnr, j, big_k = sncndn(tau, m, m1)
    else:  # sncndn with the row's Landen descent
        snr, cnr, dnr, j, big_k = sncndn_landen(
            tau, int(c[FC_LEV]), c[FC_SCALE], c[FC_MB], c[29], c[30], c[31], c[32], c[33], c[34],
            c[35], c[36], c[37], c[38], c[39], c[40])  # mu_0 .. mu_11: FC_MU0 .. FC_MU0 + 11
    # addition theorem (A&S 16.17) written for the increments, so that a small step's rounding is
    # relative to the step (1 - cn r and 1 - dn r from sn r, no cancellation)
    gc = snr * snr / (1.0 + cnr) if cnr > 0.0 else 1.0 - cnr  # 1 - cn r
    gd = m * snr * snr / (1.0 + dnr)  # 1 - dn r
    mu_ = m * sn0 * sn0 * snr * snr
    den = 1.0 / (1.0 - mu_)
    gam = gc + gd - gc * gd  # 1 - cn r dn r
    sn1 = sn0 + (snr * cn0 * dn0 - sn0 * gam + sn0 * mu_) * den
    cn1 = cn0 + (-cn0 * gc - sn0 * snr * dn0 * dnr + cn0 * mu_) * den
    # dn from the identity dn^2 = cn^2 + (1 - m) sn^2: positive, no cancellation
    dn1 = math.sqrt(cn1 * cn1 + m1 * sn1 * sn1)
    # the integral of 1 / (1 + n sn^2) over [u0, u0 + r]: reduced amplitudes at both ends
    sg0 = 1.0 if cn0 >= 0.0 else -1.0
    s_red0 = sg0 * sn0
    if sg0 * cn1 >= 0.0:
        e = 0
        s_red1 = sg0 * sn1
        if s_red1 - s_red0 < -1.0:  # wrapped past 3 pi / 2 by rounding
            e = 2
    else:
        e = 1
        s_red1 = -sg0 * sn1
        if s_red1 - s_red0 > 1.0:  # came back below -pi / 2 by rounding
            e = -1
    # int du / (1 + n sn^2) = tau - n int sn^2 du / (1 + n sn^2): the latter's Carlson form has no
    # 1/n, so a near-symmetric body (n -> 0, slow precession lam -> 0) loses nothing to the
    # difference of the two ends; G(phi) = S^3 R_J(C^2, D^2, 1, 1 + n S^2) / 3 (|phi| <= pi/2),
    # the anchor's end G0 a constant of the row
    rj_c = c[FC_RJC]
    dg = 0.0
    if nn != 0.0:
        s21 = s_red1 * s_red1
        dg = s_red1 * s21 * carlson_rj1(cn1 * cn1, dn1 * dn1, 1.0 + nn * s21) / 3.0 - c[FC_G0]
    if big_k == math.inf:  # on the separatrix the amplitude never leaves (-pi/2, pi/2)
        e = 0
    halfs = j + e
    if halfs != 0 and nn != 0.0:
        if rj_c < 0.0:
            rj_c = carlson_rj1(0.0, m1, 1.0 + nn)
        dg += 2.0 * halfs * rj_c / 3.0
    # dphi = l k3 t + l (k1 - k3) / lam * (tau - n dg)
    dphi = ell * kk1 * t - ell * d13 * nn / lam * dg
    # the momentum at u0 + tau
    sj = -1.0 if (j & 1) else 1.0
    n1_ = amp1 * cn1 * sj
    n2_ = sigma * amp2 * sn1 * sj
    n3_ = s * amp3 * dn1
    # rotation since the anchor in the working frame: B0^T Rz(dphi) B1
    bw, bx, by, bz = _euler_quat(n1_, n2_, n3_, ell)
    ch, sh = math.cos(0.5 * dphi), math.sin(0.5 * dphi)
    # conj(B0) (x) rz
    tw, tx, ty, tz = _qmul(c[FC_AW], -c[FC_AX], -c[FC_AY], -c[FC_AZ],
                           ch, 0.0, 0.0, sh)
    cw, cx, cy, cz = _qmul(tw, tx, ty, tz, bw, bx, by, bz)
    # back to the body frame: v_body[i_k] = s_k v'_k, s = (1, 1, sgn3)
    sgn3 = c[FC_SGN3]
    i1, i2 = int(c[FC_I1]), int(c[FC_I2])
    c0 = c1 = c2 = 0.0
    o0 = o1 = o2 = 0.0
    for k in range(3):
        if k == 0:
            idx, vc, vn = i1, cx, n1_
        elif k == 1:
            idx, vc, vn = i2, cy, n2_
        else:
            idx, vc, vn = 3 - i1 - i2, cz * sgn3, n3_ * sgn3
        if idx == 0:
            c0, o0 = vc, vn
        elif idx == 1:
            c1, o1 = vc, vn
        else:
            c2, o2 = vc, vn
    return cw, c0, c1, c2, o0, o1, o2, rj_c


@njit(cache=True)
def free_flow_body(b0, b1, b2, k0, k1, k2, h):
    """The exact torque-free motion over h of a body with body-frame angular momentum
    Lb = (b0, b1, b2) and inverse principal moments (k0, k1, k2) (any order): the body itself as
    the anchor, the flow evaluated at h (:func:`flow_constants`, :func:`flow_rotation`).

    Returns (cw, cx, cy, cz, n0, n1, n2): the unit quaternion c (cw >= 0) of the body's rotation
    over the step in its own frame (q(t + h) = q(t) (x) c) and the body momentum at t + h.
    """
    flip = 1.0
    if h < 0.0:  # the backward flow is the forward flow of -L (Euler's equations are quadratic)
        flip = -1.0
        b0, b1, b2, h = -b0, -b1, -b2, -h
    fc = np.empty((1, N_FLOW))
    flow_constants(fc, 0, b0, b1, b2, k0, k1, k2)
    cw, cx, cy, cz, o0, o1, o2 = flow_rotation(fc, 0, h)
    return cw, cx, cy, cz, flip * o0, flip * o1, flip * o2


@njit(cache=True)
def free_flow_quat(w, x, y, z, lx, ly, lz, k0, k1, k2, h):
    """q(t + h) (unit, wxyz) of the torque-free body with orientation q = (w, x, y, z) (unit,
    body -> world), world angular momentum (lx, ly, lz) and inverse principal moments k."""
    # Lb = R^T L
    r00 = w * w + x * x - y * y - z * z
    r01 = 2.0 * (x * y - w * z)
    r02 = 2.0 * (x * z + w * y)
    r10 = 2.0 * (x * y + w * z)
    r11 = w * w - x * x + y * y - z * z
    r12 = 2.0 * (y * z - w * x)
    r20 = 2.0 * (x * z - w * y)
    r21 = 2.0 * (y * z + w * x)
    r22 = w * w - x * x - y * y + z * z
    b0 = r00 * lx + r10 * ly + r20 * lz
    b1 = r01 * lx + r11 * ly + r21 * lz
    b2 = r02 * lx + r12 * ly + r22 * lz
    cw, cx, cy, cz, _, _, _ = free_flow_body(b0, b1, b2, k0, k1, k2, h)
    qw, qx, qy, qz = _qmul(w, x, y, z, cw, cx, cy, cz)
    n = 1.0 / math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    return qw * n, qx * n, qy * n, qz * n
