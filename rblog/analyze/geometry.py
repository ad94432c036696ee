"""Separations between the logged shapes, recomputed from the logged poses and the model's shapes.

Nothing here reads the contacts a simulator reported: the analyzers judge those against these.

Conventions (those of :class:`rblog.trajectory.Contacts`):

* ``sep`` is the signed distance between two surfaces (m): > 0 apart, < 0 penetration depth.
* ``normal`` is a unit world vector from body b into body a; ``point`` a world point midway
  between the two surfaces (the witness of the contact: centre of the touching face, edge or
  corner when a box lies flat, on an edge or on a corner).
* Poses use the logged ``rotation`` (body->world, columns are the body axes in the world frame),
  as the integrator held it; a drifted matrix maps the shape as drifted.

Shape pairs (``a`` first):

* sphere-plane: ``n.x - offset - r``;  box-plane: ``n.x - offset - sum_j h_j |n.A_j|``.
* sphere-sphere: ``|x_a - x_b| - r_a - r_b`` (exact).
* sphere-box: the sphere centre in the box frame, clamped to the box: exact outside; inside, the
  depth to the nearest face plus the radius (the minimum translation distance).
* box-box: separating-axis test over the 15 axes (3 + 3 face normals, 9 edge cross products):
  ``max_L (|L.(x_a - x_b)| - r_a(L) - r_b(L))``. When the boxes overlap this is exactly minus the
  penetration depth (the minimum translation distance of two convex polyhedra lies on one of these
  axes); when apart it is a lower bound of the distance (exact for face-vertex and edge-edge
  closest features), so a contact test with it errs towards "in contact".

Static boxes and dynamic bodies share one index space in the pair tables: ``b < N`` is a body,
``b = N + m`` is static box ``m``. Only candidate pairs from a broadphase are evaluated: a sweep
(sort-and-sweep on the axis of largest spread, vectorized over every sample interval at once) of
the bounding spheres swept over each interval [k, k+1], so that the same candidates serve the
contact tests at both samples and the tunneling test between them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..model import SHAPE_BOX, SHAPE_SPHERE, Model

#: |cos| below which a box axis counts as parallel to a contact plane (witness points)
_FACE_EPS = 1e-6
#: edge cross products shorter than this are parallel edges (their axis is skipped)
_AXIS_EPS = 1e-6


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) wxyz quaternions (normalized here) -> (..., 3, 3) body->world matrices."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    r = np.empty(q.shape[:-1] + (3, 3))
    r[..., 0, 0] = 1 - 2 * (y * y + z * z)
    r[..., 0, 1] = 2 * (x * y - w * z)
    r[..., 0, 2] = 2 * (x * z + w * y)
    r[..., 1, 0] = 2 * (x * y + w * z)
    r[..., 1, 1] = 1 - 2 * (x * x + z * z)
    r[..., 1, 2] = 2 * (y * z - w * x)
    r[..., 2, 0] = 2 * (x * z - w * y)
    r[..., 2, 1] = 2 * (y * z + w * x)
    r[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return r


def bounding_radius(model: Model) -> np.ndarray:
    """(N,) radius of the sphere about the centre that holds the body (m)."""
    size = np.asarray(model.body_size, float)
    return np.where(model.body_shape == SHAPE_SPHERE, size[:, 0], np.linalg.norm(size, axis=1))


def inner_radius(model: Model) -> np.ndarray:
    """(N,) radius of the largest sphere about the centre inside the body (m)."""
    size = np.asarray(model.body_size, float)
    return np.where(model.body_shape == SHAPE_SPHERE, size[:, 0], size.min(axis=1))


def _box_witness(x: np.ndarray, rot: np.ndarray, h: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The point of boxes (x, rot, h) furthest along d (..., 3): the centre of the face, edge or
    corner that faces d (axes within _FACE_EPS of perpendicular to d contribute their middle)."""
    proj = np.einsum("...ij,...i->...j", rot, d)  # d . A_j
    s = np.where(np.abs(proj) > _FACE_EPS, np.sign(proj), 0.0) * h
    return x + np.einsum("...ij,...j->...i", rot, s)


@njit(cache=True, nogil=True)
def _plane_kernel(position, rotation, is_sphere, size, n, offset, sep, height):
    t_n, nb = position.shape[0], position.shape[1]
    for t in range(t_n):
        for b in range(nb):
            x = position[t, b]
            h = x[0] * n[0] + x[1] * n[1] + x[2] * n[2] - offset
            if is_sphere[b]:
                sup = size[b, 0]
            else:
                r = rotation[t, b]
                sup = 0.0
                for j in range(3):
                    sup += size[b, j] * abs(r[0, j] * n[0] + r[1, j] * n[1] + r[2, j] * n[2])
            height[t, b] = h
            sep[t, b] = h - sup


