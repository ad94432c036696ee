"""rblog.adapters.ode on ODE worlds written by hand the way ODE's demos build them (a hash space, a
plane, boxes with dMassSetBoxTotal, a near callback that fills dContact surfaces and attaches
``dJointCreateContact`` joints to ``dGeomGetBody(g1), dGeomGetBody(g2)``, a contact group emptied
after each step). Recorded in two lines; the log is what ODE's own accessors report, the contact
impulses are each body's momentum change (ODE's step applies exactly the forces dJointFeedback
reports), ``rblog check`` passes it, and a box's pose sunk 5 mm into the ground is caught."""

from __future__ import annotations

import ctypes
import json
import types

import numpy as np
import pytest
from click.testing import CliRunner

import rblog

ode = pytest.importorskip("odepy", reason="ODE: apt-get install libode8; pip install ode-python")
from rblog.adapters import AdapterError  # noqa: E402
from rblog.adapters.ode import OdeRecorder  # noqa: E402
from rblog.contract.model import BODY_JOINTED, JOINT_HINGE, SHAPE_BOX, SHAPE_SPHERE, SUPPLIED_LOGGED, \
    SUPPLIED_MISSING, SUPPLIED_NONE  # noqa: E402
from rblog.contract.trajectory import INTERVAL_CHANNELS  # noqa: E402
from rblog.record.recorder import Recorder  # noqa: E402
from tests.study.test_ode_engine import dcollide_depths, momentum_residuals  # noqa: E402

DT = 1e-3
MU, BOUNCE = 0.5, 0.3
EPS = np.finfo(float).eps


class Demo:
    """An ODE world as ODE's demos write one (demo_boxstack, without drawstuff)."""

    MAX_CONTACTS = 8

    def __init__(self):
        ode.dInitODE2(0)
        ode.dRandSetSeed(0)
        self.world = ode.dWorldCreate()
        self.space = ode.dHashSpaceCreate(None)
        self.contactgroup = ode.dJointGroupCreate(0)
        ode.dWorldSetGravity(self.world, 0, 0, -9.81)
        self.ground = ode.dCreatePlane(self.space, 0, 0, 1, 0)
        self.bodies, self.geoms = [], []
        self.near = ode.dNearCallback(self._near)

    def box(self, mass, lengths, pos, quat=(1.0, 0.0, 0.0, 0.0), vel=(0, 0, 0), avel=(0, 0, 0)):
        b = ode.dBodyCreate(self.world)
        m = ode.dMass()
        ode.dMassSetBoxTotal(ctypes.byref(m), mass, *lengths)
        ode.dBodySetMass(b, ctypes.byref(m))
        g = ode.dCreateBox(self.space, *lengths)
        ode.dGeomSetBody(g, b)
        ode.dBodySetPosition(b, *pos)
        ode.dBodySetQuaternion(b, (ode.dQuaternion)(*quat))
        ode.dBodySetLinearVel(b, *vel)
        ode.dBodySetAngularVel(b, *avel)
        self.bodies.append(b)
        self.geoms.append(g)
        return b

    def sphere(self, mass, radius, pos):
        b = ode.dBodyCreate(self.world)
        m = ode.dMass()
        ode.dMassSetSphereTotal(ctypes.byref(m), mass, radius)
        ode.dBodySetMass(b, ctypes.byref(m))
        g = ode.dCreateSphere(self.space, radius)
        ode.dGeomSetBody(g, b)
        ode.dBodySetPosition(b, *pos)
        self.bodies.append(b)
        return b

    def _near(self, data, o1, o2):
        b1, b2 = ode.dGeomGetBody(o1), ode.dGeomGetBody(o2)
        if b1 and b2 and ode.dAreConnectedExcluding(b1, b2, ode.dJointTypeContact):
            return  # bodies on a joint do not collide (ODE's demos)
        contact = (ode.dContact * self.MAX_CONTACTS)()
        for c in contact:
            c.surface.mode = ode.dContactBounce | ode.dContactApprox1
            c.surface.mu = MU
            c.surface.bounce = BOUNCE
            c.surface.bounce_vel = 0.1
        n = ode.dCollide(o1, o2, self.MAX_CONTACTS, ctypes.byref(contact[0].geom),
                         ctypes.sizeof(ode.dContact))
        for i in range(n):
            c = ode.dJointCreateContact(self.world, self.contactgroup, ctypes.byref(contact[i]))
            ode.dJointAttach(c, b1, b2)

    def step(self):
        ode.dSpaceCollide(self.space, None, self.near)
        ode.dWorldStep(self.world, DT)
        ode.dJointGroupEmpty(self.contactgroup)

    def close(self):
        ode.dJointGroupDestroy(self.contactgroup)
        ode.dSpaceDestroy(self.space)
        ode.dWorldDestroy(self.world)


