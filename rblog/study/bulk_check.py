"""``rblog check`` on many logs: every log judged, one entry per log, in the order given.

:func:`find_logs` expands what the user named (files, directories, glob patterns, list files)
into log paths; :func:`check_log` judges one log and never raises for a bad log (an unreadable
one is an entry with ``status = "unreadable"``); :func:`check_many` runs :func:`check_log` over
the paths through a :class:`~rblog.study.cluster.Executor` (serial, local cluster or running
scheduler). The entries are the same whichever executor ran them: :func:`check_log` is the only
code that produces them, and the executor returns them in input order.

An entry (JSON-able)::

    {"log": path, "status": "clean" | "truncated" | "flagged" | "not judged" | "unreadable" | "failed",
     "samples", "bodies", "truncated", "t_end_s", "warnings": [...],
     "results": [Result.to_dict(model), ...]}          # readable logs
    {"log": path, "status": "unreadable" | "failed", "error": one line}   # the others

``truncated``: nothing flagged, but the log stops before the run's end (an interrupted or
stopped run): clean only up to there, so never counted as clean. ``failed``: the worker process
died under the log twice (see rblog.study.cluster).

Exit code of a batch (:func:`exit_code`): the worst over its logs, 0 clean or truncated <
1 flagged < 2 unreadable or failed < 4 not judged.
"""

from __future__ import annotations

import csv
import glob
import os
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Callable, Sequence

from rblog.errors import RblogError

#: suffixes of the logs a directory is searched for
LOG_SUFFIXES = (".rrd", ".mcap")
#: suffixes of list files (one log path per line; blank lines and '#' comments ignored; relative
#: paths are relative to the list file's directory)
LIST_SUFFIXES = (".txt", ".list", ".lst")
#: exit code of each status; a batch exits with the largest
STATUS_EXIT = {"clean": 0, "truncated": 0, "flagged": 1, "unreadable": 2, "failed": 2, "not judged": 4}
#: the fewest samples an audit can judge (drifts and rates need two); a shorter log is
#: "not judged" (exit 4), never "clean"
MIN_SAMPLES_TO_JUDGE = 2
#: columns of the per-log table besides the per-analyzer ones
TABLE_COLUMNS = ("log", "status", "samples", "bodies", "truncated", "t_end_s", "warnings", "error")


def find_logs(specs: Sequence[str]) -> list[str]:
    """Expand the names given on the command line into log paths, in the order given.

    * a directory: every ``.rrd``/``.mcap`` file below it (recursively), sorted;
    * a pattern with ``*``, ``?`` or ``[``: its matches (``**`` recurses), sorted;
    * a file ending in ``.txt``/``.list``/``.lst``: the paths it lists;
    * anything else: taken as a log path as is (a missing one is reported as unreadable).

    Raises RblogError when a directory holds no log, a pattern matches nothing, or a list file
    cannot be read.
    """
    out: list[str] = []
    for spec in specs:
        p = Path(spec)
        if p.is_dir():
            found = sorted(str(q) for q in p.rglob("*") if q.suffix.lower() in LOG_SUFFIXES and q.is_file())
            if not found:
                raise RblogError(f"{spec}: directory holds no .rrd or .mcap log")
            out += found
        elif any(c in spec for c in "*?[") and not p.exists():
            found = sorted(glob.glob(spec, recursive=True))
            found = [f for f in found if not Path(f).is_dir()]
            if not found:
                raise RblogError(f"{spec}: pattern matches no file")
            out += found
        elif p.suffix.lower() in LIST_SUFFIXES and p.is_file():
            try:
                lines = p.read_text(encoding="utf-8").splitlines()
            except (OSError, UnicodeDecodeError) as e:
                raise RblogError(f"{spec}: cannot read list file: {e}") from None
            for line in lines:
                line = line.split("#", 1)[0].strip()
                if line:
                    q = Path(line)
                    out.append(str(q if q.is_absolute() else p.parent / q))
        else:
            out.append(spec)
    return out


