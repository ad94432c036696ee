"""Motion under contact against closed forms: sliding to a stop, rolling down a slope.

The contact forces of these scenes are constant over every step (the normal force balances
gravity's normal part, friction is mu N while sliding or the static force of rolling), so the
motion is uniformly accelerated and a position update exact for constant acceleration lies on
the closed form to round-off at any dt.

* A box sliding on level ground at v0 with friction mu decelerates at mu g: x(t) = v0 t - mu g
  t^2 / 2 until t_stop = v0 / (mu g), then rests at x_stop = v0^2 / (2 mu g). t_stop falls inside
  a step (v0 = 2, mu = 0.5: t_stop = 0.40775 s), so the stop inside the step must be exact too.
* A uniform sphere (I = 2/5 m r^2) rolling without slip down a slope of angle theta: with F the
  friction force up the slope, m a = m g sin(theta) - F and I a / r^2 = F, so
  a = g sin(theta) / (1 + I / (m r^2)) = 5/7 g sin(theta) and s(t) = a t^2 / 2 from rest
  (rolling needs mu >= tan(theta) I / (I + m r^2) = 2/7 tan(theta) = 0.077 at 15 degrees).

The box's solve runs to convergence from a cold start (CONVERGED), so that what is measured is
the position update, not the solve's residual: with the default velocity_tolerance (1e-4 m/s)
the box rocks on its four corners by the leftover and ends 8e-9 m (dt 1e-3) and 1.3e-7 m (dt
1e-2) off x_stop; warm started from the stop step's friction impulse, the solve at dt 1e-2 keeps
a slip of 1.3e-5 m/s for a step even at 1e-12 m/s and 500 sweeps (6.5e-8 m off). A sphere's
single point is solved exactly by one update, so it runs with the defaults.
"""

from __future__ import annotations

import numpy as np
import pytest

from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE
from rblog.engine import integrators as rot, rotation
from rblog.engine.contact import ContactParams, ContactWorld
from rblog.study.scenes import make_model, make_state

G = 9.81
SPLIT = (rot.METHOD_SPLITTING, rot.ORTHO_NORMALIZE)
CONVERGED = dict(velocity_tolerance=1e-10, max_velocity_iterations=200, warm_starting=False)


def run(world, state, dt, n_steps):
    """Every step sampled; returns (times (S,), samples dict of (S, N, ...))."""
    n = world.n_bodies
    k = n_steps + 1  # the buffers' rows (advance asks for one more than it may write)
    out = dict(position=np.zeros((k, n, 3)), linear_momentum=np.zeros((k, n, 3)),
               quat_wxyz=np.zeros((k, n, 4)), rotation=np.zeros((k, n, 3, 3)),
               angular_momentum=np.zeros((k, n, 3)))
    ns, bad_step, _, _ = world.advance(
        dt, n_steps, 1, True, state.position, state.linear_momentum, state.quat_wxyz,
        state.rotation, state.angular_momentum_world, out["position"], out["linear_momentum"],
        out["quat_wxyz"], out["rotation"], out["angular_momentum"])
    assert bad_step == -1 and ns == n_steps
    return dt * np.arange(1, n_steps + 1), {key: v[:ns] for key, v in out.items()}


