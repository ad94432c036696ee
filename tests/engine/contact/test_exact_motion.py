"""Motion under a constant contact force to round-off (ContactParams.exact_contact_motion;
csrc/engine/world_step.cpp, "Exact motion on one static surface"), against closed forms derived
here from Newton's laws, and symplectic Euler's first-order error with the option off.

* A box sliding on the ground at v0 with friction mu decelerates at mu g: x(t) = v0 t - mu g t^2 / 2
  until t_stop = v0 / (mu g), where it stops at v0^2 / (2 mu g) and stays.
* A body rolling without slip down a slope of angle theta (gravity tilted, the ground level):
  m a = m g sin(theta) - f, I alpha = f r, a = alpha r, so a = g sin(theta) / (1 + I / (m r^2))
  and s(t) = a t^2 / 2: a sphere's I = 2/5 m r^2 gives 5/7 g sin(theta); a capsule of radius r
  and cylinder length 2 h (uniform density) rolling about its axis has I = m_cyl r^2 / 2 +
  2/5 m_sph r^2 over m = m_cyl + m_sph, m_cyl ~ 2 pi r^2 h, m_sph ~ 4/3 pi r^3; a solid
  cylinder on its side has I = m r^2 / 2 about its axis, a = 2/3 g sin(theta).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE
from rblog.engine.contact import ContactParams, ContactWorld
from rblog.engine.scene import parse_scene
from rblog.study.scenes import make_model, make_state
from tests.engine.contact.test_contact import SPLIT, simulate
from tests.engine.contact.test_stage_threads import threads  # noqa: F401 (the fixture)

G = 9.81
# a converged velocity solve (the default stops at 1e-4 m/s, and the first steps' normal and
# friction impulses, warm started from zero, would leave ~1e-4 m/s of error in the velocity)
CONVERGED = dict(velocity_tolerance=1e-13, max_velocity_iterations=200)


def _slide(dt, exact, mu=0.5, v0=2.0, a=0.1, seconds=0.6):
    """A 2a cube (1 kg) on the ground sliding along x at v0: (times, x of the centre, z)."""
    model = make_model([SHAPE_BOX], [[a, a, a]], [1.0], restitution=0.0, friction=mu)
    world = ContactWorld(model, ContactParams(sleep=False, exact_contact_motion=exact, **CONVERGED), *SPLIT)
    state = make_state(model, [[0.0, 0.0, a]], [[v0, 0.0, 0.0]])
    n = int(round(seconds / dt))
    out, _, bad, _ = simulate(world, state, dt, n)
    assert bad == -1
    t = dt * np.arange(1, n + 1)  # a sample after every step
    return t, out["position"][:, 0, 0], out["position"][:, 0, 2], out["linear_momentum"][:, 0]


@pytest.mark.parametrize("dt", [1e-3, 1e-2])
def test_sliding_box_follows_the_parabola_and_stops_at_v2_over_2_mu_g(dt):
    mu, v0 = 0.5, 2.0
    t, x, z, p = _slide(dt, True, mu, v0)
    t_stop = v0 / (mu * G)
    d_stop = v0 ** 2 / (2.0 * mu * G)
    sliding = t < t_stop
    parabola = v0 * t[sliding] - 0.5 * mu * G * t[sliding] ** 2
    # measured: parabola 3.3e-15 m (dt 1e-3), 2.2e-16 m (dt 1e-2)
    assert np.abs(x[sliding] - parabola).max() <= 1e-9
    # the stop inside a step (kinetic friction's closed form): measured 3.1e-15 / 1.7e-16 m
    k = np.argmax(~sliding)
    assert abs(x[k] - d_stop) <= 1e-9
    # Afterwards the solve's own residual: warm starting applies the stop step's friction
    # impulse (m |u|) again and the four points' friction rows leave ~1e-6 m/s for a step, then
    # the box rocks to rest: at most 1.4 nm at dt 1e-3, 11 nm at dt 1e-2, the same with the
    # option off (the steps after the stop are symplectic Euler's either way). Not the position
    # update's: bounded here at about 1.5-2x the measured.
    assert np.abs(x[~sliding] - d_stop).max() <= (2e-9 if dt < 5e-3 else 2.5e-8)
    assert np.abs(z[:k + 1] - 0.1).max() <= 1e-12  # neither sinks nor lifts while sliding


@pytest.mark.parametrize("dt", [1e-3, 1e-2])
def test_capsule_sliding_along_its_axis_stops_at_v2_over_2_mu_g(dt):
    """A capsule lying on its side (axis along y) pushed along its axis: no roll, kinetic
    friction mu g on its two-point line contact, the same parabola and stop as the box."""
    mu, v0 = 0.5, 2.0
    body = CAPSULE + "\nvelocity = [0, 2.0, 0]"
    t, x, _ = _roll(body, dt, True, 0.6, theta_deg=0.0)
    y, t_stop, d_stop = x[:, 1], v0 / (mu * G), v0 ** 2 / (2.0 * mu * G)
    sliding = t < t_stop
    # measured: parabola 1.8e-15 / 3.3e-16 m, the stop step 1.5e-15 / 3.3e-16 m (dt 1e-3 / 1e-2)
    assert np.abs(y[sliding] - (v0 * t[sliding] - 0.5 * mu * G * t[sliding] ** 2)).max() <= 1e-9
    assert abs(y[np.argmax(~sliding)] - d_stop) <= 1e-9
    assert np.abs(y[~sliding] - d_stop).max() <= 1e-9  # measured 1.5e-15 / 3.3e-16 m
    assert np.abs(x[:, 2] - 0.05).max() <= 1e-12  # measured 3.5e-17 / 1.9e-16 m
    assert np.abs(x[:, 0]).max() <= 1e-12  # does not roll (measured 0)


@pytest.mark.parametrize("dt", [1e-3, 1e-2])
def test_sliding_box_without_the_option_falls_short_by_h_v0_over_2(dt):
    """Symplectic Euler's x += h v_new: the stop comes short by about h v0 / 2 (1 mm at dt 1e-3)."""
    mu, v0 = 0.5, 2.0
    t, x, _, _ = _slide(dt, False, mu, v0)
    short = v0 ** 2 / (2.0 * mu * G) - x[-1]
    assert short == pytest.approx(0.5 * dt * v0, rel=0.01)  # measured 0.05 % / 0.4 % off


