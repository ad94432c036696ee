"""The audit's geometry of every shape pair (rblog.analyze.shapes) against an independent
implementation (tests/analyze/shape_reference.py: coal for the pairs it computes exactly,
MuJoCo's mj_geomDistance for those with a cylinder or an ellipsoid), over random poses spread
from deep overlap to apart, and the same poses moved to touching.

Measured worst errors (|sep - reference|, m) over 10,000 poses + the same 10,000 moved to
touching, per pair (``pytest -m slow tests/analyze/test_geometry_shapes.py``, seed 11); the
default run checks 150 + 150 per pair (seed 7) against the same bounds:

* Exact pairs against coal (every plane pair, sphere/capsule/box/mesh among themselves; closed
  forms, and GJK/EPA on polytopes, which end on exact faces): 1e-9 m asserted; measured
  <= 9.1e-15 m (box-mesh), <= 1.1e-15 m for the others; normals <= 1.4e-13. coal itself failed
  on 1 of 20,000 box-box poses (-DBL_MAX) and stalled on another (2.0e-7 m where the audit,
  MuJoCo and a vertex-to-box check give 0: MuJoCo's second opinion is taken there).
* Pairs with a cylinder or an ellipsoid against MuJoCo (ccd_tolerance 1e-12; the audit stops
  at GJK_TOL_M = EPA_TOL_M = 1e-10 m): away from touching 1e-9 m asserted for >= 99.9% of poses
  and 1e-6 m for all, measured <= 8.0e-10 m except ellipsoid-cylinder 5.8e-9 m and
  sphere-ellipsoid 2.9e-7 m (there MuJoCo is the one off: the exact root-solve agrees with the
  audit to 7e-11 m, test_deep_sphere_in_curved_exact); within touching 1e-5 m asserted,
  measured (2,000 poses per pair) up to 6.1e-6 m where MuJoCo is the one further from 0
  (cylinder-mesh, cylinder-box: a flat cap on a face), and where the audit is: <= 1e-10 m
  for sphere, capsule and ellipsoid-ellipsoid pairs, <= 3.3e-7 m for ellipsoids and cylinders
  against flat faces (its GJK stalls there and EPA cannot always settle it).
* Witnesses: pa - pb = sep n to 1e-12 m for every pair.
  1 of 20,000 sphere-ellipsoid poses hit CONVEX_MAX_ITER (reported not converged). Normals
  are only as good as the square root of the distance tolerance (the distance is stationary
  in the direction): 1e-3 asserted on apart poses, measured <= 2.7e-4 (ellipsoid-cylinder),
  <= 6e-5 for the others.
"""

from __future__ import annotations

import numpy as np
import pytest

from shape_reference import PAIRS, compare, mujoco_second_opinion, reference_of

from rblog.analyze import shapes

# (|sep - ref| bound, |normal - ref normal| bound on poses apart by > 1 mm)
EXACT = (1e-9, 1e-9)
CURVED = (1e-9, 1e-3)


