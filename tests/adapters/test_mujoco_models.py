"""dm_control's models as shipped (the MJCF files inside the dm-control package), recorded with
rblog.adapters.mujoco in two lines at every step and every 10th, with zero and random controls.
Everything is compared with MuJoCo's own numbers, computed here on a separate MjData (mj_forward
at the logged qpos/qvel, mj_objectVelocity, geom_xpos/geom_xmat, mj_subtreeVel), never with
what the adapter computed:

* every geom's type, size and world pose at every sample;
* each body's momentum change over each interval against its logged impulses + m g dt: stacker's
  boxes (planar slides whose centre of mass is on the slides) to round-off; free bodies up to
  the closed-form K of the adapter's docstring (MuJoCo integrates the free joint's origin, not
  the centre of mass), to 1e-9 relative; bodies on joints within the step's integration error,
  shown second order (halving dt quarters it);
* a free box spinning on the floor: its angular momentum change = logged impulses + the drift
  MuJoCo's Euler has in free flight (a closed form of qpos/qvel), to round-off;
* the joint impulses of a tree hanging from a free body sum to zero (Newton's third law inside
  MuJoCo's cfrc_int); the contact channel equals the sum of the contact rows.
"""

from __future__ import annotations

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")
pytest.importorskip("dm_control")
from rblog.adapters import AdapterError  # noqa: E402
from rblog.adapters import mujoco as adapter  # noqa: E402
from rblog.contract.model import (BODY_FREE, BODY_JOINTED, GEOM_BOX, GEOM_CAPSULE,  # noqa: E402
                                  GEOM_CYLINDER, GEOM_ELLIPSOID, GEOM_MESH, GEOM_PLANE,
                                  GEOM_SPHERE, IMPULSE_KINDS, WORK_KINDS)
from rblog.contract.orientation import quat_wxyz_to_matrix  # noqa: E402

MODELS = ["humanoid", "stacker", "manipulator", "cartpole", "walker", "ball_in_cup", "finger", "fish"]
STEPS = 200
#: geom world poses: the log's body pose x the geom's pose in it against MuJoCo's geom_xpos /
#: geom_xmat; body poses against xipos / ximat. Measured: 4.4e-16 (m, matrix entries) for the
#: geoms; 0 for the bodies (the same MuJoCo calls)
POSE_TOL = 1e-12
#: impulse balances, relative to the largest momentum change of the body over the run (or the
#: largest joint impulse). Measured at 200 steps: stacker's boxes 2.7e-14, free bodies after K
#: 1.6e-15, a free tree's joint impulses 1.2e-14 (sum), 2.0e-14 (moment)
BALANCE_REL = 1e-9

_MJ_GEOM = {0: GEOM_PLANE, 2: GEOM_SPHERE, 3: GEOM_CAPSULE, 4: GEOM_ELLIPSOID, 5: GEOM_CYLINDER,
            6: GEOM_BOX, 7: GEOM_MESH}


def record(name, every=1, ctrl="random", steps=STEPS, integrator=None, model=None):
    """The user's two lines on a dm_control model, and MuJoCo's own state after every step."""
    m = adapter.suite_model(name) if model is None else model
    if integrator:
        m.opt.integrator = getattr(mujoco.mjtIntegrator, "mjINT_" + integrator.upper())
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    rng = np.random.default_rng(7)
    qpos, qvel = [d.qpos.copy()], [d.qvel.copy()]
    rec = adapter.recorder(m, d, every=every)         # line 1
    for _ in range(steps):
        if ctrl == "random":
            d.ctrl[:] = rng.uniform(-1.0, 1.0, m.nu)
        mujoco.mj_step(m, d)
        rec(d)                                         # line 2
        qpos.append(d.qpos.copy())
        qvel.append(d.qvel.copy())
    rec.close()
    return m, rec.trajectory, np.array(qpos), np.array(qvel)


def mujoco_state(m, qpos, qvel):
    """MuJoCo's own (xipos, ximat, p = m v_com, L about the COM, geom_xpos, geom_xmat) of every
    body but the world at each given state (mj_forward, mj_objectVelocity at the COM)."""
    d = mujoco.MjData(m)
    nb = m.nbody - 1
    out = dict(x=[], r=[], p=[], L=[], gx=[], gr=[])
    vel = np.zeros(6)
    for q, v in zip(qpos, qvel):
        d.qpos[:], d.qvel[:] = q, v
        mujoco.mj_forward(m, d)
        p, L = np.zeros((nb, 3)), np.zeros((nb, 3))
        for b in range(1, m.nbody):
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, b, vel, 0)
            ri = d.ximat[b].reshape(3, 3)
            p[b - 1] = m.body_mass[b] * vel[3:]
            L[b - 1] = ri @ (m.body_inertia[b] * (ri.T @ vel[:3]))
        out["x"].append(d.xipos[1:].copy())
        out["r"].append(d.ximat[1:].reshape(-1, 3, 3).copy())
        out["p"].append(p)
        out["L"].append(L)
        out["gx"].append(d.geom_xpos.copy())
        out["gr"].append(d.geom_xmat.reshape(-1, 3, 3).copy())
    return {k: np.array(v) for k, v in out.items()}


