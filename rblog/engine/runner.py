"""The run loop: choose the stages a scene needs, advance in compiled blocks, hand each block of
samples to the recorders, and keep the summary figures.

Python runs once per block (see :func:`samples_per_block`),
never per step. A diverging, interrupted or failing run closes every recorder with what was
written so far, so logs stay readable up to the last good sample.

Why this module is long: the run loop and everything that must hold while it runs live together,
because they share its state: the wall-time sizing of compiled calls (sampling stays on global
multiples of the stride whatever the split), the signal flag checked between calls (SIGINT and
SIGTERM answered within a call's budget, logs closed "interrupted"), and the running summary
figures. The threads that log beside the stepping are rblog.engine.pipeline's.
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

    samples_in_block = samples_per_block(n_bodies, stride)
    steps_per_block = samples_in_block * stride  # the most steps one compiled call may take

    def new_buffers(s):
        """Sample buffers for ``s`` samples. Fresh ones each call: the block is handed to the
        recorders as is (no copy), and a recorder may keep it."""
        s = s + 1
        return (np.empty((s, n_bodies, 3)), np.empty((s, n_bodies, 3)), np.empty((s, n_bodies, 4)),
                np.empty((s, n_bodies, 3, 3)), np.empty((s, n_bodies, 3)),
                np.empty((s, n_bodies, 6)))  # the contact impulses of each interval

    stop = _StopFlag()
    drift = _Drift(model, _measure_world(scene, method, ortho_code) if plan.contacts else None)
    opened: list[Recorder] = []
    writer: BlockPipeline | None = None
    done = 0
    n_samples = 0
    status, message = "ok", ""
    t_start = time.perf_counter()
    try:
        with stop:
            # a first call of zero steps and the first derived channels before the clock starts
            # (nothing compiles: the core was built at install). A signal here interrupts at
            # once (Python code).
            stop.raise_now = True
            advance(dt, 0, stride, False, st.copy(), new_buffers(samples_in_block))
            derive(model, info, np.array([0]), np.array([0.0]), st.position[None],
                   st.linear_momentum[None], st.quat_wxyz[None], st.rotation[None],
                   st.angular_momentum_world[None])
            for r in recorders:
                r.open(model, info)
                opened.append(r)
            stop.raise_now = False
            stop.check()
            t_start = time.perf_counter()  # the run's wall time: stepping and writing
            writer = BlockPipeline(model, info, drift, opened)
            writer.submit(np.array([0]), st.position[None].copy(), st.linear_momentum[None].copy(),
                          st.quat_wxyz[None].copy(), st.rotation[None].copy(),
                          st.angular_momentum_world[None].copy(), None,
                          np.zeros((1, n_bodies, 6)))  # the initial state: no interval
            n_samples += 1
            # Each compiled call is sized so that it takes about CALL_WALL_BUDGET_S of wall
            # time (measured on the previous call), which bounds how late a signal is seen and
            # how much a killed run loses. Samples stay at global multiples of the stride (and
            # the last step), whatever the call boundaries, and the kernels carry their whole
            # state across calls, so the result does not depend on the split.
            sec_per_step = None
            last_n = 1
            while done < n_total:
                stop.check()
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
                bufs = new_buffers(len(local))
                t_call = time.perf_counter()
                _, bad_step, bad_body, contacts = advance(dt, n, call_stride, sample_last, st, bufs)
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
                    t_log = time.perf_counter()
                    writer.submit(done + local, *(b[:keep] for b in bufs[:5]), contacts,
                                  impulses=bufs[5][:keep])
                    if profile is not None:
                        profile.add("logging", time.perf_counter() - t_log)
                    n_samples += keep
                if bad_step >= 0:
                    bad_global = done + bad_step
                    done = bad_global - 1
                    raise SimulationDiverged(bad_global, bad_global * dt, int(bad_body),
                                             model.body_name[bad_body],
                                             _divergence_reason(model, st, int(bad_body), dt))
                done += n
                if progress is not None:
                    progress(done, n_total)
            t_log = time.perf_counter()
            writer.finish(close=True)  # the lanes close their logs, side by side
            if profile is not None:
                profile.add("logging", time.perf_counter() - t_log)
    except (KeyboardInterrupt, _Stopped) as e:
        signum = e.signum if isinstance(e, _Stopped) else signal.SIGINT
        name = signal.Signals(signum).name
        status, message = "interrupted", f"interrupted ({name}) at step {done}"
        _finish_quietly(writer)
        _close_all_quietly(opened, True, message)
        raise RunInterrupted(
            f"run interrupted at step {done} (t = {done * dt:.6g} s) by {name}; logs keep every "
            "sample written before it", signum=signum) from None
    except SimulationDiverged as e:
        _finish_quietly(writer)
        _close_all(opened, True, str(e))
        raise
    except SystemError as e:
        # a signal handler's exception surfacing out of a compiled call
        if isinstance(e.__cause__ or e.__context__, KeyboardInterrupt):
            _finish_quietly(writer)
            _close_all_quietly(opened, True, f"interrupted (SIGINT) at step {done}")
            raise RunInterrupted(f"run interrupted at step {done} (t = {done * dt:.6g} s) by "
                                 "SIGINT; logs keep every sample written before it") from None
        _finish_quietly(writer)
        _close_all(opened, True, f"run failed: {e}")
        raise
    except BaseException as e:
        _finish_quietly(writer)
        _close_all(opened, True, f"run failed: {e}")
        raise
    _close_all([r for r in opened if not writer.has_closed(r)], False, None)
    wall = time.perf_counter() - t_start
    if profile is not None:
        profile.wall = wall
    return RunSummary(
        status=status, steps=done, bodies=n_bodies, samples=n_samples, sim_time_s=done * dt,
        wall_time_s=wall, steps_per_s=done / wall if wall > 0 else float("inf"),
        body_steps_per_s=done * n_bodies / wall if wall > 0 else float("inf"),
        energy_drift_rel=drift.energy, angular_momentum_drift_rel=drift.spin,
        ortho_error_max=drift.ortho, quat_norm_error_max=drift.qnorm, integrator=integrator,
        orthonormalize=ortho, dt=dt, log_every=stride, stages=[s for s, _ in plan.stages],
        message=message, not_applicable=drift_not_applicable(model, plan.contacts),
        contact_penetration_max_m=drift.penetration if plan.contacts else None,
    )


def simulate(scene: Scene, **kwargs) -> tuple[Trajectory, RunSummary]:
    """Run ``scene`` keeping every logged sample in memory; returns (trajectory, summary)."""
    col = TrajectoryCollector()
    recorders = [col, *kwargs.pop("recorders", ())]
    summary = run(scene, recorders=recorders, **kwargs)
    return col.trajectory, summary


def _finish_quietly(writer: BlockPipeline | None):
    """On the way out of a failed run: write what was queued (good samples), swallow errors."""
    if writer is not None:
        writer.finish_quietly()


def _close_all_quietly(recorders, truncated, reason):
    """Close every log on the way out of an interrupted run; a close error is not the news."""
    try:
        _close_all(recorders, truncated, reason)
    except Exception:
        pass


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
