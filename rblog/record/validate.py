"""The reader's boundary: every decoded channel checked against the contract (docs/log-format.md,
"The data" and "Fields with fixed values") before a Trajectory leaves the reader.

A log that frames and checksums correctly can still hold contents no writer following the
contract produces: a body table whose arrays disagree on N, contact rows whose arrays differ in
length, body indices out of range, rows of steps that have no sample, a message that is not the
protobuf its schema names. Each check raises :class:`~rblog.errors.LogReadError` naming the
channel, the record and what the contract expects, so that an analyzer never indexes out of
range and the CLI prints one line.

What is not checked here: the state channels' values (non-finite positions, a clock that runs
backwards, quaternions that disagree with the matrix). Those are findings about the run, reported
by rblog.analyze.consistency, not reasons to refuse the log.
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np

from rblog.contract.model import LOG_SHAPE_CODES
from rblog.contract.trajectory import CONTACT_IMPACT, CONTACT_RESTING, STATIC_BODY, Trajectory
from rblog.errors import LogReadError
from rblog.record import _common as C

#: model fields whose values must be finite numbers (materials may be NaN: unknown)
_FINITE_MODEL = ("body_size", "body_mass", "body_inertia_diag", "body_force_world",
                 "body_torque_world", "gravity", "ground_normal", "ground_offset",
                 "static_box_position", "static_box_quat_wxyz", "static_box_half_extents",
                 "joint_anchor_body", "joint_anchor_parent", "joint_axis_body",
                 "joint_axis_parent", "geom_pos_body", "geom_quat_wxyz_body", "geom_size",
                 "mesh_vert")
_MATERIALS = ("body_restitution", "body_friction", "ground_restitution", "ground_friction",
              "static_box_restitution", "static_box_friction", "geom_friction",
              "geom_restitution")
#: contact row fields: values per contact (1 or 3)
_CONTACT_WIDTH = {"step": 1, "t": 1, "body_a": 1, "body_b": 1, "kind": 1, "separation": 1,
                  "normal_impulse": 1, "point": 3, "normal": 3, "friction_impulse": 3}
_CONTACT_INTEGER = ("step", "body_a", "body_b", "kind")


def _numeric(path: str, where: str, v, integer: bool) -> np.ndarray:
    try:
        a = np.asarray(v)
    except (TypeError, ValueError):
        raise LogReadError(path, f"{where}: not an array of numbers") from None
    if a.dtype.kind not in ("iub" if integer else "iubf"):
        want = "integers" if integer else "numbers"
        raise LogReadError(path, f"{where}: holds {a.dtype} values, expected {want}")
    return a.reshape(-1)


#: integer model fields with a range: name -> (lowest, highest as f(N, table rows), what)
_CODES = {
    "body_kind": (0, lambda n, c: 3, "a body kind"),
    "body_parent": (-1, lambda n, c: n - 1, "a body index or -1 (world)"),
    "body_impulse_supplied": (0, lambda n, c: 2, "a supplied code"),
    "body_work_supplied": (0, lambda n, c: 2, "a supplied code"),
    "joint_type": (0, lambda n, c: 5, "a joint type"),
    "joint_body": (0, lambda n, c: n - 1, "a body index"),
    "geom_type": (0, lambda n, c: 6, "a geom type"),
    "geom_body": (-1, lambda n, c: n - 1, "a body index or -1 (world)"),
    "geom_vert_adr": (0, lambda n, c: max(c.get("mesh_vert", 0), 0), "a row of mesh_vert"),
    "geom_vert_num": (0, lambda n, c: c.get("mesh_vert", 0), "a count of mesh_vert rows"),
}


def _short_repr(v) -> str:
    r = repr(v)
    return r if len(r) <= 60 else r[:57] + "..."


def _table_of(name: str) -> str:
    """The table a model field's rows belong to: body, static_box, joint, geom or mesh_vert."""
    for prefix in ("body_", "static_box_", "joint_", "geom_"):
        if name.startswith(prefix):
            return prefix[:-1]
    return name


def _rows(path, where, name, table, size, width, counts, n):
    """``size`` values of ``width`` each: N for a body field; for another table the same row
    count as that table's other fields."""
    if table == "body":
        if size != n * width:
            raise LogReadError(path, f"{where}: {name} holds {size} values, expected "
                               f"{n * width} ({width} for each of {n} bodies)")
        return
    count, rest = divmod(size, width)
    known = counts.get(table)
    if rest or (known is not None and count != known):
        raise LogReadError(path, f"{where}: {name} holds {size} values, expected {width} per "
                           f"{table.replace('_', ' ')} row"
                           + (f" for {known} rows" if known is not None else ""))
    counts[table] = count


