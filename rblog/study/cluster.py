"""Fan independent tasks out on ``dask.distributed``: a local cluster of worker processes, a running
scheduler reached by its address, or (without Dask, or when asked) this process, serially.

Every bulk job of rblog (``rblog check`` on many logs, ``rblog sweep``, ``rblog bench``,
``rblog stress``) is a list of independent tasks ``fn(item) -> small dict``. :class:`Executor`
runs them and returns the results **in the order of the items**, whatever order they finish in, so
a table built from them does not depend on the number of workers.

What moves over the network: the task function (pickled by ``cloudpickle``: module-level
functions travel by name, so the workers need rblog installed), the items (a log's path, a
scene's TOML text: bytes to kilobytes) and the results (summary dicts). Logs are never sent: a
worker reads and writes them by path, so on a real cluster they must live on storage every worker
sees (docs/cluster.md).

Chunks. Tasks of tens of milliseconds (a sweep's variants) would spend a good part of their time
in scheduling (~3 ms a task on this machine) and in a worker's hand-offs, so :meth:`Executor.map`
with ``chunked=True`` sends **guided chunks**: one Dask task runs ``fn`` over a run of items, the
first chunks large (about ``remaining / (GUIDED_CHUNKS_PER_WORKER x workers)`` items), the last
ones single items, so the workers still finish together (:func:`guided_chunks`). Results are
returned per item exactly as without chunks. An item that raises inside a chunk is reported alone
(the chunk's other items keep their results); a worker that dies under a chunk loses the chunk's
results, and every item of it is sent again **one by one** (one death counts as one try of each),
so a poison item is still isolated and reported after its retry, and nothing else is lost.

Failures. A task that raises is reported as a :class:`TaskFailure` (``kind="error"``), never
retried (rblog's task functions catch the errors a user can cause and return them as results, so
what reaches here is a bug). A task whose worker process dies under it (killed, out of memory,
a crash in compiled code) is retried once on another worker; a second death reports it as a
:class:`TaskFailure` (``kind="worker-died"``) and the rest of the batch goes on. The retry is the
client's: on a local cluster the scheduler gives up at the first death
(``distributed.scheduler.allowed-failures`` = 0) and the client resubmits once; a running
scheduler first applies its own ``allowed-failures`` (Dask's default: 3), then the client
resubmits once.

Threads. A worker process is long-lived and loads rblog's compiled core once. Local workers get
``RBLOG_THREADS`` = cores // workers (at least 1) unless it is set: the core splits large scenes
over that many threads, and two workers of two threads each would oversubscribe two cores
(results are bitwise the same for any thread count).

Dask is the optional extra ``cluster`` (``pip install -e ".[cluster]"``); without it, only the
serial executor exists and asking for workers raises :class:`ClusterUnavailable` naming the extra.
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass
from typing import Any, Callable, Sequence

from rblog.errors import RblogError, ClusterUnavailable

#: what to install for workers
INSTALL_HINT = 'the optional extra "cluster" (pip install -e ".[cluster]", or pip install "rblog[cluster]")'
#: local clusters: one thread per worker process (the kernels are single-threaded and hold the
#: GIL in their Python parts, so threads would not add throughput)
THREADS_PER_WORKER = 1
#: tasks sent to a worker per thread ahead of need (Dask's default: 1.1, i.e. 2 for one thread)
WORKER_SATURATION = 1.0
#: guided chunks: a chunk takes about remaining / (this x workers) of the items not yet chunked;
#: 4 gives ~25 tasks for 100 items on 2 workers, the last 8 of one item each
GUIDED_CHUNKS_PER_WORKER = 4
#: local clusters have no dashboard, so the worker diagnostics that feed it are off: the
#: statistical profiler (a thread that takes the GIL every 10 ms to walk the task's stack) and
#: the event loop's 20 ms health tick (checked every 0.5 s instead); each wake-up takes the GIL
#: from the task and from the run's writer threads
LOCAL_DIAGNOSTICS_OFF = {"distributed.worker.profile.enabled": False,
                         "distributed.admin.tick.interval": "500ms"}
#: client-side resubmissions of a task whose worker died under it
RETRIES_AFTER_WORKER_DEATH = 1
#: seconds to wait for a running scheduler to answer / for its workers to appear
CONNECT_TIMEOUT_S = 30.0


@dataclass
class TaskFailure:
    """A task that produced no result.

    Attributes:
        index: position of its item.  kind: ``"worker-died"`` (its worker process died on every
        try) or ``"error"`` (the task raised).  error: one line.  tries: how many times it ran.
    """

    index: int
    kind: str
    error: str
    tries: int = 1


def dask_available() -> bool:
    """True when ``dask.distributed`` can be imported."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


