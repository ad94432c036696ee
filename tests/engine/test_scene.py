"""Scene files: every class of bad input is a one-line SceneError naming the file, the key path and
what was expected; valid scenes build the bodies that rigid-body theory and the format say.

Reference values: box inertia m/3 (b^2 + c^2, a^2 + c^2, a^2 + b^2) for half-extents (a, b, c),
sphere 2/5 m r^2, box volume 8abc, sphere 4/3 pi r^3; rotations from scipy.spatial.transform.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rblog.errors import RblogError, SceneError
from rblog.engine.scene import load_scene, parse_scene

SIM = """
[sim]
dt = 1e-3
duration = 1.0
gravity = [0.0, 0.0, 0.0]
"""
BOX = """
[[body]]
name = "box"
shape = "box"
half_extents = [0.3, 0.2, 0.1]
mass = 2.0
"""


def body(**kw) -> str:
    """A [[body]] table: a valid 2 kg box unless keys are overridden (None removes a key)."""
    d = {"name": '"box"', "shape": '"box"', "half_extents": "[0.3, 0.2, 0.1]", "mass": "2.0"}
    d.update(kw)
    return "[[body]]\n" + "".join(f"{k} = {v}\n" for k, v in d.items() if v is not None)


def sim(**kw) -> str:
    d = {"dt": "1e-3", "duration": "1.0", "gravity": "[0.0, 0.0, 0.0]"}
    d.update(kw)
    return "[sim]\n" + "".join(f"{k} = {v}\n" for k, v in d.items() if v is not None)


GRID = """
[[generator]]
layout = "grid"
grid = [2, 2, 1]
{extra}
[generator.body]
shape = "sphere"
radius = 0.1
mass = 1.0
{body}
"""
RANDOM = """
[[generator]]
layout = "random"
count = 5
region_min = [0.0, 0.0, 0.0]
region_max = [1.0, 1.0, 1.0]
{extra}
[generator.body]
shape = "sphere"
radius = 0.1
mass = 1.0
"""

# (id, scene text, key path, words of what was expected)
BAD = [
    # unknown keys
    ("unknown-top", SIM + BOX + "\n[simulation]\ndt = 1\n", "simulation", "unknown key"),
    ("unknown-sim", sim(step="1e-3") + BOX, "sim.step", "unknown key"),
    ("unknown-body", SIM + body(colour='"red"'), "body[0].colour", "unknown key"),
    ("unknown-body-2", SIM + BOX + body(name='"b2"', masss="1.0"), "body[1].masss", "unknown key"),
    ("unknown-axis-angle", SIM + body(axis_angle="{ axis = [0, 0, 1], deg = 30 }"),
     "body[0].axis_angle.deg", "unknown key"),
    ("unknown-generator", SIM + GRID.format(extra="colour = 1", body=""), "generator[0].colour",
     "unknown key"),
    ("unknown-generator-body", SIM + GRID.format(extra="", body="colour = 1"),
     "generator[0].body.colour", "unknown key"),
    # wrong types
    ("type-mass-string", SIM + body(mass='"heavy"'), "body[0].mass", "expected a number"),
    ("type-mass-bool", SIM + body(mass="true"), "body[0].mass", "expected a number"),
    ("type-dt-string", sim(dt='"0.01"') + BOX, "sim.dt", "expected a number"),
    ("type-position-len", SIM + body(position="[0.0, 1.0]"), "body[0].position",
     "expected a list of 3 numbers"),
    ("type-position-scalar", SIM + body(position="1.0"), "body[0].position",
     "expected a list of 3 numbers"),
    ("type-position-elem", SIM + body(position='[0.0, "up", 1.0]'), "body[0].position[1]",
     "expected a number"),
    ("type-shape", SIM + body(shape="3"), "body[0].shape", "expected a string"),
    ("type-shape-choice", SIM + body(shape='"cone"'), "body[0].shape", "expected one of"),
    ("type-sim-table", "sim = 3\n" + BOX, "sim", "expected a table"),
    ("type-integrator", sim(integrator='"euler"') + BOX, "sim.integrator", "expected one of"),
    ("type-ortho-for-integrator", sim(integrator='"splitting"', orthonormalize='"polar"') + BOX,
     "sim.orthonormalize", "expected one of"),
    ("type-log-every", sim(log_every="0.5") + BOX, "sim.log_every", "expected an integer"),
    # non-positive
    ("mass-zero", SIM + body(mass="0.0"), "body[0].mass", "expected a positive number"),
    ("mass-negative", SIM + body(mass="-1.0"), "body[0].mass", "expected a positive number"),
    ("density-zero", SIM + body(mass=None, density="0"), "body[0].density",
     "expected a positive number"),
    ("radius-zero", SIM + body(shape='"sphere"', half_extents=None, radius="0.0"),
     "body[0].radius", "expected a positive number"),
    ("radius-negative", SIM + body(shape='"sphere"', half_extents=None, radius="-0.1"),
     "body[0].radius", "expected a positive number"),
    ("half-extents-zero", SIM + body(half_extents="[0.3, 0.0, 0.1]"), "body[0].half_extents[1]",
     "expected a positive number"),
    ("half-extents-negative", SIM + body(half_extents="[0.3, 0.2, -0.1]"),
     "body[0].half_extents[2]", "expected a positive number"),
    ("inertia-zero", SIM + body(inertia_diag="[1.0, 0.0, 1.0]"), "body[0].inertia_diag[1]",
     "expected a positive number"),
    ("inertia-triangle", SIM + body(inertia_diag="[1.0, 1.0, 3.0]"), "body[0].inertia_diag",
     "triangle inequality"),
    ("dt-zero", sim(dt="0.0") + BOX, "sim.dt", "expected a positive number"),
    ("duration-negative", sim(duration="-1.0") + BOX, "sim.duration", "expected a positive number"),
    # non-finite numbers (TOML has nan and inf literals)
    ("nan-mass", SIM + body(mass="nan"), "body[0].mass", "expected a finite number"),
    ("inf-dt", sim(dt="inf") + BOX, "sim.dt", "expected a finite number"),
    ("inf-position", SIM + body(position="[0.0, -inf, 1.0]"), "body[0].position[1]",
     "expected a finite number"),
    ("nan-velocity", SIM + body(velocity="[+nan, 0.0, 0.0]"), "body[0].velocity[0]",
     "expected a finite number"),
    ("nan-gravity", sim(gravity="[0.0, 0.0, nan]") + BOX, "sim.gravity[2]",
     "expected a finite number"),
    ("inf-torque", SIM + body(torque="[0.0, inf, 0.0]"), "body[0].torque[1]",
     "expected a finite number"),
    # zero quaternion
    ("zero-quat-wxyz", SIM + body(quat_wxyz="[0.0, 0.0, 0.0, 0.0]"), "body[0].quat_wxyz",
     "non-zero quaternion"),
    ("zero-quat-xyzw", SIM + body(quat_xyzw="[0.0, 0.0, 0.0, 0.0]"), "body[0].quat_xyzw",
     "non-zero quaternion"),
    ("zero-axis", SIM + body(axis_angle="{ axis = [0, 0, 0], angle_deg = 30 }"),
     "body[0].axis_angle.axis", "non-zero vector"),
    ("two-orientations", SIM + body(quat_wxyz="[1, 0, 0, 0]", rotvec="[0, 0, 1]"),
     "body[0].rotvec", "give one orientation"),
    # missing [sim], dt, duration
    ("missing-sim", BOX, "sim", "missing"),
    ("missing-dt", sim(dt=None) + BOX, "sim.dt", "missing"),
    ("missing-duration", sim(duration=None) + BOX, "sim.duration", "missing"),
    ("missing-shape", SIM + body(shape=None), "body[0].shape", "missing"),
    ("missing-half-extents", SIM + body(half_extents=None), "body[0].half_extents", "missing"),
    ("missing-radius", SIM + body(shape='"sphere"', half_extents=None), "body[0].radius",
     "missing"),
    ("no-bodies", SIM, "body", "no bodies"),
    # mass and density
    ("mass-and-density", SIM + body(density="1000.0"), "body[0].mass",
     "exactly one of mass (kg) or density"),
    ("neither-mass-nor-density", SIM + body(mass=None), "body[0].mass",
     "exactly one of mass (kg) or density"),
    ("two-angular-velocities", SIM + body(angular_velocity="[0, 0, 1]",
                                          angular_velocity_body="[0, 0, 1]"),
     "body[0].angular_velocity_body", "not both"),
    ("duplicate-names", SIM + BOX + BOX, "body.name", "'box' is used twice"),
    # bad generators
    ("gen-layout", SIM + GRID.format(extra="", body="").replace('"grid"', '"hex"'),
     "generator[0].layout", "expected one of grid, random"),
    ("gen-grid-missing", SIM + GRID.format(extra="", body="").replace("grid = [2, 2, 1]", ""),
     "generator[0].grid", "missing"),
    ("gen-grid-zero", SIM + GRID.format(extra="", body="").replace("[2, 2, 1]", "[2, 0, 1]"),
     "generator[0].grid[1]", "expected an integer >= 1"),
    ("gen-grid-float", SIM + GRID.format(extra="", body="").replace("[2, 2, 1]", "[2, 2.5, 1]"),
     "generator[0].grid[1]", "expected an integer"),
    ("gen-grid-with-count", SIM + GRID.format(extra="count = 4", body=""), "generator[0].count",
     "not count"),
    ("gen-random-count", SIM + RANDOM.format(extra="").replace("count = 5", ""),
     "generator[0].count", "missing"),
    ("gen-random-region", SIM + RANDOM.format(extra="").replace("region_max = [1.0, 1.0, 1.0]",
                                                                 "region_max = [1.0, -1.0, 1.0]"),
     "generator[0].region_max", "region_max >= region_min"),
    ("gen-spin-order", SIM + GRID.format(extra="spin = [3.0, 1.0]", body=""), "generator[0].spin",
     "min <= max"),
    ("gen-speed-negative", SIM + GRID.format(extra="speed = [-1.0, 1.0]", body=""),
     "generator[0].speed[0]", "expected a number >= 0"),
    ("gen-body-name", SIM + GRID.format(extra="", body='name = "x"'), "generator[0].body.name",
     "name_prefix"),
    ("gen-body-mass", SIM + GRID.format(extra="", body="").replace("mass = 1.0", "mass = -1.0"),
     "generator[0].body.mass", "expected a positive number"),
    ("gen-not-array", SIM + "[generator]\nlayout = \"grid\"\n", "generator",
     "expected an array of tables"),
]


@pytest.mark.parametrize("text,key,expected", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_scene_raises_scene_error(text, key, expected):
    path = "scenes/bad.toml"
    with pytest.raises(SceneError) as info:
        parse_scene(text, path)
    e = info.value
    msg = str(e)
    assert "\n" not in msg
    assert isinstance(e, RblogError) and e.exit_code == 2
    assert e.path == path and e.key == key
    assert msg.startswith(f"{path}: {key}: "), msg
    assert expected in msg, msg


def test_bad_ids_unique():
    assert len({b[0] for b in BAD}) == len(BAD)


def test_malformed_toml_names_file(tmp_path):
    p = tmp_path / "broken.toml"
    p.write_text(SIM + "[[body]]\nmass = \n", encoding="utf-8")
    with pytest.raises(SceneError) as info:
        load_scene(p)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(f"{p}: ")
    assert "not valid TOML" in msg
    assert "line" in msg  # where in the file


def test_missing_file_names_file(tmp_path):
    p = tmp_path / "nowhere" / "scene.toml"
    with pytest.raises(SceneError) as info:
        load_scene(p)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg == f"{p}: no such file"


def test_directory_is_not_a_scene(tmp_path):
    with pytest.raises(SceneError) as info:
        load_scene(tmp_path)
    assert str(info.value).startswith(f"{tmp_path}: ")
    assert "\n" not in str(info.value)


def test_not_utf8_is_scene_error(tmp_path):
    p = tmp_path / "latin1.toml"
    p.write_bytes(SIM.encode() + b'[[body]]\nname = "caf\xe9"\n')
    with pytest.raises(SceneError) as info:
        load_scene(p)
    assert str(info.value).startswith(f"{p}: ")
    assert "\n" not in str(info.value)


def test_load_scene_reads_file(tmp_path):
    p = tmp_path / "ok.toml"
    p.write_text(SIM + BOX, encoding="utf-8")
    s = load_scene(p)
    assert s.path == str(p)
    assert s.toml_text == SIM + BOX
    assert s.model.n_bodies == 1
    assert s.sim.dt == 1e-3 and s.sim.duration == 1.0 and s.sim.n_steps == 1000


# ---------------------------------------------------------------------------------------------
# valid scenes


def test_grid_generator_count_and_positions():
    text = SIM + """
