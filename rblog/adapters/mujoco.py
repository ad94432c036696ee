"""Record a MuJoCo model as shipped (every body, joint and geom) into log contract v3.

Two lines::

    rec = rblog.adapters.mujoco.recorder(m, d, mcap="run.mcap", every=1)  # the model, sample 0
    for _ in range(n): mujoco.mj_step(m, d); rec(d)                        # after every step
    rec.close()                                    # or `with`; rblog.check(rblog.load("run.mcap"))

``rec(d)`` is called after **every** ``mj_step``: it accumulates that step's impulses (cheap:
one ``mj_rnePostConstraint`` and a few array copies) and every ``every``-th step it logs a
sample (the state, the contacts of that step, and the impulses summed over the interval since
the previous sample). A call after several steps (``d.time`` moved by more than one
``timestep``) logs its sample with that interval's impulses and work as NaN (unknown), so the
analyzers leave it unjudged. For a rollout, ``record_rollout(m, initial_state, state)`` (no
contacts, no impulses: the log says they are missing).

MuJoCo's model, as the log holds it (docs/log-format.md):

* **bodies**: every MuJoCo body but the world, in MuJoCo's order (log index = body id - 1),
  named as MuJoCo names them: a body with a free joint is ``free``; with other joints
  ``joints`` (its parent ``body_parentid``); a body without joints welded to a moving parent is
  ``joints`` with one ``fixed`` joint row; a mocap body ``kinematic``; a body welded to the
  world ``static``. The log's body frame is MuJoCo's **inertial frame** (``xipos``/``ximat``:
  centre of mass, principal axes of ``body_inertia``), so geoms and joint anchors are turned
  out of the body frame (``xpos``/``xmat``) with ``body_ipos``/``body_iquat``.
* **joints**: hinge, slide and ball as MuJoCo has them (``jnt_pos``, ``jnt_axis`` in the child;
  the same point and axis in the parent's frame at ``qpos0``), ``jnt_range`` where
  ``jnt_limited`` (a ball's range is ``[0, max angle]``). Planar bodies (slide-slide-hinge)
  are three rows on one body, as MuJoCo has them.
* **geoms**: every geom, with MuJoCo's shape and size (sphere, capsule ``[r, half-length]``,
  cylinder, ellipsoid, box, plane ``[hx, hy]`` (0: infinite)), meshes with their vertices
  (``mesh_vert`` rows ``mesh_vertadr``.. in the geom frame: MuJoCo collides with their convex
  hull); friction ``geom_friction[:, 0]`` (MuJoCo takes the max of a pair), restitution
  unknown (NaN: MuJoCo's bounce comes from solref) unless given, the filter
  ``contype``/``conaffinity`` under ``collide_rule = "or"``. Heightfields, SDF geoms and flexes
  cannot be recorded: :func:`inspect` raises one line naming every one of them.
* **state**: from a private ``MjData`` after ``mj_kinematics``, ``mj_comPos``, ``mj_comVel`` at
  the logged ``qpos``/``qvel``: position ``xipos``, rotation ``ximat``, angular velocity
  ``cvel[:, :3]`` and the centre of mass's velocity ``cvel[:, 3:] + w x (xipos - c)``
  (``cvel`` is about ``c = subtree_com[body_rootid]``, world-oriented). Mocap bodies move
  with ``mocap_pos``/``mocap_quat`` and have zero velocity (MuJoCo's own ``cvel``).
* **contacts**: the rows of v2 (mj_contactForce's force on geom2 x ``timestep``, decoded from
  ``efc_force`` for all contacts at once); geoms of static bodies are the world (-1).

Per-interval impulses (N s, N m s about each body's centre of mass, world frame), per step
``s`` from MuJoCo's own numbers, then summed over the steps of each interval:

* After ``mj_step`` with Euler or the implicit integrators, ``d`` holds the step's start:
  kinematics (``xipos``, ``cdof``, ``subtree_com``), contacts and ``efc_force``, the
  generalized forces ``qfrc_*``; ``qvel`` is the new one. The hook puts the step's start
  velocity ``v0`` and the acceleration MuJoCo integrated, ``a = (v1 - v0) / h``, into ``d``,
  calls ``mj_rnePostConstraint`` (``cfrc_ext``: ``xfrc_applied`` and the contacts;
  ``cfrc_int``: the wrench each body's subtree receives from its parent, gravity included
  through ``cacc[world] = -g``), and puts ``qvel``/``qacc`` back. MuJoCo's spatial wrenches are
  ``[torque; force]`` about ``c`` (world orientation); a torque about the centre of mass is
  ``tau_c - (xipos - c) x f``.
* contact = ``cfrc_ext`` minus ``xfrc_applied``; applied = ``xfrc_applied`` (at the centre
  of mass) plus ``qfrc_applied``; passive = ``qfrc_passive``, and under Euler/implicit(fast)
  with ``dof_damping`` the damping MuJoCo integrates implicitly, ``- B (v1 - v0)`` (Euler
  solves ``(M + h B) a = f``, i.e. ``M a = f - h B a``); actuator = ``qfrc_actuator``. A
  generalized force ``f_j`` on dof ``j`` of body ``b`` is the wrench ``f_j S_j`` on ``b`` and
  ``-f_j S_j`` on its parent (none on the world), with ``S_j`` the couple along the axis of a
  rotational dof (``cdof[j, :3]``) or the force along a translational one through the joint's
  anchor: ``S_j . cdof_j = 1``, so the pair does the work ``f_j qvel_j``. joint = the net of
  ``cfrc_int`` (the body's own minus its children's) minus the generalized forces mapped to
  the body: the constraint reactions, limits, frictionloss, tendon equalities (and, under
  implicitfast / implicit, the part of ``h D a`` that is not ``dof_damping``: actuator and
  tendon velocity derivatives).
* work (J) per step: ``h f_j v1_j`` of each dof's force, attributed to the dof's body (the
  displacement the semi-implicit step makes is ``h v1``); for ``xfrc_applied`` ``h (f . v +
  tau . w)`` at the step's start.

The balance this gives, per body and step: ``m (v_com(q1, v1) - v_com(q0, v0)) = h (sum of the
impulses) + m g h + K``. The forces are MuJoCo's at the step's start and close Newton-Euler
exactly there (``cfrc_int`` is its residual); ``K`` is the integration error of MuJoCo's step
seen at the centre of mass: MuJoCo integrates generalized velocities, and ``v_com = J(q) v`` is
not linear in them. For a free body (its free joint's origin velocity ``u`` and body-frame
angular velocity integrate linearly; ``R1 w_b1 = R0 exp(h w_b1) w_b1 = R0 w_b1``), with
``arm = R ipos``, ``w`` world:

    K = m [ w1 x (arm1 - arm0) - h w0 x (w0 x arm0) ]            (O(h^2); 0 when ipos = 0)

and the tests check the free bodies' logged impulses against it at round-off (``m g h`` +
impulses + K = Δp to 1e-9 relative). Bodies on joints have ``K = m (J(q1) - J(q0) - h
dJ/dt) v``-like terms, O(h^2) per step: measured in tests/adapters (and 0 to round-off for a
body on slides whose centre of mass is on the slides, as stacker's boxes).

**RK4** re-evaluates the forces at three more states inside the step and leaves ``d`` with the
last one's, so the hook runs ``mj_forward`` at the step's start on a private ``MjData`` and logs
the forces of the first stage; ``a = (v1 - v0) / h`` is RK4's weighted mean of the four stages,
so the joint impulses (the Newton-Euler residual) close each body's balance as above, and the
other kinds are the first stage's: a free body's balance then misses ``h sum_i b_i (F_i - F_1)
= O(h^2) dF/dt``, which a log cannot carry.

**Cost** per step (``rec(d)``): ``mj_rnePostConstraint`` (~1 us) with ``qvel``/``qacc`` swapped
in and back, and a few copies of contiguous pieces of mjData into a preallocated row
(:class:`Rows`); per sample the contacts' raw ``mjContact`` structs and ``efc_force``. A
sample's state is the next step's row (its start is the sample's state) under Euler and the
implicit integrators without mocap bodies, else :class:`Kinematics`. Every BLOCK_STEPS steps
the rows are resolved into impulses, vectorized, and written as one block. Measured with
benchmarks/bench_adapters.py (CPU time against the bare ``mj_step`` loop; RESULTS.md).
"""

