"""Work-precision study: every integrator x a range of time steps on the reference problems of
:mod:`rblog.study.reference`, with the peers (:mod:`rblog.study.peers`) side by side when installed.

For each run: wall time per simulated second, the error against the exact answer, and the drift
of the invariants. Outputs: a terminal table (:func:`format_table`), JSON
(:meth:`BenchReport.to_dict`), CSV (:func:`write_csv`, columns :data:`CSV_COLUMNS`) and a
work-precision plot (:func:`write_plot`, PNG).

How time is measured. Accuracy runs log samples (100 per simulated second, or every step where the
answer needs it) and are not timed. Timing runs repeat the same scene with no recorder and one
sample at the end, best of :data:`TIMING_REPEATS`, and report ``wall_time_s`` of
:func:`rblog.engine.runner.run` (kernels already loaded). A run of a few hundred steps is dominated by
the run loop's fixed cost (~0.2 ms), so free-body problems, whose motion goes on unchanged, are
timed over a longer run of at least :data:`TIMING_MIN_STEPS` steps; contact problems are timed over
their own duration. Peers are timed the same way (MuJoCo: one ``mj_step(nstep=N)`` call; pybullet
has no multi-step call, so its figure includes one Python call per step).

Orders of convergence are least-squares slopes of log(error) against log(dt) over the runs whose
error lies in [:data:`ORDER_FIT_MIN`, :data:`ORDER_FIT_MAX`] (asymptotic regime, above the
reference's own ~1e-12 accuracy).

JSON (``schema`` = :data:`SCHEMA`)::

    {"schema", "kind": "bench", "created", "command", "quick", "machine": {...},
     "settings": {"dts", "integrators", "peers"},
     "problems": [{"name", "title", "primary", "available", "reason", "contacts"}],
     "runs": [{<CSV_COLUMNS>}],
     "orders": {problem: {"engine/integrator": {"omega_rel": p, "angle_rad": p, "<primary>": p}}},
     "peer_ratios": [{"problem", "dt", "peer", "vs", "speed_ratio", "error_ratio", ...}],
     "cost_at_error": {problem: {"engine/integrator": {"1e-06": wall s per simulated s}}},
     "files": {"json", "csv", "png"}, "notes": [...]}

Why this module is long: it is the whole `rblog bench` study: the grid of problems, integrators and dt,
the peers, the fits of convergence order, and its report (table, CSV, JSON, PNG).
"""

from __future__ import annotations

import csv
import itertools
import json
import math
import os
import platform
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from rblog import __version__
from rblog.errors import RblogError, SimulationDiverged
from rblog.study.reference import PROBLEMS, Problem, Samples, contact_engine_status, get_problem

SCHEMA = "rblog-bench/1"
#: the integrators measured by default (``name`` or ``name/orthonormalize``)
INTEGRATORS = ("seed", "seed-quat", "splitting", "rk4", "exact", "exact4")
#: time steps (s) of the full study and of --quick
DTS = (2e-2, 1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4)
DTS_QUICK = (2e-2, 1e-2, 5e-3)
#: problems of --quick (all of them: they are small); the full study runs the same set
PROBLEMS_QUICK = tuple(PROBLEMS)
#: timing runs: best of this many (--quick: TIMING_REPEATS_QUICK)
TIMING_REPEATS = 5
TIMING_REPEATS_QUICK = 2
#: free-body timing runs are lengthened to at least this many steps (amortizes the ~0.2 ms
#: fixed cost of a run); at most this factor longer than the problem
TIMING_MIN_STEPS = 20_000
TIMING_MAX_STRETCH = 100
#: errors inside this range are used to fit orders of convergence
ORDER_FIT_MIN = 1e-10
ORDER_FIT_MAX = 1e-1
#: the rblog integrator peers are compared against (the default)
RATIO_BASELINE = "rk4"
#: problems with smooth exact solutions, where orders of convergence mean something
SMOOTH_PROBLEMS = ("torque-free-intermediate", "torque-free-generic", "torqued-body", "free-fall")
#: errors at which the cost of every engine/integrator is interpolated (cost_at_error)
COST_TARGETS = (1e-2, 1e-4, 1e-6, 1e-8)
#: time steps whose peer ratios the terminal table shows (all are in the JSON)
TABLE_RATIO_DTS = (1e-2, 1e-3)

