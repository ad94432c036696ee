"""Sliding is not resting (issue 16): a contact whose friction is at the Coulomb limit, or whose
tangential load reaches it, slides; its slip is not creep. Slip with the friction strictly inside
the cone is what static friction forbids, and stays creep.

Logs are written with the public writer API (``rblog.Recorder``): a 0.1 m cube of 1 kg on the
ground (mu = 0.5 on both, combined geometrically: 0.5), dt = 1 ms, logged every 10 steps for 2 s,
pushed along x by a constant applied force F = push x mu m g and moving at a constant speed. Its
contact rows (four corners, each J_n = m g dt / 4) carry the friction impulse that balances the
push, -F dt / 4 each: a box pushed at the friction limit slides at constant speed (kinetic
friction balances the push); pushed at half of it, static friction holds it and any motion is
creep.
"""

from __future__ import annotations

import numpy as np
import pytest

import rblog
from rblog.analyze import check
from rblog.analyze import tolerances as T

G = 9.81
MU = 0.5
M = 1.0
HH = 0.05
DT = 1e-3
EVERY = 10
DURATION = 2.0


def _corners(x):
    return np.array([[x[0] + sx * HH, x[1] + sy * HH, 0.0] for sx in (-1, 1) for sy in (-1, 1)])


def pushed_boxes(path=None, *, speed, push, friction, boxes=1, rows=True, neighbour_push=True):
    """``boxes`` cubes in a row along x on the ground, touching, all moving at ``speed`` (m/s)
    along x; the first one pushed by F = push x boxes x mu m g, each one's ground rows carrying
    friction -friction x mu m g dt (total, along x). With two boxes, the first pushes the second
    through their touching faces with an impulse of push x mu m g dt (logged when
    ``neighbour_push``). Returns the trajectory (written to ``path`` as .mcap if given)."""
    model = rblog.body_table(
        name=[f"box{i}" for i in range(boxes)], shape=["box"] * boxes,
        size=[[HH, HH, HH]] * boxes, mass=[M] * boxes, friction=MU, restitution=0.0,
        force_world=[[push * boxes * MU * M * G, 0.0, 0.0]] + [[0.0, 0.0, 0.0]] * (boxes - 1),
        ground=True, ground_friction=MU, ground_restitution=0.0)
    n_s = int(round(DURATION / (DT * EVERY))) + 1
    step = np.arange(n_s, dtype=np.int64) * EVERY
    t = step * DT
    x0 = np.array([[0.3 + 2 * HH * i, -0.2, HH] for i in range(boxes)])
    x = x0[None] + speed * t[:, None, None] * np.array([1.0, 0.0, 0.0])
    v = np.broadcast_to([speed, 0.0, 0.0], (n_s, boxes, 3))
    q = np.broadcast_to([1.0, 0.0, 0.0, 0.0], (n_s, boxes, 4))
    w = np.zeros((n_s, boxes, 3))
    contacts = None
    if rows:
        c = dict(step=[], body_a=[], body_b=[], point=[], normal=[], separation=[],
                 normal_impulse=[], friction_impulse=[])

        def row(s, a, b, p, nrm, jn, f):
            c["step"].append(s), c["body_a"].append(a), c["body_b"].append(b)
            c["point"].append(p), c["normal"].append(nrm), c["separation"].append(0.0)
            c["normal_impulse"].append(jn), c["friction_impulse"].append(f)

        for k in range(1, n_s):
            for i in range(boxes):
                for p in _corners(x[k, i]):
                    row(step[k], i, -1, p, (0, 0, 1), M * G * DT / 4,
                        (-friction * MU * M * G * DT / 4, 0, 0))
            if boxes == 2 and neighbour_push:
                # box 0 pushes box 1 through their shared face: normal from box 0 into box 1
                mid = 0.5 * (x[k, 0] + x[k, 1])
                row(step[k], 1, 0, mid, (1, 0, 0), push * MU * M * G * DT, (0, 0, 0))
        contacts = c
    rec = rblog.Recorder(model, mcap=None if path is None else str(path), dt=DT,
                         log_every=EVERY, keep=True, writer="test_sliding")
    with rec:
        rec.write(t=t, step=step, position=x, quat_wxyz=q, velocity=v, angular_velocity=w,
                  contacts=contacts)
    return rblog.load(str(path)) if path is not None else rec.trajectory


