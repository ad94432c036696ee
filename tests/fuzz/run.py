"""Run rblog's fuzz targets (targets.py) under atheris (libFuzzer, coverage-guided).

    python tests/fuzz/run.py TARGET [libFuzzer options ...]     one target, e.g. -runs=1000
    python tests/fuzz/run.py --all SECONDS [--lanes 2]          every target SECONDS each,
                                                                 LANES at a time; prints the
                                                                 executions per target

The seed corpus tests/fuzz/corpus/TARGET/ is read, never written: new inputs go to a work folder
(``--work``, default $TMPDIR/rblog-fuzz/TARGET), and a finding (an exception that is not an
RblogError, a crash, a hang past -timeout) is written there as crash-*/timeout-* and ends the
run with a non-zero exit. Needs the ``fuzz`` extra (atheris). docs/fuzzing.md has the long run.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
DEFAULT_WORK = Path(tempfile.gettempdir()) / "rblog-fuzz"
#: libFuzzer's per-input time limit (s): a read or parse of one small input takes < 1 s
TIMEOUT_S = 30
#: libFuzzer's memory limit per process (MB)
RSS_LIMIT_MB = 4096


def fuzz_one(target: str, args: list[str]) -> None:
    import atheris

    work = DEFAULT_WORK / target
    for a in list(args):
        if a.startswith("--work="):
            work = Path(a.split("=", 1)[1]) / target
            args.remove(a)
    work.mkdir(parents=True, exist_ok=True)
    sys.path.insert(0, str(HERE))
    with atheris.instrument_imports(include=["rblog", "mcap", "mcap_protobuf", "targets"]):
        import targets
        # the modules the targets reach (rblog imports most of them lazily)
        import mcap.reader, mcap.stream_reader, mcap.writer  # noqa: F401, E401
        import rblog.adapters.mujoco, rblog.analyze.consistency  # noqa: F401, E401
        import rblog.engine.scene, rblog.engine.scene_checks  # noqa: F401, E401
        import rblog.record.reader, rblog.record.recorder, rblog.record.safe_rrd  # noqa: F401, E401
    fn = targets.TARGETS[target]

    def one(data: bytes) -> None:
        fn(data)

    files = [a for a in args if not a.startswith("-") and Path(a).is_file()]
    # a replay (`run.py TARGET FILE`): libFuzzer runs the given inputs once and stops; it takes
    # files or folders, not both, so the corpus folders go only into a fuzzing run
    folders = [] if files else [str(work), str(HERE / "corpus" / target)]
    argv = [sys.argv[0], f"-timeout={TIMEOUT_S}", f"-rss_limit_mb={RSS_LIMIT_MB}",
            f"-artifact_prefix={work}/", *args, *folders]
    atheris.Setup(argv, one)
    atheris.Fuzz()


def fuzz_all(seconds: int, lanes: int, work: Path) -> int:
    sys.path.insert(0, str(HERE))
    from targets import TARGETS

    queue = list(TARGETS)
    running: list[tuple[str, subprocess.Popen, Path]] = []
    done: dict[str, tuple[int, float, int]] = {}
    while queue or running:
        while queue and len(running) < lanes:
            t = queue.pop(0)
            log = work / f"{t}.log"
            work.mkdir(parents=True, exist_ok=True)
            p = subprocess.Popen([sys.executable, __file__, t, f"-max_total_time={seconds}",
                                  "-print_final_stats=1", f"--work={work}"],
                                 stdout=subprocess.DEVNULL, stderr=open(log, "w"))
            running.append((t, p, log))
        time.sleep(2)
        for item in list(running):
            t, p, log = item
            if p.poll() is None:
                continue
            running.remove(item)
            text = log.read_text(errors="replace")
            m = re.search(r"Done (\d+) runs in (\d+) second", text)
            execs = int(m.group(1)) if m else _last_count(text)
            secs = float(m.group(2)) if m else float("nan")
            done[t] = (execs, secs, p.returncode)
    print(f"{'target':<13} {'executions':>11} {'seconds':>8}  result")
    for t in TARGETS:
        execs, secs, rc = done[t]
        print(f"{t:<13} {execs:>11,} {secs:>8.0f}  "
              f"{'no finding' if rc == 0 else f'FINDING (exit {rc}): see {work}/{t}.log'}")
    return max((rc != 0 for _, _, rc in done.values()), default=0)


def _last_count(text: str) -> int:
    counts = re.findall(r"^#(\d+)\s", text, re.M)
    return int(counts[-1]) if counts else 0


def main() -> None:
    args = sys.argv[1:]
    if not args:
        sys.exit(__doc__)
    if args[0] == "--all":
        seconds = int(args[1])
        lanes = int(args[args.index("--lanes") + 1]) if "--lanes" in args else 2
        work = Path(args[args.index("--work") + 1]) if "--work" in args else DEFAULT_WORK
        sys.exit(fuzz_all(seconds, lanes, work))
    os.environ.setdefault("RBLOG_THREADS", "1")
    fuzz_one(args[0], args[1:])


if __name__ == "__main__":
    main()