CSV_COLUMNS = (
    "engine", "problem", "integrator", "dt", "status", "message", "steps", "wall_s",
    "wall_per_sim_s", "ns_per_step", "error", "error_key", "omega_rel", "angle_rad",
    "position_m", "velocity_rel", "apex_m", "energy_drift_rel", "energy_growth_rel",
    "angular_momentum_drift_rel", "momentum_drift_rel", "ortho_error_max", "pareto",
)


def parse_integrator(spec: str) -> tuple[str, str | None]:
    """``"seed/none"`` -> ("seed", "none"); ``"rk4"`` -> ("rk4", None)."""
    name, _, ortho = spec.partition("/")
    return name, (ortho or None)


def machine_info() -> dict:
    """What ran the study: CPU, cores, Python and library versions."""
    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    info = {"cpu": cpu, "cores": os.cpu_count(), "platform": platform.platform(),
            "python": platform.python_version(), "numpy": np.__version__,
            "rblog": __version__}
    try:
        import scipy

        info["scipy"] = scipy.__version__
    except ImportError:
        pass
    return info


#: what installs the study's optional modules (scipy, matplotlib) into a checkout's venv
BENCH_EXTRA = 'pip install -e ".[bench]"'
#: the optional module that draws bench.png and stress.png
PLOT_MODULE = "matplotlib"


def module_missing(name: str) -> bool:
    """True when the optional module ``name`` cannot be imported (found without importing it)."""
    import importlib.util

    try:
        return importlib.util.find_spec(name) is None
    except (ImportError, ValueError):  # a module set to None in sys.modules, a broken package
        return True


def missing_dependencies(problems: list[str] | tuple | None = None, *, plot: bool = True,
                         what: str = "bench.png") -> str:
    """One line naming the optional modules the study lacks, what each costs (problems left out,
    the plot not drawn) and the command that installs them; "" when nothing is missing. Meant
    to be printed before any run (``rblog bench`` and ``rblog stress`` do)."""
    names = list(problems) if problems else list(PROBLEMS_QUICK)
    by_module: dict[str, list[str]] = {}
    for n in names:
        if n in PROBLEMS:
            for mod in get_problem(n).needs:
                if module_missing(mod):
                    by_module.setdefault(mod, []).append(n)
    parts = [f"{mod} is not installed: {len(skip)} of {len(names)} problems skipped "
             f"({', '.join(skip)})" for mod, skip in by_module.items()]
    if plot and module_missing(PLOT_MODULE):
        parts.append(f"{PLOT_MODULE} is not installed: no {what}")
    if not parts:
        return ""
    return "; ".join(parts) + f". To run everything: {BENCH_EXTRA}"


def new_row(engine: str, problem: str, integrator: str, dt: float) -> dict:
    row = {k: None for k in CSV_COLUMNS}
    row.update(engine=engine, problem=problem, integrator=integrator, dt=dt, status="ok",
               message="", pareto=False)
    return row


def _score(row: dict, problem: Problem, samples: Samples):
    errs = problem.evaluate(samples)
    for k, v in errs.items():
        if k in row and isinstance(v, (int, float)):
            row[k] = float(v)
    row["error_key"] = problem.primary
    row["error"] = float(errs[problem.primary])
    row.update(problem.invariants(samples))