@pytest.fixture
def boxes():
    w = Demo()
    rng = np.random.default_rng(7)
    for k in range(3):  # three boxes dropped from 0.3-0.7 m, tilted, one spinning
        ax = rng.normal(size=3)
        ax /= np.linalg.norm(ax)
        ang = 0.4 * k
        q = (np.cos(ang / 2), *(np.sin(ang / 2) * ax))
        w.box(1.0 + k, (0.2, 0.3, 0.1), (0.6 * k, 0.0, 0.3 + 0.2 * k), q, vel=(0.2, 0, 0),
              avel=(0, 0, 3.0 * (k == 2)))
    yield w
    w.close()


def record(w, n, tmp_path, **kw):
    """The user's two lines around the demo's loop; returns (trajectory, ODE's states)."""
    mcap = tmp_path / "ode.mcap"
    kw.setdefault("applied_forces", False)  # the demo's loop adds no force or torque
    rec = OdeRecorder(w.world, w.space, dt=DT, mcap=str(mcap), keep=True,     # line 1
                      friction=MU, restitution=BOUNCE, **kw)
    states = []
    for _ in range(n):
        ode.dSpaceCollide(w.space, None, w.near)
        ode.dWorldStep(w.world, DT)
        rec()                                                                  # line 2
        ode.dJointGroupEmpty(w.contactgroup)
        states.append([(ode.dBodyGetPosition(b)[:3], ode.dBodyGetQuaternion(b)[:4],
                        ode.dBodyGetAngularVel(b)[:3]) for b in w.bodies])
    rec.close()
    return rec.trajectory, states, mcap


