"""Write a run to an MCAP file: protobuf messages, every schema embedded (docs/log-format.md).

Topics: ``/rblog/run`` (static model and metadata), ``/rblog/state`` (full float64 state, one
message per sample), ``/rblog/contacts``, ``/rblog/metrics`` (plot-friendly totals), ``/tf``
(``foxglove.FrameTransforms``), ``/scene`` (``foxglove.SceneUpdate``) and ``/rblog/status``.

The per-sample messages (State, Metrics, /tf) are encoded a whole block at a time, as complete
MCAP Message records, by one compiled call (:class:`_SampleRecords`), and added to the mcap
package's ``Writer`` a chunk at a time through :class:`_BlockChunkBuilder`; the Writer writes
everything else (header, schemas, channels, compressed chunks with their CRC, message indexes,
summary, footer), its chunks and CRCs through :class:`_Writer` (LZ4 at LZ4_LEVEL, libdeflate's
CRC-32: the bytes mcap's Writer writes at that level). Chunks are finalized every
``CHUNK_BYTES`` of messages or ``FLUSH_EVERY_S`` of wall time, whichever comes first, so memory
stays bounded and a killed process loses at most that much.

Why this module is long: it is the one place that knows MCAP's side of the contract: the
static records (run, scene), the wire format of every per-sample and contact message written
straight from numpy buffers by compiled kernels (protobuf layout and MCAP record framing: C++,
csrc/record/mcap_encode.cpp, module ``rblog.record._encode``, which releases the GIL), and
the chunk builder that feeds those records to the mcap Writer exactly as it would chunk them
one by one.
"""

from __future__ import annotations

import time

import numpy as np
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
from foxglove_schemas_protobuf.CylinderPrimitive_pb2 import CylinderPrimitive
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.KeyValuePair_pb2 import KeyValuePair
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.SpherePrimitive_pb2 import SpherePrimitive
from foxglove_schemas_protobuf.TriangleListPrimitive_pb2 import TriangleListPrimitive
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.writer import CompressionType, Writer
from mcap_protobuf.schema import build_file_descriptor_set

from rblog import __version__
from rblog.errors import LogWriteError
from rblog.contract.model import (GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_ELLIPSOID,
                                  GEOM_MESH, GEOM_PLANE, GEOM_SPHERE, Model)
from rblog.contract.trajectory import Contacts, RunInfo, Trajectory
from rblog.record import _common as C
from rblog.record import _encode
from rblog.record import schema as S

#: chunk size (bytes of uncompressed messages); also the most a killed writer loses
CHUNK_BYTES = 1 << 20
#: a chunk is also finalized (and the file flushed) when this much wall time passed since the last
FLUSH_EVERY_S = 0.5
#: chunk compression. Bytes per body-sample / write CPU per sample, measured on
#: samples/spinning_bodies.toml (300 bodies): none 361 / 337 us, lz4 236 / 342 us,
#: zstd 163 / 414 us; on noise-like states (100 bodies) none 371, lz4 333, zstd 302 at
#: 1 : 1.8 : 3 cost. lz4 buys a third off for almost nothing; Foxglove and Rerun read all three.
DEFAULT_COMPRESSION = "lz4"
#: the LZ4 frame compression level of the chunks (LZ4F: below 0 is the fast mode with
#: acceleration -level; the frame is a standard LZ4 frame whatever the level, every reader
#: decodes it). Over the chunks of a 2000-step log of benchmarks/bench_adapters.py's MuJoCo
#: worlds (a sample every step; ``lz4.frame.compress`` of lz4 4.4.5 in unlinked 64 KiB blocks;
#: ms of CPU for all chunks, compressed / raw bytes): stacker (22.6 MB) -32 10.3 ms 0.608,
#: -64 7.1 ms 0.667, -128 4.8 ms 0.733, -256 4.0 ms 0.798; humanoid (23.2 MB) -32 7.1 ms 0.764,
#: -64 4.8 ms 0.789, -128 4.0 ms 0.813, -256 3.7 ms 0.834. Writing the bytes costs ~0.17 ms of
#: CPU per MiB (page cache), so -128 saves ~5 ms (stacker) and ~2.5 ms (humanoid) of the
#: recording's CPU against -32 for 10-20 % more bytes; below -128 the bytes grow faster than the
#: time falls.
LZ4_LEVEL = -128
#: whether the chunk's LZ4 blocks (64 KiB) may refer back to the previous one (LZ4F linked
#: blocks). Unlinked, over the 23-24 chunks of a 2000-step log at level -32 (ms of CPU for all,
#: compressed / raw bytes): stacker 22.6 -> 16.1 ms, 0.541 -> 0.557; humanoid 14.1 -> 9.1 ms,
#: 0.725 -> 0.733 (a standard LZ4 frame either way).
LZ4_BLOCK_LINKED = False

TOPIC_RUN = "/rblog/run"
TOPIC_STATE = "/rblog/state"
TOPIC_CONTACTS = "/rblog/contacts"
TOPIC_METRICS = "/rblog/metrics"
TOPIC_STATUS = "/rblog/status"
TOPIC_TF = "/tf"
TOPIC_SCENE = "/scene"


_COMPRESSION = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                "none": CompressionType.NONE}


