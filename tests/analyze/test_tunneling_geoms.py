"""Tunneling judged per geom pair for bodies without a v2 shape (capsules, meshes: contract v3
geoms): a capsule whose logged pose jumps through a wall box or the floor between two samples is
caught with the pair, the interval and the depth; a fast capsule through a thin box in a
hand-built log is caught and the same capsule going past the box's edge is not; clean real models
(dm_control's stacker, humanoid and walker; pybullet's r2d2 and kuka) stay clean, judged on their
geoms. The pair filter follows MuJoCo's own rule (contype/conaffinity, welded bodies,
filterparent)."""

from __future__ import annotations

import numpy as np
import pytest

import rblog
from rblog.analyze import shapes
from rblog.record.recorder import body_table

mujoco = pytest.importorskip("mujoco")

# a capsule (r = 0.03 m, half-length 0.1 m, axis along y) dropped on the floor at x = 0.2 m, a wall
# box 0.02 m thick (half-extent 0.01 m along x) standing at x = 0.5 m
WALL_XML = """
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <geom name="wall" type="box" pos="0.5 0 0.3" size="0.01 0.5 0.3"/>
    <body name="rod" pos="0.2 0 0.05">
      <freejoint/>
      <geom name="rod" type="capsule" size="0.03 0.1" euler="90 0 0"/>
    </body>
  </worldbody>
</mujoco>
"""
R_ROD, T_WALL = 0.03, 0.01
K_FAULT = 200  # the interval [200, 201] carries the planted jump


def _wall_log():
    from rblog.adapters import mujoco as ad

    m = mujoco.MjModel.from_xml_string(WALL_XML)
    d = mujoco.MjData(m)
    rec = ad.recorder(m, d, every=1)
    qpos = [d.qpos.copy()]
    for _ in range(300):
        mujoco.mj_step(m, d)
        rec(d)
        qpos.append(d.qpos.copy())
    rec.close()
    return m, rec.trajectory, np.array(qpos)


def _tunneling(traj):
    return next(r for r in rblog.check(traj, only=["tunneling"]))


def test_capsule_resting_beside_a_wall_is_clean_and_judged_on_its_geoms():
    _, traj, _ = _wall_log()
    assert traj.model.body_shape[0] < 0  # a capsule: no v2 shape
    res = _tunneling(traj)
    assert res.passed and res.judged, res.reason
    assert not res.not_judged  # its geoms are judged: no "not judged" line for it
    assert res.stats["geom_plane_pairs"] >= 1


def test_capsule_jumping_through_the_wall_in_the_log_is_caught():
    m, traj, qpos = _wall_log()
    pos = traj.position.copy()
    pos[K_FAULT + 1:, 0, 0] += 0.6  # the logged pose only: from x ~ 0.2 m to x ~ 0.8 m
    traj.position = pos
    res = _tunneling(traj)
    assert not res.passed
    assert len(res.findings) == 1, [f.message for f in res.findings]
    f = res.findings[0]
    assert f.bodies == [0] and "'wall'" in f.message and "'rod'" in f.message
    assert f.step == traj.step[K_FAULT + 1] and f.t == pytest.approx(traj.t[K_FAULT + 1])
    # reference: MuJoCo's own signed distance of the two geoms at the path's midpoint (the pose
    # at sample 200 moved by half the jump: the sub-steps hold the midpoint), less the threshold
    # (1 - pass_frac) (r + t) of the two inner radii
    d = mujoco.MjData(m)
    d.qpos[:] = qpos[K_FAULT]
    d.qpos[0] += 0.3
    mujoco.mj_forward(m, d)
    rod = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "rod")
    wall = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "wall")
    dist = mujoco.mj_geomDistance(m, d, rod, wall, 1.0, None)
    assert -dist == pytest.approx(R_ROD + T_WALL, abs=1e-4)  # centred in the wall: r + t deep
    want = -dist - 0.5 * (R_ROD + T_WALL)
    # measured: 7e-18 m off MuJoCo's (the rotation barely turns while the capsule rests)
    assert f.value == pytest.approx(want, abs=1e-9)


