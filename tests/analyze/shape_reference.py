"""An independent reference for the audit's geometry: coal (the maintained successor of FCL), and
random poses of every pair of shapes, deep, touching and apart.

Two references, each where it is exact or the tighter:

* coal (the maintained successor of FCL): closed forms for its sphere, capsule, box and halfspace
  pairs, GJK and EPA (asked for 1e-12, absolute) for the polytope pairs (box, convex mesh),
  where they end on exact faces. Every pair without a cylinder or an ellipsoid, and every plane
  pair, is checked against it.
* MuJoCo's ``mj_geomDistance`` (its own GJK and EPA, ``opt.ccd_tolerance`` 1e-12, 1000
  iterations) for the pairs with a cylinder or an ellipsoid: coal 3.0.3 fails on them when
  they overlap deeply (it returns -DBL_MAX in 23 of 200 sphere-ellipsoid poses and 56 of 200
  ellipsoid-ellipsoid ones, and depths off by up to 0.33 m, e.g. a sphere 0.0885 m deep in a
  cylinder whose closed form is -min(R - rho, h - |z|) - r = -0.1438 m is -0.2230 m in coal),
  while MuJoCo agrees with that closed form and with the audit to 1.2e-10 m on the same poses.
"""

from __future__ import annotations

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

import pytest

coal = pytest.importorskip("coal")

TYPES = ("plane", "sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh")
PAIRS = [(a, b) for i, a in enumerate(TYPES) for b in TYPES[i:] if (a, b) != ("plane", "plane")]


def request():
    req = coal.DistanceRequest()
    req.enable_signed_distance = True
    req.gjk_convergence_criterion_type = coal.GJKConvergenceCriterionType.Absolute
    req.gjk_tolerance = 1e-12
    req.epa_tolerance = 1e-12
    req.gjk_max_iterations = 1000
    req.epa_max_iterations = 1000
    return req


def random_mesh(rng, n=14):
    """(n, 3) vertices of a random convex-ish blob about the origin (m): points on an ellipsoid
    with jitter, so that some lie inside the hull (it is the hull that counts)."""
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d * rng.uniform(0.05, 0.3, 3) * rng.uniform(0.7, 1.0, (n, 1))


def random_size(rng, t):
    if t == "sphere":
        return np.array([rng.uniform(0.03, 0.3), 0, 0])
    if t in ("capsule", "cylinder"):
        return np.array([rng.uniform(0.03, 0.2), rng.uniform(0.02, 0.3), 0])
    if t in ("ellipsoid", "box"):
        return rng.uniform(0.03, 0.3, 3)
    return np.zeros(3)


def bounding_radius(t, s, verts=None):
    return {"plane": 0.0, "sphere": s[0], "capsule": s[0] + s[1],
            "ellipsoid": s.max(), "cylinder": np.hypot(s[0], s[1]),
            "box": np.linalg.norm(s),
            "mesh": 0.0 if verts is None else np.linalg.norm(verts, axis=1).max()}[t]


def coal_shape(t, s, verts=None):
    if t == "plane":
        return coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)
    if t == "sphere":
        return coal.Sphere(s[0])
    if t == "capsule":
        return coal.Capsule(s[0], 2 * s[1])
    if t == "cylinder":
        return coal.Cylinder(s[0], 2 * s[1])
    if t == "ellipsoid":
        return coal.Ellipsoid(s[0], s[1], s[2])
    if t == "box":
        return coal.Box(2 * s[0], 2 * s[1], 2 * s[2])
    v = coal.StdVec_Vec3s()
    for p in verts:
        v.append(np.asarray(p, float))
    return coal.Convex.convexHull(v, False, "")


def coal_distance(req, ga, xa, ra, gb, xb, rb):
    """(signed distance, normal from a to b, point on a, point on b) by coal."""
    res = coal.DistanceResult()
    d = coal.distance(ga, coal.Transform3s(ra, xa), gb, coal.Transform3s(rb, xb), req, res)
    return d, np.array(res.normal), np.array(res.getNearestPoint1()), \
        np.array(res.getNearestPoint2())


