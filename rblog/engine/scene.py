"""Scene files: TOML in, a validated :class:`Scene` (model + initial state + run settings) out.

Every value is checked up front. A mistake raises :class:`~rblog.errors.SceneError` whose message
names the file, the key path (``body[2].mass``) and what was expected. See README.md for the
format; SI units throughout.

Why this module is long: every key of the scene format is validated here, each with its own one-line
error naming the file, the key, the value and what was expected; the format has one home.
"""

from __future__ import annotations

import difflib
from collections import Counter
import math
import tomllib
from dataclasses import dataclass, field
from types import SimpleNamespace
from pathlib import Path
from typing import Any

import numpy as np

from rblog.errors import SceneError
from rblog.contract.model import (GEOM_CODES, SHAPE_BOX, SHAPE_CODES, SHAPE_NONE, SHAPE_SPHERE,
                                  Model, geoms_from_v2)
from rblog.engine.state import State
from rblog.engine.rotation import axis_angle_to_quat_np, quat_to_matrix_np
from rblog.engine.integrators import ORTHO_ALLOWED
from rblog.engine.constants import (
    BYTES_PER_BODY_ESTIMATE, MAX_BODIES, MAX_NESTING, MAX_RUN_STEPS, QUAT_MIN_NORM,
    QUAT_NORM_WARN_TOL,
)
from rblog.engine import mass_properties as mp
from rblog.engine import scene_checks

INTEGRATORS = tuple(ORTHO_ALLOWED)
#: the default integrator; chosen by benchmarks/bench_integrators.py (see benchmarks/RESULTS.md)
DEFAULT_INTEGRATOR = "rk4"

SIM_KEYS = {"dt", "duration", "gravity", "integrator", "orthonormalize", "seed", "log_every",
            "log_rate"}
GROUND_KEYS = {"height", "normal", "restitution", "friction"}
ORIENTATION_KEYS = ("quat_wxyz", "quat_xyzw", "axis_angle", "rotvec")
#: the shapes a [[body]] can have and the size keys each takes (m): a sphere's radius; a box's
#: half extents; a capsule's radius and half_length (the segment |z| <= half_length of the body's
#: z axis grown by radius: total length 2 half_length + 2 radius, the contract's and MuJoCo's
#: convention); a cylinder's radius and half_length (|z| <= half_length); a hull's vertices (a
#: list of [x, y, z], m) or mesh (a mesh file relative to the scene file), one of the two
#: (rblog.engine.hull: its body frame is its centre of mass and principal axes)
SHAPE_KEYS = {"sphere": ("radius",), "box": ("half_extents",),
              "capsule": ("radius", "half_length"), "cylinder": ("radius", "half_length"),
              "hull": ("vertices", "mesh")}
#: the shapes a compound body's part can have (a compound's ``parts``: a list of tables, each
#: a shape with its size keys, ``position`` (m) and an orientation in the body's scene frame)
PART_SHAPES = tuple(SHAPE_KEYS)
#: a compound body: several parts of one density (``mass`` or ``density``), one rigid body whose
#: frame is the parts' common centre of mass and principal axes (mass_properties)
SCENE_SHAPES = (*SHAPE_KEYS, "compound")
SIZE_KEYS = {"radius", "half_extents", "half_length", "vertices", "mesh"}
PART_KEYS = {"shape", *SIZE_KEYS, "position", *ORIENTATION_KEYS}
#: the contract's geom name of each scene shape (a hull is the contract's convex mesh)
SHAPE_GEOM = {"sphere": "sphere", "box": "box", "capsule": "capsule", "cylinder": "cylinder",
              "hull": "mesh"}
BODY_KEYS = {"name", "shape", "radius", "half_extents", "half_length", "vertices", "mesh", "parts",
             "mass", "density",
             "inertia_diag",
             "position", *ORIENTATION_KEYS, "velocity", "angular_velocity",
             "angular_velocity_body", "force", "torque", "restitution", "friction", "group"}
STATIC_BOX_KEYS = {"name", "position", *ORIENTATION_KEYS, "half_extents", "restitution",
                   "friction"}
GENERATOR_KEYS = {"layout", "count", "grid", "spacing", "origin", "region_min", "region_max",
                  "speed", "spin", "random_orientation", "name_prefix", "seed", "body"}
TOP_KEYS = {"sim", "ground", "body", "generator", "static_box", "contact"}

DEFAULT_RESTITUTION = 0.5
DEFAULT_FRICTION = 0.5


@dataclass
class SimParams:
    """Run settings from ``[sim]`` (CLI options override them)."""

    dt: float
    duration: float
    integrator: str = DEFAULT_INTEGRATOR
    orthonormalize: str | None = None  # None: the integrator's default
    seed: int = 0
    log_every: int | None = None
    log_rate: float | None = None

    @property
    def n_steps(self) -> int:
        return max(1, int(round(self.duration / self.dt)))


@dataclass
class Scene:
    """A validated scene.

    Attributes:
        path: the file.  toml_text: its text as given.
        model: fixed model.  state: initial state (t = 0).  sim: run settings.
        contact: the ``[contact]`` table as given (validated by the contact module).
        resolved: the scene after defaults and generators, JSON-able (logged with the run).
    """

    path: str
    toml_text: str
    model: Model
    state: State
    sim: SimParams
    contact: dict = field(default_factory=dict)
    resolved: dict = field(default_factory=dict)
    #: one-line warnings about values that were accepted but are probably mistakes
    warnings: list[str] = field(default_factory=list)

    def shape_counts(self) -> dict[str, int]:
        """Bodies per shape name (the contract's geom names; "compound" for a body of several
        geoms), in the order first seen."""
        from rblog.contract.model import GEOM_NAMES

        m = self.model
        gb = np.asarray(m.geom_body)
        parts = np.bincount(gb[gb >= 0], minlength=m.n_bodies)
        out: dict[str, int] = {}
        for g in np.flatnonzero(gb >= 0).tolist():
            b = int(gb[g])
            if parts[b] > 1 and g != int(np.flatnonzero(gb == b)[0]):
                continue  # a compound counts once
            name = "compound" if parts[b] > 1 else GEOM_NAMES[int(m.geom_type[g])]
            out[name] = out.get(name, 0) + 1
        return out


