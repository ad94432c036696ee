"""``rblog sweep``: parse, call :mod:`rblog.study.sweep` on a :class:`rblog.study.cluster.Executor`,
print. Registered in cli/main.py with ``main.add_command``. Also the ``--workers``/``--scheduler``
options every bulk command shares (:func:`executor_options`, :func:`make_executor`)."""

from __future__ import annotations

import shlex
import sys

import click

from rblog.errors import RblogError


def _fail(err: RblogError):
    click.echo(f"rblog: error: {err}", err=True)
    sys.exit(err.exit_code)


def executor_options(fn):
    """Add ``--workers N`` and ``--scheduler ADDRESS`` to a command."""
    fn = click.option("--scheduler", metavar="ADDRESS",
                      help="Run on a running dask.distributed scheduler (tcp://host:8786).")(fn)
    fn = click.option("--workers", type=click.IntRange(min=0),
                      help="Run on a local Dask cluster of N worker processes (0 or unset: in "
                           "this process).")(fn)
    return fn


def make_executor(workers, scheduler):
    from rblog.study.cluster import Executor

    return Executor(workers=workers, scheduler=scheduler)


class _Bar:
    """A rich progress bar on stderr (only when stderr is a terminal)."""

    def __init__(self, label: str, enabled: bool):
        self.label, self.enabled, self.bar = label, enabled, None

    def __call__(self, done: int, total: int):
        if not self.enabled:
            return
        if self.bar is None:
            from rich.console import Console
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

            self.bar = Progress(TextColumn(self.label), BarColumn(), MofNCompleteColumn(),
                                TimeRemainingColumn(), console=Console(stderr=True), transient=True)
            self.bar.start()
            self.task = self.bar.add_task("run", total=total)
        self.bar.update(self.task, completed=done)

    def close(self):
        if self.bar is not None:
            self.bar.stop()


@click.command()
@click.argument("scene", type=click.Path(dir_okay=False, path_type=str))
@click.option("--set", "sets", multiple=True, metavar="KEY=V1,V2,...|KEY=LO:HI",
              help="Vary a scene key: a list (grid) or a range (random, needs --samples). Keys: "
                   "dt, duration, integrator, orthonormalize, sim.*, ground.*, body[k].*, "
                   "body[*].* (every body), vector components as key[i]. Repeatable.")
@click.option("--samples", type=click.IntRange(min=1),
              help="Draw N random variants (lists: one value each, ranges: uniform) instead of "
                   "the grid.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the random draws.")
@click.option("--out", "out_dir", default="rblog-sweep", show_default=True,
              type=click.Path(file_okay=False, path_type=str),
              help="Directory for sweep.json/.csv/.parquet/.png and logs/.")
@click.option("--no-logs", is_flag=True, help="Write no logs: only the results table and the check.")
@click.option("--no-check", is_flag=True, help="Do not run the analyzers on each variant.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON on stdout.")
@executor_options
def sweep(scene, sets, samples, seed, out_dir, no_logs, no_check, as_json, workers, scheduler):
    """Run a grid or a random sample of variants of SCENE (each on the cluster when --workers or
    --scheduler is given) and write one results table: parameters, run time, errors against the
    exact answer where one exists, the check's verdict; and a plot of error against cost."""
    import json

    from rblog.study.sweep import format_table, run_sweep, write_outputs

    bar = _Bar("sweep", sys.stderr.isatty())
    try:
        ex = make_executor(workers, scheduler)
        with ex:
            report = run_sweep(scene, sets, samples=samples, seed=seed, executor=ex,
                               out_dir=out_dir, write_logs=not no_logs, check=not no_check,
                               on_done=bar, command=_command())
        bar.close()
        files = write_outputs(report, out_dir)
    except RblogError as e:
        bar.close()
        _fail(e)
    if as_json:
        click.echo(json.dumps(report.to_dict()))
    else:
        click.echo(format_table(report))
        for kind, path in files.items():
            click.echo(f"wrote {path}")
    bad = any(r["status"] != "ok" or r.get("check") == "flagged" for r in report.rows)
    sys.exit(1 if bad else 0)


def _command() -> str:
    return "rblog " + " ".join(shlex.quote(a) for a in sys.argv[1:])
