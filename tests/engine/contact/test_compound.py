"""Compound bodies (``shape = "compound"``, several parts as one rigid body): mass properties
against a parallel-axis sum derived here and trimesh's integration of the parts' union mesh,
the body frame (centre of mass, principal axes), the scene keys' one-line errors, and the engine
with a geom table: resting still, rolling down a slope by the closed form, no contacts between
parts of one body.

Closed forms (uniform density rho, every part's volume counted):

* a dumbbell of two balls of radius r at z = +-d joined by a capsule (radius rc, half length
  hc) along z: M = rho (2 V_s + V_c), the centre of mass at 0 by symmetry, I_zz = 2 * 2/5 m_s r^2
  + I_zz(capsule), I_xx = I_yy = 2 (2/5 m_s r^2 + m_s d^2) + I_xx(capsule) (parallel axes);
* rolling without slip on its two balls down a slope of angle theta (axle horizontal, across the
  slope): M a = M g sin(theta) - f, I_axle alpha = f r, a = alpha r, so a = g sin(theta) /
  (1 + I_axle / (M r^2)); symplectic Euler's positions are s_n = a h^2 n (n + 1) / 2 =
  a t^2 / 2 (1 + h / t) (tests/engine/contact/test_exact_motion.py, the sphere).
"""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest

from rblog.engine.contact import ContactParams, ContactWorld
from rblog.engine.scene import parse_scene
from rblog.errors import SceneError
from tests.engine.contact.test_contact import SPLIT, simulate

G = 9.81
CONVERGED = dict(velocity_tolerance=1e-13, max_velocity_iterations=200)


def _dumbbell(r=0.05, d=0.15, rc=0.02, hc=0.1, density=1000.0, extra=""):
    return textwrap.dedent(f"""
        [[body]]
        name = "dumbbell"
        shape = "compound"
        density = {density}
        parts = [
          {{shape = "sphere", radius = {r}, position = [0, 0, {-d}]}},
          {{shape = "sphere", radius = {r}, position = [0, 0, {d}]}},
          {{shape = "capsule", radius = {rc}, half_length = {hc}}},
        ]
        """) + extra


SIM = "[sim]\ndt = 1e-3\nduration = 1.0\n"