#: the kinds of MuJoCo's forces at each step's start (the integration kind is the rest)
FORCE_KINDS = tuple(k for k in IMPULSE_KINDS if k != "integration")


def impulse_sum(traj):
    """(linear, angular) (T, N, 3): the logged impulses of MuJoCo's forces, FORCE_KINDS."""
    lin = sum(traj.impulse(k)[0] for k in FORCE_KINDS)
    ang = sum(traj.impulse(k)[1] for k in FORCE_KINDS)
    return lin, ang


def free_body_K(m, b, qpos, qvel):
    """(T-1, 3) the closed-form K of each step for free body b (adapter docstring):
    m [w1 x (arm1 - arm0) - h w0 x (w0 x arm0)], arm = R ipos, w = R w_body."""
    j = int(m.body_jntadr[b])
    qa, va = int(m.jnt_qposadr[j]), int(m.jnt_dofadr[j])
    r = quat_wxyz_to_matrix(qpos[:, qa + 3:qa + 7] / np.linalg.norm(qpos[:, qa + 3:qa + 7], axis=1)[:, None])
    arm = r @ np.asarray(m.body_ipos[b])
    w = np.einsum("tij,tj->ti", r, qvel[:, va + 3:va + 6])
    h = m.opt.timestep
    return m.body_mass[b] * (np.cross(w[1:], arm[1:] - arm[:-1]) - h * np.cross(w[:-1], np.cross(w[:-1], arm[:-1])))


#: (model, stride, controls, integrator): every model at both strides (random controls at every
#: step, zero at every 10th), the other pairings marked slow; implicitfast on the free-body models
CASES = [(name, 1, "random", None) for name in MODELS] + [(name, 10, "zero", None) for name in MODELS] + \
    [pytest.param(name, every, ctrl, None, marks=pytest.mark.slow)
     for name in MODELS for every, ctrl in ((1, "zero"), (10, "random"))] + \
    [(name, every, "random", "implicitfast") for name in ("humanoid", "stacker", "fish") for every in (1, 10)]


