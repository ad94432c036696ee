"""rblog's fuzz targets: each takes bytes and feeds them to one entry point that reads user input.

A target passes when the entry point returns or raises an ``RblogError`` (a one-line message);
any other exception is a finding, and so is a crash, an abort or a hang (atheris, run.py, reports
those). Targets:

* ``mcap``: the bytes as an .mcap file, ``rblog.load`` (framing, CRCs, protobuf, contents).
* ``mcap_fields``: a seed .mcap with one field of one rblog message set from the bytes and the
  file re-written with valid framing and CRCs, so the mutation reaches the contents checks.
* ``rrd``: the bytes as an .rrd file, ``rblog.load``.
* ``rrd_payload``: a seed .rrd with bytes of one Arrow IPC payload changed, re-compressed and
  re-framed, so the mutation reaches pyarrow's decoding instead of stopping at LZ4.
* ``scene``: the bytes as TOML text, ``rblog.engine.scene.parse_scene``.
* ``writer``: ``rblog.body_table`` and ``rblog.Recorder`` with arguments of types and shapes
  drawn from the bytes, then one ``write``.
* ``mujoco``: the bytes as an MJCF string; a model MuJoCo accepts goes through
  ``rblog.adapters.mujoco.MujocoRecorder`` for three steps.

Each target is a plain function, so the seed corpus (tests/fuzz/corpus/<target>/) is replayed by
pytest (test_fuzz.py) with or without atheris.
"""

from __future__ import annotations

import io
import math
import os
import struct
import tempfile
import warnings
from functools import cache
from pathlib import Path

import numpy as np

from rblog.errors import RblogError

CORPUS = Path(__file__).resolve().parent / "corpus"
_TMP = Path(tempfile.mkdtemp(prefix="rblog-fuzz-"))


def _as_file(data: bytes, suffix: str) -> Path:
    p = _TMP / f"input{os.getpid()}{suffix}"
    p.write_bytes(data)
    return p


def _load(path: Path) -> None:
    import rblog

    try:
        traj = rblog.load(path)
    except RblogError:
        return
    # what the analyzers will index: lengths the reader promised
    n, T = traj.n_bodies, traj.n_samples
    assert traj.position.shape == (T, n, 3) and traj.rotation.shape == (T, n, 3, 3)
    c = traj.contacts
    assert all(len(getattr(c, f)) == len(c) for f in ("t", "body_a", "body_b", "point", "kind"))
    assert ((c.body_a >= 0) & (c.body_a < n)).all() and ((c.body_b >= -1) & (c.body_b < n)).all()
    assert np.isin(c.step, traj.step).all()


def mcap(data: bytes) -> None:
    _load(_as_file(data, ".mcap"))


def rrd(data: bytes) -> None:
    _load(_as_file(data, ".rrd"))


def scene(data: bytes) -> None:
    from rblog.engine.scene import parse_scene

    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        return
    try:
        parse_scene(text, "fuzz.toml")
    except RblogError:
        pass


# --- structured mutations of the seed logs ---------------------------------------------------

@cache
def _seed(name: str) -> bytes:
    return (CORPUS / "seeds" / name).read_bytes()


def _take(data: bytes, pos: int, n: int) -> tuple[int, int]:
    chunk = data[pos:pos + n].ljust(n, b"\0")
    return int.from_bytes(chunk, "little"), pos + n


