"""The per-sample fast path: Recorder.sample_block rows filled in place, written a block at a
time, give the same log as one write of the whole run."""

from __future__ import annotations

import numpy as np
import pytest

import rblog


def _model():
    return rblog.body_table(name=["a", "b", "c"], shape="box", size=[[0.1, 0.2, 0.3]] * 3,
                            mass=[1.0, 2.0, 3.0], ground=True, impulses=("contact",))


def _run(T=600, seed=5):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(T, 3, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return dict(t=np.arange(T) * 1e-3, step=np.arange(T, dtype=np.int64),
                position=rng.normal(size=(T, 3, 3)), quat_wxyz=q, velocity=rng.normal(size=(T, 3, 3)),
                angular_velocity=rng.normal(size=(T, 3, 3)),
                impulse_contact_linear=rng.normal(size=(T, 3, 3)),
                impulse_contact_angular=rng.normal(size=(T, 3, 3)))


@pytest.mark.parametrize("fmt", ["mcap", "rrd"])
def test_sample_block_equals_one_write(tmp_path, fmt):
    a = _run()
    T = len(a["t"])
    with_contacts = np.arange(T) % 7 == 3  # a contact row on body 1 every 7th sample
    whole = dict(step=a["step"][with_contacts], body_a=np.ones(with_contacts.sum(), np.int64),
                 body_b=-np.ones(with_contacts.sum(), np.int64),
                 point=np.zeros((with_contacts.sum(), 3)), normal=np.tile([0, 0, 1.0], (with_contacts.sum(), 1)),
                 separation=np.full(with_contacts.sum(), -1e-4), normal_impulse=a["t"][with_contacts])
    ref = rblog.Recorder(_model(), dt=1e-3, keep=True, **{fmt: tmp_path / f"ref.{fmt}"})
    with ref:
        ref.write(**a, contacts=whole)
    rec = rblog.Recorder(_model(), dt=1e-3, keep=True, **{fmt: tmp_path / f"blk.{fmt}"})
    with rec:
        blk = rec.sample_block(capacity=256)
        for k in range(T):
            r = blk.row()
            blk.t[r], blk.step[r] = a["t"][k], a["step"][k]
            for name in ("position", "quat_wxyz", "velocity", "angular_velocity"):
                np.copyto(getattr(blk, name)[r], a[name][k])
            for part in (0.5, 0.5):  # impulses summed into the fresh (zero) row step by step
                blk.impulse_contact_linear[r] += part * a["impulse_contact_linear"][k]
                blk.impulse_contact_angular[r] += part * a["impulse_contact_angular"][k]
            if with_contacts[k]:
                blk.add_contacts(body_a=[1], body_b=[-1], point=[[0, 0, 0]], normal=[[0, 0, 1.0]],
                                 separation=[-1e-4], normal_impulse=[a["t"][k]])
            blk.commit()
        first = rec.blocks[0].position.copy()
    assert rec.blocks_written == 3  # 256 + 256 + the 88 that close() flushed
    assert np.array_equal(rec.blocks[0].position, first)  # a written block is not reused
    x, y = ref.trajectory, rec.trajectory
    for name in ("step", "t", "position", "quat_wxyz", "rotation", "angular_momentum",
                 "total_energy", "impulse_contact_angular"):
        assert getattr(x, name).tobytes() == getattr(y, name).tobytes(), name
    # 0.5 v + 0.5 v is v exactly (halving is exact in binary floating point)
    assert np.array_equal(y.impulse_contact_linear, a["impulse_contact_linear"])
    assert np.array_equal(x.contacts.step, y.contacts.step)
    assert np.array_equal(x.contacts.normal_impulse, y.contacts.normal_impulse)
    got = rblog.load(tmp_path / f"blk.{fmt}")
    assert got.position.tobytes() == x.position.tobytes() and len(got.contacts) == len(x.contacts)


def test_sample_block_errors_are_one_line():
    rec = rblog.Recorder(_model(), dt=1e-3)
    with pytest.raises(rblog.RecordError, match="capacity = 0"):
        rec.sample_block(0)
    blk = rec.sample_block(4)
    r = blk.row()
    blk.quat_wxyz[r] = [1, 0, 0, 0]
    blk.add_contacts(body_a=[0], body_b=[-1], point=[[0, 0, 0]], normal=[[0, 0, 1]],
                     separation=[0.0], normal_impulse=[0.0])
    blk.commit()
    blk.add_contacts(body_a=[0], body_b=[-1], point=[[0, 0, 0]], normal=[[0, 0, 1]],
                     separation=[0.0], normal_impulse=[0.0], kind=[1])
    blk.quat_wxyz[blk.row()] = [1, 0, 0, 0]
    blk.commit()
    with pytest.raises(rblog.RecordError) as err:
        blk.flush()
    assert "\n" not in str(err.value) and "same fields" in str(err.value)
