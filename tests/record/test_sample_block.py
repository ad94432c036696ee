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
            if with_contacts[k] and k % 2:
                blk.add_contacts(body_a=[1], body_b=[-1], point=[[0, 0, 0]], normal=[[0, 0, 1.0]],
                                 separation=[-1e-4], normal_impulse=[a["t"][k]])
            elif with_contacts[k]:  # the same row through the in-place views
                c = blk.contact_rows(1)
                c.body_a[0], c.body_b[0], c.normal[0, 2] = 1, -1, 1.0
                c.separation[0], c.normal_impulse[0] = -1e-4, a["t"][k]
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
    blk.quat_wxyz[blk.row()] = [1, 0, 0, 0]
    for bad, words in (({"body_a": [0], "colour": [1]}, "unknown field 'colour'"),
                       ({"body_a": [0], "point": [[0, 0]]}, "point has shape (1, 2), expected (1, 3)")):
        with pytest.raises(rblog.RecordError) as err:
            blk.add_contacts(**bad)
        assert "\n" not in str(err.value) and words in str(err.value), str(err.value)
    with pytest.raises(rblog.RecordError, match="fields"):
        rec.sample_block(4, fields=("quat_wxyz", "velocity"))  # no position


def test_contact_messages_added_in_bulk_are_the_writers_bytes(tmp_path, monkeypatch):
    # a block's rblog.Contacts messages go into the chunk in one piece; the file is the one
    # mcap's Writer writes adding them one by one (chunks closed at the same records: 4 MB, so
    # several 1 MiB chunks close inside blocks)
    from rblog.record import mcap_writer as MW

    m = rblog.body_table(name=["a", "b"], shape="box", size=[[0.1, 0.1, 0.1]] * 2, mass=[1.0, 1.0],
                         ground=True)
    T, rng = 3000, np.random.default_rng(1)
    k = 2 * T
    rows = dict(step=np.repeat(np.arange(T), 2), body_a=np.tile([0, 1], T), body_b=-np.ones(k, int),
                point=rng.normal(size=(k, 3)), normal=np.tile([0, 0, 1.0], (k, 1)),
                separation=rng.normal(size=k), normal_impulse=rng.random(k))
    arr = dict(t=np.arange(T) * 1e-3, step=np.arange(T), position=rng.normal(size=(T, 2, 3)),
               quat_wxyz=np.tile([1.0, 0, 0, 0], (T, 2, 1)), velocity=np.zeros((T, 2, 3)),
               angular_velocity=np.zeros((T, 2, 3)))

    def record(path):
        with rblog.Recorder(m, dt=1e-3, mcap=path, mcap_compression="none") as rec:
            for lo in range(0, T, 500):
                sel = (rows["step"] >= lo) & (rows["step"] < lo + 500)
                rec.write(**{n: v[lo:lo + 500] for n, v in arr.items()},
                          contacts={n: v[sel] for n, v in rows.items()})

    record(tmp_path / "bulk.mcap")

    def one_by_one(self, ch, ns, buf, ends):
        for i, t in enumerate(np.asarray(ns).tolist()):
            self._w.add_message(ch, t, bytes(buf[ends[i]:ends[i + 1]]), t)

    monkeypatch.setattr(MW._BlockChunkBuilder, "add_messages", one_by_one)
    record(tmp_path / "one.mcap")
    bulk, one = (tmp_path / "bulk.mcap").read_bytes(), (tmp_path / "one.mcap").read_bytes()
    assert len(bulk) > 3 * MW.CHUNK_BYTES and bulk == one
    assert len(rblog.load(tmp_path / "bulk.mcap").contacts) == k
