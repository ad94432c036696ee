"""``rblog sweep``: run a grid or a random sample of variants of one scene, each as an independent
task on a :class:`~rblog.study.cluster.Executor`, and gather one results table.

A variant is the scene with some keys set (:mod:`rblog.study.variants`):

* ``sim.dt=1e-3,3e-3,1e-2``: a list of values (the grid takes every one; a random sample picks
  one per variant, uniformly). ``dt``, ``duration``, ``integrator``, ``orthonormalize`` are
  short for ``sim.<key>``.
* ``body[0].restitution=0.2:0.8``: a range, sampled uniformly (needs ``samples``).
* ``body[*].angular_velocity_body[2]=-5:5``: ``[*]`` sets every ``[[body]]``; with a range, each
  body draws its own value (random initial conditions); ``[k]`` after a vector key sets one
  component (a missing vector starts at zero).

Without ``samples`` the variants are the Cartesian product of the lists, the first ``--set``
varying slowest. With ``samples = N`` and ``seed = S`` they are N draws of
``numpy.random.default_rng(S)``, made here, before any task runs, so the variants (and the table)
do not depend on the executor.

Each task gets the variant's scene **text** (kilobytes) and returns a row (a dict of numbers):
the parameters, the run's wall time, the errors against the exact answer where one exists, the
drift of the invariants and the verdict of ``rblog check``'s analyzers on the run. Logs, when
written, go to ``out_dir/logs/`` by path (on a real cluster: storage every worker sees).

Exact answer. A scene of one body with no ground, no static boxes and no applied force or torque
moves exactly as a torque-free body in uniform gravity: the orientation of
:class:`rblog.study.reference.TorqueFree` (elliptic functions) and x0 + v0 t + g t^2 / 2. Errors
(:func:`rblog.study.reference._eval_free`): ``angle_rad`` (largest rotation between the logged and
exact orientation), ``omega_rel``, ``position_m``, ``velocity_rel``. Other scenes have no
reference; their rows carry the invariants' drift only.
"""

from __future__ import annotations

import csv
import json
import math
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from rblog.errors import RblogError, SceneError, SimulationDiverged

SCHEMA = "rblog-sweep/1"
#: columns of the results table after the parameter columns
RESULT_COLUMNS = (
    "status", "message", "integrator", "dt", "steps", "bodies", "samples", "wall_s",
    "body_steps_per_s", "angle_rad", "omega_rel", "position_m", "velocity_rel",
    "energy_drift_rel", "angular_momentum_drift_rel", "ortho_error_max", "check", "check_flagged",
    "log",
)
#: columns that measure time: they differ from run to run; every other column is a function of
#: the variant alone (the same whatever executor ran it)
TIMING_COLUMNS = ("wall_s", "body_steps_per_s")
#: the error plotted against cost when the scene has an exact answer (else energy_drift_rel)
PLOT_ERROR = "angle_rad"


# ---- one variant (runs on a worker) ------------------------------------------------------------

@dataclass
class VariantTask:
    """What travels to a worker: the variant's scene text and where to write its log."""

    index: int
    params: dict
    toml: str
    scene_name: str
    log_path: str | None = None
    check: bool = True


