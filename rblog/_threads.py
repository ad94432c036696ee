"""How many threads rblog uses by default: ``default_threads()``.

The environment variable ``RBLOG_THREADS`` when it is set (a positive integer), else the machine's
CPU count (``os.cpu_count()``). The analyzers (``rblog check``: how many run at once) and the
engine use the same number. An invalid value is a one-line :class:`rblog.errors.RblogError`
naming the variable, not a silent fallback.

Outside the rooms (engine, analyze, record): imports nothing of rblog but rblog.errors.
"""

from __future__ import annotations

import os

from rblog.errors import RblogError

#: the environment variable that sets the default thread count
ENV = "RBLOG_THREADS"


def default_threads() -> int:
    """``RBLOG_THREADS`` if set (a positive integer; anything else raises RblogError), else
    ``os.cpu_count()`` (1 when Python cannot tell)."""
    raw = os.environ.get(ENV)
    if raw is None:
        return os.cpu_count() or 1
    text = raw.strip()
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1 or not text.lstrip("+").isdigit():
        raise RblogError(f"{ENV}={raw!r}: expected a positive integer (the default thread count)")
    return n


__all__ = ["ENV", "default_threads"]
