"""Type and value checks of the writer API's arguments (``rblog.Recorder``, ``rblog.body_table``):
an argument of the wrong type or value is a one-line ``RecordError`` naming it, its value and
what was expected, never a TypeError or ValueError from ``float()``, ``int()`` or ``dict()``.

Arrays (sizes, masses, loads) are checked where they are converted (recorder.py, ``arr``); this
module checks the arguments that are not arrays.
"""

from __future__ import annotations

import math
import os
from numbers import Integral, Real

import numpy as np

from rblog.contract.model import Model
from rblog.contract.trajectory import RunInfo
from rblog.errors import RblogError

#: what a material not given is: unknown (docs/log-format.md, "materials"), not judged
UNKNOWN_MATERIAL = math.nan


def _error(message: str) -> RblogError:
    from rblog.errors import RecordError

    return RecordError(message)


def _short(v) -> str:
    r = repr(v)
    return r if len(r) <= 60 else r[:57] + "..."


def number(v, what: str, *, positive=False, nonneg=False, allow_nan=False) -> float:
    """A real number (not a bool, not a string), finite unless ``allow_nan`` lets NaN through."""
    if isinstance(v, bool) or not isinstance(v, (Real, np.floating, np.integer)):
        raise _error(f"{what} = {_short(v)}, expected a number")
    x = float(v)
    if math.isnan(x) and allow_nan:
        return x
    if not math.isfinite(x):
        raise _error(f"{what} = {_short(v)}, expected a finite number")
    if positive and not x > 0:
        raise _error(f"{what} = {_short(v)}, expected a positive number")
    if nonneg and x < 0:
        raise _error(f"{what} = {_short(v)}, expected a number >= 0")
    return x


def integer(v, what: str, *, lo: int | None = None) -> int:
    if isinstance(v, bool) or not isinstance(v, (Integral, np.integer)):
        raise _error(f"{what} = {_short(v)}, expected an integer")
    if lo is not None and int(v) < lo:
        raise _error(f"{what} = {_short(v)}, expected an integer >= {lo}")
    return int(v)


def text(v, what: str) -> str:
    if not isinstance(v, str):
        raise _error(f"{what} = {_short(v)}, expected a string")
    return v


def flag(v, what: str) -> bool:
    if not isinstance(v, (bool, np.bool_)):
        raise _error(f"{what} = {_short(v)}, expected True or False")
    return bool(v)


def path_or_none(v, what: str):
    if v is not None and not isinstance(v, (str, os.PathLike)):
        raise _error(f"{what} = {_short(v)}, expected a file path (str or Path) or None")
    return v


def recorder(*, model, rrd, mcap, dt, writer, integrator, log_every, duration_s, engine_settings,
             scene_path, scene_toml, scene_resolved, seed, keep, info, mcap_compression, writers,
             fail_fast, combine_friction, combine_restitution) -> None:
    """Every argument of ``Recorder(...)`` but ``check`` (LiveAudit checks its own options); the
    combine rules' names are checked in recorder.py, their type here."""
    if model is not None and not isinstance(model, Model):
        raise _error(f"Recorder: model is a {type(model).__name__}, expected a Model "
                     "(rblog.body_table) or None")
    if info is not None and not isinstance(info, RunInfo):
        raise _error(f"Recorder: info is a {type(info).__name__}, expected a RunInfo or None")
    path_or_none(rrd, "Recorder: rrd")
    path_or_none(mcap, "Recorder: mcap")
    number(dt, "Recorder: dt", nonneg=True)
    integer(log_every, "Recorder: log_every", lo=1)
    number(duration_s, "Recorder: duration_s", nonneg=True)
    for v, what in ((writer, "writer"), (integrator, "integrator"), (scene_toml, "scene_toml"),
                    (mcap_compression, "mcap_compression"), (combine_friction, "combine_friction"),
                    (combine_restitution, "combine_restitution")):
        text(v, f"Recorder: {what}")
    if not isinstance(scene_path, (str, os.PathLike)):
        raise _error(f"Recorder: scene_path = {_short(scene_path)}, expected a path (str or Path)")
    for v, what in ((engine_settings, "engine_settings"), (scene_resolved, "scene_resolved")):
        if v is not None and not isinstance(v, dict):
            raise _error(f"Recorder: {what} = {_short(v)}, expected a dict (JSON-able) or None")
    if seed is not None:
        integer(seed, "Recorder: seed")
    if keep is not None:
        flag(keep, "Recorder: keep")
    flag(fail_fast, "Recorder: fail_fast")
    if writers is not None and not isinstance(writers, (list, tuple)):
        raise _error(f"Recorder: writers = {_short(writers)}, expected a list of recorders")


def body_table(*, name, shape, ground, ground_offset, ground_restitution, ground_friction) -> None:
    """The arguments of ``body_table(...)`` that are not converted to arrays there."""
    if isinstance(name, (str, bytes)) or not isinstance(name, (list, tuple, np.ndarray)):
        raise _error(f"body_table: name = {_short(name)}, expected a list of N names")
    if not all(isinstance(x, (str, np.str_)) for x in name):
        bad = next(x for x in name if not isinstance(x, (str, np.str_)))
        raise _error(f"body_table: name holds {_short(bad)}, expected N strings")
    if len(name) == 0:
        raise _error("body_table: name = [], expected at least one body")
    if shape is not None and (not isinstance(shape, (str, Integral, np.integer, list, tuple,
                                                     np.ndarray)) or isinstance(shape, bool)):
        raise _error(f"body_table: shape = {_short(shape)}, expected 'sphere', 'box', 'none' "
                     "(or 0, 1, -1), or a list of them (one per name)")
    flag(ground, "body_table: ground")
    number(ground_offset, "body_table: ground_offset")
    number(ground_restitution, "body_table: ground_restitution", nonneg=True, allow_nan=True)
    number(ground_friction, "body_table: ground_friction", nonneg=True, allow_nan=True)


def model_values(model: Model) -> None:
    """The body table's values: sizes, inertia >= 0 and finite; materials >= 0 or NaN (unknown);
    gravity, loads and the ground finite."""
    checks = (("size", model.body_size, False), ("inertia_diag", model.body_inertia_diag, False),
              ("force_world", model.body_force_world, None),
              ("torque_world", model.body_torque_world, None), ("gravity", model.gravity, None),
              ("ground_normal", model.ground_normal, None),
              ("restitution", model.body_restitution, True), ("friction", model.body_friction, True),
              ("static_box_position", model.static_box_position, None),
              ("static_box_half_extents", model.static_box_half_extents, False),
              ("static_box_restitution", model.static_box_restitution, True),
              ("static_box_friction", model.static_box_friction, True))
    for what, a, material in checks:
        a = np.asarray(a, float)
        bad = (np.isinf(a) if material else ~np.isfinite(a))
        if material is not None:
            bad |= a < 0
        if bad.any():
            i = np.unravel_index(int(np.flatnonzero(bad)[0]), a.shape)
            want = ("a number >= 0 or NaN (unknown)" if material else
                    "a finite number >= 0" if material is False else "a finite number")
            raise _error(f"body_table: {what}[{', '.join(map(str, i))}] = {a[i]!r}, expected {want}")
