"""Transitional: the numba versions of the rotation, integrator and exact-flow helpers and of
``write_sample``, as they were before the free-body code moved to C++ (rblog.engine._core).

rblog.engine.contact.step and .project are still numba until their own C++ port lands, and they
import ``load_mat``, ``omega_world`` (rotation), ``write_sample`` (free), ``drift_rotation``,
``drift_exact_anchored``, ``sync_quat``, ``turn_within_bound`` (integrators) into compiled code, so
while ``ACTIVE`` those names of the public modules resolve here (the modules' ``__getattr__``);
everything else, and every name once ``ACTIVE`` is False, is the C++ binding. Delete this package
(and the ``_LEGACY`` blocks of rotation.py, integrators.py, free.py) when step.py and project.py
no longer compile numba code. ``RBLOG_NUMBA_LEGACY=0`` turns it off (tests of the C++ bindings).
"""

from __future__ import annotations

import os

ACTIVE = os.environ.get("RBLOG_NUMBA_LEGACY", "1") != "0"
