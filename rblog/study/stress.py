"""Stability suite: how each integrator (and the contact engine) holds up at the edges.

Cases (each a list of variants, run with every integrator):

* ``spin``: a generic asymmetric body spinning at 10, 100 and 1,000 rad/s (dt = 1 ms, so up to
  1 rad per step).
* ``inertia``: a thin rod with inertia ratios 1:10^2, 1:10^4, 1:10^6, spinning about its axis and
  tumbling.
* ``long``: the intermediate-axis box for 10^6 steps.
* ``dt-sweep``: a generic tumbling body at time steps from 1 ms to 3 s; gives the largest stable
  dt of each integrator.
* contact cases (need rblog's contact engine; reported as unavailable otherwise):
  ``dt-sweep-contact`` (a resting box), ``impact`` (a ball hitting the ground at 10 to 1,000 m/s:
  tunneling), ``stack`` (a tall stack of boxes), ``mass-ratio`` (a 1,000 kg box on a 1 kg box),
  ``many-contact`` (10,000 balls dropped on the ground).
* ``many``: 10,000 free spinning bodies (throughput and invariants).

Every run is judged the same way. It is *unstable* when the state becomes non-finite
(:class:`~rblog.errors.SimulationDiverged`, caught), when the energy error exceeds
:data:`UNSTABLE_ENERGY` (free bodies: |E - E0|; contact: energy gained), when R drifts from
orthonormal by more than :data:`UNSTABLE_ORTHO`, or when the case's own check fails (tunneling,
a collapsed stack, penetration). "First went wrong" is the earliest logged sample at which a
tighter warning limit was crossed (:data:`WARN_ENERGY`, :data:`WARN_ORTHO`, :data:`WARN_SPIN`,
or the case check), or the step that diverged. Energies are relative to the kinetic energy plus
the potential energy above the ground at t = 0. Nothing a run raises stops the suite: every
:class:`~rblog.errors.RblogError` and any other exception becomes a row with its message, except
:class:`~rblog.errors.RunInterrupted` (Ctrl-C or SIGTERM), which stops the suite (exit 130/143).

JSON (``schema`` = :data:`SCHEMA`)::

    {"schema", "kind": "stress", "created", "command", "quick", "machine",
     "settings": {"integrators"}, "cases": [{"name", "title", "contacts", "available", "reason"}],
     "runs": [{<ROW_FIELDS>}], "largest_stable_dt": {case: {integrator: dt or null}},
     "files": {...}, "notes": [...]}

Why this module is long: it is the whole stability suite: its cases (each a list of variants), the run
of each variant, and the report.
"""

from __future__ import annotations

import itertools
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from rblog.study.bench import machine_info, parse_integrator
from rblog.errors import LogWriteError, RblogError, RunInterrupted, SimulationDiverged
from rblog.study.reference import contact_engine_status

SCHEMA = "rblog-stress/1"
#: integrators of the suite; ``seed/none`` is the notes' scheme without orthonormalization
INTEGRATORS = ("seed", "seed/none", "seed-quat", "splitting", "rk4")
#: unstable above these (relative energy error or gain; ||R^T R - I||_F)
UNSTABLE_ENERGY = 0.10
UNSTABLE_ORTHO = 1e-2
#: "first went wrong" at these (energy, orthonormality, relative |L| of any body)
WARN_ENERGY = 1e-2
WARN_ORTHO = 1e-6
WARN_SPIN = 1e-2
#: energy errors above this are drawn at this height
PLOT_CLIP = 1e3

ROW_FIELDS = (
    "case", "variant", "param", "integrator", "dt", "status", "stable", "steps", "bodies",
    "sim_time_s", "wall_s", "body_steps_per_s", "energy_growth_rel", "energy_drift_rel",
    "energy_gain_rel", "angular_momentum_drift_rel", "ortho_error_max", "first_bad_t",
    "first_bad_step", "first_bad_what", "message",
)


