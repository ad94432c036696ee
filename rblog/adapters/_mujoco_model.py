"""MuJoCo's model in log contract v3: the bodies, joints and geoms of an ``MjModel`` (the
frames and conventions are in :mod:`rblog.adapters.mujoco`'s docstring), MuJoCo's settings and the
contact rows (dm_control's suite models: _mujoco_suite).

Why this module is long: it is the one reading of an MjModel's arrays into the contract's
tables (the layout of bodies and their kinds, joints with their anchors, axes and limits, geoms
with their shapes, materials and filters), each done with numpy over the model's arrays, not a
loop per element; apart, the body, joint and geom readers would each restate the layout."""

from __future__ import annotations

import weakref

import numpy as np

from rblog.adapters import AdapterError, require
from rblog.adapters._common import Fields
from rblog.contract.model import (BODY_FREE, BODY_JOINTED, BODY_KINEMATIC, BODY_STATIC, GEOM_BOX,
                                  GEOM_CAPSULE, GEOM_CYLINDER, GEOM_ELLIPSOID, GEOM_MESH,
                                  GEOM_PLANE, GEOM_SPHERE, IMPULSE_KINDS, JOINT_BALL, JOINT_FIXED,
                                  JOINT_HINGE, JOINT_SLIDE, WORK_KINDS)

#: the contract's value of engine_settings.contact_rows for MuJoCo's contacts
CONTACT_ROWS = {
    "separation": "before the step (contact.dist: the collision detection at its start)",
    "impulse": "mj_contactForce (from efc_force) * timestep, on geom2's body",
    "speculative": "dropped (no force and positive dist)",
    "torques": "torsional and rolling (condim 4, 6) not logged",
}

#: steps whose raw arrays are gathered before they are turned into impulses, vectorized
BLOCK_STEPS = 256

#: MuJoCo geom type (mjtGeom) -> the contract's GEOM_* code; hfield (1) and sdf (8) have none
_GEOM = {0: GEOM_PLANE, 2: GEOM_SPHERE, 3: GEOM_CAPSULE, 4: GEOM_ELLIPSOID, 5: GEOM_CYLINDER,
         6: GEOM_BOX, 7: GEOM_MESH}
#: MuJoCo joint type (mjtJoint) -> JOINT_* (free joints are a body kind, not a row)
_JOINT = {1: JOINT_BALL, 2: JOINT_SLIDE, 3: JOINT_HINGE}


def _mj():
    return require("mujoco")


#: one idle MjData per model, for the recorders' own kinematics (``MjData(m)`` allocates the
#: model's arena and buffer: ~0.8 ms for dm_control's models, 28 MB): :func:`take_scratch` takes
#: it, :func:`give_back` returns it; it lives as long as the model
_SCRATCH = weakref.WeakKeyDictionary()


def take_scratch(m):
    """An ``MjData(m)`` to use alone until :func:`give_back`: the idle one of ``m`` after
    ``mj_resetData`` (the state of a new one), or a new one."""
    mj = _mj()
    try:
        d = _SCRATCH.pop(m, None)
    except TypeError:  # a model a weak reference cannot hold
        d = None
    if d is None:
        return mj.MjData(m)
    mj.mj_resetData(m, d)
    return d


def give_back(m, d) -> None:
    """Make ``d`` (from :func:`take_scratch`, no longer used) the idle MjData of ``m``."""
    try:
        _SCRATCH.setdefault(m, d)
    except TypeError:
        pass


def _one_of(a, values) -> np.ndarray:
    """``np.isin(a, values)`` for a few values (without isin's sort)."""
    a = np.asarray(a)
    return (a[..., None] == np.asarray(values)).any(axis=-1)


def _is_model(m) -> bool:
    return type(m).__name__ == "MjModel"


def _quat_conj(q):
    q = np.asarray(q, np.float64)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def _quat_mats(q) -> np.ndarray:
    """(n, 3, 3) rotation matrices of (n, 4) quaternions (w, x, y, z), each normalized by its
    own ``sqrt(q . q)`` first, then converted in one vectorized call."""
    from rblog.contract.orientation import quat_wxyz_to_matrix

    q = np.asarray(q, np.float64).reshape(-1, 4)
    norm = np.array([np.sqrt(r.dot(r)) for r in q]).reshape(len(q), 1)
    return quat_wxyz_to_matrix(q / norm)