def _crc32_function():
    """CRC-32 (zlib's: ``crc(data, value)``, as ``zlib.crc32``): libdeflate's ``libdeflate_crc32``
    (carry-less multiply; per 1 MiB chunk 0.07 ms of CPU against zlib 1.2.13's 0.60 ms) when the
    system has libdeflate and it agrees with zlib on a test vector, else ``zlib.crc32``."""
    import ctypes
    import ctypes.util
    import zlib

    try:
        lib = ctypes.CDLL(ctypes.util.find_library("deflate") or "libdeflate.so.0")
        fn = lib.libdeflate_crc32
    except (OSError, AttributeError):
        return zlib.crc32
    fn.restype, fn.argtypes = ctypes.c_uint32, [ctypes.c_uint32, ctypes.c_void_p, ctypes.c_size_t]

    def crc32(data, value: int = 0) -> int:
        b = np.frombuffer(data, np.uint8)
        return int(fn(value, b.ctypes.data, b.nbytes)) if b.nbytes else value

    probe = bytes(range(256)) * 5 + b"rblog"
    if crc32(probe) != zlib.crc32(probe) or crc32(probe[7:], 0x1234) != zlib.crc32(probe[7:], 0x1234):
        return zlib.crc32
    return crc32


_crc32 = _crc32_function()


class _Writer(Writer):
    """mcap's Writer with its chunk finalize and its data-section write (``__finalize_chunk``,
    ``__flush`` of mcap 1.x, whose private attributes these read) doing what mcap's do, two
    costs changed: LZ4 chunks are compressed at LZ4_LEVEL in unlinked blocks (LZ4_BLOCK_LINKED;
    mcap's own calls ``lz4.frame.compress`` at level 0, linked) and the CRCs are :data:`_crc32`'s (the same values). The
    records, both CRCs (a chunk's uncompressed bytes, the data section) and the chunk indexes are
    the bytes mcap's Writer writes with that compression level. A Writer without those attributes
    runs mcap's own methods."""

    def _known(self) -> bool:
        known = self.__dict__.get("_rblog_known")
        if known is None:  # once per writer: the attributes are set in Writer.__init__
            known = self.__dict__["_rblog_known"] = all(hasattr(self, "_Writer__" + a)
                                                        for a in _WRITER_ATTRS)
        return known

    def _Writer__flush(self):
        if not self._known():
            return Writer._Writer__flush(self)
        data = self._Writer__record_builder.end()
        if self._Writer__enable_data_crcs:
            self._Writer__data_section_crc = _crc32(data, self._Writer__data_section_crc)
        self._Writer__stream.write(data)

    def _Writer__finalize_chunk(self):
        if not self._known():
            return Writer._Writer__finalize_chunk(self)
        builder = self._Writer__chunk_builder
        if not builder or builder.num_messages == 0:
            return
        import struct

        from mcap.records import ChunkIndex
        from mcap.writer import IndexType

        self._Writer__statistics.chunk_count += 1
        chunk_data = builder.end()
        comp = self._Writer__compression
        if comp == CompressionType.LZ4:
            import lz4.frame

            name, compressed = "lz4", lz4.frame.compress(chunk_data, compression_level=LZ4_LEVEL,
                                                         block_linked=LZ4_BLOCK_LINKED)
        elif comp == CompressionType.ZSTD:
            import zstandard

            name, compressed = "zstd", zstandard.compress(chunk_data)
        else:
            name, compressed = "", chunk_data
        # the Chunk record (mcap.records.Chunk.write's bytes), written straight to the stream:
        # opcode, length, start and end time, uncompressed size, CRC, compression, records
        crc = _crc32(chunk_data) if self._Writer__enable_crcs else 0
        tag = name.encode()
        head = struct.pack(f"<BQQQQII{len(tag)}sQ", int(Opcode.CHUNK),
                           8 + 8 + 8 + 4 + 4 + len(tag) + 8 + len(compressed),
                           builder.message_start_time, builder.message_end_time, len(chunk_data),
                           crc, len(tag), tag, len(compressed))
        stream, rb = self._Writer__stream, self._Writer__record_builder
        self._Writer__flush()
        start = stream.tell()
        for part in (head, compressed):
            if self._Writer__enable_data_crcs:
                self._Writer__data_section_crc = _crc32(part, self._Writer__data_section_crc)
            stream.write(part)
        index = ChunkIndex(message_start_time=builder.message_start_time,
                           message_end_time=builder.message_end_time, chunk_start_offset=start,
                           chunk_length=len(head) + len(compressed), message_index_offsets={},
                           message_index_length=0, compression=name,
                           compressed_size=len(compressed), uncompressed_size=len(chunk_data))
        self._Writer__flush()
        index_start = stream.tell()
        if self._Writer__index_types & IndexType.MESSAGE:
            for cid, idx in builder.message_indices.items():
                index.message_index_offsets[cid] = index_start + rb.count
                idx.write(rb)
        index.message_index_length = rb.count
        self._Writer__flush()
        self._Writer__chunk_indices.append(index)
        builder.reset()


#: the private attributes of mcap's Writer that _Writer's methods read
_WRITER_ATTRS = ("statistics", "enable_crcs", "enable_data_crcs", "data_section_crc", "stream",
                 "record_builder", "index_types", "chunk_indices", "chunk_builder", "compression")


def _compression(name: str) -> CompressionType:
    """The chunk compression: ``name`` if its package is importable (``lz4`` and ``zstandard``
    are dependencies of ``mcap``), else none."""
    if name == "zstd":
        try:
            import zstandard  # noqa: F401
        except ImportError:
            return CompressionType.NONE
    elif name == "lz4":
        try:
            import lz4.frame  # noqa: F401
        except ImportError:
            return CompressionType.NONE
    return _COMPRESSION[name]


