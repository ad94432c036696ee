"""Separations between the logged shapes, recomputed from the logged poses and the model's shapes.

Nothing here reads the contacts a simulator reported: the analyzers judge those against these.

Conventions (those of :class:`rblog.contract.trajectory.Contacts`):

* ``sep`` is the signed distance between two surfaces (m): > 0 apart, < 0 penetration depth.
* ``normal`` is a unit world vector from body b into body a; ``point`` a world point midway
  between the two surfaces along the normal: the witness of the contact, at the centre of the
  patch where the bodies touch.
* Poses use the logged ``rotation`` (body->world, columns are the body axes in the world frame),
  as the integrator held it; a drifted matrix maps the shape as drifted.

The shape pairs (sphere-plane, box-plane, sphere-sphere, sphere-box, box-box by the separating
axis test), the witness points (a box's touching feature within WITNESS_BAND_M of its extreme:
corner, edge or face; the centre of two features' intersection in the contact plane) and the
broadphase are computed by the audit's compiled module, ``rblog.analyze._audit``; their
derivation is the header comment of csrc/audit/geometry.cpp. That code is the audit's own,
independent of the engine's narrowphase on purpose (an audit that shared the code it audits would
inherit its bugs).

Static boxes and dynamic bodies share one index space in the pair tables: ``b < N`` is a body,
``b = N + m`` is static box ``m``. Only candidate pairs from a broadphase are evaluated: a
compiled sort-and-sweep (on the axis of largest spread, insertion-sorted from the previous
interval's order) of each body's bounding sphere swept over each sample interval [k, k+1] and
grown by how far the body can stray from the straight path (a body that bounces back between
samples is never on the chord), so that the same candidates serve the contact tests at both
samples and the tunneling test between them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rblog.analyze import _audit
from rblog.analyze.tolerances import WITNESS_BAND_M
from rblog.contract.orientation import quat_wxyz_to_matrix
from rblog.contract.model import SHAPE_BOX, SHAPE_NONE, SHAPE_SPHERE, Model

#: thickness of a box's touching feature (m; see WITNESS_BAND_M)
_BAND = WITNESS_BAND_M
#: edge cross products shorter than this are parallel edges (their axis is skipped)
_AXIS_EPS = 1e-6

# the compiled module dispatches on the shape codes it mirrors (csrc/audit/audit.hpp)
assert (_audit.SHAPE_SPHERE, _audit.SHAPE_BOX) == (SHAPE_SPHERE, SHAPE_BOX)


#: (..., 4) wxyz quaternions (normalized) -> (..., 3, 3) body->world matrices: the contract's own
#: conversion (rblog.contract.orientation), the same one every reader of a log uses
quat_to_matrix = quat_wxyz_to_matrix


def geom_bounding_radius(model: Model) -> np.ndarray:
    """(G,) radius of the sphere about each geom's centre that holds the geom (m): sphere r,
    capsule r + h, cylinder sqrt(r^2 + h^2), box and ellipsoid |size| (a bound), mesh its farthest
    vertex; a plane's |size| (meaningless: planes are half-spaces)."""
    from rblog.contract.model import GEOM_CAPSULE, GEOM_CYLINDER, GEOM_MESH, GEOM_SPHERE

    gt = np.asarray(model.geom_type, np.int64)
    gs = np.asarray(model.geom_size, float).reshape(-1, 3)
    r = np.linalg.norm(gs, axis=1)  # box half extents, ellipsoid semi-axes: a bound
    r = np.where(gt == GEOM_SPHERE, gs[:, 0], r)
    r = np.where(gt == GEOM_CAPSULE, gs[:, 0] + gs[:, 1], r)
    r = np.where(gt == GEOM_CYLINDER, np.hypot(gs[:, 0], gs[:, 1]), r)
    verts = np.asarray(model.mesh_vert, float).reshape(-1, 3)
    for g in np.flatnonzero(gt == GEOM_MESH):
        a, k = int(model.geom_vert_adr[g]), int(model.geom_vert_num[g])
        r[g] = np.linalg.norm(verts[a:a + k], axis=1).max() if k else 0.0
    return r