def _check(ta, tb, p, seed):
    r = compare(ta, tb, p, seed)
    o = r["ours"]
    tol_sep, tol_n = CURVED if r["ref"] == "mujoco" else EXACT
    # EPA on a curved core deep inside a nearly round one (the nearest boundary almost as near
    # in every direction) can need more than CONVEX_MAX_ITER iterations: reported "not
    # converged" with its lower bound of the depth; rare, and off by little
    nc = o["status"] != shapes.OK
    assert (o["status"][nc] == shapes.NOT_CONVERGED).all()
    assert nc.mean() <= 2e-3 and (r["ref"] == "mujoco" or not nc.any()), nc.sum()
    assert np.abs(o["sep"] - r["ref_sep"])[nc].max(initial=0.0) <= 1e-3
    # the reference's own failures (coal returns -DBL_MAX: 1 of 20,000 box-box poses, a touching
    # one) are left out, and must stay rare
    valid = (np.abs(r["ref_sep"]) < 1e300) & ~nc
    assert valid.mean() >= 0.999
    err = np.where(valid, np.abs(o["sep"] - r["ref_sep"]), 0.0)
    # near touching a curved pair's GJK stalls on rounding in both
    # implementations: the audit and MuJoCo differ there by up to 1.8e-7 m where the audit is
    # the one further from 0, and by 6.5e-6 m where MuJoCo is (a cylinder's flat face on a mesh
    # face: the audit 4.1e-10 m, MuJoCo 6.5e-6 m)
    near = (np.arange(2 * p) >= p) & (r["ref"] == "mujoco")  # the poses moved to touching
    away = np.where(near, 0.0, err)
    k = int(np.argmax(away))
    if r["ref"] == "coal":
        # coal's GJK stalls in a few touching box-box poses (2.0e-7 m where the audit, MuJoCo
        # and a vertex-to-box check give 0: 1 of 20,000): those get MuJoCo's second opinion
        off = np.nonzero(away > tol_sep)[0]
        assert len(off) <= 1e-3 * len(away) and (not len(off) or "mesh" not in (ta, tb))
        if len(off):
            second = mujoco_second_opinion(ta, tb, r["cases"], off)
            assert np.abs(o["sep"][off] - second).max() <= tol_sep, (ta, tb, off)
            away[off] = 0.0
            k = int(np.argmax(away))
        assert err[k] <= tol_sep, (ta, tb, k, o["sep"][k], r["ref_sep"][k])
    else:
        # MuJoCo's EPA stops short in a few deep poses of nearly round shapes (a sphere 0.44 m
        # deep in a near-spherical ellipsoid: MuJoCo 2.9e-7 m off the exact root-solve, the
        # audit 7e-11 m; test_deep_sphere_in_curved_exact checks those cases exactly)
        assert (away > tol_sep).mean() <= 1e-3, (ta, tb, k, o["sep"][k], r["ref_sep"][k])
        assert err[k] <= 1e-6, (ta, tb, k, o["sep"][k], r["ref_sep"][k])
    assert err[near].max(initial=0.0) <= 1e-5, (ta, tb)
    # the spread reaches every regime: deep (> 1 cm), touching (< 1e-9 m) and apart (> 1 cm)
    assert (r["ref_sep"] < -1e-2).sum() > p // 10
    assert (r["ref_sep"] > 1e-2).sum() > p // 10
    assert (np.abs(r["ref_sep"]) < 1e-6).sum() >= 0.9 * p
    apart = (r["ref_sep"] > 1e-3) & valid
    nerr = np.linalg.norm(o["normal"] - r["ref_normal"], axis=1)[apart]
    assert nerr.max() <= tol_n, (ta, tb, nerr.max())
    # witnesses: pa - pb = sep n, and the normal and depth of overlapping poses are those of the
    # shortest separating translation: a moved by |sep| + 1e-6 along n is 1e-6 m apart
    wit = np.abs(o["pa"] - o["pb"] - o["sep"][:, None] * o["normal"]).max(axis=1)[valid]
    assert wit.max() <= 1e-12, wit.max()
    deep = (r["ref_sep"] < -1e-3) & valid
    xa = r["xa"] + np.where(deep, 1e-6 - o["sep"], 0.0)[:, None] * o["normal"]
    moved, _ = r["again"](xa, r["xb"])
    assert np.abs(moved[deep] - 1e-6).max() <= (1e-9 if r["ref"] == "coal" else 1e-7), (ta, tb)
    return away.max(), nerr.max() if len(nerr) else 0.0, int(nc.sum()), int((~valid).sum())


@pytest.mark.parametrize("ta,tb", PAIRS, ids=[f"{a}-{b}" for a, b in PAIRS])
def test_pair_matches_reference(ta, tb):
    _check(ta, tb, 150, 7)


@pytest.mark.slow
@pytest.mark.parametrize("ta,tb", PAIRS, ids=[f"{a}-{b}" for a, b in PAIRS])
def test_pair_matches_reference_10000(ta, tb):
    _check(ta, tb, 10_000, 11)


def _point_in_ellipsoid_depth(c, a):
    """Distance from c (inside) to the boundary of the ellipsoid of semi-axes a: the closest
    point y_i = a_i^2 c_i / (a_i^2 + t) with t the root of sum (a_i c_i / (a_i^2 + t))^2 = 1 in
    (-min a_i^2, 0] (Eberly, Distance from a point to an ellipse, an ellipsoid)."""
    from scipy.optimize import brentq

    f = lambda t: np.sum((a * c / (a * a + t)) ** 2) - 1
    t = brentq(f, -np.min(a * a) * (1 - 1e-15), 0.0, xtol=1e-300, rtol=1e-15, maxiter=500)
    return np.linalg.norm(a * a * c / (a * a + t) - c)


