"""Static friction holds (friction anchors) and torsional friction of one-point contacts
(rblog/engine/contact/solver.py, "Friction anchor" and "Torsional friction"): closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE
from rblog.engine.constants import TORSIONAL_PATCH_RADIUS_M
from rblog.engine.contact import ContactParams, ContactWorld

from rblog.study.scenes import make_model, make_state
from tests.engine.contact.test_contact import SPLIT, simulate

G = 9.81


@pytest.mark.parametrize("sweeps", [1, 30])
def test_box_on_a_ramp_below_the_friction_angle_stays_put(sweeps):
    """A cube on a 20 deg ramp (tan 20 = 0.36 < mu 0.6; the ramp is the ground under tilted
    gravity) sticks: static friction allows no slip, even when the velocity solve stops after
    one sweep a step (its residual would otherwise add up)."""
    th = math.radians(20.0)
    model = make_model([SHAPE_BOX], [[0.05, 0.05, 0.05]], [0.1], restitution=0.0, friction=0.6,
                       gravity=(G * math.sin(th), 0.0, -G * math.cos(th)))
    params = ContactParams(sleep=False, velocity_iterations=sweeps,
                           max_velocity_iterations=sweeps)
    world = ContactWorld(model, params, *SPLIT)
    state = make_state(model, [[0.0, 0.0, 0.05]])
    out, _, bad, _ = simulate(world, state, 1e-3, 3000, stride=100)
    assert bad == -1
    x = out["position"][:, 0]
    # down-slope drift over 3 s after the first 0.1 s: none (the anchor takes back any step's
    # slip; measured 3.1e-12 m at one sweep, 2e-21 m at 30; 1.26 um in the first 0.1 s at one)
    drift = np.abs(x[1:, 0] - x[1, 0]).max()
    assert drift <= 1e-9, drift
    assert np.abs(out["linear_momentum"][-1, 0]).max() <= 1e-9  # measured 1.1e-13 kg m/s


def test_spinning_sphere_stops_by_torsional_friction():
    """A sphere spinning about the vertical on the ground: its one-point contact's twist row
    brakes it with the moment mu m g r_patch (r_patch = TORSIONAL_PATCH_RADIUS_M), so
    w(t) = w0 - mu m g r_patch t / I until it stops, then stays stopped."""
    mu, r, m, w0 = 0.5, 0.1, 1.0, 3.0
    model = make_model([SHAPE_SPHERE], [r], [m], restitution=0.0, friction=mu)
    world = ContactWorld(model, ContactParams(sleep=False), *SPLIT)
    state = make_state(model, [[0.0, 0.0, r]], omega=[[0.0, 0.0, w0]])
    dt = 1e-3
    out, _, bad, _ = simulate(world, state, dt, 1000, stride=50)
    assert bad == -1
    inertia = 0.4 * m * r * r
    alpha = mu * m * G * TORSIONAL_PATCH_RADIUS_M / inertia
    t = (np.arange(out["angular_momentum"].shape[0]) + 1) * 50 * dt  # a sample after every 50th step
    w = out["angular_momentum"][:, 0, 2] / inertia
    spinning = t < 0.9 * w0 / alpha
    # braking at the closed-form rate (measured 4e-14 rad/s)
    err = np.abs(w[spinning] - (w0 - alpha * t[spinning])).max()
    assert err <= 1e-9 * w0, err
    # stopped after w0 / alpha, and the contact's lateral friction never acted (no drift)
    assert abs(w[-1]) <= 1e-9 * w0, w[-1]  # measured 7.6e-231 rad/s
    assert np.abs(out["position"][:, 0, :2]).max() <= 1e-9
