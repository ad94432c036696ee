"""The per-step hook of :mod:`rblog.adapters.mujoco`: each logged body's state from MuJoCo's
kinematics (:class:`Kinematics`), one row of mjData per step (:class:`Rows`), and the rows of a
block turned into impulses and work per body (:class:`StepImpulses`; the derivation is in
:mod:`rblog.adapters.mujoco`'s docstring).

Why this module is long: each compiled piece (the hook, the block resolve, the momenta) keeps its
numpy reference here, next to it, so the two can be read and tested side by side."""

from __future__ import annotations

import math

import numpy as np

from rblog.adapters._mujoco_model import BLOCK_STEPS, Layout, _mj
from rblog.contract.model import IMPULSE_KINDS, WORK_KINDS

class Kinematics:
    """The logged state of every body at given ``qpos``/``qvel`` (and mocap poses), from a
    private ``MjData`` (``d``, default a new one): ``mj_kinematics``, ``mj_comPos``,
    ``mj_comVel``."""

    def __init__(self, m, layout: Layout, d=None):
        mj = _mj()
        self.mj, self.m, self.d = mj, m, mj.MjData(m) if d is None else d
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
        if d is None:  # the recorder gave its MjData back (closed): a new one
            d = self.d = mj.MjData(m)
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
        pv += _cross(pw, arm)
        return out


def momenta(mass, inertia, r, v, w):
    """(P, L) (..., N, 3) of states ``r`` (..., N, 3, 3), ``v``, ``w`` (..., N, 3) of bodies of
    ``mass`` (N,), ``inertia`` (N, 3) principal: ``P = m v``, ``L = R (I (R^T w))``, the sums
    over j = 0, 1, 2 in order (the order of rblog.adapters._hook.integration)."""
    p = mass[None, :, None] * v
    w_body = r[..., 0, :] * w[..., 0:1] + r[..., 1, :] * w[..., 1:2] + r[..., 2, :] * w[..., 2:3]
    iw = inertia[None] * w_body
    L = r[..., :, 0] * iw[..., 0:1] + r[..., :, 1] * iw[..., 1:2] + r[..., :, 2] * iw[..., 2:3]
    return p, L


def _cross(a, b):
    """a x b over the last axis of (..., 3) arrays (numpy's cross, without its checks)."""
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def _xfrc_about_c(xf, r):
    """(..., 6) [torque; force] about c of ``xfrc_applied`` rows ``xf`` (..., 6) [force; torque]
    at the centre of mass, ``r`` (..., 3) c -> centre of mass."""
    return np.concatenate([xf[..., 3:] + _cross(r, xf[..., :3]), xf[..., :3]], axis=-1)


def _xfrc_work(F, xf, r, h):
    """(K, nbody) J the work of ``xfrc_applied`` ``xf`` (K, nbody, 6) [force; torque] at the
    centre of mass over each step: h (f . v_com + torque . w), from the rows' ``cvel`` (about c)
    and ``r`` (K, nbody, 3) c -> centre of mass."""
    cv = F("cvel")
    v_com = cv[..., 3:] + _cross(cv[..., :3], r)
    return h * (np.einsum("kbi,kbi->kb", xf[..., :3], v_com) +
                np.einsum("kbi,kbi->kb", xf[..., 3:], cv[..., :3]))


_FUNCTIONS = []
_EINSUM_PAIRS = []


def _einsum_pairs() -> bool:
    """Whether numpy's ``einsum("kjs,kjs->kj")`` over s = 0..5 sums the products as two lanes,
    the even and the odd ones each from +0.0, then the two (its x86-64 baseline, two float64
    lanes): the order of the compiled joint forces' cdof sum. Probed once on random numbers."""
    if not _EINSUM_PAIRS:
        rng = np.random.default_rng(36)
        a = rng.standard_normal((64, 3, 6)) * 10.0 ** rng.integers(-6, 7, (64, 3, 6))
        b = rng.standard_normal((64, 3, 6)) * 10.0 ** rng.integers(-6, 7, (64, 3, 6))
        p = a * b
        pairs = ((p[..., 0] + p[..., 2]) + p[..., 4]) + ((p[..., 1] + p[..., 3]) + p[..., 5])
        ein = np.einsum("kjs,kjs->kj", a, b)
        _EINSUM_PAIRS.append(bool(np.array_equal(pairs.view(np.int64), ein.view(np.int64))))
    return _EINSUM_PAIRS[0]