def pen(traj):
    return {r.analyzer: r for r in check(traj)}["penetration"]


def creep_findings(res):
    return [f for f in res.findings if "creeps" in f.message]


# ---- the clean direction: a box sliding at the friction limit is not creeping --------------

@pytest.mark.parametrize("rows", [True, False], ids=["logged-friction", "inferred-impulse"])
def test_box_pushed_at_the_friction_limit_slides_and_is_not_creep(tmp_path, rows):
    """5 mm/s under the resting speed (5 cm/s) and the creep speed (1 cm/s): before issue 16's
    fix counted as resting, creep 5 mm/s x 1.9 s = 9.5 mm. Friction at mu J_n: sliding."""
    traj = pushed_boxes(tmp_path / "slide.mcap", speed=5e-3, push=1.0, friction=1.0, rows=rows)
    res = {r.analyzer: r for r in check(traj)}
    assert all(r.passed for r in res.values()), {a: r.reason for a, r in res.items() if not r.passed}
    p = res["penetration"]
    key = "sliding_friction_at_limit" if rows else "sliding_inferred"
    assert p.stats[key] == traj.n_samples - (1 if rows else 0)  # every sample with a row
    assert p.stats.get("creep_max_m", 0.0) == 0.0


def test_box_pushed_by_its_neighbour_slides_when_the_push_reaches_the_cone():
    """Two touching boxes, the first pushed by 2 mu m g: each slides at 5 mm/s. Box 1's ground
    rows carry no friction (an engine that logs none): its load, the neighbour's impulse mu m g
    dt, reaches mu J_n, so it slides, not creeps."""
    traj = pushed_boxes(speed=5e-3, push=1.0, friction=0.0, boxes=2)
    p = pen(traj)
    assert not creep_findings(p), [f.message for f in p.findings]
    assert p.stats["sliding_pushed"] >= traj.n_samples - 1  # box 1 at every logged sample


# ---- the fault direction: creep with friction inside the cone is flagged -------------------

@pytest.mark.parametrize("rows", [True, False], ids=["logged-friction", "inferred-impulse"])
def test_planted_creep_of_a_box_held_by_static_friction_is_flagged(tmp_path, rows):
    """Pushed at half the limit, friction logged at half the limit (static friction holds it):
    a 0.1 mm/s creep from the first sample slides 0.1 mm/s x 2 s = 0.2 mm > 0.1 mm (a steady
    slip has no settling slide: the whole stay counts)."""
    speed = 1e-4
    traj = pushed_boxes(tmp_path / "creep.mcap", speed=speed, push=0.5, friction=0.5, rows=rows)
    p = pen(traj)
    (f,) = creep_findings(p)
    assert f.value == pytest.approx(speed * DURATION, rel=1e-9)
    assert f.tolerance == T.PENETRATION_CREEP_M and f.unit == "m" and f.bodies == [0]
    assert "box0" in f.message and "mm" in f.message and "tol 0.1 mm" in f.message
    assert p.stats["sliding_friction_at_limit"] + p.stats["sliding_inferred"] == 0


def test_planted_creep_below_the_tolerance_passes():
    """0.045 mm/s x 2 s = 0.09 mm: under the 0.1 mm creep tolerance."""
    p = pen(pushed_boxes(speed=4.5e-5, push=0.5, friction=0.5))
    assert p.passed and p.stats["creep_max_m"] == pytest.approx(4.5e-5 * DURATION, rel=1e-9)


