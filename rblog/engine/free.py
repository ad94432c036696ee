"""The kernels that advance free bodies (no contacts) many steps per call: C++
(csrc/engine/free.cpp, where the loops and their reasons are written), called here.

Bodies are independent without contacts, so the kernel runs over tiles of BODY_TILE bodies, steps
inside a tile: the tile's state stays in L1 for the whole block, and samples are written for
consecutive bodies; with samples SPARSE_STRIDE or more steps apart, bodies four (AVX2) or two at
a time in the lanes of a vector, their state in registers (bitwise the one-body results). Each
integrator has its own instantiation of the kernel (its step compiled into the loop; the stages
in csrc/engine/integrators.hpp). Samples are written after every ``stride``-th step (and after
the last step of the block when ``sample_last``).

Threads: :func:`advance_free` splits the bodies into contiguous BODY_TILE-aligned ranges
(:func:`body_ranges`), one per thread, and runs them as tasks of the engine's pool (rblog.engine.
_core, sized by ``_core.set_threads``; the GIL is released). A body's arithmetic does not depend
on which range it is in, so the result is bitwise the same for any thread count.
"""

from __future__ import annotations

from rblog.engine import _core
from rblog.engine.integrators import METHOD_NAMES
from rblog.engine.state import new_anchors

#: bodies advanced together, steps inner: their state (~180 B each) stays in L1, and a sample's
#: writes for consecutive bodies share cache lines (a bodies-outer loop wrote each body's samples
#: a whole sample-row apart: one cache miss per channel per sample).
BODY_TILE = 32
#: ... but when samples are this many steps apart or more, the write pattern does not matter and
#: one body at a time (its position and momentum in registers for the whole block) is faster.
SPARSE_STRIDE = 8
#: below this many body-steps in a call, one thread (a task hand-off costs more than it saves)
MIN_PARALLEL_BODY_STEPS = 200_000


def body_ranges(n_bodies: int, n_threads: int) -> list[tuple[int, int]]:
    """Contiguous [b0, b1) ranges, one per thread, split on BODY_TILE boundaries."""
    tiles = -(-n_bodies // BODY_TILE)
    k = max(1, min(n_threads, tiles))
    cuts = [min(n_bodies, ((tiles * t) // k) * BODY_TILE) for t in range(k + 1)]
    return [(cuts[t], cuts[t + 1]) for t in range(k) if cuts[t + 1] > cuts[t]]


def _check_method(method) -> int:
    method = int(method)
    if method not in METHOD_NAMES:
        raise ValueError(f"unknown integrator code {method}")
    return method


def _tile(stride: int) -> int:
    """Sparse samples: one body at a time; dense: tiles of bodies."""
    return 1 if stride >= SPARSE_STRIDE else BODY_TILE


def advance_free(method, ortho, dt, n_steps, stride, sample_last,
                 inv_mass, inv_inertia, force_world, torque_world,
                 position, linear_momentum, quat_wxyz, rotation, angular_momentum,
                 out_position, out_linear_momentum, out_quat_wxyz, out_rotation,
                 out_angular_momentum, n_threads=None, anchors=None):
    """Advance all bodies ``n_steps`` steps of ``dt`` on ``n_threads`` threads (default: the
    engine's pool, ``_core.threads()``; a larger count grows the pool); arguments and result as
    :func:`advance_free_range` over all bodies, bitwise the same for any thread count.
    ``anchors`` (rblog.engine.state.FlowAnchors, updated in place) carries the exact integrators'
    flow anchors from call to call, so a run gives the same result however it is split into
    calls; None: anchors for this call only."""
    method = _check_method(method)
    n = position.shape[0]
    if anchors is None:
        anchors = new_anchors(n)
    if n_threads is None:
        n_threads = _core.threads()
    elif n_threads > _core.threads():
        _core.set_threads(n_threads)
    ranges = body_ranges(n, n_threads) if n * n_steps >= MIN_PARALLEL_BODY_STEPS else [(0, n)]
    return _core.advance_free(method, ortho, dt, n_steps, stride, bool(sample_last), inv_mass,
                              inv_inertia, force_world, torque_world, position, linear_momentum,
                              quat_wxyz, rotation, angular_momentum, out_position,
                              out_linear_momentum, out_quat_wxyz, out_rotation,
                              out_angular_momentum, anchors, ranges, _tile(stride))


def advance_free_range(method, ortho, dt, n_steps, stride, sample_last,
                       inv_mass, inv_inertia, force_world, torque_world,
                       position, linear_momentum, quat_wxyz, rotation, angular_momentum,
                       out_position, out_linear_momentum, out_quat_wxyz, out_rotation,
                       out_angular_momentum, anchors, b0, b1):
    """Advance bodies b0 .. b1-1 ``n_steps`` steps of ``dt`` by integrator ``method`` on the
    calling thread; write their samples.

    Args:
        method, ortho: METHOD_* and ORTHO_* codes (rblog.engine.integrators).
        inv_mass: (N,).  inv_inertia: (N, 3) diag(I_body^-1).
        force_world: (N, 3) total constant force incl. gravity (N).  torque_world: (N, 3) (N m).
        position, linear_momentum, quat_wxyz, rotation, angular_momentum: state, updated in place.
        out_*: (S, N, ...) sample buffers, S >= n_steps // stride (+ 1 when sample_last and the
            last step is not a multiple of stride).
        anchors: rblog.engine.state.FlowAnchors, updated in place (exact integrators only).
        b0, b1: the body range (0, N for all).

    Returns:
        (n_samples, bad_step, bad_body): samples written, and the first local step (1-based) at
        which some body's state became non-finite or turned more than MAX_ROTATION_PER_STEP_RAD
        (-1 if none) and that body. The caller keeps only samples taken before a bad step.
    """
    method = _check_method(method)
    return _core.advance_free_range(method, ortho, dt, n_steps, stride, bool(sample_last),
                                    inv_mass, inv_inertia, force_world, torque_world, position,
                                    linear_momentum, quat_wxyz, rotation, angular_momentum,
                                    out_position, out_linear_momentum, out_quat_wxyz,
                                    out_rotation, out_angular_momentum, anchors, b0, b1,
                                    _tile(stride))


#: write_sample(method, j, i, position, linear_momentum, quat_wxyz, rotation, angular_momentum,
#: out_position, out_linear_momentum, out_quat_wxyz, out_rotation, out_angular_momentum): body
#: i's state into sample row j of the out_* buffers (q synced from R first for seed)
write_sample = _core.write_sample