def _roll(body_toml, dt, exact, seconds, theta_deg=15.0):
    """Run a one-body scene on the ground under gravity tilted by theta about y (the slope runs
    down +x); returns (times, positions (S, 3), angular momenta (S, 3))."""
    th = math.radians(theta_deg)
    toml = f"""
[sim]
dt = {dt}
duration = {seconds}
gravity = [{G * math.sin(th)!r}, 0.0, {-G * math.cos(th)!r}]
[ground]
restitution = 0.0
friction = 0.5
[[body]]
{body_toml}
restitution = 0.0
friction = 0.5
"""
    sc = parse_scene(toml)
    world = ContactWorld(sc.model, ContactParams(sleep=False, exact_contact_motion=exact, **CONVERGED), *SPLIT)
    n = int(round(seconds / dt))
    out, _, bad, _ = simulate(world, sc.state, dt, n)
    assert bad == -1
    return dt * np.arange(1, n + 1), out["position"][:, 0], out["angular_momentum"][:, 0]


SPHERE = 'shape = "sphere"\nradius = 0.1\nmass = 1.0\nposition = [0, 0, 0.1]'
CAPSULE = ('shape = "capsule"\nradius = 0.05\nhalf_length = 0.15\ndensity = 1000\n'
           'position = [0, 0, 0.05]\naxis_angle = {axis = [1, 0, 0], angle_deg = 90}')
# on its side, the axis (body z) along y: rolls down +x about its axis
CYLINDER_ON_SIDE = ('shape = "cylinder"\nradius = 0.05\nhalf_length = 0.15\ndensity = 1000\n'
                    'position = [0, 0, 0.05]\naxis_angle = {axis = [1, 0, 0], angle_deg = 90}')


def _capsule_ratio(r, h):
    """I_axis / (m r^2) of a uniform capsule: cylinder of length 2 h plus a ball of radius r."""
    m_cyl, m_sph = 2.0 * math.pi * r * r * h, 4.0 / 3.0 * math.pi * r ** 3
    return (0.5 * m_cyl + 0.4 * m_sph) / (m_cyl + m_sph)