def test_boxes_on_a_plane_in_two_lines(boxes, tmp_path):
    traj, states, mcap = record(boxes, 1500, tmp_path)
    m = traj.model
    assert m.n_bodies == 3 and list(m.body_shape) == [SHAPE_BOX] * 3
    np.testing.assert_allclose(m.body_size, [[0.1, 0.15, 0.05]] * 3)
    np.testing.assert_allclose(m.body_mass, [1, 2, 3])
    # dMassSetBoxTotal: I_xx = M (ly^2 + lz^2) / 12 about the box's axes (the body frame)
    np.testing.assert_allclose(m.body_inertia_diag[0], [(0.09 + 0.01) / 12, (0.04 + 0.01) / 12,
                                                        (0.04 + 0.09) / 12], rtol=1e-12)
    assert m.ground and np.allclose(m.ground_normal, [0, 0, 1]) and m.ground_offset == 0.0
    np.testing.assert_allclose(m.gravity, [0, 0, -9.81])
    # the log is ODE's state (the body frame is the contract frame: a centred box)
    pos, quat, avel = (np.array([[s[i][k] for i in range(3)] for s in states]) for k in range(3))
    np.testing.assert_array_equal(traj.position[1:], pos)
    np.testing.assert_array_equal(traj.quat_wxyz[1:], quat)
    # (the recorder logs w through L = R I R^T w: round-off, measured 1.1e-14 rad/s at 3 rad/s)
    np.testing.assert_allclose(traj.angular_velocity[1:], avel, rtol=0, atol=1e-13)
    assert len(traj.contacts.step) > 0 and np.all(traj.contacts.body_b == -1)
    np.testing.assert_allclose(traj.contacts.normal, np.tile([0, 0, 1.0], (len(traj.contacts.step), 1)))
    lin, ang = momentum_residuals(traj)
    # relative to the step's impulses and momenta: measured 505 ulp linear (1e-15 N s on a resting
    # box's 0.03 N s: ODE sums m g + J^T lambda in its own order) and 2 ulp angular
    assert lin < 2000 * EPS and ang < 40 * EPS, (lin, ang)
    results = {r.analyzer: r for r in rblog.check(rblog.load(mcap))}
    flagged = [r for r in results.values() if not r.passed]
    # two real faults of ODE, both in `momentum`, each confirmed from the logged state itself:
    assert [r.analyzer for r in flagged] == ["momentum"], [r.reason for r in flagged]
    mom = results["momentum"]
    flight = [f for f in mom.findings if "angular momentum not conserved in free flight" in f.message]
    cone = [f for f in mom.findings if "friction cone" in f.message]
    assert len(flight) + len(cone) == len(mom.findings) and flight and cone
    # (1) ODE's implicit gyroscopic torque does not conserve a spinning box's angular momentum in
    # free flight: L = R I R^T w over box 2's first flight (before its first contact row)
    assert (2,) in {tuple(f.bodies) for f in flight}
    first = traj.contacts.step[traj.contacts.body_a == 2].min()
    k = traj.step < first
    lw = np.einsum("tij,j,tkj,tk->ti", traj.rotation[k, 2], m.body_inertia_diag[2],
                   traj.rotation[k, 2], traj.angular_velocity[k, 2])
    drift = np.max(np.linalg.norm(lw - lw[0], axis=1)) / np.linalg.norm(lw[0])
    assert drift > mom.tolerance, drift  # measured 1.7e-3
    # (2) dContactApprox1 bounds each of ODE's two friction directions by mu times the normal
    # force as its LCP solve goes: a pyramid, and the solved rows end up outside Coulomb's cone
    # now and then. From the logged rows: measured 79 of 12638 rows with |J_t| > mu J_n (by up
    # to 2.1 mu J_n)
    c = traj.contacts
    over = np.linalg.norm(c.friction_impulse, axis=1) > MU * c.normal_impulse * (1 + mom.tolerance) + 1e-15
    assert 0 < over.sum() < 0.02 * len(over), over.sum()
    assert {int(b) for f in cone for b in f.bodies} <= {int(b) for b in c.body_a[over]}
    assert not results["penetration"].skipped and results["penetration"].passed
    # the resting depth the check sees is within dCollide's depths at the logged poses
    depth = max(dcollide_depths(traj, i).max() for i in range(3))
    assert results["penetration"].stats["rest_depth_max_m"] <= depth * (1 + 1e-9)
    assert depth < results["penetration"].tolerance  # measured 3.8e-5 m (an impact's)
    res = CliRunner().invoke(rblog_main(), ["check", "--json", str(mcap)])
    assert res.exit_code == 1, res.output  # the free-flight finding above
    assert json.loads(res.stdout)["logs"][0]["results"][0]["passed"]  # consistency


def rblog_main():
    from rblog_cli.main import main

    return main


def test_a_box_sunk_5_mm_is_caught(boxes, tmp_path):
    traj, _, mcap = record(boxes, 1500, tmp_path)
    # the planted fault: box 0's pose 5 mm lower from 1.0 s on (resting by then), the rest as ODE
    # logged it (the contact rows too: their separations stay ODE's)
    pos = traj.position.copy()
    late = traj.t >= 1.0
    pos[late, 0, 2] -= 0.005
    bad = tmp_path / "sunk.mcap"
    with Recorder(traj.model, mcap=str(bad), dt=traj.info.dt, writer=traj.info.writer,
                  integrator=traj.info.integrator, combine_friction=traj.info.combine_friction,
                  combine_restitution=traj.info.combine_restitution,
                  engine_settings=traj.info.engine_settings) as rec:
        rec.write(t=traj.t, step=traj.step, position=pos, quat_wxyz=traj.quat_wxyz,
                  velocity=traj.velocity, angular_velocity=traj.angular_velocity,
                  contacts={k: getattr(traj.contacts, k) for k in
                            ("step", "body_a", "body_b", "point", "normal", "separation",
                             "normal_impulse", "friction_impulse")},
                  **{k: getattr(traj, k) for k in INTERVAL_CHANNELS if getattr(traj, k) is not None})
    clean = {r.analyzer: r for r in rblog.check(rblog.load(mcap))}
    sunk = {r.analyzer: r for r in rblog.check(rblog.load(bad))}
    assert clean["penetration"].passed
    pen = sunk["penetration"]
    assert not pen.passed
    assert any(0 in f.bodies for f in pen.findings), [f.message for f in pen.findings]
    # the deepest the sunk box reaches is its 5 mm below ODE's ~1e-12 m
    assert pen.stats["depth_max_m"] == pytest.approx(0.005, abs=1e-6)
    res = CliRunner().invoke(rblog_main(), ["check", str(bad)])
    assert res.exit_code == 1 and "box" in res.output.lower() or "body 0" in res.output