def _hook_built() -> bool:
    """Whether the build has the compiled hook (rblog.adapters._hook)."""
    try:
        from rblog.adapters._hook import StepHook  # noqa: F401
    except ImportError:
        return False
    return True


def _mujoco_functions():
    """(address of mj_rnePostConstraint, of mj_mulM) in the libmujoco the bindings loaded, or
    None when it is not found."""
    if not _FUNCTIONS:
        import ctypes
        import glob
        import os

        mj = _mj()
        found = None
        for path in sorted(glob.glob(os.path.join(os.path.dirname(mj.__file__), "libmujoco*"))):
            try:
                lib = ctypes.CDLL(path)
                found = tuple(ctypes.cast(getattr(lib, f), ctypes.c_void_p).value
                              for f in ("mj_rnePostConstraint", "mj_mulM"))
                break
            except (OSError, AttributeError):
                continue
        _FUNCTIONS.append(found)
    return _FUNCTIONS[0]


def _actuators_depend_on_velocity(m) -> bool:
    """Whether an actuator's force depends on velocity (affine gain or bias with a velocity
    term: MuJoCo's velocity servos and position servos with kv; muscles)."""
    dyn_gain = np.asarray(m.actuator_gaintype) != 0
    gain_v = np.asarray(m.actuator_gainprm)[:, 2] != 0
    bias_v = (np.asarray(m.actuator_biastype) != 0) & (np.asarray(m.actuator_biasprm)[:, 2] != 0)
    return bool(np.any((dyn_gain & gain_v) | bias_v | (np.asarray(m.actuator_gaintype) == 2)))


def _passive_depends_on_velocity(m) -> bool:
    """Whether passive forces beyond dof damping depend on velocity: tendon damping, fluid."""
    fluid = float(m.opt.density) > 0 or float(m.opt.viscosity) > 0
    return bool(np.any(np.asarray(m.tendon_damping) != 0) or fluid)


#: the arrays of mjData a step's row holds (after the step: Euler and implicit keep the step's
#: start in all but qpos, qvel); the span is one contiguous piece of mjData's buffer
ROW_FIELDS = ("qpos", "qvel", "qfrc_applied", "xfrc_applied", "xquat", "xipos", "ximat", "xanchor",
              "subtree_com", "cdof", "cvel", "qfrc_passive", "qfrc_actuator", "qfrc_smooth",
              "qfrc_constraint", "cfrc_int", "cfrc_ext")
#: two fields of mjData are copied as one span when the bytes between them are fewer than this:
#: numpy's copies (a copy's own cost, ~1 us, is about that many bytes at this machine's ~4 GB/s)
SPAN_GAP_BYTES = 4096
#: the same for the compiled hook's memcpy (~20 ns a call): humanoid's row is 1,149 doubles
#: (9.2 kB) in 14 pieces instead of 2,189 in 4
SPAN_GAP_BYTES_COMPILED = 64
#: bytes of gathered rows per block (the block shrinks for large models)
BLOCK_BYTES = 16 << 20


