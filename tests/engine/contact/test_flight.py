"""Exact ballistic flight in scenes with contacts, and bounces down to the restitution threshold.

Theory: a body that nothing pushes moves on the parabola x0 + v0 t + g t^2 / 2 (to round-off,
whatever stages the scene runs); a ball dropped from h0 onto a plane with restitution e rises to
e^(2n) h0 after its n-th bounce, and bounces while its impact speed e^n sqrt(2 g h0) exceeds the
restitution threshold, 2 |g| dt + velocity_tolerance unless the scene sets one
(rblog.engine.constants, "restitution threshold").
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE
from rblog.contract.trajectory import CONTACT_IMPACT
from rblog.engine import integrators as rot
from rblog.engine.contact import ContactParams, ContactWorld
from rblog.study.scenes import make_model, make_state

G = 9.81
SPLIT = (rot.METHOD_SPLITTING, rot.ORTHO_NORMALIZE)


def simulate(world, state, dt, n_steps):
    """Advance n_steps in one call, a sample after every step; (samples, contacts)."""
    n = world.n_bodies
    out = dict(position=np.zeros((n_steps, n, 3)), linear_momentum=np.zeros((n_steps, n, 3)),
               quat_wxyz=np.zeros((n_steps, n, 4)), rotation=np.zeros((n_steps, n, 3, 3)),
               angular_momentum=np.zeros((n_steps, n, 3)))
    ns, bad_step, _, contacts = world.advance(
        dt, n_steps, 1, False, state.position, state.linear_momentum, state.quat_wxyz,
        state.rotation, state.angular_momentum_world, out["position"], out["linear_momentum"],
        out["quat_wxyz"], out["rotation"], out["angular_momentum"])
    assert bad_step == -1 and ns == n_steps
    return out, contacts


def first_push_step(contacts, body):
    """The first (1-based) step at which a contact pushed ``body`` (normal impulse > 0)."""
    pushed = ((contacts.body_a == body) | (contacts.body_b == body)) & (contacts.normal_impulse > 0)
    return int(contacts.step[pushed].min()) if pushed.any() else None


# ---- exact flight ------------------------------------------------------------------------------

@pytest.mark.parametrize("dt", [1e-3, 1e-2])
@pytest.mark.parametrize("integrator", [rot.METHOD_SPLITTING, rot.METHOD_RK4])
def test_free_fall_over_a_ground_is_the_parabola(dt, integrator):
    """A thrown sphere and a tumbling box fall onto the ground while two boxes stand stacked
    nearby (every contact stage runs): until a contact first pushes them, their positions and
    momenta are the parabola's to 1e-12 (symplectic Euler, the old translation, is g dt t / 2
    off: 2.7 mm at dt = 1e-3 after the sphere's 0.56 s of flight)."""
    h = 0.1
    model = make_model([SHAPE_SPHERE, SHAPE_BOX, SHAPE_BOX, SHAPE_BOX],
                       [0.1, [0.2, 0.1, 0.05], [h] * 3, [h] * 3], [1.0, 2.0, 1.0, 1.0],
                       restitution=0.5)
    x0 = np.array([[0.0, 0.0, 1.1], [2.0, 0.0, 1.5], [-2.0, 0.0, h], [-2.0, 0.0, 3 * h]])
    v0 = np.array([[0.3, -0.2, 1.0], [0.0, 0.4, 0.5], [0.0] * 3, [0.0] * 3])
    state = make_state(model, x0, v0, omega=[[0, 0, 0], [3.0, -1.0, 7.0], [0] * 3, [0] * 3])
    world = ContactWorld(model, ContactParams(sleep=False), integrator, rot.ORTHO_NORMALIZE)
    n_steps = int(round(0.8 / dt))
    out, contacts = simulate(world, state, dt, n_steps)
    g = np.array([0.0, 0.0, -G])
    for body in (0, 1):
        first = first_push_step(contacts, body)
        assert first is not None and first > 10, (body, first)  # it did land, after a flight
        k = np.arange(1, first)  # steps before the first push
        t = k * dt
        m = model.body_mass[body]
        x_exact = x0[body] + v0[body] * t[:, None] + 0.5 * g * t[:, None] ** 2
        p_exact = m * (v0[body] + g * t[:, None])
        # the target; measured <= 4.2e-15 m and 6.6e-14 N s (dt 1e-3), 3.3e-16 m and
        # 7.1e-15 N s (dt 1e-2), the same for both integrators
        assert np.abs(out["position"][k - 1, body] - x_exact).max() <= 1e-12
        assert np.abs(out["linear_momentum"][k - 1, body] - p_exact).max() <= 1e-12
    # the stack stands still meanwhile (measured: its top moves 2.8e-8 m at dt 1e-3, 3.4e-7 m
    # at dt 1e-2)
    assert np.abs(out["position"][:, 3] - x0[3]).max() <= 1e-6


