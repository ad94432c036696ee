"""rblog.adapters.pybullet on worlds built by hand: a bouncing ball and a sliding box (against
numpy on pybullet's states and Coulomb's law), every shape pybullet makes, Bullet's damping against
its closed form, applied loads, joints against the URDF and their own invariants, strides, and the
one-line errors."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

pb = pytest.importorskip("pybullet")
pybullet_data = pytest.importorskip("pybullet_data")
from rblog.adapters import AdapterError  # noqa: E402
from rblog.adapters.pybullet import DAMPING_DEFAULT, PybulletRecorder, load_shipped  # noqa: E402
from rblog.contract.orientation import quat_wxyz_to_matrix  # noqa: E402

DT = 1e-3
G = 9.81
#: measured: 8.9e-16 N s (Bullet applies exactly the impulses it reports)
BALANCE_NS = 1e-9


@pytest.fixture
def client():
    cid = pb.connect(pb.DIRECT)
    pb.setGravity(0, 0, -G, physicsClientId=cid)
    pb.setTimeStep(DT, physicsClientId=cid)
    plane = pb.createMultiBody(0, pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=cid),
                               physicsClientId=cid)
    pb.changeDynamics(plane, -1, restitution=1.0, lateralFriction=1.0, physicsClientId=cid)
    yield cid
    pb.disconnect(physicsClientId=cid)


def body(cid, shape, mass, pos, restitution, friction, damped=False, **kw):
    col = pb.createCollisionShape(shape, physicsClientId=cid, **kw)
    bid = pb.createMultiBody(mass, col, basePosition=pos, physicsClientId=cid)
    pb.changeDynamics(bid, -1, restitution=restitution, lateralFriction=friction, physicsClientId=cid)
    if not damped:
        pb.changeDynamics(bid, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=cid)
    return bid


def run(cid, n, **kw):
    """The user's two lines, plus pybullet's own velocities after every step."""
    rec = PybulletRecorder(cid, keep=True, **kw)       # line 1: the bodies of the client
    ids = [b for b, _ in rec.world.rows]
    vel = [[pb.getBaseVelocity(b, physicsClientId=cid)[0] for b in ids]]
    for _ in range(n):
        pb.stepSimulation(physicsClientId=cid)
        rec()                                           # line 2: state, contacts, impulses
        vel.append([pb.getBaseVelocity(b, physicsClientId=cid)[0] for b in ids])
    rec.close()
    return rec.trajectory, np.array(vel)


def balance_residual(traj, vel) -> float:
    """max |m dv - m g dt - sum of the logged impulses| over steps and bodies (N s)."""
    kinds = [k for k in ("contact", "applied", "passive", "actuator", "joint")
             if traj.impulse(k) is not None]
    total = sum(traj.impulse(k)[0][1:] for k in kinds)
    mass = traj.model.body_mass[None, :, None]
    dp = mass * np.diff(vel, axis=0) - mass * np.array([0.0, 0.0, -G]) * DT
    return float(np.abs(dp - total).max())


def test_bouncing_ball(client):
    ball = body(client, pb.GEOM_SPHERE, 1.0, [0, 0, 1], 0.6, 0.5, radius=0.05)
    traj, vel = run(client, 900, damping={ball: (0.0, 0.0)})
    m = traj.model
    assert m.body_shape.tolist() == [0] and m.body_size[0, 0] == 0.05
    assert m.body_name[0].startswith("body1/")  # createMultiBody: no robot name
    np.testing.assert_allclose(m.body_inertia_diag[0], [0.4 * 0.05 ** 2] * 3)
    assert traj.info.combine_restitution == "product"
    assert balance_residual(traj, vel) < BALANCE_NS
    # numpy: the first bounce from pybullet's velocities: the steps whose dv is not -g dt push
    vz = vel[:, 0, 2]
    free = np.abs(np.diff(vz) / DT + G) < 1e-9
    k_in = np.flatnonzero(~free)[0]
    k_out = k_in + np.flatnonzero(free[k_in:])[0]
    e = vz[k_out] / -vz[k_in]
    assert abs(e - 0.6) < 0.05
    # the apex after the bounce is e^2 of the drop height (ballistic flight)
    apex = traj.position[k_out:k_out + 400, 0, 2].max() - 0.05
    assert apex == pytest.approx(e ** 2 * 0.95, rel=1e-2)  # measured 0.3 % (dt-sampled apex)


def test_box_slides_to_rest(client):
    box = body(client, pb.GEOM_BOX, 2.0, [0, 0, 0.05], 0.0, 0.5, halfExtents=[0.1, 0.1, 0.05])
    pb.resetBaseVelocity(box, [1.0, 0, 0], [0, 0, 0], physicsClientId=client)
    traj, vel = run(client, 400, damping={box: (0.0, 0.0)})
    m = traj.model
    assert m.body_shape.tolist() == [1]
    np.testing.assert_allclose(m.body_size[0], [0.1, 0.1, 0.05])
    assert traj.info.combine_friction == "product"
    assert balance_residual(traj, vel) < BALANCE_NS
    # Coulomb: the box slows at mu g with mu = 0.5 x 1.0 (Bullet's product) while it slides;
    # measured: Bullet's sliding box slows at 0.964 mu g (its friction stays inside the cone)
    vx = vel[:, 0, 0]
    sliding = vx[1:] > 0.05
    decel = -np.diff(vx)[sliding[:len(vx) - 1]] / DT
    assert 0.9 * 0.5 * G < np.median(decel) <= 0.5 * G * (1 + 1e-9)


def test_damping_is_bullets_closed_form(client):
    """pybullet's default damping on a tumbling cube in flight: the logged passive impulse is
    -m v (k + k|v|) dt and -R I R^T w (k + k|w|) dt, k = 0.04 as a float32 (btMultiBody), and
    with it the balance closes; left out, the momentum misses it by that much."""
    cube = body(client, pb.GEOM_BOX, 1.5, [0, 0, 5], 0.0, 0.5, damped=True,
                halfExtents=[0.1, 0.2, 0.3])
    pb.resetBaseVelocity(cube, [2.0, -1.0, 3.0], [1.0, 2.0, 3.0], physicsClientId=client)
    traj, vel = run(client, 200)
    k = float(np.float32(0.04))
    assert k == DAMPING_DEFAULT
    v0 = vel[:-1, 0]
    want = -1.5 * v0 * (k + k * np.linalg.norm(v0, axis=1))[:, None] * DT
    lin, ang = traj.impulse("passive")
    np.testing.assert_allclose(lin[1:, 0], want, rtol=1e-12, atol=0)
    assert balance_residual(traj, vel) < BALANCE_NS
    # both directions: without the passive impulse the balance misses by the damping
    mass = 1.5
    dp = mass * np.diff(vel, axis=0)[:, 0] - mass * np.array([0, 0, -G]) * DT
    assert np.abs(dp).max() > 0 and np.abs(dp - want).max() < BALANCE_NS
    assert np.abs(dp).min() > 1e3 * BALANCE_NS
    # angular: L = R I R^T w changes by the logged angular damping within the free-flight drift
    r = np.array([quat_wxyz_to_matrix(q) for q in traj.quat_wxyz[:, 0]])
    inertia = traj.model.body_inertia_diag[0]
    w = traj.angular_velocity[:, 0]
    lmom = np.einsum("tij,tj->ti", r, inertia * np.einsum("tji,tj->ti", r, w))
    w_body = np.einsum("tji,tj->ti", r[:-1], w[:-1])
    want_a = -np.einsum("tij,tj->ti", r[:-1], inertia * w_body) * \
        (k + k * np.linalg.norm(w[:-1], axis=1))[:, None] * DT
    np.testing.assert_allclose(ang[1:, 0], want_a, rtol=1e-12, atol=1e-18)
    # what is left is Bullet's free-flight drift (its explicit gyroscopic term): measured
    # 2.3e-6 |L| per step, against the damping's 1.9e-4 |L| per step
    drift = np.abs(np.diff(lmom, axis=0) - ang[1:, 0]).max() / np.abs(lmom).max()
    assert drift < 1e-5
    assert np.abs(np.diff(lmom, axis=0)).max() / np.abs(lmom).max() > 1e-4


def test_user_damping_is_declared(client):
    """changeDynamics(linearDamping=0) cannot be read back: undeclared, the log carries the
    default and misses the momentum by it; declared with damping=, it balances."""
    cube = body(client, pb.GEOM_BOX, 1.0, [0, 0, 5], 0.0, 0.5, halfExtents=[0.1, 0.1, 0.1])
    pb.resetBaseVelocity(cube, [3.0, 0, 0], [0, 0, 0], physicsClientId=client)
    traj, vel = run(client, 50)
    assert balance_residual(traj, vel) > 1e-6  # measured 5e-4 N s: the default 0.04 damping
    pb.resetBaseVelocity(cube, [3.0, 0, 0], [0, 0, 0], physicsClientId=client)
    traj, vel = run(client, 50, damping={cube: (0.0, 0.0)})
    assert balance_residual(traj, vel) < BALANCE_NS
    with pytest.raises(AdapterError, match="damping: body ids \\[99\\]"):
        PybulletRecorder(client, damping={99: (0.0, 0.0)})


def test_applied_loads(client):
    """Loads given through the recorder are logged (F dt; (x - c) x F dt about the centre of
    mass); one given to pybullet directly is invisible: the balance misses it by F dt."""
    cube = body(client, pb.GEOM_BOX, 2.0, [0, 0, 5], 0.0, 0.5, halfExtents=[0.1, 0.1, 0.1])
    rec = PybulletRecorder(client, keep=True, damping={cube: (0.0, 0.0)})
    vel = [pb.getBaseVelocity(cube, physicsClientId=client)[0]]
    force = np.array([3.0, -4.0, 20.0])
    for k in range(20):
        pos = np.array(pb.getBasePositionAndOrientation(cube, physicsClientId=client)[0])
        if k < 10:
            rec.apply_external_force(cube, -1, force, pos + [0.1, 0.0, 0.0])
        else:
            pb.applyExternalForce(cube, -1, force.tolist(), pos.tolist(), pb.WORLD_FRAME,
                                  physicsClientId=client)
        pb.stepSimulation(physicsClientId=client)
        rec()
        vel.append(pb.getBaseVelocity(cube, physicsClientId=client)[0])
    rec.close()
    traj, vel = rec.trajectory, np.array(vel)[:, None]
    lin, ang = traj.impulse("applied")
    np.testing.assert_allclose(lin[1:11, 0], np.tile(force * DT, (10, 1)), rtol=1e-15)
    np.testing.assert_allclose(ang[1:11, 0], np.tile(np.cross([0.1, 0, 0], force) * DT, (10, 1)),
                               rtol=1e-12, atol=1e-18)
    mass = 2.0
    dp = mass * np.diff(vel, axis=0)[:, 0] - mass * np.array([0, 0, -G]) * DT
    res = dp - sum(traj.impulse(k)[0][1:, 0] for k in ("contact", "applied", "passive"))
    assert np.abs(res[:10]).max() < BALANCE_NS
    np.testing.assert_allclose(res[10:], np.tile(force * DT, (10, 1)), rtol=1e-9)
    rec = PybulletRecorder(client, applied=False)
    assert (rec.model.body_impulse_supplied[:, 1] == 0).all()  # applied: missing
    rec.close()


def test_every_shape(client):
    """Sphere, box, capsule, cylinder, mesh, a compound and a plane become geoms of their kind
    with pybullet's sizes (its capsule and cylinder heights are the cylinder part's length)."""
    shapes = [(pb.GEOM_SPHERE, dict(radius=0.1)), (pb.GEOM_BOX, dict(halfExtents=[0.1, 0.2, 0.3])),
              (pb.GEOM_CAPSULE, dict(radius=0.1, height=0.4)),
              (pb.GEOM_CYLINDER, dict(radius=0.15, height=0.5)),
              (pb.GEOM_MESH, dict(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                                  meshScale=[0.2, 0.2, 0.2]))]
    for k, (t, kw) in enumerate(shapes):
        col = pb.createCollisionShape(t, collisionFramePosition=[0.01, 0.02, 0.03],
                                      physicsClientId=client, **kw)
        pb.createMultiBody(1.0, col, basePosition=[k, 0, 1], physicsClientId=client)
    arr = pb.createCollisionShapeArray([pb.GEOM_BOX, pb.GEOM_SPHERE], halfExtents=[[0.1] * 3, [0] * 3],
                                       radii=[0, 0.05], collisionFramePositions=[[0, 0, 0], [0, 0, 0.3]],
                                       physicsClientId=client)
    pb.createMultiBody(1.0, arr, basePosition=[9, 0, 1], physicsClientId=client)
    rec = PybulletRecorder(client)
    m = rec.model
    rec.close()
    names = ("sphere", "box", "capsule", "cylinder", "ellipsoid", "mesh", "plane")
    kinds = [names[int(t)] for t in m.geom_type]
    assert kinds == ["plane", "sphere", "box", "capsule", "cylinder", "mesh", "box", "sphere"]
    assert m.geom_body.tolist() == [-1, 0, 1, 2, 3, 4, 5, 5]
    np.testing.assert_allclose(m.geom_size[1:5], [[0.1, 0, 0], [0.1, 0.2, 0.3], [0.1, 0.2, 0],
                                                  [0.15, 0.25, 0]])
    np.testing.assert_allclose(m.geom_pos_body[1:6], [[0.01, 0.02, 0.03]] * 5)
    a, n = int(m.geom_vert_adr[5]), int(m.geom_vert_num[5])
    got = sorted(map(tuple, np.round(m.mesh_vert[a:a + n], 15)))  # Bullet's hull orders them
    assert got == sorted(map(tuple, 0.2 * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])))
    np.testing.assert_allclose(m.geom_pos_body[7], [0, 0, 0.3])
    assert m.body_shape[5] == -1  # two geoms: no single v2 shape
    assert m.ground and m.ground_normal.tolist() == [0.0, 0.0, 1.0]


def _joint_invariants(tr, q):
    """max over samples and joints of |anchor from the child - from the parent - q axis| (m; q a
    slide's position, pybullet's own, (T, J)) and of |axis from the child - from the parent|."""
    m = tr.model
    worst_p = worst_a = 0.0
    for t in range(len(tr.t)):
        for i in range(len(m.joint_name)):
            c = int(m.joint_body[i])
            p = int(m.body_parent[c])
            rc = quat_wxyz_to_matrix(tr.quat_wxyz[t, c])
            at_c = tr.position[t, c] + rc @ m.joint_anchor_body[i]
            if p < 0:
                at_p, ax_p = m.joint_anchor_parent[i], m.joint_axis_parent[i]
            else:
                rp = quat_wxyz_to_matrix(tr.quat_wxyz[t, p])
                at_p = tr.position[t, p] + rp @ m.joint_anchor_parent[i]
                ax_p = rp @ m.joint_axis_parent[i]
            if int(m.joint_type[i]) == 2:  # JOINT_SLIDE: the child's anchor moved q along it
                at_p = at_p + q[t, i] * ax_p
            worst_p = max(worst_p, float(np.abs(at_c - at_p).max()))
            worst_a = max(worst_a, float(np.abs(rc @ m.joint_axis_body[i] - ax_p).max()))
    return worst_p, worst_a


@pytest.mark.parametrize("world,urdf", [("kuka_cube", "kuka_iiwa/model.urdf"), ("r2d2", "r2d2.urdf")])
def test_joints_against_the_urdf_and_their_invariants(world, urdf):
    """Joint types and limits as the URDF states them; at every step of the motion the anchor
    seen from the child and from the parent is one point, and a hinge's axis one axis."""
    cid = pb.connect(pb.DIRECT)
    try:
        load_shipped(world, cid)
        for j in range(pb.getNumJoints(1, physicsClientId=cid)):  # drive every joint (body 1)
            pb.setJointMotorControl2(1, j, pb.VELOCITY_CONTROL, targetVelocity=0.5 * (-1) ** j,
                                     force=500.0, physicsClientId=cid)
        rec = PybulletRecorder(cid, keep=True)
        nj = pb.getNumJoints(1, physicsClientId=cid)
        q = [[s[0] for s in pb.getJointStates(1, range(nj), physicsClientId=cid)]]
        for _ in range(100):
            rec.step()
            q.append([s[0] for s in pb.getJointStates(1, range(nj), physicsClientId=cid)])
        rec.close()
        tr = rec.trajectory
    finally:
        pb.disconnect(physicsClientId=cid)
    m = tr.model
    root = ET.parse(Path(pybullet_data.getDataPath()) / urdf).getroot()
    joints = {j.get("name"): j for j in root.findall("joint")}
    assert sorted(m.joint_name) == sorted(joints)
    codes = {"revolute": 3, "continuous": 3, "prismatic": 2, "fixed": 4}  # JOINT_HINGE, ...
    for i, name in enumerate(m.joint_name):
        j = joints[name]
        assert int(m.joint_type[i]) == codes[j.get("type")]
        lim = j.find("limit")
        # a continuous joint's <limit lower upper> (r2d2's head_swivel) is reported by
        # getJointInfo like a revolute's, and Bullet does not enforce it: logged as reported
        if lim is not None and lim.get("lower") is not None:
            np.testing.assert_allclose(m.joint_range[i], [float(lim.get("lower")),
                                                          float(lim.get("upper"))])
        else:
            assert np.isnan(m.joint_range[i]).all()
    worst_p, worst_a = _joint_invariants(tr, np.array(q))  # joint rows in pybullet's order
    # measured: kuka 2.2e-16 m and 9e-16; r2d2 (falling, driven) 4.2e-16 m and 9.7e-16
    assert worst_p < 1e-12 and worst_a < 1e-8, (worst_p, worst_a)
    assert np.abs(tr.angular_velocity[-1]).max() > 0.1  # it did move


