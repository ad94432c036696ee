"""Read an rblog log (.rrd or .mcap) back into one :class:`~rblog.contract.trajectory.Trajectory`.

Only the canonical channels are read (``rblog/...`` entities, ``/rblog/...`` topics; see
docs/log-format.md); their float64 values come back bit-identical to what was written. A file
cut short (a killed writer) is read up to its last complete record and marked ``truncated``.

Why this module is long: it reads both formats (Rerun .rrd through pyarrow under checks,
rblog.record.safe_rrd; MCAP through the protobuf schemas) into one Trajectory with one channel table and one validation,
including what can be recovered from truncated and killed logs.
"""

from __future__ import annotations

import os
from dataclasses import fields
from pathlib import Path

import numpy as np

from rblog.errors import LogReadError
from rblog.contract.model import (IMPULSE_KINDS, WORK_KINDS, impulse_supplied_columns,
                                  work_supplied_columns)
from rblog.contract.trajectory import (BODY_CHANNELS, INTERVAL_CHANNELS, TOTAL_CHANNELS, Contacts,
                                       Trajectory)
from rblog.record import _common as C
from rblog.record import safe_rrd, validate

MCAP_MAGIC = b"\x89MCAP0\r\n"
RRD_MAGIC = b"RRF2"

_CONTACT_INT = {"step": np.int64, "body_a": np.int64, "body_b": np.int64, "kind": np.int8}
_CONTACT_VEC = ("point", "normal", "friction_impulse")


def load(path: str | os.PathLike) -> Trajectory:
    """Read a log written by rblog (or by any program following docs/log-format.md).

    Raises LogReadError (one line, naming the file) when the file is missing, is not a log of a
    known format, or holds no readable sample.
    """
    p = Path(path)
    if not p.exists():
        raise LogReadError(str(path), "no such file")
    if p.is_dir():
        raise LogReadError(str(path), "is a directory, not a log file")
    try:
        with open(p, "rb") as f:
            head = f.read(8)
    except OSError as e:
        raise LogReadError(str(path), e.strerror or str(e)) from None
    if not head:
        raise LogReadError(str(path), "empty file")
    if head.startswith(MCAP_MAGIC[: len(head)]) and len(head) == 8:
        return _load_mcap(p)
    if head.startswith(RRD_MAGIC):
        return _load_rrd(p)
    if p.suffix.lower() in (".mcap", ".rrd") and len(head) < 8:
        raise LogReadError(str(path), "file too short to hold a log")
    raise LogReadError(str(path), "not an MCAP or Rerun (.rrd) log (unrecognized file header)")


# --- assembling ---------------------------------------------------------------------------------