def bounding_radius(model: Model) -> np.ndarray:
    """(N,) radius of the sphere about the centre that holds the body (m): from its sphere or
    box, or, for a body without one, from its geoms (contract v3: each geom's own bounding
    radius about its centre plus its offset; planes left out)."""
    size = np.asarray(model.body_size, float)
    rho = np.where(model.body_shape == SHAPE_SPHERE, size[:, 0], np.linalg.norm(size, axis=1))
    gb = np.asarray(model.geom_body, np.int64)
    if not len(gb):
        return rho
    from rblog.contract.model import GEOM_PLANE

    gt = np.asarray(model.geom_type, np.int64)
    r = geom_bounding_radius(model) + np.linalg.norm(
        np.asarray(model.geom_pos_body, float).reshape(-1, 3), axis=1)
    keep = (gb >= 0) & (gt != GEOM_PLANE)
    from_geoms = np.zeros(len(rho))
    np.maximum.at(from_geoms, gb[keep], r[keep])
    return np.where(model.body_shape == SHAPE_NONE, from_geoms, rho)


def inner_radius(model: Model) -> np.ndarray:
    """(N,) radius of the largest sphere about the centre inside the body (m)."""
    size = np.asarray(model.body_size, float)
    return np.where(model.body_shape == SHAPE_SPHERE, size[:, 0], size.min(axis=1))


def plane_separation(model: Model, position: np.ndarray, rotation: np.ndarray):
    """Signed distance of every body to the ground plane.

    Returns (sep (T, N), centre_height (T, N)) in m; centre_height = n.x - offset, and the
    support of a box along n is sum_j h_j |n.A_j|.
    """
    shape = position.shape[:2]
    sep, height = np.empty(shape), np.empty(shape)
    _audit.plane_kernel(np.ascontiguousarray(position, dtype=np.float64),
                        np.ascontiguousarray(rotation, dtype=np.float64),
                        np.ascontiguousarray(np.asarray(model.body_shape) == SHAPE_SPHERE),
                        np.ascontiguousarray(model.body_size, dtype=np.float64),
                        np.ascontiguousarray(model.ground_normal, dtype=np.float64),
                        float(model.ground_offset), sep, height)
    return sep, height


def plane_witness(model: Model, body: np.ndarray, position: np.ndarray, rotation: np.ndarray):
    """Contact points with the ground of bodies ``body`` (P,) at poses (P, 3), (P, 3, 3)."""
    p = len(body)
    return plane_witness_at(model, np.zeros(p, np.int64), np.arange(p), np.asarray(body),
                            np.asarray(position, float)[None], np.asarray(rotation, float)[None])


def plane_witness_at(model: Model, k: np.ndarray, j: np.ndarray, body: np.ndarray,
                     position: np.ndarray, rotation: np.ndarray, with_span: bool = False):
    """(P, 3) contact points with the ground of bodies ``body`` (P,) at the poses
    ``position[k, j]`` (..., 3), ``rotation[k, j]`` (..., 3, 3) (indexed in the compiled pass,
    without gathering the poses first); with ``with_span`` also (P, 3) half-spans (an edge on
    the ground: the patch is point +- span; else 0)."""
    out = np.empty((len(k), 3))
    spn = np.zeros((len(k), 3)) if with_span else np.empty((0, 3))
    c = np.ascontiguousarray
    _audit.witness_kernel(c(position, dtype=np.float64), c(rotation, dtype=np.float64),
                          c(k, dtype=np.int64), c(j, dtype=np.int64), c(body, dtype=np.int64),
                          c(np.asarray(model.body_shape) == SHAPE_SPHERE),
                          c(model.body_size, dtype=np.float64),
                          c(model.ground_normal, dtype=np.float64), _BAND, out, spn)
    return (out, spn) if with_span else out


def _edge_edge(ax, ay, eax, eay, bx, by, ebx, eby):
    """Edges a +- ea, b +- eb in the contact plane: parallel (the tilt between them moves an end
    by at most the band) -> the middle of their overlap along a, halfway to b's line; else the
    closest points. Returns (x, y) (the compiled narrowphase's own function, csrc/audit/geometry.cpp)."""
    return _audit.edge_edge(float(ax), float(ay), float(eax), float(eay), float(bx), float(by),
                            float(ebx), float(eby), _BAND)