def model_record(path: str, model: dict) -> None:
    """The run record's body table as flat arrays (what ``_common.model_from_arrays`` takes):
    every field present that the contract requires, of its kind, N (or M) entries of its width,
    finite where a value is required, materials >= 0 or NaN (unknown)."""
    where = "run record (rblog/model, /rblog/run)"
    names = model.get("body_name")
    if names is None or isinstance(names, (str, bytes)) or len(names) == 0:
        raise LogReadError(path, f"{where}: body_name holds no body, expected N >= 1 names")
    if not all(isinstance(x, str) for x in names):
        raise LogReadError(path, f"{where}: body_name holds non-text values, expected N names")
    n = len(names)
    counts: dict[str, int] = {}  # rows of each table beside the bodies': static_box, joint, geom
    coded: dict[str, np.ndarray] = {}  # the fields of _CODES, checked once every count is known
    for name, (kind, shape) in C.MODEL_FIELDS.items():
        if name == "body_name":
            continue
        v = model.get(name)
        if v is None:
            if name.startswith("body_") and name not in C.V3_MODEL_FIELDS:
                raise LogReadError(path, f"{where}: {name} missing, expected {n} values")
            continue
        table = _table_of(name)
        if kind == "s":
            texts = [v] if isinstance(v, (str, bytes)) else list(np.asarray(v, object).reshape(-1))
            if not all(isinstance(x, str) for x in texts) or (shape is None and len(texts) != 1):
                raise LogReadError(path, f"{where}: {name} holds {_short_repr(v)}, expected "
                                   + ("one text" if shape is None else "a text per row"))
            if shape is not None:
                _rows(path, where, name, table, len(texts), 1, counts, n)
            continue
        a = _numeric(path, f"{where}: {name}", v, integer=kind in "ib")
        if shape is None:
            want = 3 if name in ("gravity", "ground_normal") else 1
            if a.size != want:
                raise LogReadError(path, f"{where}: {name} holds {a.size} values, expected {want}")
        else:
            _rows(path, where, name, table, a.size, int(np.prod(shape)) if shape else 1, counts, n)
        if name in _FINITE_MODEL and not np.isfinite(a).all():
            raise LogReadError(path, f"{where}: {name} holds {_first_bad(a)}, expected finite "
                               "numbers")
        if name in _MATERIALS and (np.isinf(a).any() or (a < 0).any()):
            raise LogReadError(path, f"{where}: {name} holds {_first_bad(a, a < 0)}, expected "
                               "numbers >= 0 (or NaN: unknown)")
        if name == "body_mass" and not (a > 0).all():
            raise LogReadError(path, f"{where}: body_mass holds {_first_bad(a, ~(a > 0))}, "
                               "expected positive masses (kg)")
        if name == "body_inertia_diag" and (a < 0).any():
            raise LogReadError(path, f"{where}: body_inertia_diag holds {_first_bad(a, a < 0)}, "
                               "expected moments >= 0 (kg m^2)")
        if name in _CODES:
            coded[name] = a
        if name == "body_shape" and not np.isin(a, list(LOG_SHAPE_CODES.values())).all():
            bad = a[~np.isin(a, list(LOG_SHAPE_CODES.values()))][0]
            raise LogReadError(path, f"{where}: body_shape holds {int(bad)}, expected 0 (sphere), "
                               "1 (box) or -1 (none)")

    for name, a in coded.items():
        lo, hi_of, what = _CODES[name]
        hi = hi_of(n, counts)
        if a.size and (a.min() < lo or a.max() > hi):
            bad = a[(a < lo) | (a > hi)][0]
            raise LogReadError(path, f"{where}: {name} holds {int(bad)}, expected {what} "
                               f"({lo}..{hi})")
    adr, num = coded.get("geom_vert_adr"), coded.get("geom_vert_num")
    if adr is not None and num is not None and adr.size == num.size and adr.size and \
            (adr + num).max() > counts.get("mesh_vert", 0):
        raise LogReadError(path, f"{where}: geom_vert_adr + geom_vert_num reach row "
                           f"{int((adr + num).max())}, past the {counts.get('mesh_vert', 0)} rows "
                           "of mesh_vert")