def test_stride_sums_the_steps():
    """A log at every 10th step carries the sum of the ten steps' impulses of a log at every
    step (the same world, deterministic)."""
    out = []
    for stride in (1, 10):
        cid = pb.connect(pb.DIRECT)
        try:
            load_shipped("domino", cid)
            rec = PybulletRecorder(cid, keep=True, every=stride)
            rec.step(60)
            rec.close()
            out.append(rec.trajectory)
        finally:
            pb.disconnect(physicsClientId=cid)
    every, tenth = out
    for kind in ("contact", "passive"):
        a, b = every.impulse(kind), tenth.impulse(kind)
        for part in (0, 1):
            sums = a[part][1:].reshape(6, 10, *a[part].shape[1:]).sum(axis=1)
            np.testing.assert_allclose(b[part][1:], sums, rtol=1e-12, atol=1e-18)
    np.testing.assert_array_equal(tenth.position, every.position[::10])


def test_maximal_coordinates_recorded_and_missing_named():
    cid = pb.connect(pb.DIRECT)
    try:
        load_shipped("r2d2_maximal", cid)
        rec = PybulletRecorder(cid, keep=True)
        rec.step(10)
        rec.close()
    finally:
        pb.disconnect(physicsClientId=cid)
    es = rec.trajectory.info.engine_settings
    assert es["missing"] == {"contact": ["body1/base_link"], "geoms": ["body1/base_link"],
                             "joint": ["body1/base_link"]}
    assert "useMaximalCoordinates" in es["maximal_coordinates"]
    # contact missing, applied logged, passive none (no damping), actuator none, joint missing
    assert rec.model.body_impulse_supplied[0].tolist() == [0, 1, 2, 2, 0, 2]


