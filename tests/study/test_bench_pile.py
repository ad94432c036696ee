"""benchmarks/bench_pile.py's thread ratios: wall time over the first thread count, and the
process CPU time's beside it (both threads summed)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from bench_pile import thread_ratios  # noqa: E402


def test_thread_ratio_is_the_wall_speed_up():
    # 2,000 steps: one thread in 10 s of wall and CPU; two threads in 6 s of wall that kept both
    # busy (12 s of CPU): 10 / 6 = 1.667x in wall time, 10 / 12 = 0.833x in CPU time
    runs = {"rblog-1t": (1, 2000 / 10.0, 2000 / 10.0), "rblog-2t": (2, 2000 / 6.0, 2000 / 12.0)}
    [(name, nt, nt0, wall, cpu)] = thread_ratios(runs)
    assert (name, nt, nt0) == ("rblog-2t", 2, 1)
    assert wall == pytest.approx(10.0 / 6.0, rel=1e-12)
    assert cpu == pytest.approx(10.0 / 12.0, rel=1e-12)


def test_thread_ratios_need_two_counts():
    assert thread_ratios({}) == []
    assert thread_ratios({"rblog-1t": (1, 100.0, 100.0)}) == []
    # against the first count given, whatever its order
    r = thread_ratios({"rblog-2t": (2, 150.0, 80.0), "rblog-1t": (1, 100.0, 100.0)})
    assert [(n, a, b) for n, a, b, _, _ in r] == [("rblog-1t", 1, 2)]
    assert r[0][3] == pytest.approx(100.0 / 150.0)
