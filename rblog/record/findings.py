"""`rblog check` findings where a user looks: in the Rerun viewer and in Foxglove.

:func:`write_checked` writes ONE file that holds the run and its findings, so that one command
opens both: ``rerun checked.rrd`` or Foxglove on ``checked.mcap``. The run is re-recorded from the
loaded trajectory through the ordinary writers (rblog.record.rerun_writer / mcap_writer), whatever
format the checked log was, and the findings are added to the same recording.

In Rerun (:func:`log_findings`):

* ``findings/<analyzer>`` (``TextLog``): one row per finding at its onset (Finding.onset_t: where
  a growing problem began; else the finding's time) on ``sim_time`` and ``step``, text ``ANALYZER | BODIES | value V vs limit L UNIT | message``; the findings table of
  the layout shows the time and that text. Nothing is logged static on these
  entities: a static row would hide every temporal one. A clean check logs one INFO row saying so.
  The expanded time panel marks the findings' times on the ``findings`` row.
* ``world/findings/bodies`` (``Ellipsoids3D``): the offending bodies, circled by red wireframe
  spheres a little larger than themselves (bounding spheres) and labelled with the analyzer, at their logged positions over
  the finding's interval (the impact event's span, else HIGHLIGHT_S either side of the finding's
  time), cleared afterwards.
* ``world/findings/impacts`` (``Points3D``): a marker at the deepest point of every impact event
  (the momentum analyzer's events) at the event's end time, labelled with its e_eff.

* ``events/<analyzer>`` (``TextLog``, level INFO): what the analyzers saw that is no finding, one
  row per event with a text (a body rolling, pivoting or sliding on its partner, with its slip) at
  the event's start; the time panel marks them on the ``events`` row.

In MCAP (:func:`write_checked_mcap`): ``foxglove.Log`` on FINDINGS_TOPIC (Foxglove's Log panel and
its timeline) and ``foxglove.SceneUpdate`` on MARKERS_TOPIC: a red sphere on each flagged body
(locked to the body's /tf frame) with the finding's text, over the same interval as in Rerun; the
events as ``foxglove.Log`` at level INFO on EVENTS_TOPIC.

:func:`write_findings_rrd` writes the findings alone, with a given recording id: an overlay for a
run already open in a viewer (``rerun run.rrd findings.rrd`` merges the two only when the ids
match, i.e. for a run recorded to .rrd).
"""

from __future__ import annotations

import textwrap

import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import rerun as rr

from rblog.contract.model import SHAPE_SPHERE
from rblog.contract.trajectory import Trajectory
from rblog.errors import LogWriteError, RblogError
from rblog.record import _common as C

#: a finding without an interval is highlighted this long (s) either side of its time
HIGHLIGHT_S = 0.1
#: the highlight's colour (RGBA) and how much larger than the body's bounding sphere it is drawn
HIGHLIGHT_RGBA = (230, 30, 30, 220)
HIGHLIGHT_SCALE = 1.15
#: the highlight is a wireframe sphere (the body stays visible inside it): line width in points
HIGHLIGHT_LINE = rr.components.Radius.ui_points(1.5)
FINDINGS_ENTITY = "findings"
#: MCAP topics of the findings: ``foxglove.Log`` (Foxglove lists them in its Log panel and marks
#: them on the timeline, at the run's own time base) and ``foxglove.SceneUpdate`` markers
FINDINGS_TOPIC = "/rblog/findings"
#: longest line of a finding in the Rerun findings table (characters): the table spans the
#: 1600 px layout, ~7.3 px per character of the viewer's font, less the time column
FINDINGS_WRAP_CHARS = 190
MARKERS_TOPIC = "/rblog/findings/markers"
#: the analyzers' events that carry a text (Result.events[i]["text"]): Rerun entity and MCAP topic
EVENTS_ENTITY = "events"
EVENTS_TOPIC = "/rblog/events"


