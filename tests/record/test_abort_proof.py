"""An .rrd with two changed bytes must not take the process down (issue 41).

tests/data/two_bytes_changed.rrd is a 12 kB log of samples/bouncing_ball.toml (its rblog
entities, one view chunk and the store records, cut from a 0.05 s run) with two bytes of the
view chunk's Arrow payload changed (offsets 6722 and 6832 of tests/data/two_bytes_changed.orig.rrd:
an Arrow buffer offset of 4.6e16). The Rerun SDK's reader panics on it in Rust ("the offset of
the new Buffer cannot exceed the existing length") and the interpreter aborts (SIGABRT, exit
134). rblog's reader (rblog/record/safe_rrd.py) decodes the payloads with pyarrow under checks:
a LogReadError, and `rblog check` of many logs reports the others.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import rblog
from rblog.errors import LogReadError

from conftest import SAMPLES_DIR

DATA = Path(__file__).resolve().parents[1] / "data"
BAD, ORIG = DATA / "two_bytes_changed.rrd", DATA / "two_bytes_changed.orig.rrd"
RBLOG = str(Path(sys.executable).parent / "rblog")

_SDK_READ = """
import sys, warnings
import rerun as rr
warnings.simplefilter("ignore")
r = rr.chunk.RrdReader(sys.argv[1])
for s in r.recordings():
    for c in r.stream(store=s):
        c.to_record_batch()
"""


def test_the_file_is_two_bytes_from_a_good_log():
    a, b = BAD.read_bytes(), ORIG.read_bytes()
    assert len(a) == len(b) and sum(x != y for x, y in zip(a, b)) == 2
    assert rblog.load(ORIG).n_samples == 6


def test_the_sdk_reader_aborts_on_it():
    """The reproducer: the SDK's own reader dies of SIGABRT on the file (and reads its original)."""
    bad = subprocess.run([sys.executable, "-c", _SDK_READ, str(BAD)], capture_output=True,
                         text=True, timeout=120)
    assert bad.returncode == -6, (bad.returncode, bad.stderr[-500:])
    assert "panicked" in bad.stderr
    good = subprocess.run([sys.executable, "-c", _SDK_READ, str(ORIG)], capture_output=True,
                          text=True, timeout=120)
    assert good.returncode == 0, good.stderr[-500:]


def test_load_raises_a_log_read_error():
    with pytest.raises(LogReadError) as err:
        rblog.load(BAD)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(str(BAD)) and "byte 6603" in msg, msg


def test_check_of_many_logs_reports_the_others(tmp_path):
    """`rblog check a.rrd bad.rrd c.mcap` in a process of its own: a and c are reported, bad.rrd
    named unreadable, exit 2 (the worst of clean/flagged and unreadable), no abort."""
    scene = rblog.load_scene(SAMPLES_DIR / "tumbling_box.toml")
    a, c = tmp_path / "a.rrd", tmp_path / "c.mcap"
    from rblog.record import McapRecorder, RerunRecorder

    rblog.run(scene, duration=0.5, recorders=[RerunRecorder(str(a)), McapRecorder(str(c))])
    proc = subprocess.run([RBLOG, "check", str(a), str(BAD), str(c)], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 2, (proc.returncode, proc.stderr[-800:])
    assert f"{a}: " in proc.stdout and f"{c}: " in proc.stdout, proc.stdout
    errors = [line for line in proc.stderr.splitlines() if line.startswith("rblog: error")]
    assert len(errors) == 1 and str(BAD) in errors[0] and "unreadable" in errors[0], proc.stderr
    assert "Traceback" not in proc.stderr and "panicked" not in proc.stderr
