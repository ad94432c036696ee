"""`rblog check` gives the same report for any thread count (issue 18).

The analyzers run in a pool of threads (rblog.analyze.check, ``threads=``) and share the values of
one Context, computed once by whichever thread asks first. Each analyzer is a sequential
computation of the trajectory and of those shared values, so the JSON reports must be equal
character for character for 1, 2 and 6 threads: on clean closed-form cases and on planted faults
(findings, events, a non-finite sample), in the report order, whatever order the threads finish in.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from rblog.analyze import check
from test_analyze import bouncing_ball, head_on, resting_box, stacked_boxes


def _report(traj, threads):
    return json.dumps([r.to_dict(traj.model) for r in check(traj, threads=threads)])


def _nan_late(traj):
    traj.position[-5, 0, 2] = np.nan
    return traj


CASES = {
    "bounce e 0.8 against 0.9": lambda: bouncing_ball(e=0.8, e_config=0.9)[0],
    "head-on, b altered": lambda: head_on(e=1.0, alter_b=1.05)[0],
    "resting box sinks, creeps and jitters": lambda: resting_box(sink=2e-3, slide=2e-4,
                                                                 shake=2e-3),
    "stack, top sinks": lambda: stacked_boxes(sink_top=3e-3),
    "non-finite late sample": lambda: _nan_late(resting_box(slide=2e-4)),
}


@pytest.mark.parametrize("name", CASES)
def test_report_is_the_same_for_any_thread_count(name):
    traj = CASES[name]()
    one = _report(traj, 1)
    assert any(not r["passed"] for r in json.loads(one))  # every case plants a fault
    for threads in (2, 6):
        assert _report(traj, threads) == one, threads
