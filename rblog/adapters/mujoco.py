"""Record a MuJoCo model the user steps (or a ``mujoco.rollout``) into the log contract.

Two lines::

    rec = rblog.adapters.mujoco.MujocoRecorder(m, d, mcap="run.mcap")   # the body table, sample 0
    for _ in range(n): mujoco.mj_step(m, d); rec(d)                      # state + contacts
    rec.close()                                    # or `with`; rblog.check(rblog.load("run.mcap"))

or, for a rollout, ``record_rollout(m, initial_state, state, mcap="run.mcap")``.

MuJoCo's conventions and how they become the contract's (docs/log-format.md):

* **bodies**: every body with a free joint is one rigid body of the table, together with the
  bodies welded to it (no joint of their own). Bodies that move on other joints (hinges, slides,
  balls) or mocap bodies are refused (:class:`~rblog.adapters.AdapterError`): the contract holds
  free rigid bodies and static geometry only. Bodies welded to the world are static geometry.
* **mass and inertia**: ``body_mass``; ``body_inertia`` holds the principal moments about the
  centre of mass in the frame ``body_iquat`` turns out of the body frame (composites of welded
  bodies are summed about their common centre of mass and diagonalized). The contract wants
  principal moments in *its* body frame, so each body's contract frame is chosen
  (:func:`rblog.adapters._common.body_frame`): the frame of its one box geom when the inertia is
  diagonal there and the box is centred on the centre of mass (it keeps the box shape), else the
  principal frame (a sphere keeps its shape in any frame). Other geoms (capsule, cylinder,
  ellipsoid, mesh, several collision geoms) are recorded without a shape (``"none"``).
* **state**: the free joint's ``qpos`` is the body frame's origin and orientation (w, x, y, z);
  ``qvel[0:3]`` is the world-frame velocity of that origin, ``qvel[3:6]`` the angular velocity
  in the **body** frame. The contract's position is the centre of mass, ``x + R ipos``; its
  velocity ``v + w_world x (R ipos)``; its angular velocity ``w_world = R qvel[3:6]``; its
  quaternion ``q ⊗ q_frame``. After ``mj_step`` the ``d.xpos``/``d.xquat`` arrays still hold the
  poses of the step's start, so everything is computed from ``qpos``/``qvel``.
* **contacts**: after ``mj_step`` ``d.contact`` holds the contacts the step's collision detection
  found at its start (``dist`` is the separation then) and ``efc_force`` the forces it solved.
  ``mj_contactForce`` is, in the contact frame (rows of ``contact.frame``: normal from geom1 to
  geom2, two tangents), the force on geom2; the adapter decodes the same numbers from
  ``efc_force`` for all contacts at once (pyramidal or elliptic cones). The row's ``body_a`` is
  geom2's body, ``body_b`` geom1's, ``normal`` the frame's normal (from b into a), impulses =
  force x ``timestep``; a static geom is turned into ``body_b = -1`` with the signs flipped.
  Torsional and rolling friction torques (condim 4 and 6) have no channel and are not logged.
  With the Euler and implicit integrators the impulses are exactly the step's: each body's rows
  sum to its momentum change minus ``m g dt`` (tests/adapters/); RK4 re-solves per stage.
* **materials**: friction is ``geom_friction[:, 0]`` (sliding), combined by MuJoCo's ``max``
  (``<pair>`` and ``priority`` overrides are not followed). MuJoCo states no restitution (a
  bounce comes from the solref spring-damper), so it is logged as unknown (NaN) unless the caller
  gives ``restitution=``.
* **world**: ``opt.gravity``; the first plane geom welded to the world is the ground (its +z is
  the normal), world box geoms are static boxes; other static geoms are listed in
  ``engine_settings["static_geoms_not_in_the_table"]`` (their contacts are still logged, with
  ``body_b = -1``). ``xfrc_applied`` at the recorder's start is the constant force and torque.
"""

from __future__ import annotations

import numpy as np

from rblog.adapters import AdapterError, require
from rblog.adapters._common import BLOCK_SAMPLES, body_frame, quat_mul
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE, Model
from rblog.contract.orientation import matrix_to_quat, quat_wxyz_to_matrix

#: the contract's value of engine_settings.contact_rows for MuJoCo's contacts
CONTACT_ROWS = {
    "separation": "before the step (contact.dist: the collision detection at its start)",
    "impulse": "mj_contactForce (from efc_force) * timestep, on geom2's body",
    "speculative": "dropped (no force and positive dist)",
    "torques": "torsional and rolling (condim 4, 6) not logged",
}