def test_a_ball_and_materials_as_stated(tmp_path):
    w = Demo()
    try:
        w.sphere(0.5, 0.1, (0, 0, 0.6))
        traj, _, mcap = record(w, 800, tmp_path)
    finally:
        w.close()
    assert list(traj.model.body_shape) == [SHAPE_SPHERE]
    np.testing.assert_allclose(traj.model.body_inertia_diag[0], [0.4 * 0.5 * 0.01] * 3)
    assert traj.model.body_friction[0] == MU and traj.model.ground_restitution == BOUNCE
    vz = traj.velocity[:, 0, 2]
    k = int(np.nonzero((vz[:-1] < 0) & (vz[1:] > 0))[0][0])
    # dContactBounce: rebound -e v_n, then gravity for the rest of the step
    assert -vz[k + 1] / vz[k] == pytest.approx(BOUNCE, abs=2 * 9.81 * DT / abs(vz[k]))
    res = {r.analyzer: r for r in rblog.check(rblog.load(mcap))}
    assert res["momentum"].passed and res["penetration"].passed


def chain(w, n=5, length=0.2, height=2.0):
    """ODE's demo_chain with hinges: n boxes end to end along x, the first hinged to the world at
    x = 0, each to the next at their shared end, axes along y: released level, it swings down."""
    prev, joints = None, []
    for i in range(n):
        b = w.box(0.5, (length, 0.05, 0.05), (length / 2 + i * length, 0.0, height))
        j = ode.dJointCreateHinge(w.world, None)
        ode.dJointAttach(j, prev, b)
        ode.dJointSetHingeAnchor(j, i * length, 0.0, height)
        ode.dJointSetHingeAxis(j, 0.0, 1.0, 0.0)
        joints.append(j)
        prev = b
    return joints


def hinge_gap(j) -> float:
    """|anchor on body 1 - anchor on body 2| of an ODE hinge now (m): ODE's joint error."""
    a1, a2 = (ode.dVector3)(), (ode.dVector3)()
    ode.dJointGetHingeAnchor(j, a1)
    ode.dJointGetHingeAnchor2(j, a2)
    return float(np.linalg.norm(np.array(a1[:3]) - np.array(a2[:3])))


