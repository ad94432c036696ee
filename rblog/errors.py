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


# ---- by room: what each part of rblog raises ----------------------------------------------


class CheckOptionError(RblogError):
    """An unknown analyzer or tolerance name, or a tolerance that is not a number."""


class IncompatibleLogs(RblogError):
    """The two logs do not describe the same bodies, or share no sample time."""


class AuditFailed(RblogError):
    """``--fail-fast``: the live audit found a problem; the run stopped there (logs closed,
    readable, marked truncated). Exit code 1, as a failed ``rblog check``."""

    exit_code = 1

    def __init__(self, finding: "rblog.analyze.live.LiveFinding"):
        self.finding = finding
        f = finding.finding
        super().__init__(f"live audit: {finding.analyzer} finding at t = {f.t:.6g} s (step "
                         f"{f.step}): {f.message}; run stopped (--fail-fast), logs keep every "
                         "sample written before it")


class RecordError(RblogError):
    """Arrays handed to the Recorder do not fit the body table or the contract (a one-line
    message naming the argument, its shape and what was expected)."""


class AdapterError(RblogError):
    """An engine's model or data that the adapter cannot record (one line naming what and why),
    or the engine is not installed."""


class UnsupportedShapePair(RblogError):
    """The scene holds two shapes that may touch but have no collider in the narrowphase table.
    The names of the shape codes and the supported pairs are the narrowphase table's
    (rblog.engine.contact.narrowphase sets ``names`` and ``supported`` when it loads)."""

    names: dict = {}
    supported: str = ""

    def __init__(self, geom_a: int, geom_b: int, where: str):
        na = self.names.get(geom_a, f"shape code {geom_a}")
        nb = self.names.get(geom_b, f"shape code {geom_b}")
        super().__init__(f"no contact generation for {na}-{nb} ({where}); supported pairs: "
                         f"{self.supported}")


class ClusterUnavailable(RblogError):
    """Workers or a scheduler were asked for, but dask.distributed is not installed, or the
    scheduler cannot be reached."""


class EngineUnsupported(RblogError):
    """The scene (or an option) needs something the chosen engine cannot represent."""

    def __init__(self, engine: str, feature: str):
        super().__init__(f"--engine {engine}: cannot represent {feature}")


class EngineMissing(RblogError):
    """The engine asked for with ``--engine`` is not installed (the ``engines`` extra)."""

    def __init__(self, engine: str, err: Exception,
                 install: str = 'pip install -e ".[engines]" in a checkout (or pip install '
                                '"rblog[engines]")'):
        super().__init__(f"--engine {engine}: not installed ({type(err).__name__}: {err}); "
                         f"{install}")
