"""Convex hulls in rblog's engine: every hull pair's gap and normal against coal's (convex
meshes; GJK/EPA to 1e-12 m, exact for polytopes) and, with a cylinder, MuJoCo's mj_geomDistance
with mesh geoms, over random poses (deep, touching, apart); the polytope pairs (hull - hull, box -
hull: separating axes) over thousands of poses, their contact points on both surfaces; hull -
plane against the closed form (the lowest vertex), and hulls resting on each of their faces for
10 s."""

from __future__ import annotations

import numpy as np
import pytest

from rblog.engine.contact import narrowphase as npc
from rblog.engine.hull import build_hull, register

from tests.engine.contact.test_capsule import _rest
from tests.engine.contact.test_cylinder import _angle, _mj_size, _size

mujoco = pytest.importorskip("mujoco")
coal = pytest.importorskip("coal")
Rotation = pytest.importorskip("scipy.spatial.transform").Rotation

SPEC = 10.0  # m: every point is kept, so the manifold's least gap is the pair's
GEOM = {"sphere": npc.GEOM_SPHERE, "capsule": npc.GEOM_CAPSULE, "box": npc.GEOM_BOX,
        "cylinder": npc.GEOM_CYLINDER, "hull": npc.GEOM_HULL}


def _fail(e):
    raise AssertionError(e)


def _random_hull(rng):
    """(engine size row [id, 0, 0], body-frame vertices (V, 3)) of the hull of 6..20 random
    points."""
    p = rng.normal(size=(int(rng.integers(6, 21)), 3)) * rng.uniform(0.03, 0.25, 3)
    h = build_hull(p, _fail)
    return np.array([register(h.vertices, _fail), 0.0, 0.0]), h.vertices


def _mj_geom(t, s, v, k):
    if t == "hull":
        return (f'<mesh name="m{k}" vertex="{" ".join(repr(float(x)) for x in v.ravel())}"/>',
                f'<geom type="mesh" mesh="m{k}"/>')
    return "", f'<geom type="{t}" size="{_mj_size(t, s)}"/>'