def check_log(path: str, only=None, skip=None, tolerances: dict | None = None) -> dict:
    """Load and audit one log; the entry described in the module docstring. Never raises for a
    log that cannot be read (``status = "unreadable"``)."""
    from rblog.analyze import check
    from rblog.record.reader import load

    try:
        traj = load(path)
        results = check(traj, only=only, skip=skip, tolerances=tolerances)
    except RblogError as e:
        return {"log": path, "status": "unreadable", "error": str(e)}
    flagged = any(r.verdict == "FAIL" for r in results)
    warns = list(traj.warnings)
    status = "flagged" if flagged else "clean"
    if not flagged and traj.n_samples < MIN_SAMPLES_TO_JUDGE:
        status = "not judged"
        warns.append(f"not judged: {traj.n_samples} sample(s), an audit needs at least "
                     f"{MIN_SAMPLES_TO_JUDGE}")
    elif not flagged and any(r.verdict == "not judged" for r in results):
        status = "not judged"
    elif not flagged and traj.truncated:
        status = "truncated"
    from rblog.analyze.contents import log_contents

    return {"log": path, "status": status, "contents": log_contents(traj),
            "samples": traj.n_samples, "bodies": traj.n_bodies, "truncated": traj.truncated,
            "t_end_s": float(traj.t[-1]) if traj.n_samples else 0.0,
            "warnings": warns,
            "results": [r.to_dict(traj.model) for r in results]}


@dataclass
class BulkReport:
    """What :func:`check_many` found: ``entries`` in the order of the paths."""

    entries: list[dict]
    executor: str = ""
    wall_s: float = 0.0
    analyzers: list[str] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        return exit_code(self.entries)

    def to_dict(self) -> dict:
        return {"logs": self.entries, "passed": self.exit_code == 0}

    def summary(self) -> dict:
        """``{"logs": {status: count}, "analyzers": {name: {"pass", "FAIL", "skip"}}}``."""
        return summarize(self.entries)


def check_many(paths: Sequence[str], executor=None, *, only=None, skip=None,
               tolerances: dict | None = None,
               on_done: Callable[[int, int], None] | None = None) -> BulkReport:
    """Audit every log of ``paths`` through ``executor`` (default: serial in this process).

    The analyzer options are validated once here (a bad one raises CheckOptionError before any
    log is read). A log whose worker died twice becomes an entry with ``status = "failed"``.
    """
    import time

    from rblog.analyze import ANALYZERS, split_tolerances
    from rblog.study.cluster import Executor, TaskFailure

    split_tolerances(tolerances)
    ex = executor or Executor()
    fn = partial(check_log, only=only, skip=skip, tolerances=tolerances)
    t0 = time.perf_counter()
    with _started(ex):
        out = ex.map(fn, list(paths), on_done=on_done, chunked=True)
    entries = []
    for path, r in zip(paths, out):
        if isinstance(r, TaskFailure):
            r = {"log": path, "status": "failed",
                 "error": f"{path}: not checked: {r.error} (after {r.tries} tries)"}
        entries.append(r)
    names = [n for n in ANALYZERS if (not only or n in only) and n not in (skip or ())]
    return BulkReport(entries, ex.describe(), time.perf_counter() - t0, names)


class _started:
    """Start the executor if the caller did not (and close it again afterwards)."""

    def __init__(self, ex):
        self.ex, self.own = ex, ex.client is None and not ex.serial

    def __enter__(self):
        if self.own:
            self.ex.start()

    def __exit__(self, *exc):
        if self.own:
            self.ex.close()


def exit_code(entries: Sequence[dict]) -> int:
    """The worst exit code over the entries (0 when there are none)."""
    return max((STATUS_EXIT[e["status"]] for e in entries), default=0)


def _verdict(r: dict) -> str:
    """A result's verdict (Result.verdict) from its dict."""
    if "verdict" in r:
        return r["verdict"]
    return "skip" if r["skipped"] else ("pass" if r["passed"] else "FAIL")


