"""Energy's contact-free stretches from the logged contact impulses (rblog.analyze.energy.touched):
where the log carries a body's contact impulses at every interval, an interval touches nothing
when the engine pushed the body with none. A MuJoCo ball falls 1 cm beside a wall, recorded at
every 10th step: its swept reach (a bound of 0.08 m an interval at 4 m/s) takes it to touch the
wall in every interval, while MuJoCo never makes a contact (ncon 0 at every step). Judged both
ways: the clean log passes on stretches it judges; a 5 % kinetic energy gain written into the
log only (the velocity scaled from sample 15 on, mid-fall; the allowance there is 0.06 J, 1.4 %:
Euler's first-order term m |g| dt |v|) is caught on the ball at that sample."""

from __future__ import annotations

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

import rblog  # noqa: E402
from rblog.adapters import mujoco as adapter  # noqa: E402
from rblog.record import rewritten  # noqa: E402

XML = """<mujoco><option timestep="0.002"/><worldbody><geom type="plane" size="2 2 0.1"/>
<geom name="wall" type="box" pos="0.11 0 1" size="0.05 0.5 1"/>
<body name="ball" pos="0 0 1"><freejoint/><geom type="sphere" size="0.05" mass="1"/></body>
</worldbody></mujoco>"""


def _record(steps):
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    rec = adapter.recorder(m, d, every=10)
    ncon = []
    for _ in range(steps):
        mujoco.mj_step(m, d)
        ncon.append(d.ncon)
        rec(d)
    rec.close()
    return rec.trajectory, np.array(ncon)


def _energy(tr):
    return next(r for r in rblog.check(tr, threads=1, only=["energy"]) if r.analyzer == "energy")


def test_a_ball_beside_a_wall_is_judged_and_a_planted_gain_is_caught():
    tr, ncon = _record(400)  # 0.8 s: it reaches the floor at 0.44 s
    falls_free = np.flatnonzero(ncon)[0] if ncon.any() else len(ncon)
    assert falls_free > 200  # MuJoCo's contacts begin at the floor only (measured: step 220)
    clean = _energy(tr)
    assert clean.verdict == "pass" and clean.stats["free_stretches"] >= 1, clean.reason
    k = 15  # step 150, mid-fall at 2.9 m/s
    v = tr.velocity.copy()
    v[k:] *= np.sqrt(1.05)
    kicked = _energy(rewritten(tr, velocity=v))
    assert kicked.verdict == "FAIL"
    f = kicked.findings[0]
    # the worst sample is the stretch's last before the floor, where the planted gain is
    # largest: 5 % of the kinetic energy there (m = 1 kg), on the clean run's own change
    # (Euler's first-order drop, -m g dt (v - v0) / 2 = -0.042 J)
    assert f.bodies == [0] and tr.t[k] <= f.t and f.step <= falls_free
    j = int(np.flatnonzero(np.isclose(tr.t, f.t))[0])
    e = 0.5 * np.sum(tr.velocity[:, 0] ** 2, axis=1) + 9.81 * tr.position[:, 0, 2]
    ke = 0.5 * np.sum(tr.velocity[j, 0] ** 2)
    # measured: 0.423 J (the message's 3 digits) against 0.4658 - 0.0428 J
    assert float(f.message.split("by ")[1].split(" J")[0]) == pytest.approx(
        e[j] - e[0] + 0.05 * ke, rel=2e-3)
