"""What the live audit costs a run: `rblog run SCENE` against `rblog run SCENE --check`.

    python benchmarks/bench_live.py [SCENE] [--pairs N]     # default samples/pile.toml, 5 pairs

Both runs write the same logs (.rrd and .mcap, the default of `rblog run`) through the library
path `rblog run` takes (the run loop with one Recorder per writer); the second adds the live audit
(rblog.record.live_audit.LiveAudit, its default budget) as `--check` does. Pairs are interleaved
(A B A B ...) in one process, so that the load of a shared machine hits both alike; the wall time
of each (from the first step to the logs closed; with --check the final check of the whole run
is inside it) and its process CPU (every thread) are printed side by side with the ratios, then
the median ratios and the audit's own figures (prefix checks run, their seconds on the audit's
thread, the final check's seconds).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import rblog
from rblog.engine.runner import run
from rblog.record import McapRecorder, RerunRecorder
from rblog.record.live_audit import LiveAudit
from rblog.record.recorder import Recorder


def one(scene, tmp: str, tag: str, audit: bool):
    rrd = RerunRecorder(f"{tmp}/{tag}.rrd")
    recs = [Recorder(writers=[rrd]), Recorder(writers=[McapRecorder(f"{tmp}/{tag}.mcap")])]
    a = None
    if audit:
        a = LiveAudit(rerun=[rrd])
        recs.append(a)
    t0, c0 = time.perf_counter(), time.process_time()
    run(scene, recorders=recs)
    return time.perf_counter() - t0, time.process_time() - c0, a


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?",
                    default=str(Path(__file__).resolve().parents[1] / "samples" / "pile.toml"))
    ap.add_argument("--pairs", type=int, default=5)
    args = ap.parse_args(argv)
    scene = rblog.load_scene(args.scene)
    print(f"{args.scene}: {scene.model.n_bodies} bodies; wall time (s) of the run writing .rrd and "
          f".mcap, without and with the live audit, interleaved")
    print(f"  {'pair':>4}  {'logs':>8}  {'logs+check':>10}  {'ratio':>6}  {'CPU logs':>8}  "
          f"{'CPU +check':>10}  {'ratio':>6}  {'checks':>6}  {'prefix s':>8}  {'final s':>7}")
    ratios, cpu_ratios = [], []
    with tempfile.TemporaryDirectory() as tmp:
        one(scene, tmp, "warm", True)  # imports, first-call costs
        for k in range(args.pairs):
            a, ca, _ = one(scene, tmp, f"a{k}", False)
            b, cb, au = one(scene, tmp, f"b{k}", True)
            ratios.append(b / a)
            cpu_ratios.append(cb / ca)
            st = au.stats
            print(f"  {k:>4}  {a:8.3f}  {b:10.3f}  {b / a:6.3f}  {ca:8.3f}  {cb:10.3f}  "
                  f"{cb / ca:6.3f}  {st.checks:>6}  {st.check_s:8.3f}  {st.final_s:7.3f}", flush=True)
    print(f"  wall: median ratio {statistics.median(ratios):.3f} (min {min(ratios):.3f}, "
          f"max {max(ratios):.3f}); target <= 1.3")
    print(f"  process CPU: median ratio {statistics.median(cpu_ratios):.3f} "
          f"(min {min(cpu_ratios):.3f}, max {max(cpu_ratios):.3f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