def test_unsupported_shapes_are_one_line_naming_each(client):
    for k in range(2):
        field = pb.createCollisionShape(pb.GEOM_HEIGHTFIELD, meshScale=[0.1, 0.1, 1],
                                        heightfieldData=[0.0, 0.1] * 8, numHeightfieldRows=4,
                                        numHeightfieldColumns=4, physicsClientId=client)
        pb.createMultiBody(0, field, basePosition=[k, 0, 0], physicsClientId=client)
    body(client, pb.GEOM_SPHERE, 1.0, [0, 0, 1], 0.5, 0.5, radius=0.1)
    with pytest.raises(AdapterError, match=r"^rblog\.adapters\.pybullet: the contract has no place "
                                           r"for 2 element\(s\) of client \d+: body1/\w+: no "
                                           r"collision shape data .*; body2/\w+: no collision") as e:
        PybulletRecorder(client)
    assert "\n" not in str(e.value)


def test_only_static_geometry_is_one_line(client):
    with pytest.raises(AdapterError, match="has no dynamic body to record"):
        PybulletRecorder(client)


def test_bad_client_is_one_line():
    with pytest.raises(AdapterError, match="rblog.adapters.pybullet"):
        PybulletRecorder(12345)


@pytest.mark.parametrize("every", [1, 10])
def test_rblog_run_engine_pybullet_logs_the_impulses(every):
    """``rblog run --engine pybullet`` reads Bullet through the adapter: each interval's logged
    contact + applied + passive impulses and m g dt make each body's momentum change (pybullet's
    velocities, logged), on the box_stack sample."""
    from rblog.engine.scene import load_scene
    from rblog.study.engines import run_engine
    from tests.conftest import SAMPLES_DIR

    scene = load_scene(SAMPLES_DIR / "box_stack.toml")
    _, tr = run_engine(scene, "pybullet", duration=0.5, log_every=every, keep=True)
    m = tr.model
    assert (m.body_impulse_supplied == np.array([1, 1, 1, 2, 2, 2])).all()
    mass = m.body_mass[None, :, None]
    dp = np.diff(mass * tr.velocity, axis=0) - mass * m.gravity * np.diff(tr.t)[:, None, None]
    total = sum(tr.impulse(k)[0][1:] for k in ("contact", "applied", "passive"))
    scale = np.abs(mass * tr.velocity).max() + np.abs(total).max()
    # measured: 1.4e-15 relative at every step, 1.5e-15 at every 10th (Bullet's own numbers)
    assert np.abs(dp - total).max() / scale < 1e-12
    assert np.abs(tr.impulse("contact")[0]).max() > 0


