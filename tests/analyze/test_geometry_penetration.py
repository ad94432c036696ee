"""Penetration per geom pair for bodies without a v2 shape (a capsule and a cylinder on a floor,
logged from MuJoCo), judged with the audit's own geometry (rblog.analyze.shapes).

The truth is MuJoCo's: its contacts' ``dist`` after ``mj_forward`` at the logged poses. The
bodies start just above the floor (stiff contacts, solref 5 ms): a clean log passes with
MuJoCo's deepest depth; the capsule sunk 20 mm in the log from t = 0.6 s is
flagged on the capsule-floor pair at 0.6 s with MuJoCo's depth there.
"""

from __future__ import annotations

import numpy as np
import pytest

import rblog
from rblog.analyze import check

mujoco = pytest.importorskip("mujoco")

XML = """
<mujoco>
  <option timestep="0.002"/>
  <default><geom solref="0.005 1"/></default>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1"/>
    <body name="limb" pos="0 0 0.068" euler="0 80 0">
      <freejoint/>
      <geom name="limb" type="capsule" size="0.04 0.15"/>
    </body>
    <body name="can" pos="0.5 0 0.089" euler="10 0 0">
      <freejoint/>
      <geom name="can" type="cylinder" size="0.05 0.08"/>
    </body>
  </worldbody>
</mujoco>
"""
_TYPES = {"plane": "plane", "capsule": "capsule", "cylinder": "cylinder"}


def _quat(mat9):
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.asarray(mat9, float))
    return q


def mujoco_log(seconds=1.2):
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    n = m.nbody - 1
    tname = {int(mujoco.mjtGeom.mjGEOM_PLANE): "plane",
             int(mujoco.mjtGeom.mjGEOM_CAPSULE): "capsule",
             int(mujoco.mjtGeom.mjGEOM_CYLINDER): "cylinder"}
    gb = m.geom_bodyid
    gpos, gquat = [], []
    for g, b in enumerate(gb):
        rb = d.ximat[b].reshape(3, 3) if b else np.eye(3)
        xb = d.xipos[b] if b else np.zeros(3)
        gpos.append(rb.T @ (d.geom_xpos[g] - xb))
        gquat.append(_quat((rb.T @ d.geom_xmat[g].reshape(3, 3)).ravel()))
    model = rblog.body_table(
        name=["limb", "can"], mass=m.body_mass[1:], inertia_diag=m.body_inertia[1:],
        geoms=dict(body=gb - 1, type=[tname[int(t)] for t in m.geom_type], size=m.geom_size,
                   pos_body=gpos, quat_wxyz_body=gquat, name=["floor", "limb", "can"]),
        collide_rule="or", gravity=m.opt.gravity)
    steps = int(round(seconds / m.opt.timestep))
    every = 5
    out = {k: [] for k in ("position", "quat_wxyz", "velocity", "angular_velocity")}
    t, qpos = [], []
    vel = np.empty(6)
    for s in range(steps + 1):
        if s:
            mujoco.mj_step(m, d)
            mujoco.mj_forward(m, d)  # (mj_step leaves xipos, ximat at the pose before it)
        if s % every:
            continue
        t.append(d.time)
        qpos.append(d.qpos.copy())
        out["position"].append(d.xipos[1:].copy())
        out["quat_wxyz"].append([_quat(d.ximat[i]) for i in range(1, n + 1)])
        av, lv = [], []
        for i in range(1, n + 1):
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_XBODY, i, vel, 0)
            av.append(vel[:3].copy())
            lv.append(vel[3:] + np.cross(vel[:3], d.xipos[i] - d.xpos[i]))
        out["angular_velocity"].append(av)
        out["velocity"].append(lv)
    arrays = {k: np.array(v, float) for k, v in out.items()}
    arrays.update(t=np.array(t), step=np.arange(len(t)) * every)
    return m, model, arrays, np.array(qpos)


def mujoco_depth(m, qpos, shift=None):
    """(T,) MuJoCo's deepest contact depth (-min contact.dist, 0 without contacts) at each
    logged pose (the limb moved by ``shift`` (T, 3) when given), after mj_forward."""
    d = mujoco.MjData(m)
    out = np.zeros(len(qpos))
    for k, q in enumerate(qpos):
        d.qpos[:] = q
        if shift is not None:
            d.qpos[:3] += shift[k]
        mujoco.mj_forward(m, d)
        if d.ncon:
            out[k] = max(0.0, -min(d.contact[c].dist for c in range(d.ncon)))
    return out


def _pen(model, arrays):
    rec = rblog.Recorder(model, dt=0.002, writer="mujoco")
    rec.write(**arrays)
    rec.close()
    return next(r for r in check(rec.trajectory, only=["penetration"]))


def test_clean_mujoco_log_passes_with_mujocos_depth():
    m, model, arrays, qpos = mujoco_log()
    res = _pen(model, arrays)
    assert res.judged and res.passed, res.reason
    truth = mujoco_depth(m, qpos).max()
    # MuJoCo's soft contacts rest a little into the floor; the audit's depth is MuJoCo's to
    # round-off
    assert 0 < truth < 5e-3
    assert abs(res.stats["geom_depth_max_m"] - truth) < 1e-9
    assert "not judged" not in res.reason  # the capsule and the cylinder are judged on their geoms


def test_capsule_sunk_20mm_is_flagged():
    m, model, arrays, qpos = mujoco_log()
    k0 = int(np.searchsorted(arrays["t"], 0.6))
    shift = np.zeros((len(qpos), 3))
    shift[k0:, 2] = -0.02
    arrays["position"][:, 0] += shift
    res = _pen(model, arrays)
    assert not res.passed
    geom = [f for f in res.findings if "into geom 0 ('floor')" in f.message]
    assert len(geom) == 1 and geom[0].bodies == [0]
    f = geom[0]
    truth = mujoco_depth(m, qpos, shift)
    assert abs(f.value - truth.max()) < 1e-9
    assert f.t >= arrays["t"][k0] and f.value > 0.02
    assert "'limb'" in f.message
