"""The writer pipeline: logging runs beside the stepping, not after it.

The run loop (rblog.engine.runner) hands each compiled call's raw samples (step, position,
momentum, quaternion, rotation, angular momentum; contacts) to :class:`BlockPipeline` and goes on
stepping (the core releases the GIL). The pipeline's threads do the rest::

    run loop ──submit──► [queue] ──► derive thread ──► [lane queue] ──► lane thread: recorder 1
                         (bounded)   gathers blocks,    (bounded)   └─► lane thread: recorder 2
                                     derives channels,
                                     the summary's drift

- **Gathering.** Calls are sized for responsiveness (CALL_WALL_BUDGET_S of wall time each), so
  their blocks are small (a few to a few tens of samples); each recorder pays a fixed cost per
  block (the Rerun SDK: one chunk per entity and block; MCAP: one compiled call and its index).
  The derive thread joins the blocks that arrive within GATHER_HOLD_S of the first one (up to
  GATHER_MAX_BODY_SAMPLES) into one, then derives once. The records a log holds and their order
  do not depend on where blocks were joined (a sample is a record of its own; contacts are
  grouped by step, and a step never spans two calls), so logs stay byte-identical in their
  records whatever the thread count or the machine's load.
- **Lanes.** With more than one recorder, each writes on its own thread, so that one's GIL-free
  work (lz4 and CRC of MCAP chunks, the Rerun SDK's encoding on its own threads, file I/O)
  overlaps the other's. Every recorder gets every block, in order.
- **Bounded.** Every queue holds at most QUEUE_BLOCKS blocks: when the writers fall behind, the
  run loop waits in :meth:`BlockPipeline.submit` (memory stays bounded).
- **Errors.** A recorder's exception stops the run at the next :meth:`~BlockPipeline.submit` or
  at :meth:`~BlockPipeline.finish`, re-raised in the run loop's thread (a ``RecordError`` or
  ``LogWriteError`` as raised, never lost in a thread); the other recorders still get every block
  submitted before it (nothing the run produced is lost because another log failed).
- **Lockstep.** A recorder with a true ``lockstep`` attribute (the live audit with
  ``--fail-fast``, rblog.record.live_audit) gets each block before the run loop hands over the
  next: :meth:`~BlockPipeline.submit` waits until every recorder handled every block submitted
  so far (the next call's stepping still overlaps the writing), and blocks are not gathered. So
  its error stops the run within one block.
- **Closing.** At the end of a run that went well (``finish(close=True)``) the lanes close their
  recorders at once, each on its own thread (the Rerun SDK's final flush beside the MCAP
  summary), once every lane wrote its last block and none failed; after a failure or an
  interrupt the run loop closes them (truncated) itself.

Why the kill and interrupt promises still hold: a block is held at most GATHER_HOLD_S before the
recorders get it (test_signals: the writers are handed samples at least every 0.5 s), and
:meth:`~BlockPipeline.finish` writes every block submitted (good samples up to the last good
step) before the logs are closed.
"""

from __future__ import annotations

import queue
import threading
import time

import numpy as np

from rblog.contract.model import IMPULSE_KINDS, SUPPLIED_LOGGED, Model
from rblog.contract.trajectory import Contacts, RunInfo, derive

#: blocks each queue holds (the run loop's to the derive thread, and each lane's)
QUEUE_BLOCKS = 2
#: the derive thread joins the blocks that arrive within this wall time of the first one (s) ...
GATHER_HOLD_S = 0.15
#: ... up to this many body-samples (one of the run loop's largest blocks, ~14 MB derived). The
#: Rerun SDK has a sweet spot in chunk size: samples/spinning_bodies.toml's 501 samples x 300
#: bodies replayed to the .rrd writer in k equal blocks cost (process CPU, median of 5, loaded
#: 2-core machine) k = 1: 360 ms, 3: 226, 5: 161-184, 8: 203, 12: 218, 20: 251, 30: 349 ms: per
#: block ~0.4 ms a chunk in the calling thread, and the SDK's own threads slow down on chunks of
#: tens of MB. 32,768 body-samples is k ~ 5 there.
GATHER_MAX_BODY_SAMPLES = 32_768

#: the end of the submitted blocks (derive thread), and the lanes' end-of-run item that also
#: closes the recorder
_END = None
_CLOSE = object()