@pytest.mark.parametrize("name, every, ctrl, integrator", CASES, ids=lambda v: str(v))
def test_model_as_shipped(name, every, ctrl, integrator):
    m, traj, qpos, qvel = record(name, every=every, ctrl=ctrl, integrator=integrator)
    tm = traj.model
    steps = traj.step
    assert steps.tolist() == list(range(0, STEPS + 1, every))
    mj = mujoco_state(m, qpos[steps], qvel[steps])
    # every body, named as MuJoCo names them
    assert tm.body_name == [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(1, m.nbody)]
    np.testing.assert_allclose(traj.position, mj["x"], rtol=0, atol=POSE_TOL)
    np.testing.assert_allclose(traj.rotation, mj["r"], rtol=0, atol=POSE_TOL)
    # every geom: type, size, and its world pose at every sample
    gt = np.asarray(m.geom_type)
    keep = np.flatnonzero(np.isin(gt, list(_MJ_GEOM)))
    assert tm.n_geoms == len(keep)
    assert tm.geom_type.tolist() == [_MJ_GEOM[int(t)] for t in gt[keep]]
    for k, g in enumerate(keep):
        code, size = tm.geom_type[k], m.geom_size[g]
        n_size = {GEOM_SPHERE: 1, GEOM_CAPSULE: 2, GEOM_CYLINDER: 2, GEOM_PLANE: 2, GEOM_MESH: 0}.get(code, 3)
        np.testing.assert_array_equal(tm.geom_size[k, :n_size], size[:n_size])
        b = tm.geom_body[k]
        q = tm.geom_quat_wxyz_body[k]
        rg = quat_wxyz_to_matrix(q / np.linalg.norm(q))
        if b < 0:
            wx = np.broadcast_to(tm.geom_pos_body[k], (len(steps), 3))
            wr = np.broadcast_to(rg, (len(steps), 3, 3))
        else:
            wx = traj.position[:, b] + traj.rotation[:, b] @ tm.geom_pos_body[k]
            wr = traj.rotation[:, b] @ rg
        np.testing.assert_allclose(wx, mj["gx"][:, g], rtol=0, atol=POSE_TOL, err_msg=f"geom {g} position")
        np.testing.assert_allclose(wr, mj["gr"][:, g], rtol=0, atol=POSE_TOL, err_msg=f"geom {g} rotation")
    # linear balance per body: dp - impulses - m g dt, MuJoCo's momenta
    lin, ang = impulse_sum(traj)
    dt = np.diff(traj.t)[:, None, None]
    res = np.diff(mj["p"], axis=0) - lin[1:] - tm.body_mass[None, :, None] * tm.gravity * dt
    scale = np.abs(np.diff(mj["p"], axis=0)).max(axis=(0, 2)) + 1e-300
    integ_l, integ_a = traj.impulse("integration")
    for i in np.flatnonzero(tm.body_kind == BODY_FREE):
        b = i + 1
        K = free_body_K(m, b, qpos, qvel)  # per step; summed over each interval
        K_int = np.add.reduceat(K, steps[:-1], axis=0) if every > 1 else K
        assert np.abs(res[:, i] - K_int).max() <= BALANCE_REL * scale[i], tm.body_name[i]
    # every body with a joint kind (on joints, or free carrying others): the integration kind
    # closes the balance of MuJoCo's own momenta (mj_objectVelocity at the logged states),
    # linear and angular; lone free bodies log none
    sup = tm.body_impulse_supplied
    assert (sup[:, IMPULSE_KINDS.index("integration")] == sup[:, IMPULSE_KINDS.index("joint")]).all()
    dyn = np.flatnonzero(sup[:, IMPULSE_KINDS.index("integration")] == 1)
    if len(dyn):
        # relative to the balance's largest term (each kind's, m g dt); measured: 4e-16 absolute
        # where nothing moves (cartpole at rest), ~1e-15 of the terms elsewhere
        big_l = max(scale[dyn].max(), float((tm.body_mass[dyn] * np.linalg.norm(tm.gravity)).max()
                                            * dt.max()),
                    max(np.nanmax(np.abs(traj.impulse(k)[0][:, dyn])) for k in FORCE_KINDS))
        np.testing.assert_allclose(res[:, dyn] - integ_l[1:, dyn], 0.0, rtol=0,
                                   atol=BALANCE_REL * big_l)
        dl = np.diff(mj["L"], axis=0) - ang[1:]
        big = max(np.abs(np.diff(mj["L"], axis=0)[:, dyn]).max(),
                  max(np.nanmax(np.abs(traj.impulse(k)[1][:, dyn])) for k in FORCE_KINDS))
        np.testing.assert_allclose(dl[:, dyn] - integ_a[1:, dyn], 0.0, rtol=0,
                                   atol=BALANCE_REL * big)
    boxes = [i for i, n in enumerate(tm.body_name) if n.startswith("box")]
    for i in boxes:  # stacker's boxes: slide x, slide z, hinge y, centre of mass on the slides
        assert np.abs(res[:, i]).max() <= BALANCE_REL * scale[i], tm.body_name[i]
        assert np.abs(np.diff(mj["L"], axis=0)[:, i] - ang[1:, i]).max() <= BALANCE_REL * (
            np.abs(np.diff(mj["L"], axis=0)[:, i]).max() + 1e-300)
    # a tree hanging from a free body: its joint impulses cancel (MuJoCo's cfrc_int)
    for i in np.flatnonzero(tm.body_kind == BODY_FREE):
        tree = [i] + [k for k in range(tm.n_bodies) if _root(tm, k) == i and k != i]
        if len(tree) > 1:
            jl, ja = traj.impulse("joint")
            # the angular sum is about the world origin: each body's own plus x x p
            tot = jl[1:, tree].sum(axis=1)
            big = np.abs(jl[1:, tree]).max()
            assert np.abs(tot).max() <= BALANCE_REL * big, "joint impulses of the tree do not cancel"
            moment = (ja[1:, tree] + np.cross(traj.position[:-1, tree], jl[1:, tree])).sum(axis=1)
            if every == 1:  # one step: the lever arms are the step's start, the logged sample
                assert np.abs(moment).max() <= BALANCE_REL * np.abs(ja[1:, tree]).max()


def _root(tm, k):
    while tm.body_parent[k] >= 0:
        k = int(tm.body_parent[k])
    return k


@pytest.mark.parametrize("every", [1, 7])
def test_intervals_across_blocks(every):
    """600 steps (over two blocks of BLOCK_STEPS rows), a sample every 7th: each interval sums
    its own steps, none twice: stacker's boxes still balance to round-off."""
    m, traj, qpos, qvel = record("stacker", every=every, steps=600)
    assert 600 > 2 * adapter.BLOCK_STEPS
    mj = mujoco_state(m, qpos[traj.step], qvel[traj.step])
    lin = impulse_sum(traj)[0]
    dp = np.diff(mj["p"], axis=0)
    res = dp - lin[1:] - traj.model.body_mass[None, :, None] * traj.model.gravity * np.diff(traj.t)[:, None, None]
    for i, name in enumerate(traj.model.body_name):
        if name.startswith("box"):
            assert np.abs(res[:, i]).max() <= BALANCE_REL * np.abs(dp[:, i]).max(), name


