"""One exception family for rblog.

Every error a user can cause (a bad scene, an unreadable log, an unwritable output path, a run
that diverges) is an :class:`RblogError`. The CLI prints ``str(err)`` as one line and exits with
``err.exit_code``; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations


class RblogError(Exception):
    """Base of all errors rblog raises for a user's input or environment."""

    exit_code = 2


class SceneError(RblogError):
    """A scene file is missing, malformed, or holds a value outside what is allowed.

    The message names the file, the key path (``body[2].mass``) and what was expected.
    """

    def __init__(self, path: str, key: str, expected: str):
        self.path, self.key, self.expected = str(path), key, expected
        where = f"{self.path}: {key}" if key else self.path
        super().__init__(f"{where}: {expected}")


class LogReadError(RblogError):
    """A log file is missing, not a log of a format rblog reads, or unreadable."""

    def __init__(self, path: str, problem: str):
        self.path, self.problem = str(path), problem
        super().__init__(f"{self.path}: {problem}")


class LogWriteError(RblogError):
    """An output log cannot be created or written (bad path, no permission, disk full)."""

    def __init__(self, path: str, problem: str):
        self.path, self.problem = str(path), problem
        super().__init__(f"{self.path}: cannot write log: {problem}")


class SimulationDiverged(RblogError):
    """The state became NaN or infinite, or a free body turned more than
    ``rblog.engine.constants.MAX_ROTATION_PER_STEP_RAD`` in one step (``reason`` says which).
    Logs are finalized up to the last good sample."""

    exit_code = 3

    def __init__(self, step: int, time_s: float, body: int, body_name: str,
                 reason: str = "has a non-finite state"):
        self.step, self.time_s, self.body, self.body_name = step, time_s, body, body_name
        self.reason = reason
        super().__init__(
            f"simulation diverged at step {step} (t = {time_s:.6g} s): body {body} "
            f"({body_name!r}) {reason}; logs keep every sample before it"
        )


class RunInterrupted(RblogError):
    """The run was stopped by a signal: Ctrl-C (SIGINT, exit 130) or ``kill`` (SIGTERM, exit
    143), the shell's 128 + signal number. Logs are finalized up to the last good sample, with
    the status "interrupted"."""

    exit_code = 130

    def __init__(self, message: str, signum: int = 2):
        super().__init__(message)
        self.signum = int(signum)
        self.exit_code = 128 + self.signum