def run_rblog(problem: Problem, spec: str, dt: float, *, timing: bool = True,
              repeats: int = TIMING_REPEATS) -> dict:
    """One accuracy run (and its timing) of rblog on ``problem``; never raises for a run that
    fails: the row's status says ``diverged``, ``unavailable`` or ``error``."""
    from rblog.engine.scene import parse_scene
    from rblog.engine.runner import run, simulate

    integ, ortho = parse_integrator(spec)
    row = new_row("rblog", problem.name, spec, dt)
    try:
        scene = parse_scene(problem.scene_toml(dt), f"<{problem.name}>")
        traj, summary = simulate(scene, integrator=integ, orthonormalize=ortho,
                                 log_every=problem.log_every(dt))
        row["steps"] = summary.steps
        _score(row, problem, Samples.from_trajectory(traj))
        if timing:
            n = summary.steps
            stretch = 1
            if problem.extend_for_timing and n < TIMING_MIN_STEPS:
                stretch = min(TIMING_MAX_STRETCH, math.ceil(TIMING_MIN_STEPS / n))
            t_scene = scene if stretch == 1 else parse_scene(
                problem.scene_toml(dt, problem.duration * stretch), f"<{problem.name}>")
            best, steps = math.inf, n
            for _ in range(repeats):
                s = run(t_scene, integrator=integ, orthonormalize=ortho, log_every=10**12)
                best, steps = min(best, s.wall_time_s), s.steps
            _set_timing(row, best, steps, dt)
    except SimulationDiverged as e:
        row.update(status="diverged", message=str(e))
    except (ImportError, NotImplementedError) as e:
        row.update(status="unavailable", message=f"{type(e).__name__}: {e}")
    except RblogError as e:
        row.update(status="error", message=str(e))
    except Exception as e:  # a bug in an engine stage: reported, the study goes on
        row.update(status="error", message=f"{type(e).__name__}: {e}")
    return row


def _set_timing(row: dict, wall: float, steps: int, dt: float):
    row["wall_s"] = wall
    row["wall_per_sim_s"] = wall / (steps * dt)
    row["ns_per_step"] = wall / steps * 1e9


def run_peer(peer, problem: Problem, integrator: str, dt: float, *, timing: bool = True,
             repeats: int = TIMING_REPEATS) -> dict:
    """One run of a peer engine (see rblog.study.peers), scored like rblog's."""
    row = new_row(peer.name, problem.name, integrator, dt)
    why = peer.supports(problem)
    if why:
        row.update(status="unavailable", message=why)
        return row
    try:
        samples, steps = peer.run(problem, integrator, dt)
        row["steps"] = steps
        if not (np.all(np.isfinite(samples.position)) and np.all(np.isfinite(samples.quat_wxyz))):
            row.update(status="diverged", message="non-finite state")
            return row
        _score(row, problem, samples)
        if timing:
            duration = problem.duration
            if problem.extend_for_timing and steps < TIMING_MIN_STEPS:
                duration *= min(TIMING_MAX_STRETCH, math.ceil(TIMING_MIN_STEPS / steps))
            best, n = math.inf, steps
            for _ in range(repeats):
                wall, n = peer.time(problem, integrator, dt, duration)
                best = min(best, wall)
            _set_timing(row, best, n, dt)
    except Exception as e:  # a peer failing is a result, not a crash
        row.update(status="error", message=f"{type(e).__name__}: {e}")
    return row


@dataclass
class BenchReport:
    """Everything one ``rblog bench`` measured (see the module docstring for the JSON)."""

    rows: list[dict]
    problems: list[dict]
    settings: dict
    machine: dict
    quick: bool
    command: str = ""
    created: str = ""
    orders: dict = field(default_factory=dict)
    peer_ratios: list[dict] = field(default_factory=list)
    cost_at_error: dict = field(default_factory=dict)
    files: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"schema": SCHEMA, "kind": "bench", "created": self.created, "command": self.command,
                "quick": self.quick, "machine": self.machine, "settings": self.settings,
                "problems": self.problems, "runs": [_jsonable(r) for r in self.rows],
                "orders": self.orders, "peer_ratios": self.peer_ratios,
                "cost_at_error": self.cost_at_error, "files": self.files,
                "notes": self.notes}


def _jsonable(row: dict) -> dict:
    out = {}
    for k in CSV_COLUMNS:
        v = row.get(k)
        if isinstance(v, float) and not math.isfinite(v):
            v = None
        out[k] = v
    return out


