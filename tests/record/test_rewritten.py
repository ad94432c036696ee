"""rblog.record.rewritten: a log recorded again with some arrays replaced, the rest as logged;
an array a log does not have is a one-line RecordError naming it."""

from __future__ import annotations

import numpy as np
import pytest

import rblog
from rblog.record import RecordError, rewritten


def _log():
    scene = rblog.load_scene("samples/bouncing_ball.toml")
    traj, _ = rblog.simulate(scene, duration=0.5)
    return traj


def test_the_arrays_not_given_stay_as_logged():
    tr = _log()
    v = tr.velocity.copy()
    v[10:, 0, 2] += 1.0
    out = rewritten(tr, velocity=v)
    np.testing.assert_array_equal(out.velocity, v)
    for name in ("t", "step", "position", "quat_wxyz", "angular_velocity"):
        np.testing.assert_array_equal(getattr(out, name), getattr(tr, name))
    for name in tr.interval_channels:
        np.testing.assert_array_equal(getattr(out, name), getattr(tr, name))
    assert len(out.contacts) == len(tr.contacts)
    assert out.info.dt == tr.info.dt and out.info.writer == "rewritten"


def test_an_unknown_array_is_named():
    with pytest.raises(RecordError, match=r"rewritten: velocty: not arrays of a log \(expected "):
        rewritten(_log(), velocty=np.zeros(3))