@pytest.mark.parametrize("tb", ["ellipsoid", "cylinder"])
def test_deep_sphere_in_curved_exact(tb):
    """A sphere whose centre is inside an ellipsoid or a cylinder: depth = the centre's distance
    to the boundary (closed form for the cylinder, min(R - rho, h - |z|); a 1-D root for the
    ellipsoid) + the radius. Measured worst error over 2,000 poses: 1.8e-10 m (ellipsoid),
    8.4e-11 m (cylinder), all converged (the EPA tolerance is 1e-10 m)."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(5)
    p = 2000
    sb = rng.uniform(0.05, 0.3, (p, 3))
    if tb == "cylinder":
        sb[:, 2] = 0
    rb = Rotation.random(p, random_state=6).as_matrix()
    xb = rng.normal(scale=0.2, size=(p, 3))
    u = rng.uniform(-0.95, 0.95, (p, 3))
    if tb == "cylinder":  # a point inside: radius fraction, angle, height fraction
        rho, phi = sb[:, 0] * np.sqrt(np.abs(u[:, 0])), np.pi * u[:, 1]
        local = np.stack([rho * np.cos(phi), rho * np.sin(phi), sb[:, 1] * u[:, 2]], 1)
        depth = np.minimum(sb[:, 0] - rho, sb[:, 1] - np.abs(local[:, 2]))
    else:
        d = u / np.linalg.norm(u, axis=1, keepdims=True) * rng.uniform(0, 0.95, (p, 1)) ** 2
        local = d * sb
        depth = np.array([_point_in_ellipsoid_depth(c, a) for c, a in zip(local, sb)])
    xa = xb + np.einsum("pij,pj->pi", rb, local)
    ra = rng.uniform(0.01, 0.2, p)
    sa = np.stack([ra, 0 * ra, 0 * ra], 1)
    geoms = shapes.Geoms.build(["sphere"] * p + [tb] * p, np.concatenate([sa, sb]))
    pos = np.concatenate([xa, xb])[None]
    rot = np.concatenate([np.broadcast_to(np.eye(3), (p, 3, 3)), rb])[None]
    o = shapes.pair_distance(geoms, pos, rot, np.zeros(p, np.int64), np.arange(p),
                             np.arange(p, 2 * p))
    ok = o["status"] == shapes.OK
    assert ok.mean() >= 0.995
    assert np.abs(o["sep"] - (-depth - ra))[ok].max() <= 1e-9


def test_every_pair_has_a_reference():
    assert len(PAIRS) == 27
    assert {reference_of(a, b) for a, b in PAIRS} == {"coal", "mujoco"}


def test_plane_plane_is_unsupported():
    r = shapes.distance("plane", [[0, 0, 0]], np.eye(3), 0, "plane", [[0, 0, 1]], np.eye(3), 0)
    assert r["status"][0] == shapes.UNSUPPORTED and np.isnan(r["sep"][0])


def test_broadphase_finds_every_close_pair():
    """A pile of 300 mixed geoms on a floor: the broadphase's candidates include every pair
    within the pad by brute force over all pairs (and far fewer than all pairs)."""
    rng = np.random.default_rng(3)
    g = 300
    types = rng.choice(["sphere", "capsule", "ellipsoid", "cylinder", "box"], g)
    sizes = np.array([rng.uniform(0.02, 0.08, 3) for _ in range(g)])
    types = np.append(types, "plane")
    sizes = np.vstack([sizes, np.zeros(3)])
    geoms = shapes.Geoms.build(types, sizes, body=np.append(np.arange(g), -1))
    t_n = 3
    pos = rng.uniform([-1, -1, 0], [1, 1, 0.5], (t_n, g + 1, 3))
    pos[:, g] = 0
    from scipy.spatial.transform import Rotation
    rot = Rotation.random(t_n * (g + 1), random_state=4).as_matrix().reshape(t_n, g + 1, 3, 3)
    rot[:, g] = np.eye(3)
    pad = 0.01
    k, i, j = shapes.broadphase(geoms, pos, rot, pad)
    ii, jj = np.triu_indices(g + 1, 1)
    kk = np.repeat(np.arange(t_n), len(ii))
    allp = shapes.pair_distance(geoms, pos, rot, kk, np.tile(ii, t_n), np.tile(jj, t_n),
                                with_points=False)
    close = {(a, b, c) for a, b, c, s in zip(kk, np.tile(ii, t_n), np.tile(jj, t_n), allp["sep"])
             if s <= pad}
    found = set(zip(k.tolist(), i.tolist(), j.tolist()))
    assert close <= found
    assert len(found) < 0.05 * len(kk)