class _Ctx:
    """Carries the file name so every check can name it."""

    def __init__(self, path: str):
        self.path = path
        self.warnings: list[str] = []

    def fail(self, key: str, expected: str):
        raise SceneError(self.path, key, expected)

    def warn(self, key: str, what: str):
        self.warnings.append(f"{self.path}: {key}: {what}")

    def table(self, v, key) -> dict:
        if not isinstance(v, dict):
            self.fail(key, f"expected a table, got {_tname(v)}")
        return v

    def keys(self, d: dict, key: str, allowed: set):
        for k in d:
            if k not in allowed:
                where = f"{key}.{k}" if key else k
                close = difflib.get_close_matches(str(k), sorted(allowed), n=1, cutoff=0.6)
                hint = f"did you mean {close[0]!r}? " if close else ""
                self.fail(where, f"unknown key ({hint}expected one of: {', '.join(sorted(allowed))})")

    def num(self, v, key, *, positive=False, nonneg=False, lo=None, hi=None) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(key, f"expected a number, got {_tname(v)}")
        x = float(v)
        if not math.isfinite(x):
            self.fail(key, f"expected a finite number, got {v}")
        if positive and not x > 0:
            self.fail(key, f"expected a positive number, got {v}")
        if nonneg and x < 0:
            self.fail(key, f"expected a number >= 0, got {v}")
        if lo is not None and x < lo:
            self.fail(key, f"expected a number >= {lo}, got {v}")
        if hi is not None and x > hi:
            self.fail(key, f"expected a number <= {hi}, got {v}")
        return x

    def integer(self, v, key, *, lo=None) -> int:
        if isinstance(v, bool) or not isinstance(v, int):
            self.fail(key, f"expected an integer, got {_tname(v)}")
        if lo is not None and v < lo:
            self.fail(key, f"expected an integer >= {lo}, got {v}")
        return int(v)

    def vec(self, v, key, n=3, *, positive=False, nonneg=False) -> np.ndarray:
        if not isinstance(v, list) or len(v) != n:
            self.fail(key, f"expected a list of {n} numbers, got {_show(v)}")
        return np.array([self.num(x, f"{key}[{i}]", positive=positive, nonneg=nonneg)
                         for i, x in enumerate(v)])

    def string(self, v, key, choices=None) -> str:
        if not isinstance(v, str):
            self.fail(key, f"expected a string, got {_tname(v)}")
        if choices is not None and v not in choices:
            self.fail(key, f"expected one of {', '.join(choices)}, got {v!r}")
        return v

    def boolean(self, v, key) -> bool:
        if not isinstance(v, bool):
            self.fail(key, f"expected true or false, got {_tname(v)}")
        return v


def _tname(v) -> str:
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string",
            list: "a list", dict: "a table"}.get(type(v), type(v).__name__)


