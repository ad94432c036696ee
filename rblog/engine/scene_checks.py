"""Checks of what a scene's values imply, after each value passed on its own (rblog.engine.scene).

Every number of a scene can be finite and in range while what follows from it is not: a sphere
of radius 1e308 has an infinite volume, half extents of 1e200 an infinite mass, a rotation
vector of 1e308 an infinite angle, a log rate of 1e-30 Hz a log stride of 1e33 steps, and a
thousand boxes 1 mm apart a first step with half a million contact pairs. Each is refused here
with one line naming the scene, the key and the figure, before a run starts.

Memory: a run holds about ``BYTES_PER_BODY_ESTIMATE`` per body and ``BYTES_PER_PAIR_ESTIMATE``
per pair of bodies whose bounding spheres overlap at the start (the pairs the first steps'
narrowphase and solver hold manifolds for). The pairs are counted on a grid of cells one bounding
diameter wide, so counting costs O(N log N) and never lists the pairs.
"""

from __future__ import annotations

import math

import numpy as np

from rblog.engine.constants import (BYTES_PER_BODY_ESTIMATE, BYTES_PER_PAIR_ESTIMATE, MAX_NESTING,
                                    QUAT_NORM_WARN_TOL)

_ITEMS = (list, dict)


def nesting_depth(doc, limit: int = MAX_NESTING) -> int:
    """Depth of nested tables and arrays of a parsed TOML document (the document itself is 1),
    counted without recursion and stopping once past ``limit``."""
    depth, stack = 0, [(doc, 1)]
    while stack:
        v, d = stack.pop()
        depth = max(depth, d)
        if depth > limit:
            return depth
        children = v.values() if isinstance(v, dict) else v
        stack.extend((c, d + 1) for c in children if isinstance(c, _ITEMS))
    return depth


def finite_angle(ctx, angle: float, key: str) -> None:
    """A rotation vector's length must be a finite angle (rad)."""
    if not math.isfinite(angle):
        ctx.fail(key, f"its length is {angle} rad, expected a finite angle (|rotvec| overflows)")


def check_body(ctx, body: dict, key: str) -> None:
    """One [[body]] table (or a generator's template) after its mass and inertia were derived."""
    m = body["mass"]
    if not (math.isfinite(m) and m > 0):
        ctx.fail(f"{key}.mass", f"density x volume gives a mass of {m} kg, expected a finite "
                 "positive mass (the size or density is out of range)")
    inertia = np.asarray(body["inertia_diag"], float)
    if not (np.isfinite(inertia).all() and (inertia > 0).all()):
        ctx.fail(f"{key}.inertia_diag", f"the principal moments come to {inertia.tolist()} "
                 "kg m^2, expected finite positive moments (the size or mass is out of range)")
    for k in ("velocity", "angular_velocity", "angular_velocity_body"):
        v = body.get(k)
        if v is not None:
            p = m * np.asarray(v, float) if k == "velocity" else inertia * np.asarray(v, float)
            if not np.isfinite(p).all():
                ctx.fail(f"{key}.{k}", f"gives a momentum of {p.tolist()}, expected finite "
                         "(mass or inertia times speed overflows)")


def check_log_stride(ctx, sim) -> None:
    """The log stride the scene asks for (log_every, or log_rate with dt) must be a whole number
    of steps within the run: at least one sample after t = 0."""
    n_steps = sim.duration / sim.dt
    if sim.log_every is not None:
        if sim.log_every > n_steps:
            ctx.fail("sim.log_every", f"{sim.log_every} steps between samples, more than the run's "
                     f"{n_steps:.6g} steps (expected at most {math.floor(n_steps)})")
    if sim.log_rate is not None:
        stride = 1.0 / (sim.log_rate * sim.dt) if sim.log_rate * sim.dt > 0 else math.inf
        if not stride <= max(n_steps, 1.0):
            ctx.fail("sim.log_rate", f"{sim.log_rate:g} Hz logs every {stride:.3g} steps, fewer "
                     f"than one sample in the run's {n_steps:.6g} steps (expected a rate >= "
                     f"1 / duration = {1.0 / sim.duration:.3g} Hz)")


def overlapping_pairs(position: np.ndarray, radius: np.ndarray) -> int:
    """Pairs of bodies whose bounding spheres may overlap: the bodies in each body's cell and its
    26 neighbours on a grid of cells one largest bounding diameter wide (an upper bound of the
    pairs whose spheres touch, exact in count for bodies closer than a cell), halved."""
    n = len(position)
    if n < 2:
        return 0
    cell = 2.0 * float(np.max(radius))
    if not (cell > 0 and math.isfinite(cell)):
        return 0
    with np.errstate(over="ignore", invalid="ignore"):
        ijk = np.floor(position / cell)
    if not np.isfinite(ijk).all() or np.abs(ijk).max() > 2**20 - 2:
        ijk = np.floor((position - position.min(axis=0)) / cell)
        if not np.isfinite(ijk).all() or ijk.max() > 2**21 - 2:
            return 0  # spread too far for a grid: bodies that far apart do not crowd
    ijk = ijk.astype(np.int64) + 2**20
    keys = np.sort((ijk[:, 0] << 42) | (ijk[:, 1] << 21) | ijk[:, 2])
    total = 0
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                nb = keys + ((dx << 42) + (dy << 21) + dz)
                total += int((np.searchsorted(keys, nb, "right")
                              - np.searchsorted(keys, nb, "left")).sum())
    return (total - n) // 2


def check_memory(ctx, model, state, available: int | None) -> None:
    """The memory the run will need against what the machine has now."""
    n = model.n_bodies
    pairs = overlapping_pairs(state.position, model.body_bounding_radius)
    need = n * BYTES_PER_BODY_ESTIMATE + pairs * BYTES_PER_PAIR_ESTIMATE
    if available is not None and need > available:
        ctx.fail("", f"{n:,} bodies with {pairs:,} overlapping pairs at the start need about "
                 f"{need / 1e9:.3g} GB of memory, {available / 1e9:.3g} GB available (expected a "
                 "scene that fits: fewer bodies, or bodies further apart)")


def check_state(ctx, model, state) -> None:
    """Rotations and momenta of the built state: finite, rotations orthonormal."""
    for name, a in (("quat_wxyz", state.quat_wxyz), ("rotation", state.rotation),
                    ("linear_momentum", state.linear_momentum),
                    ("angular_momentum", state.angular_momentum_world)):
        bad = ~np.isfinite(a).reshape(len(a), -1).all(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            ctx.fail(f"body {model.body_name[i]!r}", f"its initial {name} is not finite, expected "
                     "finite values (an orientation, mass or speed out of range)")
    off = np.abs(np.linalg.norm(state.quat_wxyz, axis=1) - 1.0) > QUAT_NORM_WARN_TOL
    if off.any():  # a quaternion so large that its norm overflowed, normalised to zero
        i = int(np.flatnonzero(off)[0])
        ctx.fail(f"body {model.body_name[i]!r}", f"its orientation normalises to "
                 f"{state.quat_wxyz[i].tolist()}, expected a unit quaternion (the given one "
                 "overflows)")