def gravity_of(m) -> np.ndarray:
    """(3,) the gravity MuJoCo applies: ``opt.gravity``, zero when disabled (mjDSBL_GRAVITY)."""
    mj = _mj()
    off = int(m.opt.disableflags) & int(mj.mjtDisableBit.mjDSBL_GRAVITY)
    return np.zeros(3) if off else np.array(m.opt.gravity, np.float64)


class Layout:
    """Where each logged body is in MuJoCo's arrays, and the fixed maps of the per-step hook.

    Attributes: ``body_id`` (N,) MuJoCo body ids (1..nbody-1); ``kind`` (N,) BODY_*;
    ``geom_index`` (ngeom,) the log body of each geom in contact rows (-1: world or a static
    body); ``root`` (nbody,) ``body_rootid``; ``dof_body`` (nv,); ``dof_jnt`` (nv,);
    ``dof_trans`` (nv,) bool, translational dofs (slide, a free joint's first three);
    ``pair`` (nbody, nv): +1 at (dof's body, dof), -1 at (its parent, dof) unless the world;
    ``own`` (nbody, nv): +1 at (dof's body, dof); ``net`` (nbody, nbody): ``cfrc_int`` ->
    the body's own minus its children's; ``subtree`` (nbody, nbody): 1 where b is a or below a;
    ``damping`` (nv,) ``dof_damping``.
    """

    def __init__(self, m):
        nb, nv = int(m.nbody), int(m.nv)
        self.body_id = np.arange(1, nb, dtype=np.int64)
        self.root = np.asarray(m.body_rootid, np.int64)
        parent = np.asarray(m.body_parentid, np.int64)
        self.dof_body = np.asarray(m.dof_bodyid, np.int64)
        self.dof_jnt = np.asarray(m.dof_jntid, np.int64)
        jtype = np.asarray(m.jnt_type, np.int64)[self.dof_jnt] if nv else np.zeros(0, np.int64)
        first = np.asarray(m.jnt_dofadr, np.int64)[self.dof_jnt] if nv else np.zeros(0, np.int64)
        self.dof_trans = (jtype == 2) | ((jtype == 0) & (np.arange(nv) - first < 3))
        self.pair = np.zeros((nb, nv))
        self.own = np.zeros((nb, nv))
        self.pair[self.dof_body, np.arange(nv)] = 1.0
        self.own[self.dof_body, np.arange(nv)] = 1.0
        p = parent[self.dof_body]
        sel = p > 0
        self.pair[p[sel], np.arange(nv)[sel]] -= 1.0
        self.net = np.eye(nb)
        child = np.flatnonzero(parent > 0)
        child = child[child > 0]
        self.net[parent[child], child] -= 1.0
        self.net[0] = 0.0
        self.subtree = np.eye(nb)  # (nbody, nbody): 1 at (a, b), b a or a descendant of a
        below = np.arange(1, nb)
        above = parent[below]
        while len(below):  # one generation of ancestors at a time
            up = above > 0
            below, above = below[up], above[up]
            self.subtree[above, below] = 1.0
            above = parent[above]
        self.damping = np.array(m.dof_damping, np.float64)
        nj = np.asarray(m.body_jntnum, np.int64)[1:]
        first = np.asarray(m.body_jntadr, np.int64)[1:]
        jtype = np.asarray(m.jnt_type, np.int64)
        free = (nj == 1) & (jtype[np.where(nj == 1, first, 0)] == 0) if len(jtype) else nj < 0
        self.kind = np.select(
            [np.asarray(m.body_mocapid)[1:] >= 0, np.asarray(m.body_weldid)[1:] == 0, free],
            [BODY_KINEMATIC, BODY_STATIC, BODY_FREE], BODY_JOINTED).astype(np.int64)
        body_of = np.asarray(m.geom_bodyid, np.int64)
        moving = np.concatenate([[False], self.kind != BODY_STATIC])
        self.geom_index = np.where(moving[body_of], body_of - 1, -1).astype(np.int64)
        self.dynamic = (self.kind == BODY_FREE) | (self.kind == BODY_JOINTED)

    def __len__(self):
        return len(self.body_id)


