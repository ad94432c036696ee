"""``rblog run SCENE --engine mujoco|pybullet|ode``: run a scene in another engine and record it
(:mod:`rblog.study.engines`). Called from main.py's ``run``; prints through report.py."""

from __future__ import annotations

import json

import click

from rblog.errors import RblogError
from rblog_cli.report import count, live_audit, live_report, next_commands, print_live_report


def run_with_engine(scene_path, engine, options, *, dt, duration, integrator, orthonormalize,
                    rrd, mcap, mcap_compression, no_log, log_every, log_rate, as_json, fail,
                    live_check=False, fail_fast=False):
    """Load the scene, run it in ``engine``, print the summary (like ``rblog run``)."""
    from pathlib import Path

    from rblog.engine.scene import load_scene
    from rblog.study.engines import run_engine

    if integrator or orthonormalize:
        fail(RblogError("--integrator/--orthonormalize choose rblog's integrator; with --engine "
                        "use --engine-option integrator=NAME"))
    if no_log and (rrd or mcap):
        fail(RblogError("--no-log contradicts --rrd/--mcap"))
    if not (rrd or mcap or no_log):
        stem = f"{Path(scene_path).stem}-{engine}"
        rrd, mcap = f"{stem}.rrd", f"{stem}.mcap"
    audit = None
    if live_check:
        audit = live_audit([], fail_fast, as_json)
    try:
        s = load_scene(scene_path)
        summary, _ = run_engine(s, engine, options=options, dt=dt, duration=duration,
                                log_every=log_every, log_rate=log_rate, rrd=rrd, mcap=mcap,
                                mcap_compression=mcap_compression, audit=audit)
    except RblogError as e:
        if audit is not None and audit.failed is not None and e is audit.failed:
            paths = [p for p in (rrd, mcap) if p]
            print_live_report(audit, as_json, paths=paths)
            if as_json:  # the audit stopped the run: the object still comes, status "stopped"
                click.echo(json.dumps({"status": "stopped", "message": str(e), "logs": paths,
                                       "check": live_report(audit)}))
        fail(e)
    if as_json:
        d = {"status": "ok", **summary.to_dict()}
        if audit is not None:
            d["check"] = live_report(audit)
            if d["check"]["flagged"]:
                d["status"] = "flagged"
        click.echo(json.dumps(d))
        if audit is not None and d["check"]["flagged"]:
            raise SystemExit(1)
        return
    click.echo(f"{scene_path}: {engine} {summary.version}, {count(summary.steps, 'step')} x "
               f"{count(summary.bodies, 'body')}, {summary.sim_time_s:g} s simulated in "
               f"{summary.wall_time_s:.3f} s wall "
               f"(engine stepping {summary.step_wall_s:.3f} s, recording {summary.record_wall_s:.3f} s)")
    st = summary.settings
    click.echo(f"  integrator {st.get('integrator')}, dt {summary.dt:g} s, logged every "
               f"{summary.log_every} steps ({summary.samples} samples, {summary.contacts} contact rows)")
    for p in summary.logs:
        click.echo(f"  wrote {p}")
    flagged = audit is not None and print_live_report(audit, as_json, paths=summary.logs)
    for i, cmd in enumerate(next_commands(summary.logs)):
        click.echo(f"{'next:' if i == 0 else '':<6}{cmd}")
    if flagged:
        raise SystemExit(1)
