"""What the CLI prints about audits: the report of `rblog check` on one log (a line per
analyzer, the findings, the verdict line), the live audit of `rblog run --check` and its JSON,
and the commands to run next, spelled so that they work as printed. Used by main.py and
engine_cmds.py (which import this module, never each other)."""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import click


def count(n: int, noun: str) -> str:
    """``n`` and ``noun`` for a report line: "1 body", "21 bodies", "1 sample", "401 samples"."""
    if n == 1:
        return f"1 {noun}"
    return f"{n} " + (noun[:-1] + "ies" if noun.endswith("y") else noun + "s")


def program(name: str) -> str:
    """How to call the program ``name`` from the current folder: its bare name when the shell
    finds this installation's copy on PATH, else its path beside the ``rblog`` that was typed
    (``.venv/bin/rerun`` after ``.venv/bin/rblog run ...`` in a venv that is not activated), or
    beside this Python."""
    typed = sys.argv[0]
    if os.sep in typed and Path(typed).name == "rblog":
        beside = Path(typed).with_name(name)
    else:
        beside = Path(sys.executable).with_name(name)
    found = shutil.which(name)
    if not beside.exists() or (found and Path(found).resolve() == beside.resolve()):
        return name
    if not beside.is_absolute():
        return str(beside)
    rel = os.path.relpath(beside)
    return rel if not rel.startswith("..") else str(beside)


def next_commands(paths) -> list[str]:
    """The two commands a user runs after `rblog run`: audit the log, open it in a viewer."""
    if not paths:
        return []
    rrd = [p for p in paths if str(p).endswith(".rrd")]
    log = rrd[0] if rrd else paths[0]
    see = f"{program('rerun')} {log}" if rrd else f"open {log} in Foxglove (app.foxglove.dev)"
    return [f"{program('rblog')} check {log}", see]


def live_audit(recorders, fail_fast: bool, as_json: bool):
    """The live audit for `rblog run --check` (rblog.record.live_audit), streaming into the
    Rerun log of ``recorders`` and printing each finding when announced (stderr with --json)."""
    from rblog.record.live_audit import LiveAudit
    from rblog.record.rerun_writer import RerunRecorder

    rerun = [w for r in recorders for w in getattr(r, "writers", [r])
             if isinstance(w, RerunRecorder)]
    audit = None

    def echo(lf):
        from rblog.record.live_audit import live_text

        if lf.at_end:
            return  # the end report lists them
        click.echo(f"live (seen at t = {lf.t_seen:.6g} s): {live_text(audit.model, lf)}",
                   err=as_json)

    audit = LiveAudit(fail_fast=fail_fast, on_finding=echo, rerun=rerun)
    return audit


def live_report(audit) -> dict:
    """The live audit's verdict as JSON: ``results`` (as `rblog check --json`), ``announced``
    (each finding with when it was announced), ``revised``, ``withdrawn``, ``flagged``."""
    results = audit.finish()
    model = audit.model
    return {
        "flagged": any(not r.passed and not r.skipped for r in results),
        "results": [r.to_dict(model) for r in results],
        "announced": [{**lf.finding.to_dict(), "at_end": lf.at_end, "seen_samples": lf.samples,
                       "seen_t_s": lf.t_seen, "wall_s": lf.wall_s} for lf in audit.announced],
        "revised": len(audit.live.revised), "withdrawn": len(audit.live.withdrawn),
        "prefix_checks": audit.stats.checks, "audit_s": audit.stats.total_s,
    }


def print_live_report(audit, as_json: bool, paths=()) -> bool:
    """Print the live audit's verdict (the report of `rblog check` on the log); returns True
    when the run is flagged."""
    results = audit.finish()
    traj = audit.live.trajectory
    flagged = any(not r.passed and not r.skipped for r in results)
    if as_json:
        return flagged
    live = audit.live
    during = sum(not lf.at_end for lf in live.announced)
    n = sum(len(r.findings) for r in results)
    click.echo(f"live audit: {n} finding(s), {during} announced during the run, "
               f"{len(live.announced) - during} at its end; {live.stats.checks} prefix checks")
    for lf, f in live.revised:
        click.echo(f"  revised at the end ({lf.analyzer}, step {lf.finding.step} -> {f.step}): "
                   f"{f.message}")
    for lf in live.withdrawn:
        click.echo(f"  withdrawn at the end ({lf.analyzer}, step {lf.finding.step}): "
                   f"{lf.finding.message}")
    if traj is not None:
        from rblog.analyze.contents import log_contents

        print_report({"log": ", ".join(paths) or "(run)", "truncated": bool(audit.failed),
                      "contents": log_contents(traj),
                      "status": "flagged" if flagged else "clean",
                       "samples": traj.n_samples, "bodies": traj.n_bodies,
                       "t_end_s": float(traj.t[-1]) if traj.n_samples else 0.0,
                       "results": [r.to_dict(traj.model) for r in results]})
    return flagged


#: findings listed per analyzer in a report (the rest counted; all of them are in --json)
REPORT_FINDINGS_SHOWN = 5


def _num(x, spec):
    """x formatted by spec; a non-finite figure (inf or NaN) arrives from the JSON-safe entry as
    None."""
    return "not finite" if x is None else format(x, spec)