class _Collector:
    """Gathers static records, samples and contacts from either format and builds the result."""

    def __init__(self, path: Path):
        self.path = path
        self.run: dict[str, object] | None = None
        self.model: dict[str, object] | None = None
        self.status: dict[str, object] | None = None
        self.samples: dict[str, list[np.ndarray]] = {k: [] for k in ("step", "t", *C.SAMPLE_CHANNELS)}
        self.contacts: list[dict[str, np.ndarray]] = []
        self.cut: str | None = None  # why reading stopped early, if it did
        self.warnings: list[str] = []

    @property
    def model(self) -> dict[str, object] | None:
        """The run record's body table as flat arrays (the supplied tables of a log written
        before the integration / joint-work kinds widened to IMPULSE_KINDS / WORK_KINDS)."""
        return self._model

    @model.setter
    def model(self, m: dict[str, object] | None) -> None:
        for key, widen in (("body_impulse_supplied", impulse_supplied_columns),
                           ("body_work_supplied", work_supplied_columns)):
            if m is not None and m.get(key) is not None:
                m = {**m, key: widen(m[key], len(m.get("body_name", ()))).reshape(-1)}
        self._model = m

    def interval(self) -> tuple[str, ...]:
        """The per-interval channels the run record says the log holds (v3; () before)."""
        m = self.model or {}
        n = len(m.get("body_name", ()))
        out = []
        for key, kinds, names in (
                ("body_impulse_supplied", IMPULSE_KINDS,
                 [(f"impulse_{k}_linear", f"impulse_{k}_angular") for k in IMPULSE_KINDS]),
                ("body_work_supplied", WORK_KINDS, [(f"work_{k}",) for k in WORK_KINDS])):
            v = m.get(key)
            if v is None or not n or np.size(v) != n * len(kinds):
                continue
            on = (np.asarray(v).reshape(n, len(kinds)) == 1).any(axis=0)  # SUPPLIED_LOGGED
            out += [c for k, chans in zip(on, names) if k for c in chans]
        return tuple(out)

    def add_samples(self, cols: dict[str, np.ndarray], n: int) -> None:
        """cols: 'step' (R,), 't' (R,), each state channel (R, k) for R samples, and the run's
        per-interval channels (R, k)."""
        R = len(cols["step"])
        good = np.ones(R, bool)
        if np.shape(cols.get("t")) != (R,):
            good[:] = False
        for name in (*C.STATE_CHANNELS, *self.interval()):
            a = cols.get(name)
            if a is None or a.shape != (R, C.expected_width(name, n)):
                good[:] = False
        if not good.all():
            self.warnings.append(f"dropped {int((~good).sum())} sample(s) with missing or "
                                 "mis-sized channels")
            if not good.any():
                return
        for k in ("step", "t", *C.STATE_CHANNELS, *self.interval()):
            self.samples[k].append(np.asarray(cols[k])[good])

    def build(self) -> Trajectory:
        where = str(self.path)
        if self.run is None or self.model is None:
            if self.cut:
                raise LogReadError(where, f"no readable run record ({self.cut})")
            raise LogReadError(where, "no rblog run record: not a log written by rblog")
        validate.model_record(where, self.model)
        try:
            model = C.model_from_arrays(self.model)
            info = C.info_from_fields(self.run)
        except (KeyError, ValueError, TypeError) as e:
            raise LogReadError(where, f"malformed run record ({e})") from None
        n = model.n_bodies
        interval = self.interval()
        if self.samples["step"]:
            cat = {k: np.concatenate(v) for k, v in self.samples.items() if v}
        else:
            cat = {"step": np.zeros(0, np.int64), "t": np.zeros(0)}
            cat.update({k: np.zeros((0, C.expected_width(k, n)))
                        for k in (*C.STATE_CHANNELS, *interval)})
        order = np.argsort(cat["step"], kind="stable")
        T = len(order)
        kw = {"step": cat["step"][order].astype(np.int64), "t": cat["t"][order].astype(np.float64)}
        for name, shape in BODY_CHANNELS.items():
            kw[name] = cat[name][order].astype(np.float64, copy=False).reshape(T, n, *shape)
        for name, shape in TOTAL_CHANNELS.items():
            kw[name] = cat[name][order].astype(np.float64, copy=False).reshape(T, *shape)
        for name in interval:
            kw[name] = cat[name][order].astype(np.float64, copy=False).reshape(
                T, n, *INTERVAL_CHANNELS[name])
        truncated = False
        warns = list(self.warnings)
        if self.status is None:
            truncated = True
            why = self.cut or "the log has no end record"
            warns.insert(0, f"log ends early ({why}); the writer did not close it, read {T} samples")
        elif bool(self.status.get("truncated", False)):
            truncated = True
            reason = str(self.status.get("reason") or "")
            warns.insert(0, f"run ended early: {reason}" if reason else "run ended early")
        elif self.cut:  # the end record was read, so every sample was: only the index is hurt
            warns.insert(0, f"the log's index or footer is damaged ({self.cut}); all {T} samples "
                            "were read")
        if truncated and T == 0:
            raise LogReadError(where, "log ends before its first sample"
                               + (f" ({self.cut})" if self.cut else ""))
        if info.log_format > C.LOG_FORMAT_VERSION:
            warns.append(f"log follows contract version {info.log_format}, newer than this reader's "
                         f"{C.LOG_FORMAT_VERSION}; channels it does not know are ignored")
        validate.contact_records(where, self.contacts, n, "contacts (rblog/contacts, /rblog/contacts)")
        traj = Trajectory(model=model, info=info, contacts=self._contacts(), truncated=truncated,
                          warnings=warns, **kw)
        validate.trajectory(where, traj, "contacts (rblog/contacts, /rblog/contacts)")
        from rblog.analyze.consistency import consistency_warnings  # the checks on read

        traj.warnings.extend(consistency_warnings(traj))
        return traj

    def _contacts(self) -> Contacts:
        if not self.contacts:
            return Contacts.empty()
        kw = {}
        for f in fields(Contacts):
            a = np.concatenate([c[f.name] for c in self.contacts])
            if f.name in _CONTACT_INT:
                kw[f.name] = a.astype(_CONTACT_INT[f.name])
            elif f.name in _CONTACT_VEC:
                kw[f.name] = a.astype(np.float64, copy=False).reshape(-1, 3)
            else:
                kw[f.name] = a.astype(np.float64, copy=False)
        return Contacts(**kw)


