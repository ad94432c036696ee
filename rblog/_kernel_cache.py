"""Where numba keeps rblog's compiled kernels, settled before the kernels are defined.

Every kernel is ``njit(cache=True)``. numba picks the first usable of: ``NUMBA_CACHE_DIR``,
``__pycache__`` beside the source file (in-tree), a per-user cache folder; when none can be
written it raises at *import* time ("cannot cache function ...: no locator available"), so even
``rblog --version`` died with a traceback. :func:`settle_kernel_cache` (called by the CLI before it
imports the engine) tries, in order, and says in one warning line what it fell back to:

1. ``NUMBA_CACHE_DIR`` as given (no warning when it works);
2. when it is set but unusable: a private folder ``<tmp>/rblog-kernel-cache-<uid>``;
3. numba's own locations (in-tree, per-user), checked with numba's own locators;
4. the private folder (when ``NUMBA_CACHE_DIR`` was not set);
5. no cache at all: kernels compile in every process (slower start, same results).

Nothing here imports the engine. Step 3 imports numba (only when steps 1-2 did not settle it).
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path
from typing import Callable

#: the folders holding compiled kernels (numba's in-tree cache is per source folder)
_KERNEL_DIRS = ("engine", "engine/contact", "contract", "analyze", "record", "study")


def _writable(d: str) -> bool:
    try:
        os.makedirs(d, exist_ok=True)
        with tempfile.TemporaryFile(dir=d):
            pass
        return True
    except OSError:
        return False


def private_cache_dir() -> str | None:
    """The fallback folder ``<tempdir>/rblog-kernel-cache-<uid>``, or None when the system has
    no usable temporary folder."""
    try:
        tmp = tempfile.gettempdir()
    except OSError:  # "No usable temporary directory found"
        return None
    return os.path.join(tmp, f"rblog-kernel-cache-{os.getuid()}")


def _numba_can_cache() -> bool:
    """True when numba's own locators (NUMBA_CACHE_DIR unset) can cache a kernel of every
    kernel folder of rblog: the check numba makes when a ``cache=True`` function is defined."""
    from numba.core import caching

    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl")
    root = Path(__file__).resolve().parent

    def probe():  # stands for a kernel: the locators use its line number and the file path
        pass

    for sub in _KERNEL_DIRS:
        files = sorted((root / sub).glob("*.py"))
        if not files:
            continue
        if not any(cls.from_function(probe, str(files[0])) is not None
                   for cls in impl._locator_classes):
            return False
    return True


def _set_cache_dir(d: str | None) -> None:
    if d is None:
        os.environ.pop("NUMBA_CACHE_DIR", None)
    else:
        os.environ["NUMBA_CACHE_DIR"] = d
    if "numba" in sys.modules:  # numba read the variable when imported
        from numba.core import config

        config.CACHE_DIR = d or ""


def _disable_caching() -> None:
    """Make ``cache=True`` a no-op for every dispatcher defined from now on: each keeps numba's
    NullCache (compile in memory only) instead of raising for want of a cache folder."""
    from numba.core.dispatcher import Dispatcher

    Dispatcher.enable_caching = lambda self: None


def settle_kernel_cache(warn: Callable[[str], None]) -> str:
    """Choose where kernels are cached (module docstring), before any kernel is defined.

    Args:
        warn: called with one line when rblog falls back from what the environment asked.

    Returns:
        what was chosen: ``"env"``, ``"private"``, ``"numba"`` or ``"none"``.
    """
    asked = os.environ.get("NUMBA_CACHE_DIR") or None
    if asked and _writable(asked):
        return "env"
    private = private_cache_dir()
    if asked and private and _writable(private):
        _set_cache_dir(private)
        warn(f"kernel cache {asked!r} is not writable; using {private!r}")
        return "private"
    _set_cache_dir(None)
    if _numba_can_cache():
        if asked:
            warn(f"kernel cache {asked!r} is not writable; using numba's default")
        return "numba"
    if not asked and private and _writable(private):
        _set_cache_dir(private)
        warn(f"numba cannot cache kernels beside rblog or in the user's cache folder; using "
             f"{private!r}")
        return "private"
    _disable_caching()
    tried = [repr(d) for d in (asked, private) if d] + ["numba's own folders"]
    warn(f"no writable kernel cache ({', '.join(tried)}); kernels are compiled in every run")
    return "none"