def run_variant(task: VariantTask) -> dict:
    """Run one variant, score it, check it; returns its row (never raises for a bad variant)."""
    from rblog.analyze import check
    from rblog.engine.runner import TrajectoryCollector, run
    from rblog.engine.scene import parse_scene

    row = {k: None for k in RESULT_COLUMNS}
    row.update(task.params)
    row.update(index=task.index, status="ok", message="", log=task.log_path)
    try:
        scene = parse_scene(task.toml, f"{task.scene_name} (variant {task.index})")
    except RblogError as e:
        row.update(status="error", message=str(e))
        return row
    row.update(integrator=scene.sim.integrator, dt=scene.sim.dt, bodies=scene.model.n_bodies)
    col = TrajectoryCollector()
    recorder = col
    if task.log_path:
        from rblog.record.mcap_writer import McapRecorder

        recorder = _Tee(col, McapRecorder(task.log_path))
    try:
        summary = run(scene, recorders=[recorder])
    except SimulationDiverged as e:
        row.update(status="diverged", message=str(e))
        return row
    except RblogError as e:
        row.update(status="error", message=str(e))
        return row
    traj = col.trajectory
    row.update(steps=summary.steps, samples=summary.samples, wall_s=summary.wall_time_s,
               body_steps_per_s=summary.body_steps_per_s,
               energy_drift_rel=summary.energy_drift_rel,
               angular_momentum_drift_rel=summary.angular_momentum_drift_rel,
               ortho_error_max=summary.ortho_error_max)
    problem = reference_problem(scene)
    if problem is not None:
        from rblog.study.reference import Samples

        errs = problem.evaluate(Samples.from_trajectory(traj))
        row.update({k: float(errs[k]) for k in ("angle_rad", "omega_rel", "position_m", "velocity_rel")})
    if task.check:
        results = check(traj)
        bad = [r.analyzer for r in results if not r.passed and not r.skipped]
        row.update(check="flagged" if bad else "clean", check_flagged=",".join(bad))
    return row


class _Tee:
    """Two recorders as one: the run hands each block to its one writer thread, which keeps it
    (the collector: list appends) and writes it (MCAP). Given two recorders, the run would start a
    thread per recorder and pass every block through two more queues; for a variant of ~2,000
    samples those hand-offs cost more than the overlap gains, most of all on a worker that shares
    its core with another."""

    def __init__(self, *recorders):
        self.recorders = recorders

    def open(self, model, info):
        for r in self.recorders:
            r.open(model, info)

    def write(self, block):
        for r in self.recorders:
            r.write(block)

    def close(self, truncated=False, reason=None):
        from rblog.engine.runner import _close_all

        _close_all(self.recorders, truncated, reason)  # every log closed even if one fails


def reference_problem(scene):
    """A :class:`rblog.study.reference.Problem` with the exact motion of ``scene``, or None when
    the scene has none (more than one body, a ground, static boxes, applied loads)."""
    from rblog.study.reference import BodySpec, Problem

    m = scene.model
    if (m.n_bodies != 1 or m.ground or len(m.static_box_position) or np.any(m.body_force_world)
            or np.any(m.body_torque_world)):
        return None
    st = scene.state
    mass = float(m.body_mass[0])
    inertia = np.asarray(m.body_inertia_diag[0], float)
    omega_body = (st.rotation[0].T @ st.angular_momentum_world[0]) / inertia
    body = BodySpec(m.body_name[0], "sphere", (1.0,), mass, inertia=tuple(inertia),
                    position=tuple(st.position[0]), quat_wxyz=tuple(st.quat_wxyz[0]),
                    velocity=tuple(st.linear_momentum[0] / mass), omega_body=tuple(omega_body))
    p = Problem(name="sweep", title=scene.path, bodies=[body], gravity=tuple(m.gravity),
                duration=scene.sim.duration)
    # the exact rotation integrates its orientation once per initial condition (per worker)
    p.__dict__["torque_free"] = [_torque_free(tuple(inertia), tuple(omega_body), tuple(st.quat_wxyz[0]))]
    return p


_TF_CACHE: dict = {}


def _torque_free(inertia, omega, quat):
    from rblog.study.reference import TorqueFree

    key = (inertia, omega, quat)
    if key not in _TF_CACHE:
        if len(_TF_CACHE) > 64:
            _TF_CACHE.clear()
        _TF_CACHE[key] = TorqueFree(np.array(inertia), np.array(omega), np.array(quat))
    return _TF_CACHE[key]


# ---- the sweep ---------------------------------------------------------------------------------

