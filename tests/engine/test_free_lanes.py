"""The free kernel's lane kernels (csrc/engine/lanes.hpp, free.cpp): bodies stepped two (SSE2) or
four (AVX2) at a time in the lanes of a vector must give bitwise the bits of the scalar kernel,
one body at a time, for every integrator and orthonormalization: each lane does the scalar
code's operations in its order. The scalar reference is the tiled kernel (samples at the same
steps), forced by raising SPARSE_STRIDE; the lanes run on the sparse path."""

from __future__ import annotations

import numpy as np
import pytest

from rblog.engine import _core, free
from rblog.engine.integrators import METHOD_CODES, ORTHO_ALLOWED, ORTHO_CODES
from rblog.engine.rotation import quat_to_matrix_np

LANES = (2, 4) if _core.free_lanes() == 4 else (2,)


def _bodies(n, poison, seed=5):
    """Torque-free bodies (the exact kernel's lanes) with a few exceptions: torqued bodies, one at
    rest (a steady flow), one symmetric (n = 0); with ``poison`` one whose momentum overflows on
    the first step (its lane stops, the others go on alone)."""
    rng = np.random.default_rng(seed)
    inertia = rng.uniform(0.5, 2.0, (n, 3))
    inertia[7, 1] = inertia[7, 0]
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    torque = np.zeros((n, 3))
    torque[[5, 17]] = rng.normal(size=(2, 3))
    params = (np.full(n, 0.7), 1.0 / inertia, np.tile([0.1, 0.0, -9.81], (n, 1)), torque)
    momentum = rng.normal(size=(n, 3))
    if poison:
        momentum[14] = 1e308
    angular = rng.normal(size=(n, 3)) * 1.5
    angular[9] = 0.0
    state = [rng.normal(size=(n, 3)), momentum, q, quat_to_matrix_np(q), angular]
    return params, state


def _run(integrator, ortho, poison=False, n=23, n_steps=200, stride=40, dt=0.01):
    params, state = _bodies(n, poison)
    s = n_steps // stride + 1
    out = [np.zeros((s, n, 3)), np.zeros((s, n, 3)), np.zeros((s, n, 4)), np.zeros((s, n, 3, 3)),
           np.zeros((s, n, 3))]
    res = free.advance_free(METHOD_CODES[integrator], ORTHO_CODES[ortho], dt, n_steps, stride,
                            True, *params, *state, *out, n_threads=1)
    return res, state, out


@pytest.mark.parametrize("integrator", list(METHOD_CODES))
def test_lanes_give_the_scalar_kernels_bits(monkeypatch, integrator):
    before = _core.free_lanes()
    try:
        for ortho in ORTHO_ALLOWED[integrator][0]:
            with monkeypatch.context() as mp:
                mp.setattr(free, "SPARSE_STRIDE", 10**9)  # tiles: the scalar step_body
                ref = _run(integrator, ortho)
            assert ref[0] == (5, -1, -1), ortho  # samples at steps 40, 80, ..., 200
            for lanes in LANES:
                _core.set_free_lanes(lanes)
                got = _run(integrator, ortho)
                assert got[0] == ref[0], (ortho, lanes)
                for a, b in zip(got[1] + got[2], ref[1] + ref[2]):
                    assert a.tobytes() == b.tobytes(), (ortho, lanes)
            # a lane going bad: the tiled kernel stops its whole tile there, the lanes go on with
            # the other bodies, so widths are compared with each other (the bad body's NaNs may
            # differ in sign, lanes.hpp: its row is compared by where it is finite)
            runs = []
            for lanes in LANES:
                _core.set_free_lanes(lanes)
                runs.append(_run(integrator, ortho, poison=True))
            assert runs[0][0][1:] == (1, 14)
            for got in runs[1:]:
                assert got[0] == runs[0][0], ortho
                for a, b in zip(got[1] + got[2], runs[0][1] + runs[0][2]):
                    ax = 0 if a.shape[0] == 23 else 1
                    assert np.delete(a, 14, ax).tobytes() == np.delete(b, 14, ax).tobytes(), ortho
                    assert np.array_equal(np.isfinite(a), np.isfinite(b)), ortho
    finally:
        _core.set_free_lanes(before)


def test_set_free_lanes_rejects_other_widths():
    with pytest.raises(ValueError, match="lanes"):
        _core.set_free_lanes(3)
