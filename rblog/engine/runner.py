"""The run loop: choose the stages a scene needs, advance in compiled blocks, hand each block of
samples to the recorders, and keep the summary figures.

Python runs once per block (see :func:`samples_per_block`),
never per step. A diverging, interrupted or failing run closes every recorder with what was
written so far, so logs stay readable up to the last good sample.

:func:`run` reads as its sequence: check the options, choose the stages, then ``_Loop``'s
open (the logs and their first sample), step_all (compiled calls sized to CALL_WALL_BUDGET_S of
wall time, samples on global multiples of the stride whatever the split), close; ``_Loop.abort``
is the one way out of a run that does not get there. SIGINT and SIGTERM set a flag checked
between calls (``_StopFlag``) and end the run as RunInterrupted with the logs closed
"interrupted". The threads that log beside the stepping are rblog.engine.pipeline's.
"""

from __future__ import annotations

import dataclasses
import signal
import threading
import time
from dataclasses import asdict, dataclass, field
from typing import Callable, Protocol

import numpy as np

from rblog import __version__
from rblog.engine.constants import (
    BLOCK_MAX_BODY_SAMPLES,
    BLOCK_MAX_BODY_STEPS,
    BLOCK_MAX_SAMPLES,
    CALL_GROWTH_MAX,
    CALL_WALL_BUDGET_S,
    DEFAULT_LOG_RATE_HZ,
    MAX_ROTATION_PER_STEP_RAD,
    MAX_RUN_STEPS,
)
from rblog._threads import default_threads
from rblog.engine import _core
from rblog.errors import RunInterrupted, SceneError, SimulationDiverged
from rblog.engine.free import advance_free
from rblog.contract.model import (IMPULSE_KINDS, SUPPLIED_LOGGED, SUPPLIED_NONE, WORK_KINDS,
                                  Model)
from rblog.engine.integrators import METHOD_CODES, ORTHO_ALLOWED, ORTHO_CODES
from rblog.engine.scene import Scene
from rblog.engine.pipeline import BlockPipeline
from rblog.engine.plan import Plan, plan_stages
from rblog.contract.trajectory import RunInfo, Trajectory, derive


class Recorder(Protocol):
    """What the run loop needs of a log writer (see rblog.record)."""

    def open(self, model: Model, info: RunInfo) -> None: ...
    def write(self, block: Trajectory) -> None: ...
    def close(self, truncated: bool = False, reason: str | None = None) -> None: ...


class TrajectoryCollector:
    """A recorder that keeps the whole run in memory (tests, benchmarks, small runs)."""

    def __init__(self):
        self.blocks: list[Trajectory] = []
        self.truncated = False

    def open(self, model, info):
        self.blocks = []

    def write(self, block):
        self.blocks.append(block)

    def close(self, truncated=False, reason=None):
        self.truncated = truncated

    @property
    def trajectory(self) -> Trajectory:
        traj = Trajectory.concat(self.blocks)
        traj.truncated = self.truncated
        return traj


@dataclass
class RunSummary:
    """Figures of a finished (or stopped) run. Drifts are over the logged samples.

    energy_drift_rel: max |E - E0| of the total energy (kinetic + gravity potential) over the
        run's energy scale: the largest kinetic energy plus sum_i m_i |g| (height range of body
        i), so that it does not depend on where the potential's zero is (see ``_Drift``).
    angular_momentum_drift_rel: max over bodies of | |L_i| - |L_i0| | / |L_i0| (spin angular
        momentum about each body's centre of mass; 0 for bodies with no initial spin).
    ortho_error_max: max ||R^T R - I||_F over bodies and samples.
    not_applicable: the figures above that do not measure an error in this scene, each with why
        (:func:`drift_not_applicable`): energy is an invariant only of free flight without applied
        forces or torques, each body's |L| only of free flight without applied torques. The
        figures are still computed; ``rblog run`` shows the reason instead of the number.
    contact_penetration_max_m: the deepest overlap (m) of any two shapes (bodies, ground, static
        boxes) at the logged samples, measured on their poses by the contact narrowphase
        (``contact.measure``); 0 if none overlaps; None in a scene that runs no contact stage.
    """

    status: str
    steps: int
    bodies: int
    samples: int
    sim_time_s: float
    wall_time_s: float
    steps_per_s: float
    body_steps_per_s: float
    energy_drift_rel: float
    angular_momentum_drift_rel: float
    ortho_error_max: float
    quat_norm_error_max: float
    integrator: str
    orthonormalize: str
    dt: float
    log_every: int
    stages: list[str] = field(default_factory=list)
    message: str = ""
    not_applicable: dict[str, str] = field(default_factory=dict)
    contact_penetration_max_m: float | None = None

    def to_dict(self) -> dict:
        return asdict(self)