def _show(v) -> str:
    s = repr(v)
    return s if len(s) < 40 else s[:37] + "..."


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file. Raises SceneError (one line) on any problem."""
    path = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SceneError(path, "", "no such file") from None
    except IsADirectoryError:
        raise SceneError(path, "", "is a directory, expected a .toml scene file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise SceneError(path, "", f"cannot read: {e}") from None
    return parse_scene(text, path)


def parse_scene(text: str, path: str = "<scene>") -> Scene:
    """Validate scene TOML text. ``path`` is used in error messages."""
    try:
        # an overflow gives inf, which rblog.engine.scene_checks names; numpy need not warn
        with np.errstate(over="ignore", invalid="ignore"):
            return _parse_scene(text, path)
    except MemoryError:
        raise SceneError(path, "", "out of memory while building the scene (too many bodies "
                         "for this machine; see [[generator]] count/grid)") from None


def _parse_scene(text: str, path: str) -> Scene:
    ctx = _Ctx(path)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SceneError(path, "", f"not valid TOML: {e}") from None
    except RecursionError:
        raise SceneError(path, "", f"arrays or tables nested deeper than Python can parse "
                         f"(expected at most {MAX_NESTING} levels)") from None
    if scene_checks.nesting_depth(doc) > MAX_NESTING:
        ctx.fail("", f"arrays or tables nested more than {MAX_NESTING} levels deep (expected at "
                 f"most {MAX_NESTING})")
    ctx.keys(doc, "", TOP_KEYS)
    if "sim" not in doc:
        ctx.fail("sim", "missing table [sim] (needs at least dt and duration)")
    sim_t = ctx.table(doc["sim"], "sim")
    ctx.keys(sim_t, "sim", SIM_KEYS)
    for k in ("dt", "duration"):
        if k not in sim_t:
            ctx.fail(f"sim.{k}", "missing (a positive number of seconds)")
    sim = SimParams(
        dt=ctx.num(sim_t["dt"], "sim.dt", positive=True),
        duration=ctx.num(sim_t["duration"], "sim.duration", positive=True),
        integrator=ctx.string(sim_t.get("integrator", DEFAULT_INTEGRATOR), "sim.integrator",
                              INTEGRATORS),
        seed=ctx.integer(sim_t.get("seed", 0), "sim.seed", lo=0),
    )
    if sim.dt > sim.duration:
        ctx.fail("sim.dt", f"dt = {sim.dt:g} s is longer than the duration {sim.duration:g} s "
                 "(expected dt <= duration)")
    if sim.duration / sim.dt > MAX_RUN_STEPS:
        ctx.fail("sim.dt", f"dt = {sim.dt:g} s makes {sim.duration / sim.dt:.3g} steps for "
                 f"{sim.duration:g} s (expected at most {MAX_RUN_STEPS:.0e} steps)")
    if "orthonormalize" in sim_t:
        allowed, _ = ORTHO_ALLOWED[sim.integrator]
        sim.orthonormalize = ctx.string(sim_t["orthonormalize"], "sim.orthonormalize", allowed)
    if "log_every" in sim_t and "log_rate" in sim_t:
        ctx.fail("sim.log_rate", "give log_every or log_rate, not both")
    if "log_every" in sim_t:
        sim.log_every = ctx.integer(sim_t["log_every"], "sim.log_every", lo=1)
    if "log_rate" in sim_t:
        sim.log_rate = ctx.num(sim_t["log_rate"], "sim.log_rate", positive=True)
    gravity = ctx.vec(sim_t.get("gravity", [0.0, 0.0, -9.81]), "sim.gravity")

    resolved: dict[str, Any] = {
        "sim": {"dt": sim.dt, "duration": sim.duration, "gravity": gravity.tolist(),
                "integrator": sim.integrator, "orthonormalize": sim.orthonormalize,
                "seed": sim.seed, "log_every": sim.log_every, "log_rate": sim.log_rate},
    }

    # ground plane
    ground = "ground" in doc
    g_normal, g_offset, g_rest, g_fric = np.array([0.0, 0.0, 1.0]), 0.0, DEFAULT_RESTITUTION, DEFAULT_FRICTION
    if ground:
        gt = ctx.table(doc["ground"], "ground")
        ctx.keys(gt, "ground", GROUND_KEYS)
        g_normal = ctx.vec(gt.get("normal", [0.0, 0.0, 1.0]), "ground.normal")
        nn = np.linalg.norm(g_normal)
        if nn < 1e-12:
            ctx.fail("ground.normal", "expected a non-zero vector")
        g_normal = g_normal / nn
        g_offset = ctx.num(gt.get("height", 0.0), "ground.height")
        g_rest = ctx.num(gt.get("restitution", DEFAULT_RESTITUTION), "ground.restitution", lo=0.0, hi=1.0)
        g_fric = ctx.num(gt.get("friction", DEFAULT_FRICTION), "ground.friction", nonneg=True)
        resolved["ground"] = {"normal": g_normal.tolist(), "height": g_offset,
                              "restitution": g_rest, "friction": g_fric}

    # static boxes
    statics = []
    sb_list = doc.get("static_box", [])
    if not isinstance(sb_list, list):
        ctx.fail("static_box", "expected an array of tables [[static_box]]")
    for k, sb in enumerate(sb_list):
        key = f"static_box[{k}]"
        sb = ctx.table(sb, key)
        ctx.keys(sb, key, STATIC_BOX_KEYS)
        if "half_extents" not in sb:
            ctx.fail(f"{key}.half_extents", "missing (a list of 3 positive numbers, m)")
        statics.append({
            "name": ctx.string(sb.get("name", f"static{k}"), f"{key}.name"),
            "position": ctx.vec(sb.get("position", [0, 0, 0]), f"{key}.position"),
            "quat_wxyz": _orientation(ctx, sb, key),
            "half_extents": ctx.vec(sb["half_extents"], f"{key}.half_extents", positive=True),
            "restitution": ctx.num(sb.get("restitution", DEFAULT_RESTITUTION), f"{key}.restitution", lo=0.0, hi=1.0),
            "friction": ctx.num(sb.get("friction", DEFAULT_FRICTION), f"{key}.friction", nonneg=True),
        })

    # bodies, then generated bodies: each a _Bodies block of arrays (generators are expanded
    # straight into arrays, never into per-body dicts)
    blocks: list[_Bodies] = []
    explicit = []
    body_list = doc.get("body", [])
    if not isinstance(body_list, list):
        ctx.fail("body", "expected an array of tables [[body]]")
    for k, b in enumerate(body_list):
        explicit.append(_body(ctx, ctx.table(b, f"body[{k}]"), f"body[{k}]", f"body{k}"))
    if explicit:
        blocks.append(_Bodies.from_dicts(explicit))
    gen_list = doc.get("generator", [])
    if not isinstance(gen_list, list):
        ctx.fail("generator", "expected an array of tables [[generator]]")
    generators = []
    for k, g in enumerate(gen_list):
        block, gen_resolved = _generate(ctx, ctx.table(g, f"generator[{k}]"), f"generator[{k}]",
                                        sim.seed + k)
        blocks.append(block)
        generators.append(gen_resolved)
    if not blocks:
        ctx.fail("body", "the scene has no bodies (add [[body]] or [[generator]] tables)")
    names = [name for b in blocks for name in b.name]
    if len(set(names)) != len(names):
        counts = Counter(names)
        dup = next(n for n in names if counts[n] > 1)
        ctx.fail("body.name", f"names must be unique, {dup!r} is used twice")
    del names

    contact = {}
    if "contact" in doc:
        contact = _contact_table(ctx, ctx.table(doc["contact"], "contact"))

    model, state = _build(blocks, statics, gravity, ground, g_normal, g_offset, g_rest, g_fric)
    # what the values imply together (rblog.engine.scene_checks)
    scene_checks.check_log_stride(ctx, sim)
    scene_checks.check_state(ctx, model, state)
    scene_checks.check_memory(ctx, model, state, _available_memory())
    resolved["body"] = [_jsonable(b) for b in explicit]
    if generators:
        resolved["generator"] = generators
    resolved["static_box"] = [_jsonable(s) for s in statics]
    if contact:
        resolved["contact"] = contact
    return Scene(path, text, model, state, sim, contact, resolved, warnings=ctx.warnings)


def _contact_table(ctx: _Ctx, t: dict) -> dict:
    """Check ``[contact]`` against the contact solver's settings (rblog.engine.constants)."""
    from dataclasses import fields

    from rblog.engine.constants import CONTACT_SOLVERS, ContactParams

    defaults = ContactParams()
    known = {f.name for f in fields(ContactParams)}
    ctx.keys(t, "contact", known)
    out = {}
    for k, v in t.items():
        d = getattr(defaults, k)
        key = f"contact.{k}"
        if isinstance(d, bool):
            out[k] = ctx.boolean(v, key)
        elif isinstance(d, str):
            if not isinstance(v, str) or v not in CONTACT_SOLVERS:
                ctx.fail(key, f"expected {CONTACT_RANGES[k]}, got {v!r}")
            out[k] = v
        elif isinstance(d, int):
            out[k] = ctx.integer(v, key)
        else:
            out[k] = ctx.num(v, key)
    try:
        ContactParams(**out)
    except ValueError as e:
        bad = next((k for k in out if f"contact.{k} " in str(e) or f"contact.{k}" in str(e)), "")
        if bad:
            ctx.fail(f"contact.{bad}", f"expected {CONTACT_RANGES.get(bad, 'a value in range')}, "
                     f"got {out[bad]!r}")
        ctx.fail("contact", str(e))
    return out


