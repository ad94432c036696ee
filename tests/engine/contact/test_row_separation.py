"""The contact rows' ``separation`` is the gap at the end-of-step poses (docs/log-format.md:
"rblog: after the step"), the project stage's pushes included.

Independent computation: boxes set down level, whose contact points are the bottom corners of
the upper box, so that the gap at a logged pose is a corner's height: above the ground plane,
or above the lower box's top face (along that face's normal). The project stage tilts the boxes
by a few microradians while it pushes their corners out one at a time, so the corners are taken
from the logged rotations. The scenes start 3 mm deep, far beyond the project stage's
target depth (ContactParams.projection_depth, 0.2 mm), so the first step's rows are where a
gap taken from the solver's velocities alone (s + h (v_n + v_n pseudo), before the project
stage moved the bodies) read ~ -3 mm while the poses are ~0.2 mm deep."""

from __future__ import annotations

import numpy as np
import pytest

import rblog
from rblog.engine.constants import ContactParams

DEPTH0 = 3e-3  # m, the start overlap
HALF = 0.1     # m, the cubes' half extent


def _scene(bodies: str) -> str:
    return f"""
[sim]
dt = 1e-3
duration = 0.02
log_every = 1

[ground]

{bodies}
"""


def _box(name, z, half=HALF):
    return f"""[[body]]
name = "{name}"
shape = "box"
half_extents = [{half}, {half}, {half}]
mass = 1.0
position = [0.0, 0.0, {z!r}]
"""


CORNERS = np.array([[sx, sy, -1.0] for sx in (-1, 1) for sy in (-1, 1)])  # bottom, body frame


def _rows_and_gaps(scene_text, halves):
    """The rows of a run of ``scene_text`` and, per row, the gap at its logged poses: the height
    of the upper body's bottom corner under the row's point over the ground (body_b = -1) or
    over the lower body's top face."""
    traj, _ = rblog.simulate(rblog.parse_scene(scene_text))
    c = traj.contacts
    k = np.searchsorted(np.asarray(traj.step), c.step)
    assert np.array_equal(np.asarray(traj.step)[k], c.step)  # every row's step was sampled
    x, rot = np.asarray(traj.position), np.asarray(traj.rotation)
    gaps = []
    for kk, a, b, p in zip(k, c.body_a, c.body_b, c.point):
        up, low = (a, b) if b < 0 or x[kk, a, 2] > x[kk, b, 2] else (b, a)
        corners = x[kk, up] + (CORNERS * halves[up]) @ rot[kk, up].T
        corner = corners[np.argmin(np.linalg.norm(corners[:, :2] - p[:2], axis=1))]
        if low < 0:
            gaps.append(corner[2])
        else:
            n = rot[kk, low][:, 2]  # the lower box's top face normal
            gaps.append(n @ (corner - x[kk, low]) - halves[low])
    return c, np.array(gaps)


def test_ground_rows_give_the_gap_of_the_logged_pose():
    c, gap = _rows_and_gaps(_scene(_box("cube", HALF - DEPTH0)), [HALF])
    assert (c.body_b == -1).all() and len(c.step) >= 4
    first = c.step == c.step.min()
    # the project stage pushed the cube up by ~2.8 mm in the first step
    assert gap[first].min() > -2 * ContactParams().projection_depth
    # measured 2026-11-28: |row - corner height| <= 4.5e-14 m (round-off of the corner's transport)
    np.testing.assert_allclose(c.separation, gap, rtol=0, atol=2e-13)


@pytest.mark.parametrize("depth", [DEPTH0, 0.0])
def test_rows_between_stacked_boxes_give_the_gap_of_the_logged_poses(depth):
    small = HALF / 2
    bodies = _box("lower", HALF) + _box("upper", 2 * HALF + small - depth, small)
    c, gap = _rows_and_gaps(_scene(bodies), [HALF, small])
    assert (c.body_b >= 0).any()
    # measured 2026-11-28: |row - corner height| <= 3.6e-9 m at 3 mm deep (the rows keep the
    # step's normal: the lower box's ~1e-6 rad turn times the 3 mm between the anchors), 4e-17 m
    # from a touching start
    np.testing.assert_allclose(c.separation, gap, rtol=0, atol=1e-8)
