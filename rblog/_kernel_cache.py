"""Where numba keeps rblog's compiled kernels, settled before the kernels are defined.

Every kernel is ``njit(cache=True)``. Two problems with numba's defaults:

* **Stale kernels.** numba's cache index is keyed on the *defining* file's time stamp only: a
  kernel that inlines a function from another module keeps its old machine code after that other
  module changes (an upgrade, a pull, a local edit), and the run is silently wrong. rblog therefore
  caches in a folder named for the content of its own source, ``kernels-<sha256 of rblog/**.py>``:
  changed source, new folder, fresh compile; unchanged source, the cache is reused.
* **No writable folder.** When none can be written numba raises at *import* time ("cannot cache
  function ...: no locator available"), so even ``rblog --version`` died with a traceback.

:func:`settle_kernel_cache` (run once, when the ``rblog`` package is imported, before any kernel is
defined) takes the first writable base of:

1. ``NUMBA_CACHE_DIR`` as given (no warning when it works);
2. the user's cache folder, ``$XDG_CACHE_HOME/rblog`` or ``~/.cache/rblog``;
3. a private folder ``<tmp>/rblog-kernel-cache-<uid>``;

and points numba at ``<base>/kernels-<key>``, warning in one line only when an explicit
``NUMBA_CACHE_DIR`` could not be used. When none of them is writable: numba's own locations
(in-tree ``__pycache__``, checked with numba's locators; not content-keyed, said in the warning),
else no cache at all (kernels compile in every process: slower start, same results).

Old ``kernels-*`` folders are left in place (another installed version may use them); delete the
base folder to reclaim the space. Nothing here imports the engine; numba is imported only when the
keyed folders all fail.
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
from pathlib import Path
from typing import Callable

#: the folders holding compiled kernels (numba's in-tree cache is per source folder)
_KERNEL_DIRS = ("engine", "engine/contact", "contract", "analyze", "record", "study")


#: what settle_kernel_cache chose in this process (it runs once)
_SETTLED: str | None = None


def source_key() -> str:
    """``kernels-<first 16 hex digits of the SHA-256 of every rblog/**.py, path and bytes>``:
    2.9 ms for the 66 files of the package today."""
    root = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        h.update(p.relative_to(root).as_posix().encode())
        h.update(b"\0")
        h.update(p.read_bytes())
    return "kernels-" + h.hexdigest()[:16]


def _keyed(base: str, key: str) -> str:
    """``base/key``, unless base already is that folder (a worker process inherits the keyed
    ``NUMBA_CACHE_DIR`` of the process that started it)."""
    return base if os.path.basename(os.path.normpath(base)) == key else os.path.join(base, key)


def user_cache_dir() -> str | None:
    """``$XDG_CACHE_HOME/rblog``, else ``~/.cache/rblog``; None without a home folder."""
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg:
        return os.path.join(xdg, "rblog")
    home = os.path.expanduser("~")
    return None if home == "~" else os.path.join(home, ".cache", "rblog")


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
    """Choose where kernels are cached (module docstring), before any kernel is defined. Runs
    once per process; later calls return the first answer without a word.

    Args:
        warn: called with one line when rblog falls back from what the environment asked.

    Returns:
        what was chosen: ``"env"``, ``"user"``, ``"private"``, ``"numba"`` or ``"none"``.
    """
    global _SETTLED
    if _SETTLED is None:
        _SETTLED = _settle(warn)
    return _SETTLED


def _settle(warn: Callable[[str], None]) -> str:
    asked = os.environ.get("NUMBA_CACHE_DIR") or None
    key = source_key()
    bases = [("env", asked), ("user", user_cache_dir()), ("private", private_cache_dir())]
    for kind, base in bases:
        if base and _writable(_keyed(base, key)):
            _set_cache_dir(_keyed(base, key))
            if asked and kind != "env":
                warn(f"kernel cache {asked!r} is not writable; using {_keyed(base, key)!r}")
            return kind
    _set_cache_dir(None)
    if _numba_can_cache():
        warn("no writable kernel cache folder" + (f" ({asked!r} included)" if asked else "")
             + "; using numba's in-tree cache, which does not notice changes to rblog's source "
             "(clear its __pycache__ folders after an upgrade)")
        return "numba"
    _disable_caching()
    tried = [repr(d) for _, d in bases if d] + ["numba's own folders"]
    warn(f"no writable kernel cache ({', '.join(tried)}); kernels are compiled in every run")
    return "none"