def plane_separation(model: Model, position: np.ndarray, rotation: np.ndarray):
    """Signed distance of every body to the ground plane.

    Returns (sep (T, N), centre_height (T, N)) in m; centre_height = n.x - offset, and the
    support of a box along n is sum_j h_j |n.A_j|.
    """
    shape = position.shape[:2]
    sep, height = np.empty(shape), np.empty(shape)
    _plane_kernel(np.ascontiguousarray(position, dtype=np.float64),
                  np.ascontiguousarray(rotation, dtype=np.float64),
                  np.asarray(model.body_shape) == SHAPE_SPHERE,
                  np.ascontiguousarray(model.body_size, dtype=np.float64),
                  np.asarray(model.ground_normal, float), float(model.ground_offset), sep, height)
    return sep, height


def plane_witness(model: Model, body: np.ndarray, position: np.ndarray, rotation: np.ndarray):
    """Contact points with the ground of bodies ``body`` (P,) at poses (P, 3), (P, 3, 3)."""
    n = np.asarray(model.ground_normal, float)
    size = np.asarray(model.body_size, float)[body]
    sphere = (model.body_shape[body] == SHAPE_SPHERE)[:, None]
    p_sphere = position - size[:, :1] * n
    p_box = _box_witness(position, rotation, size, -np.broadcast_to(n, position.shape))
    return np.where(sphere, p_sphere, p_box)


# --- narrowphase, vectorized over P pairs ---------------------------------------------------------
def sphere_sphere(xa, ra, xb, rb):
    """Spheres a, b: (sep (P,), normal b->a (P, 3), point (P, 3))."""
    d = xa - xb
    dist = np.linalg.norm(d, axis=-1)
    safe = dist > 0
    n = np.where(safe[:, None], d / np.where(safe, dist, 1.0)[:, None], np.array([0.0, 0.0, 1.0]))
    sep = dist - ra - rb
    point = 0.5 * ((xa - n * ra[:, None]) + (xb + n * rb[:, None]))
    return sep, n, point


def sphere_box(xs, r, xb, rb, hb):
    """Sphere (centre xs, radius r) against box (xb, rotation rb, half-extents hb).

    Returns (sep, normal from the box into the sphere, point on the box surface)."""
    p = np.einsum("pji,pj->pi", rb, xs - xb)  # sphere centre in the box frame (R^T d)
    q = np.clip(p, -hb, hb)
    diff = p - q
    dist = np.linalg.norm(diff, axis=-1)
    outside = dist > 0
    # inside: push out through the nearest face
    depth = hb - np.abs(p)
    j = np.argmin(depth, axis=-1)
    rows = np.arange(len(p))
    sgn = np.where(p[rows, j] >= 0, 1.0, -1.0)
    n_in = np.zeros_like(p)
    n_in[rows, j] = sgn
    q_in = p.copy()
    q_in[rows, j] = sgn * hb[rows, j]
    n_out = diff / np.where(outside, dist, 1.0)[:, None]
    n_loc = np.where(outside[:, None], n_out, n_in)
    q_loc = np.where(outside[:, None], q, q_in)
    sep = np.where(outside, dist - r, -depth[rows, j] - r)
    normal = np.einsum("pij,pj->pi", rb, n_loc)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    point = xb + np.einsum("pij,pj->pi", rb, q_loc)
    return sep, normal, point


def box_box(xa, ra, ha, xb, rb, hb):
    """Boxes a, b by the separating-axis test: (sep, normal b->a, point)."""
    p = len(xa)
    cross = np.cross(ra[:, :, :, None], rb[:, :, None, :], axis=1)  # (P, 3, 3, 3): A_i x B_j
    axes = np.concatenate(
        [np.moveaxis(ra, 1, 2), np.moveaxis(rb, 1, 2), np.moveaxis(cross, 1, 3).reshape(p, 9, 3)],
        axis=1,
    )  # (P, 15, 3), rows are candidate axes
    norm = np.linalg.norm(axes, axis=-1)
    valid = norm > _AXIS_EPS
    axes = axes / np.where(valid, norm, 1.0)[..., None]
    proj_a = np.abs(np.einsum("pki,pij->pkj", axes, ra))
    proj_b = np.abs(np.einsum("pki,pij->pkj", axes, rb))
    rad = (proj_a * ha[:, None, :]).sum(-1) + (proj_b * hb[:, None, :]).sum(-1)
    dc = np.einsum("pki,pi->pk", axes, xa - xb)
    s = np.abs(dc) - rad
    # prefer face axes on ties (parallel faces give equal edge axes): a bias far below any tolerance
    s[:, 6:] -= 1e-12 * (1.0 + rad[:, 6:])
    s = np.where(valid, s, -np.inf)
    k = np.argmax(s, axis=1)
    rows = np.arange(p)
    sep = s[rows, k]
    sep = np.where(k >= 6, sep + 1e-12 * (1.0 + rad[rows, k]), sep)
    n = axes[rows, k] * np.where(dc[rows, k] >= 0, 1.0, -1.0)[:, None]
    pa = _box_witness(xa, ra, ha, -n)
    pb = _box_witness(xb, rb, hb, n)
    return sep, n, 0.5 * (pa + pb)


