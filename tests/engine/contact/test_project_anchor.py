"""The project stage drops a moved body's exact-flow anchor (csrc/engine/project.cpp's
apply_projection): its attitude changed other than by the torque-free flow, so the next exact step
must flow from the projected attitude, not from the old anchor (which would undo the projection's
turn). Independent check: exact.free_flow_quat, the one-step exact map that carries no anchor."""

from __future__ import annotations

import numpy as np

from rblog.contract.model import SHAPE_BOX
from rblog.engine import _core, free
from rblog.engine.constants import ContactParams
from rblog.engine.contact.world import ContactWorld
from rblog.engine.exact import free_flow_quat
from rblog.engine.integrators import METHOD_EXACT, ORTHO_NORMALIZE
from rblog.engine.rotation import quat_to_matrix_np
from rblog.engine.state import new_anchors
from rblog.study.reference import rotation_angle_between
from rblog.study.scenes import make_model

Q0 = np.array([0.8, 0.3, -0.4, 0.34]) / np.linalg.norm([0.8, 0.3, -0.4, 0.34])


def _steps(state, params, an, dt, n):
    out = [np.empty((1, 1, 3)), np.empty((1, 1, 3)), np.empty((1, 1, 4)), np.empty((1, 1, 3, 3)),
           np.empty((1, 1, 3))]
    ns, bad, _ = free.advance_free(METHOD_EXACT, ORTHO_NORMALIZE, dt, n, n, False, *params, *state,
                                   *out, n_threads=1, anchors=an)
    assert ns == 1 and bad == -1


def test_a_projected_body_flows_from_its_new_attitude():
    dt = 1e-3
    inertia = np.array([[0.3, 0.7, 1.1]])  # no two moments equal: the flow is not a plain spin
    model = make_model([SHAPE_BOX], [[0.2, 0.1, 0.05]], [2.0])
    bd = ContactWorld(model, ContactParams(), METHOD_EXACT, ORTHO_NORMALIZE).records[0]
    bd.inv_inertia[:] = 1.0 / inertia
    bd.inertia[:] = inertia
    q = Q0[None].copy()
    l_world = np.array([[0.4, -1.3, 2.2]])
    # P = 0: the projection's L -= dx x P leaves L bitwise unchanged, so only the dropped anchor
    # can tell the next step that the attitude moved
    state = [np.zeros((1, 3)), np.zeros((1, 3)), q, quat_to_matrix_np(q), l_world]
    params = (np.ones(1), bd.inv_inertia.copy(), np.zeros((1, 3)), np.zeros((1, 3)))
    an = new_anchors(1)
    _steps(state, params, an, dt, 10)
    assert an.anchor_steps[0] == 10
    # the project stage turns the body by 0.02 rad about x and lifts it 1 mm
    dx = np.array([[0.0, 0.0, 1e-3]])
    dth = np.array([[0.02, 0.0, 0.0]])
    _core.apply_projection(np.array([[0, 1]]), dx, dth, METHOD_EXACT, ORTHO_NORMALIZE, bd,
                           False, state[0], state[3], state[2], state[1], state[4],
                           np.zeros((1, 3)), an.anchor_steps)
    assert an.anchor_steps[0] == -1
    np.testing.assert_array_equal(state[4], l_world)  # L bitwise the same
    q_proj = state[2][0].copy()
    assert rotation_angle_between(q_proj, free_flow_quat(*Q0, *l_world[0], *(1 / inertia[0]),
                                                         10 * dt)) > 1e-2  # it did turn
    _steps(state, params, an, dt, 1)
    expect = np.array(free_flow_quat(*q_proj, *l_world[0], *(1 / inertia[0]), dt))
    # measured 2.0e-16 rad (round-off); keeping the old anchor instead puts the step 0.020 rad
    # away (it undoes the projection's turn: measured by restoring anchor_steps)
    assert rotation_angle_between(state[2][0], expect) <= 1e-14
    stale = np.array(free_flow_quat(*Q0, *l_world[0], *(1 / inertia[0]), 11 * dt))
    assert rotation_angle_between(state[2][0], stale) > 1e-2