@dataclass
class Row:
    """One finding as the viewers show it."""

    analyzer: str
    t: float
    step: int
    bodies: list[int]
    body_names: str
    value: float
    tolerance: float
    unit: str
    message: str

    @property
    def text(self) -> str:
        u = "" if self.unit in ("", "1") else f" {self.unit}"
        return (f"{self.analyzer} | {self.body_names} | value {self.value:.4g}{u} vs limit "
                f"{self.tolerance:.4g}{u} | {self.message}")

    @property
    def lines(self) -> list[str]:
        """:attr:`text` broken into lines of at most FINDINGS_WRAP_CHARS, continuation lines
        indented: the Rerun findings table shows each as a row of its own (a row holds one line
        of text; a longer one is cut at the panel's edge)."""
        return textwrap.wrap(self.text, FINDINGS_WRAP_CHARS, subsequent_indent="    ",
                             break_on_hyphens=False)


def finding_rows(traj: Trajectory, results) -> list[Row]:
    """Every finding of ``results``, in time order (then analyzer)."""
    model = traj.model
    rows = []
    for r in results:
        for f in r.findings:
            names = [str(model.body_name[b]) if 0 <= b < model.n_bodies else "static"
                     for b in f.bodies]
            # placed at its onset: scrubbing to the row shows where the problem began
            t, step = (f.t, f.step) if f.onset_t is None else (f.onset_t, f.onset_step)
            rows.append(Row(r.analyzer, float(t), int(step), list(f.bodies),
                            ", ".join(names) or "-", float(f.value), float(f.tolerance),
                            str(f.unit), f.message))
    rows.sort(key=lambda w: (w.t, w.analyzer))
    return rows


def event_rows(results) -> list[tuple[float, int, str, str]]:
    """``(t, step, analyzer, text)`` of every event with a text, in time order: the start of a
    stretch (``t_start``, ``step_start``), else the event's ``t`` and ``step``."""
    rows = []
    for r in results:
        for e in r.events:
            if e.get("text"):
                t = e.get("t_start", e.get("t"))
                step = e.get("step_start", e.get("step", 0))
                rows.append((float(t), int(step), r.analyzer, str(e["text"])))
    rows.sort(key=lambda w: (w[0], w[2]))
    return rows


def run_recording_id(path: str) -> str | None:
    """The recording id of the run in the .rrd at ``path`` (None for other files)."""
    if not str(path).endswith(".rrd"):
        return None
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        recs = rr.chunk.RrdReader(path).recordings()
    stores = [s for s in recs if s.application_id == C.APPLICATION_ID] or recs
    return stores[0].recording_id if stores else None


def _time(rec: rr.RecordingStream, step: int, t: float):
    rec.set_time("step", sequence=int(step))
    rec.set_time("sim_time", duration=float(t))


def _impact_events(results) -> dict:
    events = {}
    for r in results:
        for e in r.events:
            if e.get("kind") == "impact":
                events[(int(e["step"]), tuple(e["bodies"]))] = e
    return events


def _spans(traj: Trajectory, rows: list[Row], events: dict) -> list[tuple[int, int, list, str]]:
    """(first sample, last sample, bodies, analyzer) of each finding's highlight."""
    t = np.asarray(traj.t, float)
    out = []
    for w in rows:
        ev = events.get((w.step, tuple(w.bodies)))
        t0, t1 = (ev["t_start"], ev["t_end"]) if ev else (w.t - HIGHLIGHT_S, w.t + HIGHLIGHT_S)
        k0 = int(np.searchsorted(t, t0, "left"))
        k1 = int(np.searchsorted(t, t1, "right")) - 1
        bodies = [b for b in w.bodies if 0 <= b < traj.model.n_bodies]
        if bodies and len(t):
            out.append((max(k0, 0), min(max(k1, k0), len(t) - 1), bodies, w.analyzer))
    return out