def drift_not_applicable(model: Model, contacts: bool) -> dict[str, str]:
    """Which of RunSummary's drift figures are not errors in a scene, and why: ``contacts`` is
    True when bodies can touch (the run has a contact stage: impulses turn bodies, restitution
    and friction take energy); applied forces and torques (``body_force_world``,
    ``body_torque_world``) do work, and torques change |L|. Gravity is in the energy."""
    why: dict[str, str] = {}
    torque = bool(np.any(model.body_torque_world != 0))
    force = bool(np.any(model.body_force_world != 0))
    if contacts:
        touch = "bodies touch (contacts take energy and turn bodies: not invariants here)"
        why["energy_drift_rel"] = why["angular_momentum_drift_rel"] = touch
    else:
        if force or torque:
            why["energy_drift_rel"] = "applied forces or torques do work"
        if torque:
            why["angular_momentum_drift_rel"] = "applied torques change L"
    return why


class _Drift:
    """Running maxima of the summary figures over blocks.

    The energy drift is max |E - E0| over a scale that, like E - E0, does not depend on where the
    zero of potential energy is: the largest kinetic energy seen plus sum_i m_i |g| times the
    range of heights (along g) body i covered. A run where nothing moves has drift 0.
    """

    def __init__(self, model: Model | None = None, contact_world=None):
        self.e0 = None
        self.l0 = None
        self.de_max = 0.0
        self.ke_max = 0.0
        self.h_lo = None
        self.h_hi = None
        self.spin = 0.0
        self.ortho = 0.0
        self.qnorm = 0.0
        self.penetration = 0.0  # deepest overlap at the samples' poses, m
        self.model = model
        # a ContactWorld of the scene that is never stepped: its narrowphase measures the poses
        self.contact_world = contact_world

    @property
    def energy(self) -> float:
        scale = self.ke_max
        if self.model is not None and self.h_lo is not None:
            g = float(np.linalg.norm(self.model.gravity))
            scale += float(np.sum(self.model.body_mass * g * (self.h_hi - self.h_lo)))
        return self.de_max / scale if scale > 0 else 0.0

    def update(self, b: Trajectory):
        if b.n_samples == 0:
            return
        if self.e0 is None:
            self.e0 = float(b.total_energy[0])
            self.l0 = np.linalg.norm(b.angular_momentum[0], axis=-1)
        self.de_max = max(self.de_max, float(np.max(np.abs(b.total_energy - self.e0))))
        self.ke_max = max(self.ke_max, float(np.max((b.energy_translational + b.energy_rotational).sum(axis=1))))
        if self.model is not None:
            g = np.asarray(self.model.gravity, float)
            gn = float(np.linalg.norm(g))
            if gn > 0:
                h = -(b.position @ (g / gn))  # (S, N) height along -g, m
                lo, hi = h.min(axis=0), h.max(axis=0)
                self.h_lo = lo if self.h_lo is None else np.minimum(self.h_lo, lo)
                self.h_hi = hi if self.h_hi is None else np.maximum(self.h_hi, hi)
        spin = np.linalg.norm(b.angular_momentum, axis=-1)
        has = self.l0 > 0
        if np.any(has):
            d = np.abs(spin[:, has] - self.l0[has]) / self.l0[has]
            self.spin = max(self.spin, float(d.max()))
        self.ortho = max(self.ortho, float(b.ortho_error.max()))
        self.qnorm = max(self.qnorm, float(np.abs(b.quat_norm_error).max()))
        if self.contact_world is not None:
            from rblog.engine.contact.measure import max_penetration

            for k in range(b.n_samples):  # 0.2 s of CPU for the 500-box pile's 301 samples
                self.penetration = max(self.penetration, max_penetration(
                    self.contact_world, b.position[k], b.rotation[k]))