[[generator]]
layout = "grid"
grid = [3, 4, 2]
spacing = [0.5, 1.0, 2.0]
origin = [-1.0, 2.0, 3.0]
name_prefix = "cube"
[generator.body]
shape = "box"
half_extents = [0.1, 0.1, 0.1]
mass = 1.0
"""
    s = parse_scene(text)
    assert s.model.n_bodies == 3 * 4 * 2
    expected = {(-1.0 + 0.5 * i, 2.0 + 1.0 * j, 3.0 + 2.0 * k)
                for i in range(3) for j in range(4) for k in range(2)}
    got = {tuple(np.round(p, 12)) for p in s.state.position}
    assert got == expected
    assert len(set(s.model.body_name)) == 24
    assert all(n.startswith("cube") for n in s.model.body_name)


def test_resolved_scene_keeps_generators_unexpanded():
    # the resolved scene (logged as JSON with every run) lists the [[body]] tables and each
    # generator once, whatever its count: its text does not grow with the number of bodies
    def resolved(nx):
        text = SIM + BOX + f"""
[[generator]]
layout = "grid"
grid = [{nx}, 2, 1]
spacing = [0.5, 1.0, 2.0]
origin = [-1.0, 2.0, 3.0]
[generator.body]
shape = "box"
half_extents = [0.1, 0.1, 0.1]
mass = 1.0
"""
        return parse_scene(text).resolved

    small, big = resolved(2), resolved(500)
    assert len(small["body"]) == len(big["body"]) == 1  # the one [[body]]
    (g,) = big["generator"]
    assert g["n_bodies"] == 1000 and g["grid"] == [500, 2, 1] and g["body"]["mass"] == 1.0
    # corners of the grid by hand: origin and origin + (counts - 1) * spacing
    np.testing.assert_allclose(g["position_bounds"], [[-1.0, 2.0, 3.0], [-1.0 + 499 * 0.5, 3.0, 3.0]])
    # only the digits of the counts and bounds differ
    assert len(json.dumps(big)) - len(json.dumps(small)) < 20


def test_generators_and_bodies_add_up():
    text = SIM + BOX + GRID.format(extra="", body="") + RANDOM.format(extra='name_prefix = "r"')
    s = parse_scene(text)
    assert s.model.n_bodies == 1 + 4 + 5


def _random_scene(seed_line: str, sim_seed: int | None = None):
    head = SIM if sim_seed is None else sim(seed=str(sim_seed))
    extra = seed_line + "\nspeed = [1.0, 2.0]\nspin = [3.0, 4.0]\nrandom_orientation = true"
    return parse_scene(head + RANDOM.format(extra=extra).replace("count = 5", "count = 50"))


def test_random_generator_reproducible():
    a, b = _random_scene("seed = 11"), _random_scene("seed = 11")
    for f in ("position", "linear_momentum", "quat_wxyz", "angular_momentum_world"):
        np.testing.assert_array_equal(getattr(a.state, f), getattr(b.state, f))
    c = _random_scene("seed = 12")
    assert not np.allclose(a.state.position, c.state.position)
    # without a generator seed, [sim] seed decides
    d, e, f = _random_scene("", 5), _random_scene("", 5), _random_scene("", 6)
    np.testing.assert_array_equal(d.state.position, e.state.position)
    assert not np.allclose(d.state.position, f.state.position)


def test_random_generator_ranges():
    s = _random_scene("seed = 3")
    p = s.state.position
    assert p.shape == (50, 3)
    assert np.all(p >= 0.0) and np.all(p <= 1.0)
    speed = np.linalg.norm(s.state.linear_momentum / s.model.body_mass[:, None], axis=1)
    assert np.all(speed >= 1.0 - 1e-12) and np.all(speed <= 2.0 + 1e-12)
    # spheres: L = I w with I = 2/5 m r^2
    spin = np.linalg.norm(s.state.angular_momentum_world, axis=1) / (0.4 * 1.0 * 0.1**2)
    assert np.all(spin >= 3.0 - 1e-9) and np.all(spin <= 4.0 + 1e-9)
    np.testing.assert_allclose(np.linalg.norm(s.state.quat_wxyz, axis=1), 1.0, atol=1e-15)
    # random orientations really are different
    assert len({tuple(np.round(q, 6)) for q in s.state.quat_wxyz}) == 50


def test_generator_spin_adds_to_template_body_spin():
    # the template's own spin (body frame) plus a random spin of magnitude in [min, max]: for a
    # unit isotropic inertia L = w = R w_body + w_random, so |L - R w_body| = 1 exactly
    text = SIM + """