# --- MCAP ---------------------------------------------------------------------------------------

def _load_mcap(path: Path) -> Trajectory:
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader
    from mcap_protobuf.decoder import DecoderFactory

    col = _Collector(path)
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    decoders: dict[int, object] = {}
    factory = DecoderFactory()
    state_rows: list = []
    n_bodies: int | None = None

    state_cls = None

    def flush_state():
        if state_rows and n_bodies is not None and state_cls is not None:
            col.add_samples(_decode_states(state_rows, state_cls), n_bodies)
        state_rows.clear()

    try:
        with open(path, "rb") as f:
            reader = StreamReader(f, validate_crcs=True)
            for rec in reader.records:
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec
                elif isinstance(rec, Channel):
                    channels[rec.id] = rec
                elif isinstance(rec, Message):
                    ch = channels.get(rec.channel_id)
                    sch = schemas.get(ch.schema_id) if ch else None
                    if sch is None or not sch.name.startswith("rblog."):
                        continue
                    dec = decoders.get(sch.id)
                    if dec is None:
                        dec = decoders[sch.id] = factory.decoder_for(ch.message_encoding, sch)
                    if dec is None:
                        continue
                    kind = sch.name[len("rblog."):]
                    if kind == "State":  # decoded in batches, see _decode_states
                        if state_cls is None:
                            state_cls = type(dec(b""))
                        state_rows.append(rec.data)
                        if len(state_rows) >= 4096:
                            flush_state()
                        continue
                    msg = dec(rec.data)
                    if kind == "Contacts":
                        col.contacts.append(_contacts_of(msg))
                    elif kind == "Run":
                        col.run, col.model = _run_of(msg)
                        n_bodies = len(col.model["body_name"])
                    elif kind == "Status":
                        col.status = {"complete": msg.complete, "truncated": msg.truncated,
                                      "reason": msg.reason}
    except Exception as e:  # noqa: BLE001 - any failure past the header means a cut/corrupt tail
        col.cut = _short(e, "the file is cut or corrupt after this point")
    with validate.decoding(str(path), "/rblog/state"):
        flush_state()
    if n_bodies is None and col.run is None and col.cut and not schemas:
        raise LogReadError(str(path), f"unreadable MCAP file ({col.cut})")
    return col.build()


def _short(e: BaseException, fallback: str) -> str:
    msg = str(e).strip().splitlines()[0] if str(e).strip() else ""
    name = type(e).__name__
    return f"{name}: {msg}"[:200] if msg else f"{name}: {fallback}"