def _pair_geometry(shape_a, xa, ra, ha, shape_b, xb, rb, hb):
    """Dispatch on the shape pair; every array has P rows. (sep, normal b->a, point)."""
    p = len(xa)
    sep = np.empty(p)
    normal = np.empty((p, 3))
    point = np.empty((p, 3))
    sa = shape_a == SHAPE_SPHERE
    sb = shape_b == SHAPE_SPHERE
    m = sa & sb
    if m.any():
        sep[m], normal[m], point[m] = sphere_sphere(xa[m], ha[m, 0], xb[m], hb[m, 0])
    m = sa & ~sb
    if m.any():
        sep[m], normal[m], point[m] = sphere_box(xa[m], ha[m, 0], xb[m], rb[m], hb[m])
    m = ~sa & sb
    if m.any():  # box a, sphere b: the sphere-box normal points into the sphere (b); flip it
        s_, n_, p_ = sphere_box(xb[m], hb[m, 0], xa[m], ra[m], ha[m])
        sep[m], normal[m], point[m] = s_, -n_, p_
    m = ~sa & ~sb
    if m.any():
        sep[m], normal[m], point[m] = box_box(xa[m], ra[m], ha[m], xb[m], rb[m], hb[m])
    return sep, normal, point


@dataclass
class Proximity:
    """Who is near whom, recomputed from the poses.

    Attributes:
        n_bodies, n_static: N bodies, M static boxes (entity b = N + m).
        ground_sep: (T, N) signed distance to the ground (m), or None without ground.
        ground_height: (T, N) centre height above the ground plane (m), or None.
        pair_*: sample-level table of the candidate pairs, sorted by key (k, a, b): k (sample
            index), a (< N), b (> a), sep (m), normal (b->a), point.
        iv_*: interval-level table: candidate pairs whose swept bounding volumes overlap over the
            interval [k, k+1]: k (interval index), a, b, and i0, i1 indices into the pair table of
            the same pair at samples k and k+1.
    """

    n_bodies: int
    n_static: int
    ground_sep: np.ndarray | None
    ground_height: np.ndarray | None
    pair_k: np.ndarray
    pair_a: np.ndarray
    pair_b: np.ndarray
    pair_sep: np.ndarray
    pair_normal: np.ndarray
    pair_point: np.ndarray
    iv_k: np.ndarray
    iv_a: np.ndarray
    iv_b: np.ndarray
    iv_i0: np.ndarray
    iv_i1: np.ndarray

    @property
    def iv_sep0(self) -> np.ndarray:
        return self.pair_sep[self.iv_i0]

    @property
    def iv_sep1(self) -> np.ndarray:
        return self.pair_sep[self.iv_i1]


def static_boxes(model: Model):
    """(position (M, 3), rotation (M, 3, 3), half extents (M, 3)) of the static boxes."""
    pos = np.asarray(model.static_box_position, float).reshape(-1, 3)
    h = np.asarray(model.static_box_half_extents, float).reshape(-1, 3)
    q = np.asarray(model.static_box_quat_wxyz, float).reshape(-1, 4)
    rot = quat_to_matrix(q) if len(q) else np.zeros((0, 3, 3))
    return pos, rot, h