def run_bench(
    *,
    quick: bool = False,
    problems: list[str] | tuple | None = None,
    integrators: list[str] | tuple | None = None,
    dts: list[float] | tuple | None = None,
    peers: list[str] | tuple | None = None,
    progress: Callable[[str], None] | None = None,
    command: str = "",
    executor=None,
) -> BenchReport:
    """Run the study. ``peers``: names of peer engines to include (None: every installed one;
    () for none). Problems that need an engine that cannot run are reported as unavailable.
    ``executor``: a :class:`rblog.study.cluster.Executor` for the rblog runs (default: here)."""
    from rblog.study import peers as peers_mod
    from rblog.study.cluster import map_cases

    names = list(problems) if problems else list(PROBLEMS_QUICK if quick else PROBLEMS)
    for n in names:
        if n not in PROBLEMS:
            raise RblogError(f"unknown problem {n!r} (expected one of: {', '.join(PROBLEMS)})")
    specs = list(integrators) if integrators else list(INTEGRATORS)
    dt_list = sorted(dts if dts else (DTS_QUICK if quick else DTS), reverse=True)
    peer_objs = peers_mod.available_peers(peers)
    say = progress or (lambda msg: None)
    contact_ok, contact_why = contact_engine_status()
    repeats = TIMING_REPEATS_QUICK if quick else TIMING_REPEATS

    rows, plist, notes = [], [], []
    for n in names:
        p = get_problem(n)
        info = {"name": p.name, "title": p.title, "primary": p.primary, "contacts": p.contacts,
                "available": True, "reason": ""}
        if p.contacts and not contact_ok:
            info.update(available=False, reason=contact_why)
        lacking = [m for m in p.needs if module_missing(m)]
        if lacking:  # its exact answer cannot be computed: no run is made, for rblog or peers
            info.update(available=False, reason=f"needs {', '.join(lacking)} (not installed; "
                                                f"{BENCH_EXTRA})")
        plist.append(info)
        runs = [(spec, dt) for spec in specs for dt in dt_list]
        done = map_cases(executor, lambda c: run_rblog(p, c[0], c[1], repeats=repeats),
                         runs if info["available"] else [],
                         say=lambda c: say(f"rblog {p.name} {c[0]} dt={c[1]:g}"),
                         failed=lambda c, why: {**new_row("rblog", p.name, c[0], c[1]),
                                                "status": "error", "message": why})
        for (spec, dt), r in itertools.zip_longest(runs, done):
            if not info["available"]:
                r = new_row("rblog", p.name, spec, dt)
                r.update(status="unavailable", message=info["reason"])
            rows.append(r)
            if r["status"] == "unavailable" and info["available"]:
                info.update(available=False, reason=r["message"])
        for peer in peer_objs:
            for integ in peer.integrators:
                for dt in dt_list:
                    if lacking:  # the peers' runs could not be scored either
                        r = new_row(peer.name, p.name, integ, dt)
                        r.update(status="unavailable", message=info["reason"])
                        rows.append(r)
                        continue
                    say(f"{peer.name} {p.name} {integ} dt={dt:g}")
                    rows.append(run_peer(peer, p, integ, dt, repeats=repeats))
    for name in (peers or ()):
        if name not in [q.name for q in peer_objs]:
            notes.append(f"peer {name}: {peers_mod.unavailable_reason(name)}")
    mark_pareto(rows)
    report = BenchReport(
        rows=rows, problems=plist, quick=quick, machine=machine_info(), command=command,
        created=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        settings={"dts": dt_list, "integrators": specs,
                  "peers": {q.name: q.version for q in peer_objs}},
        notes=notes,
    )
    report.orders = convergence_orders(rows)
    report.peer_ratios = peer_ratios(rows)
    report.cost_at_error = cost_at_error(rows)
    return report


def mark_pareto(rows: list[dict]):
    """Mark, per problem, the runs no other run beats on both wall time and error."""
    by_problem: dict[str, list[dict]] = {}
    for r in rows:
        if _plottable(r):
            by_problem.setdefault(r["problem"], []).append(r)
    for rs in by_problem.values():
        best = math.inf
        for r in sorted(rs, key=lambda r: (r["wall_per_sim_s"], r["error"])):
            if r["error"] < best:
                r["pareto"] = True
                best = r["error"]


def _plottable(r: dict) -> bool:
    return (r["status"] == "ok" and r["error"] is not None and r["wall_per_sim_s"] is not None
            and math.isfinite(r["error"]) and r["wall_per_sim_s"] > 0)


