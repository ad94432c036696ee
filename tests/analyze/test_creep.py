"""Creep reported at its true value (issue 31): the net slide of the contact point while settled.

A stay (a resting interval) begins with the body's arrival: it lands, or slides to a stop, or the
solver settles it, and that slide is not creep. Before, creep was counted only after the first
SETTLE_S (0.1 s) of every stay, so a box placed at rest that then slipped 0.30 mm at a steady
speed from its first sample read 0.285 mm (0.29 mm), and one that started slipping 0.05 s in read
0.29 mm. Now the settling slide is what the stay slides in its first SETTLE_S before it slows to
its least, and whatever it slides there faster than its steady slip over the next SETTLE_S
(rblog.analyze.penetration): a body at rest, or creeping at a steady rate from its first
sample, keeps all of its slide; a box that lands or slides to a stop keeps none of its arrival.

Logs are closed forms (0.2 m cubes of 1 kg on the ground, 100 Hz, through
tests/analyze/test_analyze.build): a creep of ``d`` m at constant speed between t_a and t_b slides
the contact point by exactly d.
"""

from __future__ import annotations

import numpy as np
import pytest

from rblog.analyze import check
from rblog.analyze import tolerances as T

from test_analyze import GM, build, make_model, times

HH = 0.1  # half extent (m)


def creeping_boxes(slides, duration=3.0):
    """Boxes at rest on the ground 0.5 m apart, box j sliding slides[j] = (d, t_a, t_b): d metres
    along x at constant speed from t_a to t_b (s), at rest before and after."""
    n = len(slides)
    model = make_model([dict(shape="box", size=(HH, HH, HH), mass=1.0, mu=0.5, name=f"box{j}")
                        for j in range(n)], ground=True)
    t = times(duration)
    x = np.zeros((len(t), n, 3))
    v = np.zeros((len(t), n, 3))
    for j, (d, ta, tb) in enumerate(slides):
        speed = d / (tb - ta)
        x[:, j] = np.stack([0.5 * j + np.clip(t - ta, 0, tb - ta) * speed, np.zeros_like(t),
                            np.full_like(t, HH)], 1)
        v[:, j, 0] = np.where((t >= ta) & (t < tb), speed, 0.0)
    r = np.broadcast_to(np.eye(3), (len(t), n, 3, 3))
    return build(model, t, x, v, r, np.zeros((len(t), n, 3)))


def stacked_creep(d_bottom, d_top, duration=3.0):
    """Box "top" resting on box "bottom" on the ground; bottom slides d_bottom on the ground and
    top d_top on bottom (both along x, at constant speed from t = 0.5 to 2.5 s): top moves
    d_bottom + d_top in the world."""
    model = make_model([dict(shape="box", size=(HH, HH, HH), mass=1.0, name="bottom"),
                        dict(shape="box", size=(HH, HH, HH), mass=1.0, name="top")], ground=True)
    t = times(duration)
    s = np.clip(t - 0.5, 0, 2.0) / 2.0
    moving = ((t >= 0.5) & (t < 2.5)) / 2.0
    x = np.zeros((len(t), 2, 3))
    v = np.zeros((len(t), 2, 3))
    x[:, 0] = np.stack([0.3 + d_bottom * s, np.zeros_like(t), np.full_like(t, HH)], 1)
    x[:, 1] = np.stack([0.3 + (d_bottom + d_top) * s, np.zeros_like(t), np.full_like(t, 3 * HH)], 1)
    v[:, 0, 0] = d_bottom * moving
    v[:, 1, 0] = (d_bottom + d_top) * moving
    r = np.broadcast_to(np.eye(3), (len(t), 2, 3, 3))
    return build(model, t, x, v, r, np.zeros((len(t), 2, 3)))


def arriving_box(v0, mu, creep_speed=0.0, t_creep=0.0, duration=2.0):
    """A box sliding in along x at v0 (below the resting speed), decelerating at mu g to a stop
    at v0 / (mu g), then at rest; with creep_speed (m/s) it also slips steadily from t_creep."""
    model = make_model([dict(shape="box", size=(HH, HH, HH), mass=1.0, mu=mu)], ground=True,
                       ground_mu=mu)
    t = times(duration)
    a = mu * GM
    tt = np.minimum(t, v0 / a)
    xs = v0 * tt - 0.5 * a * tt ** 2 + creep_speed * np.clip(t - t_creep, 0, None)
    vx = np.where(t < v0 / a, v0 - a * t, 0.0) + np.where(t >= t_creep, creep_speed, 0.0)
    x = np.stack([xs, np.zeros_like(t), np.full_like(t, HH)], 1)[:, None]
    v = np.stack([vx, np.zeros_like(t), np.zeros_like(t)], 1)[:, None]
    return build(model, t, x, v, np.broadcast_to(np.eye(3), (len(t), 1, 3, 3)),
                 np.zeros((len(t), 1, 3)))


def penetration(traj):
    (res,) = check(traj, only=["penetration"])
    return res


def creeps(res):
    return {f.bodies[0]: f for f in res.findings if "creeps" in f.message}


# ---- the fault direction: a creep is reported at its true size -------------------------------