class Rows:
    """Where ``ROW_FIELDS`` are in one flat float64 row, and how a row is filled from an
    ``MjData``: the fields lie in mjData's one buffer, so a row is a few copies of contiguous
    pieces of it (fields closer than SPAN_GAP_BYTES share a piece), each into its slice of the
    row. Fields that are not float64 and 8-byte aligned are copied one by one. ``gap``: the
    largest gap between two fields (bytes) copied along with them."""

    def __init__(self, d, gap: int = SPAN_GAP_BYTES):
        import ctypes

        arrs = {f: getattr(d, f) for f in ROW_FIELDS}
        self.shape = {f: a.shape for f, a in arrs.items()}
        addr = {f: a.__array_interface__["data"][0] for f, a in arrs.items() if a.size}
        fields = sorted(addr, key=addr.get)
        ok = all(arrs[f].dtype == np.float64 and arrs[f].flags.c_contiguous and addr[f] % 8 == 0
                 for f in fields)
        self.d, self.views, self.offset = d, arrs, {}
        self.addresses = []  # (address, doubles, start in the row) of each piece: the C++ hook's
        pieces, pos = [], 0  # (source view, start in the row)
        if ok:
            groups = []
            for f in fields:
                end = addr[f] + arrs[f].nbytes
                if groups and addr[f] - groups[-1][1] <= gap:
                    groups[-1][1] = max(groups[-1][1], end)
                    groups[-1][2].append(f)
                else:
                    groups.append([addr[f], end, [f]])
            for lo, hi, fs in groups:
                raw = np.ctypeslib.as_array((ctypes.c_double * ((hi - lo) // 8)).from_address(lo))
                self.addresses.append((lo, (hi - lo) // 8, pos))
                for f in fs:
                    self.offset[f] = pos + (addr[f] - lo) // 8
                pieces.append((raw, pos))
                pos += len(raw)
            ok = all(np.array_equal(pieces[0][0][:0], pieces[0][0][:0]) for _ in [0]) and all(
                np.array_equal(self._read(pieces, f, arrs[f].size), arrs[f].ravel()) for f in fields)
        if not ok:
            pieces, pos, self.addresses = [], 0, []
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
        size = math.prod(shape)
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
        # implicit, implicitfast: (M - h D) a = f, D = d(passive + actuator)/dv (implicit: and the
        # bias); the integrated force is M a = f + h D a. The hook logs M a (mj_mulM) and puts
        # h D a beyond the dof damping into the passive kind, or into the actuator kind when
        # only actuators depend on velocity (ACTUATOR_VELOCITY_TERMS)
        self.implicit = int(m.opt.integrator) in (int(mj.mjtIntegrator.mjINT_IMPLICIT),
                                                  int(mj.mjtIntegrator.mjINT_IMPLICITFAST))
        self.correction_kind = 2 if (self.implicit and _actuators_depend_on_velocity(m)
                                     and not _passive_depends_on_velocity(m)) else 1
        self.scratch = mj.MjData(m) if self.rk4 else None
        # [rows gathered k, and MujocoRecorder's samples waiting, last step seen, carried gap]:
        # shared with the compiled per-step call (rblog.adapters._hook.StepRecord)
        self.counters = np.zeros(4, np.int64)
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
        self.Ma = np.empty((self.cap, m.nv)) if self.implicit else None
        # RK4: each step's displacement (q1 - q0) / h (mj_differentiatePos), the velocity its
        # forces' work is taken at (the semi-implicit integrators displace by h v1)
        self.v_disp = np.empty((self.cap, m.nv)) if self.rk4 else None
        # RK4: whether a joint constraint (limit, friction loss, equality) has rows at the
        # step's first or last stage: its work is then not known (_unknown_rk4_joint_work)
        self.stage_constrained = np.zeros(self.cap, bool) if self.rk4 else None
        self.v_start = self.v0.copy()  # v0 of the block's first row
        self._compile()
        self._gap_v0 = {}  # row -> its v0 after steps not seen
        self._fixed = None  # the compiled resolve's fixed arrays (row offsets, layout maps)
        self._subtree_lists = None  # the compiled joint forces' subtree members (CSR)
        self.k = 0

    def bind(self, d) -> None:
        """Take the numpy views of ``d`` (the arrays of an MjData stay where they are)."""
        self.d = d
        self.qvel, self.qacc = d.qvel, d.qacc
        self.rows_of = Rows(self.scratch if self.rk4 else d,
                            gap=SPAN_GAP_BYTES_COMPILED if _hook_built() and not self.rk4
                            else SPAN_GAP_BYTES)
        self._fixed = None  # the row offsets may differ in another MjData
        if getattr(self, "rows", None) is not None:
            self._compile()

    def _compile(self) -> None:
        """The compiled hook (rblog.adapters._hook) over ``d`` and these buffers, when the
        build has it and libmujoco's functions are found; else the numpy one is used."""
        self.compiled = None
        if self.rk4 or not self.rows_of.addresses or self.rows.shape[1] != self.rows_of.width:
            return
        fns = _mujoco_functions()
        if fns is None:
            return
        try:
            from rblog.adapters._hook import StepHook
        except ImportError:
            return
        addr = lambda a: a.__array_interface__["data"][0]  # noqa: E731
        d = self.d
        self.compiled = StepHook(fns[0], fns[1] if self.Ma is not None else 0, self.m._address,
                                 d._address, addr(self.qvel), addr(self.qacc), int(self.m.nv),
                                 self.h, addr(self.rows), int(self.rows.shape[1]), addr(self.v1),
                                 addr(self.v0), addr(self.Ma) if self.Ma is not None else 0,
                                 int(self.cap), list(self.rows_of.addresses))

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
        if self.compiled is not None:
            self.k = self.compiled.step(self.k)
            return
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
            self.stage_constrained[k] = (src.ne + src.nf + src.nl + d.ne + d.nf + d.nl) > 0
            np.subtract(v1, self.v0, out=src.qacc)
            src.qacc *= 1.0 / self.h
            mj.mj_rnePostConstraint(m, src)
            mj.mj_differentiatePos(m, self.v_disp[k], self.h, self.q0, d.qpos)
            np.copyto(self.q0, d.qpos)
            np.copyto(self.act0, d.act)
        else:
            qvel, qacc = self.qvel, self.qacc
            np.copyto(self._qacc, qacc)
            np.copyto(qvel, self.v0)
            np.subtract(v1, self.v0, out=qacc)
            qacc *= 1.0 / self.h
            mj.mj_rnePostConstraint(m, d)
            if self.Ma is not None:
                mj.mj_mulM(m, d, self.Ma[k], qacc)
            np.copyto(qvel, v1)
            np.copyto(qacc, self._qacc)
        self.rows_of.fill(self.rows[k])
        np.copyto(self.v0, v1)
        self.k = k + 1

    @property
    def k(self) -> int:
        """The rows gathered in this block."""
        return int(self.counters[0])

    @k.setter
    def k(self, value: int) -> None:
        self.counters[0] = value

    @property
    def full(self) -> bool:
        return self.k >= self.cap

    def _v0(self):
        """(K, nv) each gathered step's start velocity: the previous row's v1 (or a restart's)."""
        k, v1 = self.k, self.v1[:self.k]
        v0 = np.concatenate([self.v_start[None], v1[:-1]])
        for row, v in self._gap_v0.items():
            if row < k:
                v0[row] = v
        return v0

    def fixed(self):
        """The compiled kernels' fixed arrays: the row's field offsets (ROW_FIELDS order),
        ``root``, ``body_parentid``, ``dof_body``, ``dof_jnt``, ``dof_trans`` (int64),
        ``damping``."""
        if self._fixed is None:
            lay, m = self.lay, self.m
            i64 = lambda a: np.ascontiguousarray(a, np.int64)  # noqa: E731
            self._fixed = (np.array([self.rows_of.offset[f] for f in ROW_FIELDS], np.int64),
                           i64(lay.root), i64(m.body_parentid), i64(lay.dof_body),
                           i64(lay.dof_jnt), i64(lay.dof_trans),
                           np.ascontiguousarray(lay.damping, np.float64))
        return self._fixed

    def resolve(self):
        """The gathered steps as (impulses (K, 6, nbody, 6) [angular about the COM; linear], N s
        and N m s, in IMPULSE_KINDS order, integration 0 (per interval, MujocoRecorder); work
        (K, 4, nbody) J, WORK_KINDS order). The rows stay until :meth:`reset`. Compiled
        (``rblog.adapters._hook.resolve``: the formulas of :meth:`resolve_numpy` in the same
        order) when the build has it, the joints' constraint forces too
        (:meth:`_joint_forces_compiled`: numpy's sums in numpy's order); the velocity the work is
        taken at (:meth:`_v_work`) and the work of ``xfrc_applied`` (:func:`_xfrc_work`) come
        from numpy either way (einsum's sums, not the kernel's)."""
        W, work = self._resolve()
        if self.rk4:
            self._unknown_rk4_joint_work(work)
        return W, work

    def _unknown_rk4_joint_work(self, work) -> None:
        """NaN joint work (WORK_KINDS' joint, on every body with a dof) in the RK4 steps with a
        joint constraint at their first or last stage. RK4's step changes the energy by ``h
        sum_i b_i f_i . v_i`` over its four stages, and a limit's force is not smooth across
        them (dm_control's cartpole: the slider's limit force peaks at 46 N inside a step whose
        first stage's is a fraction of it); the log holds the first stage's force alone, so the
        step's work of such a constraint is not known (energy does not judge those intervals).
        Smooth forces (actuators, springs, damping) keep the first stage's work at the
        step's displacement, the O(h^2) per step the analyzers allow."""
        flag = self.stage_constrained[:self.k]
        if flag.any():
            bodies = np.asarray(self.lay.own).any(axis=1)
            rows = work[flag, WORK_KINDS.index("joint")]
            rows[:, bodies] = np.nan
            work[flag, WORK_KINDS.index("joint")] = rows

    def _resolve(self):
        try:
            from rblog.adapters._hook import resolve
        except ImportError:
            return self.resolve_numpy()
        k, lay, m = self.k, self.lay, self.m
        off, root, parent, dof_body, dof_jnt, dof_trans, damping = self.fixed()
        nb, nv = len(lay.root), int(m.nv)
        R = self.rows[:k]
        F = lambda f: self.rows_of.field(R, f)  # noqa: E731
        v1, v0 = self.v1[:k], self._v0()
        xf = F("xfrc_applied")
        contact_c = F("cfrc_ext")
        pushed = bool(xf.any())
        if pushed:
            r = F("xipos") - F("subtree_com")[:, lay.root]
            contact_c = contact_c - _xfrc_about_c(xf, r)
        q_joint = self._joint_forces_compiled(R, off, None if not pushed else contact_c, F)
        v_work = np.ascontiguousarray(self._v_work(v0, v1))
        W = np.empty((k, len(IMPULSE_KINDS), nb, 6))
        work = np.empty((k, len(WORK_KINDS), nb))
        ma = self.Ma[:k] if self.Ma is not None else np.empty((0, nv))
        resolve(R, off, v1, v0, ma, root, parent, dof_body, dof_jnt, dof_trans, damping,
                self.h, bool(self.implicit_damping), int(self.correction_kind), q_joint, v_work,
                W, work)
        if pushed:
            work[:, 0] += _xfrc_work(F, xf, r, self.h)
        return W, work

    def _v_work(self, v0, v1):
        """(K, nv) the velocity a step's forces work at: the mean of its ends for the
        semi-implicit integrators (the states' kinetic energy changes by (v0 + v1)/2 . M (v1 -
        v0) = h f . (v0 + v1)/2), RK4's displacement (q1 - q0) / h."""
        return 0.5 * (v0 + v1) if self.v_disp is None else self.v_disp[:self.k]

    def resolve_numpy(self):
        """:meth:`resolve` in numpy (the reference of the compiled one)."""
        k, lay, h = self.k, self.lay, self.h
        R = self.rows[:k]
        F = lambda f: self.rows_of.field(R, f)  # noqa: E731
        v1 = self.v1[:k]
        v0 = self._v0()
        c = F("subtree_com")[:, lay.root]                       # (K, nb, 3) each body's c
        r = F("xipos") - c                                      # c -> centre of mass
        xf = F("xfrc_applied")                                  # [force; torque] at the COM
        pushed = bool(xf.any())
        nb = len(lay.root)
        W = np.empty((k, len(IMPULSE_KINDS), nb, 6))
        W[:, IMPULSE_KINDS.index("integration")] = 0.0  # per interval: MujocoRecorder._integration
        if pushed:
            xf_c = _xfrc_about_c(xf, r)
            np.subtract(F("cfrc_ext"), xf_c, out=W[:, 0])
        else:
            W[:, 0] = F("cfrc_ext")
        q_joint = self._joint_forces(F, W[:, 0])
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
        if self.Ma is not None:  # h D a beyond the dof damping: M a - f - (-B dv)
            extra = self.Ma[:k] - F("qfrc_smooth") - F("qfrc_constraint") + lay.damping * (v1 - v0)
            tau[:, self.correction_kind] += extra
        gen = lay.pair @ (tau[..., None] * S[:, None])          # (K, 3, nb, 6)
        W[:, 1:4] = gen
        if pushed:
            W[:, 1] += xf_c
        np.matmul(lay.net, F("cfrc_int"), out=W[:, 4])
        W[:, 4] -= gen.sum(axis=1)
        W[..., :3] -= _cross(r[:, None], W[..., 3:])            # torques about the COM
        W *= h
        v_work = self._v_work(v0, v1)
        work = np.empty((k, len(WORK_KINDS), nb))
        work[:, :3] = (tau * v_work[:, None]) @ lay.own.T * h    # applied, passive, actuator
        work[:, 3] = (q_joint * v_work) @ lay.own.T * h          # joint
        if pushed:
            work[:, 0] += _xfrc_work(F, xf, r, h)
        return W, work

    def _joint_forces_compiled(self, R, off, contact_c, F):
        """:meth:`_joint_forces` by ``rblog.adapters._hook.joint_forces``: the subtree sums in
        matmul's order (ascending bodies from +0.0: ``subtree`` is 0/1) and, when this numpy's
        einsum sums six products as the kernel does (:func:`_einsum_pairs`), the cdof products
        too; else numpy's einsum over the kernel's subtree sums. ``contact_c`` None: the rows'
        cfrc_ext."""
        from rblog.adapters._hook import joint_forces

        if self._subtree_lists is None:
            S = np.asarray(self.lay.subtree) != 0
            self._subtree_lists = (
                np.concatenate([[0], np.cumsum(S.sum(axis=1))]).astype(np.int64),
                np.concatenate([np.flatnonzero(row) for row in S] or [np.zeros(0)]).astype(np.int64),
                np.ascontiguousarray(self.lay.dof_body, np.int64))
        start, members, dof_body = self._subtree_lists
        k, nv = len(R), int(self.m.nv)
        con = np.empty((0, 0, 0)) if contact_c is None else np.ascontiguousarray(contact_c,
                                                                                 np.float64)
        if _einsum_pairs():
            q = np.empty((k, nv))
            joint_forces(R, off, con, start, members, dof_body, 0, np.empty((0, 0, 0)), q)
            return q
        below = np.empty((k, nv, 6))
        joint_forces(R, off, con, start, members, dof_body, 1, below, np.empty((0, 0)))
        return np.ascontiguousarray(F("qfrc_constraint") - np.einsum("kjs,kjs->kj", F("cdof"),
                                                                      below))

    def _joint_forces(self, F, contact_c):
        """(K, nv) the generalized force of the joints' non-ideal constraints (limits, friction
        loss, equalities, tendon limits): ``qfrc_constraint`` less the contacts' part, that of
        the contact wrenches ``contact_c`` (K, nbody, 6) [torque; force] about c on every body
        of a dof's subtree, paired with the dof's motion ``cdof`` (J^T f = sum_b cdof . f_b)."""
        lay = self.lay
        below = np.matmul(lay.subtree, contact_c)[:, lay.dof_body]   # (K, nv, 6)
        return F("qfrc_constraint") - np.einsum("kjs,kjs->kj", F("cdof"), below)

    def reset(self) -> None:
        """Drop the gathered rows; the next row's v0 is the last one's v1 (or a restart's)."""
        if self.k in self._gap_v0:
            np.copyto(self.v_start, self._gap_v0[self.k])
        elif self.k:
            np.copyto(self.v_start, self.v1[self.k - 1])
        self.k = 0
        self._gap_v0 = {}