class FreeBodies:
    """Where each recorded body's state is in MuJoCo's arrays and how its frame is turned.

    Attributes: ``body_id`` (N,) MuJoCo body ids; ``qpos_adr``, ``qvel_adr`` (N,) of their free
    joints; ``com`` (N, 3) centre of mass in MuJoCo's body frame; ``q_frame`` (N, 4) the contract
    frame in MuJoCo's body frame; ``geom_index`` (ngeom,) recorded body of each geom, -1 static.
    """

    def __init__(self, body_id, qpos_adr, qvel_adr, com, q_frame, geom_index):
        self.body_id, self.qpos_adr, self.qvel_adr = body_id, qpos_adr, qvel_adr
        self.com, self.q_frame, self.geom_index = com, q_frame, geom_index

    def __len__(self):
        return len(self.body_id)

    def state(self, qpos, qvel):
        """Contract state from ``qpos`` (..., nq) and ``qvel`` (..., nv) (any leading axes):
        (position, quat_wxyz, velocity, angular_velocity), world frame, (..., N, 3 or 4)."""
        qpos, qvel = np.asarray(qpos, np.float64), np.asarray(qvel, np.float64)
        qp = qpos[..., self.qpos_adr[:, None] + np.arange(7)]
        qv = qvel[..., self.qvel_adr[:, None] + np.arange(6)]
        qb = qp[..., 3:7]
        r = quat_wxyz_to_matrix(qb)
        arm = np.einsum("...ij,...j->...i", r, self.com)          # origin -> centre of mass
        w = np.einsum("...ij,...j->...i", r, qv[..., 3:6])       # body -> world frame
        x = qp[..., :3] + arm
        v = qv[..., :3] + np.cross(w, arm)
        return x, quat_mul(qb, self.q_frame), v, w


def _mj():
    return require("mujoco")


def _is_model(m) -> bool:
    return type(m).__name__ == "MjModel"