def pair_geometry(model: Model, position, rotation, ks, a, b, with_points: bool = True,
                  with_span: bool = False):
    """Separation (R,), and unless ``with_points`` is False the normal b->a (R, 3) and witness
    point (R, 3), of rows (ks, a, b); with ``with_span`` also the patch's half-span (R, 3) (an
    edge on a face: the patch is point +- span; else 0)."""
    sx, sr, sh = static_boxes(model)
    r = len(ks)
    sep = np.empty(r)
    # (normals and points are only needed near contacts: skip the memory when not asked)
    nrm, pt = (np.empty((r, 3)), np.empty((r, 3))) if with_points else (np.empty((0, 3)),) * 2
    spn = np.zeros((r, 3)) if with_points and with_span else np.empty((0, 3))
    c = np.ascontiguousarray
    _audit.pairs_kernel(c(ks, dtype=np.int64), c(a, dtype=np.int64), c(b, dtype=np.int64),
                        c(position, dtype=np.float64), c(rotation, dtype=np.float64),
                        c(model.body_shape, dtype=np.int64), c(model.body_size, dtype=np.float64),
                        c(sx[None], dtype=np.float64), c(sr[None], dtype=np.float64),
                        c(sh, dtype=np.float64), sep, nrm, pt, spn, bool(with_points), _BAND,
                        _AXIS_EPS)
    if with_span:
        return sep, nrm, pt, spn
    return (sep, nrm, pt) if with_points else sep


def _batch(shape_a, xa, ra, ha, shape_b, xb, rb, hb):
    """P explicit pairs (for tests and one-off use) through the compiled narrowphase."""
    p = len(xa)
    pos = np.concatenate([xa, xb])[None]
    rot = np.concatenate([ra, rb])[None]
    size = np.concatenate([ha, hb])
    model = Model(body_name=[""] * 2 * p, body_shape=np.concatenate([shape_a, shape_b]),
                  body_size=size, body_mass=np.ones(2 * p), body_inertia_diag=np.ones((2 * p, 3)),
                  body_force_world=np.zeros((2 * p, 3)), body_torque_world=np.zeros((2 * p, 3)),
                  body_restitution=np.zeros(2 * p), body_friction=np.zeros(2 * p),
                  body_group=np.zeros(2 * p, np.int64), gravity=np.zeros(3))
    return pair_geometry(model, pos, rot, np.zeros(p, np.int64), np.arange(p),
                         np.arange(p, 2 * p))


def _eye(p):
    return np.broadcast_to(np.eye(3), (p, 3, 3))


def sphere_sphere(xa, ra, xb, rb):
    """Spheres: (sep (P,), normal b->a (P, 3), point (P, 3))."""
    p = len(xa)
    ha = np.zeros((p, 3))
    hb = np.zeros((p, 3))
    ha[:, 0], hb[:, 0] = ra, rb
    z = np.zeros(p, np.int64)
    return _batch(z, xa, _eye(p), ha, z, xb, _eye(p), hb)


def sphere_box(xs, r, xb, rb, hb):
    """Sphere (xs, r) against box (xb, rotation rb, half extents hb): (sep, normal from the box
    into the sphere, point on the box surface)."""
    p = len(xs)
    hs = np.zeros((p, 3))
    hs[:, 0] = r
    return _batch(np.zeros(p, np.int64), xs, _eye(p), hs, np.ones(p, np.int64), xb, rb, hb)


def box_box(xa, ra, ha, xb, rb, hb):
    """Boxes a, b by the separating-axis test: (sep, normal b->a, point)."""
    p = len(xa)
    o = np.ones(p, np.int64)
    return _batch(o, xa, ra, ha, o, xb, rb, hb)


