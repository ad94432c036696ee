"""``rblog``: the command-line front end. It parses, calls the library, and prints; nothing else.

Known errors (rblog.errors.RblogError) print one line and exit with the error's code (2 for bad
input); anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import faulthandler
import json
import os
import sys
import time
from pathlib import Path

import click

from rblog.errors import RblogError
from rblog_cli import IN_PROGRAM, LOGS_STATE
from rblog_cli.report import (count, live_audit, live_report, next_commands, print_live_report,
                              print_report, program)


# the registry alone (pure Python): `rblog --help` loads neither numpy nor the core
from rblog.engine.registry import ORTHO_ALLOWED, ORTHO_CODES

INTEGRATORS = tuple(ORTHO_ALLOWED)


def _fail(err: RblogError):
    click.echo(f"rblog: error: {err}", err=True)
    from rblog.errors import RunInterrupted

    if isinstance(err, RunInterrupted) and IN_PROGRAM:
        # The logs are closed and complete up to the last step; what is left is interpreter
        # teardown (the Rerun SDK's exit hooks, thread joins), measured 0.5-0.65 s on a loaded
        # machine. A signal asks the process to go now: exit without it.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(err.exit_code)
    sys.exit(err.exit_code)


class _Progress:
    """A progress bar on stderr that appears only when the run will take more than ~1 s."""

    def __init__(self, enabled: bool, label: str = "simulating"):
        self.enabled, self.label = enabled, label
        self.bar = None
        self.t0 = time.perf_counter()

    def __call__(self, done: int, total: int):
        from rblog.engine.constants import PROGRESS_MIN_WALL_S

        if not self.enabled:
            return
        if self.bar is None:
            elapsed = time.perf_counter() - self.t0
            if done >= total or elapsed / done * (total - done) < PROGRESS_MIN_WALL_S:
                return
            from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
            from rich.console import Console

            self.bar = Progress(TextColumn(self.label), BarColumn(), TextColumn("{task.percentage:>3.0f}%"),
                                TimeRemainingColumn(), console=Console(stderr=True), transient=True)
            self.bar.start()
            self.task = self.bar.add_task("run", total=total)
        self.bar.update(self.task, completed=done)

    def close(self):
        if self.bar is not None:
            self.bar.stop()


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="rblog")
def main():
    """rblog: simulate rigid bodies, record what happened, audit the recording."""
    # a crash in native code (the core, an engine, an SDK) prints every thread's Python stack
    # to stderr instead of ending the process without a word; not where sys.stderr has no file
    # descriptor (click's CliRunner, a host that replaced it): faulthandler writes to an fd
    try:
        faulthandler.enable()
    except (OSError, ValueError, AttributeError):  # io.UnsupportedOperation('fileno') among them
        pass


@main.command()
@click.argument("scene", type=click.Path(dir_okay=False, path_type=str))
def validate(scene):
    """Check a scene file without running it."""
    from rblog.engine.scene import load_scene

    try:
        s = load_scene(scene)
    except RblogError as e:
        _fail(e)
    for w in s.warnings:
        click.echo(f"rblog: warning: {w}", err=True)
    click.echo(f"{scene}: ok ({count(s.model.n_bodies, 'body')}, {count(s.sim.n_steps, 'step')} of "
               f"{s.sim.dt:g} s, integrator {s.sim.integrator})")
    click.echo("  shapes: " + ", ".join(f"{k} {v}" for k, v in s.shape_counts().items()))


@main.command()
@click.argument("scene", type=click.Path(dir_okay=False, path_type=str))
@click.option("--dt", type=float, help="Time step (s); overrides [sim] dt.")
@click.option("--duration", type=float, help="Simulated time (s); overrides [sim] duration.")
@click.option("--integrator", type=click.Choice(INTEGRATORS), help="Integrator; overrides [sim].")
@click.option("--orthonormalize", type=click.Choice(sorted(ORTHO_CODES)),
              help="seed: polar|gram-schmidt|none; seed-quat: normalize|none.")
@click.option("--rrd", type=click.Path(dir_okay=False, path_type=str), help="Write a Rerun log here.")
@click.option("--mcap", type=click.Path(dir_okay=False, path_type=str), help="Write an MCAP log here.")
@click.option("--mcap-compression", type=click.Choice(["lz4", "zstd", "none"]), default="lz4",
              show_default=True, help="Chunk compression of the MCAP log (none: fastest, largest).")
@click.option("--no-log", is_flag=True, help="Write no log (by default, SCENE-STEM.rrd and .mcap).")
@click.option("--log-every", type=click.IntRange(min=1), help="Log every K-th step.")
@click.option("--log-rate", type=click.FloatRange(min=0, min_open=True),
              help="Log at HZ samples per simulated second (default 100).")
@click.option("--spawn", is_flag=True, help="Also stream to a new Rerun viewer.")
@click.option("--connect", "connect_url", help="Also stream to a running Rerun viewer at this URL.")
@click.option("--explain", is_flag=True,
              help="Print the stages chosen for this scene and why, then exit (add --run to run).")
@click.option("--run", "run_too", is_flag=True, help="With --explain: run the scene afterwards.")
@click.option("--all-stages", is_flag=True, help="Force every stage on (for benchmarks).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as one JSON object.")
@click.option("--engine", type=click.Choice(["rblog", "mujoco", "pybullet", "ode"]), default="rblog",
              show_default=True,
              help='Engine to run the scene in (mujoco/pybullet: pip install -e ".[engines]"; ode: '
                   'libode8 and pip install -e ".[ode]").')
@click.option("--engine-option", "engine_options", multiple=True, metavar="KEY=VALUE",
              help="A setting of the --engine, e.g. integrator=RK4 (repeatable).")
@click.option("--profile", "profile", is_flag=True, help="Print the time spent in each stage.")
@click.option("--threads", type=click.IntRange(min=1), metavar="N",
              help="Threads to step on (default: RBLOG_THREADS, else every core); the result is "
                   "bitwise the same for any N.")
@click.option("--check", "live_check", is_flag=True,
              help="Audit while running: the analyzers of `rblog check` run on the blocks as they "
                   "are written, each finding is printed (and streamed into the .rrd) when it is "
                   "final, and the verdict of `rblog check` on the log is printed at the end "
                   "(exit 1 if flagged).")
@click.option("--fail-fast", is_flag=True,
              help="With --check (implied): stop the run at the first finding (exit 1; logs "
                   "closed, readable, marked truncated).")
def run(scene, dt, duration, integrator, orthonormalize, rrd, mcap, mcap_compression, no_log,
        log_every, log_rate, spawn, connect_url, explain, run_too, all_stages, as_json, engine,
        engine_options, profile, threads, live_check, fail_fast):
    """Simulate SCENE (a .toml file) and record it."""
    live_check = live_check or fail_fast
    if engine != "rblog" or engine_options:
        if engine == "rblog" or spawn or connect_url or explain or all_stages or profile:
            _fail(RblogError("--engine-option needs --engine mujoco|pybullet|ode, which takes no "
                             "--spawn/--connect/--explain/--all-stages/--profile"))
        if log_every is not None and log_rate is not None:
            _fail(RblogError("give --log-every or --log-rate, not both"))
        from rblog_cli.engine_cmds import run_with_engine

        return run_with_engine(scene, engine, engine_options, dt=dt, duration=duration,
                               integrator=integrator, orthonormalize=orthonormalize, rrd=rrd,
                               mcap=mcap, mcap_compression=mcap_compression, no_log=no_log,
                               log_every=log_every, log_rate=log_rate, as_json=as_json, fail=_fail,
                               live_check=live_check, fail_fast=fail_fast)
    LOGS_STATE[0] = "no log written"  # until the run loop opens them under its own handlers
    from rblog.engine.scene import load_scene
    from rblog.engine.runner import run as run_scene
    from rblog.engine.plan import plan_stages

    if log_every is not None and log_rate is not None:
        _fail(RblogError("give --log-every or --log-rate, not both"))
    if run_too and not explain:
        _fail(RblogError("--run goes with --explain (a plain `rblog run` runs already)"))
    audit = None
    try:
        s = load_scene(scene)
        for w in s.warnings:
            click.echo(f"rblog: warning: {w}", err=True)
        # every output is checked before the run starts
        recorders, paths = _recorders(scene, rrd, mcap, no_log, spawn, connect_url, mcap_compression,
                                      check_only=True)
        if explain:
            plan = plan_stages(s, duration or s.sim.duration, force_contacts=all_stages)
            if plan.contacts:
                from rblog.engine.integrators import METHOD_CODES, ORTHO_ALLOWED

                integ = integrator or s.sim.integrator
                plan.make_contact_world(METHOD_CODES[integ], ORTHO_CODES[ORTHO_ALLOWED[integ][1]])
                for w in plan.warnings:
                    click.echo(f"rblog: warning: {w}", err=True)
            for stage, why in plan.stages:
                click.echo(f"{stage:<28} {why}", err=as_json)
            if not run_too:
                return
        recorders, paths = _recorders(scene, rrd, mcap, no_log, spawn, connect_url, mcap_compression)
        if live_check:
            audit = live_audit(recorders, fail_fast, as_json)
            recorders = [*recorders, audit]
        prog = _Progress(enabled=sys.stderr.isatty())
        prof = None
        if profile:
            from rblog.engine.profile import Profile

            prof = Profile()
        try:
            summary = run_scene(
                s, dt=dt, duration=duration, integrator=integrator, orthonormalize=orthonormalize,
                log_every=log_every, log_rate=log_rate, recorders=recorders, progress=prog,
                force_contacts=all_stages, threads=threads,
                warn=lambda m: click.echo(f"rblog: warning: {m}", err=True), profile=prof)
        finally:
            prog.close()
        LOGS_STATE[0] = "logs complete"
    except RblogError as e:
        if audit is not None and audit.failed is not None and e is audit.failed:
            print_live_report(audit, as_json, paths=paths)
            if as_json:  # the audit stopped the run: the object still comes, status "stopped"
                click.echo(json.dumps({"status": "stopped", "message": str(e), "logs": paths,
                                       "check": live_report(audit)}))
        _fail(e)
    d = summary.to_dict()
    d["logs"] = paths
    for key in summary.not_applicable:  # not an error in this scene: no number, the reason
        d[key] = None
    if prof is not None:
        d["profile_s"] = {name: sec for name, sec, _ in prof.table()}
        if audit is not None:
            # the live audit runs beside the stepping (its own thread); what it cost the run is
            # in the wall time, compared in benchmarks/bench_live.py; here its own seconds
            d["profile_s"]["live audit (own thread)"] = audit.stats.total_s
        if not as_json:
            click.echo("profile (s, share of wall time):")
            for name, sec, share in prof.table():
                click.echo(f"  {name:<36} {sec:9.4f}  {100 * share:5.1f} %")
            if audit is not None:
                st = audit.stats
                click.echo(f"  {'live audit (own thread)':<36} {st.total_s:9.4f}  "
                           f"{100 * st.total_s / max(summary.wall_time_s, 1e-12):5.1f} %  "
                           f"({st.checks} prefix checks {st.check_s:.4f} s, final check "
                           f"{st.final_s:.4f} s)")
    if as_json:
        if audit is not None:
            d["check"] = live_report(audit)
            if d["check"]["flagged"]:
                d["status"] = "flagged"
        click.echo(json.dumps(d))
        if audit is not None:
            sys.exit(1 if d["check"]["flagged"] else 0)
        return
    click.echo(
        f"{scene}: {count(summary.steps, 'step')} x {count(summary.bodies, 'body')}, "
        f"{summary.sim_time_s:g} s "
        f"simulated in {summary.wall_time_s:.3f} s wall ({summary.steps_per_s:,.0f} steps/s, "
        f"{summary.body_steps_per_s:,.0f} body-steps/s)")
    click.echo(f"  integrator {summary.integrator} (orthonormalize {summary.orthonormalize}), "
               f"dt {summary.dt:g} s, logged every {summary.log_every} steps ({summary.samples} samples)")
    na = summary.not_applicable
    e_why, l_why = na.get("energy_drift_rel"), na.get("angular_momentum_drift_rel")
    # the engine's self-report (rblog.engine.summary.Drift), told apart from the audit
    click.echo("  the engine's own figures at the logged samples (the audit: rblog check LOG)")
    if e_why and e_why == l_why:
        click.echo(f"    energy, |L| drift     not shown: {e_why}")
    else:
        click.echo("    energy drift (rel)    " + (f"not shown: {e_why}" if e_why else
                                                  f"{summary.energy_drift_rel:.3e}"))
        click.echo("    |L| drift (rel)       " + (f"not shown: {l_why}" if l_why else
                                                  f"{summary.angular_momentum_drift_rel:.3e}"))
    if summary.contact_penetration_max_m is not None:
        click.echo(f"    deepest penetration   {1e3 * summary.contact_penetration_max_m:.3f} mm "
                   "(the engine's narrowphase on the logged poses)")
    click.echo(f"    max ||R^T R - I||_F   {summary.ortho_error_max:.3e}")
    for p in paths:
        click.echo(f"  wrote {p}")
    flagged = audit is not None and print_live_report(audit, as_json, paths=paths)
    for i, cmd in enumerate(next_commands(paths)):
        click.echo(f"{'next:' if i == 0 else '':<6}{cmd}")
    if audit is not None:
        sys.exit(1 if flagged else 0)


#: `rblog check` uses local workers by default above this many logs (starting them costs ~2 s)
BULK_PARALLEL_MIN_LOGS = 8
#: above this many logs, the text report shows only the flagged logs, then the summary
BULK_DETAIL_MAX_LOGS = 20


@main.command()
@click.argument("logs", nargs=-1, type=click.Path(path_type=str))
@click.option("--only", help="Comma-separated analyzers to run (default: all).")
@click.option("--skip", help="Comma-separated analyzers to leave out.")
@click.option("--tol", "tols", multiple=True, metavar="ANALYZER.NAME=VALUE",
              help="Override a tolerance, e.g. --tol penetration.depth_m=2e-3 (repeatable; see --list).")
@click.option("--list", "list_only", is_flag=True, help="List the analyzers and their tolerances.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as one JSON document.")
@click.option("--workers", type=click.IntRange(min=0),
              help="Check on a local Dask cluster of N worker processes (0: in this process). "
                   f"Default: one per core when more than {BULK_PARALLEL_MIN_LOGS} logs are given "
                   "and Dask is installed.")
@click.option("--scheduler", metavar="ADDRESS",
              help="Check on a running dask.distributed scheduler (tcp://host:8786); the logs "
                   "must be readable by the workers at the same paths.")
@click.option("--table", "table_path", type=click.Path(dir_okay=False, path_type=str),
              help="Write the per-log table here (.parquet, else CSV).")
@click.option("--rrd", "findings_rrd", type=click.Path(dir_okay=False, path_type=str),
              help="Write one Rerun recording holding the run and its findings (table, bodies "
                   "marked in 3D), to open with `rerun FILE` (one LOG, .rrd or .mcap).")
@click.option("--mcap", "findings_mcap", type=click.Path(dir_okay=False, path_type=str),
              help="Write one MCAP file holding the run and its findings (foxglove.Log and "
                   "markers), to open in Foxglove (one LOG, .rrd or .mcap).")
@click.option("--threads", type=click.IntRange(min=1), metavar="N",
              help="Analyzers run at once, per process (default: RBLOG_THREADS, else every "
                   "core); the verdicts are the same for any N.")
def check(logs, only, skip, tols, list_only, as_json, workers, scheduler, table_path,
          findings_rrd, findings_mcap, threads):
    """Audit saved logs (.rrd or .mcap): rigidity, collision momentum, resting-contact
    penetration, energy, tunneling. LOGS are files, directories (searched for logs), glob
    patterns or list files (.txt: one path per line). Every log is judged; the exit code is the
    worst over them: 0 clean, 1 flagged, 2 unreadable, 4 too short to judge (never clean)."""
    from rblog.analyze import ANALYZERS
    from rblog.study import bulk_check
    from rblog.study.cluster import Executor, dask_available, default_workers

    if list_only:
        for name, cls in ANALYZERS.items():
            click.echo(f"{name:<14} {cls.description}")
            for key, default, unit in cls.tolerance_table():
                click.echo(f"    --tol {key}={default:g}  ({unit})")
        return
    if not logs:
        raise click.UsageError("give at least one LOG (.rrd or .mcap), or --list")
    if threads is not None:
        # read by rblog.check in this process and inherited by local workers
        os.environ["RBLOG_THREADS"] = str(threads)
    names = set(ANALYZERS)
    sel_only = _names(only, names, "--only")
    sel_skip = _names(skip, names, "--skip")
    tolerances = {}
    for t in tols:
        key, eq, val = t.partition("=")
        try:
            tolerances[key.strip()] = float(val)
        except ValueError:
            _fail(RblogError(f"--tol {t}: expected ANALYZER.NAME=NUMBER"))
        if not eq or key.split(".")[0] not in names:
            _fail(RblogError(f"--tol {t}: expected ANALYZER.NAME=NUMBER with ANALYZER one of "
                             f"{', '.join(sorted(names))}"))
    try:
        paths = bulk_check.find_logs(logs)
        outs = [(o, p) for o, p in (("--rrd", findings_rrd), ("--mcap", findings_mcap)) if p]
        if outs:
            _findings_for_one_log(outs, paths, sel_only, sel_skip, tolerances)
        if workers is None and scheduler is None and len(paths) > BULK_PARALLEL_MIN_LOGS \
                and dask_available() and default_workers() > 1:
            workers = default_workers()
        ex = Executor(workers=workers, scheduler=scheduler)
        prog = _Progress(enabled=sys.stderr.isatty() and len(paths) > 1, label="checking")
        try:
            with ex:
                report = bulk_check.check_many(paths, ex, only=sel_only, skip=sel_skip,
                                               tolerances=tolerances, on_done=prog)
        finally:
            prog.close()
        if table_path:
            bulk_check.write_table(report.entries, table_path)
    except RblogError as e:
        _fail(e)
    many = len(paths) > BULK_DETAIL_MAX_LOGS
    for e in report.entries:
        if e["status"] in ("unreadable", "failed"):
            click.echo(f"rblog: error: {e['error']}", err=True)
            continue
        for w in e["warnings"]:
            click.echo(f"rblog: warning: {e['log']}: {w}", err=True)
        if not as_json and (not many or e["status"] != "clean"):
            print_report(e)
    if as_json:
        click.echo(json.dumps(report.to_dict(), indent=1))
    elif len(paths) > 1:
        if many:
            click.echo(f"(clean logs not shown: more than {BULK_DETAIL_MAX_LOGS}; see --table or --json)")
        click.echo(bulk_check.format_summary(report))
    if table_path:
        click.echo(f"wrote {table_path}", err=as_json)
    sys.exit(report.exit_code)


def _findings_for_one_log(outs, paths, only, skip, tolerances):
    """--rrd / --mcap: the one log and its findings, checked here, in one file per option (the
    report itself comes from the bulk check, which may run elsewhere)."""
    from rblog.analyze import check as run_checks
    from rblog.record.findings import open_command, write_checked
    from rblog.record.reader import load

    for opt, out in outs:
        want = ".rrd" if opt == "--rrd" else ".mcap"
        if not out.endswith(want):
            _fail(RblogError(f"{opt} {out}: expected a file name ending in {want}"))
        if len(paths) != 1:
            _fail(RblogError(f"{opt} {out}: give exactly one LOG (got {len(paths)})"))
        if Path(out).resolve() == Path(paths[0]).resolve():
            _fail(RblogError(f"{opt} {out}: that is the checked log itself; name another file"))
    try:
        traj = load(paths[0])
    except RblogError:
        return  # reported as unreadable by the check itself
    results = run_checks(traj, only=only, skip=skip, tolerances=tolerances)
    for opt, out in outs:
        try:
            n = write_checked(out, traj, results)
        except RblogError as e:
            _fail(e)
        click.echo(f"rblog: {paths[0]} and its {n} findings written to {out} "
                   f"(open with: {open_command(out, program('rerun'))})", err=True)


def _names(csv, known, opt):
    if not csv:
        return None
    out = [n.strip() for n in csv.split(",") if n.strip()]
    bad = [n for n in out if n not in known]
    if bad:
        _fail(RblogError(f"{opt}: unknown analyzer {bad[0]!r} (expected one of "
                         f"{', '.join(sorted(known))})"))
    return out


def _recorders(scene, rrd, mcap, no_log, spawn, connect_url, mcap_compression="lz4",
               check_only=False):
    """The log writers asked for; by default SCENE-STEM.rrd and SCENE-STEM.mcap in the cwd.
    With ``check_only``, only check the outputs (same path twice, a folder that is missing or
    not writable, a viewer URL nobody listens at) and return ([], paths)."""
    if no_log and (rrd or mcap):
        raise RblogError("--no-log contradicts --rrd/--mcap")
    if not (rrd or mcap or no_log):
        stem = Path(scene).stem
        rrd, mcap = f"{stem}.rrd", f"{stem}.mcap"
    if check_only:
        import os
        from rblog.errors import LogWriteError

        if rrd and mcap and Path(rrd).resolve() == Path(mcap).resolve():
            raise RblogError(f"--rrd and --mcap name the same file {rrd!r} (expected two paths)")
        for p in (rrd, mcap):
            if not p:
                continue
            parent = Path(p).resolve().parent
            if Path(p).is_dir():
                raise LogWriteError(p, "is a directory (expected a file path)")
            if not parent.is_dir():
                raise LogWriteError(p, f"folder {str(parent)!r} does not exist")
            if not os.access(parent, os.W_OK) or (Path(p).exists() and not os.access(p, os.W_OK)):
                raise LogWriteError(p, "permission denied")
        if connect_url:
            from rblog.record.rerun_writer import check_viewer_reachable

            check_viewer_reachable(connect_url)
        return [], [p for p in (rrd, mcap) if p]
    recorders, paths = [], []
    if rrd or spawn or connect_url:
        from rblog.record.rerun_writer import RerunRecorder

        recorders.append(RerunRecorder(rrd, spawn=spawn, connect_url=connect_url))
        if rrd:
            paths.append(rrd)
    if mcap:
        from rblog.record.mcap_writer import McapRecorder

        recorders.append(McapRecorder(mcap, compression=mcap_compression))
        paths.append(mcap)
    if not recorders:  # --no-log: import no writer (the Rerun SDK alone takes ~0.3 s)
        return [], paths
    # rblog's own runs record through the public writer API too (one Recorder per writer, so the
    # run loop still writes each on its own thread; benchmarks/bench_engines.py: no cost)
    from rblog.record.recorder import Recorder

    return [Recorder(writers=[r]) for r in recorders], paths


from rblog_cli.bench_cmds import bench, stress  # noqa: E402
from rblog_cli.convert_cmds import convert, findings  # noqa: E402
from rblog_cli.diff_cmds import diff  # noqa: E402

main.add_command(bench)
main.add_command(stress)
main.add_command(diff)
main.add_command(convert)
main.add_command(findings)
from rblog_cli.cluster_cmds import sweep  # noqa: E402

main.add_command(sweep)

if __name__ == "__main__":
    main()