def _highlight_radius(model) -> np.ndarray:
    size = np.asarray(model.body_size, float)
    radius = np.linalg.norm(size, axis=1)  # box: half diagonal
    return np.where(np.asarray(model.body_shape) == SHAPE_SPHERE, size[:, 0], radius) * HIGHLIGHT_SCALE


def log_findings(rec: rr.RecordingStream, traj: Trajectory, results) -> int:
    """Log the findings of ``results`` on ``traj`` into ``rec`` (see the module docstring);
    returns how many findings."""
    model = traj.model
    t, step = np.asarray(traj.t, float), np.asarray(traj.step, np.int64)
    rows = finding_rows(traj, results)
    for w in rows:
        _time(rec, w.step, w.t)
        for line in w.lines:  # one row per line, all at the finding's onset
            rec.log(f"{FINDINGS_ENTITY}/{w.analyzer}", rr.TextLog(line, level="ERROR"))
    if not rows and len(t):
        ran = ", ".join(r.analyzer for r in results if not r.skipped) or "none"
        _time(rec, int(step[0]), float(t[0]))
        rec.log(f"{FINDINGS_ENTITY}/check", rr.TextLog(f"no findings (analyzers run: {ran})",
                                                       level="INFO"))
    for t_ev, step_ev, analyzer, text in event_rows(results):
        _time(rec, step_ev, t_ev)
        rec.log(f"{EVENTS_ENTITY}/{analyzer}", rr.TextLog(text, level="INFO"))
    events = _impact_events(results)
    spans = _spans(traj, rows, events)
    # highlights: per sample, the union of the bodies flagged then (one row per sample in a span,
    # an empty row after each span clears it)
    if spans and len(t):
        radius = _highlight_radius(model)
        flagged = [dict() for _ in range(len(t))]
        for k0, k1, bodies, analyzer in spans:
            for k in range(k0, k1 + 1):
                for b in bodies:
                    flagged[k].setdefault(b, set()).add(analyzer)
        ks = sorted({k for k0, k1, _, _ in spans for k in range(k0, k1 + 1)}
                    | {k1 + 1 for _, k1, _, _ in spans if k1 + 1 < len(t)})
        centers, radii, labels, offsets = [], [], [], [0]
        for k in ks:
            b = sorted(flagged[k])
            centers.extend(traj.position[k, b])
            radii.extend(radius[b])
            labels.extend(f"{model.body_name[i]}: {', '.join(sorted(flagged[k][i]))}" for i in b)
            offsets.append(offsets[-1] + len(b))
        lengths = np.diff(offsets)
        rec.log("world/findings/bodies", rr.Ellipsoids3D.from_fields(
            colors=[HIGHLIGHT_RGBA], fill_mode="MajorWireframe", line_radii=[HIGHLIGHT_LINE],
            show_labels=True), static=True)
        rec.send_columns(
            "world/findings/bodies",
            indexes=[rr.TimeColumn("step", sequence=step[ks]),
                     rr.TimeColumn("sim_time", duration=t[ks])],
            columns=rr.Ellipsoids3D.columns(
                centers=np.asarray(centers, float).reshape(-1, 3),
                half_sizes=np.repeat(np.asarray(radii, float), 3).reshape(-1, 3),
                labels=labels,
            ).partition(lengths))
    # ---- impact markers
    imp = [e for e in events.values() if e.get("point") and None not in e["point"]]
    for e in imp:
        _time(rec, e["step"], e["t"])
        eff = e.get("restitution_effective")
        label = "impact" + (f" e={eff:.3f}" if eff is not None else "")
        rec.log("world/findings/impacts", rr.Points3D([e["point"]], radii=[0.015],
                                                      colors=[[255, 200, 0]], labels=[label]))
    return len(rows)


def _touch(path: str):
    try:
        with open(path, "wb"):
            pass
    except OSError as e:
        raise LogWriteError(str(path), e.strerror or str(e)) from None