@dataclass
class Proximity:
    """Who is near whom, recomputed from the poses.

    Attributes:
        n_bodies, n_static: N bodies, M static boxes (entity b = N + m).
        ground_sep: (T, N) signed distance to the ground (m), or None without ground.
        ground_height: (T, N) centre height above the ground plane (m), or None.
        iv_*: interval table: candidate pairs whose swept bounding volumes overlap over the
            interval [k, k+1]: k (interval index), a (< N), b (> a; >= N static box b - N), and
            their separations sep0, sep1 (m) at both samples. Normals and witness points come
            from :meth:`iv_geometry` for the rows that need them.
    """

    model: Model
    position: np.ndarray
    rotation: np.ndarray
    n_bodies: int
    n_static: int
    ground_sep: np.ndarray | None
    ground_height: np.ndarray | None
    iv_k: np.ndarray
    iv_a: np.ndarray
    iv_b: np.ndarray
    iv_sep0: np.ndarray
    iv_sep1: np.ndarray

    def iv_geometry(self, rows: np.ndarray, end, with_span: bool = False):
        """(sep, normal b->a, point) of interval rows ``rows`` at their sample k + end (end: 0,
        1, or an array of them); with ``with_span`` also the patch half-span (see
        pair_geometry)."""
        k = self.iv_k[rows] + (end if len(self.position) > 1 else 0)
        return pair_geometry(self.model, self.position, self.rotation, k, self.iv_a[rows],
                             self.iv_b[rows], with_span=with_span)

    def near_pairs(self, dist: float) -> dict:
        """Sample table of the pairs closer than ``dist`` (m): dict of k (sample), a, b, sep, and
        row, end (the interval row and which of its samples, for :meth:`iv_geometry`), from the
        intervals' first samples and the last interval's last sample. A pair closer than the
        pad at sample k is a candidate of both intervals that hold k (their volumes contain the
        bounding spheres at k), so none is missed."""
        t_n = len(self.position)
        last_k = max(t_n - 2, 0)
        r0 = np.nonzero(self.iv_sep0 <= dist)[0]
        r1 = np.nonzero((self.iv_sep1 <= dist) & (self.iv_k == last_k))[0] if t_n > 1 else \
            np.zeros(0, np.int64)
        rows = np.concatenate([r0, r1])
        end = np.concatenate([np.zeros(len(r0), np.int64), np.ones(len(r1), np.int64)])
        return dict(k=self.iv_k[rows] + end, a=self.iv_a[rows], b=self.iv_b[rows],
                    sep=np.concatenate([self.iv_sep0[r0], self.iv_sep1[r1]]), row=rows, end=end)


def static_boxes(model: Model):
    """(position (M, 3), rotation (M, 3, 3), half extents (M, 3)) of the static boxes."""
    pos = np.asarray(model.static_box_position, float).reshape(-1, 3)
    h = np.asarray(model.static_box_half_extents, float).reshape(-1, 3)
    q = np.asarray(model.static_box_quat_wxyz, float).reshape(-1, 4)
    rot = quat_to_matrix(q) if len(q) else np.zeros((0, 3, 3))
    return pos, rot, h


def sweep_pairs(model: Model, position: np.ndarray, grow: np.ndarray, pad: float = 0.0):
    """Candidate pairs (k, a, b) per interval (sweep_kernel, csrc/audit/geometry.cpp); b >= N is
    static box b - N.

    grow: (K, N) how much each body's AABB is grown (m); static boxes are grown by ``pad``."""
    t_n, n = position.shape[:2]
    sx, sr, sh = static_boxes(model)
    ext = (np.abs(sr) * sh[:, None, :]).sum(-1) if len(sx) else np.zeros((0, 3))
    s_lo, s_hi = sx - ext - pad, sx + ext + pad
    spread = _audit.spread(np.ascontiguousarray(position, dtype=np.float64).reshape(-1, 3)) \
        if position.size else np.zeros(3)
    axis = int(np.argmax(spread))
    cap = max(1024, 4 * n * max(t_n - 1, 1))
    while True:
        out = [np.empty(cap, np.int64) for _ in range(3)]
        cnt = _audit.sweep_kernel(np.ascontiguousarray(position, dtype=np.float64),
                                  np.ascontiguousarray(grow, dtype=np.float64),
                                  np.ascontiguousarray(s_lo, dtype=np.float64),
                                  np.ascontiguousarray(s_hi, dtype=np.float64),
                                  np.ascontiguousarray(model.body_group, dtype=np.int64), axis,
                                  *out)
        if cnt <= cap:
            return out[0][:cnt], out[1][:cnt], out[2][:cnt]
        cap = cnt


