"""The body table and world of a scene (what does not change), as struct-of-arrays over bodies.

Part of the log contract: the engine builds it from a scene, the recorders write it, the readers
rebuild it from a log and the analyzers judge a trajectory against it. The changing state the
engine steps is :class:`rblog.engine.state.State`.

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
#: a body whose geometry the contract cannot describe (a capsule, cylinder or mesh of another
#: engine, several geoms): its mass, inertia and motion are logged, its ``body_size`` is zero, and
#: what needs a shape (separations, tunneling) must skip it. Only recorders write it: a scene has
#: no such body (the engine simulates spheres and boxes only).
SHAPE_NONE = -1
#: the shapes of scenes and of rblog's engine
SHAPE_NAMES = {SHAPE_SPHERE: "sphere", SHAPE_BOX: "box"}
SHAPE_CODES = {v: k for k, v in SHAPE_NAMES.items()}
#: every body_shape value a log may hold, by name (SHAPE_CODES plus "none")
LOG_SHAPE_CODES = {**SHAPE_CODES, "none": SHAPE_NONE}


@dataclass
class Model:
    """What does not change during a run.

    Attributes:
        body_name: N names.
        body_shape: (N,) int, SHAPE_SPHERE or SHAPE_BOX (SHAPE_NONE, -1, in logs of other
            engines: no shape the contract describes).
        body_size: (N, 3) sphere radius in [:, 0] (others 0), or box half-extents (m, body frame);
            zeros for SHAPE_NONE.
        body_mass: (N,) kg.  body_inv_mass: (N,) 1/kg.
        body_inertia_diag: (N, 3) principal moments about the centre of mass, body frame (kg m^2).
        body_inv_inertia_diag: (N, 3) their inverses.
        body_force_world: (N, 3) constant applied force besides gravity (N, world frame).
        body_torque_world: (N, 3) constant applied torque (N m, world frame).
        body_restitution, body_friction: (N,) material coefficients; NaN = not stated by the
            engine that wrote the log (unknown, so not to be judged).
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

    @property
    def body_bounding_radius(self) -> np.ndarray:
        """(N,) radius of each body's bounding sphere about its centre of mass (m): the sphere's
        radius, or a box's half diagonal |half extents|; 0 for a body without a shape."""
        return np.where(self.body_shape == SHAPE_SPHERE, self.body_size[:, 0],
                        np.linalg.norm(self.body_size, axis=1))
