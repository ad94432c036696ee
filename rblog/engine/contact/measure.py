"""Penetration audits: the narrowphase run on a given configuration, nothing else (the kernel:
csrc/engine/measure.cpp, pair_min_separations).

``separations`` measures any state (rblog's, or another engine's converted to rblog's model) with
the same geometry code, so penetration statistics of two engines are comparable.
"""

from __future__ import annotations

import numpy as np

from rblog.engine import _core
from rblog.engine.contact import narrowphase as _narrowphase  # noqa: F401  (sets the C++ constants)


def separations(world, position, rotation, margin: float = 0.0) -> np.ndarray:
    """Least separation (m, < 0 penetration) of every touching pair of shapes (the bodies' geoms,
    static boxes, ground) at this configuration, for the model of ``world`` (a ContactWorld)."""
    position = np.ascontiguousarray(position, float)
    rotation = np.ascontiguousarray(rotation, float)
    bd, st = world._bodies, world._statics
    return _core.pair_min_separations(
        bd, int(st.n_static),
        st.pos, st.rot, st.ext, st.lo, st.hi, bool(st.ground), st.gn, float(st.goff), position,
        rotation, float(margin))


def max_penetration(world, position, rotation) -> float:
    """Deepest penetration (m, >= 0) between any two shapes at this configuration."""
    s = separations(world, position, rotation)
    return float(max(0.0, -s.min())) if len(s) else 0.0