def inspect(m, d=None, *, restitution=None, ground_restitution=None):
    """The body table of ``m`` and where its bodies are: (Model, FreeBodies, notes dict).

    ``restitution`` (scalar or per recorded body) and ``ground_restitution`` (the ground's and
    the static boxes') default to NaN (unknown: MuJoCo states none); when only ``restitution`` is
    given, the static geometry gets 0, so that under the logged ``max`` rule a body's value is
    its contacts' with the ground."""
    mj = _mj()
    if not _is_model(m):
        raise AdapterError(f"rblog.adapters.mujoco: m is a {type(m).__name__}, expected a mujoco.MjModel")
    d0 = mj.MjData(m)
    if d is not None:
        d0.qpos[:] = d.qpos
        d0.mocap_pos[:] = d.mocap_pos
        d0.mocap_quat[:] = d.mocap_quat
    mj.mj_kinematics(m, d0)
    name = lambda kind, i: mj.mj_id2name(m, kind, i) or f"{'body' if kind == mj.mjtObj.mjOBJ_BODY else 'geom'}{i}"  # noqa: E731
    free_type = int(mj.mjtJoint.mjJNT_FREE)
    weld = np.asarray(m.body_weldid)
    free, qadr, vadr = [], [], []
    for b in range(1, m.nbody):
        nj = int(m.body_jntnum[b])
        if int(m.body_mocapid[b]) >= 0:
            raise AdapterError(f"rblog.adapters.mujoco: body {name(mj.mjtObj.mjOBJ_BODY, b)!r} is a "
                               "mocap body: the contract records free bodies and static geometry only")
        if nj == 0:
            continue
        j = int(m.body_jntadr[b])
        if nj == 1 and int(m.jnt_type[j]) == free_type:
            free.append(b)
            qadr.append(int(m.jnt_qposadr[j]))
            vadr.append(int(m.jnt_dofadr[j]))
            continue
        kinds = [mj.mjtJoint(int(m.jnt_type[j + k])).name.removeprefix("mjJNT_").lower() for k in range(nj)]
        raise AdapterError(f"rblog.adapters.mujoco: body {name(mj.mjtObj.mjOBJ_BODY, b)!r} moves on "
                           f"{'/'.join(kinds)} joints: the contract records free bodies (a free "
                           "joint) and static geometry only")
    index = {b: i for i, b in enumerate(free)}
    n = len(free)
    body_of = np.asarray(m.geom_bodyid)
    geom_index = np.array([index.get(int(weld[body_of[g]]), -1) for g in range(m.ngeom)], np.int64)
    collides = (np.asarray(m.geom_contype) | np.asarray(m.geom_conaffinity)) != 0
    gtype = np.asarray(m.geom_type)
    shapes, sizes, inertias, q_frames, coms, masses, frictions, names = [], [], [], [], [], [], [], []
    for i, b in enumerate(free):
        rb, xb = d0.xmat[b].reshape(3, 3), d0.xpos[b]
        members = [c for c in range(m.nbody) if int(weld[c]) == b]
        masses_c = np.array([float(m.body_mass[c]) for c in members])
        mass = float(masses_c.sum())
        if not mass > 0:
            raise AdapterError(f"rblog.adapters.mujoco: body {name(mj.mjtObj.mjOBJ_BODY, b)!r} has "
                               "no mass: a free body needs a positive mass")
        if len(members) == 1:
            com = np.array(m.body_ipos[b], np.float64)
            moments = np.array(m.body_inertia[b], np.float64)
            q_in = np.array(m.body_iquat[b], np.float64)
        else:  # welded bodies: one rigid body, summed about the common centre of mass
            com_c = np.array([rb.T @ (d0.xipos[c] - xb) for c in members])
            com = (masses_c[:, None] * com_c).sum(axis=0) / mass
            tensor = np.zeros((3, 3))
            for k, c in enumerate(members):
                rc = rb.T @ d0.ximat[c].reshape(3, 3)
                dvec = com_c[k] - com
                tensor += rc @ np.diag(m.body_inertia[c]) @ rc.T
                tensor += masses_c[k] * (dvec @ dvec * np.eye(3) - np.outer(dvec, dvec))
            moments, axes = np.linalg.eigh(tensor)
            if np.linalg.det(axes) < 0:
                axes[:, 2] *= -1.0
            q_in = matrix_to_quat(axes)
        geoms = [g for g in range(m.ngeom) if geom_index[g] == i and collides[g]]
        geom = None
        if len(geoms) == 1:
            g = geoms[0]
            code = {int(mj.mjtGeom.mjGEOM_SPHERE): SHAPE_SPHERE,
                    int(mj.mjtGeom.mjGEOM_BOX): SHAPE_BOX}.get(int(gtype[g]))
            if code is not None:
                centre = rb.T @ (d0.geom_xpos[g] - xb)
                q_geom = matrix_to_quat(rb.T @ d0.geom_xmat[g].reshape(3, 3))
                geom = (code, np.array(m.geom_size[g], np.float64), centre, q_geom, com)
        shape, size, inertia, q_frame = body_frame(moments, q_in, geom)
        shapes.append(shape)
        sizes.append(size)
        inertias.append(inertia)
        q_frames.append(q_frame)
        coms.append(com)
        masses.append(mass)
        fr = [float(m.geom_friction[g, 0]) for g in geoms]
        frictions.append(max(fr) if fr else 0.0)
        names.append(name(mj.mjtObj.mjOBJ_BODY, b))
    # static geometry: the ground (first plane), static boxes; the rest is listed
    ground, g_normal, g_offset, g_friction = False, np.array([0.0, 0.0, 1.0]), 0.0, 0.5
    sb_pos, sb_quat, sb_half, sb_fric, other = [], [], [], [], []
    for g in range(m.ngeom):
        if geom_index[g] >= 0 or not collides[g]:
            continue
        xm = d0.geom_xmat[g].reshape(3, 3)
        if int(gtype[g]) == int(mj.mjtGeom.mjGEOM_PLANE) and not ground:
            ground, g_normal = True, xm[:, 2].copy()
            g_offset = float(g_normal @ d0.geom_xpos[g])
            g_friction = float(m.geom_friction[g, 0])
        elif int(gtype[g]) == int(mj.mjtGeom.mjGEOM_BOX):
            sb_pos.append(d0.geom_xpos[g].copy())
            sb_quat.append(matrix_to_quat(xm))
            sb_half.append(np.array(m.geom_size[g], np.float64))
            sb_fric.append(float(m.geom_friction[g, 0]))
        else:
            other.append(f"{name(mj.mjtObj.mjOBJ_GEOM, g)} ({mj.mjtGeom(int(gtype[g])).name.removeprefix('mjGEOM_').lower()})")
    nan = float("nan")
    if ground_restitution is None and restitution is not None:
        ground_restitution = 0.0  # the bodies' values are the pairs' under the max rule
    rest = np.broadcast_to(np.asarray(nan if restitution is None else restitution, np.float64), (n,)).copy()
    xfrc = np.zeros((n, 6)) if d is None else np.array([d.xfrc_applied[b] for b in free]).reshape(n, 6)
    nsb = len(sb_pos)
    model = Model(
        body_name=names, body_shape=np.array(shapes, np.int64).reshape(n),
        body_size=np.array(sizes).reshape(n, 3), body_mass=np.array(masses, np.float64).reshape(n),
        body_inertia_diag=np.array(inertias).reshape(n, 3), body_force_world=xfrc[:, :3].copy(),
        body_torque_world=xfrc[:, 3:].copy(), body_restitution=rest,
        body_friction=np.array(frictions, np.float64).reshape(n), body_group=np.zeros(n, np.int64),
        gravity=np.array(m.opt.gravity, np.float64), ground=ground, ground_normal=g_normal,
        ground_offset=g_offset, ground_restitution=nan if ground_restitution is None else float(ground_restitution),
        ground_friction=g_friction,
        static_box_position=np.array(sb_pos).reshape(nsb, 3), static_box_quat_wxyz=np.array(sb_quat).reshape(nsb, 4),
        static_box_half_extents=np.array(sb_half).reshape(nsb, 3),
        static_box_restitution=np.full(nsb, nan if ground_restitution is None else float(ground_restitution)),
        static_box_friction=np.array(sb_fric, np.float64).reshape(nsb))
    layout = FreeBodies(np.array(free, np.int64), np.array(qadr, np.int64), np.array(vadr, np.int64),
                        np.array(coms).reshape(n, 3), np.array(q_frames).reshape(n, 4), geom_index)
    notes = {"static_geoms_not_in_the_table": other,
             "restitution": ("not stated by MuJoCo (solref spring-damper): unknown (NaN)"
                             if restitution is None else "given by the caller")}
    return model, layout, notes


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
        "contact_model": "soft (solref, solimp per geom or pair)",
        "combine_native": {"friction": "max", "solref": "solmix-weighted mean"},
        "contact_rows": dict(CONTACT_ROWS),
    }


