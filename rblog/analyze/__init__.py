"""Physics analyzers for recorded runs (`rblog check`).

Each analyzer takes a :class:`rblog.contract.trajectory.Trajectory` (what a log reader returns: logged
channels, model, run info, contacts) and returns a :class:`Result`; it never uses simulator
internals, so a log written by another program is checked the same way.

Example::

    from rblog.analyze import check
    results = check(traj, skip=["tunneling"], tolerances={"penetration.depth_m": 5e-4})
    clean = all(r.passed for r in results)

Analyzers (default tolerances and their reasons: rblog/analyze/tolerances.py):

* ``consistency``: channels agree with each other (quaternion order, matrix transpose, frames).
* ``drift``: rigidity of the logged rotation (orthonormality, det, |q|, body-fixed distances).
* ``momentum``: momentum conservation in collisions, friction cone, restitution, impact energy.
* ``penetration``: depth, jitter and creep of resting contacts, recomputed from poses.
* ``energy``: drift while only conservative forces act; gain across contacts.
* ``tunneling``: bodies passing through the ground, static boxes or each other between samples.
"""

from __future__ import annotations

#: public name -> the module of this package that defines it (imported on first use, PEP 562)
_LAZY = {
    "ANALYZERS": "suite", "check": "suite", "default_tolerances": "suite",
    "split_tolerances": "suite", "Analyzer": "base", "CheckOptionError": "base",
    "Context": "base", "Finding": "base", "Result": "base",
}

__all__ = sorted(_LAZY)


def __getattr__(name):
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(f"rblog.analyze.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'rblog.analyze' has no attribute {name!r}")
