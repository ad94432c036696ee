"""The changing state the engine steps, as struct-of-arrays over bodies (see
:mod:`rblog.contract.model` for the conventions: float64, bodies first, world frame, wxyz)."""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np

#: The anchors of the ``exact`` integrators' flow (rblog.engine.integrators.drift_exact_anchored),
#: one row per body: the attitude and world momentum the flow is evaluated from, how many steps of
#: ``anchor_dt_s`` the body has flown from them, and that step. The kernels evaluate the flow at
#: the elapsed time anchor_steps * anchor_dt_s (an integer count, never a float sum), so a run's
#: rounding does not accumulate. ``anchor_steps`` -1: no anchor (the next exact step sets one).
#: An anchor is valid only while the body's L equals ``anchor_L_world`` bitwise and the step is
#: ``anchor_dt_s`` (checked by the kernels: a torque kick, a contact impulse or a new dt sets a
#: new anchor); whatever changes a body's attitude other than the flow must set its
#: anchor_steps to -1 (State.reset_anchors, the contact step's project stage).
#: 64 bytes per body: anchor_quat_wxyz (N, 4), anchor_L_world (N, 3) kg m^2/s, anchor_steps (N,)
#: int64, anchor_dt_s (N,) s.
FlowAnchors = namedtuple("FlowAnchors", "anchor_quat_wxyz anchor_L_world anchor_steps anchor_dt_s")


def new_anchors(n: int) -> FlowAnchors:
    """Anchors for n bodies, none set."""
    return FlowAnchors(np.zeros((n, 4)), np.zeros((n, 3)), np.full(n, -1, np.int64), np.zeros(n))


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
        anchors: the exact integrators' flow anchors (FlowAnchors; none set by default). Code
            that edits quat_wxyz or rotation outside the kernels calls :meth:`reset_anchors`.
    """

    position: np.ndarray
    linear_momentum: np.ndarray
    quat_wxyz: np.ndarray
    rotation: np.ndarray
    angular_momentum_world: np.ndarray
    step: int = 0
    time_s: float = 0.0
    anchors: FlowAnchors | None = None

    def __post_init__(self):
        if self.anchors is None:
            self.anchors = new_anchors(self.position.shape[0])

    def reset_anchors(self) -> None:
        """Forget every body's flow anchor (after an edit of the attitude or L)."""
        self.anchors.anchor_steps[:] = -1

    def copy(self) -> "State":
        return State(
            self.position.copy(),
            self.linear_momentum.copy(),
            self.quat_wxyz.copy(),
            self.rotation.copy(),
            self.angular_momentum_world.copy(),
            self.step,
            self.time_s,
            FlowAnchors(*(a.copy() for a in self.anchors)),
        )