#: efc rows gathered per contact: a pyramidal condim-6 contact has 10 (2 per tangent direction)
_EFC_WIDTH = 10


def capture_contacts(d, step: int):
    """The raw contact data of ``d`` right after ``mj_step`` (copies; decoded later, a block at a
    time, by :func:`decode_contacts`), or None when there are none."""
    k = int(d.ncon)
    if k == 0:
        return None
    con = d.contact
    adr = con.efc_address[:k].copy()
    ef = d.efc_force
    idx = np.clip(adr[:, None] + np.arange(_EFC_WIDTH), 0, max(len(ef) - 1, 0))
    return dict(step=np.full(k, int(step), np.int64), geom=con.geom[:k].copy(), adr=adr,
                dim=con.dim[:k].copy(), mu=con.friction[:k, :2].copy(), exclude=con.exclude[:k].copy(),
                frame=con.frame[:k].copy(), dist=con.dist[:k].copy(), pos=con.pos[:k].copy(),
                efc=ef[idx] if len(ef) else np.zeros((k, _EFC_WIDTH)))


def decode_contacts(m, layout: FreeBodies, raws):
    """Contact rows in the contract's convention (dict for Recorder.write, or None) from the
    :func:`capture_contacts` of one or more steps."""
    raws = [r for r in raws if r is not None]
    if not raws:
        return None
    raw = {key: np.concatenate([r[key] for r in raws]) for key in raws[0]}
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


def contacts(m, d, layout: FreeBodies, step: int):
    """The contact rows of the step that ended at ``step`` (``d`` right after ``mj_step``), in the
    contract's convention, as a dict for Recorder.write; None when there are none."""
    return decode_contacts(m, layout, [capture_contacts(d, step)])


