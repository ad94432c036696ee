"""Threads: results bitwise identical for any thread count (bodies are independent without
contacts, so a body's arithmetic must not depend on which thread's range it falls in)."""

from __future__ import annotations

import numpy as np
import pytest

from rblog.engine import free
from rblog.engine.integrators import METHOD_CODES, ORTHO_ALLOWED, ORTHO_CODES
from rblog.engine.rotation import quat_to_matrix_np


def _bodies(n, seed=3):
    rng = np.random.default_rng(seed)
    inertia = rng.uniform(0.5, 2.0, (n, 3))
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    params = (np.full(n, 0.7), 1.0 / inertia, np.tile([0.1, 0.0, -9.81], (n, 1)),
              rng.normal(size=(n, 3)) * 0.01)
    state = [rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), q, quat_to_matrix_np(q),
             rng.normal(size=(n, 3)) * 3.0]
    return params, state


def _run(integrator, n, n_steps, stride, threads, poison=None):
    params, state = _bodies(n)
    if poison is not None:  # a body whose momentum overflows: the kernel must report it
        body, value = poison
        state[1][body] = value
    s = n_steps // stride + 1
    out = [np.zeros((s, n, 3)), np.zeros((s, n, 3)), np.zeros((s, n, 4)), np.zeros((s, n, 3, 3)),
           np.zeros((s, n, 3))]
    ortho = ORTHO_CODES[ORTHO_ALLOWED[integrator][1]]
    res = free.advance_free(METHOD_CODES[integrator], ortho, 1e-3, n_steps, stride, True, *params,
                            *state, *out, n_threads=threads)
    return res, state, out


@pytest.mark.parametrize("integrator", ["seed", "splitting", "rk4"])
@pytest.mark.parametrize("stride", [1, 10])  # dense (tiles) and sparse (one body at a time)
def test_free_kernel_bitwise_same_for_any_thread_count(monkeypatch, integrator, stride):
    monkeypatch.setattr(free, "MIN_PARALLEL_BODY_STEPS", 0)
    n = 3 * free.BODY_TILE + 5  # ranges that do not split evenly
    ref = _run(integrator, n, 40, stride, 1)
    assert ref[0] == (4 if stride == 10 else 40, -1, -1)
    for threads in (2, 3, 4):
        got = _run(integrator, n, 40, stride, threads)
        assert got[0] == ref[0]
        for a, b in zip(got[1] + got[2], ref[1] + ref[2]):
            assert a.tobytes() == b.tobytes()


def test_bad_body_reported_as_serial(monkeypatch):
    """The earliest non-finite body wins, whichever thread stepped it."""
    monkeypatch.setattr(free, "MIN_PARALLEL_BODY_STEPS", 0)
    n = 4 * free.BODY_TILE
    # momentum 1e308 overflows at the first kick-drift; body in the last range
    ref = _run("splitting", n, 20, 1, 1, poison=(n - 3, 1e308))
    assert ref[0][1] == 1 and ref[0][2] == n - 3
    for threads in (2, 4):
        assert _run("splitting", n, 20, 1, threads, poison=(n - 3, 1e308))[0] == ref[0]


def test_body_ranges_cover_every_body_once():
    for n in (1, 31, 32, 33, 1000, 10_007):
        for t in (1, 2, 3, 8):
            r = free.body_ranges(n, t)
            assert r[0][0] == 0 and r[-1][1] == n
            assert all(a[1] == b[0] for a, b in zip(r, r[1:]))
            assert all(b0 % free.BODY_TILE == 0 for b0, _ in r)