@pytest.mark.parametrize("dt", [1e-3, 1e-2])
@pytest.mark.parametrize("body", ["sphere", "capsule", "cylinder"])
def test_rolling_down_a_slope_covers_a_t2_over_2(body, dt):
    th = math.radians(15.0)
    k = {"sphere": 0.4, "capsule": _capsule_ratio(0.05, 0.15), "cylinder": 0.5}[body]
    acc = G * math.sin(th) / (1.0 + k)
    if body == "sphere":
        assert acc == pytest.approx(5.0 / 7.0 * G * math.sin(th), rel=1e-15)
    if body == "cylinder":
        assert acc == pytest.approx(2.0 / 3.0 * G * math.sin(th), rel=1e-15)
    toml = {"sphere": SPHERE, "capsule": CAPSULE, "cylinder": CYLINDER_ON_SIDE}[body]
    t, x, _ = _roll(toml, dt, True, 1.0)
    s = x[:, 0]  # from x = 0
    exact = 0.5 * acc * t ** 2
    # measured: sphere 5.6e-15 / 1.8e-15 (dt 1e-3 / 1e-2), capsule 1.8e-14 / 1.2e-15,
    # cylinder 4.0e-15 / 1.0e-15
    assert np.abs(s / exact - 1.0).max() <= 1e-9
    z0 = 0.1 if body == "sphere" else 0.05
    assert np.abs(x[:, 1]).max() <= 1e-12  # rolls straight (measured <= 1.5e-17 / 1.4e-16 m)
    assert np.abs(x[:, 2] - z0).max() <= 1e-12  # neither sinks nor lifts (5.6e-17 / 1.2e-16 m)


def test_rolling_sphere_without_the_option_lags_by_h_over_t():
    """Symplectic Euler: s_n = a h^2 n (n + 1) / 2 = a t^2 / 2 (1 + h / t), ahead by h / t."""
    dt = 1e-3
    th = math.radians(15.0)
    t, x, _ = _roll(SPHERE, dt, False, 1.0)
    s = x[-1, 0]
    exact = 0.5 * 5.0 / 7.0 * G * math.sin(th) * t[-1] ** 2
    assert abs(s / exact - 1.0) == pytest.approx(dt / t[-1], rel=1e-6)  # measured 1.2e-12


def test_exact_motion_gives_the_same_bytes_on_1_2_and_4_threads(threads):
    """300 cubes sliding apart on the ground (every one on one static surface: the rule moves
    each of them), 40 steps: the integrate stage's blocks on the pool write only their own
    bodies' rows and their own manifold's anchor flag, so 1, 2 and 4 threads give one result."""
    from rblog.engine import _core

    rng = np.random.default_rng(3)
    n, a = 300, 0.05
    grid = np.stack(np.meshgrid(np.arange(20), np.arange(15), indexing="ij"), -1).reshape(-1, 2)
    pos = np.column_stack([0.3 * grid, np.full(n, a)])
    vel = np.column_stack([rng.uniform(-1, 1, (n, 2)), np.zeros(n)])
    model = make_model([SHAPE_BOX] * n, [[a, a, a]] * n, [1.0] * n, restitution=0.0, friction=0.5)
    got = {}
    for t in (1, 2, 4):
        threads(t)
        world = ContactWorld(model, ContactParams(sleep=False, exact_contact_motion=True), *SPLIT)
        state = make_state(model, pos, vel)
        _core.thread_stats(reset=True)
        out, _, bad, _ = simulate(world, state, 1e-3, 40)
        assert bad == -1
        if t > 1:  # the stages' loops (integrate among them) did run on the pool
            assert _core.thread_stats(reset=True)["pool_calls"] >= 40, t
        got[t] = out
        assert (np.asarray(world._cache.scratch.exact_man)[:n] >= 0).all()
    for t in (2, 4):
        for k in ("position", "linear_momentum", "quat_wxyz", "rotation", "angular_momentum"):
            assert got[t][k].tobytes() == got[1][k].tobytes(), (t, k)


def _hull_on_face(name):
    """A [[body]] of tests/engine/contact/test_hull.py's hull ``name`` on its first face (that
    face on z = 0, the centre of mass above it), and the centre of mass (3,) where the scene
    puts it."""
    from tests.engine.contact.test_hull import HULLS, _fail, _on_face
    from rblog.engine.hull import build_hull

    h = build_hull(HULLS[name], _fail)
    v = _on_face(h.vertices, h.face_normal[0])
    com = build_hull(v, _fail).com
    return f'shape = "hull"\nvertices = {v.tolist()}\ndensity = 1000', com