def summarize(entries: Sequence[dict]) -> dict:
    logs = {s: 0 for s in STATUS_EXIT}
    per: dict[str, dict[str, int]] = {}
    for e in entries:
        logs[e["status"]] += 1
        for r in e.get("results", ()):
            v = _verdict(r)
            per.setdefault(r["analyzer"], {"pass": 0, "FAIL": 0, "skip": 0,
                                           "not judged": 0})[v] += 1
    return {"logs": logs, "analyzers": per}


def table_rows(entries: Sequence[dict]) -> tuple[list[str], list[dict]]:
    """The per-log table: :data:`TABLE_COLUMNS`, then for each analyzer ``<name>`` (pass, FAIL,
    skip), ``<name>_worst`` (its worst value, in ``<name>_unit``) and ``<name>_tol``."""
    names: list[str] = []
    for e in entries:
        for r in e.get("results", ()):
            if r["analyzer"] not in names:
                names.append(r["analyzer"])
    cols = list(TABLE_COLUMNS) + [f"{n}{s}" for n in names for s in ("", "_worst", "_tol", "_unit")]
    rows = []
    for e in entries:
        row = {c: None for c in cols}
        row.update(log=e["log"], status=e["status"], error=e.get("error"),
                   samples=e.get("samples"), bodies=e.get("bodies"), truncated=e.get("truncated"),
                   t_end_s=e.get("t_end_s"),
                   warnings=len(e["warnings"]) if "warnings" in e else None)
        for r in e.get("results", ()):
            n = r["analyzer"]
            row[n] = _verdict(r)
            if not r["skipped"]:
                row[f"{n}_worst"], row[f"{n}_tol"] = r["worst_value"], r["tolerance"]
                row[f"{n}_unit"] = r["unit"]
        rows.append(row)
    return cols, rows


def write_table(entries: Sequence[dict], path: str | os.PathLike) -> str:
    """Write the per-log table as Parquet (``.parquet``) or CSV (anything else); returns the
    path. Raises RblogError when it cannot be written."""
    cols, rows = table_rows(entries)
    path = str(path)
    try:
        if path.lower().endswith((".parquet", ".pq")):
            import pyarrow as pa
            import pyarrow.parquet as pq

            pq.write_table(pa.Table.from_pylist(rows), path)
        else:
            with open(path, "w", newline="", encoding="utf-8") as f:
                w = csv.DictWriter(f, fieldnames=cols)
                w.writeheader()
                for r in rows:
                    w.writerow({k: ("" if v is None else v) for k, v in r.items()})
    except OSError as e:
        raise RblogError(f"{path}: cannot write table: {e.strerror or e}") from None
    return path


def format_summary(report: BulkReport) -> str:
    """The summary table: logs by status, then each analyzer's pass / FAIL / skip counts."""
    s = report.summary()
    n = len(report.entries)
    lines = [f"{n} logs: {s['logs']['clean']} clean, {s['logs']['flagged']} flagged, "
             f"{s['logs']['unreadable']} unreadable"
             + (f", {s['logs']['truncated']} truncated (clean up to where the log stops)"
                if s["logs"]["truncated"] else "")
             + (f", {s['logs']['failed']} failed (worker died)" if s["logs"]["failed"] else "")
             + (f", {s['logs']['not judged']} not judged" if s["logs"]["not judged"] else "")
             + f"  [{report.executor}, {report.wall_s:.2f} s]"]
    if s["analyzers"]:
        lines.append(f"  {'analyzer':<14}{'pass':>7}{'FAIL':>7}{'skip':>7}{'not judged':>12}")
        for name, c in s["analyzers"].items():
            lines.append(f"  {name:<14}{c['pass']:>7}{c['FAIL']:>7}{c['skip']:>7}"
                         f"{c['not judged']:>12}")
    return "\n".join(lines)