def test_bodies_that_never_touch_fly_exactly_beside_contacts():
    """Over a ground, with a pair colliding elsewhere, a sphere that never comes near anything
    keeps the parabola for the whole run (1 s at dt = 1e-3)."""
    model = make_model([SHAPE_SPHERE] * 3, [0.1] * 3, [1.0] * 3, restitution=0.8,
                       gravity=(0.0, 0.0, -G))
    x0 = np.array([[0.0, 0.0, 20.0], [5.0, 0.0, 1.0], [5.5, 0.0, 1.0]])
    v0 = np.array([[1.0, 0.5, 3.0], [1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    state = make_state(model, x0, v0)
    world = ContactWorld(model, ContactParams(), *SPLIT)
    out, contacts = simulate(world, state, 1e-3, 1000)
    assert first_push_step(contacts, 1) is not None  # the pair did collide
    t = np.arange(1, 1001) * 1e-3
    x_exact = x0[0] + v0[0] * t[:, None] + 0.5 * np.array([0, 0, -G]) * t[:, None] ** 2
    assert np.abs(out["position"][:, 0] - x_exact).max() <= 1e-12  # measured 1.8e-14 (z ~ 20 m)


# ---- bounces and the restitution threshold -------------------------------------------------

def flights(pushed_steps, n_steps):
    """Split the samples (after steps 1..n) into flights: maximal runs of steps with no contact
    push that start after one. Returns a list of index arrays (0-based sample indices)."""
    free = np.ones(n_steps + 1, bool)
    free[pushed_steps] = False
    out, cur = [], []
    for s in range(1, n_steps + 1):
        if free[s]:
            cur.append(s - 1)
        elif cur:
            out.append(np.array(cur))
            cur = []
    if cur:
        out.append(np.array(cur))
    return out


@pytest.mark.parametrize("dt", [1e-3, 1e-2])
def test_two_cm_drop_bounces_with_its_e(dt):
    """A sphere (r = 0.1 m, e = 0.6) dropped from h0 = 2 cm: the n-th flight's apex is
    e^(2n) h0, both as the flight's energy height z + vz^2 / 2g (exact on a parabola) and as the
    highest sample (at most g dt^2 / 8 below the apex); it bounces exactly as long as its impact
    speed e^n sqrt(2 g h0) exceeds the threshold 2 g dt + 1e-4 m/s (7 bounces at dt = 1e-3, 3 at
    1e-2), then rests."""
    r, h0, e = 0.1, 0.02, 0.6
    model = make_model([SHAPE_SPHERE], [r], [1.0], restitution=e, ground_restitution=0.0)
    world = ContactWorld(model, ContactParams(sleep=False), *SPLIT)
    threshold = 2.0 * G * dt + ContactParams().velocity_tolerance
    assert world.restitution_threshold(dt) == pytest.approx(threshold, rel=1e-15)
    u0 = math.sqrt(2 * G * h0)
    n_bounces = sum(1 for n in range(50) if e ** n * u0 > threshold)
    assert n_bounces == (7 if dt == 1e-3 else 3)
    state = make_state(model, [[0.0, 0.0, r + h0]])
    n_steps = int(round(1.0 / dt))
    out, contacts = simulate(world, state, dt, n_steps)
    z = out["position"][:, 0, 2] - r
    vz = out["linear_momentum"][:, 0, 2]
    assert int((contacts.kind == CONTACT_IMPACT).sum()) == n_bounces
    pushed = np.unique(contacts.step[contacts.normal_impulse > 0])
    fl = [f for f in flights(pushed, n_steps) if vz[f].max() > 0.0]  # rising flights
    assert len(fl) == n_bounces
    for n, f in enumerate(fl, start=1):
        apex = e ** (2 * n) * h0
        energy_height = z[f] + vz[f] ** 2 / (2 * G)
        # measured: relative 4.4e-15 at n = 1 .. 1.1e-12 at n = 7 (dt 1e-3, the round-off of
        # z + vz^2/2g on a 1.6e-5 m apex), <= 4.1e-15 (dt 1e-2)
        assert np.abs(energy_height / apex - 1.0).max() <= 1e-11, (n, energy_height, apex)
        assert apex - G * dt ** 2 / 8 - 1e-15 <= z[f].max() <= apex + 1e-15
    # at rest after the last bounce: still, on the ground (measured: vz and z exactly 0)
    last = fl[-1][-1] + int(round(0.1 / dt))
    assert np.abs(vz[last:]).max() <= 1e-9
    assert np.abs(z[last:]).max() <= 1e-4


def test_scene_threshold_overrides_the_derived_one():
    """[contact] restitution_threshold = 1 m/s (Box2D's value) swallows the 2 cm drop's 0.63 m/s
    impact: no bounce at all."""
    r, h0 = 0.1, 0.02
    model = make_model([SHAPE_SPHERE], [r], [1.0], restitution=0.6, ground_restitution=0.0)
    world = ContactWorld(model, ContactParams(restitution_threshold=1.0, sleep=False), *SPLIT)
    assert world.restitution_threshold(1e-3) == 1.0
    state = make_state(model, [[0.0, 0.0, r + h0]])
    out, contacts = simulate(world, state, 1e-3, 400)
    assert not np.any(contacts.kind == CONTACT_IMPACT)
    k = int(np.argmax(contacts.normal_impulse > 0))
    assert out["position"][contacts.step[k]:, 0, 2].max() <= r + 1e-9  # it never rises again


@pytest.mark.parametrize("dt", [1e-3, 1e-2])
def test_derived_threshold_sits_between_rest_and_a_gentle_drop(dt):
    """The derived threshold exceeds what a resting contact approaches at (the step's kick g dt
    plus the solver's tolerance) and stays below a 2 cm drop's impact speed; explain() shows it."""
    model = make_model([SHAPE_SPHERE], [0.1], [1.0])
    p = ContactParams()
    world = ContactWorld(model, p, *SPLIT)
    th = world.restitution_threshold(dt)
    assert G * dt + p.velocity_tolerance < th < math.sqrt(2 * G * 0.02)
    assert any("impacts above 2 |a| dt" in why for _, why in world.explain())
    with pytest.raises(ValueError, match="restitution_threshold"):
        ContactParams(restitution_threshold=-0.1)


def test_bodies_colliding_in_the_air_keep_their_angular_momentum():
    """Three spheres collide in the air (oblique, with friction: spins change; 0-1 at step 128,
    1-2 at 144, 0-1 at 185) over a ground they never reach, each in free flight between its
    collisions. Under uniform gravity the group's angular momentum about its centre of mass,
    sum (x - c) x P + L, is conserved exactly (gravity exerts no torque about c) and the total
    momentum is P0 + M g t: the step keeps both only if pushed and free bodies fly by one scheme
    (a symplectic pushed body beside an exact free one changes the former by O(h^2 g |P|) a
    step)."""
    model = make_model([SHAPE_SPHERE] * 3, [0.1] * 3, [1.0, 2.0, 1.5], restitution=0.8,
                       friction=0.5)
    x0 = np.array([[0.0, 0.0, 5.0], [0.5, 0.08, 5.0], [1.0, 0.35, 5.0]])
    v0 = np.array([[1.5, 0.0, 0.2], [-1.0, 0.0, 0.0], [-3.0, -1.5, 0.0]])
    state = make_state(model, x0, v0, omega=[[0, 0, 3.0], [1.0, 0, 0], [0, -2.0, 0]])
    spin0 = state.angular_momentum_world.copy()
    world = ContactWorld(model, ContactParams(), *SPLIT)
    dt, n_steps = 1e-3, 600
    out, contacts = simulate(world, state, dt, n_steps)
    pushed = contacts.normal_impulse > 0
    hits = {(int(a), int(b)) for a, b in zip(contacts.body_a[pushed], contacts.body_b[pushed])}
    assert hits == {(0, 1), (1, 2)}  # the chain of impacts, and nothing touched the ground
    m = model.body_mass
    x, p, spin = out["position"], out["linear_momentum"], out["angular_momentum"]
    c = (m[None, :, None] * x).sum(1) / m.sum()
    l_cm = (np.cross(x - c[:, None], p) + spin).sum(1)
    l0 = (np.cross(x0 - (m[:, None] * x0).sum(0) / m.sum(), m[:, None] * v0) + spin0).sum(0)
    # measured 3.0e-13 relative to |L| = 0.099 N m s (1.4e-4 when pushed bodies moved by
    # symplectic Euler beside exactly flying ones)
    assert np.abs(l_cm - l0).max() <= 1e-12 * np.abs(l0).max()
    t = np.arange(1, n_steps + 1) * dt
    p_exact = (m[:, None] * v0).sum(0) + m.sum() * np.array([0, 0, -G]) * t[:, None]
    assert np.abs(p.sum(1) - p_exact).max() <= 1e-12  # measured 1.8e-13 N s
