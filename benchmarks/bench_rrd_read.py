"""Load time of an .rrd log by each way of reading it that a corrupted file cannot abort.

    python benchmarks/bench_rrd_read.py LOG.rrd [LOG.rrd ...] [--repeats 5]

Ways (each feeds the same reader (rblog.record.reader._Collector) and builds the Trajectory):

* ``sdk``: the Rerun SDK's reader (``rerun.chunk.RrdReader``; Arrow decoded in Rust: a corrupted
  payload can panic and abort the process). The reader before rblog.record.safe_rrd.
* ``validate+sdk``: rblog.record.safe_rrd's pass over every message first (pyarrow, checked),
  then the SDK. Abort-proof only for what pyarrow's validation rejects.
* ``pyarrow``: rblog.record.safe_rrd alone (what rblog.load does).
* ``child``: the SDK's reader in a child process (spawned, as a fork after the SDK's threads
  started is unsafe) that hands the Trajectory back pickled.

Prints the median wall time per way over interleaved repeats and its ratio to ``sdk``.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import statistics
import time
import warnings
from pathlib import Path

import numpy as np

from rblog.record import _common as C
from rblog.record import reader as R
from rblog.record import safe_rrd


def _sdk_read_into(col, path: Path) -> None:
    """The SDK-based reading of rblog's canonical entities (same collector calls as
    reader._read_rrd_into)."""
    import rerun as rr

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rd = rr.chunk.RrdReader(path)
        recs = rd.recordings()
        stores = [s for s in recs if s.application_id == C.APPLICATION_ID] or recs
        batches = [(c.entity_path, c.to_record_batch()) for c in rd.stream(store=stores[0])]
    _feed(col, batches)


def _pyarrow_read_into(col, path: Path) -> None:
    got, col.cut = safe_rrd.chunks(path, C.APPLICATION_ID)
    _feed(col, [(c.entity_path, c.batch) for c in got])


def _feed(col, batches) -> None:
    state = []
    for entity, batch in batches:
        ent = entity.lstrip("/")
        if not ent.startswith("rblog/"):
            continue
        comps = R._components(batch) if ent != "rblog/state" else {}
        if ent == "rblog/run":
            col.run = {**(col.run or {}), **{k: R._scalar(v[-1]) for k, v in comps.items()
                                             if v and v[-1] is not None and len(v[-1])}}
        elif ent == "rblog/model":
            col.model = {**(col.model or {}), **{k: v[-1] for k, v in comps.items()
                                                 if v and v[-1] is not None}}
        elif ent == "rblog/status":
            col.status = {k: R._scalar(v[-1]) for k, v in comps.items() if v and v[-1] is not None}
        elif ent == "rblog/state":
            comps = R._components(batch, flat=True)
            if "step" in batch.schema.names:
                comps["step"] = np.asarray(batch.column("step").to_numpy(), np.int64)
            state.append(comps)
        elif ent == "rblog/contacts":
            R._rrd_contacts(col, comps)
    n = len(col.model["body_name"])
    for comps in state:
        col.add_samples(R._rrd_state_columns(comps, n), n)


def load_sdk(path):
    col = R._Collector(Path(path))
    _sdk_read_into(col, Path(path))
    return col.build()


def load_validate_sdk(path):
    safe_rrd.chunks(Path(path), C.APPLICATION_ID)
    return load_sdk(path)


def load_pyarrow(path):
    col = R._Collector(Path(path))
    _pyarrow_read_into(col, Path(path))
    return col.build()


_POOL_CTX = mp.get_context("spawn")


def load_child(path):
    with _POOL_CTX.Pool(1) as pool:
        return pool.apply(load_sdk, (path,))


WAYS = {"sdk": load_sdk, "validate+sdk": load_validate_sdk, "pyarrow": load_pyarrow,
        "child": load_child}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("logs", nargs="+")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--ways", default=",".join(WAYS))
    args = ap.parse_args()
    ways = args.ways.split(",")
    for log in args.logs:
        ref = load_sdk(log)
        for w in ways:  # same arrays from every way
            got = WAYS[w](log)
            assert np.array_equal(got.position, ref.position) and got.n_samples == ref.n_samples, w
        times = {w: [] for w in ways}
        for _ in range(args.repeats):
            for w in ways:
                t0 = time.perf_counter()
                WAYS[w](log)
                times[w].append(time.perf_counter() - t0)
        size = Path(log).stat().st_size
        base = statistics.median(times["sdk"]) if "sdk" in times else None
        print(f"{log}: {size / 1e6:.2f} MB, {ref.n_samples} samples x {ref.n_bodies} bodies, "
              f"{len(ref.contacts)} contact rows")
        for w in ways:
            med = statistics.median(times[w])
            ratio = f"  {med / base:.3f}x sdk" if base else ""
            print(f"  {w:<13} median {med * 1e3:8.1f} ms  (min {min(times[w]) * 1e3:.1f}){ratio}")


if __name__ == "__main__":
    main()
