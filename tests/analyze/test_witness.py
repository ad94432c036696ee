"""Witness points of contacts (rblog.analyze.geometry): the centre of the patch where the bodies
really touch, from the poses and shapes alone.

Each expected point is computed here from the geometry of the case (where the touching face,
edge or corner lies), not from the program. The last tests are the case that motivated it: a box
turning about the corner it stands on (no slip there) is not creep, while the same box dragging
that corner 0.3 mm is. With the old witness (midway between the corner and the supporting face's
centre) the turning box "slid" w x 18 mm x 1.9 s = 1.7 mm.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import rblog
from rblog.analyze import check, geometry
from rblog.analyze import tolerances as T
from test_analyze import make_model

H = 0.05  # half extent of the cubes (m)
S2 = np.sqrt(2.0)


def rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def ground_witness(x, r, h=(H, H, H)):
    model = make_model([dict(shape="box", size=tuple(h), mass=1.0)], ground=True)
    return geometry.plane_witness(model, np.array([0]), np.asarray(x, float)[None],
                                  np.asarray(r, float)[None])[0]


def pair(xa, ra, ha, xb, rb, hb):
    """(sep, normal b->a, witness) of boxes a, b."""
    sep, n, p = geometry.box_box(*(np.asarray(v, float)[None] for v in (xa, ra, ha, xb, rb, hb)))
    return sep[0], n[0], p[0]


# ---- box on the ground -----------------------------------------------------------------------

def test_a_box_flat_on_the_ground_tilted_by_round_off_touches_with_its_face():
    """Tilted by 1e-5 rad about x, a 0.1 m face's corners differ in height by 1 um (under the
    0.1 mm band): the witness is the bottom face's centre, R (0, 0, -h) from the centre, at the
    level of the lowest point (the ground). The old 1e-6 cosine test made it an edge, 50 mm
    away."""
    a = 1e-5
    r = rx(a)
    x = np.array([0.3, -0.2, H * np.sin(a) + H * np.cos(a)])  # lowest corner on the ground
    face_centre = x + np.array([0.0, H * np.sin(a), -H * np.cos(a)])
    np.testing.assert_allclose(ground_witness(x, r), [face_centre[0], face_centre[1], 0.0],
                               rtol=0, atol=1e-15)


def test_a_box_tilted_by_005_rad_touches_with_its_lowest_edge():
    """Tilted by 0.05 rad about x (5 mm across the face, beyond the band): the lowest edge is the
    one at body (y, z) = (-h, -h), running along x; the witness is its midpoint, on the ground."""
    a = 0.05
    r = rx(a)
    x = np.array([0.3, -0.2, H * (np.sin(a) + np.cos(a))])
    edge_mid = x + np.array([0.0, -H * np.cos(a) + H * np.sin(a), -H * np.sin(a) - H * np.cos(a)])
    assert edge_mid[2] == pytest.approx(0.0, abs=1e-16)
    np.testing.assert_allclose(ground_witness(x, r), edge_mid, rtol=0, atol=1e-15)


# ---- box on box --------------------------------------------------------------------------------

def corner_down(corner, extra=np.eye(3)):
    """A cube standing on its corner (-h, -h, -h) at world point ``corner``: R maps the body
    diagonal (1, 1, 1)/sqrt(3) to +z, so that corner is the lowest, h sqrt(3) below the centre;
    ``extra`` (a turn about z) keeps it so. Returns (x, R)."""
    r0 = Rotation.align_vectors([[0.0, 0.0, 1.0]], [np.ones(3) / np.sqrt(3)])[0].as_matrix()
    r = extra @ r0
    return np.asarray(corner, float) + np.array([0.0, 0.0, H * np.sqrt(3.0)]), r


def test_a_corner_on_a_face_off_centre_is_the_corner():
    """A cube on its corner at (0.07, -0.04) on the 0.4 x 0.4 top face of a slab (top at z = 0.05):
    the witness is the corner (the old one was midway to the face's centre, 40 mm away)."""
    corner = [0.07, -0.04, 0.05]
    xa, ra = corner_down(corner, rz(0.3))
    sep, n, p = pair(xa, ra, [H, H, H], [0, 0, 0], np.eye(3), [0.2, 0.2, 0.05])
    assert sep == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(n, [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(p, corner, rtol=0, atol=1e-15)


def test_two_crossed_edges_touch_at_their_crossing():
    """a: a cube turned 45 deg about x (its lowest edge runs along x, h sqrt(2) below the
    centre), then 0.2 rad about z; b: a cube turned 45 deg about y (its top edge runs along y,
    h sqrt(2) above the centre). The edges cross at x = x_b, y = y_a + (x_b - x_a) tan 0.2; the
    witness is there, midway between them (they touch: at z_b + h sqrt(2))."""
    xb = np.array([0.01, 0.02, 0.0])
    xa = np.array([-0.015, 0.03, 2 * H * S2])
    sep, n, p = pair(xa, rz(0.2) @ rx(np.pi / 4), [H, H, H], xb, ry(np.pi / 4), [H, H, H])
    assert sep == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(n, [0, 0, 1], atol=1e-12)
    cross = [xb[0], xa[1] + (xb[0] - xa[0]) * np.tan(0.2), H * S2]
    np.testing.assert_allclose(p, cross, rtol=0, atol=1e-15)


def test_a_face_on_a_larger_face_offset_is_the_centroid_of_the_overlap():
    """a (half 0.05 x 0.04 x 0.05) at (0.18, 0.1) on a slab (half 0.2 x 0.15 x 0.05): a's bottom
    face spans x 0.13..0.23, y 0.06..0.14; the slab's top x -0.2..0.2, y -0.15..0.15. The
    overlap is x 0.13..0.2, y 0.06..0.14: centroid (0.165, 0.1), on the slab's top (z = 0.05)."""
    sep, n, p = pair([0.18, 0.1, 0.1], np.eye(3), [0.05, 0.04, 0.05], [0, 0, 0], np.eye(3),
                     [0.2, 0.15, 0.05])
    assert sep == 0.0
    np.testing.assert_allclose(n, [0, 0, 1])
    np.testing.assert_allclose(p, [0.165, 0.1, 0.05], rtol=0, atol=1e-15)


def test_a_diamond_overhanging_an_edge_gives_the_centroid_of_its_inside_part():
    """A cube turned 45 deg about z (its bottom face a diamond of half-diagonal d = h sqrt(2))
    centred at (0.17, 0.01) on the slab whose top ends at x = 0.2: the diamond's tip beyond
    x = 0.2 is a right triangle of height c = 0.17 + d - 0.2 and base 2c (area c^2, centroid at
    x = 0.2 + c/3, y = 0.01); the overlap is the diamond (area 4 h^2, centroid (0.17, 0.01))
    without it."""
    xa = np.array([0.17, 0.01, 0.1])
    sep, n, p = pair(xa, rz(np.pi / 4), [H, H, H], [0, 0, 0], np.eye(3), [0.2, 0.15, 0.05])
    assert sep == pytest.approx(0.0, abs=1e-15)
    d = H * S2
    c = 0.17 + d - 0.2
    a_all, a_tip = 4 * H * H, c * c
    x = (a_all * 0.17 - a_tip * (0.2 + c / 3)) / (a_all - a_tip)
    np.testing.assert_allclose(p, [x, 0.01, 0.05], rtol=0, atol=1e-14)


def test_a_cube_tilted_by_half_a_milliradian_on_a_slab_touches_with_its_face():
    """Tilted by 5e-4 rad about x, the cube's bottom corners differ in height by 0.05 mm (inside
    the 0.1 mm band): the patch is its whole bottom face (inside the slab's top), centred at
    R (0, 0, -h) from its centre, on the slab's top where its lowest edge touches."""
    a = 5e-4
    xa = np.array([0.02, 0.01, 0.05 + H * (np.sin(a) + np.cos(a))])  # lowest edge at z = 0.05
    sep, n, p = pair(xa, rx(a), [H, H, H], [0, 0, 0], np.eye(3), [0.2, 0.15, 0.05])
    assert sep == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(n, [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(p, [0.02, 0.01 + H * np.sin(a), 0.05], rtol=0, atol=1e-15)


def test_an_edge_across_a_face_partly_overhanging_is_the_middle_of_its_inside_part():
    """A cube turned 45 deg about x lies on its edge (along x, x 0.13..0.23) across the slab's
    top, which ends at x = 0.2: the inside part is x 0.13..0.2, its middle x = 0.165."""
    xa = np.array([0.18, -0.03, 0.05 + H * S2])
    sep, n, p = pair(xa, rx(np.pi / 4), [H, H, H], [0, 0, 0], np.eye(3), [0.2, 0.15, 0.05])
    assert sep == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(n, [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(p, [0.165, -0.03, 0.05], rtol=0, atol=1e-15)


def test_parallel_edges_touch_at_the_middle_of_their_overlap():
    """In the contact plane: edge a along u from -0.05 to 0.05, edge b along u from -0.02 to 0.08
    and 2 mm aside: the overlap is -0.02..0.05, its middle 0.015, halfway across (1 mm). Tilted
    so that an end moves by less than the band, still parallel; by 10 bands, their crossing (or
    their closest points when they do not cross)."""
    p = geometry._edge_edge(0.0, 0.0, 0.05, 0.0, 0.03, 0.002, 0.05, 0.0)
    np.testing.assert_allclose(p, [0.015, 0.001], rtol=0, atol=1e-17)
    a = 0.5 * T.WITNESS_BAND_M / 0.1  # b turned so its ends move by half the band
    p = geometry._edge_edge(0.0, 0.0, 0.05, 0.0, 0.03, 0.002, 0.05 * np.cos(a), 0.05 * np.sin(a))
    assert p[0] == pytest.approx(0.015, abs=1e-4) and p[1] == pytest.approx(0.001, abs=1e-4)
    a = 10 * T.WITNESS_BAND_M / 0.1  # 0.01 rad, b 0.2 mm aside: the lines cross at x = 0.01
    p = geometry._edge_edge(0.0, 0.0, 0.05, 0.0, 0.03, 0.0002, 0.05 * np.cos(a), 0.05 * np.sin(a))
    cross = 0.03 - 0.0002 / np.tan(a)  # where b's line meets y = 0
    # measured 1.1e-13: round-off of the solve, amplified by 1 / sin(0.01)
    np.testing.assert_allclose(p, [cross, 0.0], rtol=0, atol=1e-12)
    # 2 mm aside they do not meet (b's line reaches y = 0 at x = -0.17, beyond its end): the
    # midpoint of b's near end e and the point of a below it
    p = geometry._edge_edge(0.0, 0.0, 0.05, 0.0, 0.03, 0.002, 0.05 * np.cos(a), 0.05 * np.sin(a))
    e = [0.03 - 0.05 * np.cos(a), 0.002 - 0.05 * np.sin(a)]
    np.testing.assert_allclose(p, [e[0], e[1] / 2], rtol=0, atol=1e-15)


def test_the_witness_lies_midway_between_penetrating_faces():
    """Two cubes face on face, a 0.2 mm into b: the witness is 0.1 mm below a's bottom face."""
    sep, n, p = pair([0.02, 0.0, 2 * H - 2e-4], np.eye(3), [H, H, H], [0, 0, 0], np.eye(3),
                     [H, H, H])
    assert sep == pytest.approx(-2e-4, abs=1e-15)
    # overlap x -0.03..0.05, y -0.05..0.05
    np.testing.assert_allclose(p, [0.01, 0.0, H - 1e-4], rtol=0, atol=1e-15)


# ---- the motivating case: a box turning about the corner it stands on -------------------------

DT, EVERY, DURATION = 1e-3, 10, 2.0
W = 0.05  # rad/s: box433 turned at ~0.047 rad/s on box432 in the 500-box pile
CORNER = np.array([0.03, -0.02, 2 * H])  # on the bottom cube's top face, 36 mm off its centre


def stacked_rows(step, top_point, bottom_half, also=None, g=9.81):
    """Contact rows of a 1 kg "top" on a 1 kg "bottom" on the ground, logged at every step but
    the first: one row at ``top_point[k]`` carrying the top's weight (with ``also``, a second
    row at ``also[k]`` and half the weight on each), and the bottom's four ground corners (half
    extents ``bottom_half`` in x, y, centred on the origin) carrying both; no friction (inside
    the cone)."""
    c = {k: [] for k in ("step", "body_a", "body_b", "point", "normal", "separation",
                         "normal_impulse", "friction_impulse")}

    def row(s, a, b, p, jn):
        for key, val in (("step", s), ("body_a", a), ("body_b", b), ("point", p),
                         ("normal", (0.0, 0.0, 1.0)), ("separation", 0.0),
                         ("normal_impulse", jn), ("friction_impulse", (0.0, 0.0, 0.0))):
            c[key].append(val)

    for k in range(1, len(step)):
        if also is None:
            row(step[k], 1, 0, top_point[k], g * DT)
        else:
            row(step[k], 1, 0, top_point[k], g * DT / 2)
            row(step[k], 1, 0, also[k], g * DT / 2)
        for sx in (-1, 1):
            for sy in (-1, 1):
                row(step[k], 0, -1, (sx * bottom_half[0], sy * bottom_half[1], 0.0),
                    2 * g * DT / 4)
    return c


def turning_on_a_corner(drift, rows):
    """Cube "top" stands on its corner on cube "bottom" (resting on the ground) and turns about
    the vertical through the corner at W; with ``drift`` (m) the corner also slides along x,
    uniformly over the whole rest (from its first sample). Logged with the writer API;
    with ``rows``, one contact row per logged step at the corner carrying the top's weight
    (friction zero: inside the cone) and the bottom's ground rows."""
    n_s = int(round(DURATION / (DT * EVERY))) + 1
    step = np.arange(n_s, dtype=np.int64) * EVERY
    t = step * DT
    vs = drift / DURATION
    # a generic tilt of a cube on its corner (its edges 15..55 deg from the horizontal)
    r0 = Rotation.from_euler("xyz", [0.3, -0.2, 0.0]).as_matrix() @ corner_down(CORNER)[1]
    signs = np.array(list(np.ndindex(2, 2, 2))) * 2.0 - 1.0
    local = signs[np.argmin((signs * H) @ r0[2])] * H  # the lowest corner, body frame
    corner = CORNER[None] + vs * t[:, None] * [1.0, 0.0, 0.0]
    rot = np.einsum("kij,jl->kil", np.stack([rz(W * tk) for tk in t]), r0)
    x_top = corner - np.einsum("kij,j->ki", rot, local)
    w = np.array([0.0, 0.0, W])
    v_top = vs * np.array([1.0, 0.0, 0.0]) + np.cross(w, x_top - corner)
    pos = np.stack([np.broadcast_to([0.0, 0.0, H], (n_s, 3)), x_top], 1)
    vel = np.stack([np.zeros((n_s, 3)), v_top], 1)
    om = np.stack([np.zeros((n_s, 3)), np.broadcast_to(w, (n_s, 3))], 1)
    q = np.stack([np.broadcast_to([1.0, 0, 0, 0], (n_s, 4)),
                  Rotation.from_matrix(rot).as_quat(scalar_first=True)], 1)
    model = rblog.body_table(name=["bottom", "top"], shape=["box", "box"], size=[[H, H, H]] * 2,
                             mass=[1.0, 1.0], friction=0.5, restitution=0.0, ground=True,
                             ground_friction=0.5, ground_restitution=0.0)
    contacts = stacked_rows(step, corner, (H, H)) if rows else None
    rec = rblog.Recorder(model, dt=DT, log_every=EVERY, keep=True, writer="test_witness")
    with rec:
        rec.write(t=t, step=step, position=pos, quat_wxyz=q, velocity=vel, angular_velocity=om,
                  contacts=contacts)
    return rec.trajectory, corner


def creep_of_top(traj):
    pen = {r.analyzer: r for r in check(traj)}["penetration"]
    return pen, [f for f in pen.findings if "creeps" in f.message]


@pytest.mark.parametrize("rows", [False, True], ids=["no-rows", "rows"])
def test_a_box_turning_about_its_corner_on_another_box_does_not_creep(rows):
    traj, corner = turning_on_a_corner(drift=0.0, rows=rows)
    # the geometry: the top's witness on the bottom is its corner at every sample
    k = np.arange(traj.n_samples)
    _, nrm, pt = geometry.pair_geometry(traj.model, traj.position, traj.rotation, k,
                                        np.zeros_like(k), np.ones_like(k))
    np.testing.assert_allclose(nrm, np.broadcast_to([0, 0, -1], nrm.shape), atol=1e-12)
    np.testing.assert_allclose(pt, corner, rtol=0, atol=1e-14)
    pen, creep = creep_of_top(traj)
    assert not creep, [f.message for f in creep]
    # the corner does not move; the slide is taken from the poses with the rigid field about the
    # centre's midpoint, exact to third order: theta^3 |x - p| / 12 per 10 ms interval with
    # theta = 0.05 rad/s x 0.01 s and |x - p| = 0.0866 m is 9.0e-13 m, x 60 intervals 5.4e-11
    # (measured 6.0e-11 m); 0.1 mm is the tolerance
    assert pen.stats["creep_max_m"] < 2e-10


@pytest.mark.parametrize("rows", [False, True], ids=["no-rows", "rows"])
def test_the_same_box_dragging_its_corner_03_mm_creeps(rows):
    traj, _ = turning_on_a_corner(drift=3e-4, rows=rows)
    pen, creep = creep_of_top(traj)
    (f,) = [f for f in creep if "'top'" in f.message]
    # the corner slides 0.3 mm at constant speed over the whole rest (a steady slip from the
    # first sample: no settling slide; from the poses, plus the turn's third-order remainder,
    # 6e-11 m)
    assert f.value == pytest.approx(3e-4, rel=1e-6)


def swinging_on_an_edge(drift, far_end_loaded=False, pivot_twice=False):
    """Cube "top" lies on its edge (turned 45 deg about x: the edge along x, 0.1 m long) on the
    top face of slab "bottom" (0.4 x 0.3 x 0.1 m, on the ground), and swings about the vertical
    through the edge's end at the origin's (0, 0, 0.1) at W: that end stays, the other end
    scrapes sideways (the swing of rblog's pile at seed 5, box 444 on box 441). With ``drift`` (m)
    the whole box also slides along the edge (x), uniformly over the whole rest.
    One contact row per logged step at the pivot end carries the top's weight (friction zero:
    inside the cone), and the slab's four ground rows its own and the top's; with
    ``far_end_loaded`` the edge's other end has a row too, and each carries half the weight; with
    ``pivot_twice`` the second row lies at the pivot instead, 2 nm off (a box-box manifold that
    clips two rows to one corner: box406 swinging against box361 in samples/pile.toml at seed 12,
    its two rows 2.3 nm apart)."""
    n_s = int(round(DURATION / (DT * EVERY))) + 1
    step = np.arange(n_s, dtype=np.int64) * EVERY
    t = step * DT
    vs = drift / DURATION
    slab = np.array([0.2, 0.15, 0.05])
    pivot = np.array([0.0, 0.0, 2 * slab[2]])[None] + vs * t[:, None] * [1.0, 0.0, 0.0]
    r0 = rx(np.pi / 4)
    local = np.array([-H, -H, -H])  # the edge's end at the pivot, body frame (edge: (s H, -H, -H))
    rot = np.einsum("kij,jl->kil", np.stack([rz(W * tk) for tk in t]), r0)
    x_top = pivot - np.einsum("kij,j->ki", rot, local)
    w = np.array([0.0, 0.0, W])
    v_top = vs * np.array([1.0, 0.0, 0.0]) + np.cross(w, x_top - pivot)
    pos = np.stack([np.broadcast_to([0.0, 0.0, slab[2]], (n_s, 3)), x_top], 1)
    vel = np.stack([np.zeros((n_s, 3)), v_top], 1)
    om = np.stack([np.zeros((n_s, 3)), np.broadcast_to(w, (n_s, 3))], 1)
    q = np.stack([np.broadcast_to([1.0, 0, 0, 0], (n_s, 4)),
                  Rotation.from_matrix(rot).as_quat(scalar_first=True)], 1)
    model = rblog.body_table(name=["bottom", "top"], shape=["box", "box"],
                             size=[list(slab), [H, H, H]], mass=[1.0, 1.0], friction=0.5,
                             restitution=0.0, ground=True, ground_friction=0.5,
                             ground_restitution=0.0)
    far = x_top + np.einsum("kij,j->ki", rot, local * [-1.0, 1.0, 1.0])
    also = far if far_end_loaded else (pivot + 2e-9 if pivot_twice else None)
    c = stacked_rows(step, pivot, slab[:2], also=also)
    rec = rblog.Recorder(model, dt=DT, log_every=EVERY, keep=True, writer="test_witness")
    with rec:
        rec.write(t=t, step=step, position=pos, quat_wxyz=q, velocity=vel, angular_velocity=om,
                  contacts=c)
    return rec.trajectory


def test_a_box_swinging_about_an_end_of_its_edge_does_not_creep():
    """The patch is the edge: its midpoint slips W x 0.05 m = 2.5 mm/s (before the patch's span
    was used, 2.5 mm/s x 1.9 s read as 4.75 mm of creep), its pivot end not at all."""
    traj = swinging_on_an_edge(drift=0.0)
    k = np.arange(traj.n_samples)
    _, _, pt, span = geometry.pair_geometry(traj.model, traj.position, traj.rotation, k,
                                            np.ones_like(k), np.zeros_like(k), with_span=True)
    # the patch is the whole edge: centre 0.05 m from the pivot along the edge, half-span 0.05 m
    edge = traj.rotation[:, 1, :, 0]  # the top's body x axis in the world
    np.testing.assert_allclose(pt, np.array([0.0, 0.0, 0.1]) + H * edge, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.abs(np.einsum("ki,ki->k", span, edge)), H, rtol=1e-12)
    pen, creep = creep_of_top(traj)
    assert not creep, [f.message for f in creep]
    # the pivot end's slide is the third-order remainder, as for the corner above (6e-11 m):
    # measured below 1e-10 m
    assert pen.stats["creep_max_m"] < 2e-10


def test_the_same_box_sliding_03_mm_along_its_edge_creeps():
    """The box drifts 0.3 mm along x while it swings: its motion is a turn at W about a point
    vs / W = 3.2 mm off the pivot, across the drift. The patch's least-slipping point is the foot
    of that centre on the edge, which slides at vs cos(theta) along the edge (theta = W t, the
    edge's angle to x): creep |integral of vs cos(theta) (cos theta, sin theta) dt| over the
    whole rest (a steady slip from the first sample), 0.29933 mm (the part of the drift across
    the edge is the swing's, not creep)."""
    drift = 3e-4
    pen, creep = creep_of_top(swinging_on_an_edge(drift=drift))
    (f,) = [f for f in creep if "'top'" in f.message]
    vs = drift / DURATION
    t0, t1 = 0.0, DURATION
    along = vs * ((t1 - t0) / 2 + (np.sin(2 * W * t1) - np.sin(2 * W * t0)) / (4 * W))
    across = vs * (np.sin(W * t1) ** 2 - np.sin(W * t0) ** 2) / (2 * W)
    assert f.value == pytest.approx(np.hypot(along, across), rel=1e-6)


def test_the_same_swing_with_both_ends_of_the_edge_loaded_creeps():
    """Both ends of the edge carry load with their friction inside the cone: static friction
    holds the far end too, so the swing is creep, read at the edge's middle (H from the pivot):
    the chord of its arc over the whole rest (a steady swing from the first sample),
    2 H sin(W 2 s / 2) = 4.998 mm."""
    pen, creep = creep_of_top(swinging_on_an_edge(drift=0.0, far_end_loaded=True))
    (f,) = [f for f in creep if f.bodies == [1]]
    chord = 2 * H * np.sin(W * DURATION / 2)
    assert f.value == pytest.approx(chord, rel=1e-6)


def test_two_rows_at_the_pivot_are_one_loaded_point():
    """The swing with its weight on two rows 2 nm apart at the pivot end: one loaded point, so the
    edge still turns about it (the pivot's third-order remainder, as above: below 2e-10 m); read
    as two loaded points, the swing would be the 4.998 mm chord of the test above."""
    pen, creep = creep_of_top(swinging_on_an_edge(drift=0.0, pivot_twice=True))
    assert not creep, [f.message for f in creep]
    assert pen.stats["creep_max_m"] < 2e-10