class McapRecorder:
    """Records a run into ``path`` (.mcap). See docs/log-format.md for the layout."""

    def __init__(self, path: str, *, compression: str = DEFAULT_COMPRESSION):
        if compression not in _COMPRESSION:
            raise ValueError(f"compression must be one of {sorted(_COMPRESSION)}")
        self.path = str(path)
        self.compression = compression
        self._fh = None
        self._w: Writer | None = None
        self._closed = False
        self._last_ns = 0
        self._last_flush = 0.0
        self.samples_written = 0

    # --- lifecycle ------------------------------------------------------------------------------

    def open(self, model: Model, info: RunInfo) -> None:
        """Create the file and write the header, schemas, run record and scene."""
        try:
            self._fh = open(self.path, "wb")
        except OSError as e:
            raise LogWriteError(self.path, e.strerror or str(e)) from None
        try:
            self._model = model
            self._n = model.n_bodies
            self._names = C.view_names(model.body_name)
            self._w = _Writer(self._fh, chunk_size=CHUNK_BYTES,
                              compression=_compression(self.compression))
            self._chunks = _BlockChunkBuilder.install(self._w)
            self._w.start(profile="", library=f"rblog {__version__}")
            self._register_channels()
            self._write_run(model, info)
            self._write_scene(model)
            self._w.add_metadata("rblog", {k: str(v) for k, v in C.info_to_fields(info).items()
                                           if k not in ("scene_toml", "scene_resolved_json")})
            self._interval = C.run_interval_channels(model)
            self._records = _SampleRecords(self._names, [self._ch[TOPIC_STATE],
                                                         self._ch[TOPIC_METRICS], self._ch[TOPIC_TF]],
                                           self._interval)
            # exercise the encoder once now (argument checks), not mid-run
            self._records.warm_up()
            encode_contacts(_ONE_CONTACT)
            self._flush(force=True)
        except OSError as e:
            self._abandon()
            raise LogWriteError(self.path, e.strerror or str(e)) from None

    def write(self, block: Trajectory) -> None:
        """Append a block of samples (and its contacts)."""
        if self._w is None or self._closed:
            raise LogWriteError(self.path, "recorder is not open")
        T = len(block.t)
        try:
            if T:
                self._write_samples(block)
            self._write_contacts(block.contacts)
            self._flush()
        except OSError as e:
            raise LogWriteError(self.path, e.strerror or str(e)) from None

    def close(self, truncated: bool = False, reason: str | None = None) -> None:
        """Write the status record, the summary and the footer; safe to call twice or after an
        error (a file left without footer is still read by rblog.load)."""
        if self._closed:
            return
        self._closed = True
        if self._w is None:
            self._abandon()
            return
        err = None
        try:
            status = S.message_class("Status")(complete=not truncated, truncated=bool(truncated),
                                               reason=reason or "")
            self._w.add_message(self._ch[TOPIC_STATUS], self._last_ns, status.SerializeToString(),
                                self._last_ns)
            self._w.finish()
        except (OSError, ValueError) as e:
            err = e
        finally:
            try:
                self._fh.close()
            except OSError as e:
                err = err or e
        if err is not None:
            raise LogWriteError(self.path, getattr(err, "strerror", None) or str(err)) from None

    def write_messages(self, topic: str, message_class, messages) -> None:
        """Add a topic of protobuf messages of ``message_class`` (its schema embedded) and write
        ``messages``, (log time ns, message) pairs, on it: more content beside the run (e.g. the
        findings of rblog.record.findings). The topic must not be one of the run's."""
        if self._w is None or self._closed:
            raise LogWriteError(self.path, "recorder is not open")
        if topic in self._ch:
            raise ValueError(f"{topic} is already a topic of this log")
        data = build_file_descriptor_set(message_class).SerializeToString()
        try:
            sid = self._w.register_schema(message_class.DESCRIPTOR.full_name, "protobuf", data)
            self._ch[topic] = ch = self._w.register_channel(topic, "protobuf", sid)
            for ns, msg in messages:
                self._w.add_message(ch, int(ns), msg.SerializeToString(), int(ns))
        except OSError as e:
            raise LogWriteError(self.path, e.strerror or str(e)) from None

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self.close(truncated=exc_type is not None, reason=None if exc is None else str(exc))

    # --- internals ------------------------------------------------------------------------------

    def _abandon(self):
        self._closed = True
        if self._fh is not None:
            try:
                self._fh.close()
            except OSError:
                pass

    def _register_channels(self):
        w = self._w
        rblog_data = S.file_descriptor_set_bytes()
        self._ch: dict[str, int] = {}
        for topic, name in ((TOPIC_RUN, "Run"), (TOPIC_STATE, "State"),
                            (TOPIC_CONTACTS, "Contacts"), (TOPIC_METRICS, "Metrics"),
                            (TOPIC_STATUS, "Status")):
            sid = w.register_schema(f"rblog.{name}", "protobuf", rblog_data)
            self._ch[topic] = w.register_channel(topic, "protobuf", sid)
        for topic, cls in ((TOPIC_TF, FrameTransforms), (TOPIC_SCENE, SceneUpdate)):
            data = build_file_descriptor_set(cls).SerializeToString()
            sid = w.register_schema(cls.DESCRIPTOR.full_name, "protobuf", data)
            self._ch[topic] = w.register_channel(topic, "protobuf", sid)

    def _write_run(self, model: Model, info: RunInfo):
        msg = S.message_class("Run")(rblog_log_format=C.LOG_FORMAT_VERSION)
        for k, v in C.info_to_fields(info).items():
            setattr(msg, k, v)
        for k, v in C.model_to_arrays(model).items():
            if k in ("ground", "collide_parent"):
                setattr(msg, k, bool(v[0]))
            elif k in ("ground_offset", "ground_restitution", "ground_friction"):
                setattr(msg, k, float(v[0]))
            elif k == "collide_rule":
                msg.collide_rule = v
            else:
                getattr(msg, k).extend(v.tolist() if isinstance(v, np.ndarray) else v)
        self._w.add_message(self._ch[TOPIC_RUN], 0, msg.SerializeToString(), 0)

    def _write_scene(self, model: Model):
        """One SceneEntity per body (its frame, frame-locked: every geom of the body as a
        primitive posed in the body's frame) and one per world geom (frame ``world``, id the
        geom's view name: ``ground``, ``static_box_<j>`` for a v2 model's)."""
        upd = SceneUpdate()
        gb = np.asarray(model.geom_body)
        ents = []
        for i, name in enumerate(self._names):
            ent = upd.entities.add(frame_id=name, id=f"body/{name}", frame_locked=True)
            ent.metadata.append(KeyValuePair(key="name", value=str(model.body_name[i])))
            ents.append(ent)
        gnames = C.geom_view_names(model)
        for g in range(len(gb)):
            b = int(gb[g])
            if b >= 0:
                _add_primitive(ents[b], model, g, _color(b, 0.9))
            else:
                ent = upd.entities.add(frame_id="world", id=gnames[g], frame_locked=True)
                ent.metadata.append(KeyValuePair(key="name", value=str(model.geom_name[g])))
                grey = Color(r=0.5, g=0.5, b=0.5, a=0.6) if int(model.geom_type[g]) == GEOM_PLANE \
                    else Color(r=0.6, g=0.6, b=0.65, a=0.8)
                _add_primitive(ent, model, g, grey)
        self._w.add_message(self._ch[TOPIC_SCENE], 0, upd.SerializeToString(), 0)

    def _write_samples(self, block: Trajectory):
        T, n = len(block.t), self._n
        a = C.block_arrays(block, n, self._interval, copy=False)
        step = np.ascontiguousarray(block.step, np.int64)
        t = np.ascontiguousarray(block.t, np.float64)
        ns = C.time_ns(t)
        state = [step, t, *(a[name] for _, name, _, _ in self._records.state_fields[2:])]
        metrics = [step, t, a["total_energy"], a["energy_translational"].sum(axis=1),
                   a["energy_rotational"].sum(axis=1), a["energy_potential"].sum(axis=1),
                   a["total_linear_momentum"], a["total_angular_momentum"],
                   _max0(a["ortho_error"]), _max0(np.abs(a["quat_norm_error"]))]
        position, quat_wxyz = a["position"].reshape(T, n, 3), a["quat_wxyz"].reshape(T, n, 4)
        if self._chunks is not None:
            self._chunks.add_sample_records(self._records, ns, state, metrics, position, quat_wxyz)
        else:  # an mcap Writer without the chunk builder we know: one message at a time
            buf, ends = self._records.encode(ns, state, metrics, position, quat_wxyz)
            times = np.repeat(ns, 3)
            mv, e = memoryview(buf), [0, *ends.tolist()]
            add, ch, tl = self._w.add_message, np.tile(self._records.channels, T).tolist(), times.tolist()
            for j in range(3 * T):
                add(ch[j], tl[j], mv[e[j] + _MESSAGE_HEAD:e[j + 1]], tl[j])
        self._last_ns = max(self._last_ns, int(ns[-1]))
        self.samples_written += T

    def _write_contacts(self, c: Contacts):
        if not len(c):
            return
        if self._chunks is not None:  # a block's messages at once (one index update, not M)
            buf, ends, step0, t0 = encode_contacts_buffer(c)
            ns = C.time_ns(t0)
            self._chunks.add_messages(self._ch[TOPIC_CONTACTS], ns, buf, ends)
        else:
            msgs, step0, t0 = encode_contacts(c)
            ns = C.time_ns(t0)
            add, ch = self._w.add_message, self._ch[TOPIC_CONTACTS]
            for m, ti in zip(msgs, ns.tolist()):
                add(ch, ti, m, ti)
        self._last_ns = max(self._last_ns, int(ns[-1]))

    def _flush(self, force: bool = False):
        now = time.monotonic()
        if force or now - self._last_flush >= FLUSH_EVERY_S:
            self._w.flush()  # finalizes the chunk in progress and flushes the file object
            self._last_flush = now


