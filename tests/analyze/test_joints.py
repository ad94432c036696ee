"""The joints analyzer (rblog.analyze.joints) on chains logged from two engines.

* MuJoCo (generalized coordinates: its joints hold by construction, to round-off) passes;
* the same log with one link's logged position pulled 5 mm from t = 0.5 s on is flagged on
  that link's joint only, at 0.5 s, with 5 mm;
* pybullet in maximal coordinates (free rigid bodies held by Bullet's constraints) lets its
  joints drift: flagged;
* a log whose bodies move on joints without a joint table is not judged.

The joint tables are built here from each engine's own data at the initial pose (MuJoCo's
xanchor / xaxis, the constraints pybullet was given), in the body frames of the contract (centre of mass,
principal axes).
"""

from __future__ import annotations

import numpy as np
import pytest

import rblog
from rblog.analyze import check
from rblog.analyze.joints import joint_errors

mujoco = pytest.importorskip("mujoco")

# a 4-link hinge chain hanging from the world, started 1 rad off the vertical; its last link
# also carries a second hinge about another axis
CHAIN_XML = """
<mujoco>
  <option timestep="0.002" integrator="implicitfast"/>
  <worldbody>
    <body name="l1" pos="0 0 2">
      <joint name="j1" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
      <body name="l2" pos="0.3 0 0">
        <joint name="j2" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.25 0 0.05" size="0.03"/>
        <body name="l3" pos="0.25 0 0.05">
          <joint name="j3" type="hinge" axis="1 0 1"/>
          <geom type="box" pos="0.1 0 0" size="0.1 0.02 0.03"/>
          <body name="l4" pos="0.2 0 0">
            <joint name="j4" type="hinge" axis="0 0 1"/>
            <geom type="sphere" pos="0.1 0.02 0" size="0.05"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _frames_quat(mat9):
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.asarray(mat9, float))
    return q


def mujoco_chain(seconds=1.0):
    """(model, arrays for Recorder.write, dt) of the chain, logged every step."""
    m = mujoco.MjModel.from_xml_string(CHAIN_XML)
    d = mujoco.MjData(m)
    d.qpos[:] = [1.0, -0.5, 0.7, 1.2]
    d.qvel[:] = [0.5, 2.0, -3.0, 4.0]
    mujoco.mj_forward(m, d)
    n = m.nbody - 1
    # joints at the initial pose: the anchor and axis in the child's and the parent's inertial
    # frames (world for body 0)
    jb = m.jnt_bodyid - 1
    par = m.body_parentid[1:] - 1
    anchor_b, anchor_p, axis_b, axis_p = [], [], [], []
    for j in range(m.njnt):
        c, p = jb[j] + 1, par[jb[j]] + 1
        rc, rp = d.ximat[c].reshape(3, 3), d.ximat[p].reshape(3, 3)
        anchor_b.append(rc.T @ (d.xanchor[j] - d.xipos[c]))
        anchor_p.append(rp.T @ (d.xanchor[j] - d.xipos[p]))
        axis_b.append(rc.T @ d.xaxis[j])
        axis_p.append(rp.T @ d.xaxis[j])
    # geoms in the inertial frames
    gtype = {int(mujoco.mjtGeom.mjGEOM_SPHERE): "sphere",
             int(mujoco.mjtGeom.mjGEOM_CAPSULE): "capsule", int(mujoco.mjtGeom.mjGEOM_BOX): "box"}
    gb = m.geom_bodyid
    gpos = [d.ximat[b].reshape(3, 3).T @ (d.geom_xpos[g] - d.xipos[b]) for g, b in enumerate(gb)]
    gquat = [_frames_quat((d.ximat[b].reshape(3, 3).T @ d.geom_xmat[g].reshape(3, 3)).ravel())
             for g, b in enumerate(gb)]
    geoms = dict(body=gb - 1, type=[gtype[int(t)] for t in m.geom_type], size=m.geom_size,
                 pos_body=gpos, quat_wxyz_body=gquat)
    model = rblog.body_table(
        name=[m.body(i + 1).name for i in range(n)], mass=m.body_mass[1:], geoms=geoms,
        inertia_diag=m.body_inertia[1:], kind=["joints"] * n, parent=par,
        joints=dict(body=jb, type=["hinge"] * m.njnt, anchor_body=anchor_b,
                    anchor_parent=anchor_p, axis_body=axis_b, axis_parent=axis_p,
                    name=[m.joint(j).name for j in range(m.njnt)]),
        gravity=m.opt.gravity)
    steps = int(round(seconds / m.opt.timestep))
    out = {k: np.empty((steps + 1, n, w)) for k, w in
           (("position", 3), ("quat_wxyz", 4), ("velocity", 3), ("angular_velocity", 3))}
    t = np.empty(steps + 1)
    vel = np.empty(6)
    for s in range(steps + 1):
        if s:
            mujoco.mj_step(m, d)
            mujoco.mj_forward(m, d)  # (mj_step leaves xipos, ximat at the pose before it)
        t[s] = d.time
        for i in range(n):
            out["position"][s, i] = d.xipos[i + 1]
            out["quat_wxyz"][s, i] = _frames_quat(d.ximat[i + 1])
            # velocity of the centre of mass (world), angular velocity (world)
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_XBODY, i + 1, vel, 0)
            out["angular_velocity"][s, i] = vel[:3]
            out["velocity"][s, i] = vel[3:] + np.cross(vel[:3], d.xipos[i + 1] - d.xpos[i + 1])
    out.update(t=t, step=np.arange(steps + 1, dtype=np.int64))
    return model, out, m.opt.timestep


def _traj(model, arrays, dt, writer):
    rec = rblog.Recorder(model, dt=dt, writer=writer)
    rec.write(**arrays)
    rec.close()
    return rec.trajectory


def _joints(traj):
    return next(r for r in check(traj, only=["joints"]))


def test_mujoco_chain_passes():
    model, arrays, dt = mujoco_chain()
    traj = _traj(model, arrays, dt, "mujoco")
    res = _joints(traj)
    assert res.judged and res.passed, res.reason
    err = joint_errors(traj)
    # measured: anchors 5.0e-16 m apart at most (|x| <= 1.9 m: 0.5 ulp of the transform's
    # size), axes 1.1e-15 rad (5 ulps)
    assert err["gap"].max() < 64 * np.finfo(float).eps * 2.5
    assert err["angle"].max() < 64 * np.finfo(float).eps


def test_pulled_anchor_is_flagged_on_its_joint():
    model, arrays, dt = mujoco_chain()
    k0 = int(np.searchsorted(arrays["t"], 0.5))
    arrays["position"][k0:, 3] += [0.0, 0.005, 0.0]  # the last link, 5 mm along y
    res = _joints(_traj(model, arrays, dt, "mujoco"))
    assert not res.passed
    gaps = [f for f in res.findings if "anchor separation" in f.message]
    assert {f.bodies[0] for f in res.findings} == {3}
    f = gaps[0]
    assert "'j4'" in f.message
    assert abs(f.value - 0.005) < 1e-9
    assert f"past tolerance from t = {arrays['t'][k0]:.6g} s" in f.message


def test_no_joint_table_not_judged():
    """Bodies on joints without a joint table: not judged, saying so; free bodies only: skip."""
    arrays = dict(t=np.arange(3) * 0.01, step=np.arange(3), position=np.zeros((3, 1, 3)),
                  quat_wxyz=np.tile([1.0, 0, 0, 0], (3, 1, 1)), velocity=np.zeros((3, 1, 3)),
                  angular_velocity=np.zeros((3, 1, 3)))
    for kind, judged in (("joints", False), ("free", True)):
        model = rblog.body_table(name=["b"], mass=[1.0], inertia_diag=[[1, 1, 1]], kind=[kind],
                                 geoms=dict(body=[0], type=["sphere"], size=[[0.1, 0, 0]]))
        res = _joints(_traj(model, arrays, 0.01, "test"))
        assert res.judged is judged
        assert ("no joint table" in res.reason) if not judged else \
            (res.skipped and "no joints" in res.reason)


pybullet = pytest.importorskip("pybullet")


def pybullet_chain(seconds=2.0, iterations=None):
    """A chain of 4 bars in pybullet (DIRECT) in maximal coordinates: each bar a free rigid body
    (its centre of mass at its frame), held to the world and to each other by ball joints
    (createConstraint JOINT_POINT2POINT: Bullet's btPoint2PointConstraint) and the last two by a
    fixed joint (JOINT_FIXED), released horizontal; logged every step at dt = 1/240 s.
    (A multibody loaded with useMaximalCoordinates=True exposes only its base to the Python API,
    so its links cannot be logged: these are the same rigid bodies and constraints, made by
    hand.) ``iterations``: Bullet's solver iterations (default pybullet's 50)."""
    p = pybullet
    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, -9.81, physicsClientId=cid)
        if iterations:
            p.setPhysicsEngineParameter(numSolverIterations=int(iterations), physicsClientId=cid)
        n, half = 5, 0.15
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[half, 0.03, 0.03],
                                     physicsClientId=cid)
        bodies = [p.createMultiBody(baseMass=1.0, baseCollisionShapeIndex=col,
                                    basePosition=[half + 2 * half * i, 0, 2],
                                    physicsClientId=cid) for i in range(n)]
        for a, b in zip(bodies, bodies[1:]):
            p.setCollisionFilterPair(a, b, -1, -1, 0, physicsClientId=cid)
        types, anchor_b, anchor_p, parent = [], [], [], []
        for i, b in enumerate(bodies):
            par = -1 if i == 0 else bodies[i - 1]
            fixed = i == n - 1
            pf = [0, 0, 2] if i == 0 else [half, 0, 0]
            cf = [-half, 0, 0]
            jtype = p.JOINT_FIXED if fixed else p.JOINT_POINT2POINT
            if i == 0:  # to the world: pybullet takes the world as the child (-1)
                p.createConstraint(b, -1, -1, -1, jtype, [0, 0, 0], cf, pf, physicsClientId=cid)
            else:
                p.createConstraint(par, -1, b, -1, jtype, [0, 0, 0], pf, cf, physicsClientId=cid)
            types.append("fixed" if fixed else "ball")
            anchor_b.append(cf)
            anchor_p.append(pf)
            parent.append(i - 1)
        info = p.getDynamicsInfo(bodies[0], -1, physicsClientId=cid)
        model = rblog.body_table(
            name=[f"bar{i}" for i in range(n)], mass=[1.0] * n, inertia_diag=[info[2]] * n,
            kind=["joints"] * n, parent=parent,
            geoms=dict(body=list(range(n)), type=["box"] * n, size=[[half, 0.03, 0.03]] * n),
            joints=dict(body=list(range(n)), type=types, anchor_body=anchor_b,
                        anchor_parent=anchor_p, axis_body=np.zeros((n, 3)),
                        axis_parent=np.zeros((n, 3)), name=[f"j{i}" for i in range(n)]),
            gravity=(0, 0, -9.81))
        steps = int(seconds * 240)
        rows = {k: [] for k in ("position", "quat_wxyz", "velocity", "angular_velocity")}
        for s_ in range(steps + 1):
            if s_:
                p.stepSimulation(physicsClientId=cid)
            for k in rows:
                rows[k].append([])
            for b in bodies:
                x, q = p.getBasePositionAndOrientation(b, physicsClientId=cid)
                v, w = p.getBaseVelocity(b, physicsClientId=cid)
                rows["position"][-1].append(x)
                rows["quat_wxyz"][-1].append([q[3], q[0], q[1], q[2]])
                rows["velocity"][-1].append(v)
                rows["angular_velocity"][-1].append(w)
        arrays = {k: np.array(x, float) for k, x in rows.items()}
        arrays.update(t=np.arange(steps + 1) / 240.0, step=np.arange(steps + 1))
        return model, arrays, 1.0 / 240.0
    finally:
        p.disconnect(cid)


def test_pybullet_maximal_coordinates_drift_is_flagged():
    model, arrays, dt = pybullet_chain()
    traj = _traj(model, arrays, dt, "pybullet maximal")
    res = _joints(traj)
    err = joint_errors(traj)
    assert not res.passed, res.reason
    # measured: the five joints' anchors come 0.81, 1.10, 1.04, 1.57, 2.58 mm apart at worst,
    # against derived tolerances of at most 0.66 mm (the step term at the fastest swing; the
    # fixed joint's 2e-12 m: its bars turn together); the fixed joint turns 2.4e-5 rad
    gaps = [f for f in res.findings if "anchor separation" in f.message]
    assert {f.bodies[0] for f in gaps} == set(range(5))
    assert err["gap"].max() > 2e-3
    assert all(f.value > f.tolerance for f in res.findings)


@pytest.mark.parametrize("jtype,allowed,forbidden,what,size", [
    # slide along z: moving along the axis is the joint's motion; 1 mm across it is not
    ("slide", [0.0, 0.0, 0.1], [0.001, 0.0, 0.1], "anchor separation", 0.001),
    # planar with normal z: any motion in the plane; 2 mm along the normal is not
    ("planar", [0.05, -0.03, 0.0], [0.05, -0.03, 0.002], "anchor separation", 0.002),
    # hinge about z: the anchor stays; 3 mm off is not
    ("hinge", [0.0, 0.0, 0.0], [0.0, 0.003, 0.0], "anchor separation", 0.003),
])
def test_each_joint_type_allows_its_motion_only(jtype, allowed, forbidden, what, size):
    """Two bodies at rest, the child on a joint of the parent (anchor 0.1 m above the parent's
    centre, 0.1 m below the child's); from t = 0.05 s the child is displaced by ``allowed``
    (the joint's own motion: passes) or ``forbidden`` (flagged with its size)."""
    t = np.arange(11) * 0.01
    for shift, flagged in ((allowed, False), (forbidden, True)):
        pos = np.zeros((11, 2, 3))
        pos[:, 1] = [0.0, 0.0, 0.2]
        pos[5:, 1] += shift
        arrays = dict(t=t, step=np.arange(11), position=pos,
                      quat_wxyz=np.tile([1.0, 0, 0, 0], (11, 2, 1)), velocity=np.zeros((11, 2, 3)),
                      angular_velocity=np.zeros((11, 2, 3)))
        model = rblog.body_table(
            name=["base", "child"], mass=[1.0, 1.0], inertia_diag=[[1, 1, 1]] * 2,
            kind=["free", "joints"], parent=[-1, 0],
            geoms=dict(body=[0, 1], type=["sphere", "sphere"], size=[[0.05, 0, 0]] * 2),
            joints=dict(body=[1], type=[jtype], anchor_body=[[0, 0, -0.1]],
                        anchor_parent=[[0, 0, 0.1]], axis_body=[[0, 0, 1]],
                        axis_parent=[[0, 0, 1]], name=["j"]))
        res = _joints(_traj(model, arrays, 0.01, "test"))
        assert res.passed is not flagged, res.reason
        if flagged:
            f = res.findings[0]
            assert what in f.message and abs(f.value - size) < 1e-12
            assert "past tolerance from t = 0.05 s" in f.message


def test_fixed_joint_turned_is_flagged():
    """A fixed joint whose child turns 0.01 rad about its anchor from t = 0.05 s: the anchors
    stay together, the relative rotation is flagged with 0.01 rad."""
    t = np.arange(11) * 0.01
    ang = 0.01
    q = np.tile([1.0, 0, 0, 0], (11, 2, 1))
    q[5:, 1] = [np.cos(ang / 2), np.sin(ang / 2), 0, 0]  # about x through the child's centre
    pos = np.zeros((11, 2, 3))
    pos[:, 1] = [0.0, 0.0, 0.2]
    # keep the anchor (0.1 m below the child's centre) in place: move the centre with the turn
    r = np.array([[1, 0, 0], [0, np.cos(ang), -np.sin(ang)], [0, np.sin(ang), np.cos(ang)]])
    pos[5:, 1] = [0.0, 0.0, 0.1] - r @ [0, 0, -0.1]
    arrays = dict(t=t, step=np.arange(11), position=pos, quat_wxyz=q,
                  velocity=np.zeros((11, 2, 3)), angular_velocity=np.zeros((11, 2, 3)))
    model = rblog.body_table(
        name=["base", "child"], mass=[1.0, 1.0], inertia_diag=[[1, 1, 1]] * 2,
        kind=["free", "joints"], parent=[-1, 0],
        geoms=dict(body=[0, 1], type=["sphere", "sphere"], size=[[0.05, 0, 0]] * 2),
        joints=dict(body=[1], type=["fixed"], anchor_body=[[0, 0, -0.1]],
                    anchor_parent=[[0, 0, 0.1]], axis_body=[[0, 0, 0]], axis_parent=[[0, 0, 0]],
                    name=["weld"]))
    res = _joints(_traj(model, arrays, 0.01, "test"))
    assert [f.message.split(":")[1].split(" reaches")[0].strip() for f in res.findings] == \
        ["relative rotation"]
    assert abs(res.findings[0].value - ang) < 1e-12


# a universal joint (two hinges about one point, as MuJoCo's humanoid hip) swinging under
# gravity, and a planar body (slide x, slide z, hinge y, as dm_control's stacker boxes) falling
COMPOUND_XML = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body name="arm" pos="0 0 2">
      <joint name="ux" type="hinge" axis="1 0 0"/>
      <joint name="uy" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.3 0.1 -0.2" size="0.03"/>
    </body>
    <body name="slab" pos="1 0 1">
      <joint name="px" type="slide" axis="1 0 0"/>
      <joint name="pz" type="slide" axis="0 0 1"/>
      <joint name="py" type="hinge" axis="0 1 0"/>
      <geom type="box" size="0.1 0.05 0.02" pos="0.05 0 0"/>
    </body>
  </worldbody>
</mujoco>
"""


def _recorded(xml, qvel, steps):
    """The trajectory of the MJCF ``xml`` started at ``qvel``, recorded every step for ``steps``."""
    from rblog.adapters import mujoco as adapter

    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qvel[:] = qvel
    mujoco.mj_forward(m, d)
    rec = adapter.recorder(m, d)
    for _ in range(steps):
        mujoco.mj_step(m, d)
        rec(d)
    rec.close()
    return rec.trajectory


def _compound(pull=None):
    # both hinges and the planar body all move
    traj = _recorded(COMPOUND_XML, [2.0, -3.0, 0.5, 0.4, 5.0], 300)
    if pull is not None:
        pos = traj.position.copy()
        pos[pull:, 0] += [0.0, 0.0, 0.005]  # the arm, 5 mm up, in the log only
        traj.position = pos
    return traj


def test_compound_joints_judged_for_what_they_forbid():
    """A universal joint's two rows each turn the other's axis (row by row: 1.97 and 1.18 rad
    "misaligned", the slab's rows 1.7 m "apart", measured): judged as one fixed point (its
    anchors 2.2e-16 m apart, measured), it passes; the planar body is judged on its hinge row
    for what the three rows forbid together (its anchor off the x-z plane: 0 m measured, tol
    2.5e-6 m; the hinge axis off y: 0 rad), so nothing is left out; a planted 5 mm pull of the
    arm is still caught on its joint, at its time, with its size."""
    res = _joints(_compound())
    assert res.judged and res.passed, res.reason
    assert not any("compound" in x for x in res.not_judged), res.not_judged
    pulled = _joints(_compound(pull=150))
    assert {f.bodies[0] for f in pulled.findings} == {0}
    f = pulled.findings[0]
    assert "'ux'" in f.message and "anchor separation" in f.message
    assert abs(f.value - 0.005) < 1e-9
    assert f.step == 150


def _slab_moved(step, shift=None, tilt=None):
    """The compound log with the slab (body 1) moved in the log only from sample ``step`` on:
    shifted by ``shift`` (m, world) or turned by ``tilt`` rad about the world x axis."""
    traj = _compound()
    pos, rot = traj.position.copy(), traj.rotation.copy()
    if shift is not None:
        pos[step:, 1] += shift
    if tilt is not None:
        c, s = np.cos(tilt), np.sin(tilt)
        rot[step:, 1] = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]) @ rot[step:, 1]
    traj.position, traj.rotation = pos, rot
    return traj


def test_planar_compound_flags_what_its_slides_and_hinge_forbid():
    """Slide x, slide z, hinge y (dm_control's stacker boxes): the body may move in the x-z plane
    and turn about y, nothing else. In the log only, from sample 150: 5 mm along y (off the plane)
    is flagged on the hinge row with 5 mm at that sample; 5 mm along x (in the plane) is allowed;
    a 0.05 rad turn about x is flagged as the hinge axis 0.05 rad off y, at that sample."""
    off = _joints(_slab_moved(150, shift=[0.0, 0.005, 0.0]))
    assert {f.bodies[0] for f in off.findings} == {1}
    f = off.findings[0]
    assert "'py'" in f.message and "anchor separation" in f.message
    assert abs(f.value - 0.005) < 1e-9 and f.step == 150
    assert _joints(_slab_moved(150, shift=[0.005, 0.0, 0.0])).passed
    tilted = _joints(_slab_moved(150, tilt=0.05))
    axis = [f for f in tilted.findings if "axis misalignment" in f.message]
    assert len(axis) == 1 and "'py'" in axis[0].message
    assert abs(axis[0].value - 0.05) < 1e-12 and axis[0].step == 150


TELESCOPE_XML = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body name="boom" pos="0 0 1">
      <joint name="swing" type="hinge" axis="0 1 0"/>
      <joint name="reach" type="slide" axis="1 0 0"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.03"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_slide_after_a_turn_is_left_out_by_name():
    """A hinge then a slide (a telescoping boom): the slide's axis turns with the hinge, which the
    log's two frames cannot separate, so the body is named as not judged and nothing passes or
    fails on it."""
    res = _joints(_recorded(TELESCOPE_XML, [1.5, 0.3], 100))
    assert not res.judged, res.reason
    assert "'boom'" in res.reason and "slides then turns" in res.reason, res.reason


def _anchor_gap(traj, child, parent, anchor_child, anchor_parent):
    """(T,) |world anchor in the child - world anchor in the parent| from the logged poses."""
    a = traj.position[:, child] + traj.rotation[:, child] @ np.asarray(anchor_child, float)
    b = traj.position[:, parent] + traj.rotation[:, parent] @ np.asarray(anchor_parent, float)
    return np.linalg.norm(a - b, axis=1)


def test_pybullet_maximal_anchor_pulled_5mm_is_found_on_its_joint_alone():
    """The pybullet chain in maximal coordinates with its last bar pulled 5 mm along y in the
    log only, from t = 1 s: the fixed joint j4 (bar4 on bar3) is found at its worst separation,
    measured here from the logged poses (measured: 4.7e-5 m before the pull, Bullet's own;
    5.0002 mm at the pull; 5.63 mm at worst, t = 1.67 s); every other joint's finding is the one
    the unpulled log has (Bullet's own drift, which this log also holds)."""
    model, arrays, dt = pybullet_chain()
    clean = _joints(_traj(model, arrays, dt, "pybullet maximal"))
    k0 = int(np.searchsorted(arrays["t"], 1.0))
    arrays["position"][k0:, 4] += [0.0, 0.005, 0.0]
    traj = _traj(model, arrays, dt, "pybullet maximal")
    res = _joints(traj)
    gap = _anchor_gap(traj, 4, 3, [-0.15, 0, 0], [0.15, 0, 0])
    j4 = [f for f in res.findings if "'j4'" in f.message and "anchor separation" in f.message]
    assert len(j4) == 1 and j4[0].bodies[0] == 4
    assert abs(j4[0].value - gap.max()) < 1e-9 and gap[k0:].max() == gap.max()
    assert abs(gap[k0] - 0.005) < 1e-4 and j4[0].t >= arrays["t"][k0]
    others = lambda r: sorted((f.message, f.value) for f in r.findings if "'j4'" not in f.message)
    assert others(res) == others(clean)
