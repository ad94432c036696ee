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
  the body: the constraint reactions, limits, frictionloss, tendon equalities.
* implicit, implicitfast: MuJoCo solves ``(M - h D) a = f`` with ``D`` the velocity derivative
  of the passive and actuator forces (implicit: and of the bias), so the force it integrates is
  ``M a = f + h D a``. The hook computes ``M a`` (``mj_mulM``) and logs ``h D a`` with the passive
  kind (its dof-damping part is ``- B (v1 - v0)``, as under Euler), or with the actuator kind
  when only actuators depend on velocity: a tree's joint impulses still cancel.
* work (J) per step: ``h f_j (v0_j + v1_j)/2`` of each dof's force, attributed to the dof's body
  (the change of the states' kinetic energy under a semi-implicit step; RK4: at its displacement
  ``(q1 - q0) / h``); joint work: that of ``qfrc_constraint`` less the contacts' part (limits,
  friction loss, equalities); for ``xfrc_applied`` ``h (f . v + tau . w)`` at the step's start.
* integration (bodies whose joint kind is logged): per interval, the engine's momentum change
  ``m v``, ``L = R I R^T w`` between the two samples less the other kinds and ``m g dt``: the
  ``K`` below (docs/log-format.md, "The integration kind").

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
dJ/dt) v``-like terms, O(h^2) per step: logged as the integration kind (and 0 to round-off for
a body on slides whose centre of mass is on the slides, as stacker's boxes).

**RK4** re-evaluates the forces at three more states inside the step and leaves ``d`` with the
last one's, so the hook runs ``mj_forward`` at the step's start on a private ``MjData`` and logs
the forces of the first stage; ``a = (v1 - v0) / h`` is RK4's weighted mean of the four stages,
so the joint impulses (the Newton-Euler residual) close each body's balance as above, and the
other kinds are the first stage's: a free body's balance then misses ``h sum_i b_i (F_i - F_1)
= O(h^2) dF/dt``, which a log cannot carry.

**Cost** per step (``rec(d)``): one compiled call (``rblog.adapters._hook.StepRecord``, which
reads ``d->time``, ``ncon``, ``nefc``, ``efc_force`` at the offsets of
``rblog/adapters/_mjdata_offsets.py``; Python's own path for RK4, mocap bodies, a step not right
after the last one, another ``MjData``, and the numpy :class:`StepImpulses` without the build):
the hook, ``mj_rnePostConstraint`` (~1 us) with ``qvel``/``qacc`` swapped in and back, a few
copies of contiguous pieces of mjData into a preallocated row (:class:`Rows`), the sample's
bookkeeping and, per sample, the contacts' raw ``mjContact`` structs and ``efc_force``. A
sample's state is the next step's row (its start is the sample's state) under Euler and the
implicit integrators without mocap bodies, else :class:`Kinematics`. Every BLOCK_STEPS steps
the rows are resolved into impulses and the samples' states (compiled: ``_hook.resolve``, with
the joints' constraint forces, the work's velocity and xfrc_applied's work from numpy;
``_hook.states``; the integration kind and the samples' momenta ``_hook.integration``; numpy
without them), the contacts copied at each logged step (``_hook.ContactCapture``) decoded, and
all written as one block (``Recorder.write(owned=True)``: the impulse and work arrays are not
copied again). Per run, the body table is built from MjModel's arrays in numpy, and the
recorder's own ``MjData`` (inspect's and :class:`Kinematics`' kinematics) is the model's idle one
once a recorder of that model has closed (``take_scratch``: an ``MjData`` of dm_control's models
costs ~0.8 ms). Measured with benchmarks/bench_adapters.py (CPU time against the bare
``mj_step`` loop; RESULTS.md).

Why this module is long: the derivation of every impulse kind lives in this docstring, and the
recorder's per-block steps (states, impulses per interval, integration kind) each keep their
numpy reference beside the compiled call.
"""

from __future__ import annotations

import numpy as np

from rblog.adapters import AdapterError
from rblog.adapters._common import EngineRecorder
from rblog.adapters._mujoco_model import (BLOCK_STEPS, CONTACT_ROWS, Layout, _ContactArray, _is_model,
                                          _mj, _packed_contact_dict, capture_contacts, contacts,
                                          decode_contacts, give_back, gravity_of, inspect,
                                          settings, state_offsets, take_scratch, unsupported)
from rblog.adapters._mujoco_rollout import record_rollout
from rblog.adapters._mujoco_suite import suite_model
from rblog.adapters._mujoco_step import (ROW_FIELDS, Kinematics, Rows, StepImpulses, _cross,
                                         momenta)
from rblog.contract.model import IMPULSE_KINDS, SUPPLIED_LOGGED, WORK_KINDS


class MujocoRecorder(EngineRecorder):
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
        scratch = take_scratch(m)  # inspect's kinematics at qpos0, then Kinematics' own
        self.model, self.layout, notes = inspect(m, d, restitution=restitution, scratch=scratch)
        self.dt = float(m.opt.timestep)
        if not (np.isfinite(self.dt) and self.dt > 0):  # the samples' steps are time / dt
            raise AdapterError(f"rblog.adapters.mujoco: the model's option timestep is "
                               f"{self.dt!r}, expected a finite time step > 0 s")
        engine = {**settings(m), **notes, "sample_every": self.every}
        self.recorder = Recorder(self.model, rrd=rrd, mcap=mcap, dt=self.dt,
                                 writer=writer or f"mujoco {mj.__version__} via rblog.adapters",
                                 integrator=engine["integrator"], log_every=self.every,
                                 combine_friction="max", combine_restitution="max",
                                 engine_settings=engine, keep=keep, **recorder_options)
        self.recorder.open()
        from rblog.record._common import run_interval_channels

        self._channels = set(run_interval_channels(self.model))
        self.kin = Kinematics(m, self.layout, scratch)
        self._iquat = np.ascontiguousarray(self.kin.iquat, np.float64)
        self.hook = StepImpulses(m, self.layout, d, block=block)
        self.deferred = not self.hook.rk4 and int(m.nmocap) == 0
        cap = self.hook.cap + 1
        self._ids = self.layout.body_id
        self._steps = np.empty(cap, np.int64)
        # samples waiting for their interval's impulses (and, deferred, their kinematics)
        self._new_state_buffers()
        self._row = np.full(cap, -1, np.int64)  # the hook row of the sample's own step, -1: state known
        self._gap = np.zeros(cap, bool)
        self._raw = []
        self._hook_steps = np.empty(self.hook.cap, np.int64)  # the step each gathered row ended
        self._carry_W = np.zeros((len(IMPULSE_KINDS), m.nbody, 6))
        self._carry_work = np.zeros((len(WORK_KINDS), m.nbody))
        self._carray, self._carray_d = None, None  # the raw view of d's contacts, once there are some
        try:  # the logged steps' raw contacts, copied in C++ (else capture_contacts, numpy)
            from rblog.adapters._hook import ContactCapture

            self._capture = ContactCapture()
        except ImportError:
            self._capture = None
        self._decoding = False  # the compiled capture decodes the contacts (_decode_in_capture)
        self._fast, self._fast_d, self._efc_offset = None, None, None
        self._prev_momenta = None  # (step, P (N, 3), L (N, 3)) of the last sample written
        self._integration_fixed = None  # the compiled integration's fixed arrays
        self.step = int(round(float(d.time) / self.dt))
        self._add_sample(d, row=-1, contacts=False)
        self._arm(d)

    # the per-step counters, in the hook's array the compiled call shares (StepImpulses.counters)
    _ns = property(lambda self: int(self.hook.counters[1]),
                   lambda self, v: self.hook.counters.__setitem__(1, v),
                   doc="samples waiting to be written")
    step = property(lambda self: int(self.hook.counters[2]),
                    lambda self, v: self.hook.counters.__setitem__(2, v),
                    doc="the last step seen")
    _carry_gap = property(lambda self: bool(self.hook.counters[3]),
                          lambda self, v: self.hook.counters.__setitem__(3, int(bool(v))),
                          doc="steps not seen since the last sample")

    def _arm(self, d) -> None:
        """The compiled per-step call (rblog.adapters._hook.StepRecord) over ``d``, when the
        build has it, the hook is compiled, the samples' states are deferred and ``d``'s field
        offsets check out (rblog/adapters/_mjdata_offsets.py); else ``rec(d)`` stays Python."""
        if not self.deferred or self.hook.compiled is None or self._capture is None:
            return
        try:
            from rblog.adapters._hook import StepRecord
        except ImportError:
            return
        from rblog.adapters._mjdata_offsets import verified

        off = verified(d)
        if off is None:
            return
        addr = lambda a: a.__array_interface__["data"][0]  # noqa: E731
        self._efc_offset = off[3]
        self._fast = StepRecord(self.hook.compiled, self._capture, int(d._address), *off, self.dt,
                                self.every, len(self._steps), addr(self.hook.counters),
                                addr(self._hook_steps), addr(self._steps), addr(self._row),
                                addr(self._gap))
        self._fast_d = d

    def _add_sample(self, d, row: int, contacts: bool = True) -> None:
        i = self._ns
        self._steps[i] = self.step
        self._row[i] = row
        if row < 0:
            self.kin(d.qpos, d.qvel, d.mocap_pos, d.mocap_quat,
                     out=(self._x[i], self._r[i], self._v[i], self._w[i]))
            self._q[i] = self.kin.quat_wxyz()
        self._ns = i + 1
        ncon = d.ncon if contacts else 0
        if ncon:
            if self._carray is None or self._carray_d is not d:
                try:
                    self._carray, self._carray_d = _ContactArray(self.m, d), d
                except ValueError:  # an mjContact the view cannot describe: field by field
                    self._carray, self._carray_d = False, d
                if self._carray and self._capture is not None:
                    self._capture.contacts_at(self._carray.base, self._carray.dtype.itemsize,
                                              self._carray.count)
                    self._capture_dtype = self._carray.dtype
                    self._decode_in_capture(self._carray.dtype)
                if self._fast_d is d and not (self._carray and self._efc_ok(d)):
                    self._fast, self._fast_d = None, None  # the compiled call cannot read them
            if self._carray and self._capture is not None:
                self._capture.capture(self.step, ncon, d.efc_force)
            else:
                self._raw.append(capture_contacts(d, self.step, self._carray or None))

    def __call__(self, d) -> None:
        """Log the step that just ended in ``d`` (call after every ``mj_step``)."""
        if d is self._fast_d:  # one compiled call (StepRecord); 2: this call is Python's
            r = self._fast.record()
            if r == 0:
                return
            if r == 1:
                self.flush()
                return
        elif self._fast is not None:  # another MjData: Python's path from here on
            self._fast, self._fast_d = None, None
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

    def close(self, truncated: bool = False, reason: str | None = None) -> None:
        try:
            super().close(truncated=truncated, reason=reason)
        finally:  # the model's idle MjData again (Kinematics makes a new one if called after)
            if self.kin.d is not None:
                give_back(self.m, self.kin.d)
                self.kin.d = None

    def _efc_ok(self, d) -> bool:
        from rblog.adapters._mjdata_offsets import efc_force_matches

        return efc_force_matches(d, self._efc_offset)

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
        have = nxt < hook.k  # and that row is the very next step (not one after steps not seen)
        have[have] = self._hook_steps[nxt[have]] == self._steps[pend[have]] + 1
        if self.deferred and have.any() and _states_kernel():  # compiled: the same formulas
            from rblog.adapters._hook import states

            off, root = hook.fixed()[:2]
            states(R, off, np.ascontiguousarray(nxt[have]), np.ascontiguousarray(pend[have]),
                   self._ids, root, self._iquat, self._x, self._r, self._q, self._v, self._w)
        elif self.deferred and have.any():  # numpy: the same formulas
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
        """(W (ns, 6, nbody, 6), work (ns, 4, nbody)) of each waiting sample's interval: the
        steps in (step[i-1], step[i]]; the steps after the last sample carry over."""
        k = self.hook.k
        W, work = self.hook.resolve() if k else (None, None)
        steps = self._hook_steps[:k]
        pos = np.searchsorted(steps, self._steps[:ns], side="right")  # rows before sample i's end
        starts = np.concatenate([[0], pos[:-1]])
        last = int(pos[-1]) if ns else 0
        nonempty = pos > starts
        one = bool(np.all(pos - starts <= 1))  # at most one step per interval
        if k and last and one and ns == k == last and nonempty.all():
            rows_W, rows_work = W, work  # a sample every step: row i is sample i's interval
        else:
            rows_W = np.zeros((ns, *self._carry_W.shape))
            rows_work = np.zeros((ns, *self._carry_work.shape))
            if k and last and one:  # a gather (a slice when the rows are contiguous)
                sel = np.flatnonzero(nonempty)
                src = starts[sel]
                if sel[-1] - sel[0] == len(sel) - 1 and src[-1] - src[0] == len(src) - 1:
                    sel, src = slice(sel[0], sel[-1] + 1), slice(src[0], src[-1] + 1)
                rows_W[sel] = W[src]
                rows_work[sel] = work[src]
            elif k and last:  # reduceat sums [start_i, start_i+1), the last to `last`
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
        p, L = self._integration(W, ns)  # into W[:, integration, ids]
        ids = self._ids
        if len(ids) and np.array_equal(ids, np.arange(ids[0], ids[0] + len(ids))):
            W, work = W[:, :, ids[0]:ids[0] + len(ids)], work[:, :, ids[0]:ids[0] + len(ids)]
        else:
            W, work = W[:, :, ids], work[:, :, ids]
        gap = self._gap[:ns]
        if gap.any():
            W[gap] = np.nan
            work[gap] = np.nan
        steps = self._steps[:ns].copy()
        arrays = dict(t=steps * self.dt, step=steps, position=self._x[:ns],
                      rotation=self._r[:ns], quat_wxyz=self._q[:ns], velocity=self._v[:ns],
                      angular_velocity=self._w[:ns], linear_momentum=p,
                      angular_momentum=L)  # the momenta the integration kind is taken from
        self._new_state_buffers()  # the block keeps these (no copy); the next samples go to new ones
        for a, kind in enumerate(IMPULSE_KINDS):
            arrays[f"impulse_{kind}_angular"] = W[:, a, :, :3]
            arrays[f"impulse_{kind}_linear"] = W[:, a, :, 3:]
        for a, kind in enumerate(WORK_KINDS):
            arrays[f"work_{kind}"] = work[:, a]
        # the channels no body logs (a model of free bodies logs no joint impulse)
        for name in [k for k in arrays if k.startswith(("impulse_", "work_"))]:
            if name not in self._channels:
                del arrays[name]
        rows = self._contact_rows()
        if rows is not None:
            arrays["contacts"] = rows
        self._raw = []
        self._ns = 0
        self._gap[:] = False
        self.recorder.write(owned=True, **arrays)  # W and work are this block's own

    def _new_state_buffers(self) -> None:
        """Fresh (cap, N, ...) buffers for the waiting samples' states (position, rotation,
        quaternion, velocity, angular velocity)."""
        cap, n = len(self._steps), len(self.layout)
        self._x, self._r = np.empty((cap, n, 3)), np.empty((cap, n, 3, 3))
        self._q = np.empty((cap, n, 4))
        self._v, self._w = np.empty((cap, n, 3)), np.empty((cap, n, 3))

    def _integration(self, W, ns: int):
        """The integration kind of each waiting sample's interval, written into ``W`` (ns, kinds,
        nbody, 6) [angular; linear] at ``W[:, integration, ids]`` (the bodies whose joint kind is
        logged; 0 elsewhere): the momentum change MuJoCo's steps gave each body, ``P = m v``,
        ``L = R diag(I) R^T w`` of the engine's state at the interval's ends, less the other kinds'
        impulses and ``m g dt`` (docs/log-format.md, "The integration kind"). Returns the momenta
        ``P``, ``L`` (ns, N, 3), logged as the samples' momenta. The first sample of the run has
        no interval: 0. Keeps the last sample's momenta for the next block. Compiled
        (``rblog.adapters._hook.integration``) when the build has it, else numpy (the same
        formulas in the same order: :meth:`_integration_numpy`)."""
        try:
            from rblog.adapters._hook import integration
        except ImportError:
            return self._integration_numpy(W, ns)
        model, n = self.model, len(self._ids)
        if self._integration_fixed is None:
            c = np.ascontiguousarray
            logged = np.asarray(model.body_impulse_supplied)[:, IMPULSE_KINDS.index("integration")]
            self._integration_fixed = (
                c(self._ids, np.int64), c(model.body_mass, np.float64),
                c(model.body_inertia_diag, np.float64), c(model.gravity, np.float64),
                c(logged == SUPPLIED_LOGGED, np.int64))
        ids, mass, inertia, g, logged = self._integration_fixed
        prev = self._prev_momenta
        p, L = np.empty((ns, n, 3)), np.empty((ns, n, 3))
        zero = np.zeros((n, 3))
        integration(W, ids, mass, inertia, g, logged, np.ascontiguousarray(self._steps[:ns]),
                    self.dt, prev is not None, int(prev[0]) if prev else 0,
                    prev[1] if prev else zero, prev[2] if prev else zero, self._r, self._v,
                    self._w, p, L)
        self._prev_momenta = (int(self._steps[ns - 1]), p[-1].copy(), L[-1].copy())
        return p, L

    def _integration_numpy(self, W, ns: int):
        """:meth:`_integration` in numpy (the reference of the compiled one)."""
        model, ids = self.model, self._ids
        steps, v, r, w = self._steps[:ns], self._v[:ns], self._r[:ns], self._w[:ns]
        m = np.asarray(model.body_mass, np.float64)
        inertia = np.asarray(model.body_inertia_diag, np.float64)
        p, L = momenta(m, inertia, r, v, w)
        prev = self._prev_momenta
        if prev is None:
            prev = (steps[0], p[0], L[0])
        step0 = np.concatenate([[prev[0]], steps[:-1]])
        dt = (steps - step0) * self.dt
        dp = p - np.concatenate([prev[1][None], p[:-1]])
        dl = L - np.concatenate([prev[2][None], L[:-1]])
        Wb = W[:, :, ids]
        forces = Wb[:, 0] + Wb[:, 1]  # the kinds before integration, in order
        for a in range(2, IMPULSE_KINDS.index("integration")):
            forces += Wb[:, a]
        out = np.empty((len(steps), len(m), 6))
        out[..., 3:] = dp - m[None, :, None] * np.asarray(model.gravity, np.float64) * dt[:, None,
                                                                                           None]
        out[..., 3:] -= forces[..., 3:]
        out[..., :3] = dl - forces[..., :3]
        logged = np.asarray(model.body_impulse_supplied)[:, IMPULSE_KINDS.index("integration")]
        out[:, logged != SUPPLIED_LOGGED] = 0.0  # none or missing (the Model's table)
        W[:, IMPULSE_KINDS.index("integration"), ids] = out
        self._prev_momenta = (int(steps[-1]), p[-1].copy(), L[-1].copy())
        return p, L

    def _contact_rows(self):
        """The contact rows of the samples since the last flush: those the compiled capture
        decoded (``ContactCapture.rows``, decode_contacts' formulas), with those of the Python
        captures (decode_contacts) merged in step order; all from decode_contacts when the
        capture keeps raw structs."""
        if not self._decoding:
            return decode_contacts(self.m, self.layout, self._raw, packed=self._captured())
        rows = self._capture.rows()
        if not self._raw:
            return rows
        py = decode_contacts(self.m, self.layout, self._raw)
        if rows is None or py is None:
            return py if rows is None else rows
        order = np.argsort(np.concatenate([py["step"], rows["step"]]), kind="stable")
        return {k: np.concatenate([py[k], rows[k]])[order] for k in py}

    def _decode_in_capture(self, dtype) -> None:
        """Have the compiled capture decode each logged step's contacts (ContactCapture.
        decode_with) when the mjContact fields are of the types it reads (float64 dist, pos,
        frame, friction; int32 dim, geom, exclude, efc_address); else it keeps raw structs."""
        if self._decoding:
            return
        want = dict(dist=("<f8", ()), pos=("<f8", (3,)), frame=("<f8", (9,)),
                    friction=("<f8", (5,)), dim=("<i4", ()), geom=("<i4", (2,)),
                    exclude=("<i4", ()), efc_address=("<i4", ()))
        if list(dtype.names) != list(want) or not all(
                dtype.fields[f][0].base == np.dtype(t) and dtype.fields[f][0].shape == sh
                for f, (t, sh) in want.items()):
            return
        pyramidal = int(self.m.opt.cone) == int(_mj().mjtCone.mjCONE_PYRAMIDAL)
        self._capture.decode_with([int(dtype.fields[f][1]) for f in want],
                                  self.layout.geom_index.tolist(), pyramidal,
                                  float(self.m.opt.timestep))
        self._decoding = True

    def _captured(self):
        """The compiled capture's steps since the last flush, as _packed_contact_dict, or None."""
        if self._capture is None:
            return None
        steps, ncon, nefc, raw, efc = self._capture.take()
        if not len(steps):
            return None
        return _packed_contact_dict(steps, ncon, raw.view(self._capture_dtype), nefc, efc)


def _states_kernel() -> bool:
    """Whether the build has the compiled state gather (rblog.adapters._hook.states)."""
    try:
        from rblog.adapters._hook import states  # noqa: F401
    except ImportError:
        return False
    return True


def recorder(m, d=None, **options) -> MujocoRecorder:
    """``MujocoRecorder(m, d, **options)``: the first of the two lines."""
    return MujocoRecorder(m, d, **options)


__all__ = ["BLOCK_STEPS", "CONTACT_ROWS", "Kinematics", "Layout", "MujocoRecorder", "ROW_FIELDS",
           "Rows", "StepImpulses", "capture_contacts", "contacts", "decode_contacts", "gravity_of",
           "inspect", "record_rollout", "recorder", "settings", "state_offsets", "suite_model",
           "unsupported"]
