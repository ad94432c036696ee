"""The fixed model of a scene and the changing state, as struct-of-arrays over bodies.

Conventions (see docs/log-format.md for the full contract):

* Arrays are float64, bodies first: ``(N, 3)`` for vectors, ``(N, 4)`` for quaternions,
  ``(N, 3, 3)`` for matrices.
* ``quat_wxyz`` is scalar-first and maps body-frame vectors to the world frame, as does
  ``rotation`` (``v_world = rotation @ v_body``).
* Angular momentum is kept in the world frame (``angular_momentum_world``); the body-frame inertia
  is diagonal in principal axes (``inertia_body_diag``), so the world inverse inertia is
  ``R diag(1/I) R^T`` as in the lecture notes.
* Units are SI: m, kg, s, rad.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

SHAPE_SPHERE = 0
SHAPE_BOX = 1
SHAPE_NAMES = {SHAPE_SPHERE: "sphere", SHAPE_BOX: "box"}
SHAPE_CODES = {v: k for k, v in SHAPE_NAMES.items()}


@dataclass
class Model:
    """What does not change during a run.

    Attributes:
        body_name: N names.
        body_shape: (N,) int, SHAPE_SPHERE or SHAPE_BOX.
        body_size: (N, 3) sphere radius in [:, 0] (others 0), or box half-extents (m, body frame).
        body_mass: (N,) kg.  body_inv_mass: (N,) 1/kg.
        body_inertia_diag: (N, 3) principal moments about the centre of mass, body frame (kg m^2).
        body_inv_inertia_diag: (N, 3) their inverses.
        body_force_world: (N, 3) constant applied force besides gravity (N, world frame).
        body_torque_world: (N, 3) constant applied torque (N m, world frame).
        body_restitution, body_friction: (N,) material coefficients.
        body_group: (N,) int collision group; bodies in different non-zero groups never touch.
        gravity: (3,) m/s^2, world frame.
        ground: True when the scene has the infinite plane ``dot(ground_normal, x) = ground_offset``.
        ground_normal: (3,) unit, pointing out of the ground.  ground_offset: m.
        ground_restitution, ground_friction: material of the ground.
        static_box_position: (M, 3), static_box_quat_wxyz: (M, 4), static_box_half_extents: (M, 3),
        static_box_restitution, static_box_friction: (M,) static boxes (walls, ramps).
    """

    body_name: list[str]
    body_shape: np.ndarray
    body_size: np.ndarray
    body_mass: np.ndarray
    body_inertia_diag: np.ndarray
    body_force_world: np.ndarray
    body_torque_world: np.ndarray
    body_restitution: np.ndarray
    body_friction: np.ndarray
    body_group: np.ndarray
    gravity: np.ndarray
    ground: bool = False
    ground_normal: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    ground_offset: float = 0.0
    ground_restitution: float = 0.5
    ground_friction: float = 0.5
    static_box_position: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    static_box_quat_wxyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    static_box_half_extents: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    static_box_restitution: np.ndarray = field(default_factory=lambda: np.zeros(0))
    static_box_friction: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def n_bodies(self) -> int:
        return len(self.body_name)

    @property
    def body_inv_mass(self) -> np.ndarray:
        return 1.0 / self.body_mass

    @property
    def body_inv_inertia_diag(self) -> np.ndarray:
        return 1.0 / self.body_inertia_diag


@dataclass
class State:
    """What changes during a run, all float64, bodies first, world frame.

    Attributes:
        position: (N, 3) centre of mass (m).
        linear_momentum: (N, 3) P = m v (kg m/s).
        quat_wxyz: (N, 4) unit quaternion body->world, scalar first.
        rotation: (N, 3, 3) body->world matrix the integrator holds (may drift from orthonormal
            when orthonormalization is off; that is the point of logging it).
        angular_momentum_world: (N, 3) L = I_world omega (kg m^2/s).
        step: steps taken so far.  time_s: simulated time (s).
    """

    position: np.ndarray
    linear_momentum: np.ndarray
    quat_wxyz: np.ndarray
    rotation: np.ndarray
    angular_momentum_world: np.ndarray
    step: int = 0
    time_s: float = 0.0

    def copy(self) -> "State":
        return State(
            self.position.copy(),
            self.linear_momentum.copy(),
            self.quat_wxyz.copy(),
            self.rotation.copy(),
            self.angular_momentum_world.copy(),
            self.step,
            self.time_s,
        )