@dataclass
class Variant:
    """One scene of a case: ``check(traj) -> [(sample index, what, fatal)]`` flags case-specific
    failures (a body through the ground, a stack fallen)."""

    label: str
    param: float
    toml: str
    dt: float
    duration: float
    samples: int = 200
    check: Callable | None = None


@dataclass
class Case:
    name: str
    title: str
    contacts: bool
    variants: list[Variant]
    sweep: bool = False  # a dt sweep: report the largest stable dt


# ---- scene text ------------------------------------------------------------------------------

def _v(x) -> str:
    return "[" + ", ".join(repr(float(a)) for a in x) + "]"


def _sim(dt, duration, gravity=(0.0, 0.0, 0.0)) -> str:
    return f"[sim]\ndt = {dt!r}\nduration = {duration!r}\ngravity = {_v(gravity)}\n\n"


def _ground(restitution=0.5, friction=0.5) -> str:
    return f"[ground]\nheight = 0.0\nrestitution = {restitution!r}\nfriction = {friction!r}\n\n"


def _body(name, shape, size, mass, pos, *, inertia=None, vel=(0, 0, 0), wb=(0, 0, 0),
          restitution=0.5, friction=0.5) -> str:
    s = f'[[body]]\nname = "{name}"\nshape = "{shape}"\n'
    s += f"radius = {float(size)!r}\n" if shape == "sphere" else f"half_extents = {_v(size)}\n"
    s += f"mass = {float(mass)!r}\n"
    if inertia is not None:
        s += f"inertia_diag = {_v(inertia)}\n"
    s += (f"position = {_v(pos)}\nvelocity = {_v(vel)}\nangular_velocity_body = {_v(wb)}\n"
          f"restitution = {restitution!r}\nfriction = {friction!r}\n\n")
    return s


GENERIC_I = (1.0, 1.5, 2.2)
GENERIC_W = np.array([1.4, 0.5, 0.7])


# ---- case checks (on a Trajectory) -------------------------------------------------------------

def _check_tunnel(radius):
    def check(traj):
        z = traj.position[:, :, 2]
        bad = np.nonzero((z < -radius * 0.5).any(axis=1))[0]
        return [(int(bad[0]), "a ball went through the ground (tunneled)", True)] if len(bad) else []
    return check


def _check_penetration(half_heights, limit):
    hh = np.asarray(half_heights)

    def check(traj):
        z = traj.position[:, :, 2] - hh[None, :]
        bad = np.nonzero((z < -limit).any(axis=1))[0]
        return [(int(bad[0]), f"a body sank more than {limit:g} m into the ground", True)] if len(bad) else []
    return check


def _check_stack(x0, tol_xy, tol_z):
    x0 = np.asarray(x0)

    def check(traj):
        d = traj.position - x0[None]
        bad_xy = np.nonzero((np.linalg.norm(d[..., :2], axis=-1) > tol_xy).any(axis=1))[0]
        bad_z = np.nonzero((np.abs(d[..., 2]) > tol_z).any(axis=1))[0]
        out = []
        if len(bad_xy):
            out.append((int(bad_xy[0]), f"a box slid more than {tol_xy:g} m (stack toppling)", True))
        if len(bad_z):
            out.append((int(bad_z[0]), f"a box moved more than {tol_z:g} m vertically", True))
        return out
    return check


def _check_rest(x0, tol):
    x0 = np.asarray(x0)

    def check(traj):
        d = np.linalg.norm(traj.position - x0[None], axis=-1)
        bad = np.nonzero((d > tol).any(axis=1))[0]
        return [(int(bad[0]), f"a resting body moved more than {tol:g} m", True)] if len(bad) else []
    return check


# ---- cases -------------------------------------------------------------------------------------