def proximity(model: Model, position: np.ndarray, rotation: np.ndarray, pad: float,
              sweep: np.ndarray | None = None) -> Proximity:
    """Candidate pairs and their separations (see :class:`Proximity`).

    Args:
        position: (T, N, 3).  rotation: (T, N, 3, 3).
        pad: bounding volumes are grown by this (m), e.g. the contact distance.
        sweep: (T-1, N) how far each body may stray from the straight path between the samples
            of each interval (m; a body that bounces back mid-interval is never on the chord).
    """
    t_n, n = position.shape[:2]
    sx, sr, sh = static_boxes(model)
    m = len(sx)
    e = n + m

    ground_sep = ground_height = None
    if model.ground:
        ground_sep, ground_height = plane_separation(model, position, rotation)
        shapeless_ground(model, position, rotation, ground_sep)

    # broadphase over intervals (a single "interval" [0, 0] for a one-sample log)
    k_n = t_n - 1 if t_n > 1 else 1
    grow = np.broadcast_to(bounding_radius(model)[None, :] + pad, (k_n, n))
    if sweep is not None and t_n > 1:
        grow = grow + sweep
    k, a, b = sweep_pairs(model, position, grow, pad)
    body_pair = b < n  # two bodies: their geoms' filter (a static box is the world's)
    if body_pair.any():
        from rblog.analyze.shapes import bodies_may_touch

        keep = ~body_pair
        keep[body_pair] = bodies_may_touch(model, a[body_pair], b[body_pair])
        if not keep.all():
            k, a, b = k[keep], a[keep], b[keep]

    # separations of every candidate at both ends of its interval
    k1 = k + 1 if t_n > 1 else k
    sep0 = pair_geometry(model, position, rotation, k, a, b, with_points=False)
    sep1 = pair_geometry(model, position, rotation, k1, a, b, with_points=False)
    shapeless_separation(model, position, rotation, k, k1, a, b, sep0, sep1)
    return Proximity(
        model=model, position=position, rotation=rotation,
        n_bodies=n, n_static=m, ground_sep=ground_sep, ground_height=ground_height,
        iv_k=k, iv_a=a, iv_b=b, iv_sep0=sep0, iv_sep1=sep1,
    )