CYLINDER_ON_END = ('shape = "cylinder"\nradius = 0.1\nhalf_length = 0.05\ndensity = 1000\n'
                   'position = [0, 0, 0.05]', np.array([0.0, 0.0, 0.05]))


@pytest.mark.parametrize("dt", [1e-3, 1e-2])
@pytest.mark.parametrize("body", ["cylinder", "hex_prism", "octahedron"])
def test_sliding_on_a_face_stops_at_v2_over_2_mu_g(body, dt):
    """A cylinder on its end, a hull on a face (a hexagon, a triangle) sliding along x at v0:
    kinetic friction mu m g on the face, the box's parabola and stop (the face's width against
    its height keeps it from tipping: mu < half width / height)."""
    mu, v0 = 0.5, 2.0
    toml, c0 = CYLINDER_ON_END if body == "cylinder" else _hull_on_face(body)
    t, x, _ = _roll(toml + "\nvelocity = [2.0, 0, 0]", dt, True, 0.6, theta_deg=0.0)
    s = x[:, 0] - c0[0]
    t_stop, d_stop = v0 / (mu * G), v0 ** 2 / (2.0 * mu * G)
    sliding = t < t_stop
    k = np.argmax(~sliding)
    # measured (dt 1e-3 / 1e-2): parabola cylinder 1.2e-15 / 1.1e-16 m, hex prism 5.7e-15 /
    # 4.1e-12 m, octahedron 3.7e-15 / 1.7e-16 m; the stop step 7.2e-16 / 1.9e-15, 1.3e-11 /
    # 4.1e-12, 3.5e-15 / 5.6e-17 m (the hexagon's four kept points are not symmetric about the
    # centre: its friction turns it a little, 3.4e-9 m sideways at dt 1e-2)
    assert np.abs(s[sliding] - (v0 * t[sliding] - 0.5 * mu * G * t[sliding] ** 2)).max() <= 1e-9
    assert abs(s[k] - d_stop) <= 1e-9
    # neither sinks nor lifts: measured <= 5.6e-17 m, but the hex prism 8.3e-12 m at dt 1e-2
    assert np.abs(x[:k + 1, 2] - c0[2]).max() <= 2e-11


def test_a_cylinder_held_on_a_slope_by_static_friction_stays_still():
    """A cylinder standing on its cap on a 15 deg slope (mu 0.9 > tan 15 deg): a rolling pair,
    so no friction anchor holds it, only the velocity solve, whose residual (~1e-4 m/s in the
    first steps) is no motion under a constant force: the rule leaves such a body to symplectic
    Euler (velocity_tolerance; world_step.cpp, exact_correction), and it settles as with the
    option off. The trapezoid on that residual settled it over 0.17 s instead of 0.05 s and
    moved it 2.7e-7 m after the first 0.1 s sample."""
    from rblog.engine import integrators as rot

    th = np.radians(15.0)
    n = np.array([np.sin(th), 0.0, np.cos(th)])
    r, hl = 0.05, 0.1
    c = hl * n
    sc = parse_scene(f"""
[sim]
dt = 1e-3
duration = 3.0
[ground]
normal = [{float(n[0])!r}, 0.0, {float(n[2])!r}]
friction = 0.9
restitution = 0.0
[[body]]
shape = "cylinder"
radius = {r}
half_length = {hl}
density = 1000
friction = 0.9
position = [{float(c[0])!r}, 0.0, {float(c[2])!r}]
axis_angle = {{axis = [0, 1, 0], angle_deg = 15}}
""")
    world = ContactWorld(sc.model, ContactParams(sleep=False, exact_contact_motion=True),
                         rot.METHOD_SPLITTING, rot.ORTHO_NORMALIZE)
    out, _, bad, _ = simulate(world, sc.state, 1e-3, 3000, stride=100)
    assert bad == -1
    pos, quat = out["position"][:, 0], out["quat_wxyz"][:, 0]
    # measured from the 0.1 s sample: 6.9e-18 m, 3.0e-18 in the quaternion
    assert np.abs(pos - pos[0]).max() <= 1e-9
    assert np.abs(quat - quat[0]).max() <= 1e-9