def random_poses(rng, ta, sa, va, tb, sb, vb, p):
    """p poses (xa, ra, xb, rb) of a against b spread from deep overlap to apart by about the
    size of the pair; a plane at the origin is approached along its normal."""
    ra = Rotation.random(p, random_state=rng).as_matrix()
    rb = Rotation.random(p, random_state=rng).as_matrix()
    rad_a, rad_b = bounding_radius(ta, sa, va), bounding_radius(tb, sb, vb)
    d = rng.normal(size=(p, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    xa = rng.normal(scale=0.2, size=(p, 3))
    if ta == "plane":
        nrm = ra[:, :, 2]
        lateral = rng.normal(scale=0.3, size=(p, 3))
        lateral -= (lateral * nrm).sum(1, keepdims=True) * nrm
        xb = xa + lateral + nrm * rng.uniform(-1.2 * rad_b, 1.5 * rad_b, (p, 1))
    else:
        xb = xa + d * rng.uniform(0.0, 1.3 * (rad_a + rad_b), (p, 1))
    return xa, ra, xb, rb




CURVED = ("ellipsoid", "cylinder")


def reference_of(ta, tb):
    """Which reference checks the pair (module docstring)."""
    return "mujoco" if "plane" not in (ta, tb) and (ta in CURVED or tb in CURVED) else "coal"


class MujocoPair:
    """Two world geoms of types ta, tb in a MuJoCo model; a mesh is ``verts`` (V, 3), whose
    compiled (recentred) vertices are ``mesh_vert``. Poses and sizes are written into the model
    and data before each ``mj_geomDistance``."""

    def __init__(self, ta, tb, verts=None):
        mesh = "" if verts is None else \
            '<asset><mesh name="m" vertex="' + " ".join(f"{x:.17g}" for x in verts.ravel()) + '"/></asset>'
        geom = lambda n, t: (f'<geom name="{n}" type="mesh" mesh="m"/>' if t == "mesh"
                             else f'<geom name="{n}" type="{t}" size="0.1 0.1 0.1"/>')
        xml = f"<mujoco>{mesh}<worldbody>{geom('a', ta)}{geom('b', tb)}</worldbody></mujoco>"
        self.m = mujoco.MjModel.from_xml_string(xml)
        self.m.opt.ccd_tolerance = 1e-12
        self.m.opt.ccd_iterations = 1000
        self.m.geom_rbound[:] = 1e3  # no bounding-sphere cut-off
        self.d = mujoco.MjData(self.m)
        self.mesh_vert = None
        if verts is not None:
            self.mesh_vert = np.array(self.m.mesh_vert)
            # (mj_geomDistance reads the geom frames from geom_xpos / geom_xmat, in which the
            # compiled, recentred vertices are given)

    def distance(self, sa, xa, ra, sb, xb, rb):
        """(signed distance, normal from b into a) of a at (xa, ra) against b at (xb, rb)."""
        m, d = self.m, self.d
        for g, (s_, x, r) in enumerate(((sa, xa, ra), (sb, xb, rb))):
            if m.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH:
                m.geom_size[g] = s_ if m.geom_type[g] != mujoco.mjtGeom.mjGEOM_SPHERE else \
                    [s_[0], 0, 0]
            d.geom_xpos[g] = x
            d.geom_xmat[g] = np.asarray(r).ravel()
        ft = np.zeros(6)
        dist = mujoco.mj_geomDistance(m, d, 0, 1, 1e3, ft)
        v = ft[:3] - ft[3:]
        nv = np.linalg.norm(v)
        return dist, (v / nv * np.sign(dist) if nv > 0 else np.zeros(3))


def compare(ta, tb, p, seed):
    """p random poses of (ta, tb), each also with b moved to touching along the audit's normal
    by the audit's separation (the reference then judges that pose like any other). Returns
    dict: ours (the audit's pair_distance dict over the 2p cases), ref_sep, ref_normal (from b
    into a), ref ("coal" or "mujoco"), and what is needed to query the reference again
    (``again(xa, xb)`` -> reference separations with a and b at new centres)."""
    from rblog.analyze import shapes

    rng = np.random.default_rng(seed)
    ref = reference_of(ta, tb)
    req = request()
    # MuJoCo: one mesh per pair of types (its model is compiled once); coal: a mesh per pose
    fixed = random_mesh(rng) if ref == "mujoco" and "mesh" in (ta, tb) else None
    mj = MujocoPair(ta, tb, fixed) if ref == "mujoco" else None
    if mj is not None and fixed is not None:
        fixed = mj.mesh_vert
    draws = []
    for q in range(p):
        sa, sb = random_size(rng, ta), random_size(rng, tb)
        va = (fixed if fixed is not None else random_mesh(rng)) if ta == "mesh" else None
        vb = (fixed if fixed is not None else random_mesh(rng)) if tb == "mesh" else None
        xa, ra, xb, rb = (z[0] for z in random_poses(rng, ta, sa, va, tb, sb, vb, 1))
        draws.append((sa, va, xa, ra, sb, vb, xb, rb))

    def ours_of(cases):
        m = len(cases)
        geoms = shapes.Geoms.build([ta] * m + [tb] * m, [c[0] for c in cases] + [c[4] for c in cases],
                                   meshes=[c[1] for c in cases] + [c[5] for c in cases])
        pos = np.array([c[2] for c in cases] + [c[6] for c in cases])[None]
        rot = np.array([c[3] for c in cases] + [c[7] for c in cases])[None]
        return shapes.pair_distance(geoms, pos, rot, np.zeros(m, np.int64), np.arange(m),
                                    np.arange(m, 2 * m))

    first = ours_of(draws)
    touching = [c[:6] + (c[6] + first["sep"][q] * first["normal"][q], c[7])
                for q, c in enumerate(draws)]
    cases = draws + touching
    ours = ours_of(cases)
    shapes_ = [(coal_shape(ta, c[0], c[1]), coal_shape(tb, c[4], c[5])) for c in cases] \
        if ref == "coal" else None

    def again(xa, xb):
        out = np.empty((len(cases), 2))
        nrm = np.empty((len(cases), 3))
        for q, c in enumerate(cases):
            if ref == "coal":
                d, n, _, _ = coal_distance(req, shapes_[q][0], xa[q], c[3], shapes_[q][1], xb[q],
                                           c[7])
                out[q] = d, 0
                nrm[q] = -n
            else:
                out[q, 0], nrm[q] = mj.distance(c[0], xa[q], c[3], c[4], xb[q], c[7])
        return out[:, 0], nrm

    xa = np.array([c[2] for c in cases])
    xb = np.array([c[6] for c in cases])
    ref_sep, ref_normal = again(xa, xb)
    return dict(ours=ours, ref_sep=ref_sep, ref_normal=ref_normal, ref=ref, again=again, xa=xa,
                xb=xb, cases=cases)


def mujoco_second_opinion(ta, tb, cases, rows):
    """MuJoCo's separations of ``rows`` of ``cases`` (compare's), for pairs without a mesh."""
    mj = MujocoPair(ta, tb)
    return np.array([mj.distance(cases[q][0], cases[q][2], cases[q][3], cases[q][4],
                                 cases[q][6], cases[q][7])[0] for q in rows])
