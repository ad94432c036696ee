"""Write/read round trips of the log formats (docs/log-format.md), on synthetic trajectories.

The trajectories are closed forms built with rblog.contract.trajectory.derive (a box spinning about z at
a constant rate, a sphere falling freely), so these tests do not depend on the simulator.
"""

from __future__ import annotations

import dataclasses

import os
import subprocess
import sys
import textwrap
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

from rblog.errors import LogReadError, LogWriteError
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE, Model
from rblog.record import McapRecorder, RerunRecorder, load
from rblog.record import mcap_writer
from rblog.record import schema as S
from rblog.contract.trajectory import BODY_CHANNELS, TOTAL_CHANNELS, Contacts, RunInfo, Trajectory, derive

G = 9.81
CHANNELS = ("step", "t", *BODY_CHANNELS, *TOTAL_CHANNELS)


# --- synthetic runs ------------------------------------------------------------------------------

def make_model(n: int = 2) -> Model:
    """Bodies alternate box / sphere; one static box; ground plane z = 0."""
    shape = np.array([SHAPE_BOX if i % 2 == 0 else SHAPE_SPHERE for i in range(n)])
    size = np.where(shape[:, None] == SHAPE_BOX, [[0.5, 0.3, 0.2]], [[0.25, 0.0, 0.0]])
    mass = 1.0 + np.arange(n, dtype=float)
    inertia = np.column_stack([0.1 * mass, 0.2 * mass, 0.3 * mass])
    names = [("spinning box" if i % 2 == 0 else "falling/ball") + f" {i}" for i in range(n)]
    return Model(
        body_name=names, body_shape=shape, body_size=size, body_mass=mass,
        body_inertia_diag=inertia, body_force_world=np.zeros((n, 3)),
        body_torque_world=np.zeros((n, 3)), body_restitution=np.full(n, 0.5),
        body_friction=np.full(n, 0.3), body_group=np.arange(n) % 2,
        gravity=np.array([0.0, 0.0, -G]), ground=True, ground_offset=0.0,
        static_box_position=np.array([[2.0, 0.0, 0.5]]),
        static_box_quat_wxyz=np.array([[np.cos(0.2), 0.0, 0.0, np.sin(0.2)]]),
        static_box_half_extents=np.array([[0.5, 1.0, 0.5]]),
        static_box_restitution=np.array([0.2]), static_box_friction=np.array([0.7]),
    )


def make_info(dt: float, T: int, seed: int | None = 7) -> RunInfo:
    return RunInfo(
        integrator="seed", orthonormalize="none", dt=dt, log_every=1, duration_s=T * dt,
        rblog_version="0.1.0", scene_path="scenes/spin.toml",
        scene_toml='# spin\n[[body]]\nname = "spinning box"  # ünïcode\n',
        scene_resolved={"body": [{"mass": 1.0, "size": [0.5, 0.3, 0.2]}], "dt": dt},
        seed=seed, writer="tests",
    )


