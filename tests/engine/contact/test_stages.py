"""Each stage of the contact step on its own (rblog.engine.contact.step), against what the notes
and the geometry say it must do. The whole step is tested in test_contact.py."""

from __future__ import annotations

import numpy as np

from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE
from rblog.engine.constants import ContactParams
from rblog.engine.contact import step as S
from rblog.engine.contact.world import ContactWorld
from rblog.engine.integrators import METHOD_RK4, ORTHO_NORMALIZE
from rblog.study.scenes import make_model, make_state


def _world(shapes, sizes, masses, **kw):
    model = make_model(shapes, sizes, masses, **kw)
    return model, ContactWorld(model, ContactParams(), METHOD_RK4, ORTHO_NORMALIZE)


def _x(state):
    return S.BodyState(state.position, state.linear_momentum, state.quat_wxyz, state.rotation,
                       state.angular_momentum_world)


def test_kick_adds_h_times_weight_and_torque_to_awake_bodies_only():
    model = make_model([SHAPE_BOX, SHAPE_BOX], [0.1, 0.1], [2.0, 3.0])
    model.body_torque_world[0] = [0.0, 0.5, 0.0]
    bd, _, _ = ContactWorld(model, ContactParams(), METHOD_RK4, ORTHO_NORMALIZE).records
    state = make_state(model, [[0, 0, 1], [1, 0, 1]], [[1, 2, 3], [0, 0, 0]])
    p0, l0 = state.linear_momentum.copy(), state.angular_momentum_world.copy()
    h = 1e-3
    S.kick(bd, np.array([1, 0]), _x(state), h)
    # the notes: P_{n+1} = P_n + h F with F = m g (+ applied force); L_{n+1} = L_n + h tau
    np.testing.assert_allclose(state.linear_momentum[0], p0[0] + h * 2.0 * np.array([0, 0, -9.81]),
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(state.angular_momentum_world[0], l0[0] + h * np.array([0, 0.5, 0]),
                               rtol=0, atol=1e-18)
    np.testing.assert_array_equal(state.linear_momentum[1], p0[1])  # asleep: untouched


def test_broadphase_pairs_exactly_the_overlapping_boxes_and_the_ground():
    # spheres of r = 0.1: 0 and 1 are 0.15 apart (touching), 2 is 3 m away, 0 rests on z = 0
    model, world = _world([SHAPE_SPHERE] * 3, [0.1] * 3, [1.0] * 3)
    bd, st, cfg = world.records
    state = make_state(model, [[0, 0, 0.1], [0.15, 0, 0.1], [3, 0, 2]])
    sc = S.make_scratch(3, st)
    pairs, n = S.broadphase(bd, st, cfg.speculative_distance, np.ones(3, np.int64), _x(state), 1e-3, sc,
                            np.zeros((4, 2), np.int64))
    got = {tuple(p) for p in pairs[:n]}
    ground = 3 + st.n_static  # the ground's id follows the bodies and static boxes
    assert got == {(0, 1), (0, ground), (1, ground)}


def test_first_diverged_names_the_bad_body():
    model, world = _world([SHAPE_SPHERE] * 3, [0.1] * 3, [1.0] * 3)
    bd = world.records[0]
    h = 1e-3
    state = make_state(model, [[0, 0, 1], [1, 0, 1], [2, 0, 1]])
    assert S.first_diverged(np.ones(3, np.int64), _x(state), bd.inv_inertia, h) == -1
    state.linear_momentum[2, 1] = np.nan
    assert S.first_diverged(np.ones(3, np.int64), _x(state), bd.inv_inertia, h) == 2
    assert S.first_diverged(np.array([1, 1, 0]), _x(state), bd.inv_inertia, h) == -1  # asleep


def test_first_diverged_names_a_body_that_turns_too_far_in_a_step():
    # a 0.1 m sphere of 1 kg: I = 2/5 m r^2 = 4e-3 kg m^2. A finite L = 4e6 N m s gives
    # |omega| h = L / I * h = 1e9 rad/s * 1e-3 s = 1e6 rad, the bound: not yet diverged;
    # twice that is over MAX_ROTATION_PER_STEP_RAD (1e6 rad) though every number is finite
    model, world = _world([SHAPE_SPHERE] * 2, [0.1] * 2, [1.0] * 2)
    bd = world.records[0]
    h = 1e-3
    state = make_state(model, [[0, 0, 1], [1, 0, 1]])
    state.angular_momentum_world[1] = [0.0, 0.999999 * 4e6, 0.0]
    assert S.first_diverged(np.ones(2, np.int64), _x(state), bd.inv_inertia, h) == -1
    state.angular_momentum_world[1] = [0.0, 8e6, 0.0]
    assert S.first_diverged(np.ones(2, np.int64), _x(state), bd.inv_inertia, h) == 1


def test_integrate_moves_a_body_without_contact_on_its_parabola():
    # a body no contact pushed flies exactly: with v = P / m after the kick (v_start + g h),
    # x += h v - h^2 g / 2 = h v_start + h^2 g / 2
    model, world = _world([SHAPE_SPHERE], [0.1], [2.0])
    bd, st, cfg = world.records
    state = make_state(model, [[0, 0, 5]], [[1.0, -2.0, 0.5]])
    sc = S.make_scratch(1, st)
    x0 = state.position.copy()
    h = 1e-2
    S.integrate_positions(METHOD_RK4, ORTHO_NORMALIZE, bd, cfg, np.ones(1, np.int64), _x(state),
                          sc, h, state.anchors)
    v = np.array([1.0, -2.0, 0.5])
    np.testing.assert_allclose(state.position[0],
                               x0[0] + h * v - 0.5 * h * h * np.array([0, 0, -9.81]),
                               rtol=0, atol=1e-15)