def resolve_log_every(dt: float, log_every: int | None, log_rate: float | None) -> int:
    """Steps between logged samples from --log-every or --log-rate (Hz of simulated time)."""
    if log_every is not None:
        return max(1, int(log_every))
    rate = log_rate if log_rate is not None else DEFAULT_LOG_RATE_HZ
    return max(1, int(round(1.0 / (rate * dt))))


def samples_per_block(n_bodies: int, stride: int) -> int:
    """Logged samples per block: at most BLOCK_MAX_SAMPLES, BLOCK_MAX_BODY_SAMPLES / bodies
    (memory) and BLOCK_MAX_BODY_STEPS / (bodies * stride) (responsiveness), and at least 1."""
    n = max(1, int(n_bodies))
    return int(max(1, min(BLOCK_MAX_SAMPLES, BLOCK_MAX_BODY_SAMPLES // n,
                          BLOCK_MAX_BODY_STEPS // (n * max(1, int(stride))))))


def run(
    scene: Scene,
    *,
    dt: float | None = None,
    duration: float | None = None,
    integrator: str | None = None,
    orthonormalize: str | None = None,
    log_every: int | None = None,
    log_rate: float | None = None,
    recorders: list[Recorder] | tuple = (),
    progress: Callable[[int, int], None] | None = None,
    force_contacts: bool = False,
    profile=None,
    warn: Callable[[str], None] | None = None,
    threads: int | None = None,
) -> RunSummary:
    """Simulate ``scene`` and stream samples to ``recorders``.

    Options override the scene's ``[sim]`` values. ``progress(done_steps, total_steps)`` is called
    after every block; ``warn(msg)`` gets one-line
    warnings about the scene (bodies that start overlapping). ``profile`` (an
    ``engine.profile.Profile``) accumulates seconds per stage. ``threads``: how many threads the
    core steps on (default ``rblog._threads.default_threads()``: ``RBLOG_THREADS``, else the
    machine's cores); the result is bitwise the same for any count.

    Raises:
        SceneError: an option is out of range.
        SimulationDiverged: the state became non-finite (logs closed up to the last good sample).
        RunInterrupted: Ctrl-C (logs closed up to the last good sample).
    """
    sim = scene.sim
    dt = sim.dt if dt is None else dt
    duration = sim.duration if duration is None else duration
    if not (dt > 0 and np.isfinite(dt)):
        raise SceneError(scene.path, "--dt", f"expected a positive number, got {dt}")
    if not (duration > 0 and np.isfinite(duration)):
        raise SceneError(scene.path, "--duration", f"expected a positive number, got {duration}")
    if dt > duration:
        raise SceneError(scene.path, "--dt" if dt != sim.dt else "sim.dt",
                         f"dt = {dt:g} s is longer than the duration {duration:g} s (expected "
                         "dt <= duration)")
    if duration / dt > MAX_RUN_STEPS:
        raise SceneError(scene.path, "--dt" if dt != sim.dt else "sim.dt",
                         f"dt = {dt:g} s makes {duration / dt:.3g} steps for {duration:g} s "
                         f"(expected at most {MAX_RUN_STEPS:.0e} steps)")
    if threads is not None and (isinstance(threads, bool) or int(threads) != threads or threads < 1):
        raise SceneError(scene.path, "--threads", f"expected a positive integer, got {threads!r}")
    _core.set_threads(int(threads) if threads is not None else default_threads())
    integrator = integrator or sim.integrator
    if integrator not in ORTHO_ALLOWED:
        raise SceneError(scene.path, "--integrator",
                         f"expected one of {', '.join(ORTHO_ALLOWED)}, got {integrator!r}")
    allowed, default_ortho = ORTHO_ALLOWED[integrator]
    ortho = orthonormalize or (sim.orthonormalize if sim.integrator == integrator else None) or default_ortho
    if ortho not in allowed:
        raise SceneError(scene.path, "--orthonormalize",
                         f"integrator {integrator} takes {' or '.join(allowed)}, got {ortho!r}")
    if log_every is None and log_rate is None:
        log_every, log_rate = sim.log_every, sim.log_rate
    stride = resolve_log_every(dt, log_every, log_rate)
    n_total = max(1, int(round(duration / dt)))
    method, ortho_code = METHOD_CODES[integrator], ORTHO_CODES[ortho]

    plan = plan_stages(scene, duration, force_contacts=force_contacts)
    model = engine_model(scene.model, plan.contacts)
    n_bodies = model.n_bodies
    info = RunInfo(
        integrator=integrator, orthonormalize=ortho, dt=dt, log_every=stride,
        duration_s=n_total * dt, rblog_version=__version__, scene_path=scene.path,
        scene_toml=scene.toml_text, scene_resolved=scene.resolved, seed=sim.seed,
        writer=f"rblog {__version__}",
    )
    st = scene.state.copy()
    advance = _make_advance(plan, model, method, ortho_code, profile)
    if warn is not None:
        for w in plan.warnings:
            warn(w)

    drift = _Drift(model, _measure_world(scene, method, ortho_code) if plan.contacts else None)
    loop = _Loop(model, info, st, advance, drift, n_total, profile)
    stop = _StopFlag()
    with stop:
        try:
            loop.open(recorders, stop)
            loop.step_all(stop, progress)
            loop.close()
        except BaseException as e:
            err = loop.abort(e)
            if err is e:
                raise
            raise err from None
    if stop.signum is not None:  # arrived while the logs were being closed: they are complete
        name = signal.Signals(stop.signum).name
        raise RunInterrupted(f"run interrupted by {name} after its last step (t = "
                             f"{loop.done * dt:.6g} s); logs complete", signum=stop.signum)
    wall = time.perf_counter() - loop.t_start
    if profile is not None:
        profile.wall = wall
    done = loop.done
    return RunSummary(
        status="ok", steps=done, bodies=n_bodies, samples=loop.n_samples, sim_time_s=done * dt,
        wall_time_s=wall, steps_per_s=done / wall if wall > 0 else float("inf"),
        body_steps_per_s=done * n_bodies / wall if wall > 0 else float("inf"),
        energy_drift_rel=drift.energy, angular_momentum_drift_rel=drift.spin,
        ortho_error_max=drift.ortho, quat_norm_error_max=drift.qnorm, integrator=integrator,
        orthonormalize=ortho, dt=dt, log_every=stride, stages=[s for s, _ in plan.stages],
        not_applicable=drift_not_applicable(model, plan.contacts),
        contact_penetration_max_m=drift.penetration if plan.contacts else None,
    )


class _Loop:
    """One run's moving parts, in the order :func:`run` calls them: :meth:`open` (the logs and
    their first sample), :meth:`step_all` (compiled calls, each block of samples handed to the
    writers), :meth:`close` (the logs complete); :meth:`abort` is the one way out of a run that
    did not get there."""

    def __init__(self, model: Model, info: RunInfo, st, advance, drift, n_total: int, profile):
        self.model, self.info, self.st, self.advance = model, info, st, advance
        self.drift, self.n_total, self.profile = drift, n_total, profile
        self.dt, self.stride = info.dt, info.log_every
        self.samples_in_block = samples_per_block(model.n_bodies, self.stride)
        self.opened: list[Recorder] = []
        self.writer: BlockPipeline | None = None
        self.done = 0  # steps taken
        self.n_samples = 0  # samples handed to the writers
        self.t_start = time.perf_counter()

    def buffers(self, s: int):
        """Sample buffers for ``s`` samples (+1 spare), each (s+1, N, ...). Fresh ones each call:
        the block is handed to the recorders as is (no copy), and a recorder may keep it."""
        n = self.model.n_bodies
        s = s + 1
        return (np.empty((s, n, 3)), np.empty((s, n, 3)), np.empty((s, n, 4)),
                np.empty((s, n, 3, 3)), np.empty((s, n, 3)),
                np.empty((s, n, 6)))  # the contact impulses of each interval

    def open(self, recorders, stop: "_StopFlag"):
        """A first call of zero steps and the first derived channels (no file open yet: a signal
        raises at once), then the logs with their first sample (a signal waits until they hold
        it, so that an interrupted run leaves logs that read)."""
        st, m = self.st, self.model
        stop.raise_now = True
        self.advance(self.dt, 0, self.stride, False, st.copy(), self.buffers(self.samples_in_block))
        derive(m, self.info, np.array([0]), np.array([0.0]), st.position[None],
               st.linear_momentum[None], st.quat_wxyz[None], st.rotation[None],
               st.angular_momentum_world[None])
        stop.raise_now = False
        stop.check()
        for r in recorders:
            self.opened.append(r)  # closed on the way out even if its open fails midway
            r.open(m, self.info)
        self.t_start = time.perf_counter()  # the run's wall time: stepping and writing
        self.writer = BlockPipeline(m, self.info, self.drift, self.opened)
        self.writer.submit(np.array([0]), st.position[None].copy(), st.linear_momentum[None].copy(),
                           st.quat_wxyz[None].copy(), st.rotation[None].copy(),
                           st.angular_momentum_world[None].copy(), None,
                           np.zeros((1, m.n_bodies, 6)))  # the initial state: no interval
        self.n_samples = 1
        stop.check()

    def step_all(self, stop: "_StopFlag", progress):
        """Step to the end in compiled calls of about CALL_WALL_BUDGET_S of wall time each
        (measured on the previous call), which bounds how late a signal is seen and how much a
        killed run loses. Samples stay at global multiples of the stride (and the last step),
        whatever the call boundaries, and the kernels carry their whole state across calls, so
        the result does not depend on the split."""
        dt, stride, n_total, st = self.dt, self.stride, self.n_total, self.st
        steps_per_block = self.samples_in_block * stride  # the most steps one call may take
        sec_per_step = None
        last_n = 1
        while self.done < n_total:
            stop.check()
            done = self.done
            remaining = n_total - done
            if sec_per_step is None:
                budget = min(stride, remaining)
            else:
                budget = int(CALL_WALL_BUDGET_S / max(sec_per_step, 1e-12))
                budget = max(1, min(budget, int(CALL_GROWTH_MAX * last_n) + 1))
            budget = min(budget, steps_per_block, remaining)
            to_boundary = stride - done % stride
            if done % stride == 0 and budget >= stride:
                # whole strides (or the run's tail): sample at the call's own stride
                n = remaining if budget == remaining else (budget // stride) * stride
                call_stride = stride
                sample_last = (done + n == n_total) and (n % stride != 0)
            else:
                # inside one stride interval: at most one sample, at the call's end
                n = min(budget, to_boundary)
                if n == to_boundary:
                    call_stride, sample_last = n, False
                else:
                    call_stride, sample_last = n + 1, done + n == n_total
            first = (done // stride + 1) * stride
            glob = np.arange(first, done + n + 1, stride, dtype=np.int64)
            if done + n == n_total and n_total % stride != 0:
                glob = np.append(glob, n_total)
            local = glob - done
            bufs = self.buffers(len(local))
            t_call = time.perf_counter()
            _, bad_step, bad_body, contacts = self.advance(dt, n, call_stride, sample_last, st, bufs)
            wall = time.perf_counter() - t_call
            if bad_step < 0:
                sec_per_step = wall / n
                last_n = n
            keep = len(local) if bad_step < 0 else int(np.searchsorted(local, bad_step))
            local = local[:keep]
            if keep:
                if contacts is not None:
                    contacts.step = contacts.step + done
                    if bad_step >= 0:
                        contacts = contacts.select(contacts.step < done + bad_step)
                self._timed_logging(self.writer.submit, done + local,
                                    *(b[:keep] for b in bufs[:5]), contacts,
                                    impulses=bufs[5][:keep])
                self.n_samples += keep
            if bad_step >= 0:
                bad_global = done + bad_step
                self.done = bad_global - 1
                raise SimulationDiverged(bad_global, bad_global * dt, int(bad_body),
                                         self.model.body_name[bad_body],
                                         _divergence_reason(self.model, st, int(bad_body), dt))
            self.done = done + n
            if progress is not None:
                progress(self.done, n_total)

    def close(self):
        """Write what is queued and close every log complete (the lanes close theirs side by
        side)."""
        self._timed_logging(self.writer.finish, close=True)
        _close_all([r for r in self.opened if not self.writer.has_closed(r)], False, None)

    def abort(self, e: BaseException) -> BaseException:
        """Write the queued (good) samples, close every opened log marked truncated with the
        reason, and return the exception to raise: RunInterrupted for a signal, else ``e``."""
        if isinstance(e, SystemError) and isinstance(e.__cause__ or e.__context__, KeyboardInterrupt):
            e = KeyboardInterrupt()  # a signal handler's exception out of a compiled call
        signum = e.signum if isinstance(e, _Stopped) else (
            signal.SIGINT if isinstance(e, KeyboardInterrupt) else None)
        if signum is None:
            reason, err = (str(e) if isinstance(e, SimulationDiverged) else f"run failed: {e}"), e
        else:
            name = signal.Signals(signum).name
            reason = f"interrupted ({name}) at step {self.done}"
            kept = "logs keep every sample written before it" if self.opened else "no log written"
            err = RunInterrupted(f"run interrupted at step {self.done} (t = "
                                 f"{self.done * self.dt:.6g} s) by {name}; {kept}", signum=signum)
        if self.writer is not None:
            self.writer.finish_quietly()
        try:
            _close_all(self.opened, True, reason)
        except Exception:
            if signum is None:  # a log that cannot be closed is news; after a signal it is not
                raise
        return err

    def _timed_logging(self, fn, *args, **kwargs):
        t0 = time.perf_counter()
        fn(*args, **kwargs)
        if self.profile is not None:
            self.profile.add("logging", time.perf_counter() - t0)


def simulate(scene: Scene, **kwargs) -> tuple[Trajectory, RunSummary]:
    """Run ``scene`` keeping every logged sample in memory; returns (trajectory, summary)."""
    col = TrajectoryCollector()
    recorders = [col, *kwargs.pop("recorders", ())]
    summary = run(scene, recorders=recorders, **kwargs)
    return col.trajectory, summary


class _Stopped(Exception):
    """Raised between compiled calls when SIGINT or SIGTERM arrived."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


class _StopFlag:
    """While active (``with``), SIGINT and SIGTERM set a flag instead of raising inside a
    compiled call (where CPython can only report them as a SystemError, and only when the call
    returns). The run loop calls :meth:`check` between calls. While ``raise_now`` is set
    (compiling kernels, opening recorders: Python code), a signal raises at once. Handlers are
    installed only from the main thread (signals are delivered there) and restored on exit."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.signum: int | None = None
        self.raise_now = False
        self._old: dict = {}

    def _handler(self, signum, frame):
        self.signum = signum
        if self.raise_now:
            raise _Stopped(signum)

    def check(self):
        if self.signum is not None:
            raise _Stopped(self.signum)

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:
                try:
                    self._old[sig] = signal.signal(sig, self._handler)
                except (ValueError, OSError):
                    pass
        return self

    def __exit__(self, *exc):
        for sig, old in self._old.items():
            try:
                signal.signal(sig, old)
            except (ValueError, OSError):
                pass
        self._old = {}
        return False


def _close_all(recorders, truncated, reason):
    errors = []
    for r in recorders:
        try:
            r.close(truncated=truncated, reason=reason)
        except Exception as e:  # close every log even if one fails
            errors.append(e)
    if errors:
        raise errors[0]


def _divergence_reason(model: Model, st, i: int, dt: float) -> str:
    """Why body i stopped the run, from its state at the bad step (the kernels leave it there):
    a non-finite state, else a turn per step beyond MAX_ROTATION_PER_STEP_RAD."""
    parts = (st.position[i], st.linear_momentum[i], st.rotation[i], st.angular_momentum_world[i])
    if not all(np.all(np.isfinite(a)) for a in parts):
        return "has a non-finite state"
    # |omega| dt with omega = R diag(1/I) R^T L, as integrators.turn_within_bound
    with np.errstate(over="ignore", invalid="ignore"):
        w_body = (st.rotation[i].T @ st.angular_momentum_world[i]) / model.body_inertia_diag[i]
        turn = float(np.linalg.norm(w_body) * dt)
    if not turn > MAX_ROTATION_PER_STEP_RAD:
        return "has a non-finite state"
    return (f"turns {turn:.3g} rad in one step, more than MAX_ROTATION_PER_STEP_RAD = "
            f"{MAX_ROTATION_PER_STEP_RAD:g} rad")


def engine_model(model: Model, contacts: bool) -> Model:
    """``model`` as rblog's engine logs it (contract v3): it logs the contact impulses of every
    interval when bodies can touch (else they are none), the applied ones when a body has a
    constant force or torque (else none); it has no passive forces, actuators or joints (none),
    and no applied work besides its constant loads' (none: F . dx follows from the poses)."""
    n = model.n_bodies
    loads = bool(np.any(model.body_force_world) or np.any(model.body_torque_world))
    imp = np.full((n, len(IMPULSE_KINDS)), SUPPLIED_NONE, np.int64)
    imp[:, IMPULSE_KINDS.index("contact")] = SUPPLIED_LOGGED if contacts else SUPPLIED_NONE
    imp[:, IMPULSE_KINDS.index("applied")] = SUPPLIED_LOGGED if loads else SUPPLIED_NONE
    work = np.full((n, len(WORK_KINDS)), SUPPLIED_NONE, np.int64)
    return dataclasses.replace(model, body_impulse_supplied=imp, body_work_supplied=work)


def _measure_world(scene: Scene, method: int, ortho_code: int):
    """A ContactWorld of ``scene`` for measuring overlaps at the logged samples (on the writer
    thread; the stepping world is not shared with it)."""
    from rblog.engine.constants import ContactParams
    from rblog.engine.contact.world import ContactWorld

    return ContactWorld(scene.model, ContactParams.from_dict(scene.contact), method, ortho_code)


def _make_advance(plan: Plan, model: Model, method: int, ortho_code: int, profile=None):
    """The block-advance function for the chosen stages (timed into ``profile`` if given)."""
    if plan.contacts:
        world = plan.make_contact_world(method, ortho_code)
        if profile is not None:
            world.profile_ticks = profile.ticks

        def advance(dt, n, stride, sample_last, st, bufs):
            return world.advance(dt, n, stride, sample_last, st.position, st.linear_momentum,
                                 st.quat_wxyz, st.rotation, st.angular_momentum_world, *bufs[:5],
                                 anchors=st.anchors, out_impulses=bufs[5])

        return advance

    inv_mass = 1.0 / model.body_mass
    inv_inertia = np.ascontiguousarray(1.0 / model.body_inertia_diag)
    force = np.ascontiguousarray(model.body_mass[:, None] * model.gravity[None, :] + model.body_force_world)
    torque = np.ascontiguousarray(model.body_torque_world)

    def advance(dt, n, stride, sample_last, st, bufs):
        t0 = time.perf_counter()
        ns, bad_step, bad_body = advance_free(
            method, ortho_code, dt, n, stride, sample_last, inv_mass, inv_inertia, force, torque,
            st.position, st.linear_momentum, st.quat_wxyz, st.rotation, st.angular_momentum_world,
            *bufs[:5], anchors=st.anchors)
        bufs[5][...] = 0.0  # nothing can touch
        if profile is not None:
            profile.add("free kernel (integrate + sample)", time.perf_counter() - t0)
        return ns, bad_step, bad_body, None

    return advance