def test_creep_between_sliding_samples_is_still_creep():
    """Friction at the limit every third logged sample only (stick-slip as an unconverged
    solver logs it) while the box keeps slipping at 1 mm/s: the samples with friction inside the
    cone still slip, and their slip is creep. The sliding samples do not end the resting
    interval (else each stretch would restart the settling time and hide the creep)."""
    traj = pushed_boxes(speed=1e-3, push=0.5, friction=0.5)
    c = traj.contacts
    k = np.searchsorted(traj.step, c.step)
    at_limit = (k % 3) == 0
    c.friction_impulse[at_limit] *= 2.0  # 0.5 -> 1.0 of the limit
    p = pen(traj)
    (f,) = creep_findings(p)
    # the slip of intervals with no sliding end: 2 of 3 samples are not sliding; an interval
    # counts half of each non-sliding end's slip: (1/3 both ends + 2/3 one end x 1/2) = 2/3
    assert f.value == pytest.approx(1e-3 * DURATION * 2 / 3, rel=0.02)
    assert len(p.events) == 1  # one resting interval, not one per stick phase


def pivoting_box(friction, pivot_only=False):
    """The box turning at 0.05 rad/s about a vertical axis through its corner 0 (a pivot): the
    centre slips at 0.05 x 0.0707 = 3.5 mm/s. Corner 0 sticks (no friction); the other three
    corners' rows carry ``friction`` x mu J_n against their own slip direction. With
    ``pivot_only`` the pivot's row alone is logged, carrying the whole weight (the rest of the
    face touches without load, as an engine's one-point manifold has it)."""
    w = 0.05
    model = rblog.body_table(name=["box"], shape=["box"], size=[[HH, HH, HH]], mass=[M],
                             friction=MU, restitution=0.0, ground=True, ground_friction=MU,
                             ground_restitution=0.0)
    n_s = int(round(DURATION / (DT * EVERY))) + 1
    step = np.arange(n_s, dtype=np.int64) * EVERY
    t = step * DT
    local = np.array([[sx * HH, sy * HH, -HH] for sx in (-1, 1) for sy in (-1, 1)])
    pivot = np.array([0.3, -0.2, HH]) + local[0] * [1, 1, 0]
    a = w * t
    rz = np.zeros((n_s, 3, 3))
    rz[:, 0, 0], rz[:, 0, 1], rz[:, 1, 0], rz[:, 1, 1], rz[:, 2, 2] = (
        np.cos(a), -np.sin(a), np.sin(a), np.cos(a), 1.0)
    x0 = np.array([0.3, -0.2, HH])
    x = pivot + np.einsum("kij,j->ki", rz, x0 - pivot)
    wv = np.array([0.0, 0.0, w])
    v = np.cross(wv, x - pivot)
    q = np.stack([np.cos(a / 2), 0 * a, 0 * a, np.sin(a / 2)], 1)
    c = dict(step=[], body_a=[], body_b=[], point=[], normal=[], separation=[],
             normal_impulse=[], friction_impulse=[])
    for k in range(1, n_s):
        for j, loc in enumerate(local):
            if pivot_only and j > 0:
                continue
            p = x[k] + rz[k] @ loc
            slip = np.cross(wv, p - pivot)
            sn = np.linalg.norm(slip)
            f = np.zeros(3) if j == 0 else -friction * MU * M * G * DT / 4 * slip / sn
            for key, val in (("step", step[k]), ("body_a", 0), ("body_b", -1), ("point", p),
                             ("normal", (0, 0, 1)), ("separation", 0.0),
                             ("normal_impulse", M * G * DT / (1 if pivot_only else 4)),
                             ("friction_impulse", f)):
                c[key].append(val)
    rec = rblog.Recorder(model, dt=DT, log_every=EVERY, keep=True)
    with rec:
        rec.write(t=t, step=step, position=x[:, None], quat_wxyz=q[:, None], velocity=v[:, None],
                  angular_velocity=np.broadcast_to(wv, (n_s, 1, 3)), contacts=c)
    return rec.trajectory