def fit_order(dts, errs) -> float | None:
    """Slope of log(err) against log(dt) over the points inside the fit range (None if < 2)."""
    pts = [(d, e) for d, e in zip(dts, errs)
           if e is not None and math.isfinite(e) and ORDER_FIT_MIN <= e <= ORDER_FIT_MAX]
    if len(pts) < 2 or max(p[0] for p in pts) / min(p[0] for p in pts) < 1.5:
        return None
    x = np.log([p[0] for p in pts])
    y = np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def convergence_orders(rows: list[dict]) -> dict:
    """{problem: {"engine/integrator": {error key: order}}} for the smooth problems (free
    bodies: :data:`SMOOTH_PROBLEMS`); an order is None where fewer than two errors lie in the
    fit range."""
    out: dict = {}
    groups: dict = {}
    for r in rows:
        if r["status"] == "ok" and r["problem"] in SMOOTH_PROBLEMS:
            groups.setdefault((r["problem"], r["engine"], r["integrator"]), []).append(r)
    for (prob, eng, integ), rs in groups.items():
        rs = sorted(rs, key=lambda r: r["dt"])
        d = {}
        for key in ("omega_rel", "angle_rad", "position_m", rs[0]["error_key"]):
            if key in d or rs[0].get(key) is None or all(r[key] == 0 for r in rs):
                continue
            d[key] = fit_order([r["dt"] for r in rs], [r[key] for r in rs])
        out.setdefault(prob, {})[f"{eng}/{integ}"] = d
    return out


def peer_ratios(rows: list[dict], baseline: str = RATIO_BASELINE) -> list[dict]:
    """Peer runs against rblog's ``baseline`` integrator on the same problem and dt:
    speed_ratio = peer wall / rblog wall (> 1: the peer is slower), error_ratio likewise."""
    base = {(r["problem"], r["dt"]): r for r in rows
            if r["engine"] == "rblog" and r["integrator"] == baseline and _plottable(r)}
    out = []
    for r in rows:
        if r["engine"] == "rblog" or not _plottable(r):
            continue
        b = base.get((r["problem"], r["dt"]))
        if b is None:
            continue
        out.append({
            "problem": r["problem"], "dt": r["dt"], "peer": f"{r['engine']}/{r['integrator']}",
            "vs": f"rblog/{baseline}",
            "speed_ratio": r["wall_per_sim_s"] / b["wall_per_sim_s"],
            "error_ratio": (r["error"] / b["error"]) if b["error"] > 0 else None,
            "peer_energy_drift_rel": r["energy_drift_rel"],
            "rblog_energy_drift_rel": b["energy_drift_rel"],
        })
    return out


def cost_at_error(rows: list[dict], targets=COST_TARGETS) -> dict:
    """{problem: {"engine/integrator": {str(target): wall s per simulated s or None}}}: the wall
    time each engine/integrator needs to reach a given error, interpolated log-log between its
    runs (None where its runs never bracket the target; a run already below the target at its
    cheapest dt counts at that cost, an upper bound)."""
    out: dict = {}
    groups: dict = {}
    for r in rows:
        if _plottable(r) and r["error"] > 0:
            groups.setdefault((r["problem"], f"{r['engine']}/{r['integrator']}"), []).append(r)
    for (prob, name), rs in groups.items():
        rs = sorted(rs, key=lambda r: r["wall_per_sim_s"])
        d = {}
        for target in targets:
            cost = None
            if rs[0]["error"] <= target:
                cost = rs[0]["wall_per_sim_s"]
            else:
                for a, b in zip(rs, rs[1:]):
                    if a["error"] > target >= b["error"]:
                        f = math.log(a["error"] / target) / math.log(a["error"] / b["error"])
                        cost = math.exp(math.log(a["wall_per_sim_s"])
                                        + f * math.log(b["wall_per_sim_s"] / a["wall_per_sim_s"]))
                        break
            d[f"{target:g}"] = cost
        out.setdefault(prob, {})[name] = d
    return out


# ---- output ------------------------------------------------------------------------------------

def _fmt(v, spec=".2e") -> str:
    if v is None:
        return "-"
    if isinstance(v, float) and not math.isfinite(v):
        return "inf" if v > 0 else "nan"
    return format(v, spec)