def test_a_chain_on_hinges(tmp_path):
    w = Demo()
    try:
        joints = chain(w)
        mcap = tmp_path / "chain.mcap"
        rec = OdeRecorder(w.world, w.space, dt=DT, mcap=str(mcap), applied_forces=False)  # line 1
        ode_gaps = []
        for _ in range(1000):
            w.step()
            rec()                                                                      # line 2
            ode_gaps.append([hinge_gap(j) for j in joints])
        rec.close()
        ode_gaps = np.array(ode_gaps)  # (steps, 5): ODE's own joint error after each step
        gaps = ode_gaps[-1]
        got = rblog.load(mcap)
    finally:
        w.close()
    m = got.model
    assert list(m.body_kind) == [BODY_JOINTED] * 5 and list(m.body_parent) == [-1, 0, 1, 2, 3]
    assert list(m.joint_type) == [JOINT_HINGE] * 5 and list(m.joint_body) == [0, 1, 2, 3, 4]
    # per body, IMPULSE_KINDS (contact, applied, passive, actuator, joint, integration): contacts and joints
    # logged; no applied load (the loop adds none), no damping, no motors
    assert m.body_impulse_supplied.tolist() == [[SUPPLIED_LOGGED, SUPPLIED_NONE, SUPPLIED_NONE,
                                                 SUPPLIED_NONE, SUPPLIED_LOGGED, SUPPLIED_NONE]] * 5
    # each box's hinge is at its -x end; the parent's at its +x end (the world's at the origin)
    np.testing.assert_allclose(m.joint_anchor_body, [[-0.1, 0, 0]] * 5, atol=1e-15)
    np.testing.assert_allclose(m.joint_anchor_parent, [[0, 0, 2.0]] + [[0.1, 0, 0]] * 4, atol=1e-15)
    np.testing.assert_allclose(m.joint_axis_body, [[0, 1, 0]] * 5, atol=1e-15)
    # each anchor carried with its child and with its parent: their gap is ODE's own joint error
    # (dJointGetHingeAnchor vs ...Anchor2) at the end, and small all along (ERP 0.2 pulls it back
    # each step; measured up to 2.7e-4 m at the joints down the chain)
    x, r = got.position, got.rotation
    for k in range(5):
        c, p = int(m.joint_body[k]), int(m.body_parent[m.joint_body[k]])
        on_child = x[:, c] + np.einsum("tij,j->ti", r[:, c], m.joint_anchor_body[k])
        on_parent = (np.broadcast_to(m.joint_anchor_parent[k], on_child.shape) if p < 0 else
                     x[:, p] + np.einsum("tij,j->ti", r[:, p], m.joint_anchor_parent[k]))
        gap = np.linalg.norm(on_child - on_parent, axis=1)
        assert gap[-1] == pytest.approx(gaps[k], rel=1e-6, abs=1e-14), (k, gap[-1], gaps[k])
        assert gap.max() < 1e-3
    # the chain swings down (the last box 0.79 m at 0.4 s) and back up
    assert got.position[:, 4, 2].min() < 2.0 - 0.5
    # the balance the contract v3 states, per body and step, from the log alone: the hinges'
    # impulses are all that act besides gravity (measured 2.2e-16 N s; ODE applies what its
    # dJointFeedback reports)
    dp = got.linear_momentum[1:] - got.linear_momentum[:-1]
    jl = got.impulse_joint_linear[1:]
    g = m.body_mass[None, :, None] * m.gravity * DT
    assert np.max(np.abs(dp - jl - g)) < 1e-12
    assert np.all(got.impulse_contact_linear == 0)  # connected bodies do not collide
    results = {r.analyzer: r for r in rblog.check(got)}
    assert results["consistency"].passed and results["drift"].passed
    # rblog check's joints analyzer: ODE holds its hinges by ERP 0.2, a fraction of the error per
    # step, so they come apart by up to 0.27 mm, past the one-step arc-chord tolerance (a few
    # um): every joint flagged, each at ODE's own largest anchor gap
    jr = results["joints"]
    assert not jr.passed and {int(f.bodies[0]) for f in jr.findings} == {0, 1, 2, 3, 4}
    for f in jr.findings:
        k = int(f.bodies[0])  # joint k moves body k
        assert f.value == pytest.approx(ode_gaps[:, k].max(), rel=1e-6), (k, f.value)
    # the boxes' ends overlap where they hinge; ODE does not collide jointed bodies, and the
    # audit never pairs a body with its parent (docs/log-format.md, collide_parent): no finding
    pen = results["penetration"]
    assert pen.passed and not pen.findings, [f.message for f in pen.findings]


def test_check_judges_the_chain(tmp_path):
    """momentum reads the chain's logged hinge impulses (each body's balance per interval) and
    penetration leaves the hinged boxes' overlapping ends alone (a body and its parent)."""
    w = Demo()
    try:
        chain(w)
        _, _, mcap = record(w, 1000, tmp_path)
    finally:
        w.close()
    res = {r.analyzer: r for r in rblog.check(rblog.load(mcap))}
    assert res["momentum"].passed and res["penetration"].passed


def test_what_the_recorder_refuses(tmp_path):
    w = Demo()
    try:
        a = w.box(1.0, (0.1, 0.1, 0.1), (0, 0, 1))
        b = w.box(1.0, (0.1, 0.1, 0.1), (0, 0, 1.2))
        j = ode.dJointCreateHinge2(w.world, None)
        ode.dJointAttach(j, a, b)
        with pytest.raises(AdapterError, match="body 0 is on a hinge2 joint"):
            OdeRecorder(w.world, w.space, dt=DT)
        with pytest.raises(AdapterError, match="dt = 0"):
            OdeRecorder(w.world, w.space, dt=0)
    finally:
        w.close()
    w = Demo()
    try:
        w.box(1.0, (0.1, 0.1, 0.1), (0, 0, 1))
        rec = OdeRecorder(w.world, w.space, dt=DT)
        # by default the recorder cannot know the loop's dBodyAddForce: applied is missing
        assert rec.model.body_impulse_supplied[0, 1] == SUPPLIED_MISSING
        with pytest.raises(AdapterError, match="stepped by 0.002 s"):
            ode.dWorldStep(w.world, 0.002)
        rec.close()
        # the wrappers are gone after close: odepy's ctypes functions again
        assert not isinstance(ode.dWorldStep, types.FunctionType)
        assert not isinstance(ode.dJointCreateContact, types.FunctionType)
    finally:
        w.close()
