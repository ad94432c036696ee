"""The variants of a sweep: ``--set`` specs parsed (:func:`parse_set`), drawn as a grid or a
random sample (:func:`make_variants`), applied to a parsed scene (:func:`apply_params`) and written
back as scene text (:func:`to_toml`), which is what travels to a worker.

Keys are dotted paths into the scene's TOML: ``sim.dt``, ``ground.restitution``,
``body[0].mass``, ``body[*].restitution`` (every ``[[body]]``), ``body[0].angular_velocity_body[2]``
(one component of a vector; a missing vector starts at zero). ``dt``, ``duration``,
``integrator`` and ``orthonormalize`` are short for ``sim.<key>``. See :mod:`rblog.study.sweep`.
"""

from __future__ import annotations

import itertools
import json
import math
import re
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from rblog.errors import RblogError, SceneError

#: short keys -> their place in the scene
ALIASES = {"dt": "sim.dt", "duration": "sim.duration", "integrator": "sim.integrator",
           "orthonormalize": "sim.orthonormalize"}

_KEY_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\[(\d+|\*)\])?$")


@dataclass
class Param:
    """One ``--set``: ``key`` (dotted path), and either ``values`` (a list) or ``lo``/``hi``."""

    key: str
    values: list | None = None
    lo: float | None = None
    hi: float | None = None

    @property
    def is_range(self) -> bool:
        return self.values is None


def _value(text: str):
    t = text.strip()
    if re.fullmatch(r"[+-]?\d+", t):
        return int(t)
    try:
        return float(t)
    except ValueError:
        pass
    if t in ("true", "false"):
        return t == "true"
    return t.strip("'\"")


def parse_set(spec: str) -> Param:
    """``KEY=V1,V2,...`` or ``KEY=LO:HI`` -> :class:`Param`. Raises RblogError (one line) on a
    malformed spec."""
    key, eq, rhs = spec.partition("=")
    key = ALIASES.get(key.strip(), key.strip())
    if not eq or not key or not rhs.strip():
        raise RblogError(f"--set {spec}: expected KEY=V1,V2,... or KEY=LO:HI")
    for part in key.split("."):
        if not _KEY_RE.match(part):
            raise RblogError(f"--set {spec}: bad key part {part!r} (expected name, name[k] or name[*])")
    if ":" in rhs and "," not in rhs:
        lo, _, hi = rhs.partition(":")
        try:
            lo_f, hi_f = float(lo), float(hi)
        except ValueError:
            raise RblogError(f"--set {spec}: range LO:HI needs two numbers") from None
        if not (math.isfinite(lo_f) and math.isfinite(hi_f) and lo_f <= hi_f):
            raise RblogError(f"--set {spec}: range needs finite LO <= HI")
        return Param(key, lo=lo_f, hi=hi_f)
    return Param(key, values=[_value(v) for v in rhs.split(",") if v.strip()])


def make_variants(params: Sequence[Param], n_bodies: int, samples: int | None = None,
                  seed: int = 0) -> list[dict]:
    """The variants, each ``{concrete key: value}`` (``body[*]`` expanded to ``body[0]``...).

    Grid (``samples`` None): the product of the value lists (a range is an error). Random:
    ``samples`` draws from ``default_rng(seed)``, in the order of ``params``.
    """
    if samples is None:
        for p in params:
            if p.is_range:
                raise RblogError(f"--set {p.key}={p.lo:g}:{p.hi:g}: a range needs --samples N")
        grid = itertools.product(*[p.values for p in params]) if params else [()]
        return [_expand({p.key: v for p, v in zip(params, combo)}, n_bodies, None) for combo in grid]
    if samples < 1:
        raise RblogError(f"--samples: expected a positive count, got {samples}")
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(samples):
        draw = {}
        for p in params:
            if p.is_range:
                many = "[*]" in p.key
                draw[p.key] = (rng.uniform(p.lo, p.hi, n_bodies) if many else rng.uniform(p.lo, p.hi))
            else:
                draw[p.key] = p.values[int(rng.integers(len(p.values)))]
        out.append(_expand(draw, n_bodies, rng))
    return out


def _expand(assign: dict, n_bodies: int, rng) -> dict:
    out = {}
    for key, v in assign.items():
        if "[*]" in key:
            for i in range(n_bodies):
                vi = v[i] if isinstance(v, np.ndarray) else v
                out[key.replace("[*]", f"[{i}]", 1)] = _plain(vi)
        else:
            out[key] = _plain(v)
    return out


def _plain(v):
    return float(v) if isinstance(v, (np.floating, float)) else v


def apply_params(doc: dict, assign: dict, where: str) -> dict:
    """A copy of the parsed scene ``doc`` with ``assign`` set. Raises SceneError naming the key."""
    import copy

    doc = copy.deepcopy(doc)
    for key, value in assign.items():
        parts = key.split(".")
        node = doc
        for k, part in enumerate(parts):
            name, _, idx = part.partition("[")
            last = k == len(parts) - 1
            if idx:
                i = int(idx[:-1])
                if last:  # a component of a vector value
                    vec = node.get(name)
                    if vec is None:
                        vec = node[name] = [0.0, 0.0, 0.0]
                    if not isinstance(vec, list) or i >= len(vec):
                        raise SceneError(where, key, f"no component {i} in {name} = {vec!r}")
                    vec[i] = value
                    break
                seq = node.get(name)
                if not isinstance(seq, list) or i >= len(seq):
                    n = len(seq) if isinstance(seq, list) else 0
                    raise SceneError(where, key, f"index {i} out of range ({n} [[{name}]] tables)")
                node = seq[i]
            elif last:
                node[name] = value
            else:
                node = node.setdefault(name, {})
                if not isinstance(node, dict):
                    raise SceneError(where, key, f"{name} is not a table")
    return doc


def to_toml(doc: dict) -> str:
    """TOML text of a parsed scene (tables, arrays of tables, numbers, strings, booleans, lists);
    ``tomllib.loads(to_toml(d)) == d``."""
    lines: list[str] = []

    def val(v) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, int):
            return str(v)
        if isinstance(v, float):
            return repr(v) if math.isfinite(v) else ("nan" if v != v else ("inf" if v > 0 else "-inf"))
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list):
            return "[" + ", ".join(val(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{" + ", ".join(f"{json.dumps(k)} = {val(x)}" for k, x in v.items()) + "}"
        raise TypeError(f"cannot write {type(v).__name__} to TOML")

    def table(d: dict, prefix: str):
        scalars = {k: v for k, v in d.items() if not _is_table(v) and not _is_table_array(v)}
        for k, v in scalars.items():
            lines.append(f"{json.dumps(k)} = {val(v)}")
        for k, v in d.items():
            name = f"{prefix}{json.dumps(k)}"
            if _is_table(v):
                lines.extend(["", f"[{name}]"])
                table(v, name + ".")
            elif _is_table_array(v):
                for item in v:
                    lines.extend(["", f"[[{name}]]"])
                    table(item, name + ".")

    table(doc, "")
    return "\n".join(lines).lstrip("\n") + "\n"


def _is_table(v) -> bool:
    return isinstance(v, dict)


def _is_table_array(v) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