def format_table(report: BenchReport) -> str:
    """The terminal table: one section per problem, then orders and peer ratios."""
    lines = []
    m = report.machine
    lines.append(f"rblog bench{' --quick' if report.quick else ''}: {m.get('cpu', '?')}, "
                 f"{m.get('cores', '?')} cores, python {m.get('python')}")
    head = (f"{'engine/integrator':<22}{'dt':>8}{'ms/sim-s':>10}{'us/step':>9}{'error':>10}{'w err':>10}"
            f"{'angle':>10}{'pos err':>10}{'E drift':>10}{'|L| drift':>10}{'ortho':>10}  ")
    for info in report.problems:
        lines.append("")
        lines.append(f"{info['name']}: {info['title']}  [error = {info['primary']}]")
        if not info["available"]:
            lines.append(f"  unavailable: {info['reason']}")
        rs = [r for r in report.rows if r["problem"] == info["name"]]
        if not info["available"] and all(r["engine"] == "rblog" or r["status"] == "unavailable"
                                         for r in rs):
            continue
        lines.append(head)
        for r in rs:
            if r["engine"] == "rblog" and not info["available"]:
                continue
            name = f"{r['engine']}/{r['integrator']}"
            if r["status"] != "ok":
                lines.append(f"{name:<22}{r['dt']:>8g}  {r['status']}: {r['message'][:90]}")
                continue
            wall = r["wall_per_sim_s"] * 1e3 if r["wall_per_sim_s"] is not None else None
            us = r["ns_per_step"] * 1e-3 if r["ns_per_step"] is not None else None
            lines.append(
                f"{name:<22}{r['dt']:>8g}{_fmt(wall, '.3g'):>10}{_fmt(us, '.3g'):>9}{_fmt(r['error']):>10}"
                f"{_fmt(r['omega_rel']):>10}{_fmt(r['angle_rad']):>10}{_fmt(r['position_m']):>10}"
                f"{_fmt(r['energy_drift_rel']):>10}{_fmt(r['angular_momentum_drift_rel']):>10}"
                f"{_fmt(r['ortho_error_max']):>10}  {'*' if r['pareto'] else ''}")
    lines.append("")
    lines.append("* = on the Pareto front (no run of that problem is both faster and more accurate)")
    if report.orders:
        lines.append("")
        lines.append("measured orders of convergence (slope of log error vs log dt)")
        for prob, d in report.orders.items():
            for name, ords in d.items():
                parts = [f"{k} {_fmt(v, '.2f')}" for k, v in ords.items() if v is not None]
                lines.append(f"  {prob:<26}{name:<24}" + ("  ".join(parts) or "-"))
    if report.cost_at_error:
        lines.append("")
        lines.append("cost at equal accuracy: ms of wall time per simulated second to reach an "
                     "error of (interpolated; - = not reached)")
        targets = list(next(iter(next(iter(report.cost_at_error.values())).values())))
        lines.append(f"  {'problem':<26}{'engine/integrator':<24}"
                     + "".join(f"{t:>10}" for t in targets))
        for prob, d in report.cost_at_error.items():
            for name, c in sorted(d.items()):
                lines.append(f"  {prob:<26}{name:<24}" + "".join(
                    f"{_fmt(None if c[t] is None else c[t] * 1e3, '.3g'):>10}" for t in targets))
    if report.peer_ratios:
        lines.append("")
        lines.append(f"peers against rblog/{RATIO_BASELINE} at the same dt "
                     "(speed: peer wall / rblog wall; error: peer error / rblog error)")
        shown = [pr for pr in report.peer_ratios if pr["dt"] in TABLE_RATIO_DTS]
        if len(shown) < len(report.peer_ratios):
            lines.append(f"  (dt = {', '.join(f'{d:g}' for d in TABLE_RATIO_DTS)} s; every dt is "
                         "in the JSON)")
        for pr in (shown or report.peer_ratios):
            lines.append(f"  {pr['problem']:<26}{pr['peer']:<24}dt {pr['dt']:<8g}"
                         f"speed x{_fmt(pr['speed_ratio'], '.3g'):<10}"
                         f"error x{_fmt(pr['error_ratio'], '.3g'):<10}"
                         f"peer E drift {_fmt(pr['peer_energy_drift_rel'])}")
    for n in report.notes:
        lines.append(f"note: {n}")
    return "\n".join(lines)