def build_cases(quick: bool) -> list[Case]:
    cases = []
    w_hat = GENERIC_W / np.linalg.norm(GENERIC_W)

    spins = (10.0, 100.0, 1000.0)
    cases.append(Case("spin", "fast spin of a generic body (I = 1, 1.5, 2.2), dt = 1 ms", False, [
        Variant(f"|w| = {w:g} rad/s", w,
                _sim(1e-3, 1.0) + _body("body", "box", (0.3, 0.2, 0.1), 1.0, (0, 0, 0),
                                        inertia=GENERIC_I, wb=w * w_hat), 1e-3, 1.0)
        for w in spins]))

    ratios = (1e-2, 1e-4, 1e-6)
    cases.append(Case("inertia", "thin rod, I = (r, 1, 1), spinning 2 rad/s about its axis and "
                      "tumbling, dt = 1 ms", False, [
        Variant(f"1:{1 / r:.0e}", r,
                _sim(1e-3, 2.0 if quick else 10.0)
                + _body("rod", "box", (0.5, 0.005, 0.005), 1.0, (0, 0, 0), inertia=(r, 1.0, 1.0),
                        wb=(2.0, 1.0, 0.5)), 1e-3, 2.0 if quick else 10.0)
        for r in ratios]))

    n_long = 100_000 if quick else 1_000_000
    cases.append(Case("long", f"intermediate-axis box for {n_long:,} steps (dt = 1 ms)", False, [
        Variant(f"{n_long:.0e} steps", float(n_long),
                _sim(1e-3, n_long * 1e-3) + _body("box", "box", (0.3, 0.2, 0.1), 1.0, (0, 0, 0),
                                                  inertia=(1.0, 2.0, 3.0), wb=(0.05, 2.0, 0.05)),
                1e-3, n_long * 1e-3, samples=1000)]))

    dts = (1e-2, 1e-1, 1.0) if quick else (1e-3, 3e-3, 1e-2, 3e-2, 1e-1, 3e-1, 1.0, 3.0)
    t_sweep = 10.0 if quick else 30.0
    cases.append(Case("dt-sweep", f"generic tumbling body (I = 1, 1.5, 2.2; |w| = 1.6 rad/s) "
                      f"for {t_sweep:g} s at growing dt", False, [
        Variant(f"dt = {dt:g} s", dt,
                _sim(dt, t_sweep) + _body("body", "box", (0.3, 0.2, 0.1), 1.0, (0, 0, 0),
                                          inertia=GENERIC_I, wb=GENERIC_W), dt, t_sweep)
        for dt in dts], sweep=True))

    n_many = 1000 if quick else 10_000
    t_many = 0.1 if quick else 1.0
    cases.append(Case("many", f"{n_many:,} free spinning boxes, no gravity (dt = 1 ms)", False, [
        Variant(f"{n_many} bodies", float(n_many),
                _sim(1e-3, t_many) + "[[generator]]\nlayout = \"grid\"\n"
                f"grid = [{n_many // 100}, 100, 1]\nspacing = 1.0\nspin = [1.0, 10.0]\n"
                "random_orientation = true\nseed = 3\n[generator.body]\nshape = \"box\"\n"
                "half_extents = [0.3, 0.15, 0.08]\ndensity = 500.0\n\n", 1e-3, t_many, samples=10)]))

    # -- contact cases --
    g = (0.0, 0.0, -9.81)
    dts_c = (1e-3, 1e-2, 5e-2) if quick else (1e-3, 2e-3, 5e-3, 1e-2, 2e-2, 5e-2)
    cases.append(Case("dt-sweep-contact", "box resting on the ground (2 s) at growing dt", True, [
        Variant(f"dt = {dt:g} s", dt,
                _sim(dt, 2.0, g) + _ground() + _body("box", "box", (0.5, 0.3, 0.2), 10.0, (0, 0, 0.2)),
                dt, 2.0, check=_check_rest([[0, 0, 0.2]], 0.01)) for dt in dts_c], sweep=True))

    r = 0.05
    cases.append(Case("impact", "ball (r = 5 cm) hitting the ground at speed v, dt = 1 ms "
                      "(tunneling when v dt >> r)", True, [
        Variant(f"v = {v:g} m/s", v,
                _sim(1e-3, 0.2, g) + _ground(0.5, 0.0)
                + _body("ball", "sphere", r, 1.0, (0, 0, r + 0.05 * v), vel=(0, 0, -v),
                        restitution=0.5, friction=0.0),
                1e-3, 0.2, samples=0, check=_check_tunnel(r)) for v in (10.0, 100.0, 1000.0)]))

    n_stack = 5 if quick else 20
    t_stack = 1.0 if quick else 5.0
    h = 0.1
    x0 = [(0.0, 0.0, h + 2 * h * k) for k in range(n_stack)]
    cases.append(Case("stack", f"stack of {n_stack} cubes (20 cm) on the ground, {t_stack:g} s, "
                      "dt = 1 ms", True, [
        Variant(f"{n_stack} boxes", float(n_stack),
                _sim(1e-3, t_stack, g) + _ground()
                + "".join(_body(f"box{k}", "box", (h, h, h), 1.0, x0[k]) for k in range(n_stack)),
                1e-3, t_stack, check=_check_stack(x0, 0.05, 0.02))]))

    t_mr = 0.5 if quick else 2.0
    cases.append(Case("mass-ratio", f"1,000 kg box resting on a 1 kg box on the ground, {t_mr:g} s, "
                      "dt = 1 ms", True, [
        Variant("1:1000", 1000.0,
                _sim(1e-3, t_mr, g) + _ground()
                + _body("light", "box", (0.2, 0.2, 0.1), 1.0, (0, 0, 0.1))
                + _body("heavy", "box", (0.2, 0.2, 0.1), 1000.0, (0, 0, 0.3)),
                1e-3, t_mr, check=_check_stack([(0, 0, 0.1), (0, 0, 0.3)], 0.05, 0.02))]))

    n_mc = 200 if quick else 10_000
    t_mc = 0.2 if quick else 1.0
    side = int(math.ceil(math.sqrt(n_mc)))
    cases.append(Case("many-contact", f"{n_mc:,} balls dropped onto the ground, {t_mc:g} s, "
                      "dt = 1 ms", True, [
        Variant(f"{n_mc} balls", float(n_mc),
                _sim(1e-3, t_mc, g) + _ground() + "[[generator]]\nlayout = \"grid\"\n"
                f"grid = [{side}, {int(math.ceil(n_mc / side))}, 1]\nspacing = 0.5\n"
                "origin = [0.0, 0.0, 0.3]\n[generator.body]\nshape = \"sphere\"\n"
                "radius = 0.1\nmass = 1.0\n\n", 1e-3, t_mc, samples=10,
                check=_check_tunnel(0.1))]))
    return cases