def test_contact_rows_carry_the_contact_impulse():
    """At every step the logged contact rows (impulses on body_a, minus on body_b) sum per body
    to the interval's contact impulse; speculative points (no force, apart) have no row."""
    cid = pb.connect(pb.DIRECT)
    try:
        load_shipped("tray", cid)
        rec = PybulletRecorder(cid, keep=True)
        rec.step(150)
        rec.close()
    finally:
        pb.disconnect(physicsClientId=cid)
    tr = rec.trajectory
    c = tr.contacts
    j = c.normal_impulse[:, None] * c.normal + c.friction_impulse
    want = np.zeros_like(tr.impulse("contact")[0])
    np.add.at(want, (c.step, c.body_a), j)
    keep = c.body_b >= 0
    np.add.at(want, (c.step[keep], c.body_b[keep]), -j[keep])
    # measured: 2.2e-19 N s (the rows and the channel sum the same products)
    assert np.abs(want - tr.impulse("contact")[0]).max() < 1e-15
    assert not ((c.normal_impulse == 0) & (c.separation > 0)).any()
    assert len(c.step) > 100


def test_substeps_mark_contacts_missing(client):
    """With numSubSteps > 1 pybullet reports the last substep's forces only: contacts, damping
    and joints are missing, and no contact rows are logged."""
    pb.setPhysicsEngineParameter(numSubSteps=4, physicsClientId=client)
    body(client, pb.GEOM_SPHERE, 1.0, [0, 0, 0.3], 0.5, 0.5, radius=0.05)
    traj, _ = run(client, 300)
    assert traj.contacts is None or len(traj.contacts.step) == 0
    assert traj.model.body_impulse_supplied[0].tolist() == [0, 1, 0, 2, 2, 2]
    assert "numSubSteps 4" in traj.info.engine_settings["contact_rows"]["logged"]
    assert traj.position[:, 0, 2].min() < 0.06  # it did touch the floor


