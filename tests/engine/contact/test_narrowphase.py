"""Narrowphase: every collider against hand-computed cases (Box2D's test_collision.c style).

Conventions checked throughout: the normal points from b into a, separation < 0 is penetration,
points sit midway between the two surfaces.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rblog.engine.contact.narrowphase import (
    GEOM_BOX, GEOM_PLANE, GEOM_SPHERE, NARROWPHASE_TABLE, UnsupportedShapePair, collide_np,
)
from rblog.engine.rotation import axis_angle_to_quat_np, quat_to_matrix_np

S2 = math.sqrt(2.0)


def rot(axis, angle):
    return quat_to_matrix_np(axis_angle_to_quat_np(axis, angle))


def test_table_covers_every_pair_but_plane_plane():
    from rblog.engine.contact.narrowphase import GEOM_CAPSULE, GEOM_CYLINDER

    keys = set(NARROWPHASE_TABLE)
    every = (GEOM_SPHERE, GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_PLANE)
    for a in every:
        for b in every:
            key = (min(a, b), max(a, b))
            assert (key in keys) == (key != (GEOM_PLANE, GEOM_PLANE))
    with pytest.raises(UnsupportedShapePair):
        collide_np(GEOM_PLANE, None, None, [0], GEOM_PLANE)


# ---- sphere ----------------------------------------------------------------------------------

def test_sphere_plane():
    n, p, s, _ = collide_np(GEOM_SPHERE, [1, 2, 0.4], None, [0.5], GEOM_PLANE)
    assert np.allclose(n, [0, 0, 1]) and np.allclose(s, [-0.1])
    assert np.allclose(p, [[1, 2, -0.05]])
    # tilted plane through the origin, normal (0, 1, 1)/sqrt 2
    c = np.array([0, 1, 1]) / S2 * 0.4
    n, p, s, _ = collide_np(GEOM_SPHERE, c, None, [0.5], GEOM_PLANE,
                            plane_normal=np.array([0, 1, 1]) / S2)
    assert np.allclose(n, [0, 1 / S2, 1 / S2]) and np.allclose(s, [-0.1])
    assert np.allclose(p, [c - n * 0.45])
    # beyond the speculative distance: nothing; within it: a speculative point
    assert len(collide_np(GEOM_SPHERE, [0, 0, 0.7], None, [0.5], GEOM_PLANE, spec=0.1)[2]) == 0
    assert np.allclose(collide_np(GEOM_SPHERE, [0, 0, 0.55], None, [0.5], GEOM_PLANE,
                                  spec=0.1)[2], [0.05])


def test_sphere_sphere():
    n, p, s, _ = collide_np(GEOM_SPHERE, [0, 0, 0], None, [1.0], GEOM_SPHERE, [1.5, 0, 0], None, [1.0])
    assert np.allclose(n, [-1, 0, 0])  # from b (at +x) into a
    assert np.allclose(s, [-0.5]) and np.allclose(p, [[0.75, 0, 0]])
    assert len(collide_np(GEOM_SPHERE, [0, 0, 0], None, [1.0], GEOM_SPHERE, [3, 0, 0], None, [1.0], spec=0.5)[2]) == 0


@pytest.mark.parametrize("centre, normal, sep, point", [
    ([0, 0, 1.4], [0, 0, 1], -0.1, [0, 0, 0.95]),  # face
    ([1.3, 0, 1.3], [1 / S2, 0, 1 / S2], 0.3 * S2 - 0.5, None),  # edge
    ([1.2, 1.2, 1.2], np.ones(3) / math.sqrt(3), 0.2 * math.sqrt(3) - 0.5, None),  # corner
    ([0, 0, 0.8], [0, 0, 1], -0.2 - 0.5, [0, 0, 1 - 0.35]),  # centre inside: nearest face
])
def test_sphere_box(centre, normal, sep, point):
    n, p, s, _ = collide_np(GEOM_SPHERE, centre, None, [0.5], GEOM_BOX, [0, 0, 0], None, [1, 1, 1])
    assert np.allclose(n, normal) and np.allclose(s, [sep])
    if point is not None:
        assert np.allclose(p, [point])
    # the swapped pair (box first) has the opposite normal, same points
    n2, p2, s2, _ = collide_np(GEOM_BOX, [0, 0, 0], None, [1, 1, 1], GEOM_SPHERE, centre, None, [0.5])
    assert np.allclose(n2, -n) and np.allclose(p2, p) and np.allclose(s2, s)


def test_sphere_box_rotated_box():
    r = rot([0, 0, 1], math.pi / 4)
    # box half extent 1 rotated 45 deg about z: its +x face now faces (1, 1, 0)/sqrt 2
    c = np.array([1, 1, 0]) / S2 * 1.3
    n, p, s, _ = collide_np(GEOM_SPHERE, c, None, [0.5], GEOM_BOX, [0, 0, 0], r, [1, 1, 1])
    assert np.allclose(n, [1 / S2, 1 / S2, 0]) and np.allclose(s, [-0.2])


# ---- box vs plane ----------------------------------------------------------------------------

def test_box_plane_flat_and_on_edge():
    n, p, s, ids = collide_np(GEOM_BOX, [0, 0, 2.9], None, [1, 2, 3], GEOM_PLANE)
    assert np.allclose(n, [0, 0, 1]) and np.allclose(s, -0.1) and len(s) == 4
    assert np.allclose(sorted(map(tuple, np.round(p, 12))),
                       sorted([(x, y, -0.05) for x in (-1, 1) for y in (-2, 2)]))
    assert len(set(ids)) == 4
    # a unit cube on its edge (45 deg about x): two points at the bottom edge
    n, p, s, _ = collide_np(GEOM_BOX, [0, 0, S2 - 0.01], rot([1, 0, 0], math.pi / 4), [1, 1, 1], GEOM_PLANE)
    assert len(s) == 2 and np.allclose(s, -0.01) and np.allclose(p[:, 1], 0.0)
    # a thin plate within the speculative distance on all 8 corners keeps the 4 lowest
    n, p, s, _ = collide_np(GEOM_BOX, [0, 0, 0.011], None, [1, 1, 0.01], GEOM_PLANE, spec=0.1)
    assert len(s) == 4 and np.allclose(s, 0.001)


# ---- box vs box ------------------------------------------------------------------------------

def test_box_box_face_stack():
    n, p, s, ids = collide_np(GEOM_BOX, [0, 0, 0], None, [1, 1, 1], GEOM_BOX, [0, 0, 1.9], None, [1, 1, 1])
    assert np.allclose(n, [0, 0, -1])  # from b (above) into a
    assert len(s) == 4 and np.allclose(s, -0.1)
    assert np.allclose(sorted(map(tuple, np.round(p, 12))),
                       sorted([(x, y, 0.95) for x in (-1, 1) for y in (-1, 1)]))
    assert len(set(ids)) == 4


def test_box_box_face_stack_small_gap_keeps_four_points():
    """Regression: a small gap must not turn the contact into a single edge-edge point."""
    for z in (2.0001, 2.005):
        n, p, s, _ = collide_np(GEOM_BOX, [0, 0, 0], None, [1, 1, 1], GEOM_BOX, [0, 0, z], None, [1, 1, 1], spec=0.01)
        assert len(s) == 4 and np.allclose(s, z - 2.0) and np.allclose(n, [0, 0, -1])


def test_box_box_twisted_face_clips_octagon_to_four():
    """B turned 45 deg about z: the clipped incident face is an octagon, reduced to 4 points."""
    n, p, s, _ = collide_np(GEOM_BOX, [0, 0, 0], None, [1, 1, 1], GEOM_BOX, [0, 0, 1.9],
                            rot([0, 0, 1], math.pi / 4), [1, 1, 1])
    assert np.allclose(n, [0, 0, -1]) and len(s) == 4 and np.allclose(s, -0.1)
    assert np.all(np.abs(p[:, :2]) <= 1 + 1e-12)
    # the 4 kept points span the octagon: the quad's area is most of the octagon's
    q = p[:, :2] - p[:, :2].mean(0)
    order = np.argsort(np.arctan2(q[:, 1], q[:, 0]))
    x, y = q[order, 0], q[order, 1]
    area = 0.5 * abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1)))
    assert area > 0.7 * 8 * (S2 - 1)  # octagon area = 8 (sqrt 2 - 1)


def test_box_box_crossed_edges():
    """A's top edge along y (A turned 45 deg about y) under B's bottom edge along x (B turned
    45 deg about x): one point where the edges cross, normal along z."""
    za = 0.0
    zb = 2 * S2 - 0.1
    n, p, s, ids = collide_np(GEOM_BOX, [0, 0, za], rot([0, 1, 0], math.pi / 4), [1, 1, 1],
                              GEOM_BOX, [0, 0, zb], rot([1, 0, 0], math.pi / 4), [1, 1, 1])
    assert len(s) == 1 and np.allclose(s, [-0.1])
    assert np.allclose(n, [0, 0, -1])
    assert np.allclose(p, [[0, 0, S2 - 0.05]])
    assert ids[0] >= 100000  # an edge-edge feature


def test_box_box_separated_and_speculative():
    args = (GEOM_BOX, [0, 0, 0], None, [1, 1, 1], GEOM_BOX)
    assert len(collide_np(*args, [0, 0, 2.5], None, [1, 1, 1], spec=0.1)[2]) == 0
    n, p, s, _ = collide_np(*args, [0, 0, 2.05], None, [1, 1, 1], spec=0.1)
    assert len(s) == 4 and np.allclose(s, 0.05)


def test_box_box_swap_negates_normal():
    ra, rb = rot([1, 2, 3], 0.3), rot([-1, 0, 2], 0.7)
    a = ([0.1, 0, 0], ra, [1, 0.5, 0.7])
    b = ([0.3, 0.2, 1.4], rb, [0.6, 0.8, 0.5])
    n1, p1, s1, _ = collide_np(GEOM_BOX, *a, GEOM_BOX, *b)
    n2, p2, s2, _ = collide_np(GEOM_BOX, *b, GEOM_BOX, *a)
    assert len(s1) > 0 and np.allclose(n1, -n2, atol=1e-12)
    assert np.isclose(s1.min(), s2.min(), atol=1e-12)


@pytest.mark.parametrize("theta", [0.027, 0.2])
def test_box_box_reduction_keeps_every_touching_end_of_a_level_edge(theta):
    """B turned 45 deg about z (its face over A's top clips to an octagon) and tilted by theta
    about its own x axis: its lowest edge is level, d deep, and crosses A's top face between
    the points (1, 1 - sqrt2 c) and (sqrt2 c - 1, -1), c = cos(theta) - sin(theta) (the edge
    x -> Rz(45) (x, -c) clipped to |x|, |y| <= 1). The rest of the octagon is up to
    2 sin(theta) higher (5.4 cm at theta = 0.027), within the speculative distance. Both ends of
    the touching edge must be in the manifold: reduced by area alone, the far speculative
    vertices took three of the four slots and the box turned about one point (the 500-box pile:
    a box whose edge lay 50 um deep along 78 mm of another's face kept one contact point)."""
    d = 5e-5
    c = math.cos(theta) - math.sin(theta)
    zb = 1.0 - d + math.sin(theta) + math.cos(theta)  # lowest edge at z = 1 - d
    rb = rot([0, 0, 1], math.pi / 4) @ rot([1, 0, 0], theta)
    n, p, s, _ = collide_np(GEOM_BOX, [0, 0, 0], None, [1, 1, 1], GEOM_BOX, [0, 0, zb], rb,
                            [1, 1, 1], spec=0.5)
    assert np.allclose(n, [0, 0, -1]) and len(s) == 4
    touching = np.isclose(s, -d, rtol=0, atol=1e-12)
    assert touching.sum() == 2, s
    want = np.array([[1.0, 1.0 - S2 * c, 1.0 - d / 2], [S2 * c - 1.0, -1.0, 1.0 - d / 2]])
    got = p[touching][np.argsort(-p[touching][:, 0])]
    assert np.allclose(got, want, rtol=0, atol=1e-12), got
    assert np.all(s[~touching] > 1e-3)  # the other two are the speculative far side
