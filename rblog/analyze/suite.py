"""The analyzer suite: the registry of analyzers and :func:`check`, which runs them (re-exported by
``rblog.analyze``, which imports this module only when one of these names is first used, so that
``rblog.analyze.tolerances`` and the CLI's ``--help`` do not load the analyzers and numpy)."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

from rblog._threads import default_threads
from rblog.contract.trajectory import Trajectory
from rblog.analyze.base import Analyzer, CheckOptionError, Context, Finding, Result
from rblog.analyze.consistency import ConsistencyAnalyzer
from rblog.analyze.drift import DriftAnalyzer
from rblog.analyze.energy import EnergyAnalyzer
from rblog.analyze.joints import JointsAnalyzer
from rblog.analyze.momentum import MomentumAnalyzer
from rblog.analyze.penetration import PenetrationAnalyzer
from rblog.analyze.tunneling import TunnelingAnalyzer

#: name -> analyzer class, in report order
ANALYZERS: dict[str, type[Analyzer]] = {
    cls.name: cls
    for cls in (ConsistencyAnalyzer, DriftAnalyzer, MomentumAnalyzer, PenetrationAnalyzer, EnergyAnalyzer,
                TunnelingAnalyzer, JointsAnalyzer)
}


def split_tolerances(tolerances: dict | None) -> dict[str, dict[str, float]]:
    """``{"energy.drift_rel": 1e-2}`` -> ``{"energy": {"drift_rel": 1e-2}}``; unknown analyzer or
    tolerance names raise :class:`CheckOptionError` (a one-line message naming what exists)."""
    out: dict[str, dict[str, float]] = {name: {} for name in ANALYZERS}
    for key, value in (tolerances or {}).items():
        name, dot, tol_name = str(key).partition(".")
        if not dot or name not in ANALYZERS:
            raise CheckOptionError(
                f"unknown tolerance {key!r}: expected <analyzer>.<name> with analyzer one of "
                + ", ".join(ANALYZERS))
        if tol_name not in ANALYZERS[name].defaults:
            raise CheckOptionError(
                f"unknown tolerance {key!r}; {name} has: "
                + ", ".join(sorted(ANALYZERS[name].defaults)))
        out[name][tol_name] = value
    return out


def default_tolerances() -> dict[str, float]:
    """Every tolerance as ``{"analyzer.name": default}``."""
    return {f"{n}.{k}": v for n, cls in ANALYZERS.items() for k, v in cls.defaults.items()}


#: the order analyzers start in when they run in threads: the costliest first, so that the last to
#: finish is a short one (bench_check.py), but consistency (which needs nothing shared) before
#: penetration, which would wait for the proximity table momentum is computing
_COST_ORDER = ("momentum", "consistency", "penetration", "energy", "drift", "tunneling", "joints")

_POOLS: dict[int, ThreadPoolExecutor] = {}
_POOLS_LOCK = threading.Lock()


def _pool(n_threads: int) -> ThreadPoolExecutor:
    """A pool of exactly ``n_threads`` worker threads (made once, reused by later checks)."""
    with _POOLS_LOCK:
        if n_threads not in _POOLS:
            _POOLS[n_threads] = ThreadPoolExecutor(n_threads, f"rblog-check{n_threads}")
        return _POOLS[n_threads]


def check(traj: Trajectory, only=None, skip=None, tolerances: dict | None = None,
          threads: int | None = None) -> list[Result]:
    """Run the analyzers on ``traj`` and return their results, in ANALYZERS order.

    Args:
        only: names of the analyzers to run (default: all).
        skip: names of analyzers not to run.
        tolerances: overrides keyed ``"<analyzer>.<tolerance>"``.
        threads: how many analyzers run at once (default ``rblog._threads.default_threads()``:
            the environment variable RBLOG_THREADS, by default every core, as the engine). Each
            analyzer is a sequential computation and the values they share
            (rblog.analyze.base.Context) are computed once, so the results are the same for
            any thread count; the compiled kernels release the GIL.
    """
    for names in (only or ()), (skip or ()):
        for name in names:
            if name not in ANALYZERS:
                raise CheckOptionError(
                    f"unknown analyzer {name!r}; known: " + ", ".join(ANALYZERS))
    per = split_tolerances(tolerances)
    selected = [n for n in ANALYZERS if (not only or n in only) and n not in (skip or ())]
    analyzers = [ANALYZERS[n](**per[n]) for n in selected]
    ctx = Context(traj)
    if threads is None:
        threads = default_threads()
    threads = max(1, min(int(threads), len(analyzers)))
    if threads == 1 or ctx.traj.n_samples == 0:
        return [a.run(traj, ctx) for a in analyzers]
    order = sorted(range(len(analyzers)), key=lambda j: _COST_ORDER.index(selected[j])
                   if selected[j] in _COST_ORDER else len(_COST_ORDER))
    pool = _pool(threads)
    futures = {j: pool.submit(analyzers[j].run, traj, ctx) for j in order}
    return [futures[j].result() for j in range(len(analyzers))]


__all__ = [
    "ANALYZERS", "Analyzer", "CheckOptionError", "Context", "Finding", "Result", "check",
    "default_tolerances", "split_tolerances",
]
