"""The compiled row passes of the analyzers equal the numpy definitions they replaced, bit for bit.

`rblog check` reports must not change when a numpy pass is compiled (issue 18's speed work), so each
kernel keeps the numpy arithmetic order; these compare them on random poses, exactly (the ground
witness, redefined since with a feature band, against its numpy definition to round-off).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from rblog.analyze import geometry
from rblog.analyze import tolerances as T
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE
from test_analyze import make_model


def _ground_witness_numpy(pos, rot, h, n, band):
    """The box's touching feature along -n (rblog.analyze.geometry's definition, in numpy): axis j
    free when 2 h_j |n.A_j| <= band, else at sign(-n.A_j) h_j; its centre lowered along -n to the
    box's lowest point."""
    proj = np.einsum("pij,i->pj", rot, -n)  # -n . A_j
    free = 2 * h * np.abs(proj) <= band
    every = free.all(axis=1)  # a box thinner than the band: its axis most along n stays fixed
    free[every, np.argmax(np.abs(proj[every]), axis=1)] = False
    s = np.where(free, 0.0, np.sign(proj) * h)
    drop = np.where(free, h * np.abs(proj), 0.0).sum(axis=1)
    return pos + np.einsum("pij,pj->pi", rot, s) - drop[:, None] * n


def test_ground_witness_kernel_equals_the_numpy_definition():
    rng = np.random.default_rng(7)
    bodies = [dict(shape="box", size=tuple(rng.uniform(0.05, 0.4, 3)), mass=1.0) for _ in range(6)]
    bodies += [dict(shape="sphere", size=0.1 + 0.05 * j, mass=1.0) for j in range(3)]
    model = make_model(bodies, ground=True)
    p = 5000
    body = rng.integers(0, len(bodies), p)
    pos = rng.normal(size=(p, 3))
    rot = Rotation.random(p, random_state=3).as_matrix()
    rot[:50] = np.eye(3)  # face-down boxes: axes perpendicular to the normal give their middle
    # boxes tilted across the band's edge: 2 h |sin a| on either side of WITNESS_BAND_M
    tilt = rng.uniform(0.0, 4.0, 200) * T.WITNESS_BAND_M / 0.8
    rot[50:250] = Rotation.from_rotvec(tilt[:, None] * [1.0, 0.0, 0.0]).as_matrix()
    n = np.asarray(model.ground_normal, float)
    size = np.asarray(model.body_size, float)[body]
    box = _ground_witness_numpy(pos, rot, size, n, T.WITNESS_BAND_M)
    sphere = pos - size[:, :1] * n
    expect = np.where((model.body_shape[body] == SHAPE_SPHERE)[:, None], sphere, box)
    assert (model.body_shape[body] == SHAPE_BOX).any()
    # the compiled pass sums in another order: round-off of |x| ~ 4 m (measured 8.9e-16 m)
    np.testing.assert_allclose(geometry.plane_witness(model, body, pos, rot), expect, rtol=0,
                               atol=4e-15)
    # indexed form: poses looked up in (T, N, ...) arrays
    got = geometry.plane_witness_at(model, np.zeros(p, np.int64), np.arange(p), body, pos[None],
                                    rot[None])
    np.testing.assert_array_equal(got, geometry.plane_witness(model, body, pos, rot))
