"""What both log formats share: the static model and run metadata as flat named arrays, view
names, and simulated time in nanoseconds. See docs/log-format.md."""

from __future__ import annotations

import functools
import json
import math
import re

import numpy as np

from rblog.contract.model import (GEOM_FIELDS, IMPULSE_KINDS, INT_FIELDS, JOINT_FIELDS,
                                  WORK_KINDS, Model, quat_z_to)
from rblog.contract.trajectory import BODY_CHANNELS, INTERVAL_CHANNELS, TOTAL_CHANNELS, RunInfo

#: version of the log contract (docs/log-format.md) this module writes and reads
LOG_FORMAT_VERSION = 3
#: oldest contract version the reader accepts
LOG_FORMAT_OLDEST = 1
#: material combine rules a log may declare (RunInfo.combine_friction / combine_restitution)
COMBINE_RULES = ("geometric", "max", "min", "product", "mean")
#: Rerun application id of rblog recordings
APPLICATION_ID = "rblog"
#: length of a contact-force arrow in the Rerun view (m per N of mean force over the step)
CONTACT_ARROW_M_PER_N = 0.01

#: Model fields: name -> (kind, trailing shape per body / per static box, or None for a scalar)
#: kinds: "f" float64, "i" int64, "b" bool, "s" strings
MODEL_FIELDS: dict[str, tuple[str, tuple[int, ...] | None]] = {
    "body_name": ("s", ()),
    "body_shape": ("i", ()),
    "body_size": ("f", (3,)),
    "body_mass": ("f", ()),
    "body_inertia_diag": ("f", (3,)),
    "body_force_world": ("f", (3,)),
    "body_torque_world": ("f", (3,)),
    "body_restitution": ("f", ()),
    "body_friction": ("f", ()),
    "body_group": ("i", ()),
    "gravity": ("f", None),  # (3,)
    "ground": ("b", None),
    "ground_normal": ("f", None),  # (3,)
    "ground_offset": ("f", None),
    "ground_restitution": ("f", None),
    "ground_friction": ("f", None),
    "static_box_position": ("f", (3,)),
    "static_box_quat_wxyz": ("f", (4,)),
    "static_box_half_extents": ("f", (3,)),
    "static_box_restitution": ("f", ()),
    "static_box_friction": ("f", ()),
    # v3: bodies' kinds and parents, which impulses / works are supplied, joints, geoms
    "body_kind": ("i", ()),
    "body_parent": ("i", ()),
    "body_impulse_supplied": ("i", (len(IMPULSE_KINDS),)),
    "body_work_supplied": ("i", (len(WORK_KINDS),)),
    **{name: ("s" if name.endswith("_name") else "i" if name in INT_FIELDS else "f", trail)
       for name, trail in {**JOINT_FIELDS, **GEOM_FIELDS}.items()},
    "mesh_vert": ("f", (3,)),
    "collide_rule": ("s", None),
    "collide_parent": ("b", None),
}
_SCALAR_MODEL_FIELDS = ("ground", "ground_offset", "ground_restitution", "ground_friction",
                        "collide_rule", "collide_parent")
#: Model fields a v1/v2 log lacks (the Model derives them: rblog.contract.model)
V3_MODEL_FIELDS = tuple(list(MODEL_FIELDS)[list(MODEL_FIELDS).index("body_kind"):])

#: RunInfo fields as logged: name -> kind ("s", "f", "i"); scene_resolved travels as JSON text
INFO_FIELDS: dict[str, str] = {
    "integrator": "s",
    "orthonormalize": "s",
    "dt": "f",
    "log_every": "i",
    "duration_s": "f",
    "rblog_version": "s",
    "scene_path": "s",
    "scene_toml": "s",
    "scene_resolved_json": "s",
    "seed": "i",
    "writer": "s",
    "combine_friction": "s",
    "combine_restitution": "s",
    "engine_settings_json": "s",
}

STATE_CHANNELS = {**BODY_CHANNELS, **TOTAL_CHANNELS}
#: every per-sample channel a log may hold: the required state channels, then the optional
#: per-interval ones (contract v3)
SAMPLE_CHANNELS = {**STATE_CHANNELS, **INTERVAL_CHANNELS}


def model_to_arrays(model: Model) -> dict[str, object]:
    """Every Model field as a flat array (list of str for names; 1-element arrays for scalars)."""
    out: dict[str, object] = {}
    for name, (kind, shape) in MODEL_FIELDS.items():
        v = getattr(model, name)
        if name == "collide_rule":
            out[name] = str(v)
        elif kind == "s":
            out[name] = [str(x) for x in v]
        elif kind == "b":
            out[name] = np.array([bool(v)]) if shape is None else np.asarray(v, bool).reshape(-1)
        elif kind == "i":
            out[name] = np.asarray(v, np.int64).reshape(-1)
        else:
            out[name] = np.asarray(v, np.float64).reshape(-1)
    return out


