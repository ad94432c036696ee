"""rblog._threads.default_threads: RBLOG_THREADS when set (a positive integer), else the CPU count;
an invalid value is a one-line RblogError naming the variable. `rblog check` uses it as the
default number of analyzers run at once."""

from __future__ import annotations

import os

import pytest

from rblog._threads import default_threads
from rblog.errors import RblogError


def test_default_is_the_cpu_count(monkeypatch):
    monkeypatch.delenv("RBLOG_THREADS", raising=False)
    assert default_threads() == (os.cpu_count() or 1)


def test_the_environment_variable_sets_it(monkeypatch):
    monkeypatch.setenv("RBLOG_THREADS", "3")
    assert default_threads() == 3
    monkeypatch.setenv("RBLOG_THREADS", " 12 ")
    assert default_threads() == 12


@pytest.mark.parametrize("value", ["0", "-2", "two", "1.5", ""])
def test_an_invalid_value_is_a_one_line_error(monkeypatch, value):
    monkeypatch.setenv("RBLOG_THREADS", value)
    with pytest.raises(RblogError) as err:
        default_threads()
    msg = str(err.value)
    assert "RBLOG_THREADS" in msg and "\n" not in msg


def test_check_uses_it(monkeypatch):
    from test_analyze import resting_box

    from rblog.analyze import check

    traj = resting_box()
    monkeypatch.setenv("RBLOG_THREADS", "nope")
    with pytest.raises(RblogError):
        check(traj)
    monkeypatch.setenv("RBLOG_THREADS", "2")
    assert [r.passed for r in check(traj)] == [r.passed for r in check(traj, threads=1)]
