"""The engine's penetration figure (its own narrowphase, rblog.engine.contact.measure) against the
analyzers' independent geometry (rblog.analyze.geometry: separating-axis box-box, closest point
sphere-box, support function box-plane) on random penetrating poses. A bug in either shows up as a
disagreement; before this test the engine was only ever measured with its own code."""

from __future__ import annotations

import numpy as np
import pytest

from rblog.analyze import geometry as geo
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE
from rblog.engine import integrators as rot
from rblog.engine.contact import ContactParams, ContactWorld
from rblog.engine.contact.measure import separations
from rblog.engine.constants import AXIS_ABS_TOL, EDGE_REL_TOL, FACE_REL_TOL
from rblog.study.scenes import make_model

N_POSES = 200
#: penetration depths drawn from [DEPTH_MIN, DEPTH_MAX] (m): the range the solver lives in
DEPTH_MIN, DEPTH_MAX = 1e-5, 5e-3
#: agreement wanted (m) where both pick the same axis: measured <= 3.2e-16 (99 % of box-box
#: poses), 0 (sphere-box), 1.1e-16 (box-plane)
AGREE_M = 1e-12


def _rand_rot(rng, k):
    q = rng.normal(size=(k, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return geo.quat_to_matrix(q)


def _place(sep_fn, xa, direction, target, lo=0.0, hi=3.0):
    """Distance s along ``direction`` from xa such that sep_fn(xa + s d) = target (bisection;
    separation grows with s for convex shapes moved apart along a fixed direction)."""
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if sep_fn(xa + mid * direction) < target:
            lo = mid
        else:
            hi = mid
    return xa + 0.5 * (lo + hi) * direction


def _engine_sep(model, position, rotation):
    world = ContactWorld(model, ContactParams(), rot.METHOD_SPLITTING, rot.ORTHO_NORMALIZE)
    s = separations(world, position, rotation)
    return float(s.min()) if len(s) else np.inf


@pytest.mark.parametrize("pair", ["box-box", "sphere-box"])
def test_body_pairs_agree(pair):
    rng = np.random.default_rng(19)
    errs = []
    for _ in range(N_POSES):
        ha = rng.uniform(0.05, 0.5, 3)
        ra, rb = _rand_rot(rng, 2)
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        depth = rng.uniform(DEPTH_MIN, DEPTH_MAX)
        xa = np.zeros(3)
        if pair == "box-box":
            hb = rng.uniform(0.05, 0.5, 3)

            def sep(xb):
                return geo.box_box(xa[None], ra[None], ha[None], xb[None], rb[None], hb[None])[0][0]

            xb = _place(sep, xa, d, -depth)
            model = make_model([SHAPE_BOX, SHAPE_BOX], [ha, hb], [1.0, 1.0], ground=False)
            rots = np.stack([ra, rb])
        else:
            r = rng.uniform(0.05, 0.5)

            def sep(xs):
                return geo.sphere_box(xs[None], np.array([r]), xa[None], ra[None], ha[None])[0][0]

            xb = _place(sep, xa, d, -depth)
            model = make_model([SHAPE_BOX, SHAPE_SPHERE], [ha, r], [1.0, 1.0], ground=False)
            rots = np.stack([ra, np.eye(3)])
        truth = sep(xb)
        eng = _engine_sep(model, np.stack([xa, xb]), rots)
        errs.append((abs(eng - truth), truth, eng))
    e = np.array(errs)
    err, truth, eng = e[:, 0], e[:, 1], e[:, 2]
    if pair == "sphere-box":
        assert err.max() <= AGREE_M, err.max()  # measured 0
        return
    # box-box: the engine keeps a face axis unless another axis is better by a margin
    # (Gregorius' axis preference, constants.EDGE_REL_TOL / FACE_REL_TOL), so it may report a
    # slightly deeper (never shallower) penetration than the exact separating-axis minimum
    band = (1.0 - min(EDGE_REL_TOL, FACE_REL_TOL)) * np.abs(truth) + AXIS_ABS_TOL
    assert np.all(eng <= truth + AGREE_M), "the engine reports less penetration than there is"
    assert np.all(eng >= truth - band), "the engine is deeper than its axis preference allows"
    # measured: 199 of 200 poses agree to 3.2e-16 m; one differs by 2.6e-7 m (7e-5 of its
    # depth, inside the preference band)
    assert np.mean(err <= AGREE_M) >= 0.97, np.sort(err)[-5:]


def test_box_plane_agrees():
    rng = np.random.default_rng(20)
    worst = 0.0
    for _ in range(N_POSES):
        h = rng.uniform(0.05, 0.5, 3)
        r = _rand_rot(rng, 1)[0]
        model = make_model([SHAPE_BOX], [h], [1.0], ground=True)
        support = float(np.sum(h * np.abs(r[2, :])))  # lowest point below the centre along z
        depth = rng.uniform(DEPTH_MIN, DEPTH_MAX)
        x = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), support - depth])
        truth = geo.plane_separation(model, x[None, None], r[None, None])[0][0, 0]
        assert truth == pytest.approx(-depth, abs=1e-12)
        eng = _engine_sep(model, x[None], r[None])
        worst = max(worst, abs(eng - truth))
    assert worst <= AGREE_M, worst  # measured 1.1e-16