def model_from_arrays(d: dict[str, object]) -> Model:
    """Rebuild a Model from flat arrays (missing static-box fields mean no static boxes;
    missing v3 fields are derived by the Model: a v1/v2 log)."""
    names = [str(x) for x in d["body_name"]]
    n = len(names)
    kw: dict[str, object] = {"body_name": names}
    for name, (kind, shape) in MODEL_FIELDS.items():
        if name == "body_name":
            continue
        v = d.get(name)
        if name in V3_MODEL_FIELDS and v is None:
            continue
        if name == "collide_rule":
            kw[name] = str(v[0] if isinstance(v, (list, tuple, np.ndarray)) else v)
            continue
        if name in _SCALAR_MODEL_FIELDS:
            if v is None:
                continue
            a = np.asarray(v).reshape(-1)
            kw[name] = bool(a[0]) if kind == "b" else float(a[0])
            continue
        if kind == "s":
            kw[name] = [str(x) for x in v]
            continue
        dtype = np.int64 if kind == "i" else bool if kind == "b" else np.float64
        if shape is None:  # gravity, ground_normal
            if v is not None:
                kw[name] = np.asarray(v, dtype).reshape(3)
            continue
        if v is None:
            if name.startswith("static_box"):
                kw[name] = np.zeros((0, *shape), dtype)
                continue
            raise KeyError(name)
        a = np.asarray(v, dtype)
        count = n if name.startswith("body_") else -1
        kw[name] = a.reshape(count, *shape)
    return Model(**kw)


def info_to_fields(info: RunInfo) -> dict[str, object]:
    """RunInfo as logged scalars (seed omitted when None)."""
    out: dict[str, object] = {
        "integrator": str(info.integrator),
        "orthonormalize": str(info.orthonormalize),
        "dt": float(info.dt),
        "log_every": int(info.log_every),
        "duration_s": float(info.duration_s),
        "rblog_version": str(info.rblog_version),
        "scene_path": str(info.scene_path),
        "scene_toml": str(info.scene_toml),
        "scene_resolved_json": json.dumps(info.scene_resolved, default=_json_default),
        "writer": str(info.writer),
        "combine_friction": str(info.combine_friction),
        "combine_restitution": str(info.combine_restitution),
        "engine_settings_json": json.dumps(info.engine_settings, default=_json_default),
    }
    if info.seed is not None:
        out["seed"] = int(info.seed)
    return out


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    return str(o)


def info_from_fields(d: dict[str, object]) -> RunInfo:
    resolved = d.get("scene_resolved_json") or "{}"
    try:
        scene_resolved = json.loads(resolved)
    except ValueError:
        scene_resolved = {}
    seed = d.get("seed")
    try:
        settings = json.loads(d.get("engine_settings_json") or "{}")
    except ValueError:
        settings = {}
    fmt = d.get("rblog_log_format")
    return RunInfo(
        integrator=str(d.get("integrator", "")),
        orthonormalize=str(d.get("orthonormalize", "")),
        dt=float(d.get("dt", 0.0)),
        log_every=int(d.get("log_every", 1)),
        duration_s=float(d.get("duration_s", 0.0)),
        rblog_version=str(d.get("rblog_version", "")),
        scene_path=str(d.get("scene_path", "")),
        scene_toml=str(d.get("scene_toml", "")),
        scene_resolved=scene_resolved if isinstance(scene_resolved, dict) else {},
        seed=None if seed is None else int(seed),
        writer=str(d.get("writer", "")),
        # v1 logs predate these fields: rblog's own rules, which v1 writers used
        combine_friction=str(d.get("combine_friction") or "geometric"),
        combine_restitution=str(d.get("combine_restitution") or "max"),
        engine_settings=settings if isinstance(settings, dict) else {},
        log_format=int(fmt) if fmt not in (None, "") else LOG_FORMAT_OLDEST,
    )


_BAD = re.compile(r"[^A-Za-z0-9_-]")


def view_names(names: list[str]) -> list[str]:
    """ASCII names for entity paths and frame ids: unique, ``[A-Za-z0-9_-]`` only."""
    out: list[str] = []
    seen: set[str] = set()
    for i, name in enumerate(names):
        v = _BAD.sub("_", str(name)) or f"body_{i}"
        if v in seen or v == "world":
            v = f"{v}_{i}"
        seen.add(v)
        out.append(v)
    return out


def time_ns(t: np.ndarray) -> np.ndarray:
    """Simulated time (s) as int64 nanoseconds for viewer timelines (rounded, clamped at 0)."""
    ns = np.rint(np.asarray(t, np.float64) * 1e9)
    nan = np.isnan(ns)
    if nan.any():
        ns = np.where(nan, 0.0, ns)
    return np.clip(ns, 0, 2**62).astype(np.int64)  # -inf -> 0, inf -> 2**62


