"""pybullet's joint loads under TORQUE_CONTROL and Bullet's velocity bound, held against pybullet's
own velocities (getLinkState) and masses (getDynamicsInfo), independently of rblog's analyzers.

Under TORQUE_CONTROL pybullet adds the torque to the joint in Bullet's articulated-body pass
(addJointTorque), so the joint's reaction (getJointState's jointReactionForces) carries it, and
``appliedJointMotorTorque`` is 0 (pybullet reports the motor constraint's impulse only under
VELOCITY_CONTROL and POSITION_CONTROL): each link's logged impulses + m g dt equal m dv.
Bullet clamps every generalized velocity of a multibody to +-100 (m_maxCoordinateVelocity): a
step that ends with a joint there removed momentum no load accounts for, and the adapter logs
the joint impulse of the rows that joint moves as NaN there (not judged).
"""

from __future__ import annotations

import numpy as np
import pytest

pb = pytest.importorskip("pybullet")
pybullet_data = pytest.importorskip("pybullet_data")

import rblog  # noqa: E402
from rblog.adapters.pybullet import MAX_COORDINATE_VELOCITY, PybulletRecorder  # noqa: E402

G = np.array([0.0, 0.0, -9.81])
#: kuka bent (joints 2 and 4 carry ~20 N m of gravity), held by TORQUE_CONTROL
BENT = [0.3, 0.9, -0.4, -1.2, 0.5, 0.8, 0.0]
#: |m dv - m g dt - logged impulses| per link and step, N s (measured: 9.8e-5 at most, the
#: joints at up to 1.5 rad/s; the step's first-order error of Bullet's generalized coordinates)
LIN_NS = 3e-4
#: |dL - logged angular impulses|, N m s (measured: 4.3e-6 at most); the torques' own impulses
#: tau dt are up to 0.18 N m s, so counting them twice would leave ~0.1 here
ANG_NMS = 1.5e-5


def _state(cid, bid, n):
    """pybullet's own (position, rotation, v, w) of each link's inertial frame."""
    out = []
    for s in pb.getLinkStates(bid, list(range(n)), computeLinkVelocity=1,
                              computeForwardKinematics=1, physicsClientId=cid):
        rot = np.array(pb.getMatrixFromQuaternion(s[1])).reshape(3, 3)
        out.append((np.array(s[0]), rot, np.array(s[6]), np.array(s[7])))
    return out