def make_contacts(step: np.ndarray, dt: float, n: int) -> Contacts:
    """Every third step: one or two resting/impact contacts against the ground."""
    rows = []
    for k in step.tolist():
        if k % 3:
            continue
        for j in range(1 + (k // 3) % 2):
            rows.append((k, k * dt, j % n, -1, [0.1 * k, 0.2, 0.0], [0.0, 0.0, 1.0], -1e-4 * j,
                         0.01 * k / 3.0, [1e-3, -2e-3, 0.0], (k // 3 + j) % 2))
    col = list(zip(*rows)) if rows else [[]] * 10
    return Contacts(
        step=np.array(col[0], np.int64), t=np.array(col[1], float),
        body_a=np.array(col[2], np.int64), body_b=np.array(col[3], np.int64),
        point=np.array(col[4], float).reshape(-1, 3), normal=np.array(col[5], float).reshape(-1, 3),
        separation=np.array(col[6], float), normal_impulse=np.array(col[7], float),
        friction_impulse=np.array(col[8], float).reshape(-1, 3), kind=np.array(col[9], np.int8),
    )


def make_traj(T: int = 40, n: int = 2, dt: float = 1e-3, w: float = 3.0, step0: int = 0,
              contacts: bool = True) -> Trajectory:
    """Closed-form states: body i spins about z at rate w and falls freely from z = 5."""
    model = make_model(n)
    step = step0 + np.arange(T)
    t = step * dt
    ang = w * t
    quat = np.zeros((T, n, 4))
    quat[..., 0] = np.cos(ang / 2)[:, None]
    quat[..., 3] = np.sin(ang / 2)[:, None]
    c, s = np.cos(ang)[:, None], np.sin(ang)[:, None]
    rot = np.zeros((T, n, 3, 3))
    rot[..., 0, 0], rot[..., 0, 1], rot[..., 1, 0], rot[..., 1, 1] = c, -s, s, c
    rot[..., 2, 2] = 1.0
    pos = np.zeros((T, n, 3))
    pos[..., 0] = np.arange(n)
    pos[..., 2] = 5.0 - 0.5 * G * t[:, None] ** 2
    mom = np.zeros((T, n, 3))
    mom[..., 2] = -G * t[:, None] * model.body_mass
    ang_mom = np.zeros((T, n, 3))
    ang_mom[..., 2] = model.body_inertia_diag[:, 2] * w
    cts = make_contacts(step, dt, n) if contacts else None
    return derive(model, make_info(dt, T), step, t, pos, mom, quat, rot, ang_mom, cts)


def write(recorder, traj: Trajectory, block: int = 16, close: bool = True):
    recorder.open(traj.model, traj.info)
    for k in range(0, traj.n_samples, block):
        recorder.write(traj.slice(slice(k, k + block)))
    if close:
        recorder.close()
    return recorder


def assert_same(a: Trajectory, b: Trajectory, samples: int | None = None):
    """b equals a (or its first `samples` samples) bit for bit, with the same dtypes."""
    ref = a if samples is None else a.slice(slice(0, samples))
    for name in CHANNELS:
        x, y = getattr(ref, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape, (name, x.dtype, y.dtype, x.shape, y.shape)
        assert np.array_equal(x, y), name
    if samples is None:
        for f in fields(Contacts):
            x, y = getattr(ref.contacts, f.name), getattr(b.contacts, f.name)
            assert x.dtype == y.dtype and np.array_equal(x, y), f.name
    for f in fields(Model):
        x, y = getattr(a.model, f.name), getattr(b.model, f.name)
        if isinstance(x, np.ndarray):
            assert x.dtype == np.asarray(y).dtype and np.array_equal(x, y), f.name
        else:
            assert x == y, f.name
    assert a.info == b.info


@pytest.fixture(scope="module")
def traj() -> Trajectory:
    return make_traj(T=40, n=3)


# --- round trips ---------------------------------------------------------------------------------

def test_closed_form_is_what_we_think(traj):
    # sanity of the fixture itself: rigid rotation, constant energy of spin, exact fall
    assert np.allclose(traj.angular_velocity[..., 2], 3.0)
    assert np.allclose(traj.ortho_error, 0.0, atol=1e-15)
    e_rot = 0.5 * traj.model.body_inertia_diag[:, 2] * 9.0
    assert np.allclose(traj.energy_rotational, e_rot[None])
    assert np.allclose(np.diff(traj.total_energy), 0.0, atol=1e-9)


@pytest.mark.parametrize("fmt", ["mcap", "rrd"])
def test_round_trip_bit_identical(tmp_path, traj, fmt):
    path = tmp_path / f"run.{fmt}"
    rec = McapRecorder(str(path)) if fmt == "mcap" else RerunRecorder(str(path))
    write(rec, traj, block=7)
    back = load(path)
    assert not back.truncated and back.warnings == []
    assert_same(traj, back)


def test_formats_agree(tmp_path, traj):
    write(McapRecorder(str(tmp_path / "a.mcap")), traj)
    write(RerunRecorder(str(tmp_path / "a.rrd")), traj)
    assert_same(load(tmp_path / "a.mcap"), load(tmp_path / "a.rrd"))


def test_round_trip_edge_values(tmp_path):
    """No seed, no contacts, no static boxes, one body, values that text formats lose."""
    tr = make_traj(T=5, n=1, contacts=False)
    tr.info.seed = None
    m = tr.model
    m.static_box_position, m.static_box_quat_wxyz = np.zeros((0, 3)), np.zeros((0, 4))
    m.static_box_half_extents = np.zeros((0, 3))
    m.static_box_restitution, m.static_box_friction = np.zeros(0), np.zeros(0)
    tr.position[0, 0] = [np.nextafter(1.0, 2.0), -0.0, 1e-310]
    tr.total_energy[1] = np.pi * 1e300
    for fmt, cls in (("mcap", McapRecorder), ("rrd", RerunRecorder)):
        write(cls(str(tmp_path / f"e.{fmt}")), tr, block=2)
        back = load(tmp_path / f"e.{fmt}")
        assert_same(tr, back)
        assert back.info.seed is None and len(back.contacts) == 0
        assert np.signbit(back.position[0, 0, 1])


def test_rerun_file_verifies(tmp_path, traj):
    path = tmp_path / "v.rrd"
    write(RerunRecorder(str(path)), traj)
    out = subprocess.run([sys.executable, "-m", "rerun", "rrd", "verify", str(path)],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    import rerun as rr

    reader = rr.chunk.RrdReader(path)
    assert reader.blueprints(), "default blueprint missing"
    chunks = list(reader.stream())
    entities = {c.entity_path for c in chunks}
    # the view poses are the float32 positions and xyzw quaternions of each body, as instances
    # of one entity per shape kind in body order: boxes 0 and 2, the sphere 1
    for ent, arch, members in (("/world/bodies/boxes", "Boxes3D", [0, 2]),
                               ("/world/bodies/spheres", "Ellipsoids3D", [1])):
        rows = [c.to_record_batch() for c in chunks if c.entity_path == ent and not c.is_static]
        centers = np.concatenate([np.stack(np.concatenate(b.column(f"{arch}:centers").to_pylist()))
                                  .reshape(-1, len(members), 3) for b in rows])
        quats = np.concatenate([np.stack(np.concatenate(b.column(f"{arch}:quaternions").to_pylist()))
                                .reshape(-1, len(members), 4) for b in rows])
        assert np.array_equal(centers, traj.position[:, members].astype(np.float32))
        assert np.array_equal(quats, traj.quat_xyzw[:, members].astype(np.float32))
        static = [c.to_record_batch() for c in chunks if c.entity_path == ent and c.is_static]
        half = np.stack(np.concatenate([b.column(f"{arch}:half_sizes").to_pylist() for b in static][0]))
        expect = traj.model.body_size[members]
        if arch == "Ellipsoids3D":
            expect = np.repeat(expect[:, :1], 3, axis=1)
        assert np.allclose(half, expect)
    for ent in ("/rblog/run", "/rblog/model", "/rblog/state", "/rblog/contacts", "/rblog/status",
                "/world/ground", "/world/bodies/boxes", "/world/bodies/spheres",
                "/world/contacts", "/plots/energy/total", "/plots/momentum/linear"):
        assert ent in entities, ent


def test_long_run_rrd_has_no_footer_and_still_reads(tmp_path, traj, monkeypatch):
    from rblog.record import rerun_writer

    monkeypatch.setattr(rerun_writer, "RRD_FOOTER_MAX_CHUNKS", 0)  # as if the run were long
    path = tmp_path / "long.rrd"
    rec = write(RerunRecorder(str(path)), traj)
    assert not rec.write_footer
    back = load(path)
    assert not back.truncated and back.warnings == []
    assert_same(traj, back)
    out = subprocess.run([sys.executable, "-m", "rerun", "rrd", "verify", "--check-footers",
                          "false", str(path)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr


def test_every_mcap_message_decodes_with_its_schema(tmp_path, traj):
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    path = tmp_path / "d.mcap"
    write(McapRecorder(str(path)), traj)
    counts: dict[str, int] = {}
    tf_seen = []
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None and summary.statistics.message_count > 0
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            assert schema.encoding == "protobuf" and channel.message_encoding == "protobuf"
            assert decoded is not None
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/tf":
                tf_seen.append(decoded)
            if channel.topic == "/scene":
                ids = [e.id for e in decoded.entities]
                assert "ground" in ids and "static_box_0" in ids and len(ids) == 3 + 2
            if channel.topic == "/rblog/state":
                assert message.log_time == round(decoded.t * 1e9)
    T, n = traj.n_samples, traj.n_bodies
    assert counts["/rblog/state"] == counts["/tf"] == counts["/rblog/metrics"] == T
    assert counts["/rblog/run"] == counts["/scene"] == counts["/rblog/status"] == 1
    assert counts["/rblog/contacts"] == len(np.unique(traj.contacts.step))
    # the transforms are the positions and xyzw quaternions
    k = 17
    tfs = tf_seen[k].transforms
    assert [x.child_frame_id for x in tfs] == ["spinning_box_0", "falling_ball_1", "spinning_box_2"]
    for i, x in enumerate(tfs):
        assert x.parent_frame_id == "world"
        assert [x.translation.x, x.translation.y, x.translation.z] == traj.position[k, i].tolist()
        q = traj.quat_xyzw[k, i].tolist()
        assert [x.rotation.x, x.rotation.y, x.rotation.z, x.rotation.w] == q
        assert x.timestamp.seconds * 10**9 + x.timestamp.nanos == round(traj.t[k] * 1e9)
    assert n == 3


@pytest.mark.parametrize("chunk_bytes", [2048, 1 << 20])
def test_mcap_block_records_match_mcaps_own_writer(tmp_path, traj, monkeypatch, chunk_bytes):
    """Whole blocks of Message records added to the chunk at once give the file mcap's own
    Writer gives adding the same messages one by one (its ChunkBuilder, its add_message): byte
    for byte, chunk boundaries, message indexes, statistics and summary included; with chunks
    of 2 KB a chunk closes inside blocks and inside samples."""
    monkeypatch.setattr(mcap_writer, "CHUNK_BYTES", chunk_bytes)
    monkeypatch.setattr(mcap_writer, "FLUSH_EVERY_S", 1e9)  # no flush on the wall clock
    blocks = tmp_path / "blocks.mcap"
    write(McapRecorder(str(blocks), compression="none"), traj, block=7)
    monkeypatch.setattr(mcap_writer._BlockChunkBuilder, "install", classmethod(lambda c, w: None))
    one_by_one = tmp_path / "one_by_one.mcap"
    write(McapRecorder(str(one_by_one), compression="none"), traj, block=7)
    assert blocks.read_bytes() == one_by_one.read_bytes()
    assert_same(traj, load(blocks))


@pytest.mark.parametrize("compression,chunk_bytes", [("lz4", 2048), ("lz4", 1 << 20),
                                                     ("zstd", 2048), ("none", 2048)])
def test_mcap_chunks_are_mcaps_own(tmp_path, traj, monkeypatch, compression, chunk_bytes):
    """rblog's Writer (LZ4 at LZ4_LEVEL in LZ4_BLOCK_LINKED blocks, CRCs by _crc32) gives the file
    mcap's own Writer gives (its chunk finalize and data-section write, zlib's CRC) when its
    lz4.frame.compress runs with those settings: byte for byte (chunk records, both CRCs, chunk indexes, summary); the LZ4 chunks
    are standard LZ4 frames, every CRC checks, and the run reads back bit for bit."""
    import lz4.frame
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader

    monkeypatch.setattr(mcap_writer, "CHUNK_BYTES", chunk_bytes)
    monkeypatch.setattr(mcap_writer, "FLUSH_EVERY_S", 1e9)
    assert mcap_writer.LZ4_LEVEL < 0
    ours = tmp_path / "ours.mcap"
    write(McapRecorder(str(ours), compression=compression), traj, block=7)
    own = lz4.frame.compress
    monkeypatch.setattr(lz4.frame, "compress",
                        lambda data, **kw: own(data, compression_level=mcap_writer.LZ4_LEVEL,
                                               block_linked=mcap_writer.LZ4_BLOCK_LINKED))
    for name in ("_Writer__finalize_chunk", "_Writer__flush"):
        monkeypatch.setattr(mcap_writer._Writer, name, getattr(mcap_writer.Writer, name))
    mcaps = tmp_path / "mcaps.mcap"
    write(McapRecorder(str(mcaps), compression=compression), traj, block=7)
    monkeypatch.undo()
    assert ours.read_bytes() == mcaps.read_bytes()
    chunks = [r for r in StreamReader(str(ours), emit_chunks=True, validate_crcs=True).records
              if isinstance(r, Chunk)]
    assert chunks and all(c.compression == {"none": ""}.get(compression, compression)
                          for c in chunks)
    if compression == "lz4":
        for c in chunks:
            assert len(lz4.frame.decompress(c.data)) == c.uncompressed_size
    assert sum(1 for _ in StreamReader(str(ours), validate_crcs=True).records) > len(chunks)
    assert_same(traj, load(ours))


def test_crc32_is_zlibs():
    """mcap_writer._crc32 (libdeflate's when the system has it) is zlib.crc32: random bytes of
    sizes around its vector widths, with and without a running value."""
    import zlib

    rng = np.random.default_rng(5)
    for n in (0, 1, 7, 15, 16, 63, 64, 255, 4097, 1 << 20):
        data = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
        assert mcap_writer._crc32(data) == zlib.crc32(data)
        assert mcap_writer._crc32(memoryview(data), 0xDEADBEEF) == zlib.crc32(data, 0xDEADBEEF)


def test_mcap_compressions(tmp_path, traj):
    for comp in ("none", "lz4", "zstd"):
        path = tmp_path / f"{comp}.mcap"
        write(McapRecorder(str(path), compression=comp), traj)
        assert_same(traj, load(path))


# --- third-party writers following docs/log-format.md ----------------------------------------------

def test_foreign_mcap_writer_following_the_contract(tmp_path, traj):
    """A writer that uses only the protobuf runtime and the documented field names."""
    from mcap_protobuf.writer import Writer

    Run, State, Contacts_, Status = (S.message_class(k) for k in ("Run", "State", "Contacts",
                                                                   "Status"))
    m, info = traj.model, traj.info
    path = tmp_path / "foreign.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        run = Run(rblog_log_format=1, integrator=info.integrator, orthonormalize=info.orthonormalize,
                  dt=info.dt, log_every=info.log_every, duration_s=info.duration_s,
                  rblog_version=info.rblog_version, scene_path=info.scene_path,
                  scene_toml=info.scene_toml, seed=info.seed, writer=info.writer,
                  scene_resolved_json=__import__("json").dumps(info.scene_resolved),
                  body_name=m.body_name, body_shape=m.body_shape.tolist(),
                  body_group=m.body_group.tolist(), ground=m.ground,
                  ground_offset=m.ground_offset, ground_restitution=m.ground_restitution,
                  ground_friction=m.ground_friction)
        for name in ("body_size", "body_mass", "body_inertia_diag", "body_force_world",
                     "body_torque_world", "body_restitution", "body_friction", "gravity",
                     "ground_normal", "static_box_position", "static_box_quat_wxyz",
                     "static_box_half_extents", "static_box_restitution", "static_box_friction"):
            getattr(run, name).extend(np.asarray(getattr(m, name)).reshape(-1).tolist())
        w.write_message("/rblog/run", run, log_time=0, publish_time=0)
        for k in range(traj.n_samples):
            msg = State(step=int(traj.step[k]), t=float(traj.t[k]))
            for name in (*BODY_CHANNELS, *TOTAL_CHANNELS):
                v = getattr(traj, name)[k]
                if name == "total_energy":
                    msg.total_energy = float(v)
                else:
                    getattr(msg, name).extend(np.asarray(v).reshape(-1).tolist())
            ns = round(traj.t[k] * 1e9)
            w.write_message("/rblog/state", msg, log_time=ns, publish_time=ns)
        c = traj.contacts
        for s in np.unique(c.step):
            sel = c.step == s
            msg = Contacts_(step=int(s), t=float(c.t[sel][0]), body_a=c.body_a[sel].tolist(),
                            body_b=c.body_b[sel].tolist(), kind=c.kind[sel].tolist(),
                            point=c.point[sel].reshape(-1).tolist(),
                            normal=c.normal[sel].reshape(-1).tolist(),
                            separation=c.separation[sel].tolist(),
                            normal_impulse=c.normal_impulse[sel].tolist(),
                            friction_impulse=c.friction_impulse[sel].reshape(-1).tolist())
            w.write_message("/rblog/contacts", msg, log_time=0, publish_time=0)
        w.write_message("/rblog/status", Status(complete=True), log_time=0, publish_time=0)
        w.finish()
    # a v1 writer (rblog_log_format = 1): read with rblog's combine rules, log_format 1
    assert_same(dataclasses.replace(traj, info=dataclasses.replace(traj.info, log_format=1)), load(path))


def test_foreign_rerun_writer_following_the_contract(tmp_path, traj):
    """A writer that uses rr.AnyValues and send_columns as the contract's example does."""
    import json
    import uuid

    import rerun as rr

    m, info = traj.model, traj.info
    path = tmp_path / "foreign.rrd"
    rec = rr.RecordingStream("rblog", recording_id=uuid.uuid4())
    rec.save(path)
    rec.log("rblog/run", rr.AnyValues(
        rblog_log_format=1, integrator=info.integrator, orthonormalize=info.orthonormalize,
        dt=info.dt, log_every=info.log_every, duration_s=info.duration_s,
        rblog_version=info.rblog_version, scene_path=info.scene_path, scene_toml=info.scene_toml,
        scene_resolved_json=json.dumps(info.scene_resolved), seed=info.seed, writer=info.writer),
        static=True)
    model = {f.name: getattr(m, f.name) for f in fields(Model)}
    model = {k: (np.asarray(v).reshape(-1) if isinstance(v, np.ndarray) else v)
             for k, v in model.items()}
    rec.log("rblog/model", rr.AnyValues(**model), static=True)
    T = traj.n_samples
    cols = []
    for name in ("t", *BODY_CHANNELS, *TOTAL_CHANNELS):
        v = np.asarray(getattr(traj, name), np.float64).reshape(T, -1)
        cols += rr.AnyValues.columns(**{name: v.reshape(-1)}).partition([v.shape[1]] * T)
    rec.send_columns("rblog/state", indexes=[rr.TimeColumn("step", sequence=traj.step),
                                             rr.TimeColumn("sim_time", duration=traj.t)],
                     columns=cols)
    c = traj.contacts
    for s in np.unique(c.step):
        sel = c.step == s
        rec.set_time("step", sequence=int(s))
        rec.log("rblog/contacts", rr.AnyValues(
            step=c.step[sel], t=c.t[sel], body_a=c.body_a[sel], body_b=c.body_b[sel],
            kind=c.kind[sel].astype(np.int64), point=c.point[sel].reshape(-1),
            normal=c.normal[sel].reshape(-1), separation=c.separation[sel],
            normal_impulse=c.normal_impulse[sel], friction_impulse=c.friction_impulse[sel].reshape(-1)))
    rec.log("rblog/status", rr.AnyValues(complete=True, truncated=False, reason=""), static=True)
    rec.flush()
    rec.disconnect()
    # a v1 writer (rblog_log_format = 1): read with rblog's combine rules, log_format 1
    assert_same(dataclasses.replace(traj, info=dataclasses.replace(traj.info, log_format=1)), load(path))


# --- ending early ---------------------------------------------------------------------------------

@pytest.mark.parametrize("fmt", ["mcap", "rrd"])
def test_close_truncated_keeps_reason(tmp_path, traj, fmt):
    path = tmp_path / f"x.{fmt}"
    rec = McapRecorder(str(path)) if fmt == "mcap" else RerunRecorder(str(path))
    write(rec, traj.slice(slice(0, 20)), close=False)
    rec.close(truncated=True, reason="simulation diverged at step 20")
    rec.close()  # idempotent
    rec.close(truncated=False)
    back = load(path)
    assert back.truncated and any("diverged at step 20" in w for w in back.warnings)
    assert_same(traj, back, samples=20)


@pytest.mark.parametrize("fmt", ["mcap", "rrd"])
def test_close_after_exception_in_run(tmp_path, traj, fmt):
    path = tmp_path / f"x.{fmt}"
    rec = McapRecorder(str(path)) if fmt == "mcap" else RerunRecorder(str(path))
    with pytest.raises(KeyboardInterrupt):
        with rec:
            rec.open(traj.model, traj.info)
            rec.write(traj.slice(slice(0, 10)))
            raise KeyboardInterrupt
    rec.close()
    back = load(path)
    assert back.truncated and back.n_samples == 10
    assert_same(traj, back, samples=10)


def _cut_points(size: int, first: int) -> list[int]:
    return sorted({first + (size - first) * k // 7 for k in range(7)} | {size - 1, size - 9})


def test_mcap_cut_file_reads_a_prefix(tmp_path, traj, monkeypatch):
    monkeypatch.setattr(mcap_writer, "CHUNK_BYTES", 2048)  # many chunks
    path = tmp_path / "full.mcap"
    write(McapRecorder(str(path)), traj, block=4)
    data = path.read_bytes()
    prev = 0
    n_ok = 0
    for cut in _cut_points(len(data), 200):
        p = tmp_path / f"cut{cut}.mcap"
        p.write_bytes(data[:cut])
        try:
            back = load(p)
        except LogReadError as e:
            assert str(p) in str(e) and "\n" not in str(e)
            assert prev == 0, "a longer prefix must not become unreadable"
            continue
        n_ok += 1
        # a cut inside the index/footer, after the end record, loses no data
        assert (back.truncated and back.warnings) or back.n_samples == traj.n_samples
        assert prev <= back.n_samples <= traj.n_samples
        assert_same(traj, back, samples=back.n_samples)
        prev = back.n_samples
    assert n_ok >= 5 and prev > traj.n_samples // 2


def test_rrd_cut_file_reads_a_prefix(tmp_path, traj):
    path = tmp_path / "full.rrd"
    write(RerunRecorder(str(path)), traj, block=4)
    data = path.read_bytes()
    prev = 0
    n_ok = 0
    for cut in _cut_points(len(data), 100):
        p = tmp_path / f"cut{cut}.rrd"
        p.write_bytes(data[:cut])
        try:
            back = load(p)
        except LogReadError as e:
            assert str(p) in str(e) and "\n" not in str(e)
            assert prev == 0
            continue
        n_ok += 1
        # a cut inside the index/footer, after the end record, loses no data
        assert (back.truncated and back.warnings) or back.n_samples == traj.n_samples
        assert prev <= back.n_samples <= traj.n_samples
        assert_same(traj, back, samples=back.n_samples)
        prev = back.n_samples
    assert n_ok >= 3 and prev > traj.n_samples // 2


_KILLED = """
import os, sys
sys.path.insert(0, {tests!r})
from test_record import make_traj
from rblog.record import McapRecorder, RerunRecorder
tr = make_traj(T=40, n=3)
rec = {cls}({path!r})
rec.open(tr.model, tr.info)
rec.write(tr.slice(slice(0, 24)))
rec._flush(force=True)          # what the writers do every FLUSH_EVERY_S of wall time
rec.write(tr.slice(slice(24, 40)))
os._exit(0)                     # killed: no close(), no footer, no status
"""


@pytest.mark.parametrize("fmt", ["mcap", "rrd"])
def test_killed_writer_leaves_a_readable_prefix(tmp_path, traj, fmt):
    path = tmp_path / f"killed.{fmt}"
    cls = "McapRecorder" if fmt == "mcap" else "RerunRecorder"
    code = _KILLED.format(tests=str(Path(__file__).parent), cls=cls, path=str(path))
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
    back = load(path)
    assert back.truncated and any("did not close" in w for w in back.warnings)
    assert 24 <= back.n_samples <= 40
    assert_same(traj, back, samples=back.n_samples)


# --- errors ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("cls", [McapRecorder, RerunRecorder])
def test_unwritable_path(tmp_path, traj, cls):
    afile = tmp_path / "afile"
    afile.write_text("x")
    for bad in (tmp_path / "no" / "such" / "dir" / "run.log", afile / "run.log", tmp_path):
        rec = cls(str(bad))
        with pytest.raises(LogWriteError) as err:
            rec.open(traj.model, traj.info)
        msg = str(err.value)
        assert str(bad) in msg and "\n" not in msg
        rec.close()  # harmless after a failed open


def test_rerun_needs_an_output(traj):
    with pytest.raises(LogWriteError):
        RerunRecorder(None).open(traj.model, traj.info)


def test_load_errors(tmp_path):
    cases = {
        tmp_path / "missing.mcap": None,
        tmp_path / "empty.rrd": b"",
        tmp_path / "text.mcap": b"hello, this is not a log\n",
        tmp_path / "magic_only.mcap": b"\x89MCAP0\r\n",
        tmp_path / "header_only.rrd": b"RRF2\x00)\x00\x00\x01\x02\x00",
    }
    for path, content in cases.items():
        if content is not None:
            path.write_bytes(content)
        with pytest.raises(LogReadError) as err:
            load(path)
        assert str(path) in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(LogReadError):
        load(tmp_path)


def test_two_rerun_recordings_in_one_process_do_not_mix(tmp_path):
    a, b = make_traj(T=12, n=1), make_traj(T=20, n=2, w=5.0)
    ra, rb = RerunRecorder(str(tmp_path / "a.rrd")), RerunRecorder(str(tmp_path / "b.rrd"))
    ra.open(a.model, a.info)
    rb.open(b.model, b.info)
    for k in range(0, 20, 4):
        if k < a.n_samples:
            ra.write(a.slice(slice(k, k + 4)))
        rb.write(b.slice(slice(k, k + 4)))
    ra.close()
    rb.close()
    assert_same(a, load(tmp_path / "a.rrd"))
    assert_same(b, load(tmp_path / "b.rrd"))


def test_schema_matches_the_contract_doc():
    """Every rblog message field in docs/log-format.md has the number and type the code uses."""
    doc = (Path(__file__).parents[2] / "docs" / "log-format.md").read_text()
    proto = doc[doc.index('syntax = "proto3";'):]
    import re

    for msg, fields_ in S.MESSAGES.items():
        body = re.search(r"message %s \{(.*?)\n\}" % msg, proto, re.S).group(1)
        declared = {m.group(3): (int(m.group(4)), m.group(2), m.group(1) or "")
                    for m in re.finditer(r"^\s*(repeated |optional )?(\w+) (\w+) = (\d+);",
                                         body, re.M)}
        assert declared == {name: (num, typ, (label + " ") if label else "")
                            for num, name, typ, label in fields_}, msg


def test_rerun_file_and_live_viewer(tmp_path, traj):
    """With a path and a viewer URL, the file is complete and the stream goes to the server."""
    import socket

    import rerun as rr

    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    server = rr.RecordingStream("rblog-test-server")
    url = server.serve_grpc(grpc_port=port)
    try:
        path = tmp_path / "live.rrd"
        write(RerunRecorder(str(path), connect_url=url), traj)
        assert_same(traj, load(path))
    finally:
        server.disconnect()


# --- cost ------------------------------------------------------------------------------------------

@pytest.mark.slow
@pytest.mark.parametrize("n", [1, 10, 100])
def test_write_cost(tmp_path, n, capsys):
    """Prints bytes per body-sample and CPU/wall cost per sample; run with
    ``pytest -m slow -s tests/record/test_record.py -k write_cost``."""
    import time

    T, B = 256, 8
    base = make_traj(T=T, n=n, contacts=False)
    rng = np.random.default_rng(0)  # noise: real states do not compress like closed forms
    for name in (*BODY_CHANNELS, *TOTAL_CHANNELS):
        a = getattr(base, name)
        setattr(base, name, a + rng.normal(size=a.shape) * 1e-3)
    blocks = []
    for b in range(B):
        x = base.slice(slice(0, T))
        x.step, x.t = x.step + b * T, x.t + b * T * base.info.dt
        blocks.append(x)
    lines = []
    for label, make in (("rrd", lambda p: RerunRecorder(p)),
                        ("mcap lz4", lambda p: McapRecorder(p)),
                        ("mcap zstd", lambda p: McapRecorder(p, compression="zstd")),
                        ("mcap none", lambda p: McapRecorder(p, compression="none"))):
        path = str(tmp_path / f"cost.{label.split()[0]}")
        rec = make(path)
        rec.open(base.model, base.info)
        rec.write(blocks[0])
        w0, c0 = time.perf_counter(), time.process_time()
        for x in blocks[1:]:
            rec.write(x)
        rec.close()
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        S_ = (B - 1) * T
        size = os.path.getsize(path)
        l0 = time.perf_counter()
        back = load(path)
        load_s = time.perf_counter() - l0
        assert back.n_samples == B * T
        lines.append(f"N={n:4d} {label:10s}: {size / (B * T * n):7.1f} B/body-sample  "
                     f"write {1e6 * cpu / S_:7.1f} us CPU ({1e6 * wall / S_:7.1f} wall) per sample "
                     f"= {1e6 * cpu / S_ / n:6.3f} us per body-sample; load "
                     f"{1e6 * load_s / (B * T):6.1f} us/sample")
    with capsys.disabled():
        print("\n" + "\n".join(lines))


def test_rerun_mcap_importer_sees_transforms(tmp_path, traj):
    """Rerun's own MCAP importer turns /tf into Transform3D rows, one per body per sample."""
    import rerun as rr

    path = tmp_path / "tf.mcap"
    write(McapRecorder(str(path)), traj)
    rows = 0
    for chunk in rr.chunk.McapReader(path, timeline_type="duration_ns").stream():
        if chunk.entity_path == "/tf" and not chunk.is_static:
            names = chunk.to_record_batch().schema.names
            assert "Transform3D:translation" in names and "Transform3D:child_frame" in names
            rows += chunk.num_rows
    assert rows == traj.n_samples * traj.n_bodies


def test_connect_streams_the_run_to_a_viewer_server(tmp_path):
    """``rblog run --connect URL`` streams to a running Rerun gRPC server (what a viewer
    started with ``rerun`` listens on) the same run it writes to the file: the server saves what
    it receives, and both read back identical."""
    import signal
    import socket
    import time as _time

    import rblog

    with socket.socket() as s:  # a free port
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    live, file_ = tmp_path / "live.rrd", tmp_path / "file.rrd"
    server = subprocess.Popen([sys.executable, "-m", "rerun", "--serve-grpc", "--port", str(port),
                               "--save", str(live)], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = _time.monotonic() + 60
        while True:  # wait until it listens
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert server.poll() is None and _time.monotonic() < deadline, "server did not start"
                _time.sleep(0.2)
        scene = Path(__file__).resolve().parents[2] / "samples" / "bouncing_ball.toml"
        out = subprocess.run([sys.executable, "-m", "rblog_cli.main", "run", str(scene), "--connect",
                              f"rerun+http://127.0.0.1:{port}/proxy", "--rrd", str(file_)],
                             capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stdout + out.stderr
        deadline = _time.monotonic() + 30  # the server writes as it receives
        while _time.monotonic() < deadline:
            try:
                if len(rblog.load(live).t) == len(rblog.load(file_).t):
                    break
            except Exception:
                pass
            _time.sleep(0.5)
    finally:
        os.killpg(server.pid, signal.SIGTERM)
        server.wait(timeout=30)
    a, b = rblog.load(file_), rblog.load(live)
    assert len(a.t) == 401 and not b.truncated  # 4 s at the scene's 100 Hz logging, plus t = 0
    for name in ("t", "position", "quat_wxyz", "linear_momentum", "angular_momentum", "total_energy"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert len(a.contacts) == len(b.contacts) > 0
    assert np.array_equal(a.contacts.normal_impulse, b.contacts.normal_impulse)


def test_frame_transforms_encoder_matches_protobuf():
    """The compiled /tf encoder writes exactly what protobuf's own serializer writes for the same
    foxglove.FrameTransforms (zero timestamp fields, long names, large times included)."""
    from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms

    from rblog.record.mcap_writer import _TfEncoder

    rng = np.random.default_rng(0)
    names = ["a", "box_12", "x" * 200, "b2"]
    T = 40
    ns = np.concatenate([[0, 1, 999_999_999, 1_000_000_000, 2**40, 2**62],
                         rng.integers(0, 2**50, T - 6)])
    pos, quat = rng.normal(size=(T, 4, 3)), rng.normal(size=(T, 4, 4))
    msgs = _TfEncoder(names).rows(ns, pos, quat)
    assert len(msgs) == T
    for t in range(T):
        ref = FrameTransforms()
        for i, name in enumerate(names):
            tr = ref.transforms.add(parent_frame_id="world", child_frame_id=name)
            tr.timestamp.seconds, tr.timestamp.nanos = divmod(int(ns[t]), 10**9)
            tr.translation.x, tr.translation.y, tr.translation.z = pos[t, i]
            tr.rotation.w, tr.rotation.x, tr.rotation.y, tr.rotation.z = quat[t, i]
        assert bytes(msgs[t]) == ref.SerializeToString(), t


def test_contacts_encoder_decodes_to_the_contacts():
    """The compiled /rblog/contacts encoder: one message per step, each decoding (with protobuf's
    own parser and rblog's schema) to exactly that step's contacts; steps with 1 to 300 contacts
    (packed lengths over one varint byte), a zero step and a negative body index included."""
    from rblog.record.mcap_writer import encode_contacts

    rng = np.random.default_rng(3)
    counts = [1, 300, 2, 17]
    steps = np.repeat(np.array([0, 5, 6, 2**40]), counts)
    k = len(steps)
    c = Contacts(step=steps, t=steps * 1e-3, body_a=rng.integers(0, 50, k),
                 body_b=rng.integers(-1, 50, k), point=rng.normal(size=(k, 3)),
                 normal=rng.normal(size=(k, 3)), separation=rng.normal(size=k),
                 normal_impulse=rng.random(k), friction_impulse=rng.normal(size=(k, 3)),
                 kind=rng.integers(0, 2, k).astype(np.int8))
    msgs, step0, t0 = encode_contacts(c)
    assert len(msgs) == 4 and step0.tolist() == [0, 5, 6, 2**40]
    cls = S.message_class("Contacts")
    lo = 0
    for m, n in zip(msgs, counts):
        d = cls.FromString(bytes(m))
        sl = slice(lo, lo + n)
        assert d.step == steps[lo] and d.t == steps[lo] * 1e-3
        assert list(d.body_a) == c.body_a[sl].tolist() and list(d.body_b) == c.body_b[sl].tolist()
        assert list(d.kind) == c.kind[sl].tolist()
        for name in ("point", "normal", "friction_impulse", "separation", "normal_impulse"):
            assert list(getattr(d, name)) == getattr(c, name)[sl].reshape(-1).tolist(), name
        lo += n


def test_state_records_from_strided_channels():
    """State records encoded from per-interval channels that are views of wider arrays (an
    engine's (T, kinds, N, 6) impulses and (T, kinds, N) work, as rblog.adapters hands them
    over, not copied) decode, with protobuf's own parser and rblog's schema, to exactly those
    values; the records are the bytes encoded from contiguous copies of the same channels."""
    from rblog.record import _common as C
    from rblog.record.mcap_writer import _MESSAGE_HEAD, _SampleRecords

    rng = np.random.default_rng(3)
    T, n = 9, 4
    interval = ("impulse_contact_linear", "impulse_contact_angular", "work_applied")
    records = _SampleRecords([f"b{i}" for i in range(n)], [1, 2, 3], interval)
    W, work = rng.normal(size=(T, 6, n + 1, 6)), rng.normal(size=(T, 4, n + 1))
    views = {"impulse_contact_linear": W[:, 0, 1:, 3:], "impulse_contact_angular": W[:, 0, 1:, :3],
             "work_applied": work[:, 0, 1:]}
    assert not any(v.flags.c_contiguous for v in views.values())
    cols = {name: rng.normal(size=(T, C.expected_width(name, n)))
            for _, name, _, _ in records.state_fields[2:] if name not in views}
    cols.update(views)
    step, t = np.arange(T, dtype=np.int64), 0.01 * np.arange(T)
    metrics = [step, t] + [rng.normal(size=T) for _ in range(4)] + \
        [rng.normal(size=(T, 3)) for _ in range(2)] + [rng.normal(size=T) for _ in range(2)]
    pos, quat = rng.normal(size=(T, n, 3)), rng.normal(size=(T, n, 4))
    names = [name for _, name, _, _ in records.state_fields[2:]]
    ns = np.arange(T, dtype=np.int64) * 10**7
    buf, ends = records.encode(ns, [step, t, *(cols[k] for k in names)], metrics, pos, quat)
    ref, ref_ends = records.encode(ns, [step, t, *(np.ascontiguousarray(cols[k]) for k in names)],
                                   metrics, pos, quat)
    assert bytes(buf) == bytes(ref) and ends.tolist() == ref_ends.tolist()
    cls = S.message_class("State")
    e = [0, *ends.tolist()]
    for k in range(T):
        msg = cls()
        msg.ParseFromString(bytes(buf[e[3 * k] + _MESSAGE_HEAD:e[3 * k + 1]]))
        for name, v in views.items():
            assert list(getattr(msg, name)) == v[k].reshape(-1).tolist(), (name, k)