@dataclass
class SweepReport:
    scene: str
    params: list[str]
    rows: list[dict]
    settings: dict
    executor: str = ""
    wall_s: float = 0.0
    created: str = ""
    command: str = ""
    files: dict = field(default_factory=dict)

    @property
    def columns(self) -> list[str]:
        keys: list[str] = []
        for r in self.rows:
            for k in r:
                if k not in keys and k not in RESULT_COLUMNS and k != "index":
                    keys.append(k)
        return ["index", *keys, *RESULT_COLUMNS]

    def to_dict(self) -> dict:
        cols = self.columns
        rows = [{k: _finite(r.get(k)) for k in cols} for r in self.rows]
        return {"schema": SCHEMA, "kind": "sweep", "scene": self.scene, "created": self.created,
                "command": self.command, "params": self.params, "settings": self.settings,
                "executor": self.executor, "wall_s": self.wall_s, "runs": rows,
                "files": self.files}


def _finite(v):
    return None if isinstance(v, float) and not math.isfinite(v) else v


def run_sweep(scene_path: str, sets: Sequence[str], *, samples: int | None = None, seed: int = 0,
              executor=None, out_dir: str | Path | None = None, write_logs: bool = True,
              check: bool = True, on_done: Callable[[int, int], None] | None = None,
              command: str = "") -> SweepReport:
    """Build the variants of ``scene_path`` from the ``--set`` specs and run them on ``executor``
    (default: serially here). Logs go to ``out_dir/logs/variant-NNNN.mcap`` when ``write_logs``.
    Raises SceneError for a scene or a variant that does not validate (before anything runs)."""
    from rblog.engine.scene import load_scene, parse_scene
    from rblog.study.cluster import Executor, TaskFailure
    from rblog.study.variants import apply_params, make_variants, parse_set, to_toml

    base = load_scene(scene_path)
    doc = tomllib.loads(base.toml_text)
    params = [parse_set(s) for s in sets]
    n_bodies = len(doc.get("body", []))
    if any("[*]" in p.key for p in params) and n_bodies == 0:
        raise SceneError(scene_path, "body[*]", "the scene has no [[body]] tables to set")
    assigns = make_variants(params, n_bodies, samples, seed)
    name = Path(scene_path).stem
    log_dir = None
    if write_logs:
        if out_dir is None:
            raise RblogError("writing logs needs an output directory")
        log_dir = Path(out_dir) / "logs"
        try:
            log_dir.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise RblogError(f"{log_dir}: cannot create: {e.strerror or e}") from None
    tasks = []
    for i, a in enumerate(assigns):
        where = f"{scene_path} (variant {i}: {_show(a)})"
        text = to_toml(apply_params(doc, a, where))
        parse_scene(text, where)  # a bad value fails here, naming the variant, before any run
        log = str((log_dir / f"{name}-{i:04d}.mcap").resolve()) if log_dir else None
        tasks.append(VariantTask(i, a, text, name, log, check))
    ex = executor or Executor()
    t0 = time.perf_counter()
    own = not ex.serial and ex.client is None
    if own:
        ex.start()
    try:
        out = ex.map(run_variant, tasks, on_done=on_done, chunked=True)
    finally:
        if own:
            ex.close()
    rows = []
    for t, r in zip(tasks, out):
        if isinstance(r, TaskFailure):
            fail = r
            r = {k: None for k in RESULT_COLUMNS}
            r.update(t.params)
            r.update(index=t.index, status="failed",
                     message=f"variant {t.index} not run: {fail.error} (after {fail.tries} tries)")
        rows.append(r)
    return SweepReport(scene=scene_path, params=[p.key for p in params], rows=rows,
                       settings={"samples": samples, "seed": seed, "sets": list(sets),
                                 "logs": write_logs, "check": check},
                       executor=ex.describe(), wall_s=time.perf_counter() - t0,
                       created=time.strftime("%Y-%m-%dT%H:%M:%S%z"), command=command)


def _show(a: dict) -> str:
    return ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in a.items())


def comparable_rows(report: SweepReport) -> list[dict]:
    """The rows without the timing columns and the log paths (which follow the output
    directory): what must not depend on the executor."""
    return [{k: v for k, v in r.items() if k not in TIMING_COLUMNS and k != "log"}
            for r in report.rows]


