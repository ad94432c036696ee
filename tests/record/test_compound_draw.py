"""A compound body in the logs: its parts are geoms of the one body (the v3 contract), the MCAP
writer draws each as Foxglove primitives of the body's SceneEntity at the part's pose in the body
frame, the Rerun writer sends each part's type entity, and both read back with the parts."""

from __future__ import annotations

import numpy as np

from rblog.contract.model import GEOM_CAPSULE, GEOM_SPHERE
from rblog.engine.scene import parse_scene
from rblog.record.reader import load

SCENE = """
[sim]
dt = 1e-3
duration = 0.02
[ground]
[[body]]
name = "dumbbell"
shape = "compound"
density = 1000.0
position = [0.0, 0.0, 0.5]
parts = [
  {shape = "sphere", radius = 0.05, position = [0, 0, -0.15]},
  {shape = "sphere", radius = 0.05, position = [0, 0, 0.15]},
  {shape = "capsule", radius = 0.02, half_length = 0.1},
]
"""


def test_every_part_is_drawn_and_read_back(tmp_path):
    import rblog
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
    from mcap.reader import make_reader

    from rblog.record import McapRecorder, RerunRecorder

    s = parse_scene(SCENE, "d.toml")
    mcap, rrd = tmp_path / "d.mcap", tmp_path / "d.rrd"
    rblog.run(s, recorders=[McapRecorder(str(mcap)), RerunRecorder(str(rrd))])
    for path in (mcap, rrd):
        got = load(path)
        m = got.model
        rows = np.flatnonzero(np.asarray(m.geom_body) == 0)
        assert np.asarray(m.geom_type)[rows].tolist() == [GEOM_SPHERE, GEOM_SPHERE, GEOM_CAPSULE]
        np.testing.assert_array_equal(np.asarray(m.geom_pos_body)[rows],
                                      [[0, 0, -0.15], [0, 0, 0.15], [0, 0, 0]])
    with open(mcap, "rb") as f:
        upd = next(SceneUpdate.FromString(msg.data) for _, ch, msg in make_reader(f).iter_messages()
                   if ch.topic == "/scene")
    ent = next(e for e in upd.entities if e.id == "body/dumbbell")
    # two balls (spheres at z = -+0.15) and the capsule (a cylinder and its two end spheres at
    # z = -+0.1), each posed in the body frame
    zs = sorted(round(p.pose.position.z, 12) for p in ent.spheres)
    assert zs == [-0.15, -0.1, 0.1, 0.15]
    assert [round(p.size.x, 12) for p in sorted(ent.spheres, key=lambda p: p.pose.position.z)] \
        == [0.1, 0.04, 0.04, 0.1]
    assert len(ent.cylinders) == 1 and ent.cylinders[0].size.z == 0.2
    from rblog.record.rerun_writer import CAPSULES_ENTITY, SPHERES_ENTITY

    blob = rrd.read_bytes()
    assert CAPSULES_ENTITY.encode() in blob and SPHERES_ENTITY.encode() in blob
