"""``rblog bench`` and ``rblog stress``: parse, call :mod:`rblog.study.bench` / :mod:`rblog.study.stress`,
print. Registered in cli/main.py with ``main.add_command``."""

from __future__ import annotations

import json
import shlex
import sys

import click

from rblog.errors import RblogError
from rblog_cli.cluster_cmds import executor_options as _executor_options
from rblog_cli.cluster_cmds import make_executor as _make_executor


def _fail(err: RblogError):
    click.echo(f"rblog: error: {err}", err=True)
    sys.exit(err.exit_code)


def _note(text: str):
    """A one-line note on stderr before any work (what is missing and how to install it)."""
    if text:
        click.echo(f"rblog: note: {text}", err=True)


def _progress(enabled: bool):
    if not enabled:
        return None
    return lambda msg: click.echo(f"  {msg}", err=True)


def _command() -> str:
    return "rblog " + " ".join(shlex.quote(a) for a in sys.argv[1:])


@click.command()
@click.option("--quick", is_flag=True, help="Small study (under a minute): 3 time steps.")
@click.option("--out", "out_dir", default="rblog-bench", show_default=True,
              type=click.Path(file_okay=False, path_type=str),
              help="Directory for bench.json, bench.csv and bench.png.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON on stdout.")
@click.option("--problem", "problems", multiple=True,
              help="Run only this reference problem (repeatable).")
@click.option("--integrator", "integrators", multiple=True,
              help="Run only this integrator, NAME or NAME/ORTHONORMALIZE (repeatable).")
@click.option("--dt", "dts", multiple=True, type=click.FloatRange(min=0, min_open=True),
              help="Time step to run (s, repeatable); overrides the default range.")
@click.option("--peer", "peers", multiple=True, type=click.Choice(["mujoco", "pybullet", "ode"]),
              help="Run only these peers (default: every one installed).")
@click.option("--no-peers", is_flag=True, help="Run rblog only.")
@click.option("--progress/--no-progress", default=None,
              help="Print each run on stderr (default: when stderr is a terminal).")
@_executor_options
def bench(quick, out_dir, as_json, problems, integrators, dts, peers, no_peers, progress, workers,
          scheduler):
    """Work-precision study: every integrator x a range of dt on problems with exact answers."""
    from rblog.study.bench import format_table, missing_dependencies, run_bench, write_outputs
    from rblog.study.reference import PROBLEMS

    for p in problems:
        if p not in PROBLEMS:
            _fail(RblogError(f"--problem: unknown problem {p!r} (expected one of: "
                             f"{', '.join(PROBLEMS)})"))
    _check_integrators(integrators)
    _note(missing_dependencies(problems or None, what="bench.png"))
    if not no_peers:
        from rblog.study.bench import module_missing
        from rblog.study.peers import PEER_NAMES

        gone = [p for p in (peers or PEER_NAMES) if module_missing(p)]
        if gone:
            _note(f"{' and '.join(gone)} not installed: no peer runs of {', '.join(gone)}. To "
                  'compare against them: pip install -e ".[engines]"')
    show = sys.stderr.isatty() if progress is None else progress
    _run_and_print(lambda ex: run_bench(quick=quick, problems=problems or None,
                                        integrators=integrators or None, dts=dts or None,
                                        peers=() if no_peers else (peers or None),
                                        progress=_progress(show), command=_command(), executor=ex),
                   workers, scheduler, write_outputs, format_table, out_dir, as_json)


@click.command()
@click.option("--quick", is_flag=True, help="Small suite for CI (seconds once compiled).")
@click.option("--out", "out_dir", default="rblog-stress", show_default=True,
              type=click.Path(file_okay=False, path_type=str),
              help="Directory for stress.json and stress.png.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON on stdout.")
@click.option("--case", "cases", multiple=True, help="Run only this case (repeatable).")
@click.option("--integrator", "integrators", multiple=True,
              help="Run only this integrator, NAME or NAME/ORTHONORMALIZE (repeatable).")
@click.option("--progress/--no-progress", default=None,
              help="Print each run on stderr (default: when stderr is a terminal).")
@_executor_options
def stress(quick, out_dir, as_json, cases, integrators, progress, workers, scheduler):
    """Stability suite: fast spin, extreme inertia, long runs, dt up to instability, impacts,
    stacks, many bodies, mass ratios. A blow-up is reported, never fatal."""
    from rblog.study.bench import BENCH_EXTRA, PLOT_MODULE, module_missing
    from rblog.study.stress import CASE_NAMES, format_table, run_stress, write_outputs

    for c in cases:
        if c not in CASE_NAMES:
            _fail(RblogError(f"--case: unknown case {c!r} (expected one of: {', '.join(CASE_NAMES)})"))
    _check_integrators(integrators)
    if module_missing(PLOT_MODULE):
        _note(f"{PLOT_MODULE} is not installed: no stress.png. To draw it: {BENCH_EXTRA}")
    show = sys.stderr.isatty() if progress is None else progress
    _run_and_print(lambda ex: run_stress(quick=quick, cases=cases or None,
                                         integrators=integrators or None,
                                         progress=_progress(show), command=_command(), executor=ex),
                   workers, scheduler, write_outputs, format_table, out_dir, as_json)


def _run_and_print(run, workers, scheduler, write_outputs, format_table, out_dir, as_json):
    """Run a suite (``run(executor)`` -> report) on the executor asked for, write its files, and
    print the report (a table, or JSON with ``as_json``) and the files written."""
    try:
        with _make_executor(workers, scheduler) as ex:
            report = run(ex)
        write_outputs(report, out_dir)
    except RblogError as e:
        _fail(e)
    if as_json:
        click.echo(json.dumps(report.to_dict()))
        return
    click.echo(format_table(report))
    click.echo("")
    for path in report.files.values():
        click.echo(f"wrote {path}")


def _check_integrators(specs):
    from rblog.engine.integrators import ORTHO_ALLOWED

    for spec in specs:
        name, _, ortho = spec.partition("/")
        if name not in ORTHO_ALLOWED:
            _fail(RblogError(f"--integrator: unknown integrator {name!r} (expected one of: "
                             f"{', '.join(ORTHO_ALLOWED)})"))
        if ortho and ortho not in ORTHO_ALLOWED[name][0]:
            _fail(RblogError(f"--integrator: {name} takes orthonormalize "
                             f"{' or '.join(ORTHO_ALLOWED[name][0])}, got {ortho!r}"))
