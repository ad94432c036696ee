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

The flow is C++ (csrc/engine/exact.hpp / exact.cpp, where the derivation below is also written
out: frames and symbols, the working frame, the attitude by Carlson's R_F and R_J, the numerics);
the names here call it through rblog.engine._core with the same arguments and results.

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

from rblog.engine import _core

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
assert FC_MU0 + 12 == N_FLOW
assert N_FLOW == _core.N_FLOW and FC_RJC == _core.FC_RJC  # the C++ mirror of the columns

#: sncndn(u, m, m1) -> (sn r, cn r, dn r, j, K): Jacobi sn, cn, dn of u >= 0 at m = 1 - m1, the
#: argument reduced by the half period (u = 2 K j + r, 0 <= r < 2K); K = inf when m1 = 0
sncndn = _core.sncndn
#: landen_descent(m, m1) -> (lev, scale, m_base, mu_0 .. mu_11): the descending Landen
#: transformations of m down to LANDEN_BASE_PARAMETER
landen_descent = _core.landen_descent
#: carlson_rf_rj(x, y, z, p) -> (R_F(x, y, z), R_J(x, y, z, p)), one shared duplication
carlson_rf_rj = _core.carlson_rf_rj
#: carlson_rj1(x, y, p) -> R_J(x, y, 1, p)
carlson_rj1 = _core.carlson_rj1
#: flow_constants(fc, r, b0, b1, b2, k0, k1, k2): row r of fc ((rows, N_FLOW) float64), the
#: constants of the torque-free flow forward in time from body momentum Lb = b, inverse moments k
flow_constants = _core.flow_constants
#: flow_rotation(fc, r, t) -> (cw, cx, cy, cz, n0, n1, n2): the unit rotation c since the anchor of
#: row r (body frame, q(t) = q_anchor (x) c, cw >= 0) and the body momentum at t; may fill FC_RJC
flow_rotation = _core.flow_rotation
#: free_flow_body(b0, b1, b2, k0, k1, k2, h) -> (cw, cx, cy, cz, n0, n1, n2): the one-step exact
#: map of the body momentum Lb = b (the body itself as the anchor; h may be negative)
free_flow_body = _core.free_flow_body
#: free_flow_quat(w, x, y, z, lx, ly, lz, k0, k1, k2, h) -> q(t + h) (unit, wxyz) from q (body ->
#: world) and the world L
free_flow_quat = _core.free_flow_quat