def _run(steps, joint_damping, amplitude):
    """kuka on a fixed base from BENT, its motors off, under TORQUE_CONTROL at every step: the
    gravity and Coriolis torques of pybullet's calculateInverseDynamics plus uniform noise
    (``amplitude`` N m on joints 1-4, a tenth on 5-6, a hundredth on 7). ``joint_damping``
    False: the URDF's joint damping (0.5) set to 0 (Bullet applies it explicitly: on link 7,
    dt c / I > 2, it diverges to the velocity bound in ~5 steps)."""
    cid = pb.connect(pb.DIRECT)
    try:
        pb.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=cid)
        pb.setGravity(0.0, 0.0, -9.81, physicsClientId=cid)
        b = pb.loadURDF("kuka_iiwa/model.urdf", useFixedBase=True, physicsClientId=cid)
        n = pb.getNumJoints(b, physicsClientId=cid)
        js = list(range(n))
        for j, q in enumerate(BENT):
            pb.resetJointState(b, j, q, physicsClientId=cid)
            if not joint_damping:
                pb.changeDynamics(b, j, jointDamping=0.0, physicsClientId=cid)
        pb.setJointMotorControlArray(b, js, pb.VELOCITY_CONTROL, forces=[0.0] * n,
                                     physicsClientId=cid)
        info = [pb.getDynamicsInfo(b, j, physicsClientId=cid) for j in js]
        mass = np.array([i[0] for i in info])
        inertia = np.array([i[2] for i in info])
        rec = PybulletRecorder(cid, keep=True)
        rng = np.random.default_rng(3)
        scale = amplitude * np.array([1, 1, 1, 1, 0.1, 0.1, 0.01])
        st, tau, motor, qd = [_state(cid, b, n)], [], [], []
        for _ in range(steps):
            s = pb.getJointStates(b, js, physicsClientId=cid)
            t = np.array(pb.calculateInverseDynamics(b, [x[0] for x in s], [x[1] for x in s],
                                                     [0.0] * n, physicsClientId=cid))
            t = t + rng.uniform(-1.0, 1.0, n) * scale
            pb.setJointMotorControlArray(b, js, pb.TORQUE_CONTROL, forces=list(t),
                                         physicsClientId=cid)
            pb.stepSimulation(physicsClientId=cid)
            rec()
            st.append(_state(cid, b, n))
            s = pb.getJointStates(b, js, physicsClientId=cid)
            tau.append(t)
            motor.append([x[3] for x in s])
            qd.append([x[1] for x in s])
        rec.close()
    finally:
        pb.disconnect(physicsClientId=cid)
    tr = rec.trajectory
    dt = tr.info.dt
    assert list(rec.world.rows) == [(b, j) for j in js]  # the base is welded: rows = links
    # pybullet's own balance: m dv - m g dt and dL (L = R I R^T w about the centre of mass)
    dp = np.array([[mass[i] * (b1[i][2] - b0[i][2]) - mass[i] * G * dt for i in js]
                   for b0, b1 in zip(st[:-1], st[1:])])
    ang = lambda x, i: x[i][1] @ (inertia[i] * (x[i][1].T @ x[i][3]))
    dl = np.array([[ang(b1, i) - ang(b0, i) for i in js] for b0, b1 in zip(st[:-1], st[1:])])
    kinds = [k for k in ("contact", "applied", "passive", "actuator", "joint")
             if tr.impulse(k) is not None]
    jl = sum(tr.impulse(k)[0][1:] for k in kinds)
    ja = sum(tr.impulse(k)[1][1:] for k in kinds)
    return dict(traj=tr, dt=dt, tau=np.array(tau), motor=np.array(motor), qd=np.array(qd),
                res_lin=np.linalg.norm(dp - jl, axis=2), res_ang=np.linalg.norm(dl - ja, axis=2))


def test_torque_control_balances_to_pybullets_own_velocities():
    """240 steps, no joint damping, noise 1 N m: every link's logged impulses + m g dt are its
    m dv from pybullet's velocities, and its angular impulses its dL, with the torques counted
    once (pybullet reports no motor torque under TORQUE_CONTROL: the reaction carries it)."""
    r = _run(240, joint_damping=False, amplitude=1.0)
    assert (r["motor"] == 0.0).all()
    assert np.abs(r["qd"]).max() < 0.1 * MAX_COORDINATE_VELOCITY
    assert np.abs(r["tau"]).max() * r["dt"] > 0.1  # a double count would show
    assert np.isfinite(r["res_lin"]).all()
    assert r["res_lin"].max() <= LIN_NS
    assert r["res_ang"].max() <= ANG_NMS
    res = next(x for x in rblog.check(r["traj"], threads=1) if x.analyzer == "momentum")
    assert res.passed, [f.message for f in res.findings]