def test_a_box_pivoting_on_a_corner_slides_and_is_not_creep():
    """Three of four points at the limit, each in its own direction (their vector sum is well
    inside the cone), the pivot inside: a slipping rigid contact, not a resting one."""
    p = pen(pivoting_box(friction=1.0))
    assert not creep_findings(p), [f.message for f in p.findings]
    assert p.stats["sliding_friction_at_limit"] == N_LOGGED


def test_a_box_pivoting_with_friction_inside_the_cone_is_creep():
    """The same motion with every point at half its limit: static friction should hold it; the
    centre slips 3.5 mm/s x 2 s ~ 7.1 mm along its arc (from its first sample: a steady slip,
    no settling slide)."""
    p = pen(pivoting_box(friction=0.5))
    (f,) = creep_findings(p)
    arc = 0.05 * np.hypot(HH, HH) * DURATION
    assert f.value == pytest.approx(arc, rel=1e-3)  # chord of a 0.1 rad arc: 4.2e-4 shorter


N_LOGGED = int(round(DURATION / (DT * EVERY)))  # samples with contact rows (all but the first)


def still_boxes_log(model, step, x, v, rows):
    """Trajectory of unrotated, non-spinning boxes at positions ``x`` (T, N, 3) and velocities
    ``v`` (T, N, 3), sampled at ``step``. ``rows`` (body, partner, z or None, J_n) lists the
    frictionless rows logged at every sample but the first, one per bottom corner of ``body``
    (at height z, or at the corner's own)."""
    c = dict(step=[], body_a=[], body_b=[], point=[], normal=[], separation=[],
             normal_impulse=[], friction_impulse=[])
    for k in range(1, len(step)):
        for body, partner, z, jn in rows:
            for p in _corners(x[k, body]):
                for key, val in (("step", step[k]), ("body_a", body), ("body_b", partner),
                                 ("point", (p[0], p[1], p[2] if z is None else z)),
                                 ("normal", (0, 0, 1)), ("separation", 0.0),
                                 ("normal_impulse", jn), ("friction_impulse", (0.0, 0.0, 0.0))):
                    c[key].append(val)
    n_s, n_b = x.shape[:2]
    rec = rblog.Recorder(model, dt=DT, log_every=EVERY, keep=True)
    with rec:
        rec.write(t=step * DT, step=step, position=x,
                  quat_wxyz=np.broadcast_to([1.0, 0, 0, 0], (n_s, n_b, 4)), velocity=v,
                  angular_velocity=np.zeros((n_s, n_b, 3)), contacts=c)
    return rec.trajectory


def stacked_boxes(load):
    """Box 1 on box 0 (box 0 on the ground, still), box 1 sliding along x at 1 mm/s (under the
    creep speed, 1 cm/s). Box 1's four rows on box 0 carry ``load`` x m g dt / 4 each and no
    friction; box 0's ground rows carry both boxes' weight. Box 0 sits 10 um into the ground so
    that the ground, not box 1, is its deepest contact."""
    speed = 1e-3
    model = rblog.body_table(name=["under", "over"], shape=["box", "box"],
                             size=[[HH, HH, HH]] * 2, mass=[M, M], friction=MU, restitution=0.0,
                             ground=True, ground_friction=MU, ground_restitution=0.0)
    n_s = int(round(DURATION / (DT * EVERY))) + 1
    step = np.arange(n_s, dtype=np.int64) * EVERY
    t = step * DT
    x = np.zeros((n_s, 2, 3))
    x[:, 0] = [0.3, -0.2, HH - 1e-5]
    x[:, 1] = [0.3, -0.2, 3 * HH - 1e-5]
    x[:, 1, 0] += speed * t
    v = np.zeros((n_s, 2, 3))
    v[:, 1, 0] = speed
    return still_boxes_log(model, step, x, v, ((0, -1, 0.0, 2 * M * G * DT / 4),
                                               (1, 0, 2 * HH - 1e-5, load * M * G * DT / 4)))


