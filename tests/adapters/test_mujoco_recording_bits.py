"""The compiled recording path of rblog.adapters.mujoco (the per-step call StepRecord, the hook,
the contact capture, the block resolve and state gather in C++) logs the bits of its numpy
path (every compiled piece turned off: rblog.adapters._hook not importable), channel by
channel, on dm_control models as shipped, at every step and at every 10th, with random
controls, a push (xfrc_applied) and steps the recorder does not see (a call after two
mj_steps: the interval's impulses unknown)."""

from __future__ import annotations

import hashlib
import sys

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")
pytest.importorskip("dm_control")
pytest.importorskip("rblog.adapters._hook")

import rblog.adapters.mujoco as adapter  # noqa: E402

STEPS = 60


def _run(m, every: int):
    """({channel: sha256 of its bytes} of a kept recording of STEPS steps, whether the
    compiled per-step call was in use at the end)."""
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    rec = adapter.recorder(m, d, every=every, keep=True, block=16)
    rng = np.random.default_rng(7)
    for i in range(STEPS):
        d.ctrl[:] = rng.uniform(-1.0, 1.0, m.nu)
        d.xfrc_applied[1:] = rng.normal(size=(m.nbody - 1, 6)) if 20 <= i < 30 else 0.0
        mujoco.mj_step(m, d)
        if i == 40:  # a step the recorder does not see
            mujoco.mj_step(m, d)
        rec(d)
    fast = rec._fast is not None
    rec.close()
    traj = rec.trajectory
    out = {}
    for name in ("t", "step", "position", "rotation", "quat_wxyz", "velocity", "angular_velocity"):
        out[name] = np.ascontiguousarray(getattr(traj, name))
    for name, value in vars(traj).items():
        if name.startswith(("impulse_", "work_")) and value is not None:
            out[name] = np.ascontiguousarray(value)
    if traj.contacts is not None:
        for name, value in vars(traj.contacts).items():
            if isinstance(value, np.ndarray):
                out[f"contacts.{name}"] = np.ascontiguousarray(value)
    return {k: hashlib.sha256(v.tobytes()).hexdigest() + str(v.shape) for k, v in out.items()}, fast


@pytest.mark.parametrize("every", [1, 10])
@pytest.mark.parametrize("name", ["humanoid", "stacker", "cartpole"])  # cartpole: RK4 as shipped
def test_compiled_recording_bits_equal_numpy(name, every, monkeypatch):
    m = adapter.suite_model(name)
    compiled, fast = _run(m, every)
    assert fast == (name != "cartpole")  # RK4: the hook runs mj_forward in Python
    monkeypatch.setitem(sys.modules, "rblog.adapters._hook", None)  # import -> ImportError
    numpy_path, fast = _run(m, every)
    assert not fast
    assert compiled.keys() == numpy_path.keys()
    assert any(k.startswith("impulse_") for k in compiled)
    differ = [k for k in compiled if compiled[k] != numpy_path[k]]
    assert not differ, f"channels not bitwise equal: {differ}"