def default_workers() -> int:
    """Local worker processes by default: the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


class Executor:
    """Runs ``fn`` over items serially, on a local cluster, or on a running scheduler.

    Use as a context manager (the local cluster is started on entry and shut down on exit)::

        with Executor(workers=2) as ex:
            results = ex.map(check_one, paths, on_done=progress)

    Args:
        workers: local worker processes (``None`` or 0 with no ``scheduler``: serial, in this
            process).
        scheduler: address of a running ``dask.distributed`` scheduler (``tcp://host:8786``);
            excludes ``workers``.
        retries: resubmissions of a task whose worker died (default
            :data:`RETRIES_AFTER_WORKER_DEATH`).
    """

    def __init__(self, workers: int | None = None, scheduler: str | None = None, *,
                 retries: int = RETRIES_AFTER_WORKER_DEATH):
        if workers is not None and workers < 0:
            raise RblogError(f"--workers: expected a number >= 0, got {workers}")
        if workers and scheduler:
            raise RblogError("give --workers or --scheduler, not both")
        self.workers = workers or 0
        self.scheduler = scheduler
        self.retries = retries
        self.client = None
        self._cluster = None
        if (self.workers or scheduler) and not dask_available():
            what = "--scheduler" if scheduler else "--workers"
            raise ClusterUnavailable(f"{what} needs dask.distributed, which is not installed: "
                                     f"install {INSTALL_HINT}")

    # -- lifecycle -----------------------------------------------------------------------------
    @property
    def serial(self) -> bool:
        return not (self.workers or self.scheduler)

    def __enter__(self) -> "Executor":
        self.start()
        return self

    def __exit__(self, *exc):
        self.close()

    def start(self):
        if self.serial or self.client is not None:
            return
        import dask
        from distributed import Client, LocalCluster

        if self.scheduler:
            try:
                self.client = Client(self.scheduler, timeout=CONNECT_TIMEOUT_S,
                                     set_as_default=False)
            except OSError as e:
                raise ClusterUnavailable(f"--scheduler {self.scheduler}: cannot connect "
                                         f"({type(e).__name__}: {e})") from None
            return
        # the scheduler gives up on a task at its worker's first death and map() resubmits it;
        # one task in flight per worker thread (saturation 1.0, not Dask's 1.1), so a dying
        # worker takes down only the task it was running, not one queued behind it
        # Dask starts workers with MALLOC_TRIM_THRESHOLD_=65536 (memory handed back to the OS
        # eagerly); reading a 20 MB log then runs 1.3-1.7x slower than in a plain process
        # (docs/cluster.md), so local workers keep glibc's default
        # each worker's core gets its share of the cores (an explicit RBLOG_THREADS wins)
        env = {}
        if "RBLOG_THREADS" not in os.environ:
            env["RBLOG_THREADS"] = str(max(1, default_workers() // self.workers))
        with dask.config.set({"distributed.scheduler.allowed-failures": 0,
                              "distributed.scheduler.worker-saturation": WORKER_SATURATION,
                              "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
                              **LOCAL_DIAGNOSTICS_OFF}):
            self._cluster = LocalCluster(
                n_workers=self.workers, threads_per_worker=THREADS_PER_WORKER, processes=True,
                dashboard_address=None, silence_logs=logging.CRITICAL, env=env)
            self.client = Client(self._cluster, set_as_default=False)

    def close(self):
        if self.client is not None:
            self.client.close()
            self.client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def describe(self) -> str:
        if self.serial:
            return "serial (this process)"
        if self.scheduler:
            n = len(self.client.scheduler_info().get("workers", {})) if self.client else "?"
            return f"scheduler {self.scheduler} ({n} workers)"
        return f"local cluster of {self.workers} worker processes"

    def n_workers(self) -> int:
        if self.serial:
            return 1
        return max(1, len(self.client.scheduler_info().get("workers", {})))

    def worker_pids(self) -> list[int]:
        """Process ids of the workers (this process when serial)."""
        if self.serial:
            return [os.getpid()]
        return sorted(self.client.run(os.getpid).values())

    def run_on_workers(self, fn: Callable[[], Any]) -> None:
        """Call ``fn()`` once in every worker (e.g. to load kernels before timing)."""
        if self.serial:
            fn()
        else:
            self.client.run(fn)

    # -- work ----------------------------------------------------------------------------------
    def map(self, fn: Callable[[Any], Any], items: Sequence, *,
            on_done: Callable[[int, int], None] | None = None, chunked: bool = False) -> list:
        """``[fn(item) for item in items]``, each entry the task's return value or a
        :class:`TaskFailure`; ``on_done(done, total)`` as items finish. ``chunked``: on a
        cluster, send guided chunks of items as tasks (see the module docstring); the results
        are the same."""
        items = list(items)
        total = len(items)
        if self.serial:
            out = []
            for i, item in enumerate(items):
                try:
                    out.append(fn(item))
                except Exception as e:  # a bug in a task: reported, the batch goes on
                    out.append(TaskFailure(i, "error", _one_line(e)))
                if on_done:
                    on_done(i + 1, total)
            return out
        spans = (guided_chunks(total, self.n_workers()) if chunked
                 else [(i, i + 1) for i in range(total)])
        return self._map_dask(fn, items, spans, on_done)

    def _map_dask(self, fn, items, spans, on_done):
        from distributed import as_completed

        client = self.client
        total = len(items)
        results: list = [None] * total
        tries = [1] * total
        # a chunk of several items runs as _run_chunk(fn, items); a single item as fn(item), so
        # an error or a death is the item's own. Chunks carry priorities so that the large ones
        # go first, whatever order Dask would give independent tasks of random keys.
        whole = [b - a > 1 for a, b in spans]
        if any(whole):
            futures = [client.submit(_run_chunk, fn, items[a:b], a, pure=False,
                                     priority=len(spans) - j) if whole[j]
                       else client.submit(fn, items[a], pure=False, priority=len(spans) - j)
                       for j, (a, b) in enumerate(spans)]
        else:  # one task per item: one submission
            futures = client.map(fn, [items[a] for a, _ in spans], pure=False)
        # key -> (first item, last item + 1, whether the task is a chunk)
        span_of = {f.key: (a, b, w) for f, (a, b), w in zip(futures, spans, whole)}
        done = 0
        pending = as_completed(futures, loop=client.loop)
        for fut in pending:
            if fut.status not in ("finished", "error", "cancelled"):
                # it finished, but its result was lost with a worker that died before the result
                # was fetched (another task killed it); the scheduler computes it again: wait
                pending.add(fut)
                continue
            a, b, is_chunk = span_of.pop(fut.key)
            if fut.status == "finished":
                got = fut.result() if is_chunk else [fut.result()]
                for i, r in zip(range(a, b), got):
                    results[i] = r
                finished = b - a
            else:
                exc = fut.exception()
                died = _worker_died(exc)
                finished = 0
                for i in range(a, b):
                    if died and tries[i] <= self.retries:
                        # each item again, alone: a poison item kills only its own task
                        tries[i] += 1
                        again = client.submit(fn, items[i], pure=False, priority=len(spans) + 1)
                        span_of[again.key] = (i, i + 1, False)
                        pending.add(again)
                        continue
                    kind = "worker-died" if died else "error"
                    results[i] = TaskFailure(i, kind, _one_line(exc), tries[i])
                    finished += 1
            fut.release()
            done += finished
            if on_done and finished:
                on_done(done, total)
        return results


def guided_chunks(n_items: int, workers: int,
                  per_worker: int = GUIDED_CHUNKS_PER_WORKER) -> list[tuple[int, int]]:
    """Consecutive ``(start, stop)`` spans covering ``range(n_items)``: each takes
    ceil(remaining / (per_worker x workers)) items, so chunks shrink to single items at the end
    (OpenMP's "guided" schedule), and workers that pull them in order finish within about one
    item of each other."""
    spans, i = [], 0
    share = max(1, per_worker * max(1, workers))
    while i < n_items:
        k = -(-(n_items - i) // share)
        spans.append((i, i + k))
        i += k
    return spans


def _run_chunk(fn, items, first: int) -> list:
    """A chunk's task, on a worker: ``fn`` over ``items``; an item that raises becomes a
    :class:`TaskFailure` (its index counted from the batch's start), the others keep going."""
    out = []
    for k, item in enumerate(items):
        try:
            out.append(fn(item))
        except Exception as e:
            out.append(TaskFailure(first + k, "error", _one_line(e)))
    return out


def _worker_died(exc) -> bool:
    from distributed.scheduler import KilledWorker

    try:
        from distributed.comm.core import CommClosedError
    except ImportError:  # pragma: no cover
        CommClosedError = OSError
    return isinstance(exc, (KilledWorker, CommClosedError))


def _one_line(exc) -> str:
    msg = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {msg}" if msg else type(exc).__name__


def measure_overhead(ex: Executor, n_tasks: int = 1000) -> dict:
    """Scheduling cost of empty tasks: wall seconds for ``n_tasks`` no-op tasks mapped through
    ``ex`` (submission, scheduling, result gathering), per task."""
    t0 = time.perf_counter()
    out = ex.map(_noop, range(n_tasks))
    wall = time.perf_counter() - t0
    assert len(out) == n_tasks
    return {"tasks": n_tasks, "wall_s": wall, "per_task_s": wall / n_tasks}


def _noop(x):
    return x


def map_cases(executor: Executor | None, fn: Callable[[Any], Any], cases: Sequence, *,
              say: Callable[[Any], None] | None = None,
              failed: Callable[[Any, str], Any] | None = None) -> list:
    """The hook of ``rblog bench`` and ``rblog stress``: ``[fn(c) for c in cases]``, in order.

    With no executor (or a serial one) each case runs here, ``say(case)`` just before it (as the
    loops did before). On a cluster the cases run as tasks and ``say(case)`` reports each one as
    it finishes; a case whose worker died twice becomes ``failed(case, message)``.
    """
    cases = list(cases)
    if executor is None or executor.serial:
        out = []
        for c in cases:
            if say:
                say(c)
            out.append(fn(c))
        return out
    results = executor.map(fn, cases, on_done=None)
    out = []
    for c, r in zip(cases, results):
        if isinstance(r, TaskFailure):
            r = failed(c, r.error) if failed else r
        if say:
            say(c)
        out.append(r)
    return out