def _name(mj, m, kind, i, prefix):
    return mj.mj_id2name(m, kind, i) or f"{prefix}{i}"


def unsupported(m) -> list[str]:
    """The elements of ``m`` the log cannot hold: colliding heightfield and SDF geoms, flexes."""
    mj = _mj()
    bad = []
    t = np.asarray(m.geom_type, np.int64)
    colliding = (np.asarray(m.geom_contype) != 0) | (np.asarray(m.geom_conaffinity) != 0)
    for g in np.flatnonzero(~_one_of(t, list(_GEOM)) & colliding).tolist():
        kind = mj.mjtGeom(int(t[g])).name.removeprefix("mjGEOM_").lower()
        bad.append(f"geom {_name(mj, m, mj.mjtObj.mjOBJ_GEOM, g, 'geom')!r} ({kind})")
    for f in range(int(getattr(m, "nflex", 0))):
        bad.append(f"flex {_name(mj, m, mj.mjtObj.mjOBJ_FLEX, f, 'flex')!r}")
    return bad


def inspect(m, d=None, *, restitution=None, scratch=None):
    """The log's model of ``m``: (Model, Layout, notes dict).

    ``restitution``: a scalar or one value per geom to log as the geoms' restitution (default
    NaN, unknown: MuJoCo states none). ``d``: the data whose mocap poses start the run (default
    the model's). ``scratch``: a fresh ``MjData(m)`` to use for the kinematics at ``qpos0``
    (an MjData of a large model costs milliseconds; :class:`MujocoRecorder` hands over the one
    its :class:`Kinematics` keeps). Raises :class:`AdapterError` naming every element that
    cannot be recorded."""
    mj = _mj()
    if not _is_model(m):
        raise AdapterError(f"rblog.adapters.mujoco: m is a {type(m).__name__}, expected a mujoco.MjModel")
    bad = unsupported(m)
    if bad:
        raise AdapterError(f"rblog.adapters.mujoco: the log cannot hold {', '.join(bad)} "
                           "(heightfields, SDF geoms and flexes have no geom type in contract v3)")
    lay = Layout(m)
    n = len(lay)
    d0 = mj.MjData(m) if scratch is None else scratch  # qpos0: the joints' zero position
    if d is not None:
        d0.mocap_pos[:] = d.mocap_pos
        d0.mocap_quat[:] = d.mocap_quat
    mj.mj_kinematics(m, d0)
    d0c = Fields(d0)
    body_name = [_name(mj, m, mj.mjtObj.mjOBJ_BODY, b, "body") for b in range(1, m.nbody)]
    mass = np.array(m.body_mass[1:], np.float64)
    inertia = np.array(m.body_inertia[1:], np.float64)
    parent = np.asarray(m.body_parentid[1:], np.int64) - 1
    parent[lay.kind != BODY_JOINTED] = -1
    # frames: MuJoCo body frame -> the log's (inertial) frame
    ipos = np.asarray(m.body_ipos, np.float64)
    iquat = np.asarray(m.body_iquat, np.float64)
    ri_t = _quat_mats(iquat).transpose(0, 2, 1)  # (nbody, 3, 3) body frame -> inertial frame
    ximat_t = np.asarray(d0c.ximat, np.float64).reshape(-1, 3, 3).transpose(0, 2, 1)
    xipos = np.asarray(d0c.xipos, np.float64)

    def rotate(r, v):  # (k, 3, 3) @ (k, 3): each row's product, as r[i] @ v[i]
        return np.matmul(r, v[:, :, None])[:, :, 0]

    def to_inertial(b, p):  # points in MuJoCo bodies b's frames -> their inertial frames
        p = np.asarray(p, np.float64).reshape(-1, 3)
        return np.where((b > 0)[:, None], rotate(ri_t[b], p - ipos[b]), p)

    def world_to_inertial(b, p):  # world points at qpos0 -> bodies b's inertial frames
        p = np.asarray(p, np.float64).reshape(-1, 3)
        return np.where((b > 0)[:, None], rotate(ximat_t[b], p - xipos[b]), p)

    def world_dir_to_inertial(b, v):
        v = np.asarray(v, np.float64).reshape(-1, 3)
        return np.where((b > 0)[:, None], rotate(ximat_t[b], v), v)

    # joints: each jointed body's joints in MuJoCo's order, or one fixed row when it has none
    # (welded to a moving parent: a fixed joint at the centre of mass)
    mc = Fields(m)  # the bindings' arrays, each fetched once
    dof_arm = np.asarray(mc.dof_armature, np.float64)
    bodies = np.flatnonzero(lay.kind == BODY_JOINTED) + 1
    count = np.asarray(mc.body_jntnum, np.int64)[bodies]
    rows = np.maximum(count, 1)
    jbody = np.repeat(bodies, rows)  # the MuJoCo body of each row
    within = np.arange(len(jbody)) - np.repeat(np.cumsum(rows) - rows, rows)
    welded = np.repeat(count, rows) == 0
    first = np.repeat(np.asarray(mc.body_jntadr, np.int64)[bodies], rows)
    jid = np.where(welded, -1, first + within)  # the MuJoCo joint of each row, -1: welded
    jpar = np.asarray(mc.body_parentid, np.int64)[jbody]
    hinged = jid[~welded]
    raw = np.asarray(mc.jnt_type, np.int64)[hinged]
    codes = np.array([_JOINT[t] for t in raw.tolist()], np.int64)
    nj = len(jbody)
    jt = np.full(nj, JOINT_FIXED, np.int64)
    jt[~welded] = codes
    ball = jt == JOINT_BALL
    ab, xb, xp = np.zeros((nj, 3)), np.zeros((nj, 3)), np.zeros((nj, 3))
    ab[~welded] = to_inertial(jbody[~welded], np.asarray(mc.jnt_pos, np.float64)[hinged])
    anchor = np.asarray(d0c.xanchor, np.float64)
    ap = world_to_inertial(jpar, np.where(welded[:, None], xipos[jbody],
                                          anchor[np.maximum(jid, 0)] if len(anchor) else 0.0))
    axial = ~welded & ~ball
    jx = jid[axial]
    xb[axial] = rotate(ri_t[jbody[axial]], np.asarray(mc.jnt_axis, np.float64)[jx])
    xp[axial] = world_dir_to_inertial(jpar[axial], np.asarray(d0c.xaxis, np.float64)[jx])
    # armature: the dofs' common value (a ball's three), NaN when they differ
    ja = np.zeros(nj)
    adr = np.asarray(mc.jnt_dofadr, np.int64)[hinged]
    ndof = np.where(codes == JOINT_BALL, 3, 1)
    arm = dof_arm[np.minimum(adr[:, None] + np.arange(3), max(len(dof_arm) - 1, 0))] \
        if len(adr) else np.zeros((0, 3))
    same = np.all((arm == arm[:, :1]) | (np.arange(3) >= ndof[:, None]), axis=1)
    ja[~welded] = np.where(same, arm[:, 0] if len(adr) else np.zeros(0), np.nan)
    jr = np.full((nj, 2), np.nan)
    lim = np.asarray(mc.jnt_range, np.float64)[hinged]
    limited = np.asarray(mc.jnt_limited)[hinged] != 0
    top = np.where(lim[:, 1] > lim[:, 0], lim[:, 1], lim[:, 0])  # max(lo, hi), as Python's
    lim = np.where((codes == JOINT_BALL)[:, None], np.stack([np.zeros(len(lim)), top], axis=1), lim)
    jr[~welded] = np.where(limited[:, None], lim, np.nan)
    jn = [f"{body_name[b - 1]} (welded)" if j < 0 else _name(mj, m, mj.mjtObj.mjOBJ_JOINT, j, "joint")
          for b, j in zip(jbody.tolist(), jid.tolist())]
    jb = jbody - 1
    # geoms
    gtype = np.asarray(mc.geom_type, np.int64)
    kept = _one_of(gtype, list(_GEOM))
    keep = np.flatnonzero(kept)
    skipped = [f"{_name(mj, m, mj.mjtObj.mjOBJ_GEOM, g, 'geom')} "
               f"({mj.mjtGeom(int(gtype[g])).name.removeprefix('mjGEOM_').lower()}, no collision)"
               for g in np.flatnonzero(~kept).tolist()]
    ng = len(keep)
    gb = np.asarray(mc.geom_bodyid, np.int64)[keep]
    g_type = np.array([_GEOM[t] for t in gtype[keep].tolist()], np.int64).reshape(ng)
    g_name = [mj.mj_id2name(m, mj.mjtObj.mjOBJ_GEOM, g) or "" for g in keep.tolist()]
    g_pos = to_inertial(gb, np.asarray(mc.geom_pos, np.float64)[keep])
    g_size = np.array(np.asarray(mc.geom_size, np.float64)[keep]).reshape(ng, 3)
    g_size[g_type == GEOM_SPHERE, 1:] = 0.0
    g_size[_one_of(g_type, (GEOM_CAPSULE, GEOM_CYLINDER, GEOM_PLANE)), 2] = 0.0
    g_size[g_type == GEOM_MESH] = 0.0
    g_vert = [None] * ng
    for i in np.flatnonzero(g_type == GEOM_MESH).tolist():
        mesh = int(mc.geom_dataid[keep[i]])
        a, k = int(mc.mesh_vertadr[mesh]), int(mc.mesh_vertnum[mesh])
        g_vert[i] = np.array(mc.mesh_vert[a:a + k], np.float64)
    # (ng, 4) each geom's orientation in its body's inertial frame: conj(iquat) * geom_quat, one
    # vectorized product (elementwise, the bits of one product per geom); the world's as given
    from rblog.adapters._common import quat_mul

    gq = np.asarray(mc.geom_quat, np.float64)[keep].reshape(ng, 4)
    g_quat = np.where((gb > 0)[:, None], quat_mul(_quat_conj(iquat[gb]), gq), gq)
    nan = float("nan")
    rest = np.broadcast_to(np.asarray(nan if restitution is None else restitution, np.float64), (ng,))
    geoms = dict(body=(gb - 1).reshape(ng), type=g_type, size=g_size, pos_body=g_pos.reshape(ng, 3),
                 quat_wxyz_body=g_quat,
                 friction=np.array(np.asarray(mc.geom_friction, np.float64)[keep, 0]).reshape(ng),
                 restitution=rest.copy(),
                 collide_group=np.asarray(mc.geom_contype, np.int64)[keep].reshape(ng),
                 collide_mask=np.asarray(mc.geom_conaffinity, np.int64)[keep].reshape(ng),
                 name=g_name, mesh_vert=g_vert)
    joints = dict(body=jb.reshape(nj), type=jt.reshape(nj),
                  anchor_body=ab.reshape(nj, 3), anchor_parent=ap.reshape(nj, 3),
                  axis_body=xb.reshape(nj, 3), axis_parent=xp.reshape(nj, 3),
                  range=jr.reshape(nj, 2), armature=ja.reshape(nj), name=jn)
    from rblog.contract.model import SUPPLIED_LOGGED, SUPPLIED_MISSING, SUPPLIED_NONE

    supplied = np.where(np.repeat(lay.dynamic[:, None], len(IMPULSE_KINDS), axis=1),
                        SUPPLIED_LOGGED, SUPPLIED_MISSING)
    # a free joint exerts nothing: on a free body that carries no other body the Newton-Euler
    # residual the hook computes is the step's integration error (round-off under Euler, RK4's
    # stage differences under RK4), not a load. (A free body with children gets their joints'
    # reactions.)
    has_children = np.zeros(len(parent), bool)
    has_children[parent[parent >= 0]] = True
    supplied[(lay.kind == BODY_FREE) & ~has_children, IMPULSE_KINDS.index("joint")] = \
        SUPPLIED_NONE
    # the integration kind (MujocoRecorder._integration) and the joint work (limits, friction
    # loss, equalities) where the joint kind is logged: a joint impulse is MuJoCo's Newton-Euler
    # residual at the step's start, the integration kind the rest of the step (a centre of mass
    # moves by J(q) qdot). A lone free body has neither: its step's error (Euler's explicit
    # gyroscopic term) stays in its balance, for the momentum analyzer to report
    lone = supplied[:, IMPULSE_KINDS.index("joint")] == SUPPLIED_NONE
    supplied[lone, IMPULSE_KINDS.index("integration")] = SUPPLIED_NONE
    work = np.where(np.repeat(lay.dynamic[:, None], len(WORK_KINDS), axis=1), SUPPLIED_LOGGED,
                    SUPPLIED_MISSING)
    work[lone, WORK_KINDS.index("joint")] = SUPPLIED_NONE
    from rblog.record.recorder import body_table

    # kinematic and static bodies may be massless in MuJoCo; the table needs positive numbers
    # there too (their momenta are not judged)
    mass_t = np.where(lay.dynamic | (mass > 0), mass, 1.0)
    inertia_t = np.where((lay.dynamic | np.all(inertia > 0, axis=1))[:, None], inertia, 1.0)
    model = body_table(name=body_name, mass=mass_t, inertia_diag=inertia_t, kind=lay.kind,
                       parent=parent, geoms=geoms, joints=joints, collide_rule="or",
                       impulses=supplied, work=work, gravity=gravity_of(m))
    notes = {"geoms_not_recorded": skipped,
             "restitution": ("not stated by MuJoCo (solref spring-damper): unknown (NaN)"
                             if restitution is None else "given by the caller"),
             "collision_filter": "contype/conaffinity ('or'); MuJoCo also skips parent-child "
                                 "pairs (filterparent) and <exclude> pairs, and <pair> overrides",
             "impulses": "per step from mj_rnePostConstraint at the step's start "
                         "(rblog.adapters.mujoco); RK4: the first stage's forces",
             "free_bodies_with_armature_not_logged": [body_name[b - 1] for b in set(lay.dof_body[dof_arm > 0]) if lay.kind[b - 1] == BODY_FREE],  # noqa: E501
             "massless_bodies_logged_with_unit_mass": [body_name[i] for i in range(n)
                                                       if not lay.dynamic[i] and not mass[i] > 0]}
    return model, lay, notes


