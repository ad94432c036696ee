"""A static body (welded to the world) in a MuJoCo log has no momentum to judge: `momentum`
names it only where a contact group it is in has other members, which are then left out with
it. Both ways on one model: a ball dropped onto a welded slab (the slab's contact group holds
the ball: named), and a marker body that collides with nothing (contype 0, as dm_control's
stacker 'target'; a group of its own at every interval: not named)."""

from __future__ import annotations

import pytest

mujoco = pytest.importorskip("mujoco")

import rblog  # noqa: E402
from rblog.adapters import mujoco as adapter  # noqa: E402

XML = """<mujoco><option timestep="0.002"/><worldbody><geom type="plane" size="2 2 0.1"/>
<body name="marker" pos="1 1 0.5"><geom type="box" size="0.02 0.02 0.02" contype="0" conaffinity="0"/></body>
{slab}
<body name="ball" pos="0 0 0.5"><freejoint/><geom type="sphere" size="0.05" mass="1"/></body>
</worldbody></mujoco>"""
SLAB = '<body name="slab" pos="0 0 0.2"><geom type="box" size="0.2 0.2 0.02"/></body>'


def _momentum(slab):
    m = mujoco.MjModel.from_xml_string(XML.format(slab=SLAB if slab else ""))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    rec = adapter.recorder(m, d, every=1)
    rec.step_and_record(d, 300)  # mj_step, then the recorder, 300 times
    rec.close()
    tr = rec.trajectory
    assert "marker" in tr.model.body_name
    return tr, next(r for r in rblog.check(tr, threads=1, only=["momentum"]))


def test_a_static_marker_that_touches_nothing_is_not_named():
    tr, res = _momentum(slab=False)
    assert res.verdict == "pass"
    assert not any("marker" in x for x in res.not_judged), res.not_judged


def test_a_static_slab_the_ball_lands_on_is_named():
    tr, res = _momentum(slab=True)
    ball = tr.model.body_name.index("ball")
    # it lands on the slab (top 0.22 m) and stays: centre 0.27 m up (MuJoCo's soft contact
    # sinks it well below a millimetre)
    assert tr.position[-1, ball, 2] == pytest.approx(0.27, abs=1e-3)
    line = [x for x in res.not_judged if "momentum not judged" in x]
    assert line and "'slab'" in line[0] and "is static" in line[0]
    assert "marker" not in line[0]