def test_contact_channel_is_the_sum_of_the_contact_rows():
    """Two paths through MuJoCo: the rows decode efc_force per contact (mj_contactForce's
    convention), the channel is cfrc_ext minus xfrc_applied (mj_rnePostConstraint)."""
    m, traj, _, _ = record("stacker", every=1, steps=400)
    c = traj.contacts
    assert len(c.step) > 100
    imp = c.normal_impulse[:, None] * c.normal + c.friction_impulse
    rows = np.zeros_like(traj.position)
    idx = np.searchsorted(traj.step, c.step)
    np.add.at(rows, (idx[c.body_a >= 0], c.body_a[c.body_a >= 0]), imp[c.body_a >= 0])
    np.add.at(rows, (idx[c.body_b >= 0], c.body_b[c.body_b >= 0]), -imp[c.body_b >= 0])
    chan = traj.impulse("contact")[0]
    dyn = traj.model.body_kind == BODY_JOINTED
    # measured: 3.5e-18 N s over 1136 rows of up to 1.4e-2 N s (stacker's condim is 3: no
    # torsional friction the rows would drop)
    np.testing.assert_allclose(rows[:, dyn], chan[:, dyn], rtol=0, atol=1e-12)


def test_joint_bodies_err_at_second_order():
    """A body on joints balances within its step's integration error: the residual of one
    step is O(h^2) (the generalized velocities integrate linearly, v_com = J(q) v does not).
    The walker, in the air without gravity and contacts, under the same smooth controls for
    0.1 s at dt and dt / 2: the per-step residual drops by 4."""
    worst = []
    for dt in (2e-3, 1e-3):
        m = adapter.suite_model("walker")
        m.opt.timestep = dt
        m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT) | int(mujoco.mjtDisableBit.mjDSBL_GRAVITY)
        d = mujoco.MjData(m)
        d.qvel[:] = np.linspace(-2.0, 2.0, m.nv)
        mujoco.mj_forward(m, d)
        n = int(round(0.1 / dt))
        qpos, qvel = [d.qpos.copy()], [d.qvel.copy()]
        rec = adapter.recorder(m, d)
        for k in range(n):
            d.ctrl[:] = np.sin(np.arange(m.nu) + 40.0 * k * dt)
            mujoco.mj_step(m, d)
            rec(d)
            qpos.append(d.qpos.copy())
            qvel.append(d.qvel.copy())
        rec.close()
        traj = rec.trajectory
        mj = mujoco_state(m, np.array(qpos), np.array(qvel))
        res = np.diff(mj["p"], axis=0) - impulse_sum(traj)[0][1:]
        worst.append(np.abs(res).max())
    # measured: 1.41e-2, 3.54e-3 N s: ratio 3.98
    assert 3.5 < worst[0] / worst[1] < 4.5, worst


PENDULUM_XML = """
<mujoco>
  <option timestep="0.002" integrator="Euler"/>
  <worldbody>
    <body name="rod" pos="0 0 1">
      <joint name="pin" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.03" mass="1" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.mark.parametrize("every", [1, 10])
def test_integration_kind_of_a_pendulum_is_its_closed_form(every):
    """A rod on a hinge (axis y through the world point p, centre of mass at r(theta) from it):
    v_com = w y x r with w = qvel, and the forces at a step's start give m h a_com = m h (wdot
    y x r0 - w0^2 r0), wdot = (w1 - w0) / h. So MuJoCo's step (theta1 = theta0 + h w1) moves the
    momentum by that plus K = m [w1 y x (r1 - r0) + h w0^2 r0] (O(h^2)); y is a principal axis
    of the rod, L = I_yy w y, and the angular K is 0. The integration kind logged is K, summed
    over each interval, from qpos/qvel alone."""
    m = mujoco.MjModel.from_xml_string(PENDULUM_XML)
    d = mujoco.MjData(m)
    d.qpos[0] = 0.3
    d.qvel[0] = 4.0
    mujoco.mj_forward(m, d)
    _, traj, qpos, qvel = record(None, every=every, ctrl="zero", steps=400, model=m)
    h, mass = m.opt.timestep, m.body_mass[1]
    th, w = qpos[:, 0], qvel[:, 0]
    # the rod's axis is body x, turned about y by theta: r = 0.25 (cos th, 0, -sin th)
    r = 0.25 * np.stack([np.cos(th), np.zeros_like(th), -np.sin(th)], axis=1)
    y = np.array([0.0, 1.0, 0.0])
    K = mass * (w[1:, None] * np.cross(y, r[1:] - r[:-1]) + h * (w[:-1] ** 2)[:, None] * r[:-1])
    K_int = np.add.reduceat(K, traj.step[:-1], axis=0) if every > 1 else K
    lin, ang = traj.impulse("integration")
    # to the round-off of a momentum difference: relative to the momentum m |v_com| (measured
    # 1.0e-15 N s at m |v_com| = 1.9 kg m/s); K itself reaches 2.7e-4 N s a step, 2.7e-3 over
    # ten (its two terms cancel to first order: K ~ m h (w0^2 - w1^2) r0)
    p_scale = mass * 0.25 * np.abs(w).max()
    np.testing.assert_allclose(lin[1:, 0], K_int, rtol=0, atol=1e-12 * p_scale)
    assert np.abs(K_int).max() > 1e-4  # a term the balance cannot do without
    np.testing.assert_allclose(ang[1:, 0], 0.0, rtol=0, atol=1e-12 * p_scale * 0.25)


LIMITED_XML = """
<mujoco>
  <option timestep="0.005"/>
  <worldbody>
    <body name="upper" pos="0 0 1">
      <joint name="shoulder" type="hinge" axis="0 1 0" range="-40 40" damping="0.5"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.03" mass="1" contype="0" conaffinity="0"/>
      <body name="lower" pos="0.4 0 0">
        <joint name="elbow" type="hinge" axis="0 1 0" range="-30 30" frictionloss="0.05"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.025" mass="0.5" contype="0" conaffinity="0"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor joint="shoulder" gear="5"/><motor joint="elbow" gear="3"/></actuator>