def write_findings_rrd(path: str, traj: Trajectory, results, recording_id: str | None = None):
    """Write the findings alone to ``path`` (.rrd), as recording ``recording_id`` (an overlay
    for a run already open in a viewer); returns the recording id. To open a run with its
    findings, :func:`write_checked` is the one to use."""
    from rblog.record.rerun_writer import _blueprint

    _touch(path)
    rid = recording_id or str(uuid.uuid4())
    rec = rr.RecordingStream(C.APPLICATION_ID, recording_id=rid)
    rec.save(str(Path(path)))
    # sent as the active blueprint: opened after the run, it replaces the run's layout
    t_end = float(traj.t[-1]) if len(traj.t) else None
    rec.send_blueprint(_blueprint(traj.model, traj.info, findings=True,
                                  bounds=np.asarray(traj.position[-1]) if len(traj.t) else None,
                                  t_end=t_end),
                       make_active=True, make_default=True)
    log_findings(rec, traj, results)
    rec.flush()
    rec.disconnect()
    return rid


def write_checked_rrd(path: str, traj: Trajectory, results) -> int:
    """Write one .rrd holding the run ``traj`` (as `rblog run` records it) and its findings, with
    the findings table in the layout; returns how many findings."""
    from rblog.record.rerun_writer import RerunRecorder

    rec = RerunRecorder(str(path), findings_panel=True)
    rec.open(traj.model, traj.info)
    try:
        rec.write(traj)
        n = 0
        for stream in rec.streams:
            n = log_findings(stream, traj, results)
    except BaseException:
        rec.close(truncated=True, reason="interrupted while writing the findings")
        raise
    rec.close(truncated=bool(traj.truncated))
    return n


def findings_count(results) -> int:
    return sum(len(r.findings) for r in results)


def _log_messages(traj: Trajectory, results) -> list[tuple[int, object]]:
    from foxglove_schemas_protobuf.Log_pb2 import Log

    out = []
    for w in finding_rows(traj, results):
        ns = int(C.time_ns(np.array([w.t]))[0])
        msg = Log(level=Log.ERROR, message=w.text, name=f"rblog check {w.analyzer}")
        msg.timestamp.FromNanoseconds(ns)
        out.append((ns, msg))
    return out


def _event_messages(results) -> list[tuple[int, object]]:
    from foxglove_schemas_protobuf.Log_pb2 import Log

    out = []
    for t, _, analyzer, text in event_rows(results):
        ns = int(C.time_ns(np.array([t]))[0])
        msg = Log(level=Log.INFO, message=text, name=f"rblog check {analyzer}")
        msg.timestamp.FromNanoseconds(ns)
        out.append((ns, msg))
    return out


def _marker_messages(traj: Trajectory, results) -> list[tuple[int, object]]:
    """One SceneUpdate per finding: a red sphere on each flagged body, in the body's frame, from
    the start of its highlight interval for its length, with the finding's text above it."""
    from foxglove_schemas_protobuf.Color_pb2 import Color
    from foxglove_schemas_protobuf.Pose_pb2 import Pose
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
    from foxglove_schemas_protobuf.SpherePrimitive_pb2 import SpherePrimitive
    from foxglove_schemas_protobuf.TextPrimitive_pb2 import TextPrimitive
    from foxglove_schemas_protobuf.Vector3_pb2 import Vector3

    model = traj.model
    names = C.view_names(model.body_name)
    radius = _highlight_radius(model)
    events = _impact_events(results)
    t = np.asarray(traj.t, float)
    rgba = [c / 255 for c in HIGHLIGHT_RGBA]
    out = []
    for j, w in enumerate(finding_rows(traj, results)):
        ev = events.get((w.step, tuple(w.bodies)))
        t0, t1 = (ev["t_start"], ev["t_end"]) if ev else (w.t - HIGHLIGHT_S, w.t + HIGHLIGHT_S)
        if len(t):
            t0, t1 = max(t0, float(t[0])), min(t1, float(t[-1]))
        t1 = max(t1, t0)
        ns0 = int(C.time_ns(np.array([t0]))[0])
        upd = SceneUpdate()
        for b in w.bodies:
            if not 0 <= b < model.n_bodies:
                continue
            ent = upd.entities.add(frame_id=names[b], id=f"finding/{j}/{names[b]}",
                                   frame_locked=True)
            ent.timestamp.FromNanoseconds(ns0)
            ent.lifetime.FromNanoseconds(max(int(round((t1 - t0) * 1e9)), 1))
            r = 2.0 * float(radius[b])
            ent.spheres.append(SpherePrimitive(pose=Pose(), size=Vector3(x=r, y=r, z=r),
                                               color=Color(r=rgba[0], g=rgba[1], b=rgba[2], a=0.6)))
            ent.texts.append(TextPrimitive(
                pose=Pose(position=Vector3(x=0.0, y=0.0, z=float(radius[b]) * 1.2)),
                billboard=True, font_size=14.0, scale_invariant=True,
                color=Color(r=1.0, g=1.0, b=1.0, a=1.0), text=f"[{w.analyzer}] {w.text}"))
        if len(upd.entities):
            out.append((ns0, upd))
    return out