from __future__ import annotations

import numpy as np

from rblog.adapters import AdapterError, require
from rblog.contract.model import (BODY_FREE, BODY_JOINTED, BODY_KINEMATIC, BODY_STATIC, GEOM_BOX,
                                  GEOM_CAPSULE, GEOM_CYLINDER, GEOM_ELLIPSOID, GEOM_MESH,
                                  GEOM_PLANE, GEOM_SPHERE, IMPULSE_KINDS, JOINT_BALL, JOINT_FIXED,
                                  JOINT_HINGE, JOINT_SLIDE, WORK_KINDS, Model)

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


def _is_model(m) -> bool:
    return type(m).__name__ == "MjModel"


def _quat_conj(q):
    q = np.asarray(q, np.float64)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def _quat_mat(q) -> np.ndarray:
    """(3, 3) rotation matrix of a unit quaternion (w, x, y, z)."""
    from rblog.contract.orientation import quat_wxyz_to_matrix

    q = np.asarray(q, np.float64)
    return quat_wxyz_to_matrix(q / np.linalg.norm(q))


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
    the body's own minus its children's; ``damping`` (nv,) ``dof_damping``.
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
        for b in range(1, nb):
            if parent[b] > 0:
                self.net[parent[b], b] -= 1.0
        self.net[0] = 0.0
        self.damping = np.array(m.dof_damping, np.float64)
        self.kind = np.full(nb - 1, BODY_FREE, np.int64)
        weld = np.asarray(m.body_weldid)
        for b in range(1, nb):
            nj = int(m.body_jntnum[b])
            if int(m.body_mocapid[b]) >= 0:
                self.kind[b - 1] = BODY_KINEMATIC
            elif int(weld[b]) == 0:
                self.kind[b - 1] = BODY_STATIC
            elif nj == 1 and int(m.jnt_type[m.body_jntadr[b]]) == 0:
                self.kind[b - 1] = BODY_FREE
            else:
                self.kind[b - 1] = BODY_JOINTED
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
    for g in range(int(m.ngeom)):
        t = int(m.geom_type[g])
        if t not in _GEOM and (int(m.geom_contype[g]) or int(m.geom_conaffinity[g])):
            kind = mj.mjtGeom(t).name.removeprefix("mjGEOM_").lower()
            bad.append(f"geom {_name(mj, m, mj.mjtObj.mjOBJ_GEOM, g, 'geom')!r} ({kind})")
    for f in range(int(getattr(m, "nflex", 0))):
        bad.append(f"flex {_name(mj, m, mj.mjtObj.mjOBJ_FLEX, f, 'flex')!r}")
    return bad