[[generator]]
layout = "grid"
grid = [4, 1, 1]
spin = [1.0, 1.0]
random_orientation = true
[generator.body]
shape = "sphere"
radius = 0.1
mass = 1.0
inertia_diag = [1.0, 1.0, 1.0]
angular_velocity_body = [0.0, 0.0, 5.0]
"""
    s = parse_scene(text)
    template = np.einsum("nij,j->ni", s.state.rotation, [0.0, 0.0, 5.0])
    extra = np.linalg.norm(s.state.angular_momentum_world - template, axis=1)
    np.testing.assert_allclose(extra, 1.0, rtol=1e-12)


# one rotation, five spellings: 50 degrees about (1, -2, 2)/3
AXIS = np.array([1.0, -2.0, 2.0]) / 3.0
ANGLE = math.radians(50.0)
REF_ROT = Rotation.from_rotvec(ANGLE * AXIS)
_qx, _qy, _qz, _qw = (float(v) for v in REF_ROT.as_quat())


def toml_list(*xs) -> str:
    return "[" + ", ".join(repr(float(x)) for x in xs) + "]"


ORIENTATIONS = {
    "quat_wxyz": f"quat_wxyz = {toml_list(_qw, _qx, _qy, _qz)}",
    "quat_wxyz_scaled": f"quat_wxyz = {toml_list(3 * _qw, 3 * _qx, 3 * _qy, 3 * _qz)}",
    "quat_wxyz_negated": f"quat_wxyz = {toml_list(-_qw, -_qx, -_qy, -_qz)}",
    "quat_xyzw": f"quat_xyzw = {toml_list(_qx, _qy, _qz, _qw)}",
    "axis_angle_deg": "axis_angle = { axis = [1.0, -2.0, 2.0], angle_deg = 50.0 }",
    "axis_angle_rad": f"axis_angle = {{ axis = [0.5, -1.0, 1.0], angle_rad = {ANGLE!r} }}",
    "rotvec": f"rotvec = {toml_list(*(ANGLE * AXIS))}",
}


@pytest.mark.parametrize("spelling", sorted(ORIENTATIONS))
def test_orientation_spellings_agree(spelling):
    s = parse_scene(SIM + BOX + ORIENTATIONS[spelling] + "\n")
    np.testing.assert_allclose(s.state.rotation[0], REF_ROT.as_matrix(), rtol=0, atol=1e-14)
    q = s.state.quat_wxyz[0]
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
    r_q = Rotation.from_quat(q, scalar_first=True).as_matrix()
    np.testing.assert_allclose(r_q, REF_ROT.as_matrix(), rtol=0, atol=1e-14)


def test_default_orientation_identity():
    s = parse_scene(SIM + BOX)
    np.testing.assert_array_equal(s.state.rotation[0], np.eye(3))


def test_default_inertia_box_and_density():
    a, b, c, rho = 0.3, 0.2, 0.1, 750.0
    s = parse_scene(SIM + body(mass=None, density=str(rho)))
    m = rho * 8 * a * b * c  # volume of a 2a x 2b x 2c box
    assert s.model.body_mass[0] == pytest.approx(m, rel=1e-14)
    np.testing.assert_allclose(s.model.body_inertia_diag[0],
                               m / 3 * np.array([b**2 + c**2, a**2 + c**2, a**2 + b**2]),
                               rtol=1e-14)


def test_default_inertia_sphere_and_density():
    r, rho = 0.25, 1200.0
    s = parse_scene(SIM + body(shape='"sphere"', half_extents=None, radius=str(r), mass=None,
                               density=str(rho)))
    m = rho * 4.0 / 3.0 * math.pi * r**3
    assert s.model.body_mass[0] == pytest.approx(m, rel=1e-14)
    np.testing.assert_allclose(s.model.body_inertia_diag[0], np.full(3, 0.4 * m * r**2), rtol=1e-14)


def test_inertia_diag_given_overrides_shape():
    s = parse_scene(SIM + body(inertia_diag="[1.0, 2.0, 3.0]"))
    np.testing.assert_array_equal(s.model.body_inertia_diag[0], [1.0, 2.0, 3.0])


def test_initial_momenta_from_velocities():
    # L = R I_body R^T w_world = R I_body w_body (world frame); P = m v
    rot = REF_ROT.as_matrix()
    inertia = np.array([1.0, 2.0, 3.0])
    w_body = np.array([0.3, -1.0, 2.0])
    base = SIM + body(inertia_diag="[1.0, 2.0, 3.0]", velocity="[1.0, -2.0, 0.5]")
    base += ORIENTATIONS["rotvec"] + "\n"
    s_body = parse_scene(base + "angular_velocity_body = [0.3, -1.0, 2.0]\n")
    np.testing.assert_allclose(s_body.state.angular_momentum_world[0], rot @ (inertia * w_body),
                               rtol=0, atol=1e-14)
    np.testing.assert_allclose(s_body.state.linear_momentum[0], 2.0 * np.array([1.0, -2.0, 0.5]),
                               rtol=0, atol=1e-15)
    w_world = rot @ w_body
    s_world = parse_scene(base + f"angular_velocity = {toml_list(*w_world)}\n")
    np.testing.assert_allclose(s_world.state.angular_momentum_world[0],
                               s_body.state.angular_momentum_world[0], rtol=0, atol=1e-14)


def test_gravity_default_and_forces():
    s = parse_scene("[sim]\ndt = 0.01\nduration = 1.0\n" + body(force="[1.0, 2.0, 3.0]",
                                                                 torque="[0.0, 0.5, 0.0]"))
    np.testing.assert_array_equal(s.model.gravity, [0.0, 0.0, -9.81])
    np.testing.assert_array_equal(s.model.body_force_world[0], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(s.model.body_torque_world[0], [0.0, 0.5, 0.0])