#: efc rows gathered per contact: a pyramidal condim-6 contact has 10 (2 per tangent direction)
_EFC_WIDTH = 10


#: the mjContact fields the rows need
_CONTACT_FIELDS = ("dist", "pos", "frame", "friction", "dim", "geom", "exclude", "efc_address")


class _ContactArray:
    """A numpy view of MuJoCo's contact array (mjContact structs at the start of ``d``'s
    arena, which stays where it is) as a structured array of the fields the rows need, with
    their offsets and the struct's size read off the bindings' own views of one contact."""

    def __init__(self, m, d):
        import ctypes

        con = d.contact
        views = {f: getattr(con, f) for f in _CONTACT_FIELDS}
        base = views["dist"].__array_interface__["data"][0]
        stride = views["dist"].strides[0]
        fields = {}
        for f, v in views.items():
            off = v.__array_interface__["data"][0] - base
            if not 0 <= off < stride or v.strides[0] != stride:
                raise ValueError(f"mjContact.{f} at {off}, stride {v.strides[0]}")
            fields[f] = (np.dtype((v.dtype, v.shape[1:])) if v.ndim > 1 else v.dtype, off)
        self.dtype = np.dtype({"names": list(fields), "formats": [t for t, _ in fields.values()],
                               "offsets": [o for _, o in fields.values()], "itemsize": stride})
        count = max(1, int(m.narena) // stride)
        self.count = count
        self.base = base
        buf = (ctypes.c_char * (count * stride)).from_address(base)
        self.view = np.frombuffer(buf, dtype=self.dtype, count=count)


def capture_contacts(d, step: int, array: "_ContactArray | None" = None):
    """The raw contact data of ``d`` right after ``mj_step`` (copies; decoded later, a block at a
    time, by :func:`decode_contacts`), or None when there are none. With ``array`` (a
    :class:`_ContactArray` of ``d``) the structs are copied in one piece."""
    k = int(d.ncon)
    if k == 0:
        return None
    ef = d.efc_force
    if array is not None and k <= array.count:
        return (int(step), array.view[:k].copy(), ef.copy())
    con = d.contact
    raw = np.empty(k, _contact_dtype(con))
    for f in _CONTACT_FIELDS:
        raw[f] = getattr(con, f)[:k]
    return (int(step), raw, ef.copy())


def _contact_dtype(con):
    v = {f: getattr(con, f) for f in _CONTACT_FIELDS}
    return np.dtype([(f, a.dtype, a.shape[1:]) for f, a in v.items()])


def _contact_dict(raws):
    """The raw captures of several steps as one dict of arrays (K rows)."""
    counts = np.array([len(r) for _, r, _ in raws])
    steps = np.array([st for st, _, _ in raws], np.int64)
    dt = raws[0][1].dtype  # as raw bytes: concatenating structured arrays is ~100x slower
    one = all(r.dtype == dt for _, r, _ in raws)
    raw = np.concatenate([r.view(np.dtype((np.void, dt.itemsize))) if one else r for _, r, _ in raws])
    raw = raw.view(dt) if one else raw
    sizes = np.array([len(e) for _, _, e in raws])
    return _packed_contact_dict(steps, counts, raw, sizes, np.concatenate([e for _, _, e in raws]))


def _packed_contact_dict(steps, counts, raw, sizes, efc):
    """The captures of S steps as one dict of arrays (K rows): steps, counts (S,) the step and
    contact count of each capture, raw (K,) the mjContact fields, sizes (S,) the length of each
    capture's efc_force, efc (sum(sizes),) those arrays back to back."""
    steps = np.repeat(np.asarray(steps, np.int64), counts)
    efc_all = np.concatenate([efc, np.zeros(1)])
    base = np.repeat(np.cumsum(sizes) - sizes, counts)
    adr = raw["efc_address"].astype(np.int64)
    idx = np.clip(np.where(adr >= 0, adr + base, 0)[:, None] + np.arange(_EFC_WIDTH), 0, len(efc_all) - 1)
    return dict(step=steps, geom=raw["geom"], adr=adr, dim=raw["dim"], mu=raw["friction"][:, :2],
                exclude=raw["exclude"], frame=raw["frame"], dist=raw["dist"], pos=raw["pos"],
                efc=efc_all[idx])


def decode_contacts(m, layout: Layout, raws, packed=None):
    """Contact rows in the contract's convention (dict for Recorder.write, or None) from the
    :func:`capture_contacts` of one or more steps, or from ``packed``: the
    :func:`_packed_contact_dict` of a ``rblog.adapters._hook.ContactCapture``'s steps."""
    raws = [r for r in raws if r is not None]
    if packed is not None and raws:  # both (an MjData the compiled capture cannot read): merge
        a, b = _contact_dict(raws), packed
        order = np.argsort(np.concatenate([a["step"], b["step"]]), kind="stable")
        raw = {k: np.concatenate([a[k], b[k]])[order] for k in a}
    elif packed is not None:
        raw = packed
    elif raws:
        raw = _contact_dict(raws)
    else:
        return None
    k = len(raw["step"])
    adr, dim, mu, f = raw["adr"], raw["dim"], raw["mu"], raw["efc"]
    local = np.zeros((k, 3))  # (normal, tangent 1, tangent 2) force on geom2, contact frame
    ok = (adr >= 0) & (raw["exclude"] == 0)
    pyramidal = int(m.opt.cone) == int(_mj().mjtCone.mjCONE_PYRAMIDAL)
    one = ok & (dim == 1)
    local[one, 0] = f[one, 0]
    many = ok & (dim > 1)
    if many.any():
        if pyramidal:  # 2 (dim - 1) edges: normal = their sum, tangent j = mu_j (f_2j - f_2j+1)
            width = 2 * (dim[many] - 1)
            e = np.where(np.arange(_EFC_WIDTH) < width[:, None], f[many], 0.0)
            local[many, 0] = e.sum(axis=1)
            local[many, 1] = mu[many, 0] * (e[:, 0] - e[:, 1])
            local[many, 2] = mu[many, 1] * (e[:, 2] - e[:, 3])
        else:  # elliptic: normal, then the tangents (then torques), contact frame
            local[many] = f[many, :3]
    frame = raw["frame"].reshape(k, 3, 3)
    normal = frame[:, 0].copy()
    fric = local[:, 1:2] * frame[:, 1] + local[:, 2:3] * frame[:, 2]
    geom = raw["geom"]
    body_a = layout.geom_index[geom[:, 1]].copy()
    body_b = layout.geom_index[geom[:, 0]].copy()
    flip = body_a < 0  # the static geometry is body_b in the contract
    body_a[flip], body_b[flip] = body_b[flip], body_a[flip]
    normal[flip] *= -1.0
    fric[flip] *= -1.0
    dist = raw["dist"]
    keep = ok & (body_a >= 0) & ~((local[:, 0] <= 0.0) & (dist > 0.0))
    if not keep.any():
        return None
    dt = float(m.opt.timestep)
    return dict(step=raw["step"][keep], body_a=body_a[keep], body_b=body_b[keep],
                point=raw["pos"][keep], normal=normal[keep], separation=dist[keep],
                normal_impulse=local[keep, 0] * dt, friction_impulse=fric[keep] * dt)


def contacts(m, d, layout: Layout, step: int):
    """The contact rows of the step that ended at ``step`` (``d`` right after ``mj_step``), in the
    contract's convention, as a dict for Recorder.write; None when there are none."""
    return decode_contacts(m, layout, [capture_contacts(d, step)])


def state_offsets(m, spec=None) -> tuple[int, int, int]:
    """Offsets of time, qpos and qvel in a state vector of ``spec`` (default
    ``mjSTATE_FULLPHYSICS``, what ``mujoco.rollout`` returns)."""
    mj = _mj()
    s = mj.mjtState
    spec = int(s.mjSTATE_FULLPHYSICS if spec is None else spec)
    need = (int(s.mjSTATE_TIME), int(s.mjSTATE_QPOS), int(s.mjSTATE_QVEL))
    if any(not spec & bit for bit in need):
        raise AdapterError("record_rollout: the state spec must hold time, qpos and qvel "
                           "(mjSTATE_FULLPHYSICS, as mujoco.rollout returns)")
    offsets, pos = {}, 0
    for bit in range(int(s.mjNSTATE)):
        if spec & (1 << bit):
            offsets[1 << bit] = pos
            pos += int(mj.mj_stateSize(m, 1 << bit))
    return tuple(offsets[b] for b in need)


def settings(m) -> dict:
    """MuJoCo's solver settings for RunInfo.engine_settings."""
    mj = _mj()
    o = m.opt
    return {
        "engine": "mujoco", "version": mj.__version__,
        "integrator": mj.mjtIntegrator(o.integrator).name.removeprefix("mjINT_"),
        "solver": mj.mjtSolver(o.solver).name.removeprefix("mjSOL_"),
        "cone": mj.mjtCone(o.cone).name.removeprefix("mjCONE_"),
        "iterations": int(o.iterations), "ls_iterations": int(o.ls_iterations),
        "tolerance": float(o.tolerance), "noslip_iterations": int(o.noslip_iterations),
        "impratio": float(o.impratio), "timestep": float(o.timestep),
        "disableflags": int(o.disableflags), "enableflags": int(o.enableflags),
        "contact_model": "soft (solref, solimp per geom or pair)",
        "combine_native": {"friction": "max", "solref": "solmix-weighted mean"},
        "contact_rows": dict(CONTACT_ROWS),
    }