def test_capsule_dropping_through_the_floor_in_the_log_is_caught():
    m, traj, qpos = _wall_log()
    pos = traj.position.copy()
    pos[K_FAULT + 1:, 0, 2] -= 0.1  # the logged pose only: 0.1 m down, through the floor
    traj.position = pos
    res = _tunneling(traj)
    assert not res.passed
    assert len(res.findings) == 1, [f.message for f in res.findings]
    f = res.findings[0]
    assert f.bodies == [0] and "'floor'" in f.message
    assert f.step == traj.step[K_FAULT + 1]
    # reference: MuJoCo's geom frame at sample 201 lowered 0.1 m: the capsule's segment's lowest
    # point z - h |axis_z| below the floor z = 0
    d = mujoco.MjData(m)
    d.qpos[:] = qpos[K_FAULT + 1]
    mujoco.mj_forward(m, d)
    rod = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "rod")
    axis_z = d.geom_xmat[rod].reshape(3, 3)[2, 2]
    low = d.geom_xpos[rod][2] - 0.1 - m.geom_size[rod][1] * abs(axis_z)
    assert f.value == pytest.approx(-low, abs=1e-9)


# --- a hand-built log: a capsule at 50 m/s and a thin wall -----------------------------------
R_CAP, H_CAP, T_BOX = 0.02, 0.08, 0.005
DT = 0.002  # 0.1 m per sample at 50 m/s


def _fast_capsule(y0: float, y1: float):
    """A capsule (axis along z) flying in a straight line at 50 m/s along x, from (0.05, y0) to
    (1.05, y1) in 10 intervals, past a world box 0.01 m thick (|y| <= 0.3 m, |z| <= 0.3 m) at
    x = 0.5 m, in zero gravity: samples at x = 0.45 and 0.55 m straddle the box."""
    model = body_table(name=["cap"], mass=[1.0], inertia_diag=[[1e-3, 1e-3, 1e-3]],
                       gravity=(0.0, 0.0, 0.0),
                       geoms=dict(body=[0, -1], type=["capsule", "box"],
                                  size=[[R_CAP, H_CAP, 0.0], [T_BOX, 0.3, 0.3]],
                                  pos_body=[[0.0, 0.0, 0.0], [0.5, 0.0, 0.0]], name=["cap", "wall"]))
    n = 11
    s = np.linspace(0.0, 1.0, n)
    p = np.zeros((n, 1, 3))
    p[:, 0, 0] = 0.05 + s
    p[:, 0, 1] = y0 + (y1 - y0) * s
    v = np.broadcast_to((p[-1] - p[0]) / (DT * (n - 1)), (n, 1, 3)).copy()
    rec = rblog.Recorder(model, dt=DT)
    rec.write(t=DT * np.arange(n), step=np.arange(n, dtype=np.int64), position=p,
              quat_wxyz=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1, 1)), velocity=v,
              angular_velocity=np.zeros((n, 1, 3)))
    rec.close()
    return rec.trajectory


def test_fast_capsule_through_a_thin_box_between_samples_is_caught():
    traj = _fast_capsule(0.0, 0.0)
    # both samples around the box are clear of it: 0.05 - 0.005 - 0.02 = 0.025 m gaps
    res = _tunneling(traj)
    assert not res.passed
    assert len(res.findings) == 1
    f = res.findings[0]
    assert "'wall'" in f.message and f.step == 5
    # closed form: at mid-interval the capsule's axis is in the box's mid-plane, r + t deep (the
    # shortest way out is along x); the threshold is (1 - 0.5) (r + t)
    assert f.value == pytest.approx(0.5 * (R_CAP + T_BOX), abs=1e-12)


def test_the_same_capsule_passing_the_box_edge_is_clean():
    # across the interval from (0.45, 0.31) to (0.55, 0.345) m: its bounds overlap the box's
    # (y <= 0.3 m), but where it passes the box (x = 0.495 m) its axis is at y = 0.3258 m, 0.0243 m
    # from the box's edge along the path's normal: 4.3 mm clear of it with r = 0.02 m
    traj = _fast_capsule(0.17, 0.52)
    res = _tunneling(traj)
    assert res.passed, res.reason
    assert res.stats["geom_rows_substepped"] >= 1  # examined between the samples, not skipped
    # closest approach: 0.0043 m of clearance below a depth threshold of 0.0125 m. The sub-steps
    # (18 over the 0.106 m path: 5.9 mm apart) miss the exact closest point by <= 2.9 mm along
    # the path, which adds at most sqrt(0.0243^2 + 0.0029^2) - 0.0243 = 1.7e-4 m (measured 8.5e-5)
    d_axis = (0.31 + 0.35 * 0.045 - 0.3) / np.hypot(1.0, 0.35)
    want = 0.5 * (R_CAP + T_BOX) + (d_axis - R_CAP)
    assert want <= res.stats["closest_clearance_m"] <= want + 1.7e-4


