"""rblog's click front end (installed as the package ``rblog_cli``).

This file is the first of rblog that the ``rblog`` program imports, so it answers SIGINT and
SIGTERM from that first instant: until the run loop installs its own handlers (which close the logs
and say at which step the run stopped, rblog.engine.runner), a signal prints one line and exits
128 + its number. No log is open then: the writers create their files only when the run opens
them, under the run loop's handlers. Without this, a Ctrl-C during the imports (the Rerun SDK
alone takes ~1 s on a loaded machine) printed click's ``Aborted!`` and exited 1, and a SIGTERM
exited silently.
"""

from __future__ import annotations

import os
import signal
import sys

#: what the one line says of the logs ("" for nothing); ``rblog run`` keeps it up to date
LOGS_STATE = [""]


def _exit_on_signal(signum, frame):
    name = signal.Signals(signum).name
    try:
        state = f" ({LOGS_STATE[0]})" if LOGS_STATE[0] else ""
        os.write(2, f"rblog: interrupted by {name}{state}\n".encode())
    finally:
        os._exit(128 + signum)


def answer_signals() -> None:
    """Install the one-line exit for SIGINT and SIGTERM (main thread of the ``rblog`` program)."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _exit_on_signal)


#: the ``rblog`` program (its console script) or ``python -m rblog_cli.main``; never a process
#: that merely imports the CLI (a test's CliRunner, where exiting is not ours to do)
_ARGV = list(getattr(sys, "orig_argv", sys.argv))
IN_PROGRAM = os.path.basename(sys.argv[0]) == "rblog" or (
    "-m" in _ARGV[:-1] and _ARGV[_ARGV.index("-m") + 1] == "rblog_cli.main")

if IN_PROGRAM:
    answer_signals()
    if sys.argv[1:2] == ["run"]:
        LOGS_STATE[0] = "no log written"