</mujoco>
"""


def test_work_of_every_kind_closes_mujocos_energy():
    """A two-link arm driven by random motor torques into its joint limits, with damping and
    friction loss, touching nothing: MuJoCo's own energy (mj_energyPos + mj_energyVel at each
    state) changes by the logged work of every kind, the joint work (limits, friction loss:
    qfrc_constraint, no contacts) included. Euler's states change their kinetic energy by
    (v0 + v1)/2 . M (v1 - v0) = h f . (v0 + v1)/2: the work is taken at the mean velocity."""
    m = mujoco.MjModel.from_xml_string(LIMITED_XML)
    _, traj, qpos, qvel = record(None, every=1, ctrl="random", steps=1000, model=m)
    d = mujoco.MjData(m)
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    energy, ke = [], []
    for q, v in zip(qpos, qvel):
        d.qpos[:], d.qvel[:] = q, v
        mujoco.mj_forward(m, d)
        energy.append(d.energy.sum())
        ke.append(d.energy[1])
    energy = np.array(energy)
    cum = lambda kinds: np.concatenate([[0.0], np.cumsum(sum(
        np.nan_to_num(traj.work(k)).sum(axis=1) for k in kinds)[1:])])
    every = energy - energy[0] - cum(("applied", "passive", "actuator", "joint"))
    without = energy - energy[0] - cum(("applied", "passive", "actuator"))
    joint = np.nansum(traj.work("joint"))
    # measured: with the joint work 0.021 of the largest kinetic energy (1.97 J; the rest is
    # Euler's own error: M(q) and the potential change across a step); without it 2.58 (the
    # limits and friction loss take -5.09 J)
    assert np.abs(every).max() < 0.05 * max(ke), (np.abs(every).max(), max(ke))
    assert np.abs(without).max() > 1.0 * max(ke)
    assert joint < 0


def test_passive_is_the_damping_mujoco_integrates():
    """walker's leaf bodies (the feet) hang on one damped hinge without spring: their passive
    impulse is the implicit damping couple -B v1 h along the hinge's axis at the step's start,
    and its work -B v1 (v0 + v1)/2 h, at the step's mean velocity (v0, v1: MuJoCo's qvel before
    and after the step, xaxis from mj_forward)."""
    m, traj, qpos, qvel = record("walker", every=1)
    tm = traj.model
    d = mujoco.MjData(m)
    h = m.opt.timestep
    for name in ("right_foot", "left_foot"):
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
        j = int(m.body_jntadr[b])
        assert m.body_jntnum[b] == 1 and m.jnt_stiffness[j] == 0 and m.dof_damping[j] > 0
        dof = int(m.jnt_dofadr[j])
        expect = np.zeros((STEPS, 3))
        for k in range(STEPS):
            d.qpos[:], d.qvel[:] = qpos[k], qvel[k]
            mujoco.mj_kinematics(m, d)
            expect[k] = -m.dof_damping[dof] * qvel[k + 1, dof] * h * d.xaxis[j]
        got = traj.impulse("passive")[1][1:, b - 1]
        # measured: 4e-19 N m s
        np.testing.assert_allclose(got, expect, rtol=0, atol=1e-15)
        work = -m.dof_damping[dof] * qvel[1:, dof] * 0.5 * (qvel[:-1, dof] + qvel[1:, dof]) * h
        np.testing.assert_allclose(traj.work_passive[1:, b - 1], work, rtol=1e-12, atol=1e-18)
        np.testing.assert_array_equal(traj.impulse("passive")[0][1:, b - 1], 0.0)  # a couple


def test_rk4_cartpole():
    """cartpole ships with RK4: the cart (a slide, centre of mass on it) balances to round-off
    with the joint impulse closing RK4's mean acceleration; the others are the first stage's."""
    m, traj, qpos, qvel = record("cartpole", every=1)
    assert traj.info.engine_settings["integrator"] == "RK4"
    mj = mujoco_state(m, qpos, qvel)
    lin = impulse_sum(traj)[0]
    dp = np.diff(mj["p"], axis=0)
    res = dp - lin[1:] - traj.model.body_mass[None, :, None] * traj.model.gravity * m.opt.timestep
    assert np.abs(res[:, 0]).max() <= BALANCE_REL * np.abs(dp[:, 0]).max()
    # the work: MuJoCo's own energy (mj_energyPos + mj_energyVel at each state) changes by the
    # logged work of every kind. RK4 displaces the joints by h sum_i b_i v_i, not h v1: the
    # work is taken at the step's displacement (q1 - q0) / h. Measured over the 200 steps:
    # 8.4e-7 J (the motor's force is constant over a step; the damping's varies by stage)
    # against a largest kinetic energy of 1.02 J; at v1, as the semi-implicit integrators
    # displace, it would be 0.32 J
    d = mujoco.MjData(m)
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    energy = []
    for q, v in zip(qpos, qvel):
        d.qpos[:], d.qvel[:] = q, v
        mujoco.mj_forward(m, d)
        energy.append(d.energy.sum())
    energy = np.array(energy)
    work = sum(np.nan_to_num(traj.work(k)).sum(axis=1) for k in ("applied", "passive", "actuator"))
    bal = energy - energy[0] - np.concatenate([[0.0], np.cumsum(work[1:])])
    assert np.abs(bal).max() < 1e-5


def test_skipped_steps_are_unknown_not_wrong():
    """rec(d) every 10th step only: the intervals it did not see have NaN impulses (the
    analyzers leave them unjudged), the states are logged."""
    m = adapter.suite_model("stacker")
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    rec = adapter.recorder(m, d)
    states = {}
    for k in range(1, 51):
        mujoco.mj_step(m, d)
        if k % 10 == 0:
            rec(d)
        if k in (9, 10, 11):
            states[k] = (d.qpos.copy(), d.qvel.copy())
    rec.close()
    traj = rec.trajectory
    assert traj.step.tolist() == [0, 10, 20, 30, 40, 50]
    lin = traj.impulse("contact")[0]
    dyn = traj.model.body_kind == BODY_JOINTED
    assert np.isnan(lin[1:, dyn]).all() and not np.isnan(lin[0, dyn]).any()
    # the states are MuJoCo's at those steps, not the next seen step's start
    mj = mujoco_state(m, [states[10][0]], [states[10][1]])
    np.testing.assert_allclose(traj.position[1], mj["x"][0], rtol=0, atol=POSE_TOL)
    np.testing.assert_allclose(traj.linear_momentum[1], mj["p"][0], rtol=0, atol=1e-12)


def test_sample_before_a_gap_keeps_its_own_state():
    """Steps 1-5 seen (a sample at 5), 6 and 7 not, then 8, 9, 10: sample 5's state is MuJoCo's
    at step 5 (not the start of step 9, the next row gathered), and interval (5, 10] is NaN."""
    m = adapter.suite_model("stacker")
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    rec = adapter.recorder(m, d, every=5)
    rng = np.random.default_rng(3)
    seen = {}
    for k in range(1, 11):
        d.ctrl[:] = rng.uniform(-1.0, 1.0, m.nu)
        mujoco.mj_step(m, d)
        seen[k] = (d.qpos.copy(), d.qvel.copy())
        if k not in (6, 7):
            rec(d)
    rec.close()
    traj = rec.trajectory
    assert traj.step.tolist() == [0, 5, 10]
    mj = mujoco_state(m, [seen[5][0], seen[10][0]], [seen[5][1], seen[10][1]])
    np.testing.assert_allclose(traj.position[1:], mj["x"], rtol=0, atol=POSE_TOL)
    np.testing.assert_allclose(traj.linear_momentum[1:], mj["p"], rtol=0, atol=1e-12)
    lin = traj.impulse("joint")[0][:, traj.model.body_kind == BODY_JOINTED]
    assert not np.isnan(lin[1]).any() and np.isnan(lin[2]).all()


def test_what_cannot_be_recorded_is_one_line():
    from dm_control.suite import common, quadruped

    m = mujoco.MjModel.from_xml_string(quadruped.make_model(terrain=True), common.ASSETS)
    with pytest.raises(AdapterError) as err:
        adapter.recorder(m)
    assert "'terrain' (hfield)" in str(err.value) and "\n" not in str(err.value)
    flex = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><flexcomp name="cloth" type="grid" count="3 3 1" spacing="0.1 0.1 0.1" '
        'dim="2"><edge equality="true"/></flexcomp><flexcomp name="sheet" type="grid" count="2 2 1" '
        'spacing="0.1 0.1 0.1" dim="2" pos="0 0 1"/></worldbody></mujoco>')
    with pytest.raises(AdapterError) as err:
        adapter.recorder(flex)
    assert "flex 'cloth'" in str(err.value) and "flex 'sheet'" in str(err.value)


def _rotation_of(rotvec):
    """(T, 3, 3) exp([rotvec]x) (Rodrigues)."""
    th = np.linalg.norm(rotvec, axis=1)[:, None, None]
    k = np.zeros((len(rotvec), 3, 3))
    x, y, z = (rotvec / np.maximum(np.linalg.norm(rotvec, axis=1), 1e-300)[:, None]).T
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -z, y, -x
    k[:, 1, 0], k[:, 2, 0], k[:, 2, 1] = z, -y, x
    return np.eye(3) + np.sin(th) * k + (1 - np.cos(th)) * k @ k


def test_free_body_angular_momentum_on_contact():
    """A spinning box dropped on MuJoCo's floor (Euler; its centre of mass at its free joint's
    origin, inertia diagonal in its frame). MuJoCo integrates I (w1 - w0) = h (tau - w0 x I w0)
    in the body frame and R1 = R0 exp(h w1), so L1 - L0 - h R0 tau = R0 [exp(h w1) I w1 - I w1 -
    h w0 x I w0]: the engine's own drift, the same formula as in free flight, from qpos/qvel
    alone. The logged angular impulses (contact torques about the centre of mass) close the
    balance up to it, to round-off; and the drift is the free-flight one: it vanishes as the
    spin does."""
    xml = ('<mujoco><option timestep="0.002" integrator="Euler"/><worldbody>'
           '<geom type="plane" size="5 5 0.1"/><body name="box" pos="0 0 0.3" euler="20 30 0">'
           '<freejoint/><geom type="box" size="0.2 0.1 0.05" mass="1"/></body></worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qvel[:] = [0.3, 0, 0, 1.0, 4.0, 2.0]
    rec = adapter.recorder(m, d)
    qpos, qvel = [d.qpos.copy()], [d.qvel.copy()]
    for _ in range(500):
        mujoco.mj_step(m, d)
        rec(d)
        qpos.append(d.qpos.copy())
        qvel.append(d.qvel.copy())
    rec.close()
    traj = rec.trajectory
    qpos, qvel = np.array(qpos), np.array(qvel)
    assert np.allclose(m.body_iquat[1], [1, 0, 0, 0]) and np.allclose(m.body_ipos[1], 0)
    inertia = np.asarray(m.body_inertia[1])
    r = quat_wxyz_to_matrix(qpos[:, 3:7] / np.linalg.norm(qpos[:, 3:7], axis=1)[:, None])
    wb = qvel[:, 3:6]
    big_l = np.einsum("tij,tj->ti", r, inertia * wb)          # MuJoCo's own L, world
    h = m.opt.timestep
    drift = np.einsum("tij,tj->ti", r[:-1], np.einsum("tij,tj->ti", _rotation_of(h * wb[1:]), inertia * wb[1:])
                      - inertia * wb[1:] - h * np.cross(wb[:-1], inertia * wb[:-1]))
    ang = impulse_sum(traj)[1][1:, 0]
    dl = np.diff(big_l, axis=0)
    c = traj.contacts
    assert len(np.unique(c.step)) > 100  # the box rests on its face for most of the run
    # measured: 4.8e-17 N m s against |dL| up to 2.1e-2 and a drift up to 3.2e-4 (420 steps in
    # contact)
    assert np.abs(dl - ang - drift).max() <= BALANCE_REL * np.abs(dl).max()
    assert np.abs(drift).max() > 1e3 * np.abs(dl - ang - drift).max()  # the drift is real


def test_mesh_and_mocap_bodies():
    """A convex mesh (a tetrahedron, MuJoCo collides with its hull) on a free body, pushed by a
    mocap paddle the user moves: the mesh's vertices in the log, placed by the body's pose, are
    MuJoCo's own vertices in the world; the paddle is a kinematic body whose pose follows
    mocap_pos and whose impulses are marked missing (not judged)."""
    xml = ('<mujoco><option timestep="0.002"/><asset><mesh name="tet" vertex="0 0 0  0.2 0 0  0 0.15 0  0 0 0.1"/>'
           '</asset><worldbody><geom type="plane" size="2 2 0.1"/>'
           '<body name="tet" pos="0 0 0.2" euler="10 20 30"><freejoint/><geom type="mesh" mesh="tet" mass="1"/></body>'
           '<body name="paddle" mocap="true" pos="-0.3 0 0.05"><geom type="box" size="0.02 0.2 0.05"/></body>'
           '</worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    rec = adapter.recorder(m, d, every=5)
    qpos, mocap = [d.qpos.copy()], [d.mocap_pos.copy()]
    for k in range(300):
        d.mocap_pos[0, 0] = -0.3 + 0.001 * k
        mujoco.mj_step(m, d)
        rec(d)
        qpos.append(d.qpos.copy())
        mocap.append(d.mocap_pos.copy())
    rec.close()
    traj, tm = rec.trajectory, rec.trajectory.model
    assert tm.body_name == ["tet", "paddle"] and tm.body_kind.tolist() == [BODY_FREE, 2]
    # body 0, free and carrying no other body: every kind logged but the joint kind, none (a
    # free joint exerts nothing), and the integration kind, none (a free body's); body 1, the
    # mocap paddle (kinematic): every kind missing
    assert tm.body_impulse_supplied.tolist() == [[1, 1, 1, 1, 2, 2], [0] * 6]
    g = int(np.flatnonzero(tm.geom_type == GEOM_MESH)[0])
    mesh = int(m.geom_dataid[1])
    local = tm.geom_vertices(g)
    a, n = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
    np.testing.assert_array_equal(local, m.mesh_vert[a:a + n])
    dd = mujoco.MjData(m)
    q = tm.geom_quat_wxyz_body[g]
    rg = quat_wxyz_to_matrix(q / np.linalg.norm(q))
    for i, s in enumerate(traj.step):
        dd.qpos[:], dd.mocap_pos[:] = qpos[s], mocap[s]
        mujoco.mj_kinematics(m, dd)
        world_mj = dd.geom_xpos[1] + local @ dd.geom_xmat[1].reshape(3, 3).T      # MuJoCo's
        r = traj.rotation[i, 0]
        world_log = traj.position[i, 0] + (tm.geom_pos_body[g] + local @ rg.T) @ r.T  # the log's
        np.testing.assert_allclose(world_log, world_mj, rtol=0, atol=POSE_TOL)
        np.testing.assert_allclose(traj.position[i, 1], dd.xipos[2], rtol=0, atol=POSE_TOL)
    assert np.isnan(traj.impulse("contact")[0][:, 1]).all()
    assert len(traj.contacts.step) > 0 and 1 in set(traj.contacts.body_a.tolist()) | set(traj.contacts.body_b.tolist())


@pytest.mark.parametrize("integrator", [None, "implicitfast"])
def test_compiled_hook_equals_numpy(integrator):
    """The per-step hook in C++ (rblog.adapters._hook, when built) logs the same bits as the
    numpy one."""
    pytest.importorskip("rblog.adapters._hook")
    logs = []
    for compiled in (True, False):
        m = adapter.suite_model("humanoid")
        if integrator:
            m.opt.integrator = getattr(mujoco.mjtIntegrator, "mjINT_" + integrator.upper())
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        rec = adapter.recorder(m, d)
        assert rec.hook.compiled is not None
        if not compiled:
            rec.hook.compiled = None
        rng = np.random.default_rng(1)
        for _ in range(300):
            d.ctrl[:] = rng.uniform(-1.0, 1.0, m.nu)
            mujoco.mj_step(m, d)
            rec(d)
        rec.close()
        logs.append(rec.trajectory)
    a, b = logs
    for kind in IMPULSE_KINDS:
        for x, y in zip(a.impulse(kind), b.impulse(kind)):
            np.testing.assert_array_equal(x, y, err_msg=kind)
    np.testing.assert_array_equal(a.position, b.position)
    np.testing.assert_array_equal(a.work_passive, b.work_passive)


@pytest.mark.parametrize("name", ["humanoid", "cartpole"])  # cartpole: RK4 (work at (q1 - q0)/h)
def test_compiled_resolve_equals_numpy(name):
    """The block's impulses and work resolved in C++ (rblog.adapters._hook.resolve) are the bits
    of the numpy resolve, every kind (integration 0, joint work), with xfrc_applied pushing."""
    pytest.importorskip("rblog.adapters._hook")
    m = adapter.suite_model(name)
    d = mujoco.MjData(m)
    rec = adapter.recorder(m, d, every=10 ** 6)  # one sample: the rows stay in the hook
    rng = np.random.default_rng(2)
    for i in range(20):
        d.ctrl[:] = rng.uniform(-1.0, 1.0, m.nu)
        d.xfrc_applied[1:] = rng.normal(size=(m.nbody - 1, 6)) if i >= 10 else 0.0
        mujoco.mj_step(m, d)
        rec(d)
    (W, work), (W_np, work_np) = rec.hook.resolve(), rec.hook.resolve_numpy()
    assert rec.hook.k == 20
    assert W.shape[1] == len(IMPULSE_KINDS) and work.shape[1] == len(WORK_KINDS)
    np.testing.assert_array_equal(W, W_np)
    np.testing.assert_array_equal(work, work_np)
    rec.close()
