"""The derived channels of the log contract, computed from the state channels in one compiled pass.

Velocities, energies, rigidity errors and totals are defined here once, for every writer (the
engine's recorders and :class:`rblog.record.Recorder` for other engines) and for the readers that
rebuild them, so that every log means the same thing by them.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, nogil=True)
def derive_channels(mass, inv_inertia, gravity, position, linear_momentum, quat_wxyz, rotation,
                    angular_momentum, velocity, omega, e_trans, e_rot, e_pot, ortho, qnorm,
                    total_p, total_l, total_e, stretched=False):
    """Derived channels of T samples x N bodies (see trajectory.derive), written into the outputs.

    omega = R diag(inv_inertia) R^T L with the logged R, or, when ``stretched`` (the quaternion
    scheme without normalization, whose R = |q|^2 Q is no rotation), omega = I_world^-1 L with
    I_world = R I_body R^T, i.e. C diag(inv_inertia) C^T L / det(R)^2 (C the cofactors of R);
    the two agree for an orthonormal R. e_pot = -m g.x; ortho = ||R^T R - I||_F;
    qnorm = |q| - 1. Totals per sample: total_p (T, 3) = sum P, total_l (T, 3) = sum x cross P + L
    (about the world origin), total_e (T,) = sum of the three energies. Inputs (T, N, ...) float64
    C-contiguous; outputs preallocated alike.
    """
    n_t, n_b = position.shape[0], position.shape[1]
    for t in range(n_t):
        sp0 = sp1 = sp2 = sl0 = sl1 = sl2 = se = 0.0
        for i in range(n_b):
            m = mass[i]
            px, py, pz = linear_momentum[t, i, 0], linear_momentum[t, i, 1], linear_momentum[t, i, 2]
            velocity[t, i, 0] = px / m
            velocity[t, i, 1] = py / m
            velocity[t, i, 2] = pz / m
            e_trans[t, i] = 0.5 * (px * px + py * py + pz * pz) / m
            e_pot[t, i] = -m * (gravity[0] * position[t, i, 0] + gravity[1] * position[t, i, 1]
                                + gravity[2] * position[t, i, 2])
            r = rotation[t, i]
            lx, ly, lz = angular_momentum[t, i, 0], angular_momentum[t, i, 1], angular_momentum[t, i, 2]
            if stretched:
                # cofactors of R: R^-1 = C^T / det, R^-T = C / det
                c00 = r[1, 1] * r[2, 2] - r[1, 2] * r[2, 1]
                c01 = r[1, 2] * r[2, 0] - r[1, 0] * r[2, 2]
                c02 = r[1, 0] * r[2, 1] - r[1, 1] * r[2, 0]
                c10 = r[0, 2] * r[2, 1] - r[0, 1] * r[2, 2]
                c11 = r[0, 0] * r[2, 2] - r[0, 2] * r[2, 0]
                c12 = r[0, 1] * r[2, 0] - r[0, 0] * r[2, 1]
                c20 = r[0, 1] * r[1, 2] - r[0, 2] * r[1, 1]
                c21 = r[0, 2] * r[1, 0] - r[0, 0] * r[1, 2]
                c22 = r[0, 0] * r[1, 1] - r[0, 1] * r[1, 0]
                det = r[0, 0] * c00 + r[0, 1] * c01 + r[0, 2] * c02
                f = 1.0 / (det * det)
                b0 = (c00 * lx + c10 * ly + c20 * lz) * inv_inertia[i, 0] * f
                b1 = (c01 * lx + c11 * ly + c21 * lz) * inv_inertia[i, 1] * f
                b2 = (c02 * lx + c12 * ly + c22 * lz) * inv_inertia[i, 2] * f
                ox = c00 * b0 + c01 * b1 + c02 * b2
                oy = c10 * b0 + c11 * b1 + c12 * b2
                oz = c20 * b0 + c21 * b1 + c22 * b2
            else:
                b0 = (r[0, 0] * lx + r[1, 0] * ly + r[2, 0] * lz) * inv_inertia[i, 0]
                b1 = (r[0, 1] * lx + r[1, 1] * ly + r[2, 1] * lz) * inv_inertia[i, 1]
                b2 = (r[0, 2] * lx + r[1, 2] * ly + r[2, 2] * lz) * inv_inertia[i, 2]
                ox = r[0, 0] * b0 + r[0, 1] * b1 + r[0, 2] * b2
                oy = r[1, 0] * b0 + r[1, 1] * b1 + r[1, 2] * b2
                oz = r[2, 0] * b0 + r[2, 1] * b1 + r[2, 2] * b2
            omega[t, i, 0] = ox
            omega[t, i, 1] = oy
            omega[t, i, 2] = oz
            e_rot[t, i] = 0.5 * (lx * ox + ly * oy + lz * oz)
            acc = 0.0
            for a in range(3):
                for b in range(3):
                    g = r[0, a] * r[0, b] + r[1, a] * r[1, b] + r[2, a] * r[2, b]
                    if a == b:
                        g -= 1.0
                    acc += g * g
            ortho[t, i] = math.sqrt(acc)
            q = quat_wxyz[t, i]
            qnorm[t, i] = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]) - 1.0
            x0, x1, x2 = position[t, i, 0], position[t, i, 1], position[t, i, 2]
            sp0 += px
            sp1 += py
            sp2 += pz
            sl0 += x1 * pz - x2 * py + lx
            sl1 += x2 * px - x0 * pz + ly
            sl2 += x0 * py - x1 * px + lz
            se += e_trans[t, i] + e_rot[t, i] + e_pot[t, i]
        total_p[t, 0] = sp0
        total_p[t, 1] = sp1
        total_p[t, 2] = sp2
        total_l[t, 0] = sl0
        total_l[t, 1] = sl1
        total_l[t, 2] = sl2
        total_e[t] = se