CASE_NAMES = ("spin", "inertia", "long", "dt-sweep", "many", "dt-sweep-contact", "impact", "stack",
              "mass-ratio", "many-contact")


# ---- running -----------------------------------------------------------------------------------

def _new_row(case: Case, v: Variant, spec: str) -> dict:
    row = {k: None for k in ROW_FIELDS}
    row.update(case=case.name, variant=v.label, param=v.param, integrator=spec, dt=v.dt,
               status="stable", stable=True, message="")
    return row


def _energy_scale(model, state) -> float:
    ke = 0.5 * float(np.sum(state.linear_momentum**2 / model.body_mass[:, None]))
    lb = np.einsum("nji,nj->ni", state.rotation, state.angular_momentum_world)
    ke += 0.5 * float(np.sum(lb**2 / model.body_inertia_diag))
    pe = 0.0
    if model.ground:
        height = state.position @ model.ground_normal - model.ground_offset
        pe = float(np.sum(model.body_mass * np.linalg.norm(model.gravity) * np.maximum(height, 0.0)))
    e = ke + pe
    return e if e > 0 else 1.0


def run_variant(case: Case, v: Variant, spec: str) -> dict:
    """Run one variant with one integrator and judge it; never raises."""
    from rblog.engine.scene import parse_scene
    from rblog.engine.runner import simulate

    row = _new_row(case, v, spec)
    integ, ortho = parse_integrator(spec)
    try:
        scene = parse_scene(v.toml, f"<stress {case.name}>")
    except RblogError as e:
        row.update(status="error", stable=None, message=str(e))
        return row
    n_steps = max(1, int(round(v.duration / v.dt)))
    every = 1 if v.samples <= 0 else max(1, n_steps // v.samples)
    row["bodies"] = scene.model.n_bodies
    scale = _energy_scale(scene.model, scene.state)
    col = None
    t0 = time.perf_counter()
    try:
        from rblog.engine.runner import TrajectoryCollector, run

        col = TrajectoryCollector()
        summary = run(scene, integrator=integ, orthonormalize=ortho, log_every=every, recorders=[col])
        traj = col.trajectory
        row.update(steps=summary.steps, sim_time_s=summary.sim_time_s, wall_s=summary.wall_time_s,
                   body_steps_per_s=summary.body_steps_per_s)
    except SimulationDiverged as e:
        traj = col.trajectory if col is not None and col.blocks else None
        row.update(status="diverged", stable=False, message=str(e), first_bad_t=e.time_s,
                   first_bad_step=e.step, first_bad_what=f"non-finite state (body {e.body_name!r})",
                   wall_s=time.perf_counter() - t0)
        if traj is not None:
            _judge(row, traj, scale, case, v, diverged=True)
        return row
    except (ImportError, NotImplementedError) as e:
        row.update(status="unavailable", stable=None, message=f"{type(e).__name__}: {e}")
        return row
    except RunInterrupted:  # Ctrl-C or kill: the user stops the suite, not this one run
        raise
    except RblogError as e:
        row.update(status="error", stable=None, message=str(e))
        return row
    except Exception as e:  # a bug in an engine stage: reported, the suite goes on
        row.update(status="error", stable=None, message=f"{type(e).__name__}: {e}")
        return row
    _judge(row, traj, scale, case, v, diverged=False)
    return row


def _judge(row: dict, traj, scale: float, case: Case, v: Variant, diverged: bool):
    e = traj.total_energy
    de = (e - e[0]) / scale
    row["energy_growth_rel"] = float(de[-1])
    row["energy_drift_rel"] = float(np.max(np.abs(de)))
    row["energy_gain_rel"] = float(max(0.0, np.max(de)))
    spin = np.linalg.norm(traj.angular_momentum, axis=-1)
    has = spin[0] > 0
    spin_dev = np.zeros(len(e))
    if np.any(has):
        spin_dev = np.max(np.abs(spin[:, has] - spin[0, has]) / spin[0, has], axis=1)
        row["angular_momentum_drift_rel"] = float(spin_dev.max())
    ortho = traj.ortho_error.max(axis=1)
    row["ortho_error_max"] = float(ortho.max())
    energy_err = np.abs(de) if not case.contacts else np.maximum(de, 0.0)
    events = []  # (sample, what, fatal)
    k = np.nonzero(energy_err > WARN_ENERGY)[0]
    if len(k):
        what = "energy error" if not case.contacts else "energy gained"
        events.append((int(k[0]), f"{what} > {WARN_ENERGY:g}", False))
    k = np.nonzero(ortho > WARN_ORTHO)[0]
    if len(k):
        events.append((int(k[0]), f"||R^T R - I|| > {WARN_ORTHO:g}", False))
    if not case.contacts:
        k = np.nonzero(spin_dev > WARN_SPIN)[0]
        if len(k):
            events.append((int(k[0]), f"|L| drift > {WARN_SPIN:g}", False))
    fatal = []
    k = np.nonzero(energy_err > UNSTABLE_ENERGY)[0]
    if len(k):
        fatal.append((int(k[0]), f"energy {'error' if not case.contacts else 'gain'} > {UNSTABLE_ENERGY:g}"))
    k = np.nonzero(ortho > UNSTABLE_ORTHO)[0]
    if len(k):
        fatal.append((int(k[0]), f"||R^T R - I|| > {UNSTABLE_ORTHO:g}"))
    if v.check is not None:
        for idx, what, is_fatal in v.check(traj):
            events.append((idx, what, False))
            if is_fatal:
                fatal.append((idx, what))
    if not diverged:
        if events:
            idx, what, _ = min(events, key=lambda x: x[0])
            row.update(first_bad_t=float(traj.t[idx]), first_bad_step=int(traj.step[idx]),
                       first_bad_what=what)
        if fatal:
            idx, what = min(fatal, key=lambda x: x[0])
            row.update(status="unstable", stable=False,
                       message=f"{what} at t = {traj.t[idx]:.6g} s")


@dataclass
class StressReport:
    rows: list[dict]
    cases: list[dict]
    settings: dict
    machine: dict
    quick: bool
    command: str = ""
    created: str = ""
    largest_stable_dt: dict = field(default_factory=dict)
    files: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        rows = [{k: (None if isinstance(r.get(k), float) and not math.isfinite(r[k]) else r.get(k))
                 for k in ROW_FIELDS} for r in self.rows]
        return {"schema": SCHEMA, "kind": "stress", "created": self.created,
                "command": self.command, "quick": self.quick, "machine": self.machine,
                "settings": self.settings, "cases": self.cases, "runs": rows,
                "largest_stable_dt": self.largest_stable_dt, "files": self.files,
                "notes": self.notes}


def run_stress(*, quick: bool = False, cases: list[str] | tuple | None = None,
               integrators: list[str] | tuple | None = None,
               progress: Callable[[str], None] | None = None, command: str = "",
               executor=None) -> StressReport:
    """Run the suite (``cases``: names from :data:`CASE_NAMES`, default all); ``executor``: a
    :class:`rblog.study.cluster.Executor` to run the variants on (default: here)."""
    from rblog.study.cluster import map_cases

    names = list(cases) if cases else list(CASE_NAMES)
    for n in names:
        if n not in CASE_NAMES:
            raise RblogError(f"unknown stress case {n!r} (expected one of: {', '.join(CASE_NAMES)})")
    specs = list(integrators) if integrators else list(INTEGRATORS)
    say = progress or (lambda m: None)
    contact_ok, contact_why = contact_engine_status()
    all_cases = {c.name: c for c in build_cases(quick)}
    rows, infos = [], []
    for n in names:
        case = all_cases[n]
        info = {"name": case.name, "title": case.title, "contacts": case.contacts,
                "available": True, "reason": ""}
        if case.contacts and not contact_ok:
            info.update(available=False, reason=contact_why)
        infos.append(info)
        runs = [(v, spec) for v in case.variants for spec in specs]
        done = map_cases(executor, lambda c, case=case: run_variant(case, c[0], c[1]),
                         runs if info["available"] else [],
                         say=lambda c, case=case: say(f"stress {case.name} [{c[0].label}] {c[1]}"),
                         failed=lambda c, why, case=case: {**_new_row(case, c[0], c[1]),
                                                           "status": "error", "stable": None,
                                                           "message": why})
        for (v, spec), r in itertools.zip_longest(runs, done):
            if not info["available"]:
                r = _new_row(case, v, spec)
                r.update(status="unavailable", stable=None, message=info["reason"])
            rows.append(r)
            if r["status"] == "unavailable":
                info.update(available=False, reason=r["message"])
    report = StressReport(rows=rows, cases=infos, quick=quick, machine=machine_info(),
                          command=command, created=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                          settings={"integrators": specs})
    report.largest_stable_dt = largest_stable_dt(rows, [all_cases[n] for n in names])
    return report


def largest_stable_dt(rows: list[dict], cases: list[Case]) -> dict:
    """{sweep case: {integrator: the largest dt such that it and every smaller dt were stable}}."""
    out = {}
    for c in cases:
        if not c.sweep:
            continue
        d = {}
        for spec in sorted({r["integrator"] for r in rows if r["case"] == c.name}):
            rs = sorted([r for r in rows if r["case"] == c.name and r["integrator"] == spec],
                        key=lambda r: r["dt"])
            if any(r["stable"] is None for r in rs):
                d[spec] = None
                continue
            best = None
            for r in rs:
                if not r["stable"]:
                    break
                best = r["dt"]
            d[spec] = best
        out[c.name] = d
    return out


# ---- output ------------------------------------------------------------------------------------

def _f(v, spec=".2e"):
    if v is None:
        return "-"
    return format(v, spec)


def format_table(report: StressReport) -> str:
    m = report.machine
    lines = [f"rblog stress{' --quick' if report.quick else ''}: {m.get('cpu', '?')}, "
             f"{m.get('cores', '?')} cores"]
    head = (f"{'variant':<20}{'integrator':<12}{'result':<12}{'E growth':>10}{'E drift':>10}"
            f"{'|L| drift':>10}{'ortho':>10}{'Mbody-st/s':>11}  first went wrong")
    for info in report.cases:
        lines.append("")
        lines.append(f"{info['name']}: {info['title']}")
        rs = [r for r in report.rows if r["case"] == info["name"]]
        if not info["available"]:
            lines.append(f"  unavailable: {info['reason']}")
            continue
        lines.append(head)
        for r in rs:
            if r["status"] in ("error", "unavailable"):
                lines.append(f"{r['variant']:<20}{r['integrator']:<12}{r['status']:<12}{r['message'][:100]}")
                continue
            bad = "-"
            if r["first_bad_what"]:
                bad = f"{r['first_bad_what']} at t = {r['first_bad_t']:.4g} s (step {r['first_bad_step']})"
            tput = r["body_steps_per_s"] / 1e6 if r["body_steps_per_s"] else None
            lines.append(
                f"{r['variant']:<20}{r['integrator']:<12}{r['status']:<12}"
                f"{_f(r['energy_growth_rel'], '+.2e'):>10}{_f(r['energy_drift_rel']):>10}"
                f"{_f(r['angular_momentum_drift_rel']):>10}{_f(r['ortho_error_max']):>10}"
                f"{_f(tput, '.3g'):>11}  {bad}")
    if report.largest_stable_dt:
        lines.append("")
        lines.append(f"largest stable dt (energy error <= {UNSTABLE_ENERGY:g}, finite, case checks)")
        for case, d in report.largest_stable_dt.items():
            parts = [f"{k} {('unavailable' if v is None and any(r['case'] == case and r['status'] == 'unavailable' for r in report.rows) else _f(v, 'g'))}"
                     for k, v in d.items()]
            lines.append(f"  {case:<18}" + ", ".join(parts))
    for n in report.notes:
        lines.append(f"note: {n}")
    return "\n".join(lines)


def write_plot(report: StressReport, path):
    """Three panels: energy error against dt (the sweep), against spin rate, and a stable/unstable
    grid of every case variant x integrator."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    specs = report.settings["integrators"]
    colors = {s: plt.cm.tab10(i % 10) for i, s in enumerate(specs)}
    fig = plt.figure(figsize=(15, 6.5))
    gs = fig.add_gridspec(1, 3, width_ratios=[1, 1, 1.5])
    for ax, case, xlabel, xkey in ((fig.add_subplot(gs[0]), "dt-sweep", "dt (s)", "dt"),
                                   (fig.add_subplot(gs[1]), "spin", "|w| (rad/s)", "param")):
        rs = [r for r in report.rows if r["case"] == case]
        ax.set_title(f"{case}: max energy error", fontsize=10)
        if not rs:
            ax.text(0.5, 0.5, "not run", ha="center", transform=ax.transAxes)
            continue
        for s in specs:
            pts = sorted([r for r in rs if r["integrator"] == s], key=lambda r: r[xkey])
            ok = [r for r in pts if r["energy_drift_rel"] is not None and r["status"] != "diverged"]
            if ok:
                ax.plot([r[xkey] for r in ok],
                        [min(max(r["energy_drift_rel"], 1e-17), PLOT_CLIP) for r in ok],
                        "-o", ms=3.5, color=colors[s], label=s, lw=1.2)
            div = [r for r in pts if r["status"] == "diverged"]
            if div:
                ax.scatter([r[xkey] for r in div], [PLOT_CLIP] * len(div), marker="x",
                           color=colors[s], s=50, label=None if ok else s)
        ax.axhline(UNSTABLE_ENERGY, color="r", lw=0.8, ls="--", label=f"unstable ({UNSTABLE_ENERGY:g})")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel + f"   (x: diverged; values clipped at {PLOT_CLIP:g})", fontsize=8)
        ax.set_ylabel("max |E - E0| / E0", fontsize=8)
        ax.grid(True, which="both", alpha=0.25)
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=7)
    ax = fig.add_subplot(gs[2])
    variants = []
    for info in report.cases:
        for r in report.rows:
            if r["case"] == info["name"] and (info["name"], r["variant"]) not in variants:
                variants.append((info["name"], r["variant"]))
    code = {"stable": 0, "unstable": 1, "diverged": 1, "unavailable": 2, "error": 3}
    grid = np.full((len(variants), len(specs)), 2.0)
    for r in report.rows:
        i = variants.index((r["case"], r["variant"]))
        if r["integrator"] in specs:
            grid[i, specs.index(r["integrator"])] = code.get(r["status"], 3)
    cmap = ListedColormap(["#8fd18f", "#f08080", "#d9d9d9", "#f0c060"])
    ax.imshow(grid, cmap=cmap, vmin=-0.5, vmax=3.5, aspect="auto")
    for r in report.rows:
        i = variants.index((r["case"], r["variant"]))
        j = specs.index(r["integrator"]) if r["integrator"] in specs else None
        if j is None:
            continue
        txt = {"diverged": "diverged", "unavailable": "n/a", "error": "error"}.get(r["status"])
        if txt is None:
            txt = _f(r["energy_drift_rel"], ".0e")
        ax.text(j, i, txt, ha="center", va="center", fontsize=6)
    ax.set_xticks(range(len(specs)))
    ax.set_xticklabels(specs, fontsize=7, rotation=20)
    ax.set_yticks(range(len(variants)))
    ax.set_yticklabels([f"{c}: {v}" for c, v in variants], fontsize=6)
    ax.set_title("green stable, red unstable/diverged, grey unavailable, amber error\n"
                 "(cell: max relative energy error)", fontsize=8)
    fig.suptitle("rblog stress", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_outputs(report: StressReport, out_dir, stem: str = "stress") -> dict:
    """Write STEM.json and STEM.png (plot skipped with a note when matplotlib is missing)."""
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise LogWriteError(str(out), str(e)) from None
    files = {"json": str(out / f"{stem}.json")}
    try:
        write_plot(report, out / f"{stem}.png")
        files["png"] = str(out / f"{stem}.png")
    except ImportError as e:
        report.notes.append(f"plot not written: {e}")
    report.files = files
    try:
        Path(files["json"]).write_text(json.dumps(report.to_dict(), indent=1), encoding="utf-8")
    except OSError as e:
        raise LogWriteError(str(out), str(e)) from None
    return files


__all__ = ["run_stress", "StressReport", "format_table", "write_plot", "write_outputs",
           "build_cases", "CASE_NAMES", "INTEGRATORS", "ROW_FIELDS", "SCHEMA",
           "largest_stable_dt", "run_variant"]
