"""numba's write_sample (rblog/engine/free.py before the C++ port), kept for contact/step.py until
its C++ port lands (see rblog/engine/_numba_legacy/__init__.py)."""

from __future__ import annotations

from numba import njit

from rblog.engine._numba_legacy.integrators import METHOD_SEED, sync_quat


@njit(cache=True, inline="always")
def write_sample(method, j, i, position, linear_momentum, quat_wxyz, rotation, angular_momentum,
                 out_position, out_linear_momentum, out_quat_wxyz, out_rotation,
                 out_angular_momentum):
    """Copy body i's state into sample row j of the out_* buffers (q synced from R first).
    Inlined into the stepping loops: a call per body-sample (array arguments and their reference
    counts) cost ~6x the copy itself."""
    if method == METHOD_SEED:  # the only integrator whose q is not current
        sync_quat(method, quat_wxyz, rotation, i)
    for a in range(3):
        out_position[j, i, a] = position[i, a]
        out_linear_momentum[j, i, a] = linear_momentum[i, a]
        out_angular_momentum[j, i, a] = angular_momentum[i, a]
        for b in range(3):
            out_rotation[j, i, a, b] = rotation[i, a, b]
    for a in range(4):
        out_quat_wxyz[j, i, a] = quat_wxyz[i, a]
