"""`rblog check` findings as a Rerun recording that overlays the run it audits.

:func:`write_findings_rrd` writes an .rrd with the run's application and recording id (read from
the run's .rrd; a new one for an .mcap run), so that opening the run and the findings together
(``rerun run.rrd findings.rrd``) merges them into one recording in the viewer:

* ``findings`` (``TextLog``): one entry per finding at its time on ``sim_time`` and ``step``, level
  ERROR, text ``[analyzer] message`` (the message names the body, time, value, limit and unit).
* ``world/findings/bodies`` (``Ellipsoids3D``): the offending bodies, drawn in red a little larger
  than themselves (bounding spheres) at their logged positions over the finding's interval (the
  impact event's span, else HIGHLIGHT_S either side of the finding's time), cleared afterwards.
* ``world/findings/impacts`` (``Points3D``): a marker at the deepest point of every impact event
  (the momentum analyzer's events: the point of peak penetration) at the event's end time,
  labelled with its e_eff.
* a blueprint: the run's own layout (rblog.record.rerun_writer) with a findings panel
  (``TextLogView``) below the 3D view.

The findings are a separate file, written after the run: the run's .rrd is never touched.
"""

from __future__ import annotations

import uuid
from pathlib import Path

import numpy as np
import rerun as rr

from rblog.contract.trajectory import Trajectory
from rblog.errors import LogWriteError
from rblog.record import _common as C

#: a finding without an interval is highlighted this long (s) either side of its time
HIGHLIGHT_S = 0.1
#: the highlight's colour (RGBA) and how much larger than the body's bounding sphere it is drawn
HIGHLIGHT_RGBA = (230, 30, 30, 220)
HIGHLIGHT_SCALE = 1.15
FINDINGS_ENTITY = "findings"


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


