"""A quaternion turned 0.05 rad in the log only (issue 37's planted faults): two boxes stacked
in MuJoCo, recorded through the adapter; from sample 100 (t = 2 s, both at rest) the upper
box's logged orientation is turned 0.05 rad about x and nothing else changes. Its lower edge
then dips 0.1 sin a + 0.05 cos a - 0.05 = 4.94 mm further into the lower box (closed form of
the 0.2 x 0.2 x 0.1 m box), on top of MuJoCo's own resting depth (contact.dist in the log's
contact rows): the penetration analyzer finds exactly that pair, from the turn on, at that
depth, and no other analyzer flags anything."""

from __future__ import annotations

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

import rblog  # noqa: E402
from rblog.adapters import mujoco as adapter  # noqa: E402
from rblog.record import rewritten  # noqa: E402

XML = """<mujoco><option timestep="0.002"/><worldbody><geom type="plane" size="2 2 0.1"/>
<body name="lower" pos="0 0 0.05"><freejoint/><geom type="box" size="0.1 0.1 0.05" mass="1"/></body>
<body name="upper" pos="0 0 0.15"><freejoint/><geom type="box" size="0.1 0.1 0.05" mass="1"/></body>
</worldbody></mujoco>"""


def _quat_mul(p, q):
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def test_a_quaternion_turned_in_the_log_only_is_one_pair_at_its_depth():
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    rec = adapter.recorder(m, d, every=10)
    rec.step_and_record(d, 1500)  # mj_step, then the recorder, 1500 times
    rec.close()
    tr = rec.trajectory
    # clean: nothing flagged; energy has nothing to judge (the boxes touch in every interval,
    # and a resting contact is no event), so it says so
    assert all(r.verdict in ("pass", "skip") or (r.analyzer, r.verdict) == ("energy", "not judged")
               for r in rblog.check(tr, threads=1))
    k, a = 100, 0.05
    q = tr.quat_wxyz.copy()
    turn = np.array([np.cos(a / 2), np.sin(a / 2), 0.0, 0.0])
    for i in range(k, len(q)):
        q[i, 1] = _quat_mul(turn, q[i, 1])
    results = rblog.check(rewritten(tr, writer="turned", quat_wxyz=q), threads=1)
    flagged = [r for r in results if r.verdict == "FAIL"]
    assert [r.analyzer for r in flagged] == ["penetration"], [(r.analyzer, r.reason) for r in flagged]
    pen = flagged[0]
    assert pen.findings and all(sorted(f.bodies) in ([0], [1]) for f in pen.findings)
    assert all(f.t >= tr.t[k] for f in pen.findings)
    # MuJoCo's own resting depth of the pair after the turn's sample (its contact rows)
    c = tr.contacts
    pair = (c.body_a >= 0) & (c.body_b >= 0) & (c.step >= tr.step[k])
    resting = -c.separation[pair].min()
    extra = 0.1 * np.sin(a) + 0.05 * np.cos(a) - 0.05
    # measured: 5.14266 mm found against 4.93543 + 0.20723 mm (0.1 um apart)
    assert pen.worst_value == pytest.approx(extra + resting, abs=1e-6), (pen.worst_value, extra, resting)
