"""The changing state the engine steps, as struct-of-arrays over bodies (see
:mod:`rblog.contract.model` for the conventions: float64, bodies first, world frame, wxyz)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