def _decode_states(datas: list[bytes], cls) -> dict[str, np.ndarray]:
    """Decode serialized ``rblog.State`` messages into columns (R, width).

    Fast path: messages of equal length whose tags and lengths are byte-identical (what any
    encoder writing fixed-width fields produces) are stacked and sliced with numpy. Anything else
    goes through the protobuf runtime with the log's own schema.
    """
    fields_by_number = {f.number: f.name for f in cls.DESCRIPTOR.fields}
    by_len: dict[int, list[int]] = {}
    for i, d in enumerate(datas):
        by_len.setdefault(len(d), []).append(i)
    parts: list[tuple[np.ndarray, dict[str, np.ndarray]]] = []
    for length, idx in by_len.items():
        group = [datas[i] for i in idx]
        cols = _fast_states(group, fields_by_number) if length else None
        if cols is None:
            cols = _state_columns([cls.FromString(d) for d in group])
        parts.append((np.array(idx), cols))
    if len(parts) == 1:
        return parts[0][1]
    order = np.argsort(np.concatenate([p[0] for p in parts]), kind="stable")
    out = {}
    for name in parts[0][1]:
        pieces = [p[1].get(name, np.zeros((len(p[0]), 0))) for p in parts]
        if len({x.shape[1:] for x in pieces}) != 1:  # ragged across groups
            out[name] = np.zeros((len(order), 0))
        else:
            out[name] = np.concatenate(pieces)[order]
    return out