def _first_bad(a: np.ndarray, mask: np.ndarray | None = None) -> str:
    mask = ~np.isfinite(a) if mask is None else (mask | np.isinf(a))
    i = int(np.flatnonzero(mask)[0])
    return f"{a[i]!r} at index {i}"


def contact_records(path: str, records: list[dict], n_bodies: int, channel: str) -> None:
    """Each contact record (one message or row: the contacts of one step) before they are joined:
    its K contacts have K values of each scalar field and 3 K of point, normal and
    friction_impulse; body_a in 0..N-1, body_b in -1..N-1, kind 0 or 1; finite values. Checked
    field by field over all records at once (a log has one record per logged step)."""
    if not records:
        return
    for r, rec in enumerate(records):
        missing = next((f for f in _CONTACT_WIDTH if f not in rec), None) \
            if isinstance(rec, dict) else "body_a"
        if missing:
            raise LogReadError(path, f"{channel} record {r}: {missing} missing, expected the "
                               f"contact fields {', '.join(_CONTACT_WIDTH)}")
    k = np.array([np.size(rec["body_a"]) for rec in records])
    starts = np.concatenate([[0], np.cumsum(k)])
    joined = {}
    for name, width in _CONTACT_WIDTH.items():
        sizes = np.array([np.size(rec[name]) for rec in records])
        bad = np.flatnonzero(sizes != width * k)
        if len(bad):
            r = int(bad[0])
            raise LogReadError(path, f"{channel} record {r}: {name} holds {sizes[r]} values, "
                               f"expected {width * k[r]} ({width} for each of its {k[r]} contacts)")
        parts = [np.asarray(rec[name]).reshape(-1) for rec in records]
        a = _numeric(path, f"{channel}: {name}", np.concatenate(parts),
                     integer=name in _CONTACT_INTEGER)
        if a.dtype.kind == "f" and not np.isfinite(a).all():
            i = int(np.flatnonzero(~np.isfinite(a))[0])
            r = int(np.searchsorted(starts * width, i, "right") - 1)
            raise LogReadError(path, f"{channel} record {r}: {name} holds {a[i]!r}, expected "
                               "finite numbers")
        joined[name] = a
    for name, lo, want in (("body_a", 0, f"a body index 0..{n_bodies - 1}"),
                           ("body_b", STATIC_BODY, f"a body index 0..{n_bodies - 1} or -1 "
                                                   "(static geometry)"),
                           ("kind", CONTACT_RESTING, "0 (resting) or 1 (impact)")):
        a = joined[name]
        hi = CONTACT_IMPACT if name == "kind" else n_bodies - 1
        bad = np.flatnonzero((a < lo) | (a > hi))
        if len(bad):
            i = int(bad[0])
            r = int(np.searchsorted(starts, i, "right") - 1)
            raise LogReadError(path, f"{channel} record {r}: {name} holds {int(a[i])}, expected "
                               f"{want}")


def trajectory(path: str, traj: Trajectory, channel: str) -> None:
    """The assembled run: every contact row belongs to a logged sample's step. Rows past the last
    sample of a log cut short (their sample was lost with the tail) are dropped with a warning;
    anywhere else a row without its sample is an error."""
    c = traj.contacts
    if not len(c):
        return
    orphan = ~np.isin(c.step, traj.step)
    if not orphan.any():
        return
    last = traj.step[-1] if traj.n_samples else np.iinfo(np.int64).min
    if traj.truncated and (c.step[orphan] > last).all():
        traj.contacts = c.select(~orphan)
        traj.warnings.append(f"dropped {int(orphan.sum())} contact row(s) of steps after the last "
                             "sample (their samples were cut off)")
        return
    s = int(c.step[orphan][0])
    raise LogReadError(path, f"{channel}: a contact row of step {s} matches no sample's step "
                       "(expected rows only at logged steps)")


@contextmanager
def decoding(path: str, channel: str):
    """Messages of ``channel`` decoded inside: a payload its schema cannot parse is a
    LogReadError naming the channel (protobuf's DecodeError otherwise escapes the reader)."""
    from google.protobuf.message import DecodeError

    try:
        yield
    except DecodeError as e:
        raise LogReadError(path, f"{channel}: a message is not a valid protobuf of its schema "
                           f"({e})") from None