@pytest.mark.parametrize("t_a", [0.0, 0.05, 0.5, 0.503])
def test_a_box_creeping_0_3_mm_reads_0_3_mm(t_a):
    """At rest on the ground (from t = 0), it slips 0.30 mm at constant speed from t_a for 2 s,
    then stays: the contact point moves exactly 0.30 mm while settled, wherever in the stay the
    slip begins (before: 0.285 mm from t_a = 0, 0.2925 mm from 0.05 s: the first SETTLE_S was
    never counted)."""
    res = penetration(creeping_boxes([(3e-4, t_a, t_a + 2.0)]))
    (f,) = creeps(res).values()
    assert f.value == pytest.approx(3e-4, rel=1e-9)
    assert f.tolerance == T.PENETRATION_CREEP_M and "0.3 mm" in f.message


def test_two_boxes_creeping_different_amounts_each_get_their_own():
    """0.30 mm and 0.15 mm, starting at different times (one within the first SETTLE_S), and a
    third box at rest: each finding carries its own body's slide (a log once read the identical
    0.10510987350322816 m for two bodies of the 500-box pile)."""
    res = penetration(creeping_boxes([(3e-4, 0.05, 2.05), (1.5e-4, 0.7, 1.7), (0.0, 1.0, 2.0)]))
    found = creeps(res)
    assert set(found) == {0, 1}
    assert found[0].value == pytest.approx(3e-4, rel=1e-9) and "'box0'" in found[0].message
    assert found[1].value == pytest.approx(1.5e-4, rel=1e-9) and "'box1'" in found[1].message
    by_body = {ev["body"]: ev["creep_m"] for ev in res.events}
    assert by_body[2] == pytest.approx(0.0, abs=1e-15)


def test_a_box_creeping_on_a_creeping_box_reads_its_own_slide():
    """Bottom slides 0.30 mm on the ground, top 0.12 mm on bottom (0.42 mm in the world): the
    creep of each is its slide on its own partner."""
    res = penetration(stacked_creep(3e-4, 1.2e-4))
    found = creeps(res)
    assert found[0].value == pytest.approx(3e-4, rel=1e-9) and "'bottom'" in found[0].message
    assert found[1].value == pytest.approx(1.2e-4, rel=1e-9) and "'top'" in found[1].message
    assert "on body 0 ('bottom')" in found[1].message


# ---- the clean direction: settling is not creep ----------------------------------------------

@pytest.mark.parametrize("mu", [0.05, 0.5])
def test_a_box_sliding_to_a_stop_does_not_creep(mu):
    """Arriving at 4 cm/s and stopping under kinetic friction (mu g): 1.6 mm (mu = 0.05) or
    0.16 mm of settling slide, none of it creep."""
    res = penetration(arriving_box(0.04, mu))
    assert not creeps(res)
    (ev,) = res.events
    assert ev["creep_m"] == pytest.approx(0.0, abs=1e-15)


@pytest.mark.parametrize("mu", [0.05, 0.5])
def test_a_box_that_stops_and_then_creeps_reads_the_creep_alone(mu):
    """The same arrival, then a steady slip of 0.15 mm/s from t = 0.09 s to the end (2 s): the
    creep is 0.15 mm/s x 1.91 s = 0.2865 mm, to within the slide of one sample interval
    (0.15 mm/s x 10 ms = 1.5 um: the samples cannot tell where in the interval the arrival's
    last bit of slide ends; at mu = 0.05 the box stops at 0.0815 s, 0.55 um before the sample)."""
    c = 1.5e-4
    res = penetration(arriving_box(0.04, mu, creep_speed=c, t_creep=0.09))
    (f,) = creeps(res).values()
    assert f.value == pytest.approx(c * (2.0 - 0.09), abs=c * 0.01)


def side_by_side(d, overlap=2e-5, duration=3.0):
    """Boxes "left" and "right" on the ground (touching it exactly), their facing sides
    overlapping by ``overlap`` (m), so that each is the other's deepest contact (its support);
    "right" slides d metres along y (along the shared face) from t = 0.5 to 2.5 s."""
    model = make_model([dict(shape="box", size=(HH, HH, HH), mass=1.0, name="left"),
                        dict(shape="box", size=(HH, HH, HH), mass=1.0, name="right")],
                       ground=True)
    t = times(duration)
    s = np.clip(t - 0.5, 0, 2.0) / 2.0
    x = np.zeros((len(t), 2, 3))
    v = np.zeros((len(t), 2, 3))
    x[:, 0] = [0.3, 0.0, HH]
    x[:, 1] = np.stack([np.full_like(t, 0.3 + 2 * HH - overlap), d * s, np.full_like(t, HH)], 1)
    v[:, 1, 1] = d * ((t >= 0.5) & (t < 2.5)) / 2.0
    r = np.broadcast_to(np.eye(3), (len(t), 2, 3, 3))
    return build(model, t, x, v, r, np.zeros((len(t), 2, 3)))


def test_a_slide_between_two_bodies_that_support_each_other_is_reported_once():
    """Each box takes the other as its support (their side overlap is deeper than their ground
    contact); "right" slides 0.2 mm along the shared face. That slide is one creep, 0.2 mm, named
    against the partner it was measured on. Before it was reported for both bodies (the 500-box
    pile's box315 "on the ground" and box317 "on box316" with the identical 0.10510987350322816 m
    was one slide between 315 and 317)."""
    res = penetration(side_by_side(2e-4))
    found = creeps(res)
    assert len(found) == 1, [f.message for f in found.values()]
    (f,) = found.values()
    assert f.value == pytest.approx(2e-4, rel=1e-9)
    assert ("'left'" in f.message and "body 1 ('right')" in f.message) or \
        ("'right'" in f.message and "body 0 ('left')" in f.message)