def test_a_box_on_an_unloaded_support_slides_and_is_not_creep():
    """Box 1's rows on box 0 carry no load at every logged step (a box chattering on another,
    loaded only between the samples, as in rblog's pile at seed 2, box 177 on box 130): mu x 0
    is their friction limit, so the contact slides; before this rule, 1 mm/s x 1.9 s = 1.9 mm
    read as creep."""
    p = pen(stacked_boxes(load=0.0))
    assert not creep_findings(p), [f.message for f in p.findings]
    assert p.stats["sliding_unloaded"] == N_LOGGED  # box 1 at every sample with rows


def test_the_same_slide_on_a_loaded_support_is_creep():
    """The same motion with box 1's weight on its rows and no friction logged (inside the
    cone): static friction should hold it; 1 mm/s x 2 s = 2 mm is creep (the whole stay: the
    slip is steady from the first sample)."""
    p = pen(stacked_boxes(load=1.0))
    (f,) = creep_findings(p)
    assert f.bodies == [1]
    assert f.value == pytest.approx(1e-3 * DURATION, rel=1e-9)
    assert p.stats["sliding_unloaded"] == 0


def shifted_box(intervals):
    """A box resting on the ground (its rows carry its weight, no friction: inside the cone),
    logged at rest at every sample, whose pose moves 0.2 mm along x from t = 1 s, evenly over
    ``intervals`` sample intervals: one interval is a kick between the samples (a resting box
    struck and stopped by friction within 10 ms, as in rblog's pile at seed 4: box 400 at 29.5
    mm/s for 7 steps between t = 1.50 and 1.51 s), ten are a slip at 2 mm/s that the logged
    velocities do not show."""
    model = rblog.body_table(name=["box"], shape=["box"], size=[[HH, HH, HH]], mass=[M],
                             friction=MU, restitution=0.0, ground=True, ground_friction=MU,
                             ground_restitution=0.0)
    n_s = int(round(DURATION / (DT * EVERY))) + 1
    step = np.arange(n_s, dtype=np.int64) * EVERY
    t = step * DT
    t0, t1 = 1.0, 1.0 + intervals * DT * EVERY
    x = np.zeros((n_s, 1, 3))
    x[:, 0] = [0.3, -0.2, HH]
    x[:, 0, 0] += 2e-4 * np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    return still_boxes_log(model, step, x, np.zeros((n_s, 1, 3)),
                           ((0, -1, None, M * G * DT / 4),))


def test_a_kick_between_two_samples_is_a_slide_not_creep():
    """0.2 mm within one 10 ms interval: 20 mm/s on average, over the creep speed (10 mm/s)."""
    p = pen(shifted_box(intervals=1))
    assert not creep_findings(p), [f.message for f in p.findings]
    assert p.stats["creep_fast_intervals"] == 1


def test_the_same_shift_over_ten_intervals_is_creep():
    """0.2 mm over ten intervals, 2 mm/s: slow, with the friction inside the cone: creep 0.2 mm."""
    p = pen(shifted_box(intervals=10))
    (f,) = creep_findings(p)
    assert f.value == pytest.approx(2e-4, rel=1e-9)
    assert p.stats["creep_fast_intervals"] == 0


def test_a_box_turning_about_its_only_loaded_corner_is_not_creep():
    """The same turn with one loaded point, the pivot (friction zero: inside the cone), and the
    rest of the face unloaded: a single point holds no torque about itself, so the box may turn
    about it. The turn's centre lies on the face patch (and on the ground), so the slide is 0;
    read at the face's centre it was 3.5 mm/s x 1.9 s = 6.7 mm (rblog's pile at seed 7: box 75
    turning at 0.13 rad/s about the one point of its manifold with box 76)."""
    p = pen(pivoting_box(friction=0.0, pivot_only=True))
    assert not creep_findings(p), [f.message for f in p.findings]
    assert p.stats["creep_max_m"] < 1e-9  # the pivot's third-order remainder