def block_arrays(block, n: int, interval: tuple = (), copy: bool = True) -> dict[str, np.ndarray]:
    """The block's state channels, then its ``interval`` channels (the run's, in
    INTERVAL_CHANNELS order; NaN where the block lacks one), as contiguous float64 (T, k)
    arrays, k values per sample. ``copy=False``: a (T, k) or (T, N, m) float64 channel whose
    last axis is contiguous (a view of a wider array) is returned as it is, not copied.

    Raises ValueError when a channel does not hold the values ``n`` bodies need."""
    T = len(block.t)
    out = {}
    for name in (*STATE_CHANNELS, *interval):
        want = expected_width(name, n)
        v = getattr(block, name)
        if v is None:
            v = np.full((T, want), np.nan)
        a = np.asarray(v, np.float64)
        if copy or a.flags.c_contiguous or a.ndim not in (2, 3) or len(a) != T or \
                a.strides[-1] != 8:
            a = np.ascontiguousarray(a).reshape(T, -1)
        width = math.prod(a.shape[1:])
        if width != want:
            raise ValueError(f"{name}: {width} values per sample, expected {want} for {n} bodies")
        out[name] = a
    return out


@functools.lru_cache(maxsize=4096)
def expected_width(name: str, n: int) -> int:
    shape = SAMPLE_CHANNELS[name]
    k = math.prod(shape)
    return k if name in TOTAL_CHANNELS else k * n


def run_interval_channels(model: Model) -> tuple[str, ...]:
    """The INTERVAL_CHANNELS a run of ``model`` logs: the kinds some body supplies."""
    imp = (np.asarray(model.body_impulse_supplied) == 1).any(axis=0)  # SUPPLIED_LOGGED
    work = (np.asarray(model.body_work_supplied) == 1).any(axis=0)
    out = [f"impulse_{k}_{part}" for k, on in zip(IMPULSE_KINDS, imp) if on
           for part in ("linear", "angular")]
    out += [f"work_{k}" for k, on in zip(WORK_KINDS, work) if on]
    return tuple(out)


#: half thickness of the box drawn for the ground plane in the viewers (m)
GROUND_HALF_THICKNESS = 0.01


def ground_box(model: Model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A thin box whose top face is the ground plane, for the viewers.

    Returns (centre (3,), quat_wxyz (4,) rotating +z onto the ground normal, half extents (3,)).
    Its half width is 10 m or enough to hold the static boxes.
    """
    n = np.asarray(model.ground_normal, np.float64)
    n = n / (np.linalg.norm(n) or 1.0)
    center = n * (float(model.ground_offset) - GROUND_HALF_THICKNESS)
    reach = scene_reach(model)
    return center, quat_z_to(n), np.array([reach, reach, GROUND_HALF_THICKNESS])


def scene_reach(model: Model) -> float:
    """Half width of the viewers' drawing of an infinite plane (m): 10 m, or enough to hold the
    world's finite geoms."""
    reach = 10.0
    world = (np.asarray(model.geom_body) < 0) & (np.asarray(model.geom_type) != 6)
    if world.any():
        reach = max(reach, float(np.max(np.abs(model.geom_pos_body[world])
                                        + np.linalg.norm(model.geom_size[world], axis=1)[:, None])))
    return reach


def plane_box(model: Model, g: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A thin box (centre, quat_wxyz, half extents) in the geom's body frame whose top face is
    plane geom ``g`` (its size's half extents, or scene_reach for an infinite side)."""
    from rblog.contract.orientation import quat_wxyz_to_matrix

    q = np.asarray(model.geom_quat_wxyz_body[g], np.float64)
    nrm = quat_wxyz_to_matrix(q)[:, 2]
    center = np.asarray(model.geom_pos_body[g], np.float64) - GROUND_HALF_THICKNESS * nrm
    hx, hy = (float(v) for v in model.geom_size[g, :2])
    reach = scene_reach(model)
    return center, q, np.array([hx or reach, hy or reach, GROUND_HALF_THICKNESS])


def hull_triangles(vert: np.ndarray) -> np.ndarray | None:
    """(K, 3) int32 vertex indices of the convex hull's triangles of ``vert`` (V, 3), outward
    wound (scipy.spatial.ConvexHull); None without scipy or for a degenerate point set."""
    try:
        from scipy.spatial import ConvexHull, QhullError
    except ImportError:
        return None
    v = np.asarray(vert, np.float64)
    if len(v) < 4:
        return None
    try:
        hull = ConvexHull(v)
    except (QhullError, ValueError):
        return None
    tri = hull.simplices.astype(np.int32)
    centre = v.mean(axis=0)
    n = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])
    flip = np.einsum("ij,ij->i", n, v[tri[:, 0]] - centre) < 0
    tri[flip] = tri[flip][:, [0, 2, 1]]
    return tri


def geom_view_names(model: Model) -> list[str]:
    """Unique ``[A-Za-z0-9_-]`` names of the geoms (their names, else ``geom_<g>``)."""
    return view_names([n or f"geom_{g}" for g, n in enumerate(model.geom_name)])