def inspect(m, d=None, *, restitution=None):
    """The log's model of ``m``: (Model, Layout, notes dict).

    ``restitution``: a scalar or one value per geom to log as the geoms' restitution (default
    NaN, unknown: MuJoCo states none). ``d``: the data whose mocap poses start the run (default
    the model's). Raises :class:`AdapterError` naming every element that cannot be recorded."""
    mj = _mj()
    if not _is_model(m):
        raise AdapterError(f"rblog.adapters.mujoco: m is a {type(m).__name__}, expected a mujoco.MjModel")
    bad = unsupported(m)
    if bad:
        raise AdapterError(f"rblog.adapters.mujoco: the log cannot hold {', '.join(bad)} "
                           "(heightfields, SDF geoms and flexes have no geom type in contract v3)")
    lay = Layout(m)
    n = len(lay)
    d0 = mj.MjData(m)  # qpos0: the joints' zero position
    if d is not None:
        d0.mocap_pos[:] = d.mocap_pos
        d0.mocap_quat[:] = d.mocap_quat
    mj.mj_kinematics(m, d0)
    body_name = [_name(mj, m, mj.mjtObj.mjOBJ_BODY, b, "body") for b in range(1, m.nbody)]
    mass = np.array(m.body_mass[1:], np.float64)
    inertia = np.array(m.body_inertia[1:], np.float64)
    parent = np.asarray(m.body_parentid[1:], np.int64) - 1
    parent[lay.kind != BODY_JOINTED] = -1
    # frames: MuJoCo body frame -> the log's (inertial) frame
    ipos = np.asarray(m.body_ipos, np.float64)
    iquat = np.asarray(m.body_iquat, np.float64)
    ri = [_quat_mat(q) for q in iquat]

    def to_inertial(b, p):  # a point in MuJoCo body b's frame -> its inertial frame
        return ri[b].T @ (np.asarray(p, np.float64) - ipos[b]) if b else np.asarray(p, np.float64)

    def world_to_inertial(b, p):  # a world point at qpos0 -> body b's inertial frame
        if b == 0:
            return np.asarray(p, np.float64).copy()
        return d0.ximat[b].reshape(3, 3).T @ (np.asarray(p, np.float64) - d0.xipos[b])

    def world_dir_to_inertial(b, v):
        return np.asarray(v, np.float64).copy() if b == 0 else d0.ximat[b].reshape(3, 3).T @ v

    # joints
    jn, jt, jb, ab, ap, xb, xp, jr = [], [], [], [], [], [], [], []
    for b in range(1, m.nbody):
        if lay.kind[b - 1] != BODY_JOINTED:
            continue
        pb = int(m.body_parentid[b])
        nj = int(m.body_jntnum[b])
        if nj == 0:  # welded to a moving parent: a fixed joint at the centre of mass
            jn.append(f"{body_name[b - 1]} (welded)")
            jt.append(JOINT_FIXED)
            jb.append(b - 1)
            ab.append(np.zeros(3))
            ap.append(world_to_inertial(pb, d0.xipos[b]))
            xb.append(np.zeros(3))
            xp.append(np.zeros(3))
            jr.append([np.nan, np.nan])
            continue
        for j in range(int(m.body_jntadr[b]), int(m.body_jntadr[b]) + nj):
            t = _JOINT[int(m.jnt_type[j])]
            jn.append(_name(mj, m, mj.mjtObj.mjOBJ_JOINT, j, "joint"))
            jt.append(t)
            jb.append(b - 1)
            ab.append(to_inertial(b, m.jnt_pos[j]))
            ap.append(world_to_inertial(pb, d0.xanchor[j]))
            if t == JOINT_BALL:
                xb.append(np.zeros(3))
                xp.append(np.zeros(3))
            else:
                xb.append(ri[b].T @ np.asarray(m.jnt_axis[j], np.float64))
                xp.append(world_dir_to_inertial(pb, d0.xaxis[j]))
            lo, hi = (float(v) for v in m.jnt_range[j])
            if not int(m.jnt_limited[j]):
                jr.append([np.nan, np.nan])
            elif t == JOINT_BALL:
                jr.append([0.0, max(lo, hi)])
            else:
                jr.append([lo, hi])
    # geoms
    gtype = np.asarray(m.geom_type, np.int64)
    keep = [g for g in range(m.ngeom) if int(gtype[g]) in _GEOM]
    skipped = [f"{_name(mj, m, mj.mjtObj.mjOBJ_GEOM, g, 'geom')} "
               f"({mj.mjtGeom(int(gtype[g])).name.removeprefix('mjGEOM_').lower()}, no collision)"
               for g in range(m.ngeom) if int(gtype[g]) not in _GEOM]
    g_body, g_type, g_pos, g_quat, g_size, g_vert, g_name = [], [], [], [], [], [], []
    for g in keep:
        b = int(m.geom_bodyid[g])
        code = _GEOM[int(gtype[g])]
        g_body.append(b - 1)
        g_type.append(code)
        g_name.append(mj.mj_id2name(m, mj.mjtObj.mjOBJ_GEOM, g) or "")
        g_pos.append(to_inertial(b, m.geom_pos[g]))
        from rblog.adapters._common import quat_mul

        q = np.asarray(m.geom_quat[g], np.float64)
        g_quat.append(quat_mul(_quat_conj(iquat[b]), q) if b else q.copy())
        s = np.array(m.geom_size[g], np.float64)
        if code == GEOM_SPHERE:
            s[1:] = 0.0
        elif code in (GEOM_CAPSULE, GEOM_CYLINDER, GEOM_PLANE):
            s[2] = 0.0
        elif code == GEOM_MESH:
            s[:] = 0.0
        g_size.append(s)
        if code == GEOM_MESH:
            mesh = int(m.geom_dataid[g])
            a, k = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
            g_vert.append(np.array(m.mesh_vert[a:a + k], np.float64))
        else:
            g_vert.append(None)
    ng = len(keep)
    nan = float("nan")
    rest = np.broadcast_to(np.asarray(nan if restitution is None else restitution, np.float64), (ng,))
    geoms = dict(body=np.array(g_body, np.int64).reshape(ng), type=np.array(g_type, np.int64).reshape(ng),
                 size=np.array(g_size).reshape(ng, 3), pos_body=np.array(g_pos).reshape(ng, 3),
                 quat_wxyz_body=np.array(g_quat).reshape(ng, 4),
                 friction=np.array([float(m.geom_friction[g, 0]) for g in keep]).reshape(ng),
                 restitution=rest.copy(),
                 collide_group=np.array([int(m.geom_contype[g]) for g in keep], np.int64).reshape(ng),
                 collide_mask=np.array([int(m.geom_conaffinity[g]) for g in keep], np.int64).reshape(ng),
                 name=g_name, mesh_vert=g_vert)
    nj = len(jt)
    joints = dict(body=np.array(jb, np.int64).reshape(nj), type=np.array(jt, np.int64).reshape(nj),
                  anchor_body=np.array(ab).reshape(nj, 3), anchor_parent=np.array(ap).reshape(nj, 3),
                  axis_body=np.array(xb).reshape(nj, 3), axis_parent=np.array(xp).reshape(nj, 3),
                  range=np.array(jr, np.float64).reshape(nj, 2), name=jn)
    supplied = np.repeat(lay.dynamic[:, None], len(IMPULSE_KINDS), axis=1)
    work = np.repeat(lay.dynamic[:, None], len(WORK_KINDS), axis=1)
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
    steps = np.repeat(np.array([st for st, _, _ in raws], np.int64), counts)
    raw = np.concatenate([r for _, r, _ in raws])
    sizes = np.array([len(e) for _, _, e in raws])
    efc_all = np.concatenate([e for _, _, e in raws] + [np.zeros(1)])
    base = np.repeat(np.cumsum(sizes) - sizes, counts)
    adr = raw["efc_address"].astype(np.int64)
    idx = np.clip(np.where(adr >= 0, adr + base, 0)[:, None] + np.arange(_EFC_WIDTH), 0, len(efc_all) - 1)
    return dict(step=steps, geom=raw["geom"], adr=adr, dim=raw["dim"], mu=raw["friction"][:, :2],
                exclude=raw["exclude"], frame=raw["frame"], dist=raw["dist"], pos=raw["pos"],
                efc=efc_all[idx])