@pytest.mark.parametrize("dt", [1e-3, 1e-2])
def test_sliding_box_follows_the_parabola_and_stops_at_v0_squared_over_2_mu_g(dt):
    """0.2 m cube, 1 kg, v0 = 2 m/s along x on the ground, mu 0.5 (box and ground), for 0.6 s."""
    mu, v0, half = 0.5, 2.0, 0.1
    model = make_model([SHAPE_BOX], [[half] * 3], [1.0], restitution=0.0, friction=mu)
    world = ContactWorld(model, ContactParams(sleep=False, **CONVERGED), *SPLIT)
    state = make_state(model, [[0.0, 0.0, half]], [[v0, 0.0, 0.0]])
    t, out = run(world, state, dt, int(round(0.6 / dt)))
    x = out["position"][:, 0]
    t_stop = v0 / (mu * G)
    x_stop = v0 ** 2 / (2 * mu * G)
    sliding = t < t_stop
    x_exact = np.where(sliding, v0 * t - mu * G * t ** 2 / 2, x_stop)
    # x += h v_new (before): 1.0e-3 m off the parabola and short of x_stop at dt 1e-3, 9.8e-3 /
    # 1.0e-2 m at dt 1e-2; now (measured) <= 3.3e-13 m sliding, 1.1e-12 m stopped
    assert np.abs(x[sliding, 0] - x_exact[sliding]).max() < 1e-9
    assert np.abs(x[~sliding, 0] - x_stop).max() < 1e-9
    # no sideways motion, no sinking, no turn (measured <= 1e-12 each: the converged solve's
    # rocking on the four corners)
    assert np.abs(x[:, 1]).max() < 1e-10
    assert np.abs(x[:, 2] - half).max() < 1e-10
    assert np.abs(out["quat_wxyz"][:, 0, 1:]).max() < 1e-10
    # at rest after the stop (measured <= 3e-11 kg m/s)
    assert np.abs(out["linear_momentum"][~sliding, 0]).max() < 1e-9


def _slope(theta):
    """A static box tilted by theta about y as the ground (no ground plane): its top face falls
    along +x'. Returns (statics for make_model, top-face centre, outward normal, downslope)."""
    q = rotation.axis_angle_to_quat_np([0.0, 1.0, 0.0], theta)
    r = rotation.quat_to_matrix_np(q[None])[0]
    ext = np.array([5.0, 1.0, 0.5])
    centre = np.array([0.0, 0.0, 0.0])
    normal = r[:, 2]
    down = r[:, 0] if r[2, 0] < 0 else -r[:, 0]
    statics = dict(static_box_position=centre[None], static_box_quat_wxyz=q[None],
                   static_box_half_extents=ext[None], static_box_restitution=np.zeros(1),
                   static_box_friction=np.full(1, 0.5))
    return statics, centre + ext[2] * normal, normal, down


@pytest.mark.parametrize("dt", [1e-3, 1e-2])
def test_sphere_rolls_down_a_slope_at_five_sevenths_g_sin_theta(dt):
    """r = 0.1 m, 1 kg uniform sphere released touching a 15 degree slope, mu 0.5, for 1 s."""
    theta, r, mu = np.radians(15.0), 0.1, 0.5
    statics, top, normal, down = _slope(theta)
    model = make_model([SHAPE_SPHERE], [r], [1.0], restitution=0.0, friction=mu, ground=False,
                       **statics)
    world = ContactWorld(model, ContactParams(sleep=False), *SPLIT)
    x0 = top + r * normal
    state = make_state(model, [x0])
    t, out = run(world, state, dt, int(round(1.0 / dt)))
    d = out["position"][:, 0] - x0
    a = 5.0 / 7.0 * G * np.sin(theta)
    s = d @ down
    rel = np.abs(s / (a * t ** 2 / 2) - 1.0)
    # x += h v_new (before): ahead by h / t relative (1.0 at the first step, 1e-3 and 1e-2 at
    # t = 1 s for dt 1e-3, 1e-2); now (measured) <= 1.8e-11 (the first step's round-off on
    # s = 9e-7 m) and 8.5e-14
    assert rel.max() < 1e-9, rel.max()
    # on the surface: the centre stays at r along the normal (measured <= 1e-16 m)
    assert np.abs(d @ normal).max() < 1e-12
    # rolling without slip: v = omega r, omega about normal x down (measured <= 1e-15 relative)
    v = out["linear_momentum"][:, 0] @ down
    omega = out["angular_momentum"][:, 0] @ np.cross(normal, down) / (0.4 * r * r)
    assert np.abs(omega * r / v - 1.0).max() < 1e-12
