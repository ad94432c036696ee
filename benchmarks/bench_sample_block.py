"""CPU cost of recording one sample at a time: Recorder.write per sample vs Recorder.sample_block
(rows filled in place, one write per block), into an .mcap file and in memory.

    python benchmarks/bench_sample_block.py [--bodies 16] [--samples 5000] [--pairs 3] [--contacts 4]

Reports CPU time (process_time, all threads) per sample, median over interleaved pairs; the
state is random, with the contact and joint impulses a MuJoCo recording logs, and ``--contacts``
contact rows per sample (as a resting stack has).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

import rblog


def _model(n: int):
    return rblog.body_table(name=[f"b{i}" for i in range(n)], shape="box", size=[[0.1, 0.1, 0.1]] * n,
                            mass=[1.0] * n, impulses=("contact", "joint"))


def _state(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    return dict(position=rng.normal(size=(n, 3)), quat_wxyz=q / np.linalg.norm(q, axis=1, keepdims=True),
                velocity=rng.normal(size=(n, 3)), angular_velocity=rng.normal(size=(n, 3)),
                impulse=rng.normal(size=(n, 3)))


def _rows(k: int, contacts: int) -> dict:
    return dict(step=np.full(contacts, k), body_a=np.zeros(contacts, np.int64),
                body_b=-np.ones(contacts, np.int64), point=np.zeros((contacts, 3)),
                normal=np.tile([0.0, 0.0, 1.0], (contacts, 1)), separation=np.zeros(contacts),
                normal_impulse=np.ones(contacts))


def per_write(model, st, samples: int, contacts: int = 0, **out) -> float:
    J = st["impulse"][None]
    with rblog.Recorder(model, dt=1e-3, **out) as rec:
        t0 = time.process_time()
        for k in range(samples):
            rec.write(t=[k * 1e-3], step=[k], position=st["position"][None],
                      quat_wxyz=st["quat_wxyz"][None], velocity=st["velocity"][None],
                      angular_velocity=st["angular_velocity"][None], impulse_contact_linear=J,
                      impulse_contact_angular=J, impulse_joint_linear=J, impulse_joint_angular=J,
                      contacts=_rows(k, contacts) if contacts else None)
        rec.close()
        return (time.process_time() - t0) / samples


def per_row(model, st, samples: int, contacts: int = 0, **out) -> float:
    J = st["impulse"]
    with rblog.Recorder(model, dt=1e-3, **out) as rec:
        blk = rec.sample_block(256)
        t0 = time.process_time()
        for k in range(samples):
            r = blk.row()
            blk.t[r], blk.step[r] = k * 1e-3, k
            np.copyto(blk.position[r], st["position"])
            np.copyto(blk.quat_wxyz[r], st["quat_wxyz"])
            np.copyto(blk.velocity[r], st["velocity"])
            np.copyto(blk.angular_velocity[r], st["angular_velocity"])
            for name in ("impulse_contact_linear", "impulse_contact_angular",
                         "impulse_joint_linear", "impulse_joint_angular"):
                getattr(blk, name)[r] += J
            if contacts:  # the rows filled in place, as an adapter copies an engine's arrays
                c = blk.contact_rows(contacts)
                c.normal[:, 2] = 1.0
                c.body_b[:] = -1
                c.normal_impulse[:] = 1.0
            blk.commit()
        rec.close()
        return (time.process_time() - t0) / samples


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bodies", type=int, default=16)
    ap.add_argument("--samples", type=int, default=5000)
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("--contacts", type=int, default=0)
    a = ap.parse_args()
    model, st = _model(a.bodies), _state(a.bodies)
    with tempfile.TemporaryDirectory() as tmp:
        mcap = {"mcap": str(Path(tmp) / "x.mcap")}
        runs = {"write() per sample, mcap": (per_write, mcap),
                "sample_block, mcap": (per_row, mcap),
                "write() per sample, memory": (per_write, {"keep": True}),
                "sample_block, memory": (per_row, {"keep": True})}
        times = {k: [] for k in runs}
        for _ in range(a.pairs):
            for k, (fn, out) in runs.items():
                times[k].append(fn(model, st, a.samples, a.contacts, **out))
    for k, v in times.items():
        print(f"{k:30s} {statistics.median(v) * 1e6:8.1f} us CPU per sample ({a.bodies} bodies, "
              f"{a.contacts} contact rows)")


if __name__ == "__main__":
    main()