def decode_contacts(m, layout: Layout, raws):
    """Contact rows in the contract's convention (dict for Recorder.write, or None) from the
    :func:`capture_contacts` of one or more steps."""
    raws = [r for r in raws if r is not None]
    if not raws:
        return None
    raw = _contact_dict(raws)
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


class Kinematics:
    """The logged state of every body at given ``qpos``/``qvel`` (and mocap poses), from a
    private ``MjData``: ``mj_kinematics``, ``mj_comPos``, ``mj_comVel``."""

    def __init__(self, m, layout: Layout):
        mj = _mj()
        self.mj, self.m, self.d = mj, m, mj.MjData(m)
        self.ids = layout.body_id
        self.c_of = layout.root[layout.body_id]
        self.iquat = np.array(m.body_iquat, np.float64)[layout.body_id]

    def quat_wxyz(self) -> np.ndarray:
        """(N, 4) the inertial frames' orientation at the last call: ``xquat`` x ``body_iquat``
        (exactly ``xquat`` where the inertial frame is the body frame)."""
        from rblog.adapters._common import quat_mul

        return quat_mul(self.d.xquat[self.ids], self.iquat)

    def __call__(self, qpos, qvel, mocap_pos=None, mocap_quat=None, out=None):
        """(position (N, 3), rotation (N, 3, 3), velocity (N, 3), angular velocity (N, 3)),
        world frame, centre of mass and principal axes; written into ``out`` when given."""
        d, m, mj = self.d, self.m, self.mj
        d.qpos[:] = qpos
        d.qvel[:] = qvel
        if mocap_pos is not None and m.nmocap:
            d.mocap_pos[:] = mocap_pos
            d.mocap_quat[:] = mocap_quat
        mj.mj_kinematics(m, d)
        mj.mj_comPos(m, d)
        mj.mj_comVel(m, d)
        x, ids = d.xipos, self.ids
        if out is None:
            out = (np.empty((len(ids), 3)), np.empty((len(ids), 3, 3)), np.empty((len(ids), 3)),
                   np.empty((len(ids), 3)))
        px, pr, pv, pw = out
        np.take(x, ids, axis=0, out=px)
        np.take(d.ximat.reshape(-1, 3, 3), ids, axis=0, out=pr)
        cvel = d.cvel
        np.take(cvel[:, :3], ids, axis=0, out=pw)
        arm = px - d.subtree_com[self.c_of]
        np.take(cvel[:, 3:], ids, axis=0, out=pv)
        pv += np.cross(pw, arm)
        return out


def _cross(a, b):
    """a x b over the last axis of (..., 3) arrays (numpy's cross, without its checks)."""
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


#: the arrays of mjData a step's row holds (after the step: Euler and implicit keep the step's
#: start in all but qpos, qvel); the span is one contiguous piece of mjData's buffer
ROW_FIELDS = ("qpos", "qvel", "qfrc_applied", "xfrc_applied", "xquat", "xipos", "ximat", "xanchor",
              "subtree_com", "cdof", "cvel", "qfrc_passive", "qfrc_actuator", "cfrc_int",
              "cfrc_ext")
#: two fields of mjData are copied as one span when the bytes between them are fewer than this
#: (a copy's own cost, ~1 us, is about that many bytes at this machine's ~4 GB/s)
SPAN_GAP_BYTES = 4096
#: bytes of gathered rows per block (the block shrinks for large models)
BLOCK_BYTES = 16 << 20