class BlockPipeline:
    """Derives each block's channels on a worker thread and hands the blocks to ``recorders``
    (see the module's docstring). ``drift.update(block)`` is called with every derived block, in
    order, on the derive thread (the run's summary figures)."""

    def __init__(self, model: Model, info: RunInfo, drift, recorders):
        self.model, self.info, self.drift, self.recorders = model, info, drift, list(recorders)
        self._last_step: int | None = None  # the last derived sample's step (applied impulses)
        self.queue: queue.Queue = queue.Queue(maxsize=QUEUE_BLOCKS)
        self.error: BaseException | None = None
        self.lanes: list[tuple[queue.Queue, threading.Thread]] = []
        self._closed: set[int] = set()  # id() of the recorders a lane closed
        self._close = False
        self._barrier = threading.Barrier(max(1, len(self.recorders)))
        self._max_samples = max(1, GATHER_MAX_BODY_SAMPLES // max(1, model.n_bodies))
        self.lockstep = any(getattr(r, "lockstep", False) for r in self.recorders)
        self._submitted = 0  # items submitted, and handled by each recorder (lockstep)
        self._handled = [0] * max(1, len(self.recorders))
        self._cond = threading.Condition()
        if len(self.recorders) > 1:
            for i, rec in enumerate(self.recorders):
                q: queue.Queue = queue.Queue(maxsize=QUEUE_BLOCKS)
                t = threading.Thread(target=self._lane, args=(rec, q, i), name=f"rblog-recorder-{i}",
                                     daemon=True)
                t.start()
                self.lanes.append((q, t))
        self.thread = threading.Thread(target=self._loop, name="rblog-writer", daemon=True)
        self.thread.start()

    # --- the run loop's side ------------------------------------------------------------------
    def submit(self, steps, position, linear_momentum, quat_wxyz, rotation, angular_momentum,
               contacts: Contacts | None, impulses=None):
        """Queue one call's samples: steps (T,) global step indices; position (T, N, 3),
        linear_momentum (T, N, 3), quat_wxyz (T, N, 4), rotation (T, N, 3, 3),
        angular_momentum (T, N, 3) world frame (owned by the pipeline from now on); contacts
        with global steps, or None; impulses (T, N, 6): each sample's contact impulse over its
        interval (linear, angular; world), or None. Waits while the queue is full; raises a
        recorder's error."""
        if self.lockstep:
            with self._cond:
                self._cond.wait_for(lambda: min(self._handled) >= self._submitted
                                    or self.error is not None)
        if self.error is not None:
            raise self.error
        self._submitted += 1
        self.queue.put((steps, position, linear_momentum, quat_wxyz, rotation, angular_momentum,
                        contacts, impulses))

    def _mark(self, lanes, n: int = 1):
        """Lockstep: recorders ``lanes`` handled ``n`` more submitted items (written, failed or
        drained)."""
        if self.lockstep:
            with self._cond:
                for i in lanes:
                    self._handled[i] += n
                self._cond.notify_all()

    def finish(self, close: bool = False):
        """Write every queued block, stop the threads, and re-raise a recorder's error. With
        ``close`` (the run went well), each lane also closes its recorder (complete) once it
        wrote its last block, unless some recorder failed; :meth:`has_closed` tells which."""
        self._close = close
        self.queue.put(_END)
        self.thread.join()
        if self.error is not None:
            raise self.error

    def finish_quietly(self):
        """On the way out of a failed or interrupted run: write what was queued (good samples),
        swallow errors (the run's own exception is the news)."""
        try:
            self.finish()
        except BaseException:
            pass

    def has_closed(self, rec) -> bool:
        return id(rec) in self._closed

    # --- the derive thread --------------------------------------------------------------------
    def _gather(self, first):
        """``first`` and the blocks that arrive within GATHER_HOLD_S of it (up to the sample
        cap): (items, ended) where ``ended`` tells that the end of the run was reached."""
        items = [first]
        samples = len(first[0])
        if self.lockstep:
            return items, False
        deadline = time.monotonic() + GATHER_HOLD_S
        while samples < self._max_samples:
            wait = deadline - time.monotonic()
            try:
                item = self.queue.get(timeout=wait) if wait > 0 else self.queue.get_nowait()
            except queue.Empty:
                break
            if item is _END:
                return items, True
            items.append(item)
            samples += len(item[0])
        return items, False

    def _derive(self, items):
        """One derived block from the raw samples of ``items`` (joined along time)."""
        if len(items) == 1:
            steps, x, p, q, r, lw, contacts, imp = items[0]
        else:
            steps, x, p, q, r, lw = (np.concatenate([it[k] for it in items]) for k in range(6))
            parts = [it[6] for it in items if it[6] is not None]
            contacts = Contacts.concat(parts) if parts else None
            imp = None if any(it[7] is None for it in items) else \
                np.concatenate([it[7] for it in items])
        dt = self.info.dt
        if contacts is not None:
            contacts.t = contacts.step * dt
        block = derive(self.model, self.info, steps, steps * dt, x, p, q, r, lw, contacts=contacts)
        self._intervals(block, imp)
        return block

    def _intervals(self, block, imp):
        """The block's per-interval channels that the run's model logs (SUPPLIED_LOGGED):
        contact impulses from the step (``imp`` (T, N, 6)), applied ones from the constant
        loads, n dt (F, tau) over the interval's n steps (the first sample's interval: the steps
        since step 0)."""
        m = self.model
        logged = np.asarray(m.body_impulse_supplied) == SUPPLIED_LOGGED
        steps = np.asarray(block.step, np.int64)
        if logged[:, IMPULSE_KINDS.index("contact")].any() and imp is not None:
            block.impulse_contact_linear = np.ascontiguousarray(imp[..., :3])
            block.impulse_contact_angular = np.ascontiguousarray(imp[..., 3:])
        if logged[:, IMPULSE_KINDS.index("applied")].any():
            prev = np.concatenate([[self._last_step if self._last_step is not None else steps[0]],
                                   steps[:-1]]) if len(steps) else steps
            span = ((steps - prev) * self.info.dt)[:, None, None]
            block.impulse_applied_linear = span * np.asarray(m.body_force_world, np.float64)[None]
            block.impulse_applied_angular = span * np.asarray(m.body_torque_world, np.float64)[None]
        if len(steps):
            self._last_step = int(steps[-1])

    def _loop(self):
        broken = False  # deriving failed: nothing more can be written
        ended = False
        try:
            while not ended:
                item = self.queue.get()
                if item is _END:
                    return
                every = range(len(self._handled))
                if broken or (self.error is not None and not self.lanes):
                    self._mark(every)
                    continue  # drain: no recorder can take this block
                items, ended = self._gather(item)
                try:
                    block = self._derive(items)
                    self.drift.update(block)
                    if self.lanes:
                        for lane, _ in self.lanes:
                            lane.put((block, len(items)))  # the items it holds (lockstep)
                    else:
                        for rec in self.recorders:
                            rec.write(block)
                        self._mark(every, len(items))
                except BaseException as e:  # re-raised in the run loop
                    broken = True
                    if self.error is None:
                        self.error = e
                    if not self.lanes:
                        self._mark(every, len(items))
        finally:
            # close only if every block reached the recorders (deriving did not fail); every
            # lane gets its end before any is joined (the lanes meet at a barrier to close)
            end = _CLOSE if self._close and not broken else _END
            for lane, _ in self.lanes:
                lane.put(end)
            for _, t in self.lanes:
                t.join()

    # --- a lane (one recorder) ----------------------------------------------------------------
    def _lane(self, rec, lane: queue.Queue, index: int):
        failed = False
        while True:
            got = lane.get()
            if got is _END or got is _CLOSE:
                block = got
                if block is _CLOSE:
                    self._barrier.wait()  # every lane wrote its last block (or failed)
                if block is _CLOSE and not failed and self.error is None:
                    try:
                        rec.close(truncated=False, reason=None)
                        self._closed.add(id(rec))
                    except BaseException as e:
                        self._closed.add(id(rec))  # closed as far as it could be
                        if self.error is None:
                            self.error = e
                return
            block, n_items = got
            if failed:
                self._mark([index], n_items)
                continue  # this recorder failed: drain; the others keep writing
            try:
                rec.write(block)
            except BaseException as e:
                failed = True
                if self.error is None:
                    self.error = e
            self._mark([index], n_items)