def test_applied_in_the_link_frame(client):
    """LINK_FRAME: force and point in the body's frame, turned by its orientation."""
    cube = body(client, pb.GEOM_BOX, 2.0, [0, 0, 5], 0.0, 0.5, halfExtents=[0.1, 0.2, 0.3])
    q = pb.getQuaternionFromEuler([0.3, -0.2, 1.0])
    pb.resetBasePositionAndOrientation(cube, [0, 0, 5], q, physicsClientId=client)
    rec = PybulletRecorder(client, keep=True, damping={cube: (0.0, 0.0)})
    v0 = np.array(pb.getBaseVelocity(cube, physicsClientId=client)[0])
    rec.apply_external_force(cube, -1, [0.0, 0.0, 10.0], [0.1, 0.0, 0.0], pb.LINK_FRAME)
    rec.step()
    rec.close()
    v1 = np.array(pb.getBaseVelocity(cube, physicsClientId=client)[0])
    lin, ang = rec.trajectory.impulse("applied")
    # pybullet's own response: m dv - m g dt is the applied impulse (no contact in flight)
    np.testing.assert_allclose(lin[1, 0], 2.0 * (v1 - v0) - 2.0 * np.array([0, 0, -G]) * DT,
                               rtol=1e-9, atol=1e-15)
    r = np.array(pb.getMatrixFromQuaternion(q)).reshape(3, 3)
    np.testing.assert_allclose(ang[1, 0], np.cross(r @ [0.1, 0, 0], r @ [0, 0, 10.0]) * DT,
                               rtol=1e-12, atol=1e-18)