class Rows:
    """Where ``ROW_FIELDS`` are in one flat float64 row, and how a row is filled from an
    ``MjData``: the fields lie in mjData's one buffer, so a row is a few copies of contiguous
    pieces of it (fields closer than SPAN_GAP_BYTES share a piece), each into its slice of the
    row. Fields that are not float64 and 8-byte aligned are copied one by one."""

    def __init__(self, d):
        import ctypes

        arrs = {f: getattr(d, f) for f in ROW_FIELDS}
        self.shape = {f: a.shape for f, a in arrs.items()}
        addr = {f: a.__array_interface__["data"][0] for f, a in arrs.items() if a.size}
        fields = sorted(addr, key=addr.get)
        ok = all(arrs[f].dtype == np.float64 and arrs[f].flags.c_contiguous and addr[f] % 8 == 0
                 for f in fields)
        self.d, self.views, self.offset = d, arrs, {}
        pieces, pos = [], 0  # (source view, start in the row)
        if ok:
            groups = []
            for f in fields:
                end = addr[f] + arrs[f].nbytes
                if groups and addr[f] - groups[-1][1] <= SPAN_GAP_BYTES:
                    groups[-1][1] = max(groups[-1][1], end)
                    groups[-1][2].append(f)
                else:
                    groups.append([addr[f], end, [f]])
            for lo, hi, fs in groups:
                raw = np.ctypeslib.as_array((ctypes.c_double * ((hi - lo) // 8)).from_address(lo))
                for f in fs:
                    self.offset[f] = pos + (addr[f] - lo) // 8
                pieces.append((raw, pos))
                pos += len(raw)
            ok = all(np.array_equal(pieces[0][0][:0], pieces[0][0][:0]) for _ in [0]) and all(
                np.array_equal(self._read(pieces, f, arrs[f].size), arrs[f].ravel()) for f in fields)
        if not ok:
            pieces, pos = [], 0
            for f in fields:
                self.offset[f] = pos
                pieces.append((arrs[f].reshape(-1), pos))
                pos += arrs[f].size
        for f in ROW_FIELDS:
            self.offset.setdefault(f, 0)
        self.pieces = [(src, row0, row0 + len(src)) for src, row0 in pieces]
        self.width = pos

    def _read(self, pieces, f, size):
        o = self.offset[f]
        for src, row0 in pieces:
            if row0 <= o < row0 + len(src):
                return src[o - row0:o - row0 + size]
        return None

    def fill(self, row) -> None:
        """Copy the fields of the bound MjData into ``row`` (width,)."""
        for src, a, b in self.pieces:
            np.copyto(row[a:b], src)

    def field(self, rows, f):
        """(K, *shape) the field ``f`` of ``rows`` (K, width)."""
        o, shape = self.offset[f], self.shape[f]
        size = int(np.prod(shape))
        return rows[:, o:o + size].reshape(len(rows), *shape)


class StepImpulses:
    """The per-step hook: after each ``mj_step`` it runs ``mj_rnePostConstraint`` at the step's
    start (``mj_forward`` first on a private MjData under RK4) and copies one row of mjData
    (:class:`Rows`) and ``qvel`` into preallocated (capacity, ...) buffers; :meth:`resolve` turns
    the gathered rows into impulses and work per body, vectorized (the derivation is in the
    module docstring)."""

    def __init__(self, m, layout: Layout, d, block: int | None = None):
        mj = _mj()
        self.mj, self.m, self.lay = mj, m, layout
        self.h = float(m.opt.timestep)
        self.rk4 = int(m.opt.integrator) == int(mj.mjtIntegrator.mjINT_RK4)
        # damping MuJoCo integrates implicitly (Euler unless mjDSBL_EULERDAMP; implicit(fast))
        eulerdamp = int(m.opt.disableflags) & (int(mj.mjtDisableBit.mjDSBL_EULERDAMP) |
                                               int(mj.mjtDisableBit.mjDSBL_DAMPER))
        self.implicit_damping = (not self.rk4) and not eulerdamp
        self.scratch = mj.MjData(m) if self.rk4 else None
        self.q0 = np.array(d.qpos, np.float64)
        self.act0 = np.array(d.act, np.float64)
        self.v0 = np.array(d.qvel, np.float64)
        self._v = np.empty(m.nv)
        self._qacc = np.empty(m.nv)
        self.bind(d)
        fit = int(max(8, min(BLOCK_STEPS, BLOCK_BYTES // (8 * max(self.rows_of.width, 1)))))
        self.cap = fit if block is None else max(1, int(block))
        self.rows = np.empty((self.cap, self.rows_of.width))
        self.v1 = np.empty((self.cap, m.nv))
        self.v_start = self.v0.copy()  # v0 of the block's first row
        self._gap_v0 = {}  # row -> its v0 after steps not seen
        self.k = 0

    def bind(self, d) -> None:
        """Take the numpy views of ``d`` (the arrays of an MjData stay where they are)."""
        self.d = d
        self.qvel, self.qacc = d.qvel, d.qacc
        self.rows_of = Rows(self.scratch if self.rk4 else d)

    def restart(self, d) -> None:
        """Take ``d`` as the start of the next step (after steps not seen)."""
        np.copyto(self.v0, d.qvel)
        self._gap_v0[self.k] = self.v0.copy()  # the next row's v0 is not the previous row's v1
        if self.rk4:
            np.copyto(self.q0, d.qpos)
            np.copyto(self.act0, d.act)

    def __call__(self, d) -> None:
        """Gather the step that just ended in ``d``."""
        if d is not self.d:
            self.bind(d)
        mj, m, k = self.mj, self.m, self.k
        v1 = self.v1[k]
        np.copyto(v1, self.qvel)
        if self.rk4:
            src = self.scratch
            src.qpos[:] = self.q0
            src.qvel[:] = self.v0
            src.act[:] = self.act0
            src.ctrl[:] = d.ctrl
            src.time = d.time - self.h
            src.qfrc_applied[:] = d.qfrc_applied
            src.xfrc_applied[:] = d.xfrc_applied
            if m.nmocap:
                src.mocap_pos[:] = d.mocap_pos
                src.mocap_quat[:] = d.mocap_quat
            src.qacc_warmstart[:] = d.qacc_warmstart
            mj.mj_forward(m, src)
            np.subtract(v1, self.v0, out=src.qacc)
            src.qacc *= 1.0 / self.h
            mj.mj_rnePostConstraint(m, src)
            np.copyto(self.q0, d.qpos)
            np.copyto(self.act0, d.act)
        else:
            qvel, qacc = self.qvel, self.qacc
            np.copyto(self._qacc, qacc)
            np.copyto(qvel, self.v0)
            np.subtract(v1, self.v0, out=qacc)
            qacc *= 1.0 / self.h
            mj.mj_rnePostConstraint(m, d)
            np.copyto(qvel, v1)
            np.copyto(qacc, self._qacc)
        self.rows_of.fill(self.rows[k])
        np.copyto(self.v0, v1)
        self.k = k + 1

    @property
    def full(self) -> bool:
        return self.k >= self.cap

    def resolve(self):
        """The gathered steps as (impulses (K, 5, nbody, 6) [angular about the COM; linear], N s
        and N m s, in IMPULSE_KINDS order; work (K, 3, nbody) J, WORK_KINDS order). The rows
        stay until :meth:`reset`."""
        k, lay, h = self.k, self.lay, self.h
        R = self.rows[:k]
        F = lambda f: self.rows_of.field(R, f)  # noqa: E731
        v1 = self.v1[:k]
        v0 = np.concatenate([self.v_start[None], v1[:-1]])
        for row, v in self._gap_v0.items():
            if row < k:
                v0[row] = v
        c = F("subtree_com")[:, lay.root]                       # (K, nb, 3) each body's c
        r = F("xipos") - c                                      # c -> centre of mass
        xf = F("xfrc_applied")                                  # [force; torque] at the COM
        pushed = bool(xf.any())
        nb = len(lay.root)
        W = np.empty((k, len(IMPULSE_KINDS), nb, 6))
        if pushed:
            xf_c = np.concatenate([xf[..., 3:] + _cross(r, xf[..., :3]), xf[..., :3]], axis=-1)
            np.subtract(F("cfrc_ext"), xf_c, out=W[:, 0])
        else:
            W[:, 0] = F("cfrc_ext")
        # S (K, nv, 6): the unit wrench of each dof, about c
        cdof = F("cdof")
        S = np.zeros_like(cdof)
        rot, tr = ~lay.dof_trans, lay.dof_trans
        S[:, rot, :3] = cdof[:, rot, :3]
        if tr.any():
            u = cdof[:, tr, 3:]
            anchor = F("xanchor")[:, lay.dof_jnt[tr]]
            S[:, tr, :3] = _cross(anchor - c[:, lay.dof_body[tr]], u)
            S[:, tr, 3:] = u
        tau = np.empty((k, 3, self.m.nv))                       # applied, passive, actuator
        tau[:, 0] = F("qfrc_applied")
        tau[:, 1] = F("qfrc_passive")
        if self.implicit_damping:
            tau[:, 1] -= lay.damping * (v1 - v0)
        tau[:, 2] = F("qfrc_actuator")
        gen = lay.pair @ (tau[..., None] * S[:, None])          # (K, 3, nb, 6)
        W[:, 1:4] = gen
        if pushed:
            W[:, 1] += xf_c
        np.matmul(lay.net, F("cfrc_int"), out=W[:, 4])
        W[:, 4] -= gen.sum(axis=1)
        W[..., :3] -= _cross(r[:, None], W[..., 3:])            # torques about the COM
        W *= h
        work = (tau * v1[:, None]) @ lay.own.T * h              # (K, 3, nb)
        if pushed:
            cv = F("cvel")
            v_com = cv[..., 3:] + _cross(cv[..., :3], r)
            work[:, 0] += h * (np.einsum("kbi,kbi->kb", xf[..., :3], v_com) +
                               np.einsum("kbi,kbi->kb", xf[..., 3:], cv[..., :3]))
        return W, work

    def reset(self) -> None:
        """Drop the gathered rows; the next row's v0 is the last one's v1 (or a restart's)."""
        if self.k in self._gap_v0:
            np.copyto(self.v_start, self._gap_v0[self.k])
        elif self.k:
            np.copyto(self.v_start, self.v1[self.k - 1])
        self.k = 0
        self._gap_v0 = {}


class MujocoRecorder:
    """Record a MuJoCo model the caller steps: ``rec = MujocoRecorder(m, d, mcap=...)``, then
    ``rec(d)`` after every ``mj_step`` (a sample every ``every`` steps), ``rec.close()`` (or
    ``with``). See the module docstring for what is logged and how.

    Args:
        m, d: the model and the data the caller steps; the state in ``d`` now is sample 0.
        rrd, mcap: output paths (either, both, or neither: kept in memory, ``rec.trajectory``).
        every: steps between samples (the impulses of every step are summed into the next).
        restitution: the geoms' restitution to log (default NaN: MuJoCo states none).
        writer: the program name logged (default ``"mujoco <version> via rblog.adapters"``).
        keep: keep the run in memory as well (default: when there is no output path).
        block: steps gathered before they are resolved and written (default BLOCK_STEPS, fewer
            for large models: BLOCK_BYTES of rows).
        **recorder_options: further :class:`rblog.Recorder` arguments (``check``, ...).

    A sample's state is MuJoCo's kinematics at its ``qpos``/``qvel``: under Euler and the
    implicit integrators without mocap bodies they are the next step's start (``xipos``,
    ``ximat``, ``cvel`` in that step's row), at no cost; otherwise (RK4, mocap bodies, the
    last sample) from :class:`Kinematics`.

    Attributes: ``model`` (the log's model), ``layout`` (:class:`Layout`), ``recorder``.
    """

    def __init__(self, m, d=None, *, rrd=None, mcap=None, every: int = 1, restitution=None,
                 writer: str | None = None, keep: bool | None = None, block: int | None = None,
                 **recorder_options):
        from rblog.record.recorder import Recorder

        mj = _mj()
        if not _is_model(m):
            raise AdapterError(f"rblog.adapters.mujoco: m is a {type(m).__name__}, expected a "
                               "mujoco.MjModel")
        self.m, self.every = m, max(1, int(every))
        if d is None:
            d = mj.MjData(m)
            mj.mj_forward(m, d)
        self.model, self.layout, notes = inspect(m, d, restitution=restitution)
        self.dt = float(m.opt.timestep)
        engine = {**settings(m), **notes, "sample_every": self.every}
        self.recorder = Recorder(self.model, rrd=rrd, mcap=mcap, dt=self.dt,
                                 writer=writer or f"mujoco {mj.__version__} via rblog.adapters",
                                 integrator=engine["integrator"], log_every=self.every,
                                 combine_friction="max", combine_restitution="max",
                                 engine_settings=engine, keep=keep, **recorder_options)
        self.recorder.open()
        self.kin = Kinematics(m, self.layout)
        self.hook = StepImpulses(m, self.layout, d, block=block)
        self.deferred = not self.hook.rk4 and int(m.nmocap) == 0
        cap = self.hook.cap + 1
        n = len(self.layout)
        self._ids = self.layout.body_id
        # samples waiting for their interval's impulses (and, deferred, their kinematics)
        self._x, self._r = np.empty((cap, n, 3)), np.empty((cap, n, 3, 3))
        self._q = np.empty((cap, n, 4))
        self._v, self._w = np.empty((cap, n, 3)), np.empty((cap, n, 3))
        self._steps = np.empty(cap, np.int64)
        self._row = np.full(cap, -1, np.int64)  # the hook row of the sample's own step, -1: state known
        self._gap = np.zeros(cap, bool)
        self._ns = 0
        self._raw = []
        self._hook_steps = np.empty(self.hook.cap, np.int64)  # the step each gathered row ended
        self._carry_W = np.zeros((len(IMPULSE_KINDS), m.nbody, 6))
        self._carry_work = np.zeros((len(WORK_KINDS), m.nbody))
        self._carry_gap = False
        self._carray, self._carray_d = None, None  # the raw view of d's contacts, once there are some
        self.step = int(round(float(d.time) / self.dt))
        self._add_sample(d, row=-1, contacts=False)

    def _add_sample(self, d, row: int, contacts: bool = True) -> None:
        i = self._ns
        self._steps[i] = self.step
        self._row[i] = row
        if row < 0:
            self.kin(d.qpos, d.qvel, d.mocap_pos, d.mocap_quat,
                     out=(self._x[i], self._r[i], self._v[i], self._w[i]))
            self._q[i] = self.kin.quat_wxyz()
        self._ns = i + 1
        if contacts and d.ncon:
            if self._carray is None or self._carray_d is not d:
                try:
                    self._carray, self._carray_d = _ContactArray(self.m, d), d
                except ValueError:  # an mjContact the view cannot describe: field by field
                    self._carray, self._carray_d = False, d
            self._raw.append(capture_contacts(d, self.step, self._carray or None))

    def __call__(self, d) -> None:
        """Log the step that just ended in ``d`` (call after every ``mj_step``)."""
        step = int(round(float(d.time) / self.dt))
        row = -1
        if step != self.step + 1:
            if step <= self.step:
                raise AdapterError(f"rblog.adapters.mujoco: d.time = {float(d.time)!r} is step "
                                   f"{step}, not after the last logged step {self.step} (was d reset?)")
            self._carry_gap = True  # steps not seen: this interval's impulses are unknown
            self.hook.restart(d)
        else:
            row = self.hook.k
            self._hook_steps[row] = step
            self.hook(d)
        self.step = step
        if step % self.every == 0:
            self._gap[self._ns] = self._carry_gap
            self._add_sample(d, row if self.deferred and row >= 0 else -1)
            self._carry_gap = False
        if self.hook.full or self._ns >= len(self._steps):
            self.flush()

    record = __call__

    def step_and_record(self, d, nstep: int = 1) -> None:
        """``mj_step`` ``nstep`` times, logging each."""
        mj = _mj()
        for _ in range(int(nstep)):
            mj.mj_step(self.m, d)
            self(d)

    def _states(self, ns: int) -> None:
        """Fill the deferred samples' states: from the row of the step after theirs (its start
        is their state), or from Kinematics at their row's qpos/qvel when that is not here."""
        hook, lay = self.hook, self.layout
        rows_of, R = hook.rows_of, hook.rows[:hook.k]
        pend = np.flatnonzero(self._row[:ns] >= 0)
        if not len(pend):
            return
        nxt = self._row[pend] + 1
        have = nxt < hook.k
        if self.deferred and have.any():
            i, rr = pend[have], nxt[have]
            ids = self._ids
            x = rows_of.field(R, "xipos")[rr][:, ids]
            self._x[i] = x
            self._r[i] = rows_of.field(R, "ximat")[rr].reshape(len(rr), -1, 3, 3)[:, ids]
            from rblog.adapters._common import quat_mul

            self._q[i] = quat_mul(rows_of.field(R, "xquat")[rr][:, ids], self.kin.iquat)
            cv = rows_of.field(R, "cvel")[rr][:, ids]
            c = rows_of.field(R, "subtree_com")[rr][:, lay.root[ids]]
            self._w[i] = cv[..., :3]
            self._v[i] = cv[..., 3:] + _cross(cv[..., :3], x - c)
        for i in pend[~have]:
            row = R[self._row[i]][None]
            self.kin(rows_of.field(row, "qpos")[0], rows_of.field(row, "qvel")[0],
                     out=(self._x[i], self._r[i], self._v[i], self._w[i]))
            self._q[i] = self.kin.quat_wxyz()
        self._row[pend] = -1

    def _impulses(self, ns: int):
        """(W (ns, 5, nbody, 6), work (ns, 3, nbody)) of each waiting sample's interval: the
        steps in (step[i-1], step[i]]; the steps after the last sample carry over."""
        k = self.hook.k
        W, work = self.hook.resolve() if k else (None, None)
        steps = self._hook_steps[:k]
        pos = np.searchsorted(steps, self._steps[:ns], side="right")  # rows before sample i's end
        starts = np.concatenate([[0], pos[:-1]])
        rows_W = np.zeros((ns, *self._carry_W.shape))
        rows_work = np.zeros((ns, *self._carry_work.shape))
        last = int(pos[-1]) if ns else 0
        if k and last:
            nonempty = pos > starts  # reduceat sums [start_i, start_i+1), the last to `last`
            rows_W[nonempty] = np.add.reduceat(W[:last], starts[nonempty], axis=0)
            rows_work[nonempty] = np.add.reduceat(work[:last], starts[nonempty], axis=0)
        if ns:
            rows_W[0] += self._carry_W
            rows_work[0] += self._carry_work
            self._carry_W = np.zeros_like(self._carry_W)
            self._carry_work = np.zeros_like(self._carry_work)
        if k and last < k:
            self._carry_W = self._carry_W + W[last:].sum(axis=0)
            self._carry_work = self._carry_work + work[last:].sum(axis=0)
        return rows_W, rows_work

    def flush(self) -> None:
        """Write the samples gathered so far (each with its interval's impulses)."""
        ns = self._ns
        self._states(ns)
        W, work = self._impulses(ns)
        self.hook.reset()
        if not ns:
            return
        ids = self._ids
        W, work = W[:, :, ids], work[:, :, ids]
        gap = self._gap[:ns]
        if gap.any():
            W[gap] = np.nan
            work[gap] = np.nan
        steps = self._steps[:ns].copy()
        arrays = dict(t=steps * self.dt, step=steps, position=self._x[:ns].copy(),
                      rotation=self._r[:ns].copy(), quat_wxyz=self._q[:ns].copy(),
                      velocity=self._v[:ns].copy(),
                      angular_velocity=self._w[:ns].copy())
        for a, kind in enumerate(IMPULSE_KINDS):
            arrays[f"impulse_{kind}_angular"] = W[:, a, :, :3]
            arrays[f"impulse_{kind}_linear"] = W[:, a, :, 3:]
        for a, kind in enumerate(WORK_KINDS):
            arrays[f"work_{kind}"] = work[:, a]
        rows = decode_contacts(self.m, self.layout, self._raw)
        if rows is not None:
            arrays["contacts"] = rows
        self._raw = []
        self._ns = 0
        self._gap[:] = False
        self.recorder.write(**arrays)

    def close(self, truncated: bool = False, reason: str | None = None) -> None:
        try:
            if not truncated:
                self.flush()
        finally:
            self.recorder.close(truncated=truncated, reason=reason)

    def __enter__(self) -> "MujocoRecorder":
        return self

    def __exit__(self, exc_type, exc, tb):
        self.close(truncated=exc_type is not None, reason=None if exc is None else str(exc))

    @property
    def trajectory(self):
        """The run so far (needs ``keep``, the default without an output path)."""
        self.flush()
        return self.recorder.trajectory


def recorder(m, d=None, **options) -> MujocoRecorder:
    """``MujocoRecorder(m, d, **options)``: the first of the two lines."""
    return MujocoRecorder(m, d, **options)


#: dm_control suite models whose XML needs its module's own builder (as its tasks load them)
_SUITE_BUILDERS = {"stacker": ("stacker", dict(n_boxes=4)),
                   "manipulator": ("manipulator", dict(use_peg=False, insert=False)),
                   "quadruped": ("quadruped", dict(floor_size=10))}


def suite_model(name: str):
    """The ``mujoco.MjModel`` of dm_control's suite model ``name`` as shipped (the MJCF files and
    assets inside the dm_control package: ``humanoid``, ``cartpole``, ``walker``, ...;
    ``stacker`` with its 4 boxes, ``manipulator`` as in ``bring_ball``); needs the ``models``
    extra (dm-control)."""
    import importlib
    import warnings

    mj = _mj()
    require("dm_control", extra="models")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # GLFW: no display
        module, kwargs = _SUITE_BUILDERS.get(name, (name, None))
        try:
            mod = importlib.import_module(f"dm_control.suite.{module}")
        except ImportError:
            raise AdapterError(f"suite_model: dm_control.suite has no model {name!r}") from None
        got = mod.make_model(**kwargs) if kwargs is not None else mod.get_model_and_assets()
    if isinstance(got, (str, bytes)):  # quadruped's builder returns the XML alone
        from dm_control.suite import common

        got = (got, common.ASSETS)
    return mj.MjModel.from_xml_string(*got)


def record_rollout(m, initial_state, state, *, d=None, rrd=None, mcap=None, batch: int = 0,
                   spec=None, restitution=None, writer: str | None = None,
                   keep: bool | None = None, **recorder_options):
    """Record the output of ``mujoco.rollout.rollout(m, d, initial_state, ...)``: ``state``
    (nbatch, nstep, nstate) or (nstep, nstate), the state after each step, and the
    ``initial_state`` it started from (sample 0). A rollout returns neither contacts nor forces:
    the log has no contact rows, and its model says that every body's impulses and work are
    missing (``body_impulse_supplied`` all False). ``batch`` picks one rollout of a batch.

    Returns the Trajectory when kept (default: when there is no output path), else None."""
    from dataclasses import replace

    from rblog.record.recorder import Recorder

    mj = _mj()
    state = np.asarray(state, np.float64)
    x0 = np.asarray(initial_state, np.float64)
    if state.ndim == 3:
        state = state[batch]
    if x0.ndim == 2:
        x0 = x0[batch if len(x0) > 1 else 0]
    nstate = int(mj.mj_stateSize(m, int(mj.mjtState.mjSTATE_FULLPHYSICS if spec is None else spec)))
    if state.ndim != 2 or state.shape[1] != nstate or x0.shape != (nstate,):
        raise AdapterError(f"record_rollout: state has shape {state.shape} and initial_state "
                           f"{x0.shape}, expected (nstep, {nstate}) and ({nstate},) (mj_stateSize)")
    it, iq, iv = state_offsets(m, spec)
    rows = np.concatenate([x0[None], state])
    model, layout, notes = inspect(m, d, restitution=restitution)
    model = replace(model, body_impulse_supplied=np.zeros_like(model.body_impulse_supplied),
                    body_work_supplied=np.zeros_like(model.body_work_supplied))
    dt = float(m.opt.timestep)
    engine = {**settings(m), **notes, "contact_rows": {"separation": "before the step (none logged: "
                                                       "mujoco.rollout returns no contacts)"},
              "impulses": "none (mujoco.rollout returns no forces)"}
    kin = Kinematics(m, layout)
    T, n = len(rows), len(layout)
    x, r, v, w = np.empty((T, n, 3)), np.empty((T, n, 3, 3)), np.empty((T, n, 3)), np.empty((T, n, 3))
    q = np.empty((T, n, 4))
    for i in range(T):
        kin(rows[i, iq:iq + m.nq], rows[i, iv:iv + m.nv], out=(x[i], r[i], v[i], w[i]))
        q[i] = kin.quat_wxyz()
    step = np.rint(rows[:, it] / dt).astype(np.int64)
    rec = Recorder(model, rrd=rrd, mcap=mcap, dt=dt, writer=writer or f"mujoco {mj.__version__} "
                   "rollout via rblog.adapters", integrator=engine["integrator"],
                   combine_friction="max", combine_restitution="max", engine_settings=engine,
                   keep=keep, **recorder_options)
    with rec:
        rec.write(t=step * dt, step=step, position=x, rotation=r, quat_wxyz=q, velocity=v,
                  angular_velocity=w)
    return rec.trajectory if rec.keep else None


__all__ = ["BLOCK_STEPS", "CONTACT_ROWS", "Kinematics", "Layout", "MujocoRecorder", "ROW_FIELDS", "Rows", "StepImpulses",
           "capture_contacts", "contacts", "decode_contacts", "gravity_of", "inspect", "record_rollout",
           "recorder", "settings", "state_offsets", "suite_model", "unsupported"]