def test_dumbbell_mass_properties_are_the_parallel_axis_sum():
    r, d, rc, hc, rho = 0.05, 0.15, 0.02, 0.1, 1000.0
    sc = parse_scene(SIM + _dumbbell(r, d, rc, hc, rho))
    m_s = rho * 4.0 / 3.0 * math.pi * r ** 3
    # capsule: a cylinder of length 2 hc and two hemispheres (mass_properties' derivation,
    # written again here): I_zz = m_cyl rc^2 / 2 + 2/5 m_ball rc^2, I_xx = m_cyl (rc^2 / 4 +
    # hc^2 / 3) + m_ball (2/5 rc^2 + hc^2 + 3/4 hc rc)
    m_cyl = rho * 2.0 * math.pi * rc * rc * hc
    m_cb = rho * 4.0 / 3.0 * math.pi * rc ** 3
    izz_c = 0.5 * m_cyl * rc * rc + 0.4 * m_cb * rc * rc
    ixx_c = m_cyl * (rc * rc / 4.0 + hc * hc / 3.0) + m_cb * (0.4 * rc * rc + hc * hc + 0.75 * hc * rc)
    mass = 2.0 * m_s + m_cyl + m_cb
    izz = 2.0 * 0.4 * m_s * r * r + izz_c
    ixx = 2.0 * (0.4 * m_s * r * r + m_s * d * d) + ixx_c
    m = sc.model
    # measured: mass 2.2e-16, moments 1.1e-16 relative
    assert m.body_mass[0] == pytest.approx(mass, rel=1e-12)
    np.testing.assert_allclose(m.body_inertia_diag[0], [ixx, ixx, izz], rtol=1e-12)
    # the body frame is the scene's (centre of mass at 0, axes principal): parts as given
    np.testing.assert_array_equal(sc.state.position[0], [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(sc.state.quat_wxyz[0], [1.0, 0.0, 0.0, 0.0])
    rows = np.flatnonzero(m.geom_body == 0)
    np.testing.assert_allclose(m.geom_pos_body[rows], [[0, 0, -d], [0, 0, d], [0, 0, 0]], atol=1e-15)
    assert m.body_shape[0] == -1 and len(rows) == 3


def _boxes_toml(boxes, mass=3.0, position=(0.4, -0.2, 1.0), orient=""):
    parts = ",\n  ".join(
        f'{{shape = "box", half_extents = {list(e)}, position = {list(p)}, '
        f'axis_angle = {{axis = {list(ax)}, angle_deg = {ang}}}}}' for e, p, ax, ang in boxes)
    return SIM + textwrap.dedent(f"""
        [[body]]
        name = "boxes"
        shape = "compound"
        mass = {mass}
        position = {list(position)}
        {orient}
        parts = [
          {parts},
        ]
        """)


# three disjoint boxes, turned, the union asymmetric (principal axes off the scene's)
BOXES = [((0.2, 0.05, 0.04), (0.0, 0.0, 0.0), (0, 0, 1), 0.0),
         ((0.03, 0.12, 0.05), (0.31, 0.05, 0.02), (0, 0, 1), 20.0),
         ((0.05, 0.05, 0.1), (-0.1, 0.02, 0.25), (1, 1, 0), 35.0)]


def test_disjoint_boxes_match_trimesh_of_their_union():
    trimesh = pytest.importorskip("trimesh")
    from scipy.spatial.transform import Rotation

    q_body = 'axis_angle = {axis = [0.3, -1, 0.2], angle_deg = 50}'
    sc = parse_scene(_boxes_toml(BOXES, orient=q_body))
    r_body = Rotation.from_rotvec(np.radians(50) * np.array([0.3, -1, 0.2]) /
                                  np.linalg.norm([0.3, -1, 0.2])).as_matrix()
    x_body = np.array([0.4, -0.2, 1.0])
    meshes = []
    for e, p, ax, ang in BOXES:
        t = np.eye(4)
        t[:3, :3] = Rotation.from_rotvec(np.radians(ang) * np.array(ax) / np.linalg.norm(ax)).as_matrix()
        t[:3, 3] = p
        meshes.append(trimesh.creation.box(extents=2 * np.array(e), transform=t))
    # disjoint (box 1 spans x >= 0.24 beyond box 0's 0.2, box 2 z >= 0.25 - |its half
    # diagonal 0.122| above box 0's 0.04): the union's integrals are the parts' sums
    union = trimesh.util.concatenate(meshes)
    union.density = 3.0 / union.volume
    ref_c = union.center_mass
    ref_i = union.moment_inertia  # about the centre of mass, the scene's body frame
    m = sc.model
    ref_moments = np.linalg.eigvalsh(ref_i)
    # measured: moments 6.7e-16 relative, centre 0 m, off-diagonal 6.4e-16 of the largest
    # moment, parts' centres 1.1e-16 m
    np.testing.assert_allclose(np.sort(m.body_inertia_diag[0]), ref_moments, rtol=1e-12)
    np.testing.assert_allclose(sc.state.position[0], x_body + r_body @ ref_c, rtol=0, atol=1e-12)
    # the logged axes are the tensor's principal axes: R_body^T-rotated tensor diagonal
    r_log = sc.state.rotation[0]
    j_log = r_log.T @ (r_body @ ref_i @ r_body.T) @ r_log
    np.testing.assert_allclose(j_log, np.diag(m.body_inertia_diag[0]), rtol=0,
                               atol=1e-12 * ref_moments.max())
    # each part where the scene put it: the box's world centre
    rows = np.flatnonzero(m.geom_body == 0)
    for g, (e, p, _, _) in zip(rows, BOXES):
        world = sc.state.position[0] + r_log @ m.geom_pos_body[g]
        np.testing.assert_allclose(world, x_body + r_body @ np.array(p), rtol=0, atol=1e-12)
        np.testing.assert_array_equal(m.geom_size[g], e)


@pytest.mark.parametrize("body,key,words", [
    ('shape = "compound"\nmass = 1', "body[0].parts", "missing (a list of part tables"),
    ('shape = "compound"\nmass = 1\nparts = []', "body[0].parts",
     "expected a non-empty list of part tables, got []"),
    ('shape = "compound"\nmass = 1\nparts = [{shape = "cone", radius = 1}]',
     "body[0].parts[0].shape", "expected one of sphere, box, capsule, cylinder, hull"),
    ('shape = "compound"\nmass = 1\nparts = [{shape = "sphere"}]', "body[0].parts[0].radius",
     "missing (a positive number, m)"),
    ('shape = "compound"\nmass = 1\nparts = [{shape = "sphere", radius = 1, pos = [0, 0, 1]}]',
     "body[0].parts[0].pos", "unknown key (expected one of: axis_angle"),
    ('shape = "compound"\nmass = 1\nparts = [{shape = "box", half_extents = [1, 1, 1], '
     'radius = 1}]', "body[0].parts[0].radius", "a box takes half_extents, not radius"),
    ('shape = "compound"\nmass = 1\nradius = 1\nparts = [{shape = "sphere", radius = 1}]',
     "body[0].radius", "a compound takes parts (each with its shape and size), not radius"),
    ('shape = "compound"\nmass = 1\ninertia_diag = [1, 1, 1]\nparts = [{shape = "sphere", '
     'radius = 1}]', "body[0].inertia_diag", "a compound takes parts"),
    ('shape = "sphere"\nradius = 1\nmass = 1\nparts = [{shape = "sphere", radius = 1}]',
     "body[0].parts", "only a compound takes parts, a sphere takes radius"),
    ('shape = "compound"\nmass = 1\nparts = [1]', "body[0].parts[0]", "expected a table"),
    ('shape = "compound"\nmass = 1\nparts = [{shape = "sphere", radius = 1, '
     'quat_wxyz = [0, 0, 0, 0]}]', "body[0].parts[0].quat_wxyz", "expected a non-zero quaternion"),
])
def test_bad_compound_keys_one_line(body, key, words):
    with pytest.raises(SceneError) as e:
        parse_scene(SIM + "[[body]]\n" + body + "\n", "s.toml")
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"s.toml: {key}: ") and words in msg, msg


def test_rblog_validate_prints_a_bad_part_in_one_line_exit_2(tmp_path):
    from click.testing import CliRunner

    from rblog_cli.main import main

    p = tmp_path / "bad.toml"
    p.write_text(SIM + '[[body]]\nshape = "compound"\nmass = 1\nparts = [{shape = "box"}]\n')
    res = CliRunner().invoke(main, ["validate", str(p)])
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "body[0].parts[0].half_extents: missing" in lines[0], res.output


def _run(toml, seconds, dt=1e-3, sleep=False, **params):
    sc = parse_scene(toml)
    start = sc.state.position.copy(), sc.state.quat_wxyz.copy()
    world = ContactWorld(sc.model, ContactParams(sleep=sleep, **params), *SPLIT)
    n = int(round(seconds / dt))
    stride = max(1, n // 1000)
    out, contacts, bad, _ = simulate(world, sc.state, dt, n, stride)  # samples after the steps
    assert bad == -1
    return sc, out, start


RESTING = """
[sim]
dt = 1e-3
duration = 10.0
[ground]
restitution = 0.0
"""


@pytest.mark.parametrize("sleep", [False, True])
@pytest.mark.parametrize("pose", ["dumbbell_lying", "tee_lying", "tee_standing"])
def test_compound_resting_still_for_10_s(pose, sleep):
    """A dumbbell on its two balls, and a T of two boxes (a bar 0.4 x 0.06 x 0.06 on top of a
    0.06 x 0.06 x 0.2 stem: lying on both, or standing on the stem's end), placed touching the
    ground: its centre of mass must stay at the height the geometry gives, still."""
    if pose == "dumbbell_lying":
        # axle along y: the balls' lowest points at z = 0 when the centre is at r
        toml = RESTING + _dumbbell() + 'position = [0.1, 0.2, 0.05]\n' \
            'axis_angle = {axis = [1, 0, 0], angle_deg = 90}\n'
        z_com = 0.05
    else:
        stand = pose == "tee_standing"
        # the T in its scene frame: bar centred at z = 0.13 (0.1 + 0.03), stem |z| <= 0.1;
        # masses by volume: bar 0.4*0.06*0.06, stem 0.06*0.06*0.2: c_z = (2 * 0.13) / 3
        bar, stem = 0.4 * 0.06 * 0.06, 0.06 * 0.06 * 0.2
        cz = bar * 0.13 / (bar + stem)
        if stand:  # on the stem's end: scene origin 0.1 above the ground
            orient, z_com = "", 0.1 + cz
        else:  # turned 90 deg about x: the scene's z is the world's -y; lying on both boxes
            orient, z_com = "axis_angle = {axis = [1, 0, 0], angle_deg = 90}", 0.03
        toml = RESTING + textwrap.dedent(f"""
            [[body]]
            name = "tee"
            shape = "compound"
            density = 700
            position = [0.0, 0.0, {0.1 if stand else 0.03}]
            {orient}
            parts = [
              {{shape = "box", half_extents = [0.2, 0.03, 0.03], position = [0, 0, 0.13]}},
              {{shape = "box", half_extents = [0.03, 0.03, 0.1]}},
            ]
            """)
    sc, out, (p0, q0) = _run(toml, 10.0, sleep=sleep)
    assert p0[0, 2] == pytest.approx(z_com, abs=1e-15)
    pos, quat = out["position"][:, 0], out["quat_wxyz"][:, 0]
    drift = np.abs(pos - p0[0]).max()
    turn = np.abs(quat - q0[0]).max()
    # measured (awake and asleep alike): dumbbell 2.0e-9 m / 2.2e-9 (the first steps' settling
    # under the cold-started solve), tee lying 1.4e-10 m / 4.2e-12, standing 1.9e-22 m /
    # 5.4e-22; the limit is 1 um
    assert drift <= 1e-6, drift
    assert turn <= 1e-6, turn


def test_dumbbell_rolls_down_a_slope_by_the_closed_form():
    """The dumbbell on its balls (axle along y, across the slope) down 15 deg (gravity tilted
    about y): s_n = a t^2 / 2 (1 + h / t) with a = g sin(theta) / (1 + I_axle / (M r^2))."""
    th = math.radians(15.0)
    r = 0.05
    toml = textwrap.dedent(f"""
        [sim]
        dt = 1e-3
        duration = 1.0
        gravity = [{G * math.sin(th)!r}, 0.0, {-G * math.cos(th)!r}]
        [ground]
        restitution = 0.0
        friction = 0.8
        """) + _dumbbell(r=r) + 'position = [0, 0, 0.05]\nrestitution = 0.0\nfriction = 0.8\n' \
        'axis_angle = {axis = [1, 0, 0], angle_deg = 90}\n'
    sc = parse_scene(toml)
    mass = sc.model.body_mass[0]
    i_axle = sc.model.body_inertia_diag[0][2]  # about the body's z, the axle
    acc = G * math.sin(th) / (1.0 + i_axle / (mass * r * r))
    dt = 1e-3
    world = ContactWorld(sc.model, ContactParams(sleep=False, **CONVERGED), *SPLIT)
    out, _, bad, _ = simulate(world, sc.state, dt, 1000)
    assert bad == -1
    t = dt * np.arange(1, 1001)  # a sample after every step
    x = out["position"][:, 0]
    s = x[:, 0]
    euler = 0.5 * acc * t ** 2 * (1.0 + dt / t)
    # measured: 4.4e-15 relative to the symplectic-Euler closed form
    assert np.abs(s / euler - 1.0).max() <= 1e-12
    assert np.abs(x[:, 1]).max() <= 1e-12  # straight down the slope (measured 1.6e-16 m)
    assert np.abs(x[:, 2] - 0.05).max() <= 1e-12  # on its balls (measured 1.1e-16 m)


def test_parts_of_one_body_never_touch():
    """A dumbbell whose capsule overlaps both balls (and the balls each other's capsule) floats
    with no contact at all: the broadphase never pairs two geoms of one body."""
    toml = "[sim]\ndt = 1e-3\nduration = 0.2\ngravity = [0, 0, 0]\n" + _dumbbell(d=0.06, hc=0.1) \
        + 'angular_velocity = [1.0, 2.0, 0.5]\n[[body]]\nshape = "sphere"\nradius = 0.01\n' \
          'mass = 1\nposition = [5, 0, 0]\n'
    sc = parse_scene(toml)
    world = ContactWorld(sc.model, ContactParams(sleep=False), *SPLIT)
    out, contacts, bad, _ = simulate(world, sc.state, 1e-3, 200)
    assert bad == -1 and len(contacts.step) == 0
    np.testing.assert_array_equal(out["linear_momentum"][:, 0], 0.0)


def test_compound_lands_on_its_lowest_part():
    """A T dropped stem down from 0.3 m comes to rest on the stem's end: the centre of mass
    ends at 0.1 + c_z above the ground (the standing pose of the resting test)."""
    bar, stem = 0.4 * 0.06 * 0.06, 0.06 * 0.06 * 0.2
    cz = bar * 0.13 / (bar + stem)
    toml = textwrap.dedent("""
        [sim]
        dt = 1e-3
        duration = 2.0
        [ground]
        restitution = 0.0
        [[body]]
        name = "tee"
        shape = "compound"
        density = 700
        restitution = 0.0
        position = [0.0, 0.0, 0.3]
        parts = [
          {shape = "box", half_extents = [0.2, 0.03, 0.03], position = [0, 0, 0.13]},
          {shape = "box", half_extents = [0.03, 0.03, 0.1]},
        ]
        """)
    sc, out, _ = _run(toml, 2.0)
    z = out["position"][-1, 0, 2]
    # measured 0 m off, upright to 2.7e-19
    assert z == pytest.approx(0.1 + cz, abs=1e-9)
    np.testing.assert_allclose(out["quat_wxyz"][-1, 0], [1, 0, 0, 0], atol=1e-12)


def test_spinning_dumbbell_parts_are_swept_by_the_turn():
    """A long dumbbell (balls 0.3 m off its centre) spinning at 40 rad/s about a horizontal axis
    drops onto the ground: each ball sweeps 12 mm a step at dt = 1 ms, so a geom box swept only by
    its body's linear motion would let a ball in ~12 mm deep. The per-geom turn bound (h |omega|
    times the part's reach from the centre of mass) keeps every contact speculative: the engine's
    own narrowphase on every sampled pose finds no point deeper than the solver's slop."""
    from rblog.engine.contact.measure import max_penetration

    toml = "[sim]\ndt = 1e-3\nduration = 0.5\n[ground]\nrestitution = 0.0\n" + \
        _dumbbell(d=0.3, hc=0.25) + 'position = [0, 0, 0.4]\nangular_velocity = [40.0, 0, 0]\n'
    sc = parse_scene(toml)
    world = ContactWorld(sc.model, ContactParams(sleep=False), *SPLIT)
    out, contacts, bad, _ = simulate(world, sc.state, 1e-3, 500)
    assert bad == -1 and len(contacts.step) > 0
    deepest = max(max_penetration(world, out["position"][k], out["rotation"][k])
                  for k in range(len(out["position"])))
    # measured: 0 m (one strike, at step 143, throws the dumbbell up); the slop is 5e-4 m
    assert deepest <= 5e-4, deepest


def test_a_hull_part_sits_where_its_vertices_say():
    """A compound of a hull (a box's corners, off-centre and turned in the part's frame) and a
    ball: its mass properties match the same union of a box part and the ball (the box's closed
    form), and the hull's logged vertices land on the corners' world positions."""
    e = np.array([0.1, 0.05, 0.03])
    corners = np.array([[sx * e[0], sy * e[1], sz * e[2]] for sx in (-1, 1) for sy in (-1, 1)
                        for sz in (-1, 1)]) + [0.02, -0.01, 0.04]
    verts = "[" + ", ".join(f"[{float(a)!r}, {float(b)!r}, {float(c)!r}]" for a, b, c in corners) + "]"
    ball = '{shape = "sphere", radius = 0.04, position = [-0.2, 0.05, 0.0]}'
    turn = 'axis_angle = {axis = [0, 0, 1], angle_deg = 30}'
    hull = SIM + textwrap.dedent(f"""
        [[body]]
        shape = "compound"
        density = 1000
        parts = [{{shape = "hull", vertices = {verts}, position = [0.1, 0, 0], {turn}}}, {ball}]
        """)
    # the box part at the hull's centre: its corners' mean, turned by the part's rotation
    c30, s30 = math.cos(math.radians(30)), math.sin(math.radians(30))
    rz = np.array([[c30, -s30, 0], [s30, c30, 0], [0, 0, 1]])
    centre = np.array([0.1, 0, 0]) + rz @ np.array([0.02, -0.01, 0.04])
    box = SIM + textwrap.dedent(f"""
        [[body]]
        shape = "compound"
        density = 1000
        parts = [{{shape = "box", half_extents = {e.tolist()}, position = {centre.tolist()}, {turn}}}, {ball}]
        """)
    a, b = parse_scene(hull), parse_scene(box)
    # measured: mass 2.2e-16, moments 4.4e-16 relative, centre 1.4e-17 m
    assert a.model.body_mass[0] == pytest.approx(b.model.body_mass[0], rel=1e-12)
    np.testing.assert_allclose(a.model.body_inertia_diag[0], b.model.body_inertia_diag[0], rtol=1e-12)
    np.testing.assert_allclose(a.state.position[0], b.state.position[0], rtol=0, atol=1e-15)
    m = a.model
    g = int(np.flatnonzero(np.asarray(m.geom_body) == 0)[0])
    from rblog.contract.orientation import quat_wxyz_to_matrix

    r_g = a.state.rotation[0] @ quat_wxyz_to_matrix(m.geom_quat_wxyz_body[g])
    world = a.state.position[0] + (r_g @ m.geom_vertices(g).T).T + a.state.rotation[0] @ m.geom_pos_body[g]
    want = np.array([0.1, 0, 0]) + corners @ rz.T
    # every logged vertex is a corner (measured 3.0e-17 m)
    d = np.linalg.norm(world[:, None, :] - want[None, :, :], axis=2).min(axis=1)
    assert d.max() <= 1e-12 and len(world) == 8
