"""The joints' rotors (MuJoCo's armature): their kinetic energy 0.5 dof_armature qvel^2 is in
MuJoCo's (mj_energyVel uses M, armature included) and in no body's momenta. The log states the
armature per joint (joint_armature) and the energy analyzer recomputes the rotors' energy from
the logged bodies' relative motion (rblog.analyze.energy.rotor_energy); checked here against
MuJoCo's own qvel, and the energy verdicts both ways."""

from __future__ import annotations

import copy

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

import rblog  # noqa: E402
from rblog.adapters import mujoco as adapter  # noqa: E402
from rblog.analyze.energy import rotor_energy  # noqa: E402


def _record(m, steps, ctrl=True):
    """(trajectory, MuJoCo's 0.5 sum(dof_armature qvel^2) at each logged sample)."""
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    rng = np.random.default_rng(7)
    rec = adapter.recorder(m, d, every=1)
    qv = [d.qvel.copy()]
    for _ in range(steps):
        if ctrl and m.nu:
            d.ctrl[:] = rng.uniform(-1.0, 1.0, m.nu)
        mujoco.mj_step(m, d)
        rec(d)
        qv.append(d.qvel.copy())
    rec.close()
    tr = rec.trajectory
    qv = np.array(qv)[np.asarray(tr.step)]
    return tr, 0.5 * (qv ** 2) @ np.asarray(m.dof_armature)


def _energy(traj):
    return next(r for r in rblog.check(traj, threads=1, only=["energy"]) if r.analyzer == "energy")


@pytest.mark.parametrize("name", ["humanoid", "walker"])
def test_rotor_energy_from_the_logged_bodies_equals_mujocos(name):
    """humanoid: hinges (up to three per body: the hips), armature 0.01; walker: a planar
    slide-slide-hinge root and hinges. Random controls, 200 steps."""
    pytest.importorskip("dm_control")
    m = adapter.suite_model(name)
    tr, truth = _record(m, 200)
    arm = tr.model.joint_armature
    assert np.isfinite(arm).all() and arm.max() == pytest.approx(float(m.dof_armature.max()))
    rot, notes = rotor_energy(tr.model, tr)
    assert notes == []
    assert truth.max() > 0.01  # the rotors hold energy to compare (humanoid: ~3 J)
    # measured: humanoid 2.9e-14 J (rel 6.8e-15) over 50 steps, walker 2.2e-16 J
    assert np.abs(rot.sum(axis=1) - truth).max() <= 1e-12 * max(1.0, truth.max())


def test_humanoid_random_controls_energy_passes_with_its_rotors():
    """The truth table's humanoid, random controls, every step: MuJoCo's own balance moves 0.10 J
    over steps 0-5 where the bodies alone dropped 3.52 J (the rotors' 3.33 J); with the rotors
    counted, no finding."""
    pytest.importorskip("dm_control")
    tr, truth = _record(adapter.suite_model("humanoid"), 100)
    res = _energy(tr)
    assert res.verdict == "pass", res.reason
    # the other way: the same log with its armature not stated is what it was: a false alarm,
    # and the result says the rotor energy is not counted
    blind = copy.copy(tr)
    blind.model = copy.copy(tr.model)
    blind.model.joint_armature = np.full(tr.model.n_joints, np.nan)
    res = _energy(blind)
    assert res.verdict == "FAIL" and "armature is not stated" in res.reason


_PENDULUM = """
<mujoco>
  <option timestep="0.001" integrator="RK4"/>
  <default><joint type="hinge" armature="0.5" damping="0"/></default>
  <worldbody>
    <body name="a" pos="0 0 2">
      <joint name="j1" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.04" contype="0" conaffinity="0"/>
      <body name="b" pos="0.5 0 0">
        <joint name="j2" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.04" contype="0" conaffinity="0"/>
        <body name="c" pos="0.5 0 0">
          <joint name="j3" axis="0 0 1"/>
          <joint name="j4" axis="0 1 0"/>
          <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04" contype="0" conaffinity="0"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _pendulum():
    """Three links on hinges, the last on two (z then y: a two-hinge body), released level."""
    return mujoco.MjModel.from_xml_string(_PENDULUM)


def test_planted_energy_gain_in_a_passive_chain_with_rotors():
    """A passive chain (no damping, no contacts, RK4) whose rotors (armature 0.5 kg m^2) hold
    ~8 % of its kinetic energy: clean, the energy analyzer passes; a 1 % energy gain written
    into the log (every body's velocities scaled by sqrt(1.01) from one sample on, so the bodies' and the
    rotors' kinetic energy both grow 1 %) is caught at that sample, on the chain."""
    m = _pendulum()
    tr, truth = _record(m, 1500, ctrl=False)
    ke_bodies = 0.5 * np.einsum("tni,tni->t", tr.linear_momentum, tr.velocity) + 0.5 * np.einsum(
        "tni,tni->t", tr.angular_momentum, tr.angular_velocity)
    k = int(np.argmax(ke_bodies))
    # the rotors matter here: measured 0.084 of the bodies' kinetic energy at its largest,
    # 84 times the drift limit (ENERGY_DRIFT_REL 1e-3)
    assert truth[k] > 0.05 * ke_bodies[k]
    res = _energy(tr)
    assert res.verdict == "pass", res.reason
    # without the rotors the clean chain reads as losing energy: what counting them fixes
    blind = copy.copy(tr)
    blind.model = copy.copy(tr.model)
    blind.model.joint_armature = np.zeros(tr.model.n_joints)
    assert _energy(blind).verdict == "FAIL"
    # planted: a 1 % gain from sample k0 on, where the chain moves fast
    k0 = k
    bad = copy.copy(tr)
    s = np.sqrt(1.01)
    for ch in ("velocity", "linear_momentum", "angular_velocity", "angular_momentum"):
        a = getattr(tr, ch).copy()
        a[k0:] *= s
        setattr(bad, ch, a)
    res = _energy(bad)
    assert res.verdict == "FAIL"
    f = res.findings[0]
    assert "grows" in f.message and set(f.bodies) == {0, 1, 2}
    assert tr.t[k0] <= f.t
    got = float(f.message.split("grows by ")[1].split(" J")[0])
    # the reported rise at the worst sample is the planted 1 % of that sample's kinetic energy
    # (bodies + rotors), to the message's 3 digits
    kw = int(np.searchsorted(tr.t, f.t))
    want = 0.01 * (ke_bodies[kw] + truth[kw])
    assert got == pytest.approx(want, rel=5e-3)
