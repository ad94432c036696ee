"""The derived channels of the log contract, computed from the state channels in one compiled pass.

Velocities, energies, rigidity errors and totals are defined here once, for every writer (the
engine's recorders and :class:`rblog.record.Recorder` for other engines) and for the readers that
rebuild them, so that every log means the same thing by them.
"""

from __future__ import annotations

from rblog.contract import _derive


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

    The kernel is C++ (csrc/contract/derive.cpp, module ``rblog.contract._derive``; it releases
    the GIL, so a writer thread derives while the engine steps).
    """
    _derive.derive_channels(mass, inv_inertia, gravity, position, linear_momentum, quat_wxyz,
                            rotation, angular_momentum, velocity, omega, e_trans, e_rot, e_pot,
                            ortho, qnorm, total_p, total_l, total_e, bool(stretched))


def state_from_velocities(mass, inertia, quat_wxyz, velocity, omega, rotation, linear_momentum,
                          angular_momentum):
    """The logged state from a writer's: rotation (T, N, 3, 3) of the normalized quaternions
    (T, N, 4; scalar first), linear_momentum = m v, angular_momentum = R (I * (R^T omega))
    (world, about the centre of mass), written into the preallocated outputs. Inputs: mass (N,),
    inertia (N, 3) principal moments, velocity and omega (T, N, 3) world; float64 C-contiguous.
    C++ (csrc/contract/state.cpp), the GIL released."""
    _derive.state_from_velocities(mass, inertia, quat_wxyz, velocity, omega, rotation,
                                  linear_momentum, angular_momentum)