class MujocoRecorder:
    """Record a MuJoCo model the caller steps: ``rec = MujocoRecorder(m, d, mcap=...)``, then
    ``rec(d)`` after each ``mj_step`` (or every few: only the state and contacts at the calls are
    logged), ``rec.close()`` (or ``with``).

    Args:
        m, d: the model and the data the caller steps; the state in ``d`` now is sample 0.
        rrd, mcap: output paths (either, both, or neither: kept in memory, ``rec.trajectory``).
        restitution, ground_restitution: what to log as the materials' restitution (MuJoCo
            states none: NaN, unknown, by default; see :func:`inspect`).
        writer: the program name logged (default ``"mujoco <version> via rblog.adapters"``).
        keep: keep the run in memory as well (default: when there is no output path).
        **recorder_options: further :class:`rblog.Recorder` arguments (``log_every``, ...).

    Attributes: ``model`` (the body table), ``layout`` (:class:`FreeBodies`), ``recorder``.
    """

    def __init__(self, m, d=None, *, rrd=None, mcap=None, restitution=None, ground_restitution=None,
                 writer: str | None = None, keep: bool | None = None, block: int | None = None,
                 **recorder_options):
        from rblog.record.recorder import Recorder

        mj = _mj()
        self.m = m
        self.model, self.layout, notes = inspect(m, d, restitution=restitution,
                                                 ground_restitution=ground_restitution)
        self.dt = float(m.opt.timestep)
        engine = {**settings(m), **notes}
        self.recorder = Recorder(self.model, rrd=rrd, mcap=mcap, dt=self.dt,
                                 writer=writer or f"mujoco {mj.__version__} via rblog.adapters",
                                 integrator=engine["integrator"], combine_friction="max",
                                 combine_restitution="max", engine_settings=engine, keep=keep,
                                 **recorder_options)
        self.recorder.open()
        self.block = BLOCK_SAMPLES if block is None else int(block)
        self._steps, self._qpos, self._qvel, self._raw = [], [], [], []
        if d is not None:
            self._add(d, contacts=False)

    def _add(self, d, contacts: bool = True) -> None:
        step = int(round(float(d.time) / self.dt))
        self._steps.append(step)
        self._qpos.append(d.qpos.copy())
        self._qvel.append(d.qvel.copy())
        if contacts:
            self._raw.append(capture_contacts(d, step))
        if len(self._steps) >= self.block:
            self.flush()

    def __call__(self, d) -> None:
        """Log ``d`` right after ``mj_step``: its state and the contacts of the step just taken
        (copied now, turned into the contract's frames a block at a time)."""
        self._add(d)

    record = __call__

    def flush(self) -> None:
        """Write the samples gathered so far."""
        if not self._steps:
            return
        steps = np.array(self._steps, np.int64)
        x, q, v, w = self.layout.state(np.array(self._qpos), np.array(self._qvel))
        rows = decode_contacts(self.m, self.layout, self._raw)
        self._steps, self._qpos, self._qvel, self._raw = [], [], [], []
        arrays = dict(t=steps * self.dt, step=steps, position=x, quat_wxyz=q, velocity=v,
                      angular_velocity=w)
        if rows is not None:
            arrays["contacts"] = rows
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


def record_rollout(m, initial_state, state, *, d=None, rrd=None, mcap=None, batch: int = 0,
                   spec=None, restitution=None, ground_restitution=None, writer: str | None = None,
                   keep: bool | None = None, **recorder_options):
    """Record the output of ``mujoco.rollout.rollout(m, d, initial_state, ...)``: ``state``
    (nbatch, nstep, nstate) or (nstep, nstate), the state after each step, and the
    ``initial_state`` it started from (sample 0). A rollout returns no contacts: the log has none
    (the analyzers then infer contacts from the motion). ``batch`` picks one rollout of a batch.

    Returns the Trajectory when kept (default: when there is no output path), else None."""
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
    model, layout, notes = inspect(m, d, restitution=restitution, ground_restitution=ground_restitution)
    dt = float(m.opt.timestep)
    engine = {**settings(m), **notes, "contact_rows": {"separation": "before the step (none logged: "
                                                       "mujoco.rollout returns no contacts)"}}
    x, q, v, w = layout.state(rows[:, iq:iq + m.nq], rows[:, iv:iv + m.nv])
    step = np.rint(rows[:, it] / dt).astype(np.int64)
    rec = Recorder(model, rrd=rrd, mcap=mcap, dt=dt, writer=writer or f"mujoco {mj.__version__} "
                   "rollout via rblog.adapters", integrator=engine["integrator"],
                   combine_friction="max", combine_restitution="max", engine_settings=engine,
                   keep=keep, **recorder_options)
    with rec:
        rec.write(t=step * dt, step=step, position=x, quat_wxyz=q, velocity=v, angular_velocity=w)
    return rec.trajectory if rec.keep else None


__all__ = ["CONTACT_ROWS", "FreeBodies", "MujocoRecorder", "capture_contacts", "contacts",
           "decode_contacts", "inspect", "record_rollout",
           "settings", "state_offsets"]
