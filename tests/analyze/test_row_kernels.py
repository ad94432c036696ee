"""The compiled row passes of the analyzers equal the numpy definitions they replaced, bit for bit.

`rblog check` reports must not change when a numpy pass is compiled (issue 18's speed work), so each
kernel keeps the numpy arithmetic order; these compare them on random poses, exactly.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from rblog.analyze import geometry
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE
from test_analyze import make_model


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
    n = np.asarray(model.ground_normal, float)
    size = np.asarray(model.body_size, float)[body]
    box = geometry._box_witness(pos, rot, size, -np.broadcast_to(n, pos.shape))
    sphere = pos - size[:, :1] * n
    expect = np.where((model.body_shape[body] == SHAPE_SPHERE)[:, None], sphere, box)
    assert (model.body_shape[body] == SHAPE_BOX).any()
    np.testing.assert_array_equal(geometry.plane_witness(model, body, pos, rot), expect)
    # indexed form: poses looked up in (T, N, ...) arrays
    got = geometry.plane_witness_at(model, np.zeros(p, np.int64), np.arange(p), body, pos[None],
                                    rot[None])
    np.testing.assert_array_equal(got, expect)