def write_csv(report: BenchReport, path: str | Path):
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=list(CSV_COLUMNS))
        w.writeheader()
        for r in report.rows:
            w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in CSV_COLUMNS})


def write_plot(report: BenchReport, path: str | Path):
    """Work-precision plot: error against wall time per simulated second, log-log, one panel per
    problem, one line per engine/integrator (dt along the line), the Pareto front marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    probs = report.problems
    ncol = 3 if len(probs) > 4 else min(2, len(probs))
    nrow = math.ceil(len(probs) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(5.2 * ncol, 4.2 * nrow), squeeze=False)
    names = sorted({f"{r['engine']}/{r['integrator']}" for r in report.rows})
    colors = {n: plt.cm.tab10(i % 10) for i, n in enumerate(names)}
    for ax, info in zip(axes.flat, probs):
        rs = [r for r in report.rows if r["problem"] == info["name"] and _plottable(r)]
        ax.set_title(info["name"], fontsize=10)
        if not rs:
            why = info["reason"] or "no successful run"
            ax.text(0.5, 0.5, "unavailable:\n" + _wrap(why, 40), ha="center", va="center",
                    transform=ax.transAxes, fontsize=8)
            ax.set_xticks([])
            ax.set_yticks([])
            continue
        for n in names:
            pts = sorted([r for r in rs if f"{r['engine']}/{r['integrator']}" == n],
                         key=lambda r: r["dt"])
            if not pts:
                continue
            ls = "-" if n.startswith("rblog/") else "--"
            ax.plot([r["wall_per_sim_s"] for r in pts], [max(r["error"], 1e-16) for r in pts],
                    ls, marker="o", ms=3.5, color=colors[n], label=n, lw=1.2)
        front = sorted([r for r in rs if r["pareto"]], key=lambda r: r["wall_per_sim_s"])
        if front:
            ax.step([r["wall_per_sim_s"] for r in front], [max(r["error"], 1e-16) for r in front],
                    where="post", color="k", lw=0.8, alpha=0.6)
            ax.scatter([r["wall_per_sim_s"] for r in front], [max(r["error"], 1e-16) for r in front],
                       s=70, facecolors="none", edgecolors="k", lw=1.0, label="Pareto front", zorder=5)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("wall time per simulated second (s)", fontsize=8)
        ax.set_ylabel(f"error ({info['primary']})", fontsize=8)
        ax.grid(True, which="both", alpha=0.25)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=6, loc="best")
    for ax in list(axes.flat)[len(probs):]:
        ax.axis("off")
    fig.suptitle("rblog bench: work-precision (lower left is better)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _wrap(s: str, width: int) -> str:
    import textwrap

    return "\n".join(textwrap.wrap(s, width)[:6])


def write_outputs(report: BenchReport, out_dir: str | Path, stem: str = "bench") -> dict:
    """Write STEM.json, STEM.csv and STEM.png into ``out_dir``; returns their paths. A missing
    matplotlib skips the plot with a note instead of failing."""
    from rblog.errors import LogWriteError

    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise LogWriteError(str(out), str(e)) from None
    files = {"json": str(out / f"{stem}.json"), "csv": str(out / f"{stem}.csv")}
    png = out / f"{stem}.png"
    try:
        write_plot(report, png)
        files["png"] = str(png)
    except ImportError as e:
        report.notes.append(f"plot not written: {e}")
    report.files = files
    try:
        write_csv(report, files["csv"])
        Path(files["json"]).write_text(json.dumps(report.to_dict(), indent=1), encoding="utf-8")
    except OSError as e:
        raise LogWriteError(str(out), str(e)) from None
    return files


__all__ = ["run_bench", "BenchReport", "format_table", "write_csv", "write_plot", "write_outputs",
           "CSV_COLUMNS", "SCHEMA", "INTEGRATORS", "DTS", "DTS_QUICK", "fit_order",
           "convergence_orders", "mark_pareto", "peer_ratios", "machine_info", "run_rblog",
           "run_peer", "parse_integrator", "missing_dependencies", "BENCH_EXTRA"]