def test_a_joint_at_bullets_velocity_bound_is_not_judged():
    """The URDF's joint damping left on: link 7 spins up to the bound within ~5 steps (pybullet's
    own joint velocity exactly 100 rad/s). Its joint impulse is NaN in exactly the steps that end
    with joint 7 at the bound (its only row: a leaf), finite elsewhere; where finite, each link
    balances against pybullet's velocities as above (at the bound, link 7 was measured 0.0985 N m s
    a step off, 2e4 times ANG_NMS). `momentum` passes, saying how many intervals it left out."""
    r = _run(120, joint_damping=True, amplitude=0.0)
    at = np.abs(r["qd"]) >= MAX_COORDINATE_VELOCITY
    assert at[:, 6].sum() > 50 and not at[:, :6].any()
    nan = np.isnan(r["res_lin"]) | np.isnan(r["res_ang"])
    assert (nan[:, 6] == at[:, 6]).all() and not nan[:, :6].any()
    # judged steps: the joints off the bound, the others up to ~10 rad/s (their first-order
    # step error, measured: 0.0158 N s linear, 2.2e-4 N m s angular at most; 1e-6 before)
    ok = ~nan
    early = np.zeros_like(ok)
    early[:4] = True
    assert r["res_lin"][early & ok].max() <= LIN_NS
    assert r["res_ang"][early & ok].max() <= ANG_NMS
    res = next(x for x in rblog.check(r["traj"], threads=1) if x.analyzer == "momentum")
    assert res.passed, [f.message for f in res.findings]
    assert res.stats["balance_intervals_not_judged"] == at[:, 6].sum()
    assert "not judged in" in res.reason and "lbr_iiwa_link_7" in res.reason


@pytest.mark.parametrize("mode", ["position", "velocity"])
def test_a_motor_constraint_is_counted_once(mode):
    """POSITION_CONTROL holding BENT, and VELOCITY_CONTROL following 0.3 sin(t / 0.083 s) rad/s,
    both at up to 300 N m: Bullet's motor is a constraint (its impulse appliedJointMotorTorque x
    dt, not in the reaction), logged once as a couple on the child and the parent; every link's
    dL equals its logged angular impulses against pybullet's own velocities (measured: 3.9e-7
    and 3.0e-5 N m s at most, the motors' impulses up to 0.18 and 0.21 N m s)."""
    cid = pb.connect(pb.DIRECT)
    try:
        pb.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=cid)
        pb.setGravity(0.0, 0.0, -9.81, physicsClientId=cid)
        b = pb.loadURDF("kuka_iiwa/model.urdf", useFixedBase=True, physicsClientId=cid)
        js = list(range(pb.getNumJoints(b, physicsClientId=cid)))
        for j, q in enumerate(BENT):
            pb.resetJointState(b, j, q, physicsClientId=cid)
        inertia = np.array([pb.getDynamicsInfo(b, j, physicsClientId=cid)[2] for j in js])
        rec = PybulletRecorder(cid, keep=True)
        st, motor = [_state(cid, b, len(js))], []
        for k in range(240):
            if mode == "position":
                pb.setJointMotorControlArray(b, js, pb.POSITION_CONTROL, targetPositions=BENT,
                                             forces=[300.0] * len(js), physicsClientId=cid)
            else:
                pb.setJointMotorControlArray(b, js, pb.VELOCITY_CONTROL,
                                             targetVelocities=[0.3 * np.sin(k / 20)] * len(js),
                                             forces=[300.0] * len(js), physicsClientId=cid)
            pb.stepSimulation(physicsClientId=cid)
            rec()
            st.append(_state(cid, b, len(js)))
            motor.append([s[3] for s in pb.getJointStates(b, js, physicsClientId=cid)])
        rec.close()
    finally:
        pb.disconnect(physicsClientId=cid)
    tr = rec.trajectory
    ang = lambda x, i: x[i][1] @ (inertia[i] * (x[i][1].T @ x[i][3]))
    dl = np.array([[ang(b1, i) - ang(b0, i) for i in js] for b0, b1 in zip(st[:-1], st[1:])])
    ja = sum(tr.impulse(k)[1][1:] for k in ("contact", "applied", "passive", "joint")
             if tr.impulse(k) is not None)
    assert np.abs(motor).max() * tr.info.dt > 0.1  # once more, or missing, would show
    assert np.linalg.norm(dl - ja, axis=2).max() <= 1e-4  # 3x the velocity case's 3.0e-5