def test_a_removed_body_is_one_line(client):
    ball = body(client, pb.GEOM_SPHERE, 1.0, [0, 0, 1], 0.5, 0.5, radius=0.1)
    rec = PybulletRecorder(client)
    pb.removeBody(ball, physicsClientId=client)
    pb.stepSimulation(physicsClientId=client)
    with pytest.raises(AdapterError, match=r"client \d+ after a step: pybullet: .*a body removed"):
        rec()
    rec.close(truncated=True)


@pytest.mark.parametrize("flip", [False, True])
def test_ground_slab_is_a_plane_and_a_static_box_stays_a_box(client, flip):
    """pybullet_data's plane.urdf collides as a 200 x 200 x 10 m box whose top face is z = 0
    (its URDF: box size 200 200 10 at xyz 0 0 -5): logged as the plane of that face, +z up,
    drawn 100 m x 100 m either way; the same slab loaded upside down (rolled 180 deg about x:
    the box spans z = 0 .. 10 m) gives the plane of its upper face, normal world +z; a 2 x 2 x 0.2 m static box stays a box."""
    pb.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=client)
    orn = [1.0, 0.0, 0.0, 0.0] if flip else [0.0, 0.0, 0.0, 1.0]  # xyzw: 180 deg about x
    pb.loadURDF("plane.urdf", [0.0, 0.0, 0.0], orn, physicsClientId=client)
    box = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[1.0, 1.0, 0.1], physicsClientId=client)
    pb.createMultiBody(0.0, box, basePosition=[0, 0, 3], physicsClientId=client)
    pb.createMultiBody(1.0, pb.createCollisionShape(pb.GEOM_SPHERE, radius=0.1,
                                                    physicsClientId=client),
                       basePosition=[0, 0, 5], physicsClientId=client)
    rec = PybulletRecorder(client)
    m = rec.model
    rec.close()
    names = ("sphere", "box", "capsule", "cylinder", "ellipsoid", "mesh", "plane")
    # the fixture's own GEOM_PLANE first
    assert [names[int(t)] for t in m.geom_type] == ["plane", "plane", "box", "sphere"]
    assert m.geom_name[1] == "plane/planeLink"
    np.testing.assert_allclose(m.geom_size[1], [100.0, 100.0, 0.0], rtol=0, atol=0)
    # the upper face: z = 0 as loaded, z = +10 upside down (the box's centre at +5)
    np.testing.assert_allclose(m.geom_pos_body[1], [0, 0, 10.0 if flip else 0.0], rtol=0,
                               atol=1e-12)
    normal = quat_wxyz_to_matrix(m.geom_quat_wxyz_body[1])[:, 2]
    np.testing.assert_allclose(normal, [0, 0, 1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(m.geom_size[2], [1.0, 1.0, 0.1], rtol=0, atol=1e-12)
