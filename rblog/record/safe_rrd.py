"""Reading an .rrd file's chunks with pyarrow, under checks, so that no byte of the file can abort
the process.

The Rerun SDK's own reader (``rerun.chunk.RrdReader``) decodes Arrow in Rust, and a payload with
two changed bytes can make it panic ("the offset of the new Buffer cannot exceed the existing
length", "Int type with bit width of 28", a NulError): a panic aborts the interpreter, which no
``except`` can catch. Here every layer is decoded by code that reports a bad input as an
exception instead:

* the stream framing (rerun 0.41): a 12-byte header ``RRF2`` + version + options, then messages
  ``kind: u64 LE, length: u64 LE, payload[length]``; kind 0 ends the stream, 1 is a store's
  SetStoreInfo, 2 an ArrowMsg (rerun.log_msg.v1alpha1);
* the ArrowMsg protobuf, by its wire format: 1 store id (a message: 1 kind, 1 = recording, 2 =
  blueprint; 2 recording id; 3 application id), 2 compression (1 none, 2 LZ4 block),
  3 uncompressed size, 4 encoding (1 Arrow IPC stream), 5 payload;
* LZ4 block decompression and the Arrow IPC stream by pyarrow (C++: flatbuffers verified,
  buffers bounds-checked), then ``RecordBatch.validate(full=True)`` (offsets, union type ids,
  UTF-8) before any value is read.

A chunk's Arrow schema carries its entity path (``rerun:entity_path``) and each column's role
(``rerun:kind``: control, index, data) and component name; that is what rblog.record.reader
reads. Measured against the SDK's reader and a validation pass in front of it:
benchmarks/RESULTS.md, "Fuzzing".
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

from rblog.errors import LogReadError

RRD_MAGIC = b"RRF2"
HEADER_BYTES = 12
KIND_END, KIND_STORE_INFO, KIND_ARROW = 0, 1, 2
STORE_RECORDING = 1
COMPRESSION_NONE, COMPRESSION_LZ4 = 1, 2
ENCODING_ARROW_IPC = 1
#: the largest decompressed payload accepted (bytes): a corrupted size field must not make the
#: reader allocate the machine's memory. rblog's writer sends blocks of at most ~32,768
#: body-samples (~7 MB); 2 GiB is far past any chunk a writer sends.
MAX_PAYLOAD_BYTES = 2**31
#: LZ4's largest expansion: a block of n bytes decompresses to at most 255 n (+ a few bytes), so
#: a larger stated size is a corrupted one (checked before the buffer is allocated)
LZ4_MAX_RATIO = 255
#: bytes each row of a chunk holds at least: its RowId (rerun.controls.RowId, 16-byte TUID), so a
#: batch claiming more rows than its payload can hold is corrupt (a column of type null has no
#: buffers for validate() to check its length against)
ROW_ID_BYTES = 16


class RrdFormatError(Exception):
    """A message of the stream that does not decode (the reader names the file and offset)."""


@dataclass
class Chunk:
    """One ArrowMsg of a recording store: its entity path and its validated record batch."""

    entity_path: str
    batch: object  # pyarrow.RecordBatch
    application_id: str


def varint(data: bytes, pos: int) -> tuple[int, int]:
    """A protobuf varint at ``pos``: (value, next position); RrdFormatError past the end or
    over 10 bytes (the MCAP reader's State fast path uses it too)."""
    result = shift = 0
    while True:
        if pos >= len(data):
            raise RrdFormatError("varint runs past the end of the message")
        b = data[pos]
        pos += 1
        result |= (b & 0x7F) << shift
        if not b & 0x80:
            return result, pos
        shift += 7
        if shift > 63:
            raise RrdFormatError("varint longer than 10 bytes")


def _fields(data: bytes) -> dict[int, object]:
    """Top-level protobuf fields: number -> int (varint) or bytes (length-delimited); the last
    occurrence wins, as protobuf's merge rule says for scalars."""
    out: dict[int, object] = {}
    pos, end = 0, len(data)
    while pos < end:
        key, pos = varint(data, pos)
        number, wire = key >> 3, key & 7
        if wire == 0:
            out[number], pos = varint(data, pos)
        elif wire == 2:
            size, pos = varint(data, pos)
            if pos + size > end:
                raise RrdFormatError(f"field {number} of {size} bytes runs past the message end")
            out[number] = data[pos:pos + size]
            pos += size
        elif wire == 1:
            pos += 8
        elif wire == 5:
            pos += 4
        else:
            raise RrdFormatError(f"field {number} has wire type {wire}")
    if pos != end:
        raise RrdFormatError("a field runs past the message end")
    return out


def messages(path: Path) -> tuple[list[tuple[int, int, memoryview]], str | None]:
    """(offset, kind, payload) of each complete message up to the end message, and why reading
    stopped early (None when the stream ends at its end message or at a message boundary)."""
    with open(path, "rb") as f:
        data = f.read()
    if len(data) < HEADER_BYTES or not data.startswith(RRD_MAGIC):
        raise RrdFormatError("no Rerun stream header")
    out, off, view = [], HEADER_BYTES, memoryview(data)
    while off + 16 <= len(data):
        kind, length = struct.unpack_from("<QQ", data, off)
        if off + 16 + length > len(data):
            return out, "the file is cut after its last complete message"
        out.append((off, kind, view[off + 16:off + 16 + length]))
        off += 16 + length
        if kind == KIND_END:
            return out, None
    return out, ("the file is cut after its last complete message" if off < len(data) else None)


def decode_arrow_msg(payload) -> tuple[int, str, object]:
    """(store kind, application id, validated pyarrow RecordBatch) of one ArrowMsg payload."""
    import pyarrow as pa

    f = _fields(bytes(payload))
    store = _fields(f[1]) if isinstance(f.get(1), bytes) else {}
    kind = store.get(1, 0)
    app = store.get(3, b"")
    app_id = _fields(app).get(1, b"") if isinstance(app, bytes) else b""
    try:
        app_id = app_id.decode() if isinstance(app_id, bytes) else ""
    except UnicodeDecodeError:
        raise RrdFormatError("application id is not UTF-8") from None
    compression, size = f.get(2, COMPRESSION_NONE), f.get(3, 0)
    encoding, body = f.get(4, ENCODING_ARROW_IPC), f.get(5, b"")
    if not isinstance(body, bytes) or not isinstance(size, int):
        raise RrdFormatError("payload or its size has the wrong wire type")
    if encoding != ENCODING_ARROW_IPC:
        raise RrdFormatError(f"encoding {encoding}, expected 1 (Arrow IPC)")
    try:
        if compression == COMPRESSION_LZ4:
            if not 0 < size <= min(MAX_PAYLOAD_BYTES, LZ4_MAX_RATIO * len(body) + 64):
                raise RrdFormatError(f"uncompressed size {size} out of range for "
                                     f"{len(body)} compressed bytes")
            raw = pa.decompress(body, decompressed_size=size, codec="lz4_raw")
        elif compression in (COMPRESSION_NONE, 0):
            raw = body
        else:
            raise RrdFormatError(f"compression {compression}, expected 1 (none) or 2 (LZ4)")
        reader = pa.ipc.open_stream(raw)
        batches = list(reader)
        if len(batches) != 1:
            raise RrdFormatError(f"{len(batches)} record batches, expected 1")
        batch = batches[0]
        if batch.num_rows * ROW_ID_BYTES > len(raw):
            raise RrdFormatError(f"{batch.num_rows} rows in {len(raw)} bytes")
        batch.validate(full=True)
        # the text the reader decodes: column names and the rerun:* metadata, UTF-8
        for field in batch.schema:
            field.name  # noqa: B018 - pyarrow decodes it here (UnicodeDecodeError)
            for key, value in (field.metadata or {}).items():
                if key.startswith(b"rerun:"):
                    value.decode()
        for key, value in (batch.schema.metadata or {}).items():
            if key.startswith(b"rerun:"):
                value.decode()
    except UnicodeDecodeError:
        raise RrdFormatError("a column name or its metadata is not UTF-8") from None
    except (pa.ArrowException, ValueError, OSError) as e:  # pyarrow's decode errors
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise RrdFormatError(first[:200]) from None
    return kind, app_id, batch


def chunks(path: Path, application_id: str) -> tuple[list[Chunk], str | None]:
    """The chunks of the recording store of ``application_id`` (or of the first recording store
    when none has it), in file order, and why the stream stopped early (None: it did not).
    Raises LogReadError naming the file, and the byte offset of a message that does not
    decode."""
    where = str(path)
    try:
        msgs, cut = messages(path)
    except RrdFormatError as e:
        raise LogReadError(where, f"unreadable Rerun file ({e})") from None
    found: list[Chunk] = []
    for off, kind, payload in msgs:
        if kind != KIND_ARROW:
            continue
        try:
            store_kind, app, batch = decode_arrow_msg(payload)
        except RrdFormatError as e:
            raise LogReadError(where, f"unreadable Rerun message at byte {off} ({e})") from None
        if store_kind != STORE_RECORDING:
            continue
        meta = batch.schema.metadata or {}
        try:
            entity = meta.get(b"rerun:entity_path", b"").decode()
        except UnicodeDecodeError:
            raise LogReadError(where, f"Rerun message at byte {off}: entity path is not "
                               "UTF-8") from None
        found.append(Chunk(entity, batch, app))
    if not found:
        raise LogReadError(where, "Rerun file holds no recording"
                           + (f" ({cut})" if cut else ""))
    apps = [c.application_id for c in found]
    want = application_id if application_id in apps else apps[0]
    return [c for c in found if c.application_id == want], cut
