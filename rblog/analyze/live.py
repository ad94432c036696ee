"""The live audit: the analyzers run while a run is being recorded (``rblog run --check``,
``Recorder(..., check=True)``).

How: :class:`LiveCheck` keeps the blocks written so far and, after a block, re-runs the suite
(:func:`rblog.analyze.suite.check`, unchanged) on the whole prefix of the run, as often as its
budget allows (below). The analyzers carry no state of their own between blocks: the prefix *is*
the state. Each finding of a prefix check is announced once it is **final**, that is once more
samples cannot take it back:

* ``drift``: at once. A body is flagged when the largest of its rigidity metrics over the samples
  passes its tolerance, and a maximum over more samples is never smaller, so a body flagged on a
  prefix is flagged on the whole run (with the same onset; its worst value and growth are those
  seen so far, the final line gives the run's). One finding per body: it is identified by the
  analyzer and the body.
* ``tunneling``: at once. Each sample interval is judged from its own two samples (the crossing,
  and the proximity candidates swept over it), so a finding of interval k is the same, word for
  word, on any longer prefix. Identified by analyzer, bodies and step.
* the others (``consistency``, ``momentum``, ``penetration``, ``energy``): their findings are
  judged over stretches whose end is not known while they last (a free flight, a resting
  interval, an impact event, a body's median over all its intervals), so a finding on a prefix
  can still change or vanish. One is announced when it was identical (message, value, step,
  bodies) in two successive prefix checks and lay at least HOLD_SAMPLES samples before the end
  of the earlier one. This is a rule of thumb, not a proof: a finding that changes after it was
  announced is reported at the end as ``revised`` or ``withdrawn``. On every sample scene and the
  MuJoCo examples none does (tests/analyze/test_live.py).
* an analyzer whose prefix result was cut at MAX_FINDINGS announces nothing more (which findings
  make the cut depends on the samples still to come).

At the end of the run (:meth:`LiveCheck.finish`) the suite runs once on the whole run: that list
is the verdict, equal to ``rblog check`` on the finished log, and every finding of it not yet
announced is announced then (``at_end``). So the findings printed over a run (live, then at the
end) are those of ``rblog check``, each printed once, a drift finding with its final numbers in
the end report.

Cost and budget: a prefix check costs what ``rblog check`` costs on the prefix (~1 M body-samples
per second on one thread), so checking after every block would cost O(T^2 / block). A check runs
only while the audit's time so far is at most ``budget`` (BUDGET_FRACTION) of the wall time
since the run opened; in between, blocks are only appended. A finding is therefore announced at
the first check after it became final, which on a large run can be later than the block that
made it. Then ``finish`` adds one whole check.

May import numpy and rblog.contract / rblog.analyze only (never rblog.engine or rblog.record).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from rblog.analyze import tolerances as T
from rblog.analyze.base import Finding, Result
from rblog.analyze.suite import check as check_suite
from rblog.contract.trajectory import Trajectory
from rblog.errors import RblogError, AuditFailed

#: analyzers whose findings are final as soon as they appear on a prefix (module docstring)
FINAL_AT_ONCE = frozenset({"drift", "tunneling"})
#: analyzers with one finding per body (identified by analyzer and body, not step)
ONE_PER_BODY = frozenset({"drift"})
#: the other analyzers' findings are announced once identical in two successive prefix checks
#: and at least this many samples before the end of the earlier one (1 s at the default 100 Hz
#: would hold every finding a whole second; 25 samples keeps an impact event's samples after
#: its end, and the momentum analyzer's extrapolation from them, inside the prefix)
HOLD_SAMPLES = 25
#: the share of the run's wall time the prefix checks may take (the final check comes on top).
#: benchmarks/bench_live.py on samples/pile.toml (2 cores, loaded): at 0.2, 7 prefix checks and
#: the run 1.21-1.30x as long as with the logs alone; at 0.1, 4-5 prefix checks, wall 0.99-1.18x,
#: process CPU 1.17-1.28x (docs/live-audit.md)
BUDGET_FRACTION = 0.1


def finding_key(analyzer: str, f: Finding) -> tuple:
    """What identifies a finding across prefixes: (analyzer, bodies) for one-per-body analyzers,
    else (analyzer, bodies, step)."""
    bodies = tuple(int(b) for b in f.bodies)
    return (analyzer, bodies) if analyzer in ONE_PER_BODY else (analyzer, bodies, int(f.step))


@dataclass
class LiveFinding:
    """A finding as the live audit announced it.

    Attributes:
        analyzer: the analyzer's name.  finding: the finding as the prefix check saw it.
        samples: how many samples the run had logged when it was announced; ``t_seen``: the
            simulated time of the last of them (s).  wall_s: seconds since the audit opened.
        at_end: announced by the final check (not final earlier).
    """

    analyzer: str
    finding: Finding
    samples: int
    t_seen: float
    wall_s: float
    at_end: bool = False

    @property
    def key(self) -> tuple:
        return finding_key(self.analyzer, self.finding)


@dataclass
class LiveStats:
    """What the live audit cost: prefix checks run, their seconds and samples; the final check."""

    checks: int = 0
    check_s: float = 0.0
    append_s: float = 0.0
    final_s: float = 0.0
    blocks: int = 0
    samples: int = 0
    checked_samples: list[int] = field(default_factory=list)

    @property
    def total_s(self) -> float:
        return self.check_s + self.append_s + self.final_s


class LiveCheck:
    """Run the analyzers over a run while it is written (see the module docstring).

    Args:
        only, skip, tolerances: as :func:`rblog.analyze.check`.
        threads: threads of the final check (default: as ``rblog check``); prefix checks run on
            one thread, beside the stepping.
        budget: share of the wall time prefix checks may take (BUDGET_FRACTION); ``None``: check
            after every block.
        on_finding: called with each :class:`LiveFinding` when it is announced.

    Use: :meth:`open`, :meth:`add` per block (returns the findings announced on it),
    :meth:`finish` (the final results, equal to ``rblog.check`` on the whole run).
    """

    def __init__(self, *, only=None, skip=None, tolerances: dict | None = None,
                 threads: int | None = None, budget: float | None = BUDGET_FRACTION,
                 on_finding=None):
        self.only, self.skip, self.tolerances = only, skip, tolerances
        self.threads = threads
        self.budget = budget
        self.on_finding = on_finding
        # validate the names now (a one-line CheckOptionError before the run, not after it)
        from rblog.analyze.suite import ANALYZERS, split_tolerances

        for names in (only or ()), (skip or ()):
            for name in names:
                if name not in ANALYZERS:
                    from rblog.analyze.base import CheckOptionError

                    raise CheckOptionError(f"unknown analyzer {name!r}; known: "
                                           + ", ".join(ANALYZERS))
        split_tolerances(tolerances)
        self.stats = LiveStats()
        self.announced: list[LiveFinding] = []
        self.results: list[Result] | None = None
        #: announced findings the final check changed (key kept, other numbers): for drift the
        #: worst value so far; for the others a rule-of-thumb announcement that did not hold
        self.revised: list[tuple[LiveFinding, Finding]] = []
        #: announced findings whose key the final check does not have
        self.withdrawn: list[LiveFinding] = []
        self._blocks: list[Trajectory] = []
        self._traj: Trajectory | None = None
        self._keys: set = set()
        self._prev: dict[tuple, tuple[dict, int]] = {}  # key -> (finding dict, prefix length)
        self._prev_len = 0
        self._capped: set[str] = set()
        self._t_open: float | None = None

    # --- feeding ------------------------------------------------------------------------------
    def open(self) -> "LiveCheck":
        """Start the clock of the budget. Pays the suite's first-use costs now (a recorder is
        opened before the run's clock starts): ``np.nanmedian`` (consistency) imports
        ``numpy.ma`` on its first call, ~0.3 s."""
        import numpy.ma  # noqa: F401

        self._t_open = time.perf_counter()
        return self

    @property
    def trajectory(self) -> Trajectory | None:
        """The run so far (None before the first block)."""
        self._join()
        return self._traj

    def _join(self):
        if self._blocks:
            parts = ([self._traj] if self._traj is not None else []) + self._blocks
            self._traj = parts[0] if len(parts) == 1 else Trajectory.concat(parts)
            self._blocks = []

    def add(self, block: Trajectory) -> list[LiveFinding]:
        """Append a block; run a prefix check if the budget allows; return what it announced."""
        if self._t_open is None:
            self.open()
        t0 = time.perf_counter()
        self._blocks.append(block)
        self.stats.blocks += 1
        self.stats.samples += block.n_samples
        self.stats.append_s += time.perf_counter() - t0
        elapsed = time.perf_counter() - self._t_open
        if self.budget is not None and self.stats.check_s > self.budget * elapsed:
            return []
        return self.check_now()

    def check_now(self) -> list[LiveFinding]:
        """Run the suite on the prefix now and announce what became final."""
        t0 = time.perf_counter()
        self._join()
        traj = self._traj
        if traj is None or traj.n_samples == self._prev_len:
            return []
        results = check_suite(traj, only=self.only, skip=self.skip, tolerances=self.tolerances,
                              threads=1)
        n = traj.n_samples
        t_end = float(traj.t[-1])
        wall = time.perf_counter() - self._t_open
        new: list[LiveFinding] = []
        seen: dict[tuple, tuple[dict, int]] = {}
        index: dict[int, int] | None = None  # step -> sample index, made when first needed
        for r in results:
            if r.skipped or r.analyzer in self._capped:
                continue
            if r.stats.get("findings", 0) > len(r.findings) or len(r.findings) >= T.MAX_FINDINGS:
                self._capped.add(r.analyzer)  # which findings make the cut is not final
                continue
            for f in r.findings:
                key = finding_key(r.analyzer, f)
                if key in self._keys:
                    continue
                if r.analyzer in FINAL_AT_ONCE:
                    final = True
                else:
                    d = f.to_dict()
                    seen[key] = (d, self._prev_len)
                    prev = self._prev.get(key)
                    if index is None:
                        index = {int(s): k for k, s in enumerate(traj.step)}
                    k_f = index.get(int(f.step), n - 1)
                    final = prev is not None and prev[0] == d and k_f + HOLD_SAMPLES <= prev[1]
                if final:
                    lf = LiveFinding(r.analyzer, f, n, t_end, wall)
                    self._keys.add(key)
                    self.announced.append(lf)
                    new.append(lf)
        # what the next check compares with: this check's findings, at this prefix length
        self._prev = {k: (d, n) for k, (d, _) in seen.items()}
        self._prev_len = n
        self.stats.checks += 1
        self.stats.checked_samples.append(n)
        self.stats.check_s += time.perf_counter() - t0
        if self.on_finding is not None:
            for lf in new:
                self.on_finding(lf)
        return new

    # --- the end ------------------------------------------------------------------------------
    def finish(self) -> list[Result]:
        """The suite on the whole run (the verdict, as ``rblog check``); announces the findings
        not announced yet (``at_end``) and sorts out :attr:`revised` and :attr:`withdrawn`.
        Idempotent."""
        if self.results is not None:
            return self.results
        if self._t_open is None:
            self.open()
        t0 = time.perf_counter()
        self._join()
        traj = self._traj
        if traj is None:
            self.results = []
            return self.results
        results = check_suite(traj, only=self.only, skip=self.skip, tolerances=self.tolerances,
                              threads=self.threads)
        final: dict[tuple, list[tuple[str, Finding]]] = {}
        for r in results:
            for f in r.findings:
                final.setdefault(finding_key(r.analyzer, f), []).append((r.analyzer, f))
        late: list[LiveFinding] = []
        n = traj.n_samples
        t_end = float(traj.t[-1]) if n else 0.0
        wall = time.perf_counter() - self._t_open
        for lf in self.announced:
            got = final.get(lf.key)
            if not got:
                self.withdrawn.append(lf)
            elif all(f.to_dict() != lf.finding.to_dict() for _, f in got):
                self.revised.append((lf, got[0][1]))
        for key, items in final.items():
            if key in self._keys:
                continue
            for analyzer, f in items:
                late.append(LiveFinding(analyzer, f, n, t_end, wall, at_end=True))
        self.announced.extend(late)
        self.results = results
        self.stats.final_s = time.perf_counter() - t0
        if self.on_finding is not None:
            for lf in late:
                self.on_finding(lf)
        return results


__all__ = ["AuditFailed", "BUDGET_FRACTION", "FINAL_AT_ONCE", "HOLD_SAMPLES", "LiveCheck",
           "LiveFinding", "LiveStats", "finding_key"]
