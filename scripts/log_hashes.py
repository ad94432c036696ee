"""Hash the logs of every sample scene under several thread counts and solver paths.

    python scripts/log_hashes.py [--samples samples] [--configs 1,2,4,1:scalar] [--out FILE]

Each configuration runs `rblog run SCENE --mcap` in a fresh process with RBLOG_THREADS=N (and
RBLOG_SOLVER_PATH=scalar for `N:scalar`: the velocity solve's lanes forced off;
RBLOG_THREAD_HANDOVER=0 so that the threads do run on a loaded machine). A log's hash is the
SHA-256 of every .mcap message in file order (topic, schema, log and publish time, sequence,
payload bytes): the records the content decides, not the chunk boundaries, which the writer also
cuts by wall time (tests/cli/test_thread_determinism.py's _mcap_records). Prints one line per
scene and configuration, `scene config hash`, and whether every configuration of a scene agrees;
with --out also writes the lines, so that two checkouts' files can be compared with `diff`.
Exit 1 when a scene's configurations disagree.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import subprocess
import sys
import tempfile
from pathlib import Path


def mcap_hash(path: Path) -> str:
    from mcap.reader import make_reader

    h = hashlib.sha256()
    with open(path, "rb") as f:
        for sch, ch, m in make_reader(f).iter_messages():
            for part in (ch.topic.encode(), (sch.name if sch else "").encode(),
                         sch.data if sch else b"", str((m.log_time, m.publish_time,
                                                        m.sequence)).encode(), bytes(m.data)):
                h.update(len(part).to_bytes(8, "little"))
                h.update(part)
    return h.hexdigest()[:16]


def run(scene: Path, config: str, tmp: Path) -> str:
    threads, _, path = config.partition(":")
    env = {**os.environ, "RBLOG_THREADS": threads, "RBLOG_THREAD_HANDOVER": "0",
           "SKBUILD_EDITABLE_VERBOSE": "0"}
    env.pop("RBLOG_SOLVER_PATH", None)
    if path:
        env["RBLOG_SOLVER_PATH"] = path
    mcap = tmp / f"{scene.stem}-{threads}-{path or 'auto'}.mcap"
    rblog = str(Path(sys.executable).with_name("rblog"))
    p = subprocess.run([rblog, "run", str(scene), "--mcap", str(mcap)], env=env,
                       capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"{scene} {config}: exit {p.returncode}\n{p.stderr}")
    return mcap_hash(mcap)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", default="samples")
    ap.add_argument("--configs", default="1,2,4,1:scalar")
    ap.add_argument("--only", default="", help="comma-separated scene stems (default: all)")
    ap.add_argument("--out")
    a = ap.parse_args()
    scenes = sorted(Path(a.samples).glob("*.toml"))
    if a.only:
        scenes = [s for s in scenes if s.stem in a.only.split(",")]
    lines, bad = [], 0
    with tempfile.TemporaryDirectory() as d:
        for scene in scenes:
            hashes = {c: run(scene, c, Path(d)) for c in a.configs.split(",")}
            for c, h in hashes.items():
                lines.append(f"{scene.stem} {c} {h}")
                print(lines[-1], flush=True)
            same = len(set(hashes.values())) == 1
            bad += not same
            print(f"{scene.stem}: {'all configurations agree' if same else 'DIFFER'}",
                  flush=True)
    if a.out:
        Path(a.out).write_text("\n".join(lines) + "\n")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
