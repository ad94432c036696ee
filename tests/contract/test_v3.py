"""Log contract v3: bodies on joints, geoms of every shape, per-interval impulses.

A v3 run round-trips bit-identically through both formats (every model field, every channel,
NaN where a body does not supply a kind); a v2 log written by the v2 code (tests/data) still
reads, its geoms derived from its v2 fields; the v2 fields are derived from geoms; every geom is
drawn as what it is in both viewers; bad tables and blocks are one-line RecordErrors."""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

import rblog
from rblog.contract.model import (BODY_FREE, BODY_JOINTED, BODY_KINEMATIC, GEOM_BOX, GEOM_CAPSULE,
                                  GEOM_CYLINDER, GEOM_ELLIPSOID, GEOM_MESH, GEOM_PLANE,
                                  GEOM_SPHERE, JOINT_BALL, JOINT_HINGE, JOINT_SLIDE, SHAPE_BOX,
                                  SHAPE_NONE, SHAPE_SPHERE, Model)
from rblog.contract.trajectory import INTERVAL_CHANNELS

DATA = Path(__file__).resolve().parents[1] / "data"
TETRA = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0], [0.0, 0.0, 0.1]])
C45 = np.cos(np.pi / 8)
S45 = np.sin(np.pi / 8)


def _model() -> Model:
    # 6 bodies: a free base with two geoms, an arm on a hinge, a hand on a slide and a ball
    # joint, a free mesh rock, a free ball, a kinematic box; the world has a floor, a wall
    # (normal +x through x = -2), a static box and a static capsule
    geoms = dict(
        body=[0, 0, 1, 2, 3, 4, 5, -1, -1, -1, -1],
        type=["box", "capsule", "cylinder", "ellipsoid", "mesh", "sphere", "box", "plane",
              "plane", "box", "capsule"],
        size=[[0.2, 0.1, 0.05], [0.03, 0.1, 0], [0.02, 0.15, 0], [0.05, 0.04, 0.03], [0, 0, 0],
              [0.1, 0, 0], [0.1, 0.1, 0.1], [0, 0, 0], [3, 1, 0], [0.5, 0.5, 0.5], [0.1, 0.3, 0]],
        pos_body=[[0, 0, 0], [0, 0, 0.1], [0, 0, 0], [0.01, 0, 0], [-0.025, -0.025, -0.025],
                  [0, 0, 0], [0, 0, 0], [0, 0, 0], [-2, 0, 1], [1, 0, 0.5], [0, 2, 0.3]],
        quat_wxyz_body=[[1, 0, 0, 0], [C45, S45, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0],
                        [1, 0, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0], [np.sqrt(0.5), 0, np.sqrt(0.5), 0],
                        [C45, 0, 0, S45], [1, 0, 0, 0]],
        friction=[0.5, 0.5, 0.8, 0.8, 0.6, 0.4, 1.0, 0.9, 0.9, 0.7, 0.7],
        restitution=[np.nan] * 11,
        collide_group=[1, 1, 2, 2, 1, 1, 0, 1, 1, 1, 1],
        collide_mask=[-1, -1, 1, 1, -1, -1, 0, -1, -1, -1, -1],
        name=["base_box", "base_capsule", "arm", "hand", "rock", "ball", "mocap", "floor",
              "wall", "crate", "post"],
        mesh_vert=[None, None, None, None, TETRA, None, None, None, None, None, None])
    joints = dict(body=[1, 2, 2], type=["hinge", "slide", "ball"],
                  anchor_body=[[0, 0, 0.15], [0, 0, 0.05], [0, 0, 0.05]],
                  anchor_parent=[[0.2, 0, 0], [0, 0, -0.15], [0, 0, -0.15]],
                  axis_body=[[0, 1, 0], [0, 0, 1], [0, 0, 0]],
                  axis_parent=[[0, 1, 0], [0, 0, 1], [0, 0, 0]],
                  range=[[-1.5, 1.5], [-0.05, 0.05], [0, np.nan]],
                  quat_parent=[[1, 0, 0, 0], [np.nan] * 4, [C45, 0, S45, 0]],
                  name=["shoulder", "wrist_slide", "wrist"])
    supplied = np.zeros((6, 6), np.int64)   # SUPPLIED_*: 0 missing, 1 logged, 2 none
    supplied[:, 0] = 1               # contact: every body
    supplied[:, 5] = 2               # integration: none (the balance closes without it)
    supplied[[1, 2], 4] = 1          # joint: the bodies on joints
    supplied[[0, 3, 4], 4] = 2       # ... the free bodies have none
    work = np.zeros((6, 4), np.int64)
    work[:, 3] = 2                   # joint work: none (ideal joints)
    work[[1, 2], 2] = 1              # actuator work on the arm and the hand
    return rblog.body_table(
        name=["base", "arm", "hand", "rock", "ball", "mocap"], mass=[3.0, 1.0, 0.5, 0.7, 1.0, 2.0],
        inertia_diag=[[0.1, 0.2, 0.3], [0.01, 0.01, 0.002], [0.001, 0.002, 0.003],
                      [0.001, 0.001, 0.001], [0.004, 0.004, 0.004], [0.01, 0.01, 0.01]],
        kind=["free", "joints", "joints", "free", "free", "kinematic"],
        parent=[-1, 0, 1, -1, -1, -1], geoms=geoms, joints=joints, collide_rule="or",
        collide_parent=True,
        impulses=supplied, work=work)