def shapeless_separation(model: Model, position, rotation, k0, k1, a, b, sep0, sep1) -> None:
    """Overwrite, in place, the separations sep0 (at samples k0) and sep1 (at k1) of the rows
    (a, b) where a body has no shape in the contract (SHAPE_NONE: its body_size says nothing, and
    pair_geometry would take it for a point): two bodies with geoms, the least distance over
    their geom pairs that may touch (rblog.analyze.shapes.pair_distance, GJK/EPA, exact for
    capsules and cylinders); else a lower bound, the body's bounding sphere (radius ρ from its
    geoms) against the other body's shape or the static box."""
    none = np.asarray(model.body_shape) == SHAPE_NONE
    n = len(none)
    rows = none[a] | (none[np.minimum(b, n - 1)] & (b < n))
    if not rows.any():
        return
    from dataclasses import replace

    rho = bounding_radius(model)
    size = np.asarray(model.body_size, float).copy()
    size[none] = 0.0
    size[none, 0] = rho[none]
    sphere = replace(model, body_shape=np.where(none, SHAPE_SPHERE, model.body_shape),
                     body_size=size)
    r = np.flatnonzero(rows)
    for ks, out in ((k0, sep0), (k1, sep1)):
        out[r] = pair_geometry(sphere, position, rotation, ks[r], a[r], b[r], with_points=False)
    if not getattr(model, "n_geoms", 0):
        return
    from rblog.analyze import shapes

    body = np.asarray(model.geom_body, np.int64)
    solid = (body >= 0) & (np.asarray(model.geom_type, np.int64) != _plane_code())
    order = np.flatnonzero(solid)[np.argsort(body[solid], kind="stable")]
    lo = np.searchsorted(body[order], np.arange(n), "left")
    hi = np.searchsorted(body[order], np.arange(n), "right")
    bb = np.minimum(b[r], n - 1)
    na, nb = hi[a[r]] - lo[a[r]], hi[bb] - lo[bb]
    u = np.flatnonzero((b[r] < n) & (na > 0) & (nb > 0))
    if not len(u):
        return
    cnt = na[u] * nb[u]
    pair = np.repeat(np.arange(len(u)), cnt)
    q = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    gi = order[lo[a[r][u]][pair] + q // nb[u][pair]]
    gj = order[lo[bb[u]][pair] + q % nb[u][pair]]
    ok = shapes.collide_mask(model, gi, gj)
    pair, gi, gj = pair[ok], gi[ok], gj[ok]
    geoms = shapes.model_geoms(model)
    gpos, grot = shapes.geom_poses(model, position, rotation)
    for ks, out in ((k0, sep0), (k1, sep1)):
        d = shapes.pair_distance(geoms, gpos, grot, ks[r][u][pair], gi, gj,
                                 with_points=False)["sep"]
        least = np.full(len(u), np.inf)
        np.minimum.at(least, pair, d)
        out[r[u]] = least


def _plane_code() -> int:
    from rblog.contract.model import GEOM_PLANE

    return GEOM_PLANE


def shapeless_ground(model: Model, position, rotation, sep) -> None:
    """Overwrite, in place, the ground separations sep (T, N) of bodies without a contract shape
    (plane_separation takes them for points) by their geoms' least height above the plane: each
    geom's centre height less its support along the normal n (sphere r; capsule r + h |z.n|;
    cylinder r sqrt(1 - (z.n)^2) + h |z.n|; box sum_j e_j |n.A_j|; mesh max_v -n.R v; an
    ellipsoid its largest semi-axis, a bound). Bodies without geoms keep their centre's."""
    none = np.asarray(model.body_shape) == SHAPE_NONE
    if not none.any() or not getattr(model, "n_geoms", 0):
        return
    from rblog.analyze import shapes
    from rblog.contract.model import (GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_MESH,
                                      GEOM_SPHERE)

    body = np.asarray(model.geom_body, np.int64)
    gt = np.asarray(model.geom_type, np.int64)
    g = np.flatnonzero((body >= 0) & (gt != _plane_code()))
    g = g[none[body[g]]]
    if not len(g):
        return
    gs = np.asarray(model.geom_size, float).reshape(-1, 3)[g]
    nrm = np.asarray(model.ground_normal, float)
    gpos, grot = shapes.geom_poses(model, position, rotation)
    gpos, grot = gpos[:, g], grot[:, g]  # (T, G, 3), (T, G, 3, 3)
    na = np.abs(np.einsum("i,tgij->tgj", nrm, grot))  # |n . A_j| (T, G, 3)
    t = gt[g]
    sup = np.linalg.norm(gs, axis=1)[None] * np.ones(na.shape[:2])  # a bound (ellipsoid)
    sup = np.where(t == GEOM_SPHERE, gs[:, 0], sup)
    sup = np.where(t == GEOM_CAPSULE, gs[:, 0] + gs[:, 1] * na[..., 2], sup)
    sup = np.where(t == GEOM_CYLINDER, gs[:, 0] * np.sqrt(np.maximum(1 - na[..., 2] ** 2, 0))
                   + gs[:, 1] * na[..., 2], sup)
    sup = np.where(t == GEOM_BOX, (gs[None] * na).sum(axis=2), sup)
    verts = np.asarray(model.mesh_vert, float).reshape(-1, 3) if model.mesh_vert is not None \
        else np.zeros((0, 3))
    for c in np.flatnonzero(t == GEOM_MESH):
        a, k = int(model.geom_vert_adr[g[c]]), int(model.geom_vert_num[g[c]])
        if k:  # max over the vertices v of -n . (R v)
            sup[:, c] = (-np.einsum("i,tij,vj->tv", nrm, grot[:, c], verts[a:a + k])).max(axis=1)
    h = gpos @ nrm - float(model.ground_offset) - sup  # (T, G)
    least = np.full((len(sep), len(none)), np.inf)
    np.minimum.at(least.T, body[g], h.T)
    has = np.isfinite(least[0])
    sep[:, has] = least[:, has]