@njit(cache=True, nogil=True)
def _sweep_kernel(position, grow, s_lo, s_hi, group, axis, out_k, out_a, out_b):
    """Sort-and-sweep over every interval [k, k+1]: the AABB of a body is its centre's box over
    the two samples grown by ``grow[k, i]``; static boxes have fixed AABBs. Pairs overlapping on
    all three axes (not static-static, not in different non-zero groups) are written to out_*
    while they fit; returns how many there are (call again with room for them when more).

    The order of the previous interval seeds an insertion sort, so a scene that moves little
    between samples sorts in linear time."""
    t_n, n = position.shape[0], position.shape[1]
    m = s_lo.shape[0]
    e = n + m
    k_n = t_n - 1 if t_n > 1 else 1
    lo = np.empty((e, 3))
    hi = np.empty((e, 3))
    for j in range(m):
        for d in range(3):
            lo[n + j, d] = s_lo[j, d]
            hi[n + j, d] = s_hi[j, d]
    order = np.arange(e)
    cap = out_k.shape[0]
    cnt = 0
    for k in range(k_n):
        k1 = k + 1 if t_n > 1 else k
        for i in range(n):
            g = grow[k, i]
            for d in range(3):
                a = position[k, i, d]
                b = position[k1, i, d]
                lo[i, d] = min(a, b) - g
                hi[i, d] = max(a, b) + g
        # insertion sort of the previous order on lo[:, axis]
        for p in range(1, e):
            cur = order[p]
            key = lo[cur, axis]
            q = p - 1
            while q >= 0 and lo[order[q], axis] > key:
                order[q + 1] = order[q]
                q -= 1
            order[q + 1] = cur
        for p in range(e):
            i = order[p]
            for q in range(p + 1, e):
                j = order[q]
                if lo[j, axis] > hi[i, axis]:
                    break
                if i >= n and j >= n:
                    continue
                ok = True
                for d in range(3):
                    if lo[j, d] > hi[i, d] or lo[i, d] > hi[j, d]:
                        ok = False
                        break
                if not ok:
                    continue
                a = min(i, j)
                b = max(i, j)
                if b < n and group[a] != 0 and group[b] != 0 and group[a] != group[b]:
                    continue
                if cnt < cap:
                    out_k[cnt] = k
                    out_a[cnt] = a
                    out_b[cnt] = b
                cnt += 1
    return cnt


def sweep_pairs(model: Model, position: np.ndarray, grow: np.ndarray, pad: float = 0.0):
    """Candidate pairs (k, a, b) per interval (see _sweep_kernel); b >= N is static box b - N.

    grow: (K, N) how much each body's AABB is grown (m); static boxes are grown by ``pad``."""
    t_n, n = position.shape[:2]
    sx, sr, sh = static_boxes(model)
    ext = (np.abs(sr) * sh[:, None, :]).sum(-1) if len(sx) else np.zeros((0, 3))
    s_lo, s_hi = sx - ext - pad, sx + ext + pad
    spread = np.ptp(position.reshape(-1, 3), axis=0) if position.size else np.zeros(3)
    axis = int(np.argmax(spread))
    cap = max(1024, 4 * n * max(t_n - 1, 1))
    while True:
        out = [np.empty(cap, np.int64) for _ in range(3)]
        cnt = _sweep_kernel(np.ascontiguousarray(position, dtype=np.float64),
                            np.ascontiguousarray(grow, dtype=np.float64), s_lo, s_hi,
                            np.asarray(model.body_group, np.int64), axis, *out)
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

    # broadphase over intervals (a single "interval" [0, 0] for a one-sample log)
    k_n = t_n - 1 if t_n > 1 else 1
    grow = np.broadcast_to(bounding_radius(model)[None, :] + pad, (k_n, n))
    if sweep is not None and t_n > 1:
        grow = grow + sweep
    k, a, b = sweep_pairs(model, position, grow, pad)

    # sample-level pairs: each candidate at both ends of its interval
    k1 = k + 1 if t_n > 1 else k
    key0 = (k * e + a) * e + b
    key1 = (k1 * e + a) * e + b
    keys, inv = np.unique(np.concatenate([key0, key1]), return_inverse=True)
    pk = keys // (e * e)
    pa = (keys // e) % e
    pb = keys % e
    xa = position[pk, pa]
    ra_ = rotation[pk, pa]
    size = np.asarray(model.body_size, float)
    ha = size[pa]
    dyn_b = pb < n
    pbd = np.where(dyn_b, pb, 0)
    pbs = np.where(dyn_b, 0, pb - n)
    xb = np.where(dyn_b[:, None], position[pk, pbd], sx[pbs] if m else 0.0)
    rb = np.where(dyn_b[:, None, None], rotation[pk, pbd], sr[pbs] if m else 0.0)
    hb = np.where(dyn_b[:, None], size[pbd], sh[pbs] if m else 0.0)
    shape_b = np.where(dyn_b, np.asarray(model.body_shape)[pbd], SHAPE_BOX)
    sep, normal, point = _pair_geometry(np.asarray(model.body_shape)[pa], xa, ra_, ha,
                                        shape_b, xb, rb, hb)
    nk = len(k)
    return Proximity(
        n_bodies=n, n_static=m, ground_sep=ground_sep, ground_height=ground_height,
        pair_k=pk, pair_a=pa, pair_b=pb, pair_sep=sep, pair_normal=normal, pair_point=point,
        iv_k=k, iv_a=a, iv_b=b, iv_i0=inv[:nk], iv_i1=inv[nk:],
    )