def mcap_fields(data: bytes) -> None:
    """data: [message index u16][field pick u8][op u8][value f64][repeat/size u8] ..."""
    from mcap.reader import make_reader
    from mcap.writer import Writer
    from mcap_protobuf.decoder import DecoderFactory

    if len(data) < 4:
        return
    edits, pos = [], 0
    while pos + 4 <= len(data) and len(edits) < 4:
        idx, pos = _take(data, pos, 2)
        fpick, pos = _take(data, pos, 1)
        op, pos = _take(data, pos, 1)
        raw, pos = _take(data, pos, 8)
        edits.append((idx, fpick, op, struct.unpack("<d", raw.to_bytes(8, "little"))[0], raw))
    factory = DecoderFactory()
    out = io.BytesIO()
    w = Writer(out)
    w.start()
    sids, cids, k = {}, {}, 0
    for schema, channel, message in make_reader(io.BytesIO(_seed("ball.mcap"))).iter_messages():
        if schema.id not in sids:
            sids[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
        if channel.id not in cids:
            cids[channel.id] = w.register_channel(channel.topic, channel.message_encoding,
                                                  sids[schema.id], channel.metadata)
        payload = message.data
        if schema.name.startswith("rblog."):
            mine = [e for e in edits if e[0] % 700 == k]
            k += 1
            if mine:
                msg = factory.decoder_for(channel.message_encoding, schema)(payload)
                for _, fpick, op, value, raw in mine:
                    _edit_field(msg, fpick, op, value, raw)
                payload = msg.SerializeToString()
        w.add_message(cids[channel.id], message.log_time, payload, message.publish_time)
    w.finish()
    _load(_as_file(out.getvalue(), ".mcap"))


def _edit_field(msg, fpick: int, op: int, value: float, raw: int) -> None:
    fields = msg.DESCRIPTOR.fields
    f = fields[fpick % len(fields)]
    v = getattr(msg, f.name)
    is_rep = hasattr(v, "append")  # a repeated field (RepeatedScalarContainer)
    kind = f.cpp_type
    if kind == f.CPPTYPE_STRING:
        new = raw.to_bytes(8, "little").decode("latin-1")
    elif kind == f.CPPTYPE_BOOL:
        new = bool(raw & 1)
    elif kind == f.CPPTYPE_DOUBLE:
        new = value
    else:
        bits = 64 if kind in (f.CPPTYPE_INT64, f.CPPTYPE_UINT64) else 32
        new = raw % (1 << bits) - (1 << (bits - 1)) if kind in (f.CPPTYPE_INT64, f.CPPTYPE_INT32) \
            else raw % (1 << bits)
        if op & 4:
            new = int(op >> 3) - 2  # small values: -2..29 (indices near the valid range)
    try:
        if not is_rep:
            setattr(msg, f.name, new)
            return
        o = op & 3
        if o == 0 and len(v):
            v[raw % len(v)] = new
        elif o == 1:
            v.append(new)
        elif o == 2 and len(v):
            del v[raw % len(v):]
        else:
            del v[:]
    except (ValueError, TypeError):  # not a value of the field's type (-2 for a uint32)
        return


def rrd_payload(data: bytes) -> None:
    """data: [message pick u16][then (offset u32, byte u8) pairs] applied to that message's
    decompressed Arrow IPC bytes."""
    import pyarrow as pa

    from rblog.record import safe_rrd

    if len(data) < 7:
        return
    seed = _seed("ball.rrd")
    p = _as_file(seed, ".seed.rrd")
    msgs, _ = safe_rrd.messages(p)
    arrow = [(off, bytes(pl)) for off, kind, pl in msgs if kind == safe_rrd.KIND_ARROW]
    pick, pos = _take(data, 0, 2)
    off, payload = arrow[pick % len(arrow)]
    f = safe_rrd._fields(payload)
    raw = bytearray(pa.decompress(f[5], decompressed_size=f[3], codec="lz4_raw", asbytes=True)
                    if f.get(2) == safe_rrd.COMPRESSION_LZ4 else f[5])
    while pos + 5 <= len(data):
        at, pos = _take(data, pos, 4)
        b, pos = _take(data, pos, 1)
        raw[at % len(raw)] = b
    f[2], f[3], f[5] = safe_rrd.COMPRESSION_LZ4, len(raw), pa.compress(bytes(raw), codec="lz4_raw",
                                                                      asbytes=True)
    new = b"".join(_key(n, v) for n, v in sorted(f.items()))
    out = seed[:off] + struct.pack("<QQ", safe_rrd.KIND_ARROW, len(new)) + new \
        + seed[off + 16 + len(payload):]
    _load(_as_file(out, ".rrd"))


def _varint(x: int) -> bytes:
    out = bytearray()
    while True:
        b, x = x & 0x7F, x >> 7
        out.append(b | (0x80 if x else 0))
        if not x:
            return bytes(out)


def _key(num: int, v) -> bytes:
    if isinstance(v, int):
        return _varint(num << 3) + _varint(v)
    return _varint(num << 3 | 2) + _varint(len(v)) + bytes(v)


# --- the writer API ---------------------------------------------------------------------------

_POOL = [None, "", "x", "sphere", "box", "none", 0, 1, -1, 2, 1.5, -0.5, math.nan, math.inf,
         True, b"x", {}, {"a": 1}, [], [1.0], [0.1, 0.0, 0.0], [[0.1, 0.0, 0.0]], [[1, 2]],
         ["a"], [None], np.zeros(0), np.ones(3), np.ones((1, 3)), np.ones((2, 3)),
         np.full((1, 3), np.nan), np.array(["a"]), object()]


def _draw(data: bytes, pos: int, good):
    """The good value (most of the time) or one of _POOL, by the next byte."""
    b, pos = _take(data, pos, 1)
    return (good if b < 128 or not len(_POOL) else _POOL[b % len(_POOL)]), pos


def writer(data: bytes) -> None:
    import rblog

    good_table = dict(name=["ball"], shape=["sphere"], size=[[0.1, 0.0, 0.0]], mass=[1.0],
                      inertia_diag=None, restitution=0.5, friction=0.5, group=0,
                      force_world=None, torque_world=None, gravity=(0.0, 0.0, -9.81),
                      ground=False, ground_offset=0.0, ground_restitution=0.5,
                      ground_friction=0.5, ground_normal=(0.0, 0.0, 1.0))
    pos, kw = 0, {}
    for k, v in good_table.items():
        kw[k], pos = _draw(data, pos, v)
    rec_kw = {}
    for k, v in dict(dt=0.01, log_every=1, duration_s=0.0, writer="", integrator="",
                     engine_settings=None, seed=None, keep=True, combine_friction="geometric",
                     combine_restitution="max").items():
        rec_kw[k], pos = _draw(data, pos, v)
    t = np.arange(3) * 0.01
    arrays = dict(t=t, position=np.zeros((3, 1, 3)), quat_wxyz=np.tile([1.0, 0, 0, 0], (3, 1, 1)),
                  velocity=np.zeros((3, 1, 3)), angular_velocity=np.zeros((3, 1, 3)))
    for k in list(arrays):
        arrays[k], pos = _draw(data, pos, arrays[k])
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = rblog.body_table(**kw)
            with rblog.Recorder(model, **rec_kw) as rec:
                rec.write(**arrays)
    except RblogError:
        pass


# --- the MuJoCo adapter ----------------------------------------------------------------------

def mujoco(data: bytes) -> None:
    try:
        import mujoco as mj
    except ImportError:
        return
    from rblog.adapters.mujoco import MujocoRecorder

    try:
        xml = data.decode("utf-8")
    except UnicodeDecodeError:
        return
    if "<include" in xml or "file=" in xml:  # no reading of other files from fuzz input
        return
    try:
        m = mj.MjModel.from_xml_string(xml)
    except (ValueError, mj.FatalError):  # MuJoCo refused the XML: not rblog's to judge
        return
    if m.nbody > 64 or m.ngeom > 256:
        return
    d = mj.MjData(m)
    try:
        with MujocoRecorder(m, d, keep=True) as rec:
            for _ in range(3):
                mj.mj_step(m, d)
                rec(d)
    except RblogError:
        pass


TARGETS = {"mcap": mcap, "mcap_fields": mcap_fields, "rrd": rrd, "rrd_payload": rrd_payload,
           "scene": scene, "writer": writer, "mujoco": mujoco}