def _fast_states(group: list[bytes], fields_by_number: dict[int, str]) -> dict | None:
    layout = _wire_layout(group[0])
    if layout is None:
        return None
    L = len(group[0])
    structure = np.ones(L, bool)
    found: dict[str, tuple[int, int, int]] = {}
    for number, wire_type, off, size in layout:
        structure[off:off + size] = False
        name = fields_by_number.get(number)
        if name is None:
            continue
        if name in found:  # a repeated field written unpacked: use the slow path
            return None
        found[name] = (wire_type, off, size)
    needed = ("step", "t", *C.STATE_CHANNELS)
    if any(n not in found for n in needed):
        return None
    needed = (*needed, *(k for k in INTERVAL_CHANNELS if k in found))
    arr = np.frombuffer(b"".join(group), np.uint8).reshape(len(group), L)
    if not (arr[:, structure] == arr[0, structure]).all():
        return None
    cols: dict[str, np.ndarray] = {}
    for name in needed:
        wire_type, off, size = found[name]
        if size % 8 or wire_type not in (1, 2):
            return None
        block = np.ascontiguousarray(arr[:, off:off + size])
        dtype = "<i8" if name == "step" else "<f8"
        cols[name] = block.view(dtype).reshape(len(group), size // 8)
    cols["step"] = cols["step"].reshape(-1).astype(np.int64)
    cols["t"] = cols["t"].reshape(-1).astype(np.float64)
    for name in needed[2:]:
        cols[name] = cols[name].astype(np.float64)
    return cols


def _wire_layout(data: bytes) -> list[tuple[int, int, int, int]] | None:
    """Top-level fields of a protobuf message: (number, wire type, payload offset, payload size);
    None when the bytes do not parse."""
    out = []
    pos, end = 0, len(data)
    try:
        while pos < end:
            key, pos = safe_rrd.varint(data, pos)
            number, wire_type = key >> 3, key & 7
            if wire_type == 0:
                start = pos
                _, pos = safe_rrd.varint(data, pos)
                out.append((number, 0, start, pos - start))
            elif wire_type == 1:
                out.append((number, 1, pos, 8))
                pos += 8
            elif wire_type == 2:
                size, pos = safe_rrd.varint(data, pos)
                out.append((number, 2, pos, size))
                pos += size
            elif wire_type == 5:
                out.append((number, 5, pos, 4))
                pos += 4
            else:
                return None
    except (IndexError, safe_rrd.RrdFormatError):
        return None
    return out if pos == end else None


def _state_columns(rows: list) -> dict[str, np.ndarray]:
    cols: dict[str, np.ndarray] = {
        "step": np.array([m.step for m in rows], np.int64),
        "t": np.array([m.t for m in rows], np.float64),
        "total_energy": np.array([m.total_energy for m in rows], np.float64).reshape(-1, 1),
    }
    known = set(rows[0].DESCRIPTOR.fields_by_name) if rows else set()
    for name in C.SAMPLE_CHANNELS:
        if name == "total_energy" or name not in known:
            continue
        lists = [getattr(m, name) for m in rows]
        width = len(lists[0])
        if name in INTERVAL_CHANNELS and not any(len(x) for x in lists):
            continue  # not in this log
        if all(len(x) == width for x in lists):
            cols[name] = np.array(lists, np.float64).reshape(len(rows), width)
        else:  # ragged: let add_samples drop the whole batch with a warning
            cols[name] = np.zeros((len(rows), 0))
    return cols


def _contacts_of(msg) -> dict[str, np.ndarray]:
    k = len(msg.body_a)
    out = {
        "step": np.full(k, msg.step, np.int64),
        "t": np.full(k, msg.t, np.float64),
        "body_a": np.array(msg.body_a, np.int64),
        "body_b": np.array(msg.body_b, np.int64),
        "kind": np.array(msg.kind, np.int64),
    }
    for name in ("point", "normal", "separation", "normal_impulse", "friction_impulse"):
        out[name] = np.array(getattr(msg, name), np.float64)
    return out


def _run_of(msg) -> tuple[dict, dict]:
    run: dict[str, object] = {"rblog_log_format": msg.rblog_log_format}
    for name in C.INFO_FIELDS:
        if name == "seed":
            if msg.HasField("seed"):
                run["seed"] = msg.seed
        else:
            run[name] = getattr(msg, name, "")  # fields newer than the log's schema: absent
    model: dict[str, object] = {}
    known = set(msg.DESCRIPTOR.fields_by_name)
    v3 = int(msg.rblog_log_format) >= 3
    for name, (kind, _) in C.MODEL_FIELDS.items():
        if name not in known or (name in C.V3_MODEL_FIELDS and not v3):
            continue  # a v1/v2 log: the Model derives it
        v = getattr(msg, name)
        if name == "collide_rule":
            model[name] = str(v)
        elif kind == "s":
            model[name] = list(v)
        elif name in ("ground", "ground_offset", "ground_restitution", "ground_friction",
                      "collide_parent"):
            model[name] = np.array([v])
        else:
            model[name] = np.array(v, np.int64 if kind == "i" else bool if kind == "b"
                                   else np.float64)
    return run, model


# --- Rerun --------------------------------------------------------------------------------------

def _load_rrd(path: Path) -> Trajectory:
    col = _Collector(path)
    _read_rrd_into(col, path)
    return col.build()


def _read_rrd_into(col: _Collector, path: Path) -> None:
    # pyarrow under checks, not the SDK's Rust reader, which a corrupted payload can abort
    # (rblog/record/safe_rrd.py); a cut file is read up to its last complete message
    chunks, col.cut = safe_rrd.chunks(path, C.APPLICATION_ID)
    state: list[dict[str, np.ndarray]] = []
    for chunk in chunks:
        ent = chunk.entity_path.lstrip("/")
        if not ent.startswith("rblog/"):
            continue
        batch = chunk.batch
        comps = _components(batch) if ent != "rblog/state" else {}
        if ent == "rblog/run":
            col.run = {**(col.run or {}), **{k: _scalar(v[-1]) for k, v in comps.items()
                                             if v and v[-1] is not None and len(v[-1])}}
        elif ent == "rblog/model":
            col.model = {**(col.model or {}), **{k: v[-1] for k, v in comps.items()
                                                 if v and v[-1] is not None}}
        elif ent == "rblog/status":
            col.status = {k: _scalar(v[-1]) for k, v in comps.items() if v and v[-1] is not None}
        elif ent == "rblog/state":
            comps = _components(batch, flat=True)
            if "step" in batch.schema.names:
                comps["step"] = np.asarray(batch.column("step").to_numpy(), np.int64)
            state.append(comps)
        elif ent == "rblog/contacts":
            _rrd_contacts(col, comps)
    names = col.model.get("body_name") if col.model else None
    if not isinstance(names, list) or not names:
        return  # no body table to size the samples by: build() names what is missing
    n = len(names)
    for comps in state:
        col.add_samples(_rrd_state_columns(comps, n), n)


def _components(batch, flat: bool = False) -> dict[str, object]:
    """Data columns of a chunk, by component name: with ``flat``, (values, offsets, valid) numpy
    triples; otherwise one array (or list of str, or None) per row."""
    out: dict[str, object] = {}
    for i, field in enumerate(batch.schema):
        meta = field.metadata or {}
        if meta.get(b"rerun:kind") != b"data":
            continue
        name = (meta.get(b"rerun:component") or field.name.encode()).decode()
        name = name.rsplit(":", 1)[-1]
        out[name] = _flat(batch.column(i)) if flat else _rows(batch.column(i))
    return out


def _flat(column):
    """A list<T> column as (values, offsets, valid) numpy arrays."""
    import pyarrow as pa

    values = column.values
    if pa.types.is_string(values.type) or pa.types.is_large_string(values.type):
        flat = np.array(values.to_pylist(), dtype=object)
    else:
        flat = values.to_numpy(zero_copy_only=False)
    offsets = np.asarray(column.offsets.to_numpy(zero_copy_only=False), np.int64)
    valid = np.asarray(column.is_valid().to_numpy(zero_copy_only=False), bool)
    return flat, offsets, valid


def _rows(column) -> list:
    """A list<T> column as one numpy array (or list of str) per row; None for null rows."""
    flat, offsets, valid = _flat(column)
    if flat.dtype == object:
        flat = list(flat)
    return [flat[offsets[i]:offsets[i + 1]] if valid[i] else None for i in range(len(valid))]


def _scalar(v):
    if isinstance(v, list):
        return v[0] if v else None
    a = np.asarray(v)
    return a.reshape(-1)[0].item() if a.size else None


def _rrd_state_columns(comps: dict[str, object], n: int) -> dict[str, np.ndarray]:
    """(values, offsets, valid) per channel -> (R, width) arrays; a channel whose rows are not all
    present with the expected width becomes (R, 0) so that add_samples drops the rows."""
    step = comps.get("step")
    R = 0 if step is None else len(step)
    cols: dict[str, np.ndarray] = {"step": step if step is not None else np.zeros(0, np.int64)}
    for name in ("t", *C.SAMPLE_CHANNELS):
        if name in INTERVAL_CHANNELS and name not in comps:
            continue
        width = 1 if name == "t" else C.expected_width(name, n)
        got = comps.get(name)
        ok = got is not None
        if ok:
            values, offsets, valid = got
            ok = (len(valid) == R and bool(valid.all()) and len(offsets) == R + 1
                  and bool((np.diff(offsets) == width).all()) and values.dtype != object)
        if not ok:
            cols[name] = np.zeros((R, 0))
            continue
        cols[name] = values[offsets[0]:offsets[0] + R * width].astype(np.float64, copy=False) \
            .reshape(R, width)
    if cols["t"].shape[1:] == (1,):
        cols["t"] = cols["t"].reshape(-1)
    return cols


def _rrd_contacts(col: _Collector, comps: dict[str, list]) -> None:
    names = [f.name for f in fields(Contacts)]
    rows = len(comps.get("body_a", []))
    for i in range(rows):
        rec = {}
        for name in names:
            v = comps.get(name)
            if v is None or v[i] is None:
                break
            rec[name] = np.asarray(v[i])
        else:
            col.contacts.append(rec)