#: the allowed range of each [contact] value, as ContactParams.validate checks it (the test
#: tests/engine/test_bad_input.py walks both so they cannot drift apart)
CONTACT_RANGES = {
    "velocity_iterations": "an integer >= 1",
    "max_velocity_iterations": "an integer >= 1",
    "velocity_tolerance": "a number >= 0 (m/s)",
    "over_relaxation": "a number in (0, 2)",
    "position_iterations": "an integer >= 0",
    "allowed_penetration": "a number >= 0 (m)",
    "position_correction_rate": "a number in (0, 1]",
    "max_correction_speed": "a number > 0 (m/s)",
    "speculative_distance": "a number >= 0 (m)",
    "restitution_threshold": "a number >= 0 (m/s)",
    "friction_anchor_distance": "a number >= 0 (m)",
    "sleep_speed": "a number >= 0 (m/s)",
    "sleep_time": "a number >= 0 (s)",
    "projection_iterations": "an integer >= 0",
    "projection_depth": "a number > 0 (m)",
    "solver": "one of \"pgs\", \"soft_step\"",
    "substeps": "an integer >= 1",
    "contact_hertz": "a number > 0 (Hz)",
    "contact_damping_ratio": "a number >= 0",
    "max_substep": "a number > 0 (s)",
}


def _orientation(ctx: _Ctx, d: dict, key: str) -> np.ndarray:
    given = [k for k in ORIENTATION_KEYS if k in d]
    if len(given) > 1:
        ctx.fail(f"{key}.{given[1]}", f"give one orientation, not both {given[0]} and {given[1]}")
    if not given:
        return np.array([1.0, 0.0, 0.0, 0.0])
    k = given[0]
    if k in ("quat_wxyz", "quat_xyzw"):
        q = ctx.vec(d[k], f"{key}.{k}", 4)
        if k == "quat_xyzw":
            q = q[[3, 0, 1, 2]]
        n = np.linalg.norm(q)
        if n < QUAT_MIN_NORM:
            ctx.fail(f"{key}.{k}", "expected a non-zero quaternion")
        if abs(n - 1.0) > QUAT_NORM_WARN_TOL:
            ctx.warn(f"{key}.{k}", f"|q| = {n:.6g}, not 1 (off by more than {QUAT_NORM_WARN_TOL:g});"
                     " normalised to unit length")
        q = q / n
    elif k == "rotvec":
        rv = ctx.vec(d[k], f"{key}.rotvec")
        ang = float(np.linalg.norm(rv))
        scene_checks.finite_angle(ctx, ang, f"{key}.rotvec")
        q = axis_angle_to_quat_np(rv, ang) if ang > 0 else np.array([1.0, 0, 0, 0])
    else:
        aa = ctx.table(d[k], f"{key}.axis_angle")
        ctx.keys(aa, f"{key}.axis_angle", {"axis", "angle_deg", "angle_rad"})
        if "axis" not in aa:
            ctx.fail(f"{key}.axis_angle.axis", "missing (a list of 3 numbers)")
        axis = ctx.vec(aa["axis"], f"{key}.axis_angle.axis")
        if np.linalg.norm(axis) < 1e-12:
            ctx.fail(f"{key}.axis_angle.axis", "expected a non-zero vector")
        if ("angle_deg" in aa) == ("angle_rad" in aa):
            ctx.fail(f"{key}.axis_angle", "expected exactly one of angle_deg, angle_rad")
        ang = (math.radians(ctx.num(aa["angle_deg"], f"{key}.axis_angle.angle_deg"))
               if "angle_deg" in aa else ctx.num(aa["angle_rad"], f"{key}.axis_angle.angle_rad"))
        q = axis_angle_to_quat_np(axis, ang)
    if q[0] < 0:
        q = -q
    return q


def _shape_size(ctx: _Ctx, b: dict, key: str, shape: str):
    """(size (3,) m, volume m^3, the Hull or None) of a body's or part's one shape, from its size
    keys (the others are refused by name)."""
    takes = SHAPE_KEYS[shape]
    joined = " or ".join(takes) if shape == "hull" else " and ".join(takes)
    for k in sorted(SIZE_KEYS - set(takes)):
        if k in b:
            ctx.fail(f"{key}.{k}", f"a {shape} takes {joined}, not {k}")
    hull = None
    if shape == "hull":
        hull = _hull(ctx, b, key)
    for k in takes if shape != "hull" else ():
        if k not in b:
            ctx.fail(f"{key}.{k}", "missing (" + ("a list of 3 positive numbers, m)"
                                                  if k == "half_extents" else "a positive number, m)"))
    if hull is not None:
        size = np.zeros(3)
        volume = hull.volume
    elif shape == "box":
        size = ctx.vec(b["half_extents"], f"{key}.half_extents", positive=True)
        volume = mp.box_volume(size)
    else:
        r = ctx.num(b["radius"], f"{key}.radius", positive=True)
        h = ctx.num(b["half_length"], f"{key}.half_length", positive=True) if "half_length" in takes else 0.0
        size = np.array([r, h, 0.0])
        volume = {"sphere": lambda: mp.sphere_volume(r), "capsule": lambda: mp.capsule_volume(r, h),
                  "cylinder": lambda: mp.cylinder_volume(r, h)}[shape]()
    return size, volume, hull


def _shape_inertia(shape: str, mass: float, size, hull) -> np.ndarray:
    """Principal moments (3,) kg m^2 of ``mass`` spread over one shape (mass_properties)."""
    if shape == "sphere":
        return mp.sphere_inertia(mass, size[0])
    if shape == "box":
        return mp.box_inertia(mass, size)
    if shape == "capsule":
        return mp.capsule_inertia(mass, size[0], size[1])
    if shape == "hull":
        return hull.inertia_diag(mass)
    return mp.cylinder_inertia(mass, size[0], size[1])