# --- the pair filter ------------------------------------------------------------------------
def test_geom_filter_is_mujocos_for_the_humanoid():
    """MuJoCo's rule (its documentation, "Collision detection"): contype/conaffinity, never two
    geoms of bodies welded together (body_weldid), never a body and its parent's weld
    (filterparent), the world's weld exempt. The humanoid's head and hands are welded to their
    parents (a fixed joint in the log)."""
    from rblog.adapters import mujoco as ad

    m = ad.suite_model("humanoid")
    d = mujoco.MjData(m)
    rec = ad.recorder(m, d, every=1)
    mujoco.mj_step(m, d)
    rec(d)
    rec.close()
    md = rec.trajectory.model
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(m.ngeom)]
    idx = [names.index(x) for x in md.geom_name]

    def mj_collides(g1, g2):
        w1, w2 = m.body_weldid[m.geom_bodyid[g1]], m.body_weldid[m.geom_bodyid[g2]]
        if w1 == w2:
            return False
        p1, p2 = m.body_weldid[m.body_parentid[w1]], m.body_weldid[m.body_parentid[w2]]
        if w1 and w2 and (w1 == p2 or w2 == p1):
            return False
        return bool(m.geom_contype[g1] & m.geom_conaffinity[g2]
                    or m.geom_contype[g2] & m.geom_conaffinity[g1])

    i, j = np.triu_indices(md.n_geoms, 1)
    want = np.array([mj_collides(idx[a], idx[b]) for a, b in zip(i, j)])
    got = shapes.collide_mask(md, i, j)
    head = md.geom_name.index("head")
    arm = md.geom_name.index("right_upper_arm")
    pair = (i == min(head, arm)) & (j == max(head, arm))
    assert not want[pair].any()  # welded to the torso, the arm's parent: MuJoCo skips it
    np.testing.assert_array_equal(got, want)


# --- clean real models ------------------------------------------------------------------------
def _mujoco_log(name, ctrl, every, steps):
    from rblog.adapters import mujoco as ad

    m = ad.suite_model(name)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(7)
    rec = ad.recorder(m, d, every=every)
    for _ in range(steps):
        if ctrl == "random":
            d.ctrl[:] = rng.uniform(-1.0, 1.0, m.nu)
        mujoco.mj_step(m, d)
        rec(d)
    rec.close()
    return rec.trajectory


def _pybullet_log(name, ctrl, every, steps):
    pb = pytest.importorskip("pybullet")
    pytest.importorskip("pybullet_data")
    from rblog.adapters.pybullet import PybulletRecorder, load_shipped

    cid = pb.connect(pb.DIRECT)
    try:
        load_shipped(name, cid)
        rec = PybulletRecorder(cid, keep=True, every=every)
        rng = np.random.default_rng(7)
        motors = []
        for k in range(pb.getNumBodies(physicsClientId=cid)):
            b = pb.getBodyUniqueId(k, physicsClientId=cid)
            for j in range(pb.getNumJoints(b, physicsClientId=cid)):
                if pb.getJointInfo(b, j, physicsClientId=cid)[2] in (pb.JOINT_REVOLUTE,
                                                                      pb.JOINT_PRISMATIC):
                    motors.append((b, j))
        for _ in range(steps):
            if ctrl == "random":
                for b, j in motors:
                    pb.setJointMotorControl2(b, j, pb.VELOCITY_CONTROL,
                                             targetVelocity=rng.uniform(-5, 5), force=50.0,
                                             physicsClientId=cid)
            pb.stepSimulation(physicsClientId=cid)
            rec()
        rec.close()
        return rec.trajectory
    finally:
        pb.disconnect(physicsClientId=cid)


def _assert_clean_on_geoms(traj):
    res = _tunneling(traj)
    assert res.passed and res.judged, res.reason
    assert not any("passing through other bodies" in x for x in res.not_judged), res.not_judged
    # judged on the geoms: pairs and planes were examined
    assert res.stats.get("geom_plane_pairs", 0) + res.stats.get("geom_pair_rows", 0) > 0


def test_humanoid_random_controls_every_10th_is_clean():
    _assert_clean_on_geoms(_mujoco_log("humanoid", "random", 10, 500))


@pytest.mark.slow
@pytest.mark.parametrize("every", [1, 10])
@pytest.mark.parametrize("ctrl", ["zero", "random"])
@pytest.mark.parametrize("name", ["stacker", "humanoid", "walker"])
def test_dm_control_models_are_clean(name, ctrl, every):
    _assert_clean_on_geoms(_mujoco_log(name, ctrl, every, 1000))


@pytest.mark.slow
@pytest.mark.parametrize("every", [1, 10])
@pytest.mark.parametrize("ctrl", ["zero", "random"])
@pytest.mark.parametrize("name", ["r2d2", "kuka_cube"])
def test_pybullet_robots_are_clean(name, ctrl, every):
    _assert_clean_on_geoms(_pybullet_log(name, ctrl, every, 1000))
