"""``rblog diff A B``: parse, call :mod:`rblog.analyze.diff`, print. Registered in cli/main.py."""

from __future__ import annotations

import json
import sys

import click

from rblog.analyze import tolerances as T
from rblog.errors import RblogError


def _fail(err: RblogError):
    click.echo(f"rblog: error: {err}", err=True)
    sys.exit(err.exit_code)


@click.command()
@click.argument("log_a", type=click.Path(dir_okay=False, path_type=str))
@click.argument("log_b", type=click.Path(dir_okay=False, path_type=str))
@click.option("--position-tol", type=click.FloatRange(min=0), default=T.DIFF_POSITION_M,
              show_default=True, help="Tolerance on |x_A - x_B| per body (m).")
@click.option("--angle-tol", type=click.FloatRange(min=0), default=T.DIFF_ANGLE_RAD,
              show_default=True, help="Tolerance on the orientation angle between the logs (rad).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as one JSON document.")
@click.option("--png", type=click.Path(dir_okay=False, path_type=str),
              help="Write a plot of the divergence over time here.")
def diff(log_a, log_b, position_tol, angle_tol, as_json, png):
    """Compare two logs of the same scene (another engine, integrator, dt or version): per-body
    position and orientation divergence, when each body leaves the tolerance, growth rate, and
    totals side by side. Exit 0 within tolerance, 1 when not, 2 on unreadable or incompatible
    logs."""
    from rblog.analyze.diff import diff as run_diff, format_table, plot
    from rblog.record.reader import load

    try:
        a, b = load(log_a), load(log_b)
        report = run_diff(a, b, position_tol_m=position_tol, angle_tol_rad=angle_tol,
                          label_a=log_a, label_b=log_b)
    except RblogError as e:
        _fail(e)
    if png:
        try:
            plot(report, png)
        except ImportError as e:
            _fail(RblogError(f"--png {png}: needs matplotlib ({e}); pip install -e \".[bench]\" "
                             "in a checkout (or pip install \"rblog[bench]\")"))
        except OSError as e:
            _fail(RblogError(f"--png {png}: cannot write ({e.strerror or e})"))
    if as_json:
        d = report.to_dict()
        if png:
            d["png"] = png
        click.echo(json.dumps(d, indent=1))
    else:
        click.echo(format_table(report))
        if png:
            click.echo(f"wrote {png}")
    sys.exit(0 if report.within else 1)