def _compound(ctx: _Ctx, b: dict, key: str):
    """A compound body's parts: (parts, volume m^3, com (3,), J (3, 3) kg m^2 per kg/m^3 about
    com, both in the body's scene frame). Each part: {"shape", "size", "hull", "volume",
    "com" (3,), "rot" (3, 3) its geom frame -> the scene frame, "origin" (3,) its geom origin}
    (mass_properties.compound_inertia_tensor: the parts' volumes summed, overlaps twice)."""
    k = f"{key}.parts"
    if "parts" not in b:
        ctx.fail(k, "missing (a list of part tables, e.g. parts = [{shape = \"sphere\", "
                 "radius = 0.1, position = [0, 0, 0.2]}, ...])")
    plist = b["parts"]
    if not isinstance(plist, list) or not plist:
        ctx.fail(k, f"expected a non-empty list of part tables, got {_show(plist)}")
    parts = []
    for n, pt in enumerate(plist):
        pk = f"{k}[{n}]"
        pt = ctx.table(pt, pk)
        ctx.keys(pt, pk, PART_KEYS)
        if "shape" not in pt:
            ctx.fail(f"{pk}.shape", f"missing (one of {', '.join(PART_SHAPES)})")
        shape = ctx.string(pt["shape"], f"{pk}.shape", PART_SHAPES)
        size, volume, hull = _shape_size(ctx, pt, pk, shape)
        pos = ctx.vec(pt.get("position", [0, 0, 0]), f"{pk}.position")
        rot = quat_to_matrix_np(_orientation(ctx, pt, pk)[None])[0]
        com, geom_rot = pos, rot
        if hull is not None:  # the hull's geom frame: its centre of mass and principal axes
            com, geom_rot = pos + rot @ hull.com, rot @ hull.axes
        parts.append({"shape": shape, "size": size, "hull": hull, "volume": volume,
                      "com": com, "rot": geom_rot})
    vols = np.array([q["volume"] for q in parts])
    tensors = [q["rot"] @ np.diag(_shape_inertia(q["shape"], q["volume"], q["size"], q["hull"]))
               @ q["rot"].T for q in parts]
    volume, com, tensor = mp.compound_inertia_tensor(vols, [q["com"] for q in parts], tensors)
    return parts, volume, com, tensor


def _body(ctx: _Ctx, b: dict, key: str, default_name: str) -> dict:
    ctx.keys(b, key, BODY_KEYS)
    if "shape" not in b:
        ctx.fail(f"{key}.shape", f"missing (one of {', '.join(SCENE_SHAPES)})")
    shape = ctx.string(b["shape"], f"{key}.shape", SCENE_SHAPES)
    hull = parts = None
    if shape == "compound":
        for k in sorted(SIZE_KEYS | {"inertia_diag"}):
            if k in b:
                ctx.fail(f"{key}.{k}", f"a compound takes parts (each with its shape and size), "
                         f"not {k}")
        parts, volume, com, tensor = _compound(ctx, b, key)
        size = np.zeros(3)
    else:
        if "parts" in b:
            ctx.fail(f"{key}.parts", f"only a compound takes parts, a {shape} takes "
                     + " and ".join(SHAPE_KEYS[shape]))
        size, volume, hull = _shape_size(ctx, b, key, shape)
    if ("mass" in b) == ("density" in b):
        ctx.fail(f"{key}.mass", "expected exactly one of mass (kg) or density (kg/m^3)")
    mass = (ctx.num(b["mass"], f"{key}.mass", positive=True) if "mass" in b
            else ctx.num(b["density"], f"{key}.density", positive=True) * volume)
    if "inertia_diag" in b:
        inertia = ctx.vec(b["inertia_diag"], f"{key}.inertia_diag", positive=True)
        i0, i1, i2 = sorted(inertia)
        if i2 > i0 + i1 + 1e-12 * i2:
            ctx.fail(f"{key}.inertia_diag", "principal moments must satisfy the triangle "
                     f"inequality (each <= sum of the others), got {inertia.tolist()}")
    elif not math.isfinite(mass):
        inertia = np.full(3, math.inf)  # check_body names the mass
    elif parts is not None:
        # principal moments of the parallel-axis sum; its axes become the body frame's
        inertia, axes = mp.principal_axes(tensor * (mass / volume))
    else:
        inertia = _shape_inertia(shape, mass, size, hull)
    q = _orientation(ctx, b, key)
    position = ctx.vec(b.get("position", [0, 0, 0]), f"{key}.position")
    frame = None  # (centre of mass, principal axes) in the scene's body frame, when not (0, 1)
    if hull is not None:
        # the body frame is the hull's centre of mass and principal axes (rblog.engine.hull)
        frame = hull.com, hull.axes
    elif parts is not None and math.isfinite(mass):
        frame = com, axes
    if frame is not None:
        from rblog.contract.orientation import matrix_to_quat, quat_mul

        position = position + quat_to_matrix_np(q[None])[0] @ frame[0]
        q = quat_mul(q, matrix_to_quat(frame[1]))
        q = q / np.linalg.norm(q)
        if q[0] < 0:
            q = -q
    if "angular_velocity" in b and "angular_velocity_body" in b:
        ctx.fail(f"{key}.angular_velocity_body", "give angular_velocity (world) or "
                 "angular_velocity_body, not both")
    out = {
        "name": ctx.string(b.get("name", default_name), f"{key}.name"),
        "shape": shape,
        "size": size,
        "mass": mass,
        "inertia_diag": inertia,
        "position": position,
        "quat_wxyz": q,
        "velocity": ctx.vec(b.get("velocity", [0, 0, 0]), f"{key}.velocity"),
        "angular_velocity": (ctx.vec(b["angular_velocity"], f"{key}.angular_velocity")
                             if "angular_velocity" in b else None),
        "angular_velocity_body": (ctx.vec(b["angular_velocity_body"], f"{key}.angular_velocity_body")
                                  if "angular_velocity_body" in b else None),
        "force": ctx.vec(b.get("force", [0, 0, 0]), f"{key}.force"),
        "torque": ctx.vec(b.get("torque", [0, 0, 0]), f"{key}.torque"),
        "restitution": ctx.num(b.get("restitution", DEFAULT_RESTITUTION), f"{key}.restitution", lo=0.0, hi=1.0),
        "friction": ctx.num(b.get("friction", DEFAULT_FRICTION), f"{key}.friction", nonneg=True),
        "group": ctx.integer(b.get("group", 0), f"{key}.group", lo=0),
    }
    if hull is not None:
        out["vertices"] = hull.vertices
    if parts is not None:
        out["parts"] = _part_geoms(parts, *(frame if frame is not None else (np.zeros(3), np.eye(3))))
    scene_checks.check_body(ctx, out, key)
    return out


def _part_geoms(parts, com, axes) -> list[dict]:
    """A compound's parts as geoms of its body frame (centre of mass ``com``, principal axes
    ``axes``, both in the scene's body frame): each {"shape", "size", "pos" (3,) m, "quat_wxyz"
    (4,) geom -> body, "vertices" (a hull's (V, 3) in its geom frame, else None)}:
    pos = Q^T (c_k - com), R = Q^T R_k."""
    from rblog.contract.orientation import matrix_to_quat

    out = []
    for q in parts:
        rot = axes.T @ q["rot"]
        quat = np.asarray(matrix_to_quat(rot), float)
        quat = quat / np.linalg.norm(quat)
        if quat[0] < 0:
            quat = -quat
        out.append({"shape": q["shape"], "size": np.asarray(q["size"], float),
                    "pos": axes.T @ (q["com"] - com), "quat_wxyz": quat,
                    "vertices": None if q["hull"] is None else q["hull"].vertices})
    return out


