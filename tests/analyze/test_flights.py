"""Momentum and energy judged per free flight and per event (issue 16), on logs written with the
public writer API (``rblog.Recorder``):

* a lone body's angular momentum over each free flight, once per flight (an explicit-Euler
  rotation step drifts L a little every step: one finding, not one per sample);
* momentum scales floored (bodies at rest in zero gravity have no momentum to compare with);
* the elastic energy a compliant contact holds at an event's first sample is not a gain;
* a contact on a static box's edge has a fan of normals: the cone is judged about the best.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import rblog
from rblog.analyze import check
from rblog.analyze import tolerances as T

DT = 1e-3
EVERY = 10


def results(traj):
    return {r.analyzer: r for r in check(traj)}


def record(model, **arrays):
    rec = rblog.Recorder(model, dt=DT, log_every=EVERY, keep=True, writer="test_flights")
    with rec:
        rec.write(**arrays)
    return rec.trajectory


# ---- lone bodies: one finding per free flight ---------------------------------------------

INERTIA = np.array([0.1, 0.2, 0.3])


def tumbling(method: str, duration=2.0):
    """A box (principal moments 0.1, 0.2, 0.3 kg m^2) in zero gravity, spinning mostly about its
    intermediate axis. ``exact``: about a principal axis only (w constant, L constant exactly).
    ``euler``: Euler's equations stepped by explicit Euler in the body frame, w += dt I^-1
    (I w x w), the orientation by the exact exponential of w dt: L = R I w is not conserved."""
    model = rblog.body_table(name=["box"], shape=["box"], size=[[0.3, 0.2, 0.1]], mass=[1.0],
                             inertia_diag=[INERTIA], gravity=(0, 0, 0))
    w = np.array([0.0, 3.0, 0.0]) if method == "exact" else np.array([0.2, 3.0, 0.1])
    rot = Rotation.identity()
    n = int(round(duration / DT))
    qs, ws = [], []
    for s in range(n + 1):
        if s % EVERY == 0:
            qs.append(np.roll(rot.as_quat(), 1))  # xyzw -> wxyz
            ws.append(rot.apply(w))
        rot = rot * Rotation.from_rotvec(w * DT)
        if method == "euler":
            w = w + DT * np.cross(INERTIA * w, w) / INERTIA
    k = len(qs)
    step = np.arange(k, dtype=np.int64) * EVERY
    traj = record(model, t=step * DT, step=step, position=np.zeros((k, 1, 3)),
                  quat_wxyz=np.array(qs)[:, None], velocity=np.zeros((k, 1, 3)),
                  angular_velocity=np.array(ws)[:, None])
    return traj


def test_exact_rotation_about_a_principal_axis_conserves_angular_momentum():
    mom = results(tumbling("exact"))["momentum"]
    assert mom.passed
    # measured: 2.7e-16 (round-off of R I R^T w over 200 samples)
    assert mom.stats["flight_angular_rel_max"] < 1e-12


def test_explicit_euler_angular_drift_is_one_finding_per_flight():
    traj = tumbling("euler")
    mom = results(traj)["momentum"]
    found = [f for f in mom.findings if "angular momentum" in f.message]
    assert len(found) == 1, [f.message for f in mom.findings]
    (f,) = found
    # independent: the largest |L(k) - L(0)| over the flight, relative to the largest |L|
    l = traj.angular_momentum[:, 0]
    want = np.linalg.norm(l - l[0], axis=1).max() / np.linalg.norm(l, axis=1).max()
    assert f.value == pytest.approx(want, rel=1e-9)
    assert f.value > 10 * T.MOMENTUM_ANGULAR_REL  # measured 8.1e-5: far past round-off
    assert "free flight" in f.message and "'box'" in f.message and "kg m^2/s" in f.message


# ---- floors: no relative figure over a zero scale ------------------------------------------

def resting_pair(residue: float):
    """Two touching spheres at rest in zero gravity; sphere 0 spins up about the line of
    centres as sphere 1 spins down (a torque between them: L conserved exactly), and sphere 0
    carries a linear momentum ``residue`` (N s) it did not get from anything."""
    model = rblog.body_table(name=["a", "b"], shape=["sphere", "sphere"], size=[0.1, 0.1],
                             mass=[1.0, 1.0], gravity=(0, 0, 0))
    k = 50
    step = np.arange(k, dtype=np.int64) * EVERY
    t = step * DT
    x = np.broadcast_to([[0.0, 0.0, 0.0], [0.2, 0.0, 0.0]], (k, 2, 3))
    i_s = 0.4 * 0.1 ** 2
    wa = np.stack([1.0 + t, 0 * t, 0 * t], 1)
    w = np.stack([wa, -wa], 1)
    p = np.zeros((k, 2, 3))
    p[k // 2:, 0, 1] = residue
    q = np.broadcast_to([1.0, 0, 0, 0], (k, 2, 4))
    return record(model, t=t, step=step, position=x, quat_wxyz=q, linear_momentum=p,
                  angular_momentum=w * i_s)


def test_round_off_momentum_of_bodies_at_rest_is_not_a_fault():
    """1e-32 N s on bodies at rest: before the floor, 1e-32 / 1e-300 read as a violation."""
    mom = results(resting_pair(1e-32))["momentum"]
    assert mom.passed, [f.message for f in mom.findings]


def test_unexplained_momentum_of_bodies_at_rest_is_flagged():
    """1e-6 N s appearing from nothing between two bodies at rest: relative to the scale
    sum m (max |v| + floor) = 1 kg x (1e-6 + 1e-9) + 1 kg x 1e-9 m/s, about 1; one finding for the
    contact (one event over its 49 intervals)."""
    mom = results(resting_pair(1e-6))["momentum"]
    found = [f for f in mom.findings if "linear momentum" in f.message]
    scale = 1e-6 + 2 * T.MOMENTUM_SPEED_FLOOR_MPS
    assert len(found) == 1 and found[0].value == pytest.approx(1e-6 / scale, rel=1e-9)


# ---- compliant stored energy ---------------------------------------------------------------

def soft_bounce(gain: float):
    """A 1 kg ball (r = 0.1 m, e = 1 with the ground) falls, and the log's sample k0 catches it
    d = 10 mm deep in a soft ground pushing with F = 1000 N (logged: J_n = F dt). At the next
    sample it is out and flying up with the energy it had at k0 plus ``gain`` (J). A linear
    spring d deep under F holds F d / 2 = 5 J, which it gives back: up to 5 J is no gain."""
    model = rblog.body_table(name=["ball"], shape=["sphere"], size=[0.1], mass=[1.0],
                             restitution=1.0, ground=True, ground_restitution=1.0)
    g, r, d, f = 9.81, 0.1, 0.01, 1000.0
    k0 = 30
    ks = np.arange(61)
    t = ks * DT * EVERY
    z0, v0 = r - d, -3.0
    e0 = 0.5 * v0 ** 2 + g * z0
    z1 = r + 0.01
    v1 = np.sqrt(2 * (e0 + gain - g * z1))
    tb, ta = t[k0] - t[:k0], t[k0 + 1:] - t[k0 + 1]
    z = np.concatenate([z0 - v0 * tb - 0.5 * g * tb ** 2, [z0], z1 + v1 * ta - 0.5 * g * ta ** 2])
    vz = np.concatenate([v0 + g * tb, [v0], v1 - g * ta])
    pos = np.stack([0 * z, 0 * z, z], 1)[:, None]
    vel = np.stack([0 * z, 0 * z, vz], 1)[:, None]
    step = ks * EVERY
    contacts = dict(step=[step[k0]], body_a=[0], body_b=[-1], point=[[0, 0, -d]],
                    normal=[[0, 0, 1]], separation=[-d], normal_impulse=[f * DT])
    return record(model, t=t, step=step, position=pos, quat_wxyz=np.broadcast_to(
        [1.0, 0, 0, 0], (len(t), 1, 4)), velocity=vel, angular_velocity=np.zeros((len(t), 1, 3)),
        contacts=contacts)


def test_energy_a_soft_contact_held_at_the_first_sample_is_not_a_gain():
    res = results(soft_bounce(gain=4.0))  # < F d / 2 = 5 J
    assert res["energy"].passed, [f.message for f in res["energy"].findings]
    assert not [f for f in res["momentum"].findings if "energy grows" in f.message]


def test_energy_beyond_what_the_soft_contact_held_is_a_gain():
    res = results(soft_bounce(gain=8.0))  # 3 J more than the spring held
    (f,) = res["energy"].findings
    assert "energy grows by 8 J" in f.message and "stored-contact (5 J)" in f.message


# ---- friction cone at a static box's edge --------------------------------------------------

def box_on_ledge(j_sideways: float):
    """A 0.1 m cube (1 kg, mu 0.5 with the ledge) resting across the +y edge of a static box
    (top face z = 0, side face y = 0) in gravity, its bottom corner region on the rim. Over each
    interval the ledge gives it m g dt up plus ``j_sideways`` x m g dt along +y: the contact
    normal at an edge is any in the fan between (0, 0, 1) and (0, 1, 0), so any such impulse
    within 45 deg + atan(mu) of the vertical is inside the cone of some normal of the fan."""
    hh = 0.05
    model = rblog.body_table(name=["box"], shape=["box"], size=[[hh, hh, hh]], mass=[1.0],
                             friction=0.5, static_box_position=[[0.0, -0.5, -0.5]],
                             static_box_quat_wxyz=[[1.0, 0, 0, 0]],
                             static_box_half_extents=[[0.5, 0.5, 0.5]], static_box_friction=[0.5],
                             static_box_restitution=[0.0])
    # the cube is tilted 45 deg about x, its lowest edge along x resting on the rim (y = 0, z = 0)
    rot = Rotation.from_rotvec([np.pi / 4, 0, 0])
    k = 40
    t = np.arange(k) * DT * EVERY
    g = 9.81
    vy = j_sideways * g * t  # the sideways impulse accelerates it along +y (it leaves the rim)
    y = hh * 0 + 0.5 * j_sideways * g * t ** 2
    pos = np.stack([0 * t, y, 0 * t + hh * np.sqrt(2)], 1)[:, None]
    vel = np.stack([0 * t, vy, 0 * t], 1)[:, None]
    q = np.broadcast_to(np.roll(rot.as_quat(), 1), (k, 1, 4))
    step = np.arange(k) * EVERY
    return record(model, t=t, step=step, position=pos, quat_wxyz=q, velocity=vel,
                  angular_velocity=np.zeros((k, 1, 3)))


def test_cone_at_a_static_edge_is_judged_about_the_fan_of_normals():
    """Sideways 0.7 m g dt for m g dt up: 35 deg from the vertical, outside the top face's cone
    (atan 0.5 = 26.6 deg) but inside the cone about a fan normal tilted 10+ deg toward +y."""
    mom = results(box_on_ledge(0.7))["momentum"]
    assert not [f for f in mom.findings if "cone" in f.message], [f.message for f in mom.findings]


def test_cone_at_a_static_edge_still_flags_an_impossible_impulse():
    """Sideways -3 m g dt (pulled toward -y, into the box's side): outside every normal's cone
    in the fan between +z and +y."""
    mom = results(box_on_ledge(-3.0))["momentum"]
    assert [f for f in mom.findings if "cone" in f.message]