def _arrays(model: Model, T: int = 7, seed: int = 3) -> dict:
    rng = np.random.default_rng(seed)
    n = model.n_bodies
    q = rng.normal(size=(T, n, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    out = dict(t=np.arange(T) * 0.02, step=np.arange(T, dtype=np.int64) * 10,
               position=rng.normal(size=(T, n, 3)), quat_wxyz=q,
               velocity=rng.normal(size=(T, n, 3)), angular_velocity=rng.normal(size=(T, n, 3)))
    for name in ("impulse_contact_linear", "impulse_contact_angular", "impulse_joint_linear",
                 "impulse_joint_angular"):
        out[name] = rng.normal(size=(T, n, 3)) * 10.0 ** rng.integers(-12, 3, size=(T, n, 3))
    out["work_actuator"] = rng.normal(size=(T, n))
    return out


def _same_model(a: Model, b: Model):
    for f in fields(Model):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            assert x.dtype == np.asarray(y).dtype and x.shape == y.shape, f.name
            assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), f.name
        else:
            assert x == y or (x != x and y != y), f.name  # NaN scalars: unknown both sides


def test_geom_joint_and_body_tables():
    m = _model()
    assert m.body_kind.tolist() == [BODY_FREE, BODY_JOINTED, BODY_JOINTED, BODY_FREE, BODY_FREE,
                                    BODY_KINEMATIC]
    assert m.geom_type.tolist() == [GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_ELLIPSOID,
                                    GEOM_MESH, GEOM_SPHERE, GEOM_BOX, GEOM_PLANE, GEOM_PLANE,
                                    GEOM_BOX, GEOM_CAPSULE]
    assert m.joint_type.tolist() == [JOINT_HINGE, JOINT_SLIDE, JOINT_BALL]
    assert np.isnan(m.joint_quat_parent[1]).all() and m.collide_parent
    assert np.array_equal(m.geom_vertices(4), TETRA)
    assert m.geom_vert_num.tolist() == [0, 0, 0, 0, 4, 0, 0, 0, 0, 0, 0]
    # v2 fields from the geoms: only the ball (one centred sphere) and the kinematic box (one
    # centred box) are v2 shapes; the base has two geoms, the others shapes v2 lacks
    assert m.body_shape.tolist() == [SHAPE_NONE, SHAPE_NONE, SHAPE_NONE, SHAPE_NONE, SHAPE_SPHERE,
                                     SHAPE_BOX]
    assert m.body_size[4].tolist() == [0.1, 0, 0] and m.body_size[5].tolist() == [0.1] * 3
    assert not m.body_size[:4].any()
    assert m.body_friction.tolist() == [0.5, 0.8, 0.8, 0.6, 0.4, 1.0]  # each body's first geom's
    # the ground is the floor (normal +z, against gravity), not the wall (normal +x: the geom's
    # z turned by a quarter turn about y); the world boxes are the static boxes
    assert m.ground and np.allclose(m.ground_normal, [0, 0, 1], atol=1e-15)
    assert m.ground_offset == 0.0 and m.ground_friction == 0.9
    assert np.array_equal(m.static_box_position, [[1, 0, 0.5]])
    assert np.array_equal(m.static_box_quat_wxyz, [[C45, 0, 0, S45]])
    assert m.impulse_supplied("joint").tolist() == [True, True, True, True, True, False]


@pytest.mark.parametrize("fmt", ["mcap", "rrd"])
def test_v3_round_trip_bit_identical(tmp_path, fmt):
    model = _model()
    arrays = _arrays(model)
    path = tmp_path / f"run.{fmt}"
    rec = rblog.Recorder(model, dt=0.002, log_every=10, writer="test v3", keep=True,
                         **{fmt: path})
    with rec:
        rec.write(**{k: v[:3] for k, v in arrays.items()})
        rec.write(**{k: v[3:] for k, v in arrays.items()})
    mem = rec.trajectory
    got = rblog.load(path)
    assert got.info.log_format == 3 and not got.truncated
    _same_model(mem.model, got.model)
    assert set(got.interval_channels) == {"impulse_contact_linear", "impulse_contact_angular",
                                          "impulse_joint_linear", "impulse_joint_angular",
                                          "work_actuator"}
    for name in ("step", "t", "position", "quat_wxyz", "rotation", "velocity", "angular_velocity",
                 "linear_momentum", "angular_momentum", "total_energy", *got.interval_channels):
        a, b = getattr(mem, name), getattr(got, name)
        assert a.shape == b.shape and a.tobytes() == b.tobytes(), name
    # what a body does not supply is NaN; what it supplies is the writer's value, bit for bit
    lin = got.impulse_joint_linear
    assert np.isnan(lin[:, [0, 3, 4, 5]]).all()
    # impulse(kind): the free bodies' joint impulse is none (0), the kinematic body's missing
    j_lin, j_ang = got.impulse("joint")
    assert (j_lin[:, [0, 3, 4]] == 0).all() and np.isnan(j_ang[:, 5]).all()
    assert j_lin[:, 1:3].tobytes() == lin[:, 1:3].tobytes()
    assert lin[:, [1, 2]].tobytes() == np.ascontiguousarray(
        arrays["impulse_joint_linear"][:, [1, 2]]).tobytes()
    assert got.impulse("passive") is None and got.impulse("contact")[0] is got.impulse_contact_linear
    assert np.isnan(got.work_actuator[:, 0]).all() and not np.isnan(got.work_actuator[:, 1:3]).any()


@pytest.mark.parametrize("fmt", ["mcap", "rrd"])
def test_v2_log_still_reads(fmt):
    # tests/data/v2_log.*: written by the v2 writer (tests/data/make_v2_log.py): a ball and a
    # crate (group 2) on the ground, one static box turned 0.2 rad about z
    traj = rblog.load(DATA / f"v2_log.{fmt}")
    m = traj.model
    assert traj.info.log_format == 2 and traj.n_samples == 20 and not traj.truncated
    assert m.body_kind.tolist() == [BODY_FREE] * 2 and m.body_parent.tolist() == [-1, -1]
    assert m.n_joints == 0 and traj.interval_channels == [] and not m.collide_parent
    # what a log that states nothing means: contact impulses missing, no other force (none)
    assert m.body_impulse_supplied.tolist() == [[0, 2, 2, 2, 2, 2]] * 2
    assert m.body_work_supplied.tolist() == [[2, 2, 2, 2]] * 2
    # geoms from the v2 fields: a body's shape at its centre, the ground plane, the static box
    assert m.geom_body.tolist() == [0, 1, -1, -1]
    assert m.geom_type.tolist() == [GEOM_SPHERE, GEOM_BOX, GEOM_PLANE, GEOM_BOX]
    assert m.geom_name == ["ball", "crate", "ground", "static_box_0"]
    assert np.array_equal(m.geom_size[:2], [[0.1, 0, 0], [0.2, 0.1, 0.05]])
    assert np.array_equal(m.geom_friction, [0.4, 0.6, 0.7, 0.5])
    assert np.array_equal(m.geom_restitution, [0.5, 0.3, 0.2, 0.5])
    assert np.array_equal(m.geom_pos_body[2:], [[0, 0, 0], [1, 0, 0.5]])
    assert np.array_equal(m.geom_quat_wxyz_body[2:], [[1, 0, 0, 0], [np.cos(0.1), 0, 0, np.sin(0.1)]])
    # group 0 collides with everything, group 2 with its own group and group 0 ("and" rule)
    g, k = m.geom_collide_group, m.geom_collide_mask
    assert m.collide_rule == "and" and (g[0] & k[1]) and (g[1] & k[0]) and (g[2] & k[1])
    # the samples as the generator wrote them: a free fall from 1 m at 100 Hz
    t = np.arange(20) * 0.01
    assert np.array_equal(traj.t, t) and np.array_equal(traj.position[:, 0, 2], 1 - 4.905 * t ** 2)
    assert len(traj.contacts) == 1 and traj.contacts.normal_impulse[0] == 0.196


def test_v2_fields_and_geoms_agree_both_ways():
    # a v2 model's geoms, turned back into v2 fields, give the same fields
    from rblog.contract.model import v2_from_geoms

    m = rblog.body_table(name=["a", "b"], shape=["sphere", "box"], size=[[0.1, 0, 0], [0.1, 0.2, 0.3]],
                         mass=[1.0, 1.0], ground=True, ground_normal=[0, 0.6, 0.8], ground_offset=-0.5,
                         static_box_position=[[0, 0, 1]], static_box_half_extents=[[1, 1, 1]])
    d = v2_from_geoms(2, m.geom_body, m.geom_type, m.geom_pos_body, m.geom_quat_wxyz_body,
                      m.geom_size, m.geom_friction, m.geom_restitution, m.gravity)
    assert np.array_equal(d["body_shape"], m.body_shape) and np.array_equal(d["body_size"], m.body_size)
    assert np.allclose(d["ground_normal"], [0, 0.6, 0.8], rtol=0, atol=1e-15)
    assert abs(d["ground_offset"] - (-0.5)) <= 1e-15
    assert np.array_equal(d["static_box_position"], m.static_box_position)


def test_every_geom_is_drawn_as_what_it_is(tmp_path):
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    model = _model()
    a = _arrays(model, T=2)
    path = tmp_path / "run.mcap"
    rrd = tmp_path / "run.rrd"
    with rblog.Recorder(model, dt=0.002, mcap=path, rrd=rrd) as rec:
        rec.write(**a)
    with open(path, "rb") as f:
        scene = next(m for _, ch, _, m in make_reader(f, decoder_factories=[DecoderFactory()])
                     .iter_decoded_messages() if ch.topic == "/scene")
    ents = {e.id: e for e in scene.entities}
    counts = {k: (len(e.cubes), len(e.spheres), len(e.cylinders), len(e.triangles))
              for k, e in ents.items()}
    assert counts["body/base"] == (1, 2, 1, 0)      # box; capsule = cylinder + 2 end spheres
    assert counts["body/arm"] == (0, 0, 1, 0)
    assert counts["body/hand"] == (0, 1, 0, 0)      # an ellipsoid: a sphere of 3 diameters
    assert counts["body/rock"] == (0, 0, 0, 1) and len(ents["body/rock"].triangles[0].points) == 12
    assert counts["floor"] == (1, 0, 0, 0) and counts["wall"] == (1, 0, 0, 0)
    hand = ents["body/hand"].spheres[0].size
    assert (hand.x, hand.y, hand.z) == (0.1, 0.08, 0.06)
    wall = ents["wall"].cubes[0].size
    assert (wall.x, wall.y) == (6.0, 2.0)  # its half extents (3, 1)
    import rerun as rr

    entities = {c.entity_path for c in rr.chunk.RrdReader(rrd).stream(
        store=rr.chunk.RrdReader(rrd).recordings()[0])}
    for ent in ("/world/bodies/boxes", "/world/bodies/spheres", "/world/bodies/ellipsoids",
                "/world/bodies/capsules", "/world/bodies/cylinders", "/world/bodies/meshes/rock",
                "/world/ground", "/world/planes/wall", "/world/statics/0", "/world/statics/1"):
        assert ent in entities, ent


def _raises(fn, *words):
    with pytest.raises(rblog.RecordError) as err:
        fn()
    msg = str(err.value)
    assert "\n" not in msg and all(w in msg for w in words), msg


def test_bad_tables_are_one_line_errors():
    ok = dict(name=["a"], mass=[1.0], inertia_diag=[[1, 1, 1]])
    g = dict(body=[0], type=["box"], size=[[0.1, 0.1, 0.1]])
    bt = rblog.body_table
    _raises(lambda: bt(**ok, geoms={**g, "type": ["cone"]}), "geoms.type[0]", "'cone'", "'capsule'")
    _raises(lambda: bt(**ok, geoms={**g, "size": [0.1, 0.1]}), "geoms.size", "(2,)", "(1, 3)")
    _raises(lambda: bt(**ok, geoms={**g, "body": [1]}), "geoms.body", "-1 (world)")
    _raises(lambda: bt(**ok, geoms={**g, "colour": [1]}), "unknown field 'colour'")
    _raises(lambda: bt(**ok, geoms={**g, "type": ["mesh"]}), "geoms.mesh_vert[0]", "V >= 4")
    _raises(lambda: bt(**ok, geoms={**g, "quat_wxyz_body": [[1, 1, 0, 0]]}), "quat_wxyz_body[0]",
            "unit quaternion")
    _raises(lambda: bt(**ok, geoms=g, shape=["box"]), "shape given with geoms")
    _raises(lambda: bt(**ok, geoms=g, ground=True), "world plane geom")
    _raises(lambda: bt(**ok, geoms=g, kind=["hinged"]), "kind[0]", "'joints'")
    _raises(lambda: bt(**ok, geoms=g, parent=[0]), "parent", "never the body itself")
    j = dict(body=[0], type=["hinge"], anchor_body=[[0, 0, 0]], anchor_parent=[[0, 0, 0]],
             axis_body=[[0, 0, 2]], axis_parent=[[0, 0, 1]])
    _raises(lambda: bt(**ok, geoms=g, joints=j), "joints.axis_body[0]", "unit axis")
    _raises(lambda: bt(**ok, geoms=g, joints={**j, "axis_body": [[0, 0, 1]], "quat_parent": [[2, 0, 0, 0]]}),
            "joints.quat_parent[0]", "unit quaternion")
    _raises(lambda: bt(**ok, geoms=g, impulses=("contact", "gravity")), "'gravity'", "'passive'")
    _raises(lambda: bt(**ok, geoms=g, impulses=[[1, 1, 1, 1, 3]]), "impulses", "2 (none)")
    _raises(lambda: bt(**ok, geoms=g, impulses="joint", impulses_none="joint"), "both")
    _raises(lambda: bt(**ok, geoms=g, impulses_missing=["spring"]), "impulses_missing", "'spring'")
    _raises(lambda: bt(**ok, geoms=g, collide_rule="xor"), "collide_rule", "'and'")


def test_supplied_codes_default_to_what_a_v2_log_means():
    bt = rblog.body_table
    g = dict(body=[0], type=["box"], size=[[0.1, 0.1, 0.1]])
    m = bt(name=["a"], mass=[1.0], inertia_diag=[[1, 1, 1]], geoms=g)
    assert m.body_impulse_supplied.tolist() == [[0, 2, 2, 2, 2, 2]]
    m = bt(name=["a"], mass=[1.0], inertia_diag=[[1, 1, 1]], geoms=g, impulses=("contact",),
           impulses_missing=("passive",), work=("actuator",), work_missing=("passive",))
    assert m.body_impulse_supplied.tolist() == [[1, 2, 0, 2, 2, 2]]
    assert m.body_work_supplied.tolist() == [[2, 0, 1, 2]]


def test_bad_interval_channels_are_one_line_errors():
    model = _model()
    a = _arrays(model, T=2)
    rec = rblog.Recorder(model, dt=0.002)
    with rec:
        _raises(lambda: rec.write(**{k: v for k, v in a.items() if k != "impulse_joint_angular"}),
                "impulse_joint_angular missing", "impulses 'joint'")
        _raises(lambda: rec.write(**a, impulse_passive_linear=a["impulse_contact_linear"]),
                "impulse_passive_linear given", "does not declare impulses 'passive'")
        _raises(lambda: rec.write(**{**a, "work_actuator": a["work_actuator"][:, :2]}),
                "work_actuator", "(2, 2)", "(2, 6)")
        _raises(lambda: rec.write(**a, impulse_gravity_linear=a["impulse_contact_linear"]),
                "unknown argument 'impulse_gravity_linear'")


def test_interval_channels_table():
    assert list(INTERVAL_CHANNELS)[:2] == ["impulse_contact_linear", "impulse_contact_angular"]
    assert len(INTERVAL_CHANNELS) == 16


def test_a_table_without_the_integration_kind_reads_as_integration_none():
    """A log written before the integration kind holds (N, 5) codes: read as integration none,
    what its balance meant (the engine's step error was not logged); likewise (N, 3) work codes
    before the joint work kind: joint work none (ideal joints)."""
    from rblog.contract.model import SUPPLIED_NONE, impulse_supplied_columns
    from rblog.record.reader import _Collector

    old = np.array([[1, 1, 2, 2, 1], [0, 2, 2, 2, 2]])
    assert impulse_supplied_columns(old, 2).tolist() == [[1, 1, 2, 2, 1, SUPPLIED_NONE],
                                                         [0, 2, 2, 2, 2, SUPPLIED_NONE]]
    col = _Collector(None)
    col.model = {"body_name": ["a", "b"], "body_impulse_supplied": old.reshape(-1)}
    assert col.model["body_impulse_supplied"].tolist() == [1, 1, 2, 2, 1, 2, 0, 2, 2, 2, 2, 2]
    assert "impulse_joint_linear" in col.interval()
    assert "impulse_integration_linear" not in col.interval()
    col.model = {"body_name": ["a"], "body_work_supplied": np.array([1, 2, 1])}
    assert col.model["body_work_supplied"].tolist() == [1, 2, 1, 2]


def test_state_kernel_matches_the_numpy_formulas():
    # the compiled q, v, w -> R, P, L of build_block against orientation.quat_wxyz_to_matrix and
    # numpy's products (unnormalized quaternions included)
    from rblog.contract.derive import state_from_velocities
    from rblog.contract.orientation import quat_wxyz_to_matrix

    rng = np.random.default_rng(11)
    T, n = 5, 7
    q = rng.normal(size=(T, n, 4)) * 3.0
    v, w = rng.normal(size=(T, n, 3)), rng.normal(size=(T, n, 3))
    mass, inertia = rng.uniform(0.1, 5, n), rng.uniform(0.01, 2, (n, 3))
    r, p, lw = np.empty((T, n, 3, 3)), np.empty((T, n, 3)), np.empty((T, n, 3))
    state_from_velocities(mass, inertia, q, v, w, r, p, lw)
    r_np = quat_wxyz_to_matrix(q)
    l_np = (r_np @ (inertia[None] * (np.swapaxes(r_np, -1, -2) @ w[..., None])[..., 0])[..., None])[..., 0]
    # measured: R identical, L 1.2e-16 relative; P bit-identical
    assert np.abs(r - r_np).max() <= 1e-15
    assert np.abs(lw - l_np).max() <= 4e-15 * np.abs(l_np).max()
    assert np.array_equal(p, mass[None, :, None] * v)