def _hull(ctx: _Ctx, b: dict, key: str):
    """The rblog.engine.hull.Hull of a hull body's ``vertices`` or ``mesh`` (one of the two)."""
    from rblog.engine.hull import build_hull, read_mesh_vertices

    if ("vertices" in b) == ("mesh" in b):
        ctx.fail(f"{key}.vertices", "expected exactly one of vertices (a list of [x, y, z], m) "
                 "or mesh (a mesh file relative to the scene file)")
    if "vertices" in b:
        k = f"{key}.vertices"
        v = b["vertices"]
        if not isinstance(v, list):
            ctx.fail(k, f"expected a list of [x, y, z] points (m), got {_tname(v)}")
        pts = np.array([ctx.vec(p, f"{k}[{i}]") for i, p in enumerate(v)]).reshape(-1, 3)
    else:
        k = f"{key}.mesh"
        name = ctx.string(b["mesh"], k)
        base = Path(ctx.path).parent if not ctx.path.startswith("<") else Path(".")
        pts = read_mesh_vertices(base / name, lambda e: ctx.fail(k, e))
    return build_hull(pts, lambda e: ctx.fail(k, e))


def _check_body_count(ctx: _Ctx, key: str, n: int):
    """Refuse a generator that asks for more bodies than MAX_BODIES or than memory can hold,
    saying how much memory it would need (instead of a MemoryError half-way)."""
    need = n * BYTES_PER_BODY_ESTIMATE
    avail = _available_memory()
    if n > MAX_BODIES or (avail is not None and need > avail):
        have = f", {avail / 1e9:.3g} GB available" if avail is not None else ""
        ctx.fail(key, f"{n:,} bodies need about {need / 1e9:.3g} GB of memory{have} "
                 f"(expected at most {MAX_BODIES:,} bodies that fit in memory)")