def write_outputs(report: SweepReport, out_dir: str | Path, stem: str = "sweep") -> dict:
    """sweep.json, sweep.csv, sweep.parquet and sweep.png (error against cost; needs matplotlib)
    in ``out_dir``; returns {kind: path}."""
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        files = {"json": str(out / f"{stem}.json"), "csv": str(out / f"{stem}.csv"),
                 "parquet": str(out / f"{stem}.parquet")}
        cols = report.columns
        rows = [{k: _finite(r.get(k)) for k in cols} for r in report.rows]
        with open(files["csv"], "w", newline="", encoding="utf-8") as f:
            w = csv.DictWriter(f, fieldnames=cols)
            w.writeheader()
            for r in rows:
                w.writerow({k: ("" if v is None else v) for k, v in r.items()})
        import pyarrow as pa
        import pyarrow.parquet as pq

        pq.write_table(pa.Table.from_pylist(rows), files["parquet"])
        try:
            files["png"] = write_plot(report, out / f"{stem}.png")
        except ImportError:
            pass
        report.files = files
        Path(files["json"]).write_text(json.dumps(report.to_dict(), indent=1), encoding="utf-8")
    except OSError as e:
        raise RblogError(f"{out}: cannot write sweep outputs: {e.strerror or e}") from None
    return files


def write_plot(report: SweepReport, path) -> str:
    """Error against cost (run wall time), one point per variant, one colour per integrator."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in report.rows if r["status"] == "ok" and r["wall_s"]]
    key = PLOT_ERROR if any(r.get(PLOT_ERROR) is not None for r in ok) else "energy_drift_rel"
    label = {"angle_rad": "orientation error against the exact motion (rad)",
             "energy_drift_rel": "relative energy drift (no exact answer for this scene)"}[key]
    fig, ax = plt.subplots(figsize=(7, 5))
    integs = sorted({r["integrator"] for r in ok})
    for k, integ in enumerate(integs):
        pts = [r for r in ok if r["integrator"] == integ and r.get(key) is not None]
        ax.scatter([r["wall_s"] for r in pts], [max(r[key], 1e-17) for r in pts],
                   s=14, color=plt.cm.tab10(k % 10), label=integ)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("run wall time (s)")
    ax.set_ylabel(label)
    ax.set_title(f"rblog sweep {Path(report.scene).name}: {len(report.rows)} variants", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    if integs:
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path)


def format_table(report: SweepReport, limit: int = 30) -> str:
    """A terminal summary: counts by status and check verdict, then the first ``limit`` rows."""
    rows = report.rows
    by = {}
    for r in rows:
        by[r["status"]] = by.get(r["status"], 0) + 1
    checks = {}
    for r in rows:
        if r.get("check"):
            checks[r["check"]] = checks.get(r["check"], 0) + 1
    lines = [f"{report.scene}: {len(rows)} variants ({', '.join(f'{v} {k}' for k, v in by.items())}"
             + (f"; check: {', '.join(f'{v} {k}' for k, v in checks.items())}" if checks else "")
             + f")  [{report.executor}, {report.wall_s:.2f} s]"]
    shown = [p for p in report.params]
    head = f"  {'#':>4} " + "".join(f"{p[-18:]:>19}" for p in shown[:4]) + \
        f"{'status':>10}{'wall s':>10}{'angle rad':>11}{'E drift':>10}{'check':>9}"
    lines.append(head)
    for r in rows[:limit]:
        vals = []
        for p in shown[:4]:
            v = r.get(p, r.get(p.replace("[*]", "[0]")))
            vals.append(f"{v:>19.4g}" if isinstance(v, float) else f"{str(v):>19}")
        f = lambda v, s: ("-" if v is None else format(v, s))
        lines.append(f"  {r['index']:>4} " + "".join(vals) + f"{r['status']:>10}"
                     f"{f(r['wall_s'], '.3g'):>10}{f(r['angle_rad'], '.2e'):>11}"
                     f"{f(r['energy_drift_rel'], '.2e'):>10}{str(r['check'] or '-'):>9}")
    if len(rows) > limit:
        lines.append(f"  ... {len(rows) - limit} more (see the table files)")
    return "\n".join(lines)
