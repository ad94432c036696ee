"""``rblog convert`` and ``rblog findings``: parse, call :mod:`rblog.record`, print. Registered in
cli/main.py with ``main.add_command``."""

from __future__ import annotations

import sys

import click

from rblog.errors import RblogError
from rblog_cli.report import count, program


def _fail(err: RblogError):
    click.echo(f"rblog: error: {err}", err=True)
    sys.exit(err.exit_code)


def _kind(path: str, what: str) -> str:
    for ext in (".rrd", ".mcap"):
        if path.endswith(ext):
            return ext
    raise RblogError(f"{path}: {what} must end in .rrd or .mcap")


@click.command()
@click.argument("src", type=click.Path(dir_okay=False, path_type=str))
@click.argument("dst", type=click.Path(dir_okay=False, path_type=str))
def convert(src, dst):
    """Rewrite the log SRC as DST (.rrd <-> .mcap), geometry, state and contacts included, so an
    .mcap run opens in Rerun with its shapes (and an .rrd run in Foxglove)."""
    from rblog.record import McapRecorder, RerunRecorder, load

    try:
        _kind(src, "SRC")
        kind = _kind(dst, "DST")
        traj = load(src)
        rec = RerunRecorder(dst) if kind == ".rrd" else McapRecorder(dst)
        rec.open(traj.model, traj.info)
        rec.write(traj)
        rec.close(truncated=traj.truncated)
    except RblogError as e:
        _fail(e)
    click.echo(f"{src} -> {dst}: {count(traj.n_samples, 'sample')} x "
               f"{count(traj.n_bodies, 'body')}, {count(len(traj.contacts), 'contact')}")


@click.command()
@click.argument("log", type=click.Path(dir_okay=False, path_type=str))
@click.argument("out", type=click.Path(dir_okay=False, path_type=str))
def findings(log, out):
    """Check LOG with the default tolerances and write the run with its findings to OUT: .rrd
    (one Rerun recording with the findings table and the flagged bodies marked, as `rblog check
    --rrd`) or .mcap (the run with foxglove.Log messages on /rblog/findings and markers on
    /rblog/findings/markers, for Foxglove). Exit 1 when something is flagged."""
    from rblog.analyze import check
    from rblog.record import load
    from rblog.record.findings import open_command, write_checked

    try:
        _kind(out, "OUT")
        traj = load(log)
        results = check(traj)
        n = write_checked(out, traj, results)
    except RblogError as e:
        _fail(e)
    for r in results:
        for f in r.findings:
            u = "" if f.unit in ("", "1") else f" {f.unit}"
            click.echo(f"  {r.analyzer:<12} t = {f.t:.4g} s: {f.value:.3g}{u} (tol "
                       f"{f.tolerance:.3g}{u}): {f.message}")
    click.echo(f"{log}: the run and its {n} findings written to {out} (open with: "
               f"{open_command(out, program('rerun'))})")
    sys.exit(1 if any(not r.passed and not r.skipped for r in results) else 0)
