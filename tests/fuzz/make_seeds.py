"""Write the fuzz targets' seed corpus (tests/fuzz/corpus/): small real logs and scenes.

    python tests/fuzz/make_seeds.py

* ``seeds/ball.mcap``, ``seeds/ball.rrd``: 0.03 s of a ball resting on the ground and a box
  beside it (contact rows in every logged sample, every 5 steps), the .rrd cut down to its
  recording's rblog entities and one view chunk (12 kB instead of 250: the blueprint and view
  entities are the viewer's, which rblog's reader skips);
* ``mcap/``, ``rrd/``: those, plus tests/data/two_bytes_changed.rrd (the issue's abort);
* ``scene/``: every sample scene;
* ``mujoco/``: three MJCF models (a box and a sphere on a plane, a hinge, a capsule);
* ``mcap_fields/``, ``rrd_payload/``, ``writer/``: a few byte strings (these targets build
  their inputs from the seed logs or from argument pools; see targets.py).
"""

from __future__ import annotations

import shutil
import struct
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
CORPUS = HERE / "corpus"

SCENE = """
[sim]
dt = 1e-3
duration = 0.03
log_every = 5

[ground]

[[body]]
name = "ball"
shape = "sphere"
radius = 0.1
mass = 1.0
position = [0.0, 0.0, 0.1]

[[body]]
name = "cube"
shape = "box"
half_extents = [0.1, 0.1, 0.1]
mass = 2.0
position = [0.5, 0.0, 0.1]
angular_velocity = [0.0, 0.0, 1.0]
"""

MJCF = [
    '<mujoco><option timestep="0.002"/><worldbody><geom type="plane" size="5 5 0.1"/>'
    '<body pos="0 0 0.2"><freejoint/><geom type="box" size="0.1 0.1 0.1" mass="1"/></body>'
    '<body pos="0.5 0 0.3"><freejoint/><geom type="sphere" size="0.1" mass="2"/></body>'
    '</worldbody></mujoco>',
    '<mujoco><worldbody><body pos="0 0 1"><joint type="hinge" axis="0 1 0"/>'
    '<geom type="capsule" size="0.05 0.2" mass="1"/></body></worldbody></mujoco>',
    '<mujoco><worldbody><geom type="plane" size="1 1 0.1"/><body pos="0 0 0.5"><freejoint/>'
    '<geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.05"/></body></worldbody></mujoco>',
]


def _strip_rrd(src: Path, dst: Path) -> None:
    """Keep the store records, the recording's rblog/* chunks and its first world/ chunk."""
    from rblog.record import safe_rrd

    data = src.read_bytes()
    msgs, _ = safe_rrd.messages(src)
    out, view = bytearray(data[:safe_rrd.HEADER_BYTES]), False
    for off, kind, payload in msgs:
        keep = kind != safe_rrd.KIND_ARROW
        if kind == safe_rrd.KIND_ARROW:
            store, _, batch = safe_rrd.decode_arrow_msg(payload)
            ent = (batch.schema.metadata or {}).get(b"rerun:entity_path", b"").decode().lstrip("/")
            keep = store == safe_rrd.STORE_RECORDING and (
                ent.startswith("rblog/") or (ent.startswith("world/") and not view))
            view = view or (keep and ent.startswith("world/"))
        if kind == safe_rrd.KIND_END:
            payload = b""
        if keep:
            out += struct.pack("<QQ", kind, len(payload)) + bytes(payload)
    dst.write_bytes(bytes(out))


def main() -> None:
    import rblog
    from rblog.engine.scene import parse_scene
    from rblog.record import McapRecorder, RerunRecorder

    seeds = CORPUS / "seeds"
    for d in ("seeds", "mcap", "rrd", "scene", "mujoco", "mcap_fields", "rrd_payload", "writer"):
        (CORPUS / d).mkdir(parents=True, exist_ok=True)
    full = seeds / "full.rrd"
    rblog.run(parse_scene(SCENE, "seed.toml"),
              recorders=[McapRecorder(str(seeds / "ball.mcap")), RerunRecorder(str(full))])
    _strip_rrd(full, seeds / "ball.rrd")
    full.unlink()
    assert len(rblog.load(seeds / "ball.rrd").contacts) > 0
    shutil.copy(seeds / "ball.mcap", CORPUS / "mcap" / "ball.mcap")
    shutil.copy(seeds / "ball.rrd", CORPUS / "rrd" / "ball.rrd")
    shutil.copy(REPO / "tests" / "data" / "two_bytes_changed.rrd", CORPUS / "rrd")
    for p in sorted((REPO / "samples").glob("*.toml")):
        shutil.copy(p, CORPUS / "scene" / p.name)
    (CORPUS / "scene" / "seed.toml").write_text(SCENE)
    for i, xml in enumerate(MJCF):
        (CORPUS / "mujoco" / f"model{i}.xml").write_text(xml)
    for target in ("mcap_fields", "rrd_payload", "writer"):
        for i, b in enumerate((bytes(16), bytes(range(64)), b"\xff" * 40, bytes(range(255, 0, -3)))):
            (CORPUS / target / f"bytes{i}").write_bytes(b)


if __name__ == "__main__":
    main()
