"""The live audit as a recorder: ``rblog run SCENE --check`` and ``Recorder(..., check=True)``.

:class:`LiveAudit` has the recorder protocol (``open(model, info)``, ``write(block)``,
``close(truncated, reason)``), so the run loop (rblog.engine.runner) and
:class:`rblog.record.Recorder` hand it every block as they hand it to the log writers. It feeds
the blocks to :class:`rblog.analyze.live.LiveCheck` (what is announced when, and why a live
verdict is the verdict of ``rblog check``: that module's docstring) and

* calls ``on_finding(LiveFinding)`` for each finding when it is announced (the CLI prints it);
* streams it into the Rerun recordings it was given, while the run goes: a row on
  ``findings/live/<analyzer>`` (level WARN, at the finding's time, text ``live: <the findings
  table's text>``), in the findings table of the layout (rblog.record.findings), so a viewer
  watching the run (``--spawn``, ``--connect``) shows it when it appears;
* when the recording closes, logs the final findings exactly as ``rblog check LOG --rrd`` logs
  them (:func:`rblog.record.findings.log_findings`: ``findings/<analyzer>`` rows, highlighted
  bodies, impact markers) from the check of the whole run; so the recording holds what
  ``rblog check --rrd`` would write, plus the ``findings/live`` rows of what was announced
  during the run (a drift finding's live row has the numbers seen then);
* with ``fail_fast``, raises :class:`~rblog.analyze.live.AuditFailed` (exit code 1) from
  :meth:`write` at the first announced finding: the run loop then stops and closes the logs
  (truncated, readable up to the last block written). ``lockstep`` asks the run loop to write
  a block to every recorder before it steps the block after the next (rblog.engine.runner), so
  that the run stops within one block of the finding.

The record room imports the analyze room here (as the reader and the Recorder do for the
consistency checks): a documented crossing (docs/architecture.md).
"""

from __future__ import annotations

import threading

from rblog.analyze.live import BUDGET_FRACTION, AuditFailed, LiveCheck, LiveFinding
from rblog.contract.model import Model
from rblog.contract.trajectory import RunInfo, Trajectory

#: where announced findings go in the Rerun recording (under the findings table's origin)
LIVE_ENTITY = "findings/live"


class LiveAudit:
    """Run the analyzers on each block as it is written (see the module docstring).

    Args:
        only, skip, tolerances, threads, budget: as :class:`rblog.analyze.live.LiveCheck`
            (``budget`` by default BUDGET_FRACTION, and None, a check after every block, with
            ``fail_fast``).
        fail_fast: stop the run (raise AuditFailed from ``write``) at the first finding.
        on_finding: called with each announced :class:`~rblog.analyze.live.LiveFinding`.
        rerun: RerunRecorder(s) to stream the findings into (their layout gets the findings
            table).
    """

    def __init__(self, *, only=None, skip=None, tolerances=None, threads=None,
                 budget: float | None | str = "default", fail_fast: bool = False,
                 on_finding=None, rerun=()):
        if budget == "default":  # fail-fast checks every block: it stops within one block
            budget = None if fail_fast else BUDGET_FRACTION
        self.live = LiveCheck(only=only, skip=skip, tolerances=tolerances, threads=threads,
                              budget=budget, on_finding=self._announce)
        self.fail_fast = bool(fail_fast)
        #: the run loop writes each block to every recorder before stepping on (fail-fast)
        self.lockstep = self.fail_fast
        self.on_finding = on_finding
        self.rerun: list = []
        for r in ([rerun] if not isinstance(rerun, (list, tuple)) else rerun):
            self.attach_rerun(r)
        self.model: Model | None = None
        self.failed: AuditFailed | None = None
        self._lock = threading.Lock()

    def attach_rerun(self, r) -> None:
        """Stream findings into RerunRecorder ``r`` too (before it opens: its layout gets the
        findings table)."""
        if r is None or r in self.rerun:
            return
        r.findings_panel = True
        r.before_close.append(self._log_final)
        self.rerun.append(r)

    # --- recorder protocol --------------------------------------------------------------------
    def open(self, model: Model, info: RunInfo) -> None:
        self.model = model
        self.live.open()

    def write(self, block: Trajectory) -> None:
        if self.failed is not None:
            raise self.failed
        new = self.live.add(block)
        if self.fail_fast and new:
            self.failed = AuditFailed(new[0])
            raise self.failed

    def close(self, truncated: bool = False, reason: str | None = None) -> None:
        self.finish()

    # --- results ------------------------------------------------------------------------------
    def finish(self):
        """The final results (the suite on everything written; computed once)."""
        with self._lock:
            return self.live.finish()

    @property
    def results(self):
        return self.live.results

    @property
    def announced(self) -> list[LiveFinding]:
        return self.live.announced

    @property
    def stats(self):
        return self.live.stats

    # --- streaming ----------------------------------------------------------------------------
    def _announce(self, lf: LiveFinding) -> None:
        if not lf.at_end:
            for r in self.rerun:
                for stream in r.streams:
                    _log_live(stream, self.model, lf)
        if self.on_finding is not None:
            self.on_finding(lf)

    def _log_final(self, streams) -> None:
        from rblog.record.findings import log_findings

        results = self.finish()
        traj = self.live.trajectory
        if traj is None:
            return
        for stream in streams:
            log_findings(stream, traj, results)


def live_text(model: Model, lf: LiveFinding) -> str:
    """One line for an announced finding: ``ANALYZER | BODIES | value V vs limit L | message``
    (the findings table's text, rblog.record.findings.Row)."""
    from rblog.record.findings import Row

    f = lf.finding
    names = [str(model.body_name[b]) if 0 <= b < model.n_bodies else "static" for b in f.bodies]
    return Row(lf.analyzer, float(f.t), int(f.step), list(f.bodies), ", ".join(names) or "-",
               float(f.value), float(f.tolerance), str(f.unit), f.message).text


def _log_live(stream, model: Model, lf: LiveFinding) -> None:
    import rerun as rr

    f = lf.finding
    stream.set_time("step", sequence=int(f.step))
    stream.set_time("sim_time", duration=float(f.t))
    stream.log(f"{LIVE_ENTITY}/{lf.analyzer}",
               rr.TextLog(f"live (seen at t = {lf.t_seen:.6g} s): {live_text(model, lf)}",
                          level="WARN"))


__all__ = ["AuditFailed", "LIVE_ENTITY", "LiveAudit", "live_text"]
