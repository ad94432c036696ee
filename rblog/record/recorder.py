"""The public writer API: record any engine's run into the log contract (docs/log-format.md).

:class:`Recorder` takes the body table once and then blocks of per-body state in whatever form an
engine holds it (orientation as a quaternion or a matrix, velocities or momenta, world frame),
derives every other channel of the contract with the same code rblog's own runs use
(:func:`rblog.contract.trajectory.derive`), and writes ``.rrd`` and/or ``.mcap`` through the same
writers as ``rblog run`` (:class:`~rblog.record.RerunRecorder`, :class:`~rblog.record.McapRecorder`);
with no output it keeps the run in memory (``recorder.trajectory``), which ``rblog.check`` audits
like a file::

    model = rblog.body_table(name=["ball"], shape=["sphere"], size=[[0.1, 0, 0]], mass=[1.0],
                             ground=True)
    with rblog.Recorder(model, mcap="ball.mcap", dt=1e-3, writer="my engine 1.0") as rec:
        for block in engine_blocks():
            rec.write(t=block.t, position=block.x, quat_wxyz=block.q, velocity=block.v,
                      angular_velocity=block.w)          # world frame, (T, N, ...) arrays
    results = rblog.check(rblog.load("ball.mcap"))

:func:`trajectory_from_arrays` builds a :class:`~rblog.contract.trajectory.Trajectory` from whole
arrays in one call. ``Recorder(..., check=True)`` audits the blocks as they are written
(rblog.record.live_audit).

Why this module is long: it is the whole public writer API, and each of its entry points
(:func:`body_table`, :func:`make_contacts`, :func:`build_block`, :class:`Recorder`) checks its
arguments with one-line errors naming the argument, its shape and what was expected.
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import NamedTuple

import numpy as np

from rblog import __version__
from rblog.contract.model import (BODY_FREE, BODY_KIND_CODES, COLLIDE_ALL, COLLIDE_RULES,
                                  DEFAULT_IMPULSE_SUPPLIED, DEFAULT_WORK_SUPPLIED,
                                  GEOM_CODES, GEOM_MESH, IMPULSE_KINDS, JOINT_BALL, JOINT_CODES,
                                  JOINT_FIXED, LOG_SHAPE_CODES, SHAPE_BOX, SHAPE_NONE,
                                  SHAPE_SPHERE, WORK_KINDS, Model, v2_from_geoms)
from rblog.contract.orientation import matrix_to_quat, quat_wxyz_to_matrix
from rblog.contract.trajectory import INTERVAL_CHANNELS, Contacts, RunInfo, Trajectory, derive
from rblog.errors import RblogError, RecordError
from rblog.record import _common as C
from rblog.record import arguments


def body_table(*, name, mass, shape=None, size=None, inertia_diag=None, restitution=None,
               friction=None, group=0, force_world=None, torque_world=None,
               gravity=(0.0, 0.0, -9.81), ground: bool = False, ground_normal=(0.0, 0.0, 1.0),
               ground_offset: float = 0.0, ground_restitution: float = math.nan,
               ground_friction: float = math.nan, static_box_position=None, static_box_quat_wxyz=None,
               static_box_half_extents=None, static_box_restitution=None,
               static_box_friction=None, kind=None, parent=None, geoms=None, joints=None,
               collide_rule: str = "and", impulses=(), work=(), impulses_none=(),
               work_none=(), impulses_missing=(), work_missing=(),
               collide_parent: bool = False) -> Model:
    """A :class:`Model` (body table and world) from per-body lists.

    Args:
        name: N names.  shape: N of ``"sphere"``, ``"box"`` or ``"none"`` (or 0, 1, -1; one value
            for all bodies); ``"none"``: a geometry the v2 fields do not describe, logged with
            zero size and the given inertia. Not with ``geoms`` (then derived from them).
        size: (N, 3): sphere radius in [:, 0]; box half extents (m, body frame). A sphere may
            also be given as a scalar radius per body, (N,).
        mass: (N,) kg, > 0.  inertia_diag: (N, 3) principal moments about the centre of mass in
            the body frame (kg m^2); default: a solid sphere's 2/5 m r^2, a solid box's
            m/3 (b^2 + c^2).
        restitution, friction: scalars or (N,); NaN = not stated by the engine (unknown):
            the value of every material not given (the ground's and static boxes' too), or with
            ``geoms`` each body's first geom's.
        group: collision group(s).
        force_world, torque_world: (N, 3) constant applied loads besides gravity.
        gravity: (3,) m/s^2.  ground...: the plane ``dot(normal, x) = offset`` if ``ground``.
        static_box_*: (M, ...) static boxes. Not with ``geoms`` (world geoms instead).
        kind: N of ``"free"``, ``"joints"``, ``"kinematic"``, ``"static"`` (or BODY_* codes; one
            value for all); default free.  parent: (N,) parent body indices, -1 = world.
        geoms: dict of G-row arrays (docs/log-format.md, "Geoms"): ``body`` (-1 = world),
            ``type`` (names or GEOM_* codes), ``size`` (G, 3); optional ``pos_body`` (G, 3, default
            0), ``quat_wxyz_body`` (G, 4, identity), ``friction``, ``restitution`` (NaN),
            ``collide_group`` (1), ``collide_mask`` (-1, every bit), ``name`` (""),
            ``mesh_vert`` (G entries: a (V, 3) array in the geom frame for a mesh, else None).
        joints: dict of J-row arrays: ``body`` (the child), ``type`` (``"hinge"``, ``"slide"``,
            ``"ball"``, ``"fixed"``, ``"planar"`` or JOINT_* codes), ``anchor_body``,
            ``anchor_parent`` (J, 3); ``axis_body``, ``axis_parent`` (J, 3; not for ball and
            fixed); optional ``range`` (J, 2, NaN = none), ``quat_parent`` (J, 4: the body's
            frame in the parent's at the joint's zero position, wxyz; NaN = not stated),
            ``armature`` (J,: the rotor inertia on each of the joint's dofs, kg m^2 or kg for a
            slide; 0 = none; NaN = not stated, the default), ``name``.
        collide_rule: ``"and"`` (Bullet, rblog) or ``"or"`` (MuJoCo) (COLLIDE_RULES).
        collide_parent: the engine lets a body touch its parent body (default: never).
        impulses: the per-interval impulse kinds this writer logs for every body (a subset of
            IMPULSE_KINDS), or an (N, 6) array of SUPPLIED_* codes (or bools: logged or
            missing) per body.  work: likewise of WORK_KINDS, or (N, 4).
        impulses_none, work_none: kinds the engine does not have at all: known to be zero for
            every body, not stored.  impulses_missing, work_missing: kinds acting that the
            writer cannot supply (what needs them is not judged). A kind named nowhere has the
            meaning of a log that states nothing (DEFAULT_IMPULSE_SUPPLIED: contact missing, the
            others none: no force besides gravity, contacts and the constant force_world /
            torque_world; work none).
    """
    arguments.body_table(name=name, shape=shape, ground=ground, ground_offset=ground_offset,
                         ground_restitution=ground_restitution, ground_friction=ground_friction)
    n = len(name)

    def arr(v, shape_, what, default=0.0):
        a = _float_array(default if v is None else v, what)
        try:
            return np.broadcast_to(a, shape_).copy()
        except ValueError:
            raise RecordError(f"body_table: {what} has shape {a.shape}, expected {shape_} "
                              f"(or a shape that broadcasts to it; N = {n} bodies)") from None

    if isinstance(name, str):
        raise RecordError(f"body_table: name is the string {name!r}, expected a list of N names")
    v3 = {}
    if geoms is not None:
        for what, v in (("shape", shape), ("size", size), ("static_box_position", static_box_position)):
            if v is not None:
                raise RecordError(f"body_table: {what} given with geoms; give the geometry once "
                                  "(geoms: the v2 fields are derived from them)")
        if ground:
            raise RecordError("body_table: ground=True given with geoms; give the ground as a "
                              "world plane geom (body -1, type 'plane')")
        v3.update(_geom_table(geoms, n, name))
        derived = v2_from_geoms(n, v3["geom_body"], v3["geom_type"], v3["geom_pos_body"],
                                v3["geom_quat_wxyz_body"], v3["geom_size"], v3["geom_friction"],
                                v3["geom_restitution"], arr(gravity, (3,), "gravity"))
        codes, sz = derived["body_shape"], derived["body_size"]
        restitution = derived["body_restitution"] if restitution is None else restitution
        friction = derived["body_friction"] if friction is None else friction
    else:
        if shape is None or size is None:
            raise RecordError("body_table: give shape and size (v2), or geoms")
        codes = _shape_codes([shape] * n if isinstance(shape, (str, int, np.integer)) else shape, n)
        sz = _float_array(size, "size")
        if sz.ndim == 1 and len(sz) == n:
            sz = np.stack([sz, np.zeros(n), np.zeros(n)], axis=1)
        sz = arr(sz, (n, 3), "size")
        none = codes == SHAPE_NONE
        if np.any(sz[none] != 0):
            i = int(np.flatnonzero(none & np.any(sz != 0, axis=1))[0])
            raise RecordError(f"body_table: size[{i}] = {sz[i].tolist()} for body {name[i]!r} of "
                              "shape 'none', expected [0, 0, 0] (a body without a shape has no size)")
    m = arr(mass, (n,), "mass")
    if np.any(~(m > 0)):
        i = int(np.flatnonzero(~(m > 0))[0])
        raise RecordError(f"body_table: mass[{i}] = {m[i]!r} for body {name[i]!r}, expected a "
                          "positive number (kg)")
    if inertia_diag is None:
        inertia = np.empty((n, 3))
        for i in range(n):
            if codes[i] == SHAPE_SPHERE:
                inertia[i] = 0.4 * m[i] * sz[i, 0] ** 2
            elif codes[i] == SHAPE_NONE:
                raise RecordError(f"body_table: inertia_diag not given, and body {name[i]!r} has "
                                  "no sphere or box to compute it from: give inertia_diag (N, 3)")
            else:
                a2, b2, c2 = sz[i] ** 2
                inertia[i] = m[i] / 3.0 * np.array([b2 + c2, a2 + c2, a2 + b2])
    else:
        inertia = arr(inertia_diag, (n, 3), "inertia_diag")
        if np.any(~(inertia > 0)):
            i = int(np.flatnonzero(np.any(~(inertia > 0), axis=1))[0])
            raise RecordError(f"body_table: inertia_diag[{i}] = {inertia[i].tolist()} for body "
                              f"{name[i]!r}, expected three positive moments (kg m^2)")
    if kind is not None:
        v3["body_kind"] = _codes(kind, n, BODY_KIND_CODES, "kind", range(4))
    if parent is not None:
        par = np.asarray(parent)
        if par.dtype.kind not in "iu" or par.shape != (n,) or len(par) and (
                par.min() < -1 or par.max() >= n or np.any(par == np.arange(n))):
            raise RecordError(f"body_table: parent = {_short(parent)}, expected ({n},) body "
                              "indices (-1 = world; never the body itself)")
        v3["body_parent"] = par.astype(np.int64)
    if joints is not None:
        v3.update(_joint_table(joints, n))
    if collide_rule not in COLLIDE_RULES:
        raise RecordError(f"body_table: collide_rule = {collide_rule!r}, expected one of "
                          f"{', '.join(map(repr, COLLIDE_RULES))}")
    v3["body_impulse_supplied"] = _supplied(impulses, impulses_none, impulses_missing, n,
                                            IMPULSE_KINDS, DEFAULT_IMPULSE_SUPPLIED, "impulses")
    v3["body_work_supplied"] = _supplied(work, work_none, work_missing, n, WORK_KINDS,
                                         DEFAULT_WORK_SUPPLIED, "work")
    if geoms is not None:
        world = {k: v for k, v in derived.items() if k.startswith(("ground", "static_box"))}
        model = Model(
            body_name=[str(x) for x in name], body_shape=codes, body_size=sz, body_mass=m,
            body_inertia_diag=inertia, body_force_world=arr(force_world, (n, 3), "force_world"),
            body_torque_world=arr(torque_world, (n, 3), "torque_world"),
            body_restitution=arr(restitution, (n,), "restitution", arguments.UNKNOWN_MATERIAL),
            body_friction=arr(friction, (n,), "friction", arguments.UNKNOWN_MATERIAL),
            body_group=_group(group, n),
            gravity=arr(gravity, (3,), "gravity"), collide_rule=collide_rule,
            collide_parent=bool(collide_parent), **world, **v3)
        arguments.model_values(model)
        return model
    mcount = 0 if static_box_position is None else len(_float_array(static_box_position,
                                                                    "static_box_position"))
    model = Model(
        body_name=[str(x) for x in name], body_shape=codes, body_size=sz, body_mass=m,
        body_inertia_diag=inertia, body_force_world=arr(force_world, (n, 3), "force_world"),
        body_torque_world=arr(torque_world, (n, 3), "torque_world"),
        body_restitution=arr(restitution, (n,), "restitution", arguments.UNKNOWN_MATERIAL),
        body_friction=arr(friction, (n,), "friction", arguments.UNKNOWN_MATERIAL),
        body_group=_group(group, n),
        gravity=arr(gravity, (3,), "gravity"), ground=bool(ground),
        ground_normal=arr(ground_normal, (3,), "ground_normal"), ground_offset=float(ground_offset),
        ground_restitution=float(ground_restitution), ground_friction=float(ground_friction),
        static_box_position=arr(static_box_position, (mcount, 3), "static_box_position"),
        static_box_quat_wxyz=arr(static_box_quat_wxyz if mcount else None, (mcount, 4),
                                 "static_box_quat_wxyz", default=[1.0, 0, 0, 0]),
        static_box_half_extents=arr(static_box_half_extents, (mcount, 3), "static_box_half_extents"),
        static_box_restitution=arr(static_box_restitution, (mcount,), "static_box_restitution",
                                   arguments.UNKNOWN_MATERIAL),
        static_box_friction=arr(static_box_friction, (mcount,), "static_box_friction",
                                arguments.UNKNOWN_MATERIAL),
        collide_rule=collide_rule, collide_parent=bool(collide_parent), **v3,
    )
    arguments.model_values(model)
    return model


def _codes(v, count: int, names: dict, what: str, valid) -> np.ndarray:
    """Names or integer codes (one for all, or ``count``) -> (count,) int64; a one-line
    RecordError naming ``what`` for anything else."""
    if isinstance(v, np.ndarray) and v.dtype.kind in "iu" and v.shape == (count,):
        out = v.astype(np.int64)
        if (out[:, None] == np.array(list(valid))).any(axis=1).all():  # all valid (else the
            return out  # loop below names the first that is not)
    vals = [v] * count if isinstance(v, (str, int, np.integer)) else list(v)
    if len(vals) != count:
        raise RecordError(f"body_table: {what} has {len(vals)} entries, expected {count}")
    out = np.empty(count, np.int64)
    valid = set(valid)
    for i, x in enumerate(vals):
        code = names.get(x) if isinstance(x, str) else \
            (int(x) if isinstance(x, (int, np.integer)) and int(x) in valid else None)
        if code is None:
            raise RecordError(f"body_table: {what}[{i}] = {x!r}, expected one of "
                              f"{', '.join(map(repr, names))} (or codes {sorted(valid)})")
        out[i] = code
    return out


def _supplied(v, none, missing, n: int, kinds: tuple, default: tuple, what: str) -> np.ndarray:
    """``impulses`` / ``work`` (kind names logged for every body, or an (N, len(kinds)) array of
    SUPPLIED_* codes or bools), ``*_none`` and ``*_missing`` (kind names) -> (N, len(kinds))
    int64 codes; a kind named nowhere gets its ``default`` code."""
    from rblog.contract.model import SUPPLIED_LOGGED, SUPPLIED_MISSING, SUPPLIED_NONE

    v, none, missing = ((x,) if isinstance(x, str) else x for x in (v, none, missing))
    a = np.asarray(v)
    if a.ndim == 2 or a.dtype == bool:
        if a.shape != (n, len(kinds)) or a.dtype.kind not in "biu" or (
                a.size and (a.min() < 0 or a.max() > SUPPLIED_NONE)):
            raise RecordError(f"body_table: {what} has shape {a.shape} and values {_short(v)}, "
                              f"expected ({n}, {len(kinds)}) codes 0 (missing), 1 (logged), "
                              f"2 (none) (columns {', '.join(kinds)})")
        if len(none) or len(missing):
            raise RecordError(f"body_table: {what} given as an array of codes; give "
                              f"{what}_none / {what}_missing only with kind names")
        return a.astype(np.int64)
    out = np.tile(np.array(default, np.int64), (n, 1))
    named: dict[str, str] = {}
    for arg, names, code in ((what, v, SUPPLIED_LOGGED), (f"{what}_none", none, SUPPLIED_NONE),
                             (f"{what}_missing", missing, SUPPLIED_MISSING)):
        for k in names:
            if k not in kinds:
                raise RecordError(f"body_table: {arg} holds {k!r}, expected some of "
                                  f"{', '.join(map(repr, kinds))}")
            if k in named:
                raise RecordError(f"body_table: {k!r} is in both {named[k]} and {arg}")
            named[k] = arg
            out[:, kinds.index(k)] = code
    return out


_GEOM_KEYS = ("body", "type", "size", "pos_body", "quat_wxyz_body", "friction", "restitution",
              "collide_group", "collide_mask", "name", "mesh_vert")
_JOINT_KEYS = ("body", "type", "anchor_body", "anchor_parent", "axis_body", "axis_parent",
               "range", "quat_parent", "armature", "name")


def _rows(table: dict, keys: tuple, required: tuple, what: str) -> int:
    if not isinstance(table, dict):
        raise RecordError(f"body_table: {what} is a {type(table).__name__}, expected a dict of "
                          f"arrays ({', '.join(keys)})")
    unknown = sorted(set(table) - set(keys))
    missing = [k for k in required if k not in table]
    if unknown or missing:
        bad = f"unknown field {unknown[0]!r}" if unknown else f"field {missing[0]!r} missing"
        raise RecordError(f"body_table: {what}: {bad}; the fields are {', '.join(keys)} "
                          f"({', '.join(required)} required)")
    return len(np.atleast_1d(np.asarray(table[required[0]])))


def _col(table, key, what, rows, trail=(), default=None, dtype=np.float64):
    """Column ``key`` of ``table`` as (rows, *trail) ``dtype`` (``default`` broadcast when
    absent), or a one-line RecordError naming ``what.key``, its shape and the expected one."""
    given = table.get(key) is not None
    v = table[key] if given else default
    try:
        a = np.asarray(v, dtype)
    except (TypeError, ValueError):
        raise RecordError(f"body_table: {what}.{key} = {_short(v)}, expected numbers") from None
    want = (rows, *trail)
    if not given:
        return np.broadcast_to(a, want).copy()
    if a.size == math.prod(want) and (a.ndim <= 1 or a.shape[0] == rows):
        return a.reshape(want).copy()
    raise RecordError(f"body_table: {what}.{key}: shape {a.shape}, expected {want} ({rows} rows)")


def _geom_table(geoms: dict, n: int, body_names) -> dict:
    G = _rows(geoms, _GEOM_KEYS, ("body", "type", "size"), "geoms")
    gb = np.asarray(geoms["body"])
    if gb.dtype.kind not in "iu" or gb.shape != (G,) or G and (gb.min() < -1 or gb.max() >= n):
        raise RecordError(f"body_table: geoms.body = {_short(geoms['body'])}, expected ({G},) "
                          f"body indices 0..{n - 1} or -1 (world)")
    gt = _codes(geoms["type"], G, GEOM_CODES, "geoms.type", GEOM_CODES.values())
    out = {"geom_body": gb.astype(np.int64), "geom_type": gt,
           "geom_size": _col(geoms, "size", "geoms", G, (3,)),
           "geom_pos_body": _col(geoms, "pos_body", "geoms", G, (3,), 0.0),
           "geom_quat_wxyz_body": _col(geoms, "quat_wxyz_body", "geoms", G, (4,), [1.0, 0, 0, 0]),
           "geom_friction": _col(geoms, "friction", "geoms", G, (), np.nan),
           "geom_restitution": _col(geoms, "restitution", "geoms", G, (), np.nan),
           "geom_collide_group": _col(geoms, "collide_group", "geoms", G, (), 1, np.int64),
           "geom_collide_mask": _col(geoms, "collide_mask", "geoms", G, (), COLLIDE_ALL, np.int64)}
    qn = np.linalg.norm(out["geom_quat_wxyz_body"], axis=1)
    if G and np.any(np.abs(qn - 1.0) > 1e-6):
        g = int(np.flatnonzero(np.abs(qn - 1.0) > 1e-6)[0])
        raise RecordError(f"body_table: geoms.quat_wxyz_body[{g}] has norm {qn[g]:.6g}, expected "
                          "a unit quaternion (w, x, y, z)")
    if np.any(out["geom_size"] < 0) or not np.all(np.isfinite(out["geom_size"])):
        g = int(np.flatnonzero(~np.all(out["geom_size"] >= 0, axis=1))[0])
        raise RecordError(f"body_table: geoms.size[{g}] = {out['geom_size'][g].tolist()}, "
                          "expected finite sizes >= 0 (m)")
    names = geoms.get("name")
    out["geom_name"] = [""] * G if names is None else [str(x) for x in names]
    if len(out["geom_name"]) != G:
        raise RecordError(f"body_table: geoms.name has {len(out['geom_name'])} entries, expected {G}")
    verts = geoms.get("mesh_vert")
    if verts is not None and len(verts) != G:
        raise RecordError(f"body_table: geoms.mesh_vert has {len(verts)} entries, expected {G} "
                          "(a (V, 3) array for each mesh, None for the others)")
    adr, num, parts = np.zeros(G, np.int64), np.zeros(G, np.int64), []
    k = 0
    for g in range(G):
        v = None if verts is None else verts[g]
        if gt[g] == GEOM_MESH:
            a = np.asarray(v if v is not None else np.zeros((0, 3)), np.float64)
            if a.ndim != 2 or a.shape[1] != 3 or len(a) < 4:
                raise RecordError(f"body_table: geoms.mesh_vert[{g}] has shape {a.shape}, expected "
                                  "(V, 3) with V >= 4 vertices (the mesh's, geom frame, m)")
            adr[g], num[g] = k, len(a)
            k += len(a)
            parts.append(a)
        elif v is not None:
            raise RecordError(f"body_table: geoms.mesh_vert[{g}] given for a geom of type "
                              f"{int(gt[g])}, expected None (vertices are for meshes only)")
    out.update(geom_vert_adr=adr, geom_vert_num=num,
               mesh_vert=np.concatenate(parts) if parts else np.zeros((0, 3)))
    return out


def _joint_table(joints: dict, n: int) -> dict:
    J = _rows(joints, _JOINT_KEYS, ("body", "type", "anchor_body", "anchor_parent"), "joints")
    jb = np.asarray(joints["body"])
    if jb.dtype.kind not in "iu" or jb.shape != (J,) or J and (jb.min() < 0 or jb.max() >= n):
        raise RecordError(f"body_table: joints.body = {_short(joints['body'])}, expected ({J},) "
                          f"body indices 0..{n - 1} (the body each joint moves)")
    jt = _codes(joints["type"], J, JOINT_CODES, "joints.type", JOINT_CODES.values())
    axisless = (jt == JOINT_BALL) | (jt == JOINT_FIXED)
    out = {"joint_body": jb.astype(np.int64), "joint_type": jt,
           "joint_anchor_body": _col(joints, "anchor_body", "joints", J, (3,)),
           "joint_anchor_parent": _col(joints, "anchor_parent", "joints", J, (3,)),
           "joint_axis_body": _col(joints, "axis_body", "joints", J, (3,), 0.0),
           "joint_axis_parent": _col(joints, "axis_parent", "joints", J, (3,), 0.0),
           "joint_range": _col(joints, "range", "joints", J, (2,), np.nan),
           "joint_quat_parent": _col(joints, "quat_parent", "joints", J, (4,), np.nan),
           "joint_armature": _col(joints, "armature", "joints", J, (), np.nan)}
    arm = out["joint_armature"]
    bad = np.flatnonzero(arm < 0)
    if len(bad):
        j = int(bad[0])
        raise RecordError(f"body_table: joints.armature[{j}] = {arm[j]!r}, expected a rotor "
                          "inertia >= 0 (kg m^2, kg for a slide) or NaN (not stated)")
    qn = np.linalg.norm(out["joint_quat_parent"], axis=1)
    bad = np.flatnonzero(np.isfinite(qn) & (np.abs(qn - 1.0) > 1e-6))
    if len(bad):
        j = int(bad[0])
        raise RecordError(f"body_table: joints.quat_parent[{j}] has norm {qn[j]:.6g}, expected a "
                          "unit quaternion (w, x, y, z) or NaN (not stated)")
    for key in ("axis_body", "axis_parent"):
        norm = np.linalg.norm(out[f"joint_{key}"], axis=1)
        bad = np.flatnonzero(~axisless & (np.abs(norm - 1.0) > 1e-6))
        if len(bad):
            j = int(bad[0])
            raise RecordError(f"body_table: joints.{key}[{j}] has norm {norm[j]:.6g}, expected a "
                              "unit axis for a hinge, slide or planar joint")
    names = joints.get("name")
    out["joint_name"] = [""] * J if names is None else [str(x) for x in names]
    return out


def _float_array(v, what: str, where: str = "body_table") -> np.ndarray:
    """``v`` as float64, or a one-line RecordError naming the argument and the value."""
    try:
        return np.asarray(v, np.float64)
    except (TypeError, ValueError):
        raise RecordError(f"{where}: {what} = {_short(v)}, expected numbers") from None


def _short(v) -> str:
    r = repr(v)
    return r if len(r) <= 60 else r[:57] + "..."


def _shape_codes(shape, n: int) -> np.ndarray:
    """Shape names or codes -> (N,) int64 codes; unknown ones are a one-line RecordError."""
    shape = list(shape)
    if len(shape) != n:
        raise RecordError(f"body_table: shape has {len(shape)} entries, expected {n} (one per name)")
    codes = np.empty(n, np.int64)
    valid = set(LOG_SHAPE_CODES.values())
    for i, s in enumerate(shape):
        code = LOG_SHAPE_CODES.get(s) if isinstance(s, str) else \
            (int(s) if isinstance(s, (int, np.integer)) and int(s) in valid else None)
        if code is None:
            raise RecordError(
                f"body_table: shape[{i}] = {s!r}, expected one of 'sphere', 'box', 'none' "
                "(or 0, 1, -1); record a capsule, cylinder or mesh as 'none' with its inertia_diag")
        codes[i] = code
    return codes


def _group(group, n: int) -> np.ndarray:
    g = np.asarray(group)
    if g.dtype.kind not in "iub":
        raise RecordError(f"body_table: group = {_short(group)}, expected integers")
    try:
        return np.broadcast_to(g.astype(np.int64), (n,)).copy()
    except ValueError:
        raise RecordError(f"body_table: group has shape {g.shape}, expected () or ({n},)") from None


#: the values of engine_settings["contact_rows"]["separation"] (docs/log-format.md, contact rows):
#: when the logged separation was measured; a value may go on with an explanation in
#: parentheses ("before the step (contacts found at its start)")
CONTACT_ROWS_SEPARATION = ("after the step", "before the step")


def _check_contact_rows(settings) -> None:
    rows = (settings or {}).get("contact_rows") if isinstance(settings, dict) else None
    sep = rows.get("separation") if isinstance(rows, dict) else None
    if sep is not None and not (isinstance(sep, str) and sep.startswith(CONTACT_ROWS_SEPARATION)):
        raise RecordError(f"engine_settings.contact_rows.separation = {_short(sep)}, expected "
                          f"{' or '.join(map(repr, CONTACT_ROWS_SEPARATION))} (optionally followed "
                          "by an explanation)")


_CONTACT_FIELDS = [f.name for f in fields(Contacts)]
_CONTACT_VECTORS = ("point", "normal", "friction_impulse")
_CONTACT_REQUIRED = ("step", "body_a", "body_b", "point", "normal", "separation", "normal_impulse")
#: the values of contacts.kind (docs/log-format.md): 0 resting (or not classified), 1 impact
KIND_VALUES = (0, 1)


def make_contacts(n_bodies: int, *, step, body_a, body_b, point, normal, separation,
                  normal_impulse, friction_impulse=None, t=None, kind=None, dt=None) -> Contacts:
    """Contact rows from arrays (K rows; see docs/log-format.md "Contact rows"). ``t`` defaults to
    ``step * dt``; ``friction_impulse`` to zero; ``kind`` to 0 (resting).

    Shapes: ``step``, ``body_a``, ``body_b``, ``separation``, ``normal_impulse``, ``kind``,
    ``t``: (K,); ``point``, ``normal``, ``friction_impulse``: (K, 3). Anything else is a one-line
    :class:`RecordError` naming the field (``contacts.point``), its shape and the expected one."""
    step = np.asarray(step).reshape(-1)
    if step.dtype.kind not in "iu" and not (step.dtype.kind == "f" and np.all(step == np.rint(step))):
        raise RecordError(f"contacts.step = {_short(step)}, expected integer step indices")
    step = step.astype(np.int64)
    k = len(step)
    if t is None:
        if dt is None:
            raise RecordError("contacts: give t, or dt so that t = step * dt")
        t = step * float(dt)

    def col(v, name, dtype, trail=()):
        try:
            a = np.asarray(v, dtype)
        except (TypeError, ValueError):
            raise RecordError(f"contacts.{name} = {_short(v)}, expected numbers") from None
        want = (k, *trail)
        # the shape itself, or the same values flattened ((3K,) for a point, as the MCAP rows)
        if a.size != math.prod(want) or (a.ndim > 1 and a.shape[0] != k):
            raise RecordError(f"contacts.{name}: shape {a.shape}, expected {want} "
                              f"(K = {k} rows, one per value of contacts.step)")
        return a.reshape(want)

    out = Contacts(
        step=step, t=col(t, "t", np.float64),
        body_a=col(body_a, "body_a", np.int64), body_b=col(body_b, "body_b", np.int64),
        point=col(point, "point", np.float64, (3,)), normal=col(normal, "normal", np.float64, (3,)),
        separation=col(separation, "separation", np.float64),
        normal_impulse=col(normal_impulse, "normal_impulse", np.float64),
        friction_impulse=(np.zeros((k, 3)) if friction_impulse is None
                          else col(friction_impulse, "friction_impulse", np.float64, (3,))),
        kind=np.zeros(k, np.int8),
    )
    if kind is not None:
        kind = col(kind, "kind", np.int64)
        if k and not np.isin(kind, KIND_VALUES).all():
            raise RecordError(f"contacts.kind holds {int(kind[~np.isin(kind, KIND_VALUES)][0])}, "
                              "expected 0 (resting, or not classified) or 1 (impact)")
        out.kind = kind.astype(np.int8)
    for name in ("body_a", "body_b"):
        a = getattr(out, name)
        if len(a) and (a.min() < -1 or a.max() >= n_bodies):
            raise RecordError(f"contacts: {name} holds {int(a.min())}..{int(a.max())}, expected "
                              f"body indices 0..{n_bodies - 1} or -1 (static geometry)")
    return out


def _arr(v, name, shape):
    try:
        a = np.asarray(v, np.float64)
    except (TypeError, ValueError):
        raise RecordError(f"{name} = {_short(v)}, expected numbers of shape {shape}") from None
    if a.shape != shape:
        raise RecordError(f"{name}: shape {a.shape}, expected {shape} (samples, bodies, ...)")
    return a


def build_block(model: Model, info: RunInfo, *, t, step=None, position, quat_wxyz=None,
                quat_xyzw=None, rotation=None, velocity=None, linear_momentum=None,
                angular_velocity=None, angular_momentum=None, contacts=None,
                owned: bool = False, **interval) -> Trajectory:
    """One block of the contract from the state an engine holds (T samples, N bodies, world frame).

    Give the orientation as ``quat_wxyz`` (or ``quat_xyzw``) and/or ``rotation`` (T, N, 3, 3)
    body->world; the linear state as ``velocity`` and/or ``linear_momentum``; the angular state as
    ``angular_velocity`` (world frame, rad/s) and/or ``angular_momentum`` (world, about the centre
    of mass). What is missing is derived: ``R`` from ``q`` or ``q`` from ``R`` (Shepperd),
    ``p = m v``, ``L = R diag(I_body) R^T w``; then every derived channel
    (:func:`rblog.contract.trajectory.derive`). Channels given twice are logged as given, so that
    a disagreement shows in the consistency checks rather than being overwritten.

    ``interval``: the per-interval channels (INTERVAL_CHANNELS: ``impulse_<kind>_linear`` /
    ``_angular`` (T, N, 3), ``work_<kind>`` (T, N)), exactly those of the kinds the model
    declares (``body_impulse_supplied`` / ``body_work_supplied``); a body's values where it does
    not supply that kind are logged as NaN. ``owned``: the ``interval`` arrays are the caller's
    to give away (float64 views of its own fresh buffers, as an engine adapter's block): the block
    keeps them as they are, without a copy, and the NaN is written into them.
    """
    t = _float_array(t, "t", "write").reshape(-1)
    if not np.isfinite(t).all():
        raise RecordError(f"write: t = {_short(t)}, expected finite times (s)")
    T, n = len(t), model.n_bodies
    if step is None:
        if not info.dt:
            raise RecordError("step: not given and the run's dt is unknown (give step or dt)")
        step = np.rint(t / info.dt).astype(np.int64)
    try:
        step = np.asarray(step, np.int64).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        raise RecordError(f"write: step = {_short(step)}, expected integer step indices") from None
    if len(step) != T:
        raise RecordError(f"step: {len(step)} values, expected {T} (one per sample)")
    position = _arr(position, "position", (T, n, 3))
    if quat_xyzw is not None:
        if quat_wxyz is not None:
            raise RecordError("give quat_wxyz or quat_xyzw, not both")
        quat_wxyz = _arr(quat_xyzw, "quat_xyzw", (T, n, 4))[..., [3, 0, 1, 2]]
    if quat_wxyz is None and rotation is None:
        raise RecordError("orientation: give quat_wxyz, quat_xyzw or rotation")
    if velocity is None and linear_momentum is None:
        raise RecordError("linear state: give velocity or linear_momentum")
    if angular_velocity is None and angular_momentum is None:
        raise RecordError("angular state: give angular_velocity (world frame) or angular_momentum")
    mass = np.asarray(model.body_mass, np.float64)
    if rotation is None and linear_momentum is None and angular_momentum is None:
        # the usual case (q, v, w): R, P and L in one compiled pass
        from rblog.contract.derive import state_from_velocities

        c = np.ascontiguousarray
        quat_wxyz = c(_arr(quat_wxyz, "quat_wxyz", (T, n, 4)))
        velocity = c(_arr(velocity, "velocity", (T, n, 3)))
        angular_velocity = c(_arr(angular_velocity, "angular_velocity", (T, n, 3)))
        rotation, p, lw = np.empty((T, n, 3, 3)), np.empty((T, n, 3)), np.empty((T, n, 3))
        state_from_velocities(c(mass), c(model.body_inertia_diag, dtype=np.float64), quat_wxyz,
                              velocity, angular_velocity, rotation, p, lw)
    else:
        if rotation is None:
            quat_wxyz = _arr(quat_wxyz, "quat_wxyz", (T, n, 4))
            rotation = quat_wxyz_to_matrix(quat_wxyz)
        else:
            rotation = _arr(rotation, "rotation", (T, n, 3, 3))
            quat_wxyz = matrix_to_quat(rotation) if quat_wxyz is None else \
                _arr(quat_wxyz, "quat_wxyz", (T, n, 4))
        if velocity is not None:
            velocity = _arr(velocity, "velocity", (T, n, 3))
        p = mass[None, :, None] * velocity if linear_momentum is None else \
            _arr(linear_momentum, "linear_momentum", (T, n, 3))
        if angular_velocity is not None:
            angular_velocity = _arr(angular_velocity, "angular_velocity", (T, n, 3))
        if angular_momentum is None:
            inertia = np.asarray(model.body_inertia_diag, np.float64)
            w_body = (np.swapaxes(rotation, -1, -2) @ angular_velocity[..., None])[..., 0]
            lw = (rotation @ (inertia[None] * w_body)[..., None])[..., 0]
        else:
            lw = _arr(angular_momentum, "angular_momentum", (T, n, 3))
    if isinstance(contacts, dict):
        unknown = sorted(set(contacts) - set(_CONTACT_FIELDS))
        missing = [k for k in _CONTACT_REQUIRED if k not in contacts]
        if unknown or missing:
            what = f"unknown field {unknown[0]!r}" if unknown else f"field {missing[0]!r} missing"
            raise RecordError(f"contacts: {what}; the fields are {', '.join(_CONTACT_REQUIRED)} "
                              "and optionally t, friction_impulse, kind (docs/log-format.md, "
                              "contact rows)")
        contacts = make_contacts(n, dt=info.dt, **contacts)
    elif contacts is not None and not isinstance(contacts, Contacts):
        raise RecordError(f"contacts: a {type(contacts).__name__}, expected a dict of arrays "
                          "(see make_contacts) or an rblog.Contacts")
    chans = _interval_channels(model, interval, T, n, copy=not owned)
    block = derive(model, info, step, t, position, p, quat_wxyz, rotation, lw, contacts=contacts)
    for name, a in chans.items():
        setattr(block, name, a)
    if velocity is not None and linear_momentum is not None:
        block.velocity = np.ascontiguousarray(velocity)
    if angular_velocity is not None and angular_momentum is not None:
        block.angular_velocity = np.ascontiguousarray(angular_velocity)
    return block


#: the per-interval plans (_interval_plan) of the body tables seen, keyed by their supplied codes
_PLANS: dict = {}


def _interval_plan(model: Model):
    """(the channels a run of ``model`` logs, the same as a set, {channel: (trailing shape, the
    bodies that do not supply its kind, or None when every body does)}): a function of the model's
    ``body_impulse_supplied`` / ``body_work_supplied`` alone, kept per codes (up to 16 tables)."""
    from rblog.record._common import run_interval_channels

    imp = np.asarray(model.body_impulse_supplied)
    work = np.asarray(model.body_work_supplied)
    key = (imp.shape, imp.dtype.str, imp.tobytes(), work.shape, work.dtype.str, work.tobytes())
    plan = _PLANS.get(key)
    if plan is not None:
        return plan
    want = run_interval_channels(model)
    sup_imp, sup_work = imp == 1, work == 1  # SUPPLIED_LOGGED
    nan_at = {}
    for name in want:
        kind = name.split("_")[1]
        sup = sup_imp[:, IMPULSE_KINDS.index(kind)] if name.startswith("impulse") else \
            sup_work[:, WORK_KINDS.index(kind)]
        at = np.flatnonzero(~sup)
        if len(at) and at[-1] - at[0] == len(at) - 1:  # contiguous: a slice
            at = slice(int(at[0]), int(at[-1]) + 1)
        nan_at[name] = (INTERVAL_CHANNELS[name], None if sup.all() else at)
    plan = (want, frozenset(want), nan_at)
    if len(_PLANS) >= 16:
        _PLANS.clear()
    _PLANS[key] = plan
    return plan


def _interval_channels(model: Model, given: dict, T: int, n: int, copy: bool = True) -> dict:
    """The block's per-interval channels, checked against what the model declares (copies of
    the given arrays, or with ``copy=False`` the arrays themselves when they are float64)."""
    want, wanted, nan_at = _interval_plan(model)
    exact = given.keys() == wanted and not any(v is None for v in given.values())
    unknown = [] if exact else sorted(set(given) - set(INTERVAL_CHANNELS))
    if unknown:
        raise RecordError(f"write: unknown argument {unknown[0]!r}; the per-interval channels "
                          f"are {', '.join(INTERVAL_CHANNELS)}")
    for name in () if exact else INTERVAL_CHANNELS:
        if (name in wanted) != (given.get(name) is not None):
            kind = name.split("_")[1]
            decl = "impulses" if name.startswith("impulse") else "work"
            if name in want:
                raise RecordError(f"write: {name} missing; the body table declares {decl} "
                                  f"{kind!r} (body_table({decl}=...)), so every block carries it")
            raise RecordError(f"write: {name} given, but the body table does not declare {decl} "
                              f"{kind!r}: add it to body_table({decl}=...)")
    out = {}
    for name in want:
        trail, missing = nan_at[name]
        a = _arr(given[name], name, (T, n, *trail))
        if copy:
            a = np.array(a, np.float64)
        if missing is not None:  # the bodies that do not supply this kind: NaN
            a[:, missing] = np.nan
        out[name] = a
    return out


class Recorder:
    """Record a run of any engine into the log contract (a context manager).

    Args:
        model: the body table (:func:`body_table`, or a :class:`Model`).
        rrd, mcap: output paths (either, both, or neither: then the run is kept in memory).
        dt: the engine's step (s); ``step`` defaults to ``round(t / dt)``.
        writer: the program that wrote the log (``"mujoco 3.2.0"``).
        integrator: the engine's integrator name.  log_every: steps between samples.
        combine_friction, combine_restitution: the engine's material combine rules (see
            ``RunInfo``; rblog's are ``geometric`` and ``max``).
        engine_settings: every solver setting used (logged as JSON).
        keep: keep the blocks in memory (default: when there is no output path).
        info: a ready :class:`RunInfo` instead of the fields above.
        check: run the analyzers on each block as it is written (the live audit,
            rblog.record.live_audit): ``True``, a dict of :class:`~rblog.record.live_audit.LiveAudit`
            options (``only``, ``skip``, ``tolerances``, ``budget``, ``on_finding``), or a
            ready ``LiveAudit``. Findings
            stream into the ``.rrd``; after :meth:`close`, :attr:`audit` ``.results`` is the
            verdict of ``rblog check`` on the finished log and ``.announced`` what was found when.
        fail_fast: with ``check``, :meth:`write` raises ``AuditFailed`` at the first finding
            (after the block reached the logs; leaving the ``with`` block closes them).

    ``write(...)`` takes a block (see :func:`build_block`); ``close(truncated, reason)`` (or
    leaving the ``with`` block; an exception marks the log truncated) finishes the files.
    ``trajectory`` is the run so far when ``keep``.
    """

    def __init__(self, model: Model | None = None, *, rrd=None, mcap=None, dt: float = 0.0, writer: str = "",
                 integrator: str = "", log_every: int = 1, duration_s: float = 0.0,
                 combine_friction: str = "geometric", combine_restitution: str = "max",
                 engine_settings: dict | None = None, scene_path: str = "", scene_toml: str = "",
                 scene_resolved: dict | None = None, seed: int | None = None,
                 keep: bool | None = None, info: RunInfo | None = None,
                 mcap_compression: str = "lz4", writers: list | None = None,
                 check: bool | dict = False, fail_fast: bool = False):
        arguments.recorder(model=model, rrd=rrd, mcap=mcap, dt=dt, writer=writer,
                           integrator=integrator, log_every=log_every, duration_s=duration_s,
                           engine_settings=engine_settings, scene_path=scene_path,
                           scene_toml=scene_toml, scene_resolved=scene_resolved, seed=seed,
                           keep=keep, info=info, mcap_compression=mcap_compression,
                           writers=writers, fail_fast=fail_fast, combine_friction=combine_friction,
                           combine_restitution=combine_restitution)
        for rule, what in ((combine_friction, "combine_friction"),
                           (combine_restitution, "combine_restitution")):
            if rule not in C.COMBINE_RULES:
                raise RecordError(f"{what}: {rule!r}, expected one of {', '.join(C.COMBINE_RULES)}")
        _check_contact_rows(engine_settings)
        self.model = model
        self.info = info or RunInfo(
            integrator=integrator, orthonormalize="none", dt=float(dt), log_every=int(log_every),
            duration_s=float(duration_s), rblog_version=__version__, scene_path=scene_path,
            scene_toml=scene_toml, scene_resolved=scene_resolved or {}, seed=seed,
            writer=writer or f"rblog.Recorder {__version__}", combine_friction=combine_friction,
            combine_restitution=combine_restitution, engine_settings=dict(engine_settings or {}),
            log_format=C.LOG_FORMAT_VERSION)
        self.writers = list(writers or [])
        if rrd is not None:
            from rblog.record.rerun_writer import RerunRecorder

            self.writers.append(RerunRecorder(rrd))
        if mcap is not None:
            from rblog.record.mcap_writer import McapRecorder

            self.writers.append(McapRecorder(mcap, compression=mcap_compression))
        self.keep = (not self.writers) if keep is None else keep
        #: the live audit (rblog.record.live_audit.LiveAudit) with ``check``, else None; it
        #: writes after the logs, so a block that fails it is in them
        self.audit = None
        if check is not False and check is not None or fail_fast:
            from rblog.record.live_audit import LiveAudit
            from rblog.record.rerun_writer import RerunRecorder

            if isinstance(check, LiveAudit):
                self.audit = check
            else:
                opts = dict(check) if isinstance(check, dict) else {}
                self.audit = LiveAudit(fail_fast=fail_fast, **opts)
            for w in self.writers:
                if isinstance(w, RerunRecorder):
                    self.audit.attach_rerun(w)
            self.writers.append(self.audit)
        self.blocks: list[Trajectory] = []
        self._sample_blocks: list[SampleBlock] = []
        self._opened: list = []
        self._open = False
        self._closed = False
        self._truncated = False
        self._last_step: int | None = None
        self.samples_written = 0
        self.blocks_written = 0
        #: why the recording failed ('' while it has not): the first write that raised. The
        #: trajectory carries it (Trajectory.failed), and rblog.check judges none of it clean.
        self.failed = ""

    # --- lifecycle --------------------------------------------------------------------------
    def open(self, model: Model | None = None, info: RunInfo | None = None) -> "Recorder":
        """Open the outputs. ``model`` and ``info`` (optional) replace the constructor's: this is
        the recorder protocol of :func:`rblog.engine.runner.run`, so rblog's own runs record
        through a Recorder as well (``rblog run`` does)."""
        if model is not None:
            self.model = model
        if info is not None:
            self.info = info
        if self.model is None:
            raise RecordError("no body table: give Recorder(model, ...) or open(model, info)")
        if not self._open:
            for w in self.writers:
                w.open(self.model, self.info)
                self._opened.append(w)
            self._open = True
        return self

    def __enter__(self) -> "Recorder":
        return self.open()

    def __exit__(self, exc_type, exc, tb):
        self.close(truncated=exc_type is not None, reason=None if exc is None else str(exc))

    def write(self, block: Trajectory | None = None, **arrays) -> Trajectory:
        """Append a block: a ready :class:`Trajectory`, or arrays for :func:`build_block`.
        Returns the block as logged."""
        if self._closed:
            raise RecordError("recorder is closed")
        if not self._open:
            self.open()
        try:
            if block is None:
                block = build_block(self.model, self.info, **arrays)
            if block.n_samples and self._last_step is not None and \
                    block.step[0] <= self._last_step:
                raise RecordError(f"step {int(block.step[0])} after step {self._last_step}: "
                                  "blocks must be written in time order")
            for w in self._opened:
                w.write(block)
        except BaseException as e:  # an interrupt as well
            # the run now misses this block's samples: its trajectory is never judged clean
            if not self.failed:
                self.failed = (f"write of block {self.blocks_written + 1} raised "
                               f"{type(e).__name__}: {e}")
            raise
        self.blocks_written += 1
        if self.keep:
            self.blocks.append(block)
        if block.n_samples:
            self._last_step = int(block.step[-1])
        self.samples_written += block.n_samples
        return block

    def sample_block(self, capacity: int = 256,
                     fields=("position", "quat_wxyz", "velocity", "angular_velocity")) -> "SampleBlock":
        """A :class:`SampleBlock` of ``capacity`` preallocated sample rows that writes itself to
        this recorder when full (and on :meth:`close`): the per-sample fast path. ``fields``:
        the state arrays the writer fills (any that :func:`build_block` takes: ``rotation``
        as well as ``quat_wxyz`` skips the conversion, ``linear_momentum`` /
        ``angular_momentum`` instead of the velocities skip the products)."""
        if self.model is None:
            raise RecordError("no body table: give Recorder(model, ...) before sample_block()")
        blk = SampleBlock(self, int(capacity), tuple(fields))
        self._sample_blocks.append(blk)
        return blk

    def close(self, truncated: bool = False, reason: str | None = None) -> None:
        if self._closed:
            return
        if not self.failed:
            for blk in self._sample_blocks:
                try:
                    blk.flush()
                except BaseException:  # noqa: BLE001 - recorded in self.failed; close the logs
                    truncated = True
                    reason = reason or self.failed
                    break
        self._closed = True
        self._truncated = truncated
        err = None
        for w in self._opened:
            try:
                w.close(truncated=truncated, reason=reason)
            except RblogError as e:
                err = err or e
        if err is not None:
            raise err

    @property
    def trajectory(self) -> Trajectory:
        """The run recorded so far (needs ``keep``). After a write that raised, its
        ``failed`` says so (and it is ``truncated``): ``rblog.check`` then returns no result with
        ``passed`` (docs/log-format.md, "not judged")."""
        if not self.keep:
            raise RecordError("the Recorder was not asked to keep the run (keep=True)")
        if not self.blocks:
            traj = build_block(self.model, self.info, t=np.zeros(0), step=np.zeros(0, np.int64),
                               position=np.zeros((0, self.model.n_bodies, 3)),
                               quat_wxyz=np.zeros((0, self.model.n_bodies, 4)),
                               velocity=np.zeros((0, self.model.n_bodies, 3)),
                               angular_velocity=np.zeros((0, self.model.n_bodies, 3)))
        else:
            traj = Trajectory.concat(self.blocks)
        traj.truncated = self._truncated or bool(self.failed)
        traj.failed = self.failed
        return traj


class ContactRows(NamedTuple):
    """Views of k contact rows of a :class:`SampleBlock` (see :func:`make_contacts`)."""

    body_a: np.ndarray            # (k,) int64
    body_b: np.ndarray            # (k,) int64, -1 = static geometry
    point: np.ndarray             # (k, 3) m, world
    normal: np.ndarray            # (k, 3) unit, from body_b into body_a
    separation: np.ndarray        # (k,) m, < 0 = penetration
    normal_impulse: np.ndarray    # (k,) N s on body_a
    friction_impulse: np.ndarray  # (k, 3) N s on body_a, world
    kind: np.ndarray              # (k,) int64, 0 resting (or not classified), 1 impact


#: the state arrays build_block takes, with their trailing shapes per body
_STATE_TRAILS = {"position": (3,), "quat_wxyz": (4,), "quat_xyzw": (4,), "rotation": (3, 3),
                 "velocity": (3,), "linear_momentum": (3,), "angular_velocity": (3,),
                 "angular_momentum": (3,)}


class SampleBlock:
    """Preallocated rows for recording one sample at a time at the cost of a copy.

    Arrays (C = capacity rows, N bodies; world frame, the units of :func:`build_block`):
    ``t`` (C,), ``step`` (C,) int64, the state ``fields`` (default ``position`` (C, N, 3),
    ``quat_wxyz`` (C, N, 4), ``velocity`` (C, N, 3), ``angular_velocity`` (C, N, 3); also
    ``rotation`` (C, N, 3, 3), ``linear_momentum``, ``angular_momentum``), and one array per per-interval
    channel the body table declares (``impulse_contact_linear`` (C, N, 3), ``work_actuator``
    (C, N), ...), zero in a fresh row so that a writer can accumulate into it step by step.

    Per sample::

        r = blk.row()                          # the next free row
        blk.t[r] = d.time; blk.step[r] = k
        np.copyto(blk.position[r], x)          # or an engine call with out=blk.position[r]
        ...                                    # quat_wxyz, velocity, angular_velocity, intervals
        c = blk.contact_rows(k)                # optional: this sample's k contact rows, views
        c.normal[:] = ...                      #   to fill in place (or blk.add_contacts(...))
        blk.commit()                           # when the block is full: one Recorder.write

    Everything per block (the derived channels, the encoding, the writers) is compiled or
    vectorized and runs once per ``capacity`` samples; each flush hands fresh arrays to the
    recorder (no copy: a kept block stays valid). :meth:`flush` writes a partial block;
    :meth:`Recorder.close` flushes every block it handed out."""

    def __init__(self, rec: "Recorder", capacity: int,
                 fields=("position", "quat_wxyz", "velocity", "angular_velocity")):
        if capacity < 1:
            raise RecordError(f"sample_block: capacity = {capacity}, expected >= 1")
        bad = sorted(set(fields) - set(_STATE_TRAILS))
        if bad or "position" not in fields:
            raise RecordError(f"sample_block: fields {list(fields)}, expected position and some of "
                              f"{', '.join(k for k in _STATE_TRAILS if k != 'position')}")
        from rblog.record._common import run_interval_channels

        self._fields = tuple(fields)
        self._rec = rec
        self.capacity = capacity
        self._n_bodies = rec.model.n_bodies
        self._interval = run_interval_channels(rec.model)
        self.n = 0
        #: called as ``before_flush(block, k)`` with the k filled rows just before they are
        #: written: a writer fills channels taken over whole intervals there, once per block
        #: (pybullet's integration kind)
        self.before_flush = None
        self._new()

    def _new(self):
        c, n = self.capacity, self._n_bodies
        self.t = np.zeros(c)
        self.step = np.zeros(c, np.int64)
        for name in self._fields:
            setattr(self, name, np.zeros((c, n, *_STATE_TRAILS[name])))
        for name in self._interval:
            setattr(self, name, np.zeros((c, n, *INTERVAL_CHANNELS[name])))
        # contact rows of the block (grown as needed): step, then ContactRows' fields
        self._nc = 0
        self._c_step = np.zeros(0, np.int64)
        self._c_a, self._c_b = np.zeros(0, np.int64), np.zeros(0, np.int64)
        self._c_point, self._c_normal = np.zeros((0, 3)), np.zeros((0, 3))
        self._c_sep, self._c_ln = np.zeros(0), np.zeros(0)
        self._c_fric, self._c_kind = np.zeros((0, 3)), np.zeros(0, np.int64)

    def row(self) -> int:
        """Index of the row the next sample goes in (flushes first if the block is full)."""
        if self.n >= self.capacity:
            self.flush()
        return self.n

    def contact_rows(self, k: int) -> "ContactRows":
        """``k`` contact rows for the sample being filled, as views into the block's
        preallocated contact arrays (fields of :class:`ContactRows`, zero, ``step`` set to the
        sample's): fill them in place (``rows.normal[:] = ...``) before the next call."""
        k = int(k)
        c0 = self._nc
        if c0 + k > len(self._c_step):
            self._grow_contacts(c0 + k)
        self._nc = c0 + k
        self._c_step[c0:c0 + k] = self.step[self.n]
        return ContactRows(*(a[c0:c0 + k] for a in self._c_arrays()))

    def add_contacts(self, **rows) -> None:
        """Contact rows of the sample being filled, from arrays (the fields of
        :func:`make_contacts` but ``step`` and ``t``: the sample's)."""
        unknown = sorted(set(rows) - set(ContactRows._fields))
        if unknown:
            raise RecordError(f"sample_block.add_contacts: unknown field {unknown[0]!r}; the "
                              f"fields are {', '.join(ContactRows._fields)}")
        k = len(np.atleast_1d(np.asarray(rows.get("body_a", ()))))
        out = self.contact_rows(k)
        for name, v in rows.items():
            dst = getattr(out, name)
            try:
                dst[...] = np.asarray(v).reshape(dst.shape)
            except ValueError:
                raise RecordError(f"sample_block.add_contacts: {name} has shape "
                                  f"{np.shape(v)}, expected {dst.shape} ({k} rows)") from None

    def _c_arrays(self):
        return (self._c_a, self._c_b, self._c_point, self._c_normal, self._c_sep, self._c_ln,
                self._c_fric, self._c_kind)

    def _grow_contacts(self, need: int):
        cap = max(need, 2 * len(self._c_step), 64)
        old = (self._c_step, *self._c_arrays())
        new = [np.zeros((cap, *a.shape[1:]), a.dtype) for a in old]
        for a, b in zip(old, new):
            b[:self._nc] = a[:self._nc]
        (self._c_step, self._c_a, self._c_b, self._c_point, self._c_normal, self._c_sep,
         self._c_ln, self._c_fric, self._c_kind) = new

    def commit(self) -> None:
        """The row :meth:`row` returned is filled: count it, and write the block when full."""
        self.n += 1
        if self.n >= self.capacity:
            self.flush()

    def flush(self) -> None:
        """Write the filled rows (if any) through the recorder and start a fresh block."""
        k = self.n
        if not k:
            return
        if self.before_flush is not None:
            self.before_flush(self, k)
        arrays = dict(t=self.t[:k], step=self.step[:k])
        for name in (*self._fields, *self._interval):
            arrays[name] = getattr(self, name)[:k]
        if self._nc:
            c = self._nc
            arrays["contacts"] = dict(zip(("step", *ContactRows._fields),
                                          (a[:c] for a in (self._c_step, *self._c_arrays()))))
        self.n = 0
        self._new()
        self._rec.write(**arrays)


def trajectory_from_arrays(model: Model, *, dt: float = 0.0, writer: str = "",
                           combine_friction: str = "geometric", combine_restitution: str = "max",
                           **arrays) -> Trajectory:
    """A whole run from arrays in memory (no file): ``rblog.check(trajectory_from_arrays(...))``
    audits it as ``rblog check`` audits a log. ``arrays`` as for :func:`build_block`."""
    rec = Recorder(model, dt=dt, writer=writer, combine_friction=combine_friction,
                   combine_restitution=combine_restitution, keep=True)
    with rec:
        rec.write(**arrays)
    traj = rec.trajectory
    from rblog.analyze.consistency import consistency_warnings

    traj.warnings.extend(consistency_warnings(traj))
    return traj


def rewritten(traj: Trajectory, *, writer: str = "rewritten", **arrays) -> Trajectory:
    """``traj`` recorded again in memory with some of its arrays replaced (``position``,
    ``quat_wxyz``, ``velocity``, ``angular_velocity``, ``contacts`` or an interval channel such
    as ``work_passive``; the others as logged): a fault planted in the log only, or a log
    mended, with every check :class:`Recorder` makes run again. The body table, time step,
    stride, integrator, combine rules and engine settings stay the log's."""
    info = traj.info
    given = dict(t=traj.t, step=traj.step, position=traj.position, quat_wxyz=traj.quat_wxyz,
                 velocity=traj.velocity, angular_velocity=traj.angular_velocity,
                 contacts=traj.contacts, **{k: getattr(traj, k) for k in traj.interval_channels})
    unknown = sorted(set(arrays) - set(given) - set(INTERVAL_CHANNELS))
    if unknown:
        raise RecordError(f"rewritten: {', '.join(unknown)}: not arrays of a log (expected "
                          f"{', '.join(sorted(set(given) | set(INTERVAL_CHANNELS)))})")
    given.update(arrays)
    rec = Recorder(traj.model, dt=info.dt, log_every=info.log_every, keep=True, writer=writer,
                   integrator=info.integrator, combine_friction=info.combine_friction,
                   combine_restitution=info.combine_restitution,
                   engine_settings=info.engine_settings)
    with rec:
        rec.write(**given)
    return rec.trajectory


#: scalar-first quaternions -> body->world matrices (re-exported for writers)
quat_to_matrix = quat_wxyz_to_matrix

__all__ = ["CONTACT_ROWS_SEPARATION", "ContactRows", "KIND_VALUES", "Recorder", "RecordError",
           "SampleBlock",
           "body_table", "build_block", "make_contacts", "rewritten",
           "trajectory_from_arrays", "matrix_to_quat", "quat_to_matrix"]