def write_checked_mcap(path: str, traj: Trajectory, results) -> int:
    """Write one .mcap holding the run ``traj`` (as `rblog run` records it) and its findings as
    ``foxglove.Log`` messages and ``foxglove.SceneUpdate`` markers, and the analyzers' events as
    ``foxglove.Log`` at level INFO; returns how many findings."""
    from foxglove_schemas_protobuf.Log_pb2 import Log
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    from rblog.record.mcap_writer import McapRecorder

    logs = _log_messages(traj, results)
    markers = _marker_messages(traj, results)
    rec = McapRecorder(str(path))
    rec.open(traj.model, traj.info)
    try:
        rec.write(traj)
        rec.write_messages(FINDINGS_TOPIC, Log, logs)
        rec.write_messages(MARKERS_TOPIC, SceneUpdate, markers)
        rec.write_messages(EVENTS_TOPIC, Log, _event_messages(results))
    except BaseException:
        rec.close(truncated=True, reason="interrupted while writing the findings")
        raise
    rec.close(truncated=bool(traj.truncated))
    return len(logs)


def write_checked(path: str, traj: Trajectory, results) -> int:
    """The run and its findings in one file: .rrd (Rerun) or .mcap (Foxglove), by extension."""
    p = str(path)
    if p.endswith(".rrd"):
        return write_checked_rrd(p, traj, results)
    if p.endswith(".mcap"):
        return write_checked_mcap(p, traj, results)
    raise RblogError(f"{p}: the findings file must end in .rrd or .mcap")


def open_command(path: str, rerun: str = "rerun") -> str:
    """What a user types to open the file :func:`write_checked` wrote (``rerun``: how the Rerun
    viewer is called from here, e.g. ``.venv/bin/rerun``)."""
    if str(path).endswith(".mcap"):
        return f"open {path} in Foxglove (app.foxglove.dev: Open local file)"
    return f"{rerun} {path}"


def write_findings_mcap(path: str, traj: Trajectory, results) -> int:
    """The findings alone in ``path`` (.mcap): ``foxglove.Log`` messages and markers, stamped with
    the run's simulated time; returns how many. :func:`write_checked_mcap` adds the run."""
    from foxglove_schemas_protobuf.Log_pb2 import Log
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
    from mcap_protobuf.writer import Writer

    logs = _log_messages(traj, results)
    markers = _marker_messages(traj, results)
    try:
        fh = open(path, "wb")
    except OSError as e:
        raise LogWriteError(str(path), e.strerror or str(e)) from None
    with fh, Writer(fh) as w:
        for topic, msgs in ((FINDINGS_TOPIC, logs), (MARKERS_TOPIC, markers),
                            (EVENTS_TOPIC, _event_messages(results))):
            for ns, msg in msgs:
                w.write_message(topic, msg, log_time=ns, publish_time=ns)
    return len(logs)