def write_findings_rrd(path: str, traj: Trajectory, results, recording_id: str | None = None):
    """Write ``results`` (a list of rblog.analyze Result) on ``traj`` to ``path`` (.rrd)."""
    from rblog.record.rerun_writer import _blueprint, position_bounds

    try:
        with open(path, "wb"):
            pass
    except OSError as e:
        raise LogWriteError(str(path), e.strerror or str(e)) from None
    rid = recording_id or str(uuid.uuid4())
    rec = rr.RecordingStream(C.APPLICATION_ID, recording_id=rid)
    rec.save(str(Path(path)))
    # sent as the active blueprint: opened after the run, it replaces the run's layout
    rec.send_blueprint(_blueprint(traj.model, traj.info, findings=True,
                                  bounds=position_bounds(traj.position)),
                       make_active=True, make_default=True)
    model = traj.model
    t, step = np.asarray(traj.t, float), np.asarray(traj.step, np.int64)
    radius = np.linalg.norm(np.asarray(model.body_size, float), axis=1)  # box: half diagonal
    from rblog.contract.model import SHAPE_SPHERE

    radius = np.where(np.asarray(model.body_shape) == SHAPE_SPHERE,
                      np.asarray(model.body_size, float)[:, 0], radius) * HIGHLIGHT_SCALE
    rec.log(FINDINGS_ENTITY, rr.TextLog("findings of rblog check (one entry per finding)",
                                        level="INFO"), static=True)
    # ---- text log and highlights, per finding
    spans = []  # (k0, k1, bodies)
    events = {}
    for r in results:
        for e in r.events:
            if e.get("kind") == "impact":
                events[(int(e["step"]), tuple(e["bodies"]))] = e
    for r in results:
        for f in r.findings:
            _time(rec, f.step, f.t)
            u = "" if f.unit in ("", "1") else f" {f.unit}"
            rec.log(FINDINGS_ENTITY, rr.TextLog(
                f"[{r.analyzer}] {f.message} (value {f.value:.4g}{u}, limit {f.tolerance:.4g}{u})",
                level="ERROR"))
            ev = events.get((int(f.step), tuple(f.bodies)))
            t0, t1 = (ev["t_start"], ev["t_end"]) if ev else (f.t - HIGHLIGHT_S, f.t + HIGHLIGHT_S)
            k0 = int(np.searchsorted(t, t0, "left"))
            k1 = int(np.searchsorted(t, t1, "right")) - 1
            bodies = [b for b in f.bodies if 0 <= b < model.n_bodies]
            if bodies and len(t):
                spans.append((max(k0, 0), min(max(k1, k0), len(t) - 1), bodies))
    # highlights: per sample, the union of the bodies flagged then (one row per sample in a span,
    # an empty row after each span clears it)
    if spans and len(t):
        flagged = [set() for _ in range(len(t))]
        for k0, k1, bodies in spans:
            for k in range(k0, k1 + 1):
                flagged[k].update(bodies)
        ks = sorted({k for k0, k1, _ in spans for k in range(k0, k1 + 1)}
                    | {k1 + 1 for _, k1, _ in spans if k1 + 1 < len(t)})
        centers, radii, offsets = [], [], [0]
        for k in ks:
            b = sorted(flagged[k])
            centers.extend(traj.position[k, b])
            radii.extend(radius[b])
            offsets.append(offsets[-1] + len(b))
        lengths = np.diff(offsets)
        rec.log("world/findings/bodies", rr.Ellipsoids3D.from_fields(
            colors=[HIGHLIGHT_RGBA], fill_mode="solid"), static=True)
        rec.send_columns(
            "world/findings/bodies",
            indexes=[rr.TimeColumn("step", sequence=step[ks]),
                     rr.TimeColumn("sim_time", duration=t[ks])],
            columns=rr.Ellipsoids3D.columns(
                centers=np.asarray(centers, float).reshape(-1, 3),
                half_sizes=np.repeat(np.asarray(radii, float), 3).reshape(-1, 3),
            ).partition(lengths))
    # ---- impact markers
    imp = [e for e in events.values() if e.get("point") and None not in e["point"]]
    for e in imp:
        _time(rec, e["step"], e["t"])
        eff = e.get("restitution_effective")
        label = "impact" + (f" e={eff:.3f}" if eff is not None else "")
        rec.log("world/findings/impacts", rr.Points3D([e["point"]], radii=[0.015],
                                                      colors=[[255, 200, 0]], labels=[label]))
    rec.flush()
    rec.disconnect()
    return rid


def findings_count(results) -> int:
    return sum(len(r.findings) for r in results)


#: MCAP topic of the findings (``foxglove.Log``): Foxglove lists them in its Log panel and marks
#: them on the timeline, at the run's own time base (simulated time as log time, like the run)
FINDINGS_TOPIC = "/rblog/findings"


def write_findings_mcap(path: str, traj: Trajectory, results) -> int:
    """Write the findings of ``results`` to ``path`` (.mcap) as ``foxglove.Log`` messages, one per
    finding, stamped with the finding's simulated time (ns, as the run's messages are); returns
    how many."""
    from foxglove_schemas_protobuf.Log_pb2 import Log
    from mcap_protobuf.writer import Writer

    rows = []
    for r in results:
        for f in r.findings:
            u = "" if f.unit in ("", "1") else f" {f.unit}"
            rows.append((int(C.time_ns(np.array([f.t]))[0]), r.analyzer,
                         f"{f.message} (value {f.value:.4g}{u}, limit {f.tolerance:.4g}{u})"))
    rows.sort()
    try:
        fh = open(path, "wb")
    except OSError as e:
        raise LogWriteError(str(path), e.strerror or str(e)) from None
    with fh, Writer(fh) as w:
        for ns, name, text in rows:
            msg = Log(level=Log.ERROR, message=text, name=f"rblog check {name}")
            msg.timestamp.FromNanoseconds(ns)
            w.write_message(FINDINGS_TOPIC, msg, log_time=ns, publish_time=ns)
    return len(rows)