def _mujoco(ta, sa, va, xa, ra, tb, sb, vb, xb, rb):
    """(signed distance, unit normal from b into a, and each shape as MuJoCo compiled it: (x, r,
    size, vertices)) by MuJoCo's mj_geomDistance. MuJoCo stores a mesh's vertices in float32,
    moved to the mesh's own frame (the geom's pose moved with it): the engine is then run on
    those vertices at that pose, the same shape to the last bit."""
    (ma, ga), (mb, gb) = _mj_geom(ta, sa, va, 0), _mj_geom(tb, sb, vb, 1)
    xml = f"""<mujoco><option ccd_tolerance="1e-13" ccd_iterations="5000"/>
    <asset>{ma}{mb}</asset><worldbody>
    <body mocap="true">{ga}</body><body mocap="true">{gb}</body></worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    for k, (x, r) in enumerate(((xa, ra), (xb, rb))):
        d.mocap_pos[k] = x
        q = Rotation.from_matrix(r).as_quat()  # x y z w
        d.mocap_quat[k] = [q[3], q[0], q[1], q[2]]
    mujoco.mj_kinematics(m, d)
    ft = np.zeros(6)
    dist = mujoco.mj_geomDistance(m, d, 0, 1, 50.0, ft)
    v = ft[:3] - ft[3:]
    shapes = []
    for g, (t, s) in enumerate(((ta, sa), (tb, sb))):
        x, r = np.array(d.geom_xpos[g]), np.array(d.geom_xmat[g]).reshape(3, 3)
        if t == "hull":
            mid = int(m.geom_dataid[g])
            a, n = int(m.mesh_vertadr[mid]), int(m.mesh_vertnum[mid])
            vv = np.array(m.mesh_vert[a:a + n], np.float64)
            s = np.array([register(vv, _fail), 0.0, 0.0])
        shapes.append((x, r, s))
    return dist, v / dist, shapes


def _coal_shape(t, s, v):
    if t == "hull":
        pts = coal.StdVec_Vec3s()
        for p in v:
            pts.append(np.asarray(p, float))
        return coal.Convex.convexHull(pts, False, "")
    return {"sphere": lambda: coal.Sphere(s[0]), "capsule": lambda: coal.Capsule(s[0], 2 * s[1]),
            "box": lambda: coal.Box(*(2 * np.asarray(s)))}[t]()


def _coal(ta, sa, va, xa, ra, tb, sb, vb, xb, rb):
    """(signed distance, unit normal from b into a) by coal (GJK/EPA to 1e-12 m, absolute: exact
    faces for polytopes, its closed forms for spheres and capsules)."""
    req = coal.DistanceRequest()
    req.enable_signed_distance = True
    req.gjk_convergence_criterion_type = coal.GJKConvergenceCriterionType.Absolute
    req.gjk_tolerance = req.epa_tolerance = 1e-12
    req.gjk_max_iterations = req.epa_max_iterations = 10000
    res = coal.DistanceResult()
    dist = coal.distance(_coal_shape(ta, sa, va), coal.Transform3s(ra, xa),
                         _coal_shape(tb, sb, vb), coal.Transform3s(rb, xb), req, res)
    return dist, -np.array(res.normal)


def _shape(rng, t):
    if t == "hull":
        return _random_hull(rng)
    return _size(rng, t), None


def _poses(ta, tb, n, seed):
    """Random (sa, xa, ra, sb, xb, rb, gap, normal): coal's, or MuJoCo's for a pair with a
    cylinder (coal's cylinder is off when deep: test_cylinder.py); a third moved along the normal
    by the gap to touching."""
    rng = np.random.default_rng(seed)
    ref = _mujoco if "cylinder" in (ta, tb) else _coal
    for k in range(n):
        (sa, va), (sb, vb) = _shape(rng, ta), _shape(rng, tb)
        ra, rb = Rotation.random(2, random_state=rng).as_matrix()
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        xa = rng.normal(scale=0.2, size=3)
        xb = xa + d * rng.uniform(0.0, 0.65)
        out = ref(ta, sa, va, xa, ra, tb, sb, vb, xb, rb)
        g, nrm = out[0], out[1]
        if ref is _mujoco:
            (xa, ra, sa), (xb, rb, sb) = out[2]
        if k % 3 == 2:  # touching: b moved along the normal by the gap
            xb, g = xb + g * nrm, 0.0
        yield sa, xa, ra, sb, xb, rb, g, nrm


#: the pairs through collide_convex (GJK/EPA and exact candidate axes; the polytope pairs are
#: test_polytope_pair_against_coal's)
PAIRS = [("hull", "sphere"), ("hull", "capsule"), ("hull", "cylinder"), ("sphere", "hull"),
         ("capsule", "hull"), ("cylinder", "hull")]


@pytest.mark.parametrize("ta,tb", PAIRS)
def test_pair_depth_and_normal_match_mujoco(ta, tb):
    n_pose = 150
    worst_gap, worst_angle = 0.0, 0.0
    for sa, xa, ra, sb, xb, rb, d_ref, n_ref in _poses(ta, tb, n_pose,
                                                        seed=len(ta) * 7 + len(tb) * 3):
        nrm, pts, sep, fid = npc.collide_np(GEOM[ta], xa, ra, sa, GEOM[tb], xb, rb, sb, spec=SPEC)
        assert 1 <= len(sep) <= 4
        assert len(set(fid.tolist())) == len(fid)
        assert np.all(np.isfinite(pts))
        worst_gap = max(worst_gap, abs(sep.min() - d_ref))
        if abs(d_ref) > 1e-6:
            worst_angle = max(worst_angle, _angle(nrm, n_ref))
    if "cylinder" in (ta, tb):
        # measured over the 150 poses: |gap - MuJoCo's| <= 6e-11 m hull-cylinder, 8.8e-9 m
        # cylinder-hull: at one touching pose (k = 107) whose true gap is -3.6e-16 m (the
        # largest g(u) = u.s_A(-u) - u.s_B(u) a Nelder-Mead search finds, along MuJoCo's
        # normal) the engine's normal is 3e-3 rad off it (a cylinder's rim on the hull: none of
        # the exact candidate axes, GJK/EPA's normal to CONVEX_EPA_TOL_M): 8.8 nm too deep;
        # normal (where the gap is not 0) <= 2.5e-5 rad
        assert worst_gap <= 2e-8, worst_gap
        assert worst_angle <= 1e-4, worst_angle
    else:
        # measured over the 150 poses of each pair: |gap - coal's| <= 7.1e-16 m (GJK/EPA and
        # the exact face and edge axes, coal's closed forms), normal <= 3.3e-8 rad (coal's
        # normal at its own GJK tolerance)
        assert worst_gap <= 1e-14, worst_gap
        assert worst_angle <= 1e-6, worst_angle


def _solid(t, s, v):
    """(vertices (V, 3), face planes (F, 4): n . x <= off inside) of a box or hull in its frame,
    by scipy's Qhull (independent of the engine's hull)."""
    from scipy.spatial import ConvexHull

    if t == "box":
        v = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * s
    eq = ConvexHull(v).equations  # n . x + c <= 0 inside
    return v, np.c_[eq[:, :3], -eq[:, 3]]


def _polytope_poses(ta, tb, n, seed):
    """Random (sa, va, xa, ra, sb, vb, xb, rb, gap, normal): coal's signed distance and normal
    (from b into a) of the two convex vertex sets; a third moved along the normal to touching
    (as _poses)."""
    rng = np.random.default_rng(seed)
    for k in range(n):
        (sa, va), (sb, vb) = _shape(rng, ta), _shape(rng, tb)
        ra, rb = Rotation.random(2, random_state=rng).as_matrix()
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        xa = rng.normal(scale=0.2, size=3)
        xb = xa + d * rng.uniform(0.0, 0.65)
        # a box as the hull of its corners: coal's Box distance is 1e-11 m off at touching
        # (its box - convex path), its convex - convex one exact
        g, nrm = _coal("hull", sa, _solid(ta, sa, va)[0], xa, ra, "hull", sb,
                       _solid(tb, sb, vb)[0], xb, rb)
        if k % 3 == 2:
            xb, g = xb + g * nrm, 0.0
        yield sa, va, xa, ra, sb, vb, xb, rb, g, nrm


@pytest.mark.parametrize("n_pose", [300, pytest.param(3000, marks=pytest.mark.slow)])
@pytest.mark.parametrize("ta,tb", [("hull", "hull"), ("box", "hull"), ("hull", "box")])
def test_polytope_pair_against_coal(ta, tb, n_pose):
    """Two polytopes by separating axes (polytope.cpp): along the engine's normal n the solids'
    separation g(n) = min_A n.x - max_B n.x (from the vertices) is never above the signed
    distance d (coal's) and below it by at most the band by which a face axis is kept over a
    slightly better one when they overlap (a's face over b's by at most (1 - FACE_REL_TOL) |g|
    + AXIS_ABS_TOL, then that face over an edge pair by at most (1 - EDGE_REL_TOL) |g| +
    AXIS_ABS_TOL; apart, g(n) is the axes' lower bound); where g(n) = d the normal is coal's.
    Every gap is at least g(n) (each is n . (p_a - p_b) of a point of each solid): g(n) itself
    for most overlapping pairs, not when the deepest vertex lies beside the reference face (a
    box's corner hanging over a table's edge touches nothing). An apart pair's point with both
    ends on the surfaces is no nearer than d (d itself when it realizes the axis). Every point
    of an overlapping pair is the midpoint of a point on one surface and a point its gap away
    along n on or in the other solid."""
    from rblog.engine.constants import AXIS_ABS_TOL, EDGE_REL_TOL, FACE_REL_TOL

    tol = 1e-14  # m: round-off of the 0.03 - 0.3 m shapes (measured below)
    worst = dict(exact=0.0, angle=0.0, band=0.0, surface=0.0, apart=0.0)
    n_exact = n_band = 0
    for sa, va, xa, ra, sb, vb, xb, rb, d_ref, n_ref in _polytope_poses(
            ta, tb, n_pose, seed=len(ta) * 5 + len(tb) + n_pose):
        nrm, pts, sep, fid = npc.collide_np(GEOM[ta], xa, ra, sa, GEOM[tb], xb, rb, sb, spec=SPEC)
        (wa, pa_), (wb, pb_) = _solid(ta, sa, va), _solid(tb, sb, vb)
        wa, wb = xa + wa @ ra.T, xb + wb @ rb.T
        if len(sep) == 0:  # no clipped point: an apart or touching pair only
            assert d_ref >= 0.0
            continue
        assert len(sep) <= 4 and len(set(fid.tolist())) == len(fid)
        g = (wa @ nrm).min() - (wb @ nrm).max()
        assert g <= d_ref + tol, (g, d_ref)
        if d_ref < 0.0:
            band = (2 - EDGE_REL_TOL - FACE_REL_TOL) * abs(g) + 2 * AXIS_ABS_TOL
            worst["band"] = max(worst["band"], (d_ref - g) / band)
        if d_ref - g <= tol:
            n_exact += 1
            worst["exact"] = max(worst["exact"], abs(g - d_ref))
            if abs(d_ref) > 1e-6:
                worst["angle"] = max(worst["angle"], _angle(nrm, n_ref))
        else:
            n_band += 1
        ends = []
        for p, s in zip(pts, sep):
            qa, qb = p + 0.5 * s * nrm, p - 0.5 * s * nrm
            fa = (pa_[:, :3] @ (ra.T @ (qa - xa)) - pa_[:, 3]).max()
            fb = (pb_[:, :3] @ (rb.T @ (qb - xb)) - pb_[:, 3]).max()
            ends.append((fa, fb, s))
        assert sep.min() >= g - tol, (sep.min(), g)
        if d_ref >= 0.0:
            for fa, fb, s in ends:  # a point with both ends on the surfaces: no nearer than d
                if max(abs(fa), abs(fb)) <= tol:
                    assert s >= d_ref - tol, (s, d_ref)
                    worst["apart"] = max(worst["apart"], abs(s - d_ref) if s - g <= tol else 0)
            continue
        for fa, fb, _ in ends:
            assert max(fa, fb) <= tol, ends
            worst["surface"] = max(worst["surface"], min(abs(fa), abs(fb)))
    # measured (300 / 3000 poses of each pair): exact poses' |g - d| <= 4.5e-16 m, normal
    # <= 5.4e-8 rad (coal's own GJK tolerance), d - g <= 0.92 of the preference band, surfaces
    # <= 2.8e-16 m, apart pairs' realized axes <= 3.6e-15 m; 68-74 % of the poses with points
    # exact (the others deep overlaps, where the band is wide, or apart)
    assert worst["exact"] <= tol and worst["apart"] <= tol, worst
    assert worst["angle"] <= 1e-6, worst
    assert worst["band"] <= 1.0, worst
    assert worst["surface"] <= tol, worst
    assert n_exact >= 0.6 * (n_exact + n_band), (n_exact, n_band)


def test_hull_plane_is_the_lowest_vertex():
    rng = np.random.default_rng(11)
    pn = np.array([0.3, -0.2, 0.9])
    pn /= np.linalg.norm(pn)
    for k in range(200):
        s, v = _random_hull(rng)
        r = Rotation.random(random_state=rng).as_matrix()
        x = rng.normal(scale=0.2, size=3)
        off = float(rng.uniform(-0.3, 0.3))
        nrm, pts, sep, fid = npc.collide_np(npc.GEOM_HULL, x, r, s, npc.GEOM_PLANE,
                                            plane_normal=pn, plane_offset=off, spec=SPEC)
        gaps = (x + v @ r.T) @ pn - off
        assert abs(sep.min() - gaps.min()) <= 1e-15 * (1 + np.abs(gaps).max())
        np.testing.assert_array_equal(nrm, pn)
        # every point is a vertex's, midway to the plane
        for p, g, f in zip(pts, sep, fid):
            w = x + r @ v[f]
            np.testing.assert_allclose(p, w - 0.5 * g * pn, atol=1e-15)
            assert g == pytest.approx(gaps[f], abs=1e-15)


def _prism(n_sides, r, h):
    a = 2 * np.pi * np.arange(n_sides) / n_sides
    ring = np.stack([r * np.cos(a), r * np.sin(a)], 1)
    return np.concatenate([np.c_[ring, np.full(n_sides, -h)], np.c_[ring, np.full(n_sides, h)]])


#: hulls stable on every face: an octahedron of unequal axes (the centre's foot on each face is
#: inside it: barycentric weights 1/a^2, 1/b^2, 1/c^2), a hexagonal prism
HULLS = {
    "octahedron": np.array([[0.1, 0, 0], [-0.1, 0, 0], [0, 0.15, 0], [0, -0.15, 0],
                            [0, 0, 0.2], [0, 0, -0.2]]),
    "hex_prism": _prism(6, 0.12, 0.08),
}

RESTING = """
[sim]
dt = 1e-3
duration = 10.0
[ground]
restitution = 0.0
[[body]]
shape = "hull"
vertices = {verts}
density = 1000
position = [0.3, -0.2, 0.0]
"""


def _on_face(v, face_normal):
    """The vertices turned so that the face of outward normal ``face_normal`` faces -z, lifted
    so that it lies on z = 0."""
    rot, _ = Rotation.align_vectors([[0, 0, -1]], [face_normal])
    w = rot.apply(v)
    return w - [0, 0, w[:, 2].min()]


@pytest.mark.parametrize("sleep", [False, True])
@pytest.mark.parametrize("name", sorted(HULLS))
def test_hull_resting_on_each_face_for_10_s(name, sleep):
    h = build_hull(HULLS[name], _fail)
    worst, worst_turn = 0.0, 0.0
    for f, n in enumerate(h.face_normal):
        v = _on_face(h.vertices, n)
        pos, quat = _rest(RESTING.format(verts=v.tolist()), sleep=sleep)
        worst = max(worst, np.abs(pos - pos[0]).max())
        worst_turn = max(worst_turn, np.abs(quat - quat[0]).max())
    # measured over every face (8 of each), with and without sleep: position 0 m, quaternion
    # <= 1.1e-16 (from t = 0: placed touching, nothing settles); the bound is 1 um
    assert worst <= 1e-6, worst
    assert worst_turn <= 1e-6, worst_turn


def test_hull_table_agrees_with_python_and_finds_the_same_hull():
    from rblog.engine import _core
    from rblog.engine.hull import HULL_MAX_FACE_VERTICES

    assert _core.hull_max_face_vertices() == HULL_MAX_FACE_VERTICES
    v = build_hull(HULLS["hex_prism"], _fail).vertices
    assert register(v, _fail) == register(v.copy(), _fail)
    assert register(v, _fail) != register(1.5 * v, _fail)


def test_a_hull_body_in_a_contact_world_is_refused_with_its_vertex_inside(tmp_path):
    # the model's mesh geom must list the hull's own vertices (a scene's always does)
    from dataclasses import replace

    from rblog.engine.contact import ContactParams, ContactWorld
    from rblog.engine.scene import parse_scene
    from rblog.errors import RblogError

    sc = parse_scene(RESTING.format(verts=HULLS["octahedron"].tolist()))
    mv = np.concatenate([sc.model.mesh_vert[:5], [[0.0, 0.0, 0.0]]])  # a vertex moved inside
    model = replace(sc.model, mesh_vert=mv)
    with pytest.raises(RblogError, match=r"body 0 \('body0'\): its mesh geom: 1 of its 6 vertices "
                                         "lie inside the hull"):
        ContactWorld(model, ContactParams())