_ONE_CONTACT = Contacts(step=np.zeros(1, np.int64), t=np.zeros(1), body_a=np.zeros(1, np.int64),
                        body_b=np.zeros(1, np.int64), point=np.zeros((1, 3)),
                        normal=np.zeros((1, 3)), separation=np.zeros(1),
                        normal_impulse=np.zeros(1), friction_impulse=np.zeros((1, 3)),
                        kind=np.zeros(1, np.int64))


def encode_contacts(c: Contacts) -> tuple[list, np.ndarray, np.ndarray]:
    """The ``rblog.Contacts`` messages of ``c``: one per run of equal (step, t), in order.

    Returns (messages as memoryviews into one buffer, step (M,), t (M,) of each message). Fields
    are in number order and repeated fields packed, as protobuf's serializer writes them, except
    that step and t are written even when zero (parsers read both forms alike). The whole block
    is encoded in one compiled call."""
    buf, ends, step, t = encode_contacts_buffer(c)
    mv = memoryview(buf)
    e = ends.tolist()
    return [mv[e[i]:e[i + 1]] for i in range(len(e) - 1)], step, t


def encode_contacts_buffer(c: Contacts) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`encode_contacts` as (buffer: the M messages back to back, ends (M + 1,): message
    i is buffer[ends[i]:ends[i + 1]], step (M,), t (M,))."""
    step = np.ascontiguousarray(c.step, np.int64)
    t = np.ascontiguousarray(c.t, np.float64)
    cut = np.flatnonzero((step[1:] != step[:-1]) | (t[1:] != t[:-1])) + 1
    bounds = np.concatenate([[0], cut, [len(step)]]).astype(np.int64)
    i32 = [np.ascontiguousarray(a, "<i4") for a in (c.body_a, c.body_b, c.kind)]
    f3 = [np.ascontiguousarray(a, "<f8").reshape(-1, 3) for a in (c.point, c.normal,
                                                                   c.friction_impulse)]
    f1 = [np.ascontiguousarray(a, "<f8").reshape(-1) for a in (c.separation, c.normal_impulse)]
    m = len(bounds) - 1
    # per message: step and t (9 bytes each), 8 packed fields of <= 1 + 10 bytes of header;
    # per contact: 3 int32 and 11 doubles
    out = np.empty(m * (18 + 8 * 11) + len(step) * (3 * 4 + 11 * 8), np.uint8)
    ends = np.empty(m + 1, np.int64)
    _encode.encode_contacts(bounds, step.view(np.uint8), t.view(np.uint8),
                     i32[0].view(np.uint8), i32[1].view(np.uint8),
                     f3[0].reshape(-1).view(np.uint8), f3[1].reshape(-1).view(np.uint8),
                     f1[0].view(np.uint8), f1[1].view(np.uint8),
                     f3[2].reshape(-1).view(np.uint8), i32[2].view(np.uint8), out, ends)
    first = bounds[:-1]
    return out[:ends[-1]], ends, step[first], t[first]


def _add_primitive(ent, model: Model, g: int, color: Color) -> None:
    """Geom ``g`` as Foxglove primitives of ``ent`` (posed in the frame of the geom's body):
    cube (box; a plane as a thin one), sphere (sphere, ellipsoid: its 3 diameters), cylinder,
    capsule (a cylinder and two spheres), mesh (its convex hull as a triangle list; its
    bounding box without scipy)."""
    t = int(model.geom_type[g])
    pos = np.asarray(model.geom_pos_body[g], np.float64)
    q = np.asarray(model.geom_quat_wxyz_body[g], np.float64)
    size = np.asarray(model.geom_size[g], np.float64)
    if t == GEOM_BOX:
        ent.cubes.append(CubePrimitive(pose=_pose(pos, q), size=_vec(2.0 * size), color=color))
    elif t == GEOM_PLANE:
        center, qp, half = C.plane_box(model, g)
        ent.cubes.append(CubePrimitive(pose=_pose(center, qp), size=_vec(2.0 * half), color=color))
    elif t in (GEOM_SPHERE, GEOM_ELLIPSOID):
        d = 2.0 * (np.repeat(size[:1], 3) if t == GEOM_SPHERE else size)
        ent.spheres.append(SpherePrimitive(pose=_pose(pos, q), size=_vec(d), color=color))
    elif t in (GEOM_CYLINDER, GEOM_CAPSULE):
        r, h = float(size[0]), float(size[1])
        ent.cylinders.append(CylinderPrimitive(pose=_pose(pos, q),
                                               size=Vector3(x=2 * r, y=2 * r, z=2 * h),
                                               bottom_scale=1.0, top_scale=1.0, color=color))
        if t == GEOM_CAPSULE:
            from rblog.contract.orientation import quat_wxyz_to_matrix

            z = quat_wxyz_to_matrix(q)[:, 2]
            for sign in (-1.0, 1.0):
                ent.spheres.append(SpherePrimitive(pose=_pose(pos + sign * h * z, q),
                                                   size=Vector3(x=2 * r, y=2 * r, z=2 * r),
                                                   color=color))
    elif t == GEOM_MESH:
        vert = model.geom_vertices(g)
        tri = C.hull_triangles(vert)
        if tri is None:
            lo, hi = (vert.min(axis=0), vert.max(axis=0)) if len(vert) else (np.zeros(3),) * 2
            ent.cubes.append(CubePrimitive(pose=_pose(pos + q_rotate(q, (lo + hi) / 2), q),
                                           size=_vec(hi - lo), color=color))
        else:
            pts = vert[tri.reshape(-1)]
            ent.triangles.append(TriangleListPrimitive(
                pose=_pose(pos, q), color=color,
                points=[Point3(x=float(a), y=float(b), z=float(c)) for a, b, c in pts]))


def q_rotate(quat_wxyz, v) -> np.ndarray:
    from rblog.contract.orientation import quat_wxyz_to_matrix

    return quat_wxyz_to_matrix(np.asarray(quat_wxyz, np.float64)) @ np.asarray(v, np.float64)


def _max0(a: np.ndarray) -> np.ndarray:
    return a.max(axis=1) if a.shape[1] else np.zeros(a.shape[0])


def _vec(v) -> Vector3:
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def _pose(position=(0.0, 0.0, 0.0), quat_wxyz=(1.0, 0.0, 0.0, 0.0)) -> Pose:
    q = quat_wxyz
    return Pose(position=_vec(position),
                orientation=Quaternion(x=float(q[1]), y=float(q[2]), z=float(q[3]), w=float(q[0])))


_PALETTE = np.array([[0.12, 0.47, 0.71], [1.0, 0.5, 0.05], [0.17, 0.63, 0.17], [0.84, 0.15, 0.16],
                     [0.58, 0.4, 0.74], [0.55, 0.34, 0.29], [0.89, 0.47, 0.76], [0.74, 0.74, 0.13],
                     [0.09, 0.75, 0.81]])


def _color(i: int, alpha: float) -> Color:
    r, g, b = _PALETTE[i % len(_PALETTE)]
    return Color(r=float(r), g=float(g), b=float(b), a=alpha)


#: bytes of an MCAP Message record before its data: opcode (1), record length (8), channel id (2),
#: sequence (4), log time (8), publish time (8)
_MESSAGE_HEAD = 31


class _SampleRecords:
    """Encodes a block's per-sample messages (``rblog.State``, ``rblog.Metrics``, ``/tf``) as
    complete MCAP Message records, back to back in sample order (state, metrics, tf of sample 0,
    then of sample 1, ...), in one compiled call that writes every byte once, straight from the
    channel arrays. The payloads are the protobuf wire format protobuf's serializer writes
    (fields in number order, repeated fields packed), except that the singular scalars of State
    and Metrics are written even when zero, as docs/log-format.md allows.

    ``channels``: the three channel ids in record order. ``interval``: the run's per-interval
    channels (C.run_interval_channels), State fields 18+ of every sample."""

    def __init__(self, names: list[str], channels: list[int], interval: tuple = ()):
        self.n = len(names)
        self.channels = np.asarray(channels, np.int64)
        self.tf = _TfEncoder(names)
        n = self.n
        #: the State fields this run writes, in number order: (number, name, type, label)
        self.state_fields = [f for f in S.MESSAGES["State"] if f[0] <= 17 or f[1] in interval]
        self.state_hdr, self.state_off = _headers(
            [S.tag(num, 1) if label == "" else S.tag(num, 2) + S.varint(8 * C.expected_width(name, n))
             for num, name, _, label in self.state_fields])
        self.state_len = int(self.state_off[-1]) + 8 * sum(
            1 if label == "" else C.expected_width(name, n)
            for _, name, _, label in self.state_fields)
        self.metrics_hdr, self.metrics_off = _headers(
            [S.tag(k, 1) for k in range(1, 7)]
            + [S.tag(7, 2) + S.varint(24), S.tag(8, 2) + S.varint(24)]
            + [S.tag(9, 1), S.tag(10, 1)])
        self.metrics_len = int(self.metrics_off[-1]) + 8 * (8 + 6)

    def encode(self, ns, state: list, metrics: list, position, quat_wxyz):
        """Records of T samples: ns (T,) log times; ``state``, ``metrics``: the messages'
        fields in number order, each (T,) or (T, k) float64/int64; position (T, N, 3),
        quat_wxyz (T, N, 4). Returns (buffer, ends (3T,)): record j is
        buffer[ends[j - 1]:ends[j]] (from 0 for j = 0)."""
        T = len(ns)
        dbl = _tf_doubles(position, quat_wxyz)
        cap = T * (3 * _MESSAGE_HEAD + self.state_len + self.metrics_len
                   + self.tf.cap_per_sample())
        out = np.empty(cap, np.uint8)
        ends = np.empty(3 * T, np.int64)
        _encode.encode_sample_records(np.ascontiguousarray(ns, np.int64), self.channels,
                               self.state_hdr, self.state_off, _byte_rows(state, T),
                               self.metrics_hdr, self.metrics_off, _byte_rows(metrics, T),
                               dbl.reshape(-1).view(np.uint8), self.tf.rest, self.tf.rest_start,
                               self.tf.dbl_off, out, ends)
        return out[:ends[-1]] if T else out[:0], ends

    def record_max(self) -> int:
        """Most bytes one of the block's Message records takes (head and message)."""
        return _MESSAGE_HEAD + max(self.state_len, self.metrics_len, self.tf.cap_per_sample())

    def warm_up(self):
        n = self.n
        z = [np.zeros(1, np.int64), np.zeros(1)]
        self.encode(np.zeros(1, np.int64),
                    z + [np.zeros((1, 1 if label == "" else C.expected_width(name, n)))
                         for _, name, _, label in self.state_fields[2:]],
                    z + [np.zeros(1)] * 4 + [np.zeros((1, 3))] * 2 + [np.zeros(1)] * 2,
                    np.zeros((1, n, 3)), np.zeros((1, n, 4)))


def _headers(parts: list[bytes]) -> tuple[np.ndarray, np.ndarray]:
    """Field headers (tag, and length for packed fields) in one array, and their offsets."""
    off = np.concatenate([[0], np.cumsum([len(p) for p in parts])]).astype(np.int64)
    return np.frombuffer(b"".join(parts), np.uint8).copy(), off


_LE_F8, _LE_I8 = np.dtype("<f8"), np.dtype("<i8")


def _byte_rows(cols: list, T: int) -> tuple:
    """Each (T,) or (T, k) little-endian 8-byte column as its (T, 8k) bytes, and a (T, k) or
    (T, N, k) one whose last axis is contiguous (a view of a wider array: an engine's impulses)
    as its (T, 8k) or (T, N, 8k) bytes; views, no copy (other layouts are copied)."""
    out = []
    for c in cols:
        c = np.asarray(c)
        c = c.astype(_LE_F8 if c.dtype.kind == "f" else _LE_I8, copy=False)
        if c.flags.c_contiguous:
            c = c.reshape(T, -1)
        elif c.ndim not in (2, 3) or c.strides[-1] != 8:
            c = np.ascontiguousarray(c).reshape(T, -1)
        out.append(c.view(np.uint8))
    return tuple(out)


def _tf_doubles(position, quat_wxyz) -> np.ndarray:
    """(T, N, 7) doubles in /tf wire order: x, y, z, qx, qy, qz, qw."""
    T, n = position.shape[0], position.shape[1]
    dbl = np.empty((T, n, 7))
    dbl[..., :3] = position
    dbl[..., 3:6] = quat_wxyz[..., 1:]
    dbl[..., 6] = quat_wxyz[..., 0]
    return dbl


class _MessageIndexArrays:
    """A chunk's MessageIndex record of one channel (mcap.records.MessageIndex), kept as arrays
    of (log time, offset) and written in one piece (mcap's writes one struct per message)."""

    def __init__(self, channel_id: int):
        self.channel_id = channel_id
        self._parts: list[np.ndarray] = []

    def add(self, times: np.ndarray, offsets: np.ndarray):
        pairs = np.empty((len(times), 2), "<u8")
        pairs[:, 0], pairs[:, 1] = times, offsets
        self._parts.append(pairs)

    def write(self, stream: RecordBuilder):
        pairs = np.concatenate(self._parts) if self._parts else np.empty((0, 2), "<u8")
        stream.start_record(Opcode.MESSAGE_INDEX)
        stream.write2(self.channel_id)
        stream.write4(pairs.nbytes)
        stream.write(pairs.tobytes())
        stream.finish_record()


class _BlockChunkBuilder:
    """The chunk builder of an ``mcap.writer.Writer`` (it stands in for mcap's ChunkBuilder,
    whose interface the Writer uses: add_channel/add_schema/add_message, count, end, reset and the
    chunk's times and message indices), to which whole runs of encoded Message records are added
    encoded straight into it (:meth:`add_sample_records`). The Writer still writes everything else: the
    header, schemas and channels, chunk records (compressed, with their CRC), message indexes,
    the summary and the footer. Chunks close where the Writer would close them adding the same
    messages one by one: after the message that takes the chunk past the Writer's chunk size."""

    def __init__(self, writer: Writer, stats, chunk_size: int):
        self._w, self._stats, self._chunk_size = writer, stats, chunk_size
        self._buf = np.empty(2 * chunk_size, np.uint8)
        self._count = 0
        self._rb = RecordBuilder()
        self.message_indices: dict[int, _MessageIndexArrays] = {}
        self.message_start_time = 0
        self.message_end_time = 0
        self.num_messages = 0

    @classmethod
    def install(cls, writer: Writer) -> "_BlockChunkBuilder | None":
        """Put a builder into ``writer`` (before ``start``); None (the Writer keeps its own) if
        this version of mcap's Writer does not keep its chunk builder and statistics where 1.x
        does."""
        if not hasattr(writer, "_Writer__chunk_builder") or \
                not hasattr(writer, "_Writer__statistics") or writer._Writer__chunk_builder is None:
            return None
        b = cls(writer, writer._Writer__statistics, writer._Writer__chunk_size)
        writer._Writer__chunk_builder = b
        return b

    # --- the interface mcap's Writer uses ---------------------------------------------------
    @property
    def count(self) -> int:
        return self._count

    def end(self):
        return memoryview(self._buf)[:self._count]

    def reset(self):
        self._count = 0
        self.message_indices = {}
        self.message_start_time = self.message_end_time = 0
        self.num_messages = 0

    def add_channel(self, channel):
        channel.write(self._rb)
        self._append(memoryview(self._rb.end()))

    def add_schema(self, schema):
        schema.write(self._rb)
        self._append(memoryview(self._rb.end()))

    def add_message(self, message):
        t = np.array([message.log_time], np.uint64)
        self._index(np.array([message.channel_id]), t, np.array([self._count], np.uint64))
        message.write(self._rb)
        self._append(memoryview(self._rb.end()))

    # --- whole runs of records --------------------------------------------------------------
    def add_sample_records(self, records: "_SampleRecords", ns: np.ndarray, state: list,
                           metrics: list, position: np.ndarray, quat_wxyz: np.ndarray):
        """Encode a block's per-sample records (see :meth:`_SampleRecords.encode`, same
        arguments) straight into the chunk, closing chunks as the Writer would (after the record
        that takes the chunk past its size); updates the Writer's statistics. The same bytes as
        adding ``records.encode(...)``'s records one after the other, without the block's
        buffer and its copy."""
        T = len(ns)
        if not T:
            return
        ns = np.ascontiguousarray(ns, np.int64)
        m = 3 * T
        st = self._stats
        t_lo, t_hi = int(ns.min()), int(ns.max())
        st.message_start_time = t_lo if st.message_count == 0 else min(st.message_start_time, t_lo)
        st.message_end_time = max(st.message_end_time, t_hi)
        st.message_count += m
        for ch in sorted(records.channels.tolist()):  # ascending channel id, np.unique's order
            st.channel_message_counts[int(ch)] += T
        st_cols, mt_cols = _byte_rows(state, T), _byte_rows(metrics, T)
        position = np.ascontiguousarray(position, np.float64)
        quat_wxyz = np.ascontiguousarray(quat_wxyz, np.float64)
        offsets = np.empty(m, np.int64)
        rec_max = records.record_max()
        r = 0
        while r < m:
            if self._count + rec_max > len(self._buf):
                self._grow(self._count + rec_max)
            r1, self._count = _encode.encode_sample_records_into(
                r, self._buf, self._count, self._chunk_size, ns, records.channels,
                records.state_hdr, records.state_off, st_cols, records.metrics_hdr,
                records.metrics_off, mt_cols, position, quat_wxyz, records.tf.rest,
                records.tf.rest_start, records.tf.dbl_off, offsets)
            if r1 > r:
                self._index_samples(records.channels, ns, r, r1, offsets[:r1 - r])
            r = r1
            if self._count > self._chunk_size:
                self._w.flush()  # closes the chunk (compressed, CRC, message indexes)

    def add_messages(self, channel: int, ns: np.ndarray, buf: np.ndarray, ends: np.ndarray):
        """MCAP Message records on ``channel`` of the M messages ``buf[ends[i]:ends[i + 1]]``
        at log times ``ns`` (M,), built with numpy and added to the chunk a run at a time
        (closing chunks as the Writer would: after the record that takes the chunk past its
        size); updates the Writer's statistics. The same bytes and index as adding them one by
        one with the Writer's ``add_message``."""
        ns = np.asarray(ns, np.int64)
        ends = np.asarray(ends, np.int64)
        m = len(ns)
        if not m:
            return
        st = self._stats
        t_lo, t_hi = int(ns.min()), int(ns.max())
        st.message_start_time = t_lo if st.message_count == 0 else min(st.message_start_time, t_lo)
        st.message_end_time = max(st.message_end_time, t_hi)
        st.message_count += m
        st.channel_message_counts[channel] += m
        size = np.diff(ends)
        rec_size = size + _MESSAGE_HEAD
        head = np.zeros((m, _MESSAGE_HEAD), np.uint8)
        head[:, 0] = int(Opcode.MESSAGE)
        head[:, 1:9] = (rec_size - 9).astype("<u8").view(np.uint8).reshape(m, 8)
        head[:, 9:11] = np.frombuffer(np.uint16(channel).astype("<u2").tobytes(), np.uint8)
        tb = ns.astype("<u8").view(np.uint8).reshape(m, 8)
        head[:, 15:23] = tb
        head[:, 23:31] = tb
        data = np.frombuffer(buf, np.uint8)
        j = 0
        while j < m:
            # the run of records up to the one that takes the chunk past its size
            past = np.flatnonzero(self._count + np.cumsum(rec_size[j:]) > self._chunk_size)
            j1 = j + int(past[0]) + 1 if len(past) else m
            start = self._count + np.concatenate([[0], np.cumsum(rec_size[j:j1 - 1])])
            total = int(rec_size[j:j1].sum())
            if self._count + total > len(self._buf):
                self._grow(self._count + total)
            _encode.put_records(head[j:j1], data, ends[j:j1 + 1], self._buf, start)
            self._count += total
            self._index(np.full(j1 - j, channel), ns[j:j1].astype(np.uint64),
                        start.astype(np.uint64))
            j = j1
            if self._count > self._chunk_size:
                self._w.flush()

    def _index_samples(self, channels3, ns, r0: int, r1: int, offsets):
        """Index the per-sample records r0..r1 - 1 (record r: channel ``channels3[r % 3]``,
        log time ``ns[r // 3]``) at ``offsets`` (r1 - r0,): what :meth:`_index` does with the
        records' channels and times spelled out, without sorting them (strided views)."""
        n = r1 - r0
        times = ns[r0 // 3:(r1 - 1) // 3 + 1]
        lo, hi = int(times.min()), int(times.max())
        self.message_start_time = lo if self.num_messages == 0 else min(self.message_start_time, lo)
        self.message_end_time = max(self.message_end_time, hi)
        self.num_messages += n
        for k in range(min(3, n)):  # in order of first message, as mcap's builder
            ch = int(channels3[(r0 + k) % 3])
            off = offsets[k::3]
            first = (r0 + k) // 3
            idx = self.message_indices.get(ch)
            if idx is None:
                idx = self.message_indices[ch] = _MessageIndexArrays(ch)
            idx.add(ns[first:first + len(off)], off)

    def _index(self, channels, times, offsets):
        n = len(times)
        lo, hi = int(times.min()), int(times.max())
        self.message_start_time = lo if self.num_messages == 0 else min(self.message_start_time, lo)
        self.message_end_time = max(self.message_end_time, hi)
        self.num_messages += n
        chans, first = np.unique(channels, return_index=True)
        for ch in chans[np.argsort(first)]:  # in order of first message, as mcap's builder
            sel = channels == ch
            idx = self.message_indices.get(int(ch))
            if idx is None:
                idx = self.message_indices[int(ch)] = _MessageIndexArrays(int(ch))
            idx.add(times[sel], offsets[sel])

    def _grow(self, need: int):
        k = self._count
        grown = np.empty(max(2 * len(self._buf), need), np.uint8)
        grown[:k] = self._buf[:k]
        self._buf = grown

    def _append(self, data):
        data = np.frombuffer(data, np.uint8)
        k, n = self._count, len(data)
        if k + n > len(self._buf):
            self._grow(k + n)
        self._buf[k:k + n] = data
        self._count = k + n


class _TfEncoder:
    """Encodes ``foxglove.FrameTransforms`` messages (one transform per body) for a whole block,
    in one compiled call.

    Wire layout of each transform (field numbers of foxglove.FrameTransform), field 1 of the
    message: 1 timestamp {1 seconds, 2 nanos}, 2 parent "world", 3 child name, 4 translation
    {1 x, 2 y, 3 z}, 5 rotation {1 x, 2 y, 3 z, 4 w}. Everything after the timestamp is constant
    per body but for the 7 doubles, so each body has a template of those bytes and the offsets of
    its doubles; the kernel copies templates, writes the sample's timestamp and the doubles.
    """

    def __init__(self, names: list[str]):
        rests, offs = [], []
        for name in names:
            parts = [S.len_field(2, b"world"), S.len_field(3, name.encode("ascii")),
                     S.tag(4, 2) + S.varint(27)]
            at = []
            for fno in (1, 2, 3):
                parts.append(S.tag(fno, 1))
                at.append(sum(map(len, parts)))
                parts.append(b"\0" * 8)
            parts.append(S.tag(5, 2) + S.varint(36))
            for fno in (1, 2, 3, 4):
                parts.append(S.tag(fno, 1))
                at.append(sum(map(len, parts)))
                parts.append(b"\0" * 8)
            rests.append(b"".join(parts))
            offs.append(at)
        self.rest = np.frombuffer(b"".join(rests), np.uint8).copy()
        self.rest_start = np.concatenate([[0], np.cumsum([len(r) for r in rests])]).astype(np.int64)
        self.dbl_off = np.array(offs, np.int64).reshape(len(names), 7)

    def cap_per_sample(self) -> int:
        """Most bytes one message takes: per transform 2 tags, 2 length varints (<= 3 bytes
        each), a timestamp of <= 22 bytes."""
        return int(self.rest_start[-1]) + len(self.dbl_off) * 30

    def rows(self, ns: np.ndarray, position: np.ndarray, quat_wxyz: np.ndarray) -> list:
        """One serialized FrameTransforms per sample (memoryviews into one buffer): ns (T,),
        position (T, N, 3), quat_wxyz (T, N, 4)."""
        T = position.shape[0]
        out = np.empty(T * self.cap_per_sample(), np.uint8)
        bounds = np.empty(T + 1, np.int64)
        _encode.encode_frame_transforms(np.ascontiguousarray(ns, np.int64),
                                 _tf_doubles(position, quat_wxyz).reshape(-1).view(np.uint8),
                                 self.rest, self.rest_start, self.dbl_off, out, bounds)
        mv = memoryview(out)
        b = bounds.tolist()
        return [mv[b[i]:b[i + 1]] for i in range(T)]