def _available_memory() -> int | None:
    """Bytes of memory available now (Linux /proc/meminfo), or None when unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def _random_unit(rng, n) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _generate(ctx: _Ctx, g: dict, key: str, default_seed: int) -> tuple["_Bodies", dict]:
    """Expand a [[generator]] table into a block of bodies (grid or seeded random layout), as
    arrays: the template body is validated once, and the per-body values (position, velocity,
    spin, orientation) are drawn for all bodies at once. Returns (bodies, the generator as
    resolved: its layout, seed and template body after defaults, and its bodies' position bounds),
    which is what the log's resolved scene keeps of it (the bodies themselves follow from it)."""
    ctx.keys(g, key, GENERATOR_KEYS)
    layout = ctx.string(g.get("layout", "grid"), f"{key}.layout", ("grid", "random"))
    template = dict(ctx.table(g.get("body", {}), f"{key}.body"))
    if "name" in template:
        ctx.fail(f"{key}.body.name", "generated bodies are named from name_prefix")
    prefix = ctx.string(g.get("name_prefix", f"g{key[10:-1]}_"), f"{key}.name_prefix")
    seed = ctx.integer(g.get("seed", default_seed), f"{key}.seed", lo=0)
    rng = np.random.default_rng(seed)
    out_g: dict[str, Any] = {"layout": layout}
    if layout == "grid":
        if "grid" not in g:
            ctx.fail(f"{key}.grid", "missing (a list of 3 counts [nx, ny, nz])")
        gr = g["grid"]
        if not isinstance(gr, list) or len(gr) != 3:
            ctx.fail(f"{key}.grid", f"expected a list of 3 integers, got {_show(gr)}")
        counts = [ctx.integer(c, f"{key}.grid[{i}]", lo=1) for i, c in enumerate(gr)]
        _check_body_count(ctx, f"{key}.grid", counts[0] * counts[1] * counts[2])
        if "count" in g:
            ctx.fail(f"{key}.count", "a grid layout takes grid = [nx, ny, nz], not count")
        sp = g.get("spacing", 1.0)
        spacing = (np.full(3, ctx.num(sp, f"{key}.spacing", positive=True))
                   if not isinstance(sp, list) else ctx.vec(sp, f"{key}.spacing", nonneg=True))
        origin = ctx.vec(g.get("origin", [0, 0, 0]), f"{key}.origin")
        idx = np.stack(np.meshgrid(*[np.arange(c) for c in counts], indexing="ij"), -1).reshape(-1, 3)
        positions = origin + idx * spacing
        del idx
        for k in ("region_min", "region_max"):
            if k in g:
                ctx.fail(f"{key}.{k}", "only for layout = \"random\"")
        out_g.update(grid=counts, spacing=spacing.tolist(), origin=origin.tolist())
    else:
        if "count" not in g:
            ctx.fail(f"{key}.count", "missing (number of bodies)")
        n = ctx.integer(g["count"], f"{key}.count", lo=1)
        _check_body_count(ctx, f"{key}.count", n)
        for k in ("region_min", "region_max"):
            if k not in g:
                ctx.fail(f"{key}.{k}", "missing (a list of 3 numbers, m)")
        lo = ctx.vec(g["region_min"], f"{key}.region_min")
        hi = ctx.vec(g["region_max"], f"{key}.region_max")
        if np.any(hi < lo):
            ctx.fail(f"{key}.region_max", "expected region_max >= region_min component-wise")
        positions = lo + rng.random((n, 3)) * (hi - lo)
        for k in ("grid", "spacing", "origin"):
            if k in g:
                ctx.fail(f"{key}.{k}", "only for layout = \"grid\"")
        out_g.update(count=n, region_min=lo.tolist(), region_max=hi.tolist())
    n = len(positions)
    speed = _range(ctx, g, "speed", key)
    spin = _range(ctx, g, "spin", key)
    rand_orient = ctx.boolean(g.get("random_orientation", False), f"{key}.random_orientation")
    vdir = _random_unit(rng, n)
    vmag = rng.uniform(*speed, size=n) if speed else np.zeros(n)
    wdir = _random_unit(rng, n)
    wmag = rng.uniform(*spin, size=n) if spin else np.zeros(n)
    quats = rng.normal(size=(n, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)

    # the template, validated once, as each generated body's table is (a name and a position
    # from the generator; with random_orientation, no orientation of its own)
    b = dict(template)
    b["name"] = f"{prefix}0"
    b["position"] = [0.0, 0.0, 0.0]
    if rand_orient:
        for k in ORIENTATION_KEYS:
            b.pop(k, None)
    tb = _body(ctx, b, f"{key}.body", b["name"])
    bad = np.argwhere(~np.isfinite(positions))
    if len(bad):  # a grid or region so far out that it overflows
        i, j = bad[0]
        ctx.num(float(positions[i, j]), f"{key}.body.position[{j}]")
    body = _Bodies.from_dicts([tb], repeat=n)
    body.name = [f"{prefix}{i}" for i in range(n)]
    body.position = positions
    if rand_orient:
        # as _orientation treats a given quaternion: divided by its norm, w >= 0 (the norm as
        # np.linalg.norm takes it, a dot product, for the same bits as one body at a time)
        norm = np.sqrt(np.matmul(quats[:, None, :], quats[:, :, None])[:, 0, 0])
        if np.any(norm < QUAT_MIN_NORM):  # pragma: no cover - normal draws are never all ~0
            ctx.fail(f"{key}.body.quat_wxyz", "expected a non-zero quaternion")
        q = quats / norm[:, None]
        q[q[:, 0] < 0] *= -1.0
        body.quat = q
    del quats
    if speed:
        body.velocity = body.velocity + vmag[:, None] * vdir
    if spin:
        base = body.omega.copy()
        in_body = body.omega_frame == _OMEGA_BODY
        if np.any(in_body):
            base[in_body] = _rotate(quat_to_matrix_np(body.quat[in_body]), body.omega[in_body])
        body.omega = base + wmag[:, None] * wdir
        body.omega_frame = np.full(n, _OMEGA_WORLD, np.int8)
    lo_p, hi_p = positions.min(axis=0), positions.max(axis=0)
    tb_json = _jsonable(tb)
    for k in ("name", "position"):
        tb_json.pop(k)
    if rand_orient:
        tb_json.pop("quat_wxyz")
    out_g.update(seed=seed, name_prefix=prefix, speed=list(speed) if speed else None,
                 spin=list(spin) if spin else None, random_orientation=rand_orient,
                 body=tb_json, n_bodies=n, position_bounds=[lo_p.tolist(), hi_p.tolist()])
    return body, out_g


def _rotate(rot: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(n, 3, 3) @ (n, 3) -> (n, 3), each product as ``rot[i] @ v[i]`` computes it."""
    return np.matmul(rot, v[:, :, None])[:, :, 0]


def _jsonable(d: dict) -> dict:
    def one(v):
        if isinstance(v, np.ndarray):
            return v.tolist()
        if isinstance(v, list) and v and isinstance(v[0], dict):  # a compound's parts
            return [_jsonable(q) for q in v]
        return v
    return {k: one(v) for k, v in d.items()}


#: frame of a body's given angular velocity (_Bodies.omega_frame): none given, world, body
_OMEGA_NONE, _OMEGA_WORLD, _OMEGA_BODY = 0, 1, 2


@dataclass
class _Bodies:
    """A block of validated bodies as arrays (N first): the [[body]] tables, or one generator's
    bodies. ``omega`` is the given angular velocity (rad/s) in the frame ``omega_frame`` names
    (_OMEGA_*; zero when none was given); the rest as in :class:`Model` and :class:`State`."""

    name: list
    shape: np.ndarray        # (n,) int64 body_shape codes (SHAPE_NONE: capsule, cylinder,
                             # hull, compound)
    size: np.ndarray         # (n, 3)
    mass: np.ndarray         # (n,)
    inertia: np.ndarray      # (n, 3)
    position: np.ndarray     # (n, 3)
    quat: np.ndarray         # (n, 4) wxyz
    velocity: np.ndarray     # (n, 3)
    omega: np.ndarray        # (n, 3)
    omega_frame: np.ndarray  # (n,) int8
    force: np.ndarray        # (n, 3)
    torque: np.ndarray       # (n, 3)
    restitution: np.ndarray  # (n,)
    friction: np.ndarray     # (n,)
    group: np.ndarray        # (n,) int64
    geoms: list              # (n,) a SHAPE_NONE body's geoms (_body_geoms), else None

    @classmethod
    def from_dicts(cls, bodies: list[dict], repeat: int = 1) -> "_Bodies":
        """From _body's dicts (each ``repeat`` times: a generator's template)."""
        def col(k, dtype=float):
            a = np.array([b[k] for b in bodies], dtype=dtype)
            return np.repeat(a, repeat, axis=0) if repeat != 1 else a

        omega = np.zeros((len(bodies), 3))
        frame = np.zeros(len(bodies), np.int8)
        for i, b in enumerate(bodies):
            if b["angular_velocity"] is not None:
                omega[i], frame[i] = b["angular_velocity"], _OMEGA_WORLD
            elif b["angular_velocity_body"] is not None:
                omega[i], frame[i] = b["angular_velocity_body"], _OMEGA_BODY
        if repeat != 1:
            omega, frame = np.repeat(omega, repeat, axis=0), np.repeat(frame, repeat)
        return cls(
            name=[b["name"] for b in bodies] * repeat,
            shape=np.repeat(np.array([SHAPE_CODES.get(b["shape"], SHAPE_NONE) for b in bodies],
                                     np.int64), repeat),
            size=col("size"), mass=col("mass"), inertia=col("inertia_diag"),
            position=col("position"), quat=col("quat_wxyz"), velocity=col("velocity"),
            omega=omega, omega_frame=frame, force=col("force"), torque=col("torque"),
            restitution=col("restitution"), friction=col("friction"),
            group=col("group", np.int64),
            geoms=[_body_geoms(b) for b in bodies for _ in range(repeat)])


def _body_geoms(b: dict) -> list[dict] | None:
    """The geoms of a body dict from _body whose shape the v2 fields cannot say (None for a
    sphere or box): a compound's parts, else its one shape in the body frame. Each {"type" the
    contract's GEOM_* code, "size" (3,), "pos" (3,), "quat_wxyz" (4,), "vertices" or None}."""
    if b["shape"] in ("sphere", "box"):
        return None
    if b["shape"] == "compound":
        return [{"type": GEOM_CODES[SHAPE_GEOM[q["shape"]]], "size": q["size"], "pos": q["pos"],
                 "quat_wxyz": q["quat_wxyz"], "vertices": q["vertices"]} for q in b["parts"]]
    return [{"type": GEOM_CODES[SHAPE_GEOM[b["shape"]]], "size": np.asarray(b["size"], float),
             "pos": np.zeros(3), "quat_wxyz": np.array([1.0, 0.0, 0.0, 0.0]),
             "vertices": b.get("vertices")}]


def _range(ctx, g, k, key):
    if k not in g:
        return None
    v = g[k]
    if not isinstance(v, list) or len(v) != 2:
        ctx.fail(f"{key}.{k}", f"expected [min, max], got {_show(v)}")
    lo = ctx.num(v[0], f"{key}.{k}[0]", nonneg=True)
    hi = ctx.num(v[1], f"{key}.{k}[1]", nonneg=True)
    if hi < lo:
        ctx.fail(f"{key}.{k}", "expected [min, max] with min <= max")
    return lo, hi


def _build(blocks: list[_Bodies], statics, gravity, ground, g_normal, g_offset, g_rest, g_fric):
    def col(k):
        return np.concatenate([getattr(b, k) for b in blocks], axis=0)

    mass = col("mass")
    inertia = col("inertia")
    quat = col("quat")
    rot = quat_to_matrix_np(quat)
    omega = col("omega")
    frame = col("omega_frame")
    omega[frame == _OMEGA_NONE] = 0.0
    in_body = np.flatnonzero(frame == _OMEGA_BODY)
    if len(in_body):
        omega[in_body] = _rotate(rot[in_body], omega[in_body])
    # L = R I_body R^T omega  (world frame)
    l_world = np.einsum("nij,nj->ni", rot, inertia * np.einsum("nji,nj->ni", rot, omega))
    del omega
    shape, size = col("shape"), col("size")
    statics_kw = dict(
        static_box_position=np.array([s["position"] for s in statics], float).reshape(-1, 3),
        static_box_quat_wxyz=np.array([s["quat_wxyz"] for s in statics], float).reshape(-1, 4),
        static_box_half_extents=np.array([s["half_extents"] for s in statics], float).reshape(-1, 3),
        static_box_restitution=np.array([s["restitution"] for s in statics], float),
        static_box_friction=np.array([s["friction"] for s in statics], float),
    )
    geoms = {}
    if np.any(shape == SHAPE_NONE):
        # a capsule, cylinder, hull or compound: the v2 fields cannot say what it is (body_shape
        # "none", size 0), the geom table does: each body's geoms (one at the centre of mass, a
        # compound's parts at their poses), then the ground and the static boxes, in the order
        # geoms_from_v2 gives a sphere-and-box scene
        names = [name for b in blocks for name in b.name]
        world = SimpleNamespace(
            body_shape=np.zeros(len(shape), np.int64), body_size=size,
            body_name=names, body_group=col("group"),
            body_friction=col("friction"), body_restitution=col("restitution"), ground=ground,
            ground_normal=np.asarray(g_normal, float), ground_offset=float(g_offset),
            ground_friction=float(g_fric), ground_restitution=float(g_rest), **statics_kw)
        v2 = geoms_from_v2(world)
        n = len(shape)
        per_body = [gl for blk in blocks for gl in blk.geoms]
        src, rows = [], []
        for i, gl in enumerate(per_body):
            if gl is None:  # a sphere or box: its v2 geom
                rows.append({"type": int(GEOM_CODES["sphere" if shape[i] == SHAPE_SPHERE else "box"]),
                             "size": size[i], "pos": np.zeros(3),
                             "quat_wxyz": np.array([1.0, 0.0, 0.0, 0.0]), "vertices": None})
                src.append(i)
            else:
                rows.extend(gl)
                src.extend([i] * len(gl))
        src = np.asarray(src, np.int64)
        many = np.bincount(src, minlength=n) > 1
        geoms = {k: (np.concatenate([np.asarray(v[:n])[src], np.asarray(v[n:])])
                     if k != "geom_name" else None) for k, v in v2.items()}
        part = np.zeros(len(src), np.int64)
        for r in range(1, len(src)):
            part[r] = part[r - 1] + 1 if src[r] == src[r - 1] else 0
        geoms["geom_name"] = [f"{names[i]}_part{part[r]}" if many[i] else names[i]
                              for r, i in enumerate(src.tolist())] + list(v2["geom_name"][n:])
        G = len(rows)
        geoms["geom_type"][:G] = [q["type"] for q in rows]
        geoms["geom_pos_body"][:G] = [q["pos"] for q in rows]
        geoms["geom_quat_wxyz_body"][:G] = [q["quat_wxyz"] for q in rows]
        geoms["geom_size"][:G] = [q["size"] for q in rows]
        # a hull's vertices (its geom frame), its size row 0
        nv = np.array([0 if q["vertices"] is None else len(q["vertices"]) for q in rows], np.int64)
        if nv.any():
            geoms["geom_vert_num"][:G] = nv
            geoms["geom_vert_adr"][:G] = np.cumsum(nv) - nv
            geoms["geom_size"][:G][nv > 0] = 0.0
            geoms["mesh_vert"] = np.concatenate([q["vertices"] for q in rows
                                                 if q["vertices"] is not None], axis=0)
        size = np.where((shape == SHAPE_NONE)[:, None], 0.0, size)
    model = Model(
        body_name=[name for b in blocks for name in b.name],
        body_shape=shape,
        body_size=size,
        body_mass=mass,
        body_inertia_diag=inertia,
        body_force_world=col("force"),
        body_torque_world=col("torque"),
        body_restitution=col("restitution"),
        body_friction=col("friction"),
        body_group=col("group"),
        gravity=np.asarray(gravity, float),
        ground=ground,
        ground_normal=np.asarray(g_normal, float),
        ground_offset=float(g_offset),
        ground_restitution=float(g_rest),
        ground_friction=float(g_fric),
        **statics_kw, **geoms,
    )
    state = State(
        position=col("position"),
        linear_momentum=mass[:, None] * col("velocity"),
        quat_wxyz=quat,
        rotation=rot,
        angular_momentum_world=l_world,
    )
    return model, state


__all__ = ["Scene", "SimParams", "load_scene", "parse_scene", "INTEGRATORS", "DEFAULT_INTEGRATOR",
           "SHAPE_BOX", "SHAPE_SPHERE"]
