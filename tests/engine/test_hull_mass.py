"""Convex hull bodies: mass properties by the divergence theorem against the box closed form
and trimesh's own integration, the body frame (centre of mass, principal axes) and the pose the
scene gives, and the scene keys' one-line errors."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from rblog.engine import mass_properties as mp
from rblog.engine.hull import build_hull
from rblog.engine.scene import load_scene, parse_scene
from rblog.errors import SceneError

trimesh = pytest.importorskip("trimesh")
pytest.importorskip("scipy")


def _fail(e):
    raise SceneError("<test>", "vertices", e)


def _corners(e):
    return np.array([[sx * e[0], sy * e[1], sz * e[2]] for sx in (-1, 1) for sy in (-1, 1)
                     for sz in (-1, 1)])


@pytest.mark.parametrize("e", [(0.1, 0.2, 0.3), (1.0, 1.0, 1.0), (0.013, 2.5, 0.4)])
def test_box_corners_give_the_box_closed_form(e):
    # a box's 8 corners, shifted off the origin: V = 8 abc, c = the shift, I = m/3 (b^2 + c^2,..)
    shift = np.array([0.3, -1.2, 0.7])
    h = build_hull(_corners(e) + shift, _fail)
    v_ref = 8.0 * e[0] * e[1] * e[2]
    m = 2.7
    i_ref = mp.box_inertia(m, e)
    # measured over the three boxes: volume 1.1e-15 relative, moments 8.9e-16 relative, centre
    # 2.2e-16 m
    assert abs(h.volume - v_ref) <= 1e-12 * v_ref
    np.testing.assert_allclose(h.inertia_diag(m), i_ref, rtol=1e-12, atol=0)
    np.testing.assert_allclose(h.com, shift, rtol=0, atol=1e-12 * np.linalg.norm(shift))
    # the box's axes are principal: kept as they are
    np.testing.assert_array_equal(h.axes, np.eye(3))
    assert len(h.faces) == 6 and all(len(f) == 4 for f in h.faces)


def _random_points(rng, n):
    return rng.normal(size=(n, 3)) * rng.uniform(0.05, 0.5, 3) + rng.normal(size=3)


@pytest.mark.parametrize("seed", range(6))
def test_random_hull_matches_trimesh_mass_properties(seed):
    rng = np.random.default_rng(seed)
    p = _random_points(rng, 8 + 5 * seed)
    h = build_hull(p, _fail)
    ref = trimesh.convex.convex_hull(p)
    ref.density = 1.0
    v_ref = ref.volume
    c_ref = ref.center_mass
    j_ref = ref.moment_inertia  # about the centre of mass, in the points' frame
    # measured over the six seeds: volume <= 8.7e-16 relative, centre <= 8.9e-16 m, tensor <=
    # 8.9e-14 relative to its largest moment (trimesh integrates in float64 its own way)
    assert abs(h.volume - v_ref) <= 1e-12 * v_ref
    np.testing.assert_allclose(h.com, c_ref, rtol=0, atol=1e-12 * np.abs(p).max())
    q = h.axes
    j = q @ np.diag(h.inertia_per_density) @ q.T
    assert np.abs(j - j_ref).max() <= 1e-12 * np.abs(j_ref).max()
    # the body frame: a rotation, and the vertices centred on the centre of mass in it
    np.testing.assert_allclose(q.T @ q, np.eye(3), atol=1e-14)
    assert np.linalg.det(q) > 0
    bh = trimesh.Trimesh(h.vertices, h.triangles)
    np.testing.assert_allclose(bh.center_mass, 0.0, atol=1e-12 * np.abs(p).max())


def test_scene_pose_is_the_centre_of_mass_in_principal_axes():
    rng = np.random.default_rng(3)
    p = _random_points(rng, 14)
    toml = textwrap.dedent(f"""
        [sim]
        dt = 0.001
        duration = 0.01
        [[body]]
        shape = "hull"
        vertices = {p.tolist()}
        density = 1000
        position = [1.0, 2.0, 3.0]
        axis_angle = {{axis = [0, 1, 1], angle_deg = 40}}
        """)
    sc = parse_scene(toml)
    h = build_hull(p, _fail)
    from scipy.spatial.transform import Rotation

    r_scene = Rotation.from_rotvec(np.radians(40) * np.array([0, 1, 1]) / np.sqrt(2)).as_matrix()
    x = sc.state.position[0]
    r = sc.state.rotation[0]
    # each vertex where the scene put it: x + R v_body = position + R_scene v_scene
    world = x + sc.model.mesh_vert @ r.T
    ref = np.array([1.0, 2.0, 3.0]) + p[np.sort(_hull_indices(p))] @ r_scene.T
    # measured 4.4e-16 m
    np.testing.assert_allclose(world, ref, rtol=0, atol=1e-14)
    np.testing.assert_allclose(sc.model.body_inertia_diag[0],
                               h.inertia_per_density * 1000.0, rtol=1e-14)
    np.testing.assert_allclose(sc.model.body_mass[0], 1000.0 * h.volume, rtol=1e-15)


def _hull_indices(p):
    from scipy.spatial import ConvexHull

    return ConvexHull(p).vertices


def test_mesh_file_is_read_relative_to_the_scene(tmp_path):
    # extents exact in float32 (STL's): the file holds the box exactly
    box = trimesh.creation.box(extents=(0.25, 0.5, 0.75))
    (tmp_path / "meshes").mkdir()
    box.export(tmp_path / "meshes" / "b.stl")
    scene = tmp_path / "s.toml"
    scene.write_text(textwrap.dedent("""
        [sim]
        dt = 0.001
        duration = 0.01
        [[body]]
        shape = "hull"
        mesh = "meshes/b.stl"
        mass = 2.0
        """))
    from rblog.engine.scene import load_scene

    sc = load_scene(scene)
    np.testing.assert_allclose(sc.model.body_inertia_diag[0],
                               mp.box_inertia(2.0, (0.125, 0.25, 0.375)), rtol=1e-12)


BAD = [
    ('vertices = [[0,0,0],[1,0,0],[0,1,0]]', "body[0].vertices: 3 points, expected at least 4"),
    ('vertices = [[0,0,0],[1,0,0],[0,1,0],[1,1,0]]', "body[0].vertices: the 4 points lie in one"),
    ('vertices = [[0,0,0],[1,0,"a"],[0,1,0],[0,0,1]]',
     "body[0].vertices[1][2]: expected a number, got a string"),
    ('vertices = [[0,0,0],[1,0],[0,1,0],[0,0,1]]',
     "body[0].vertices[1]: expected a list of 3 numbers"),
    ('vertices = 3', "body[0].vertices: expected a list of [x, y, z] points"),
    ('mesh = "nope.obj"', "body[0].mesh: no such file"),
    ('', "body[0].vertices: expected exactly one of vertices"),
    ('vertices = [[0,0,0],[1,0,0],[0,1,0],[0,0,1]]\nmesh = "a.obj"',
     "body[0].vertices: expected exactly one of vertices"),
    ('vertices = [[0,0,0],[1,0,0],[0,1,0],[0,0,1]]\nradius = 1.0',
     "body[0].radius: a hull takes vertices or mesh, not radius"),
]


@pytest.mark.parametrize("line,msg", BAD)
def test_bad_hull_keys_are_one_line_errors(line, msg, tmp_path):
    toml = f'[sim]\ndt = 0.001\nduration = 0.01\n[[body]]\nshape = "hull"\ndensity = 1.0\n{line}\n'
    with pytest.raises(SceneError) as e:
        parse_scene(toml, str(tmp_path / "s.toml"))
    assert msg in str(e.value), str(e.value)
    assert "\n" not in str(e.value)


def test_validate_prints_the_hull_error(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text('[sim]\ndt = 0.001\nduration = 0.01\n[[body]]\nshape = "hull"\nmass = 1.0\n'
                 'vertices = [[0,0,0],[1,0,0],[0,1,0],[1,1,0]]\n')
    from click.testing import CliRunner
    from rblog_cli.main import main

    r = CliRunner().invoke(main, ["validate", str(f)])
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"rblog: error: {f}: body[0].vertices: the 4 points lie in one "
                               "plane"), lines


def _without(monkeypatch, package):
    import builtins

    real = builtins.__import__

    def blocked(name, *a, **k):
        if name.startswith(package):
            raise ImportError(name)
        return real(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", blocked)


def test_missing_meshes_extra_is_one_line(monkeypatch, tmp_path):
    (tmp_path / "b.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n")
    scene = tmp_path / "s.toml"
    scene.write_text('[sim]\ndt = 0.001\nduration = 0.01\n[[body]]\nshape = "hull"\nmass = 1.0\n'
                     'mesh = "b.obj"\n')
    _without(monkeypatch, "trimesh")
    with pytest.raises(SceneError, match=r"install rblog\[meshes\]"):
        load_scene(scene)


def test_missing_scipy_is_one_line(monkeypatch):
    _without(monkeypatch, "scipy")
    with pytest.raises(SceneError, match=r"scipy \(qhull\), a dependency of rblog"):
        parse_scene('[sim]\ndt = 0.001\nduration = 0.01\n[[body]]\nshape = "hull"\nmass = 1.0\n'
                    'vertices = [[0,0,0],[1,0,0],[0,1,0],[0,0,1]]\n')


def test_a_generator_of_hulls_places_their_centres_of_mass():
    # a tetrahedron off its centre (c = (0.25, 0.25, 0.25) of the unit corner one, scaled 0.1)
    toml = textwrap.dedent("""
        [sim]
        dt = 0.001
        duration = 0.01
        [[generator]]
        layout = "grid"
        grid = [3, 1, 1]
        spacing = 0.5
        random_orientation = true
        [generator.body]
        shape = "hull"
        vertices = [[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1]]
        density = 1000
        """)
    sc = parse_scene(toml)
    m = sc.model
    np.testing.assert_array_equal(sc.state.position, [[0, 0, 0], [0.5, 0, 0], [1.0, 0, 0]])
    assert m.geom_vert_num[:3].tolist() == [4, 4, 4]
    assert m.geom_vert_adr[:3].tolist() == [0, 4, 8]
    for g in range(3):  # each body's vertices centred on its centre of mass
        np.testing.assert_allclose(m.geom_vertices(g).mean(axis=0), 0.0, atol=1e-16)
    np.testing.assert_allclose(m.body_mass, 1000 * 0.1 ** 3 / 6, rtol=1e-14)
