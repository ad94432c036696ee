"""Each log writer alone: process CPU to write a scene's run, replaying the run's blocks.

    python benchmarks/bench_writers.py [SCENE]        # default samples/spinning_bodies.toml

The scene is run once keeping its blocks (the default log rate); then each writer (MCAP lz4, MCAP
uncompressed, Rerun) writes them to a new file and closes it, three times; the least process CPU
(every thread: the Rerun SDK encodes on threads of its own) and wall time are printed, with the
CPU of the writer's calling thread. Opening the file (the static records) is not counted. To
compare with another commit, run this file with PYTHONPATH at that commit's source (the script
uses only the public writers).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import rblog  # noqa: E402
from rblog.record import McapRecorder, RerunRecorder  # noqa: E402

from bench_logging import _Keep  # noqa: E402


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    scene_path = argv[0] if argv else str(Path(__file__).resolve().parents[1] / "samples"
                                          / "spinning_bodies.toml")
    keep = _Keep()
    rblog.run(rblog.load_scene(scene_path), recorders=[keep])
    samples = sum(len(b.t) for b in keep.blocks)
    print(f"{scene_path}: {len(keep.blocks)} blocks, {samples} samples of "
          f"{keep.model.n_bodies} bodies; each writer alone, best of 3")
    with tempfile.TemporaryDirectory() as tmp:
        for name, make in (("mcap (lz4)", lambda p: McapRecorder(p + ".mcap")),
                           ("mcap (none)", lambda p: McapRecorder(p + ".mcap", compression="none")),
                           ("rrd", lambda p: RerunRecorder(p + ".rrd"))):
            best = None
            for k in range(3):
                rec = make(os.path.join(tmp, f"w{k}"))
                rec.open(keep.model, keep.info)
                c0, w0, t0 = time.process_time(), time.perf_counter(), time.thread_time()
                for b in keep.blocks:
                    rec.write(b)
                t1 = time.thread_time()
                rec.close()
                r = (time.process_time() - c0, time.perf_counter() - w0, t1 - t0)
                best = r if best is None or r[0] < best[0] else best
            print(f"  {name:<12} CPU {best[0] * 1e3:6.1f} ms  wall {best[1] * 1e3:6.1f} ms  "
                  f"calling thread {best[2] * 1e3:6.1f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