def print_report(entry):
    """One log's report from its entry (rblog.study.bulk_check.check_log): a header, one line
    per analyzer, the findings of each flagged one, and the log's verdict line."""
    flag = " (truncated)" if entry["truncated"] else ""
    click.echo(f"{entry['log']}: {count(entry['samples'], 'sample')} x "
               f"{count(entry['bodies'], 'body')}, "
               f"t = 0..{entry['t_end_s']:g} s{flag}")
    if entry.get("contents"):
        from rblog.analyze.contents import contents_line

        click.echo(f"  contents: {contents_line(entry['contents'])}")
    for r in entry["results"]:
        verdict = {"skip": "skip", "not judged": "----", "FAIL": "FAIL"}.get(r["verdict"], "pass")
        click.echo(f"  {verdict:<4} {r['analyzer']:<12} {_worst_text(r)}")
        for f in r["findings"][:REPORT_FINDINGS_SHOWN]:
            u = _unit(f["unit"])
            click.echo(f"         t = {_num(f['t'], '.4g')} s: {_num(f['value'], '.3g')}{u} (tol "
                       f"{_num(f['tolerance'], '.3g')}{u}): {f['message']}")
        more = int(r["stats"].get("findings", len(r["findings"]))) - REPORT_FINDINGS_SHOWN
        if more > 0:
            click.echo(f"         ... and {more} more (all of them: rblog check --json)")
        if r["verdict"] == "pass":
            for line in r["not_judged"]:
                click.echo(f"         not judged: {line}")
        for line in motion_lines(r):
            click.echo(f"         {line}")
    click.echo(f"  verdict: {verdict_line(entry)}")


#: rolling and sliding stretches listed per analyzer in a report (the rest counted)
REPORT_MOTION_SHOWN = 2


def motion_lines(r: dict) -> list[str]:
    """The penetration analyzer's rolling and sliding stretches (events, not findings): per kind
    a count line, then the first REPORT_MOTION_SHOWN stretches as the analyzer words them."""
    out = []
    for kind in ("rolling", "sliding"):
        n = int(r["stats"].get(f"{kind}_stretches", 0))
        if not n:
            continue
        total = r["stats"].get(f"{kind}_duration_total_s", 0.0)
        slip = r["stats"].get(f"{kind}_slip_max_mps")
        up = "nan" if slip is None else (f"{slip * 1e3:.3g} mm/s" if slip < 0.1 else
                                         f"{slip:.3g} m/s")
        out.append(f"{kind}: {n} stretch{'es' if n != 1 else ''} ({total:.3g} s, slip up to "
                   f"{up}): events, not judged as resting")
        shown = [e for e in r.get("events", ()) if e.get("kind") == kind][:REPORT_MOTION_SHOWN]
        out += [f"  {e['text']}" for e in shown]
        if n > len(shown):
            out.append(f"  ... and {n - len(shown)} more (rblog check --json lists them)")
    return out


def _unit(unit: str) -> str:
    return "" if unit in ("", "1") else f" {unit}"


def _worst_text(r: dict) -> str:
    """An analyzer's line: the quantity nearest its tolerance, with that quantity's own
    tolerance; the reason where no number says more (skip, not judged, no quantity)."""
    if r["verdict"] in ("skip", "not judged"):
        return r["reason"]
    if r["verdict"] == "FAIL":
        n = int(r["stats"].get("findings", len(r["findings"])))
        return f"{n} finding{'s' if n != 1 else ''}"
    what, value, tol = r.get("worst_what", ""), r["worst_value"], r["tolerance"]
    if not what or value is None or r["worst_t"] is None:
        return r["reason"]
    u = _unit(r["unit"])
    if value <= 0:  # nothing came near: a residual of exactly 0, or a gain never above zero
        if tol == 0:
            return r["reason"]
        level = f"{what} 0" if value == 0 else f"{what}: none above 0"
        return f"{level} (tol {tol:.3g}{u})"
    limit = "any above 0 is flagged" if tol == 0 else f"tol {tol:.3g}{u}"
    text = f"{what} {value:.3g}{u} ({limit}) at t = {r['worst_t']:.4g} s"
    bodies = r["worst_bodies"]
    if bodies:
        names = r.get("worst_body_names") or [str(b) for b in bodies]
        shown = ", ".join(n if b >= 0 else "static" for b, n in zip(bodies[:3], names))
        text += f" [{shown}{f' +{len(bodies) - 3}' if len(bodies) > 3 else ''}]"
    return text


def verdict_line(entry: dict) -> str:
    """``clean``, ``flagged: N findings (...)`` or ``not judged: why`` for one log's entry; a
    truncated log is clean only up to where it stops, and says so."""
    results = entry.get("results", ())
    counts = {r["analyzer"]: int(r["stats"].get("findings", len(r["findings"])))
              for r in results if r["verdict"] == "FAIL"}
    if entry["status"] == "flagged" or counts:
        n = sum(counts.values())
        per = ", ".join(f"{a} {k}" for a, k in counts.items())
        return f"flagged: {n} finding{'s' if n != 1 else ''} ({per})"
    if entry["status"] == "not judged":
        why = [r["reason"].removeprefix("not judged: ") for r in results
               if r["verdict"] == "not judged"]
        why += [w.removeprefix("not judged: ") for w in entry.get("warnings", ())
                if w.startswith("not judged")]
        return "not judged: " + ("; ".join(dict.fromkeys(why)) or "nothing could be judged")
    if entry["truncated"]:
        return (f"clean up to t = {entry['t_end_s']:g} s, where the log stops (truncated: the "
                "run did not finish)")
    return "clean"


