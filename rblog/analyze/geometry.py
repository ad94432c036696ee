"""Separations between the logged shapes, recomputed from the logged poses and the model's shapes.

Nothing here reads the contacts a simulator reported: the analyzers judge those against these.

Conventions (those of :class:`rblog.contract.trajectory.Contacts`):

* ``sep`` is the signed distance between two surfaces (m): > 0 apart, < 0 penetration depth.
* ``normal`` is a unit world vector from body b into body a; ``point`` a world point midway
  between the two surfaces along the normal: the witness of the contact, at the centre of the
  patch where the bodies touch (see "Witness points" below).

Witness points (the contact point whose slip the penetration analyzer integrates as creep, the
lever arm of a contact's velocity in the events analyzer):

* A box's touching feature along a direction d is the set of its points within WITNESS_BAND_M
  (rblog.analyze.tolerances) of its extreme along d: axis j is free (spanned by the feature)
  when ``2 h_j |d.A_j| <= band``, else fixed at ``sign(d.A_j) h_j``. Zero free axes is a
  corner, one an edge, two a face. (A box thinner than the band along every axis keeps its axis
  most along d fixed.)
* box-plane: the centre of the box's feature along -n, moved along n to the level of the box's
  lowest point (by at most the band), so that ``n.point - offset`` is the separation.
* box-box: the two features (a's along -n, b's along +n) projected onto the contact plane; the
  centre of their intersection there, placed midway between the two surfaces along n. Corner vs
  anything: the corner (two corners: their midpoint). Edge vs edge: the closest points of the two
  segments (their crossing; parallel edges, ``|sin| x length <= band``: the middle of their
  overlap). Edge vs face: the middle of the part of the edge inside the face (nothing inside,
  the two just apart: the midpoint of their closest points). Face vs face: the area centroid of
  the overlap of the two face polygons (Sutherland-Hodgman; a zero-area overlap: its vertices'
  mean; none: the midpoint of the faces' centres).
* spheres: the point midway between the surfaces on the line of centres (sphere-sphere), the
  point of the box's surface nearest the sphere (sphere-box).
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
``b = N + m`` is static box ``m``. Only candidate pairs from a broadphase are evaluated: a
compiled sort-and-sweep (on the axis of largest spread, insertion-sorted from the previous
interval's order) of each body's bounding sphere swept over each sample interval [k, k+1] and
grown by how far the body can stray from the straight path (a body that bounces back between
samples is never on the chord), so that the same candidates serve the contact tests at both
samples and the tunneling test between them. The narrowphase is numpy, vectorized over the
candidates of every interval at once.

Why this module is long: it is the analyzers' own geometry (separations of sphere, box and plane
pairs, bounding radii, the sweep), independent of the engine's narrowphase on purpose; one file
keeps that independent geometry in one place.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from rblog.analyze.tolerances import WITNESS_BAND_M
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE, Model

#: thickness of a box's touching feature (m; see WITNESS_BAND_M)
_BAND = WITNESS_BAND_M
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


@njit(cache=True, nogil=True)
def _feature_signs(p0, p1, p2, h0, h1, h2, band):
    """A box's touching feature along d, from p_j = d.A_j and the half extents h_j:
    (s0, s1, s2, free0, free1, free2, drop). Axis j is free (the feature spans it) when
    2 h_j |p_j| <= band, s_j = 0; else s_j = sign(p_j) h_j. The feature's centre is
    x + sum_j s_j A_j; the box reaches further along d than that centre by
    drop = sum over free axes of h_j |p_j| (<= 1.5 band). A box thinner than the band along
    every axis keeps its axis most along d fixed (a face, not the whole box)."""
    f0 = 2.0 * h0 * abs(p0) <= band
    f1 = 2.0 * h1 * abs(p1) <= band
    f2 = 2.0 * h2 * abs(p2) <= band
    if f0 and f1 and f2:
        a0, a1, a2 = abs(p0), abs(p1), abs(p2)
        if a0 >= a1 and a0 >= a2:
            f0 = False
        elif a1 >= a2:
            f1 = False
        else:
            f2 = False
    s0 = 0.0 if f0 else (h0 if p0 > 0 else -h0)
    s1 = 0.0 if f1 else (h1 if p1 > 0 else -h1)
    s2 = 0.0 if f2 else (h2 if p2 > 0 else -h2)
    drop = ((h0 * abs(p0) if f0 else 0.0) + (h1 * abs(p1) if f1 else 0.0)
            + (h2 * abs(p2) if f2 else 0.0))
    return s0, s1, s2, f0, f1, f2, drop


@njit(cache=True, nogil=True)
def _witness_kernel(position, rotation, k, j, body, is_sphere, size, n, band, out, spn):
    """out[r] = the ground contact point of body[r] at the pose position[k[r], j[r]],
    rotation[k[r], j[r]]: a sphere's lowest point; a box's touching feature along -n (axes with
    2 h_c |n.A_c| <= band free, the others at their extreme), its centre moved along -n to the
    level of the box's lowest point (by sum over free axes of h_c |n.A_c|). spn[r] (when spn
    has rows): an edge's half-span h_c A_c (the patch is out[r] +- spn[r]), else 0."""
    for r in range(k.shape[0]):
        kr, jr, b = k[r], j[r], body[r]
        x = position[kr, jr]
        if is_sphere[b]:
            for i in range(3):
                out[r, i] = x[i] - size[b, 0] * n[i]
            continue
        rot = rotation[kr, jr]
        p0 = rot[0, 0] * -n[0] + rot[1, 0] * -n[1] + rot[2, 0] * -n[2]  # -n . A_c
        p1 = rot[0, 1] * -n[0] + rot[1, 1] * -n[1] + rot[2, 1] * -n[2]
        p2 = rot[0, 2] * -n[0] + rot[1, 2] * -n[1] + rot[2, 2] * -n[2]
        s0, s1, s2, f0, f1, f2, drop = _feature_signs(p0, p1, p2, size[b, 0], size[b, 1],
                                                      size[b, 2], band)
        for i in range(3):
            out[r, i] = x[i] + (rot[i, 0] * s0 + rot[i, 1] * s1 + rot[i, 2] * s2) - drop * n[i]
        if spn.shape[0] and int(f0) + int(f1) + int(f2) == 1:
            c = 0 if f0 else (1 if f1 else 2)
            for i in range(3):
                spn[r, i] = size[b, c] * rot[i, c]


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
    _witness_kernel(c(position, dtype=np.float64), c(rotation, dtype=np.float64),
                    c(k, dtype=np.int64), c(j, dtype=np.int64), c(body, dtype=np.int64),
                    np.asarray(model.body_shape) == SHAPE_SPHERE,
                    c(model.body_size, dtype=np.float64),
                    c(model.ground_normal, dtype=np.float64), _BAND, out, spn)
    return (out, spn) if with_span else out


# --- narrowphase: compiled, one pair at a time --------------------------------------------------
# Poses travel as tuples (no array views, so no reference counting in the inner loops): x is
# (x0, x1, x2), r the row-major 9-tuple of the matrix (r[3 i + j] = R_ij), h the half extents.
@njit(cache=True, nogil=True)
def _sphere_sphere(xa, ra, xb, rb):
    """(sep, n0, n1, n2, p0, p1, p2) with n from b into a."""
    d0, d1, d2 = xa[0] - xb[0], xa[1] - xb[1], xa[2] - xb[2]
    dist = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if dist > 0:
        n0, n1, n2 = d0 / dist, d1 / dist, d2 / dist
    else:
        n0, n1, n2 = 0.0, 0.0, 1.0
    return (dist - ra - rb, n0, n1, n2,
            0.5 * (xa[0] + xb[0] + n0 * (rb - ra)), 0.5 * (xa[1] + xb[1] + n1 * (rb - ra)),
            0.5 * (xa[2] + xb[2] + n2 * (rb - ra)))


@njit(cache=True, nogil=True)
def _sphere_box(xs, r, xb, rb, hb):
    """Sphere against box: (sep, n (from the box into the sphere), p on the box surface)."""
    e0, e1, e2 = xs[0] - xb[0], xs[1] - xb[1], xs[2] - xb[2]
    # sphere centre in the box frame: R^T (xs - xb), and its clamp to the box
    l0 = rb[0] * e0 + rb[3] * e1 + rb[6] * e2
    l1 = rb[1] * e0 + rb[4] * e1 + rb[7] * e2
    l2 = rb[2] * e0 + rb[5] * e1 + rb[8] * e2
    q0 = min(max(l0, -hb[0]), hb[0])
    q1 = min(max(l1, -hb[1]), hb[1])
    q2 = min(max(l2, -hb[2]), hb[2])
    f0, f1, f2 = l0 - q0, l1 - q1, l2 - q2
    dist = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    if dist > 0:
        m0, m1, m2 = f0 / dist, f1 / dist, f2 / dist
        sep = dist - r
    else:  # inside: out through the nearest face
        g0, g1, g2 = hb[0] - abs(l0), hb[1] - abs(l1), hb[2] - abs(l2)
        m0 = m1 = m2 = 0.0
        if g0 <= g1 and g0 <= g2:
            m0 = 1.0 if l0 >= 0 else -1.0
            q0 = m0 * hb[0]
            sep = -g0 - r
        elif g1 <= g2:
            m1 = 1.0 if l1 >= 0 else -1.0
            q1 = m1 * hb[1]
            sep = -g1 - r
        else:
            m2 = 1.0 if l2 >= 0 else -1.0
            q2 = m2 * hb[2]
            sep = -g2 - r
    n0 = rb[0] * m0 + rb[1] * m1 + rb[2] * m2
    n1 = rb[3] * m0 + rb[4] * m1 + rb[5] * m2
    n2 = rb[6] * m0 + rb[7] * m1 + rb[8] * m2
    nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    return (sep, n0 / nn, n1 / nn, n2 / nn,
            xb[0] + rb[0] * q0 + rb[1] * q1 + rb[2] * q2,
            xb[1] + rb[3] * q0 + rb[4] * q1 + rb[5] * q2,
            xb[2] + rb[6] * q0 + rb[7] * q1 + rb[8] * q2)


@njit(cache=True, nogil=True)
def _box_box(xa, ra, ha, xb, rb, hb):
    """Separating-axis test over the 15 axes: (sep, n from b into a)."""
    d0, d1, d2 = xa[0] - xb[0], xa[1] - xb[1], xa[2] - xb[2]
    best_cmp = -math.inf
    best = -math.inf
    n0 = n1 = n2 = 0.0
    for ax in range(15):
        if ax < 3:
            l0, l1, l2 = ra[ax], ra[3 + ax], ra[6 + ax]
        elif ax < 6:
            l0, l1, l2 = rb[ax - 3], rb[ax], rb[ax + 3]
        else:
            i, j = (ax - 6) // 3, (ax - 6) % 3
            a0, a1, a2 = ra[i], ra[3 + i], ra[6 + i]
            b0, b1, b2 = rb[j], rb[3 + j], rb[6 + j]
            l0, l1, l2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
        norm = math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
        if norm <= _AXIS_EPS:
            continue
        l0, l1, l2 = l0 / norm, l1 / norm, l2 / norm
        rad = 0.0
        for j in range(3):
            rad += ha[j] * abs(l0 * ra[j] + l1 * ra[3 + j] + l2 * ra[6 + j])
            rad += hb[j] * abs(l0 * rb[j] + l1 * rb[3 + j] + l2 * rb[6 + j])
        dc = l0 * d0 + l1 * d1 + l2 * d2
        sv = abs(dc) - rad
        # prefer face axes on ties (parallel faces give equal edge axes)
        cmp = sv - 1e-12 * (1.0 + rad) if ax >= 6 else sv
        if cmp > best_cmp:
            best_cmp = cmp
            best = sv
            sg = 1.0 if dc >= 0 else -1.0
            n0, n1, n2 = sg * l0, sg * l1, sg * l2
    return best, n0, n1, n2


# --- box-box witness: the centre of the touching patch, in the contact plane --------------------
# Features are projected onto the plane normal to n, in coordinates (u, v) about the midpoint o of
# the two centres: a feature is (cx, cy, free axes, e1, e2, support), its centre c and the
# projections e of h_j A_j of its free axes (none: a corner; one: an edge c +- e1; two: a face,
# the parallelogram c +- e1 +- e2).
@njit(cache=True, nogil=True)
def _plane_basis(n0, n1, n2):
    """Unit u, v with (u, v, n) orthonormal."""
    if abs(n0) > 0.57735:
        u0, u1, u2 = n1, -n0, 0.0
    else:
        u0, u1, u2 = 0.0, n2, -n1
    un = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    u0, u1, u2 = u0 / un, u1 / un, u2 / un
    return (u0, u1, u2), (n1 * u2 - n2 * u1, n2 * u0 - n0 * u2, n0 * u1 - n1 * u0)


@njit(cache=True, nogil=True)
def _feature_2d(x, r, h, d0, d1, d2, o, u, v):
    """The touching feature of box (x, r, h) along d in plane coordinates about o:
    (cx, cy, n_free, e1x, e1y, e2x, e2y, support of the box along d from its centre)."""
    p0 = r[0] * d0 + r[3] * d1 + r[6] * d2
    p1 = r[1] * d0 + r[4] * d1 + r[7] * d2
    p2 = r[2] * d0 + r[5] * d1 + r[8] * d2
    s0, s1, s2, f0, f1, f2, _ = _feature_signs(p0, p1, p2, h[0], h[1], h[2], _BAND)
    c0 = x[0] - o[0] + (r[0] * s0 + r[1] * s1 + r[2] * s2)
    c1 = x[1] - o[1] + (r[3] * s0 + r[4] * s1 + r[5] * s2)
    c2 = x[2] - o[2] + (r[6] * s0 + r[7] * s1 + r[8] * s2)
    nf = 0
    e1x = e1y = e2x = e2y = 0.0
    for j in range(3):
        if (f0 if j == 0 else (f1 if j == 1 else f2)):
            a0, a1, a2 = h[j] * r[j], h[j] * r[3 + j], h[j] * r[6 + j]
            ex = a0 * u[0] + a1 * u[1] + a2 * u[2]
            ey = a0 * v[0] + a1 * v[1] + a2 * v[2]
            if nf == 0:
                e1x, e1y = ex, ey
            else:
                e2x, e2y = ex, ey
            nf += 1
    return (c0 * u[0] + c1 * u[1] + c2 * u[2], c0 * v[0] + c1 * v[1] + c2 * v[2], nf,
            e1x, e1y, e2x, e2y, h[0] * abs(p0) + h[1] * abs(p1) + h[2] * abs(p2))


@njit(cache=True, nogil=True)
def _seg_closest(p1x, p1y, d1x, d1y, p2x, p2y, d2x, d2y):
    """Closest points of segments p1 + s d1 and p2 + t d2 (s, t in [0, 1]; Ericson, Real-Time
    Collision Detection 5.1.9): (their midpoint x, y, squared distance)."""
    rx, ry = p1x - p2x, p1y - p2y
    a = d1x * d1x + d1y * d1y
    e = d2x * d2x + d2y * d2y
    f = d2x * rx + d2y * ry
    tiny = 1e-300
    if a <= tiny and e <= tiny:
        s = t = 0.0
    elif a <= tiny:
        s = 0.0
        t = min(max(f / e, 0.0), 1.0)
    else:
        c = d1x * rx + d1y * ry
        if e <= tiny:
            t = 0.0
            s = min(max(-c / a, 0.0), 1.0)
        else:
            b = d1x * d2x + d1y * d2y
            den = a * e - b * b
            s = min(max((b * f - c * e) / den, 0.0), 1.0) if den > 0 else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = min(max(-c / a, 0.0), 1.0)
            elif t > 1.0:
                t = 1.0
                s = min(max((b - c) / a, 0.0), 1.0)
    q1x, q1y = p1x + s * d1x, p1y + s * d1y
    q2x, q2y = p2x + t * d2x, p2y + t * d2y
    return 0.5 * (q1x + q2x), 0.5 * (q1y + q2y), (q1x - q2x) ** 2 + (q1y - q2y) ** 2


@njit(cache=True, nogil=True)
def _edge_edge(ax, ay, eax, eay, bx, by, ebx, eby):
    """Edges a +- ea, b +- eb: parallel (the tilt between them moves an end by at most the band)
    -> the middle of their overlap along a, halfway to b's line; else the closest points."""
    la = math.sqrt(eax * eax + eay * eay)
    lb = math.sqrt(ebx * ebx + eby * eby)
    cr = eax * eby - eay * ebx
    if la > 0 and lb > 0 and abs(cr) / (la * lb) * 2.0 * max(la, lb) <= _BAND:
        dx, dy = eax / la, eay / la
        wx, wy = bx - ax, by - ay
        tc = wx * dx + wy * dy
        hl = abs(ebx * dx + eby * dy)
        tm = 0.5 * (max(-la, tc - hl) + min(la, tc + hl))  # in the gap when they do not overlap
        return ax + tm * dx + 0.5 * (wx - tc * dx), ay + tm * dy + 0.5 * (wy - tc * dy)
    mx, my, _ = _seg_closest(ax - eax, ay - eay, 2 * eax, 2 * eay, bx - ebx, by - eby, 2 * ebx,
                             2 * eby)
    return mx, my


@njit(cache=True, nogil=True)
def _slab(a0, ad, lo, hi):
    """Clip the parameter range [lo, hi] of t to |a0 + t ad| <= 1."""
    if ad == 0.0:
        return (lo, hi) if abs(a0) <= 1.0 else (1.0, -1.0)
    t1, t2 = (-1.0 - a0) / ad, (1.0 - a0) / ad
    return max(lo, min(t1, t2)), min(hi, max(t1, t2))


@njit(cache=True, nogil=True)
def _edge_face(cx, cy, ex, ey, fx, fy, g1x, g1y, g2x, g2y):
    """Edge c +- e against the face parallelogram f +- g1 +- g2: (x, y, sx, sy), the middle of the
    part of the edge inside the face and half that part (the part is (x, y) +- (sx, sy)); none
    inside, the midpoint of the closest points of the edge and the face's boundary, and no span."""
    det = g1x * g2y - g1y * g2x
    if abs(det) > 0.0:
        # face coordinates (alpha, beta) of c + t e: the face is |alpha|, |beta| <= 1
        qx, qy = cx - fx, cy - fy
        lo, hi = _slab((qx * g2y - qy * g2x) / det, (ex * g2y - ey * g2x) / det, -1.0, 1.0)
        lo, hi = _slab((g1x * qy - g1y * qx) / det, (g1x * ey - g1y * ex) / det, lo, hi)
        if lo <= hi:
            tm = 0.5 * (lo + hi)
            th = 0.5 * (hi - lo)
            return cx + tm * ex, cy + tm * ey, th * ex, th * ey
    best = math.inf
    bx = by = 0.0
    for k in range(4):  # the face's four sides
        px, py = _face_corner(fx, fy, g1x, g1y, g2x, g2y, k)
        qx, qy = _face_corner(fx, fy, g1x, g1y, g2x, g2y, (k + 1) % 4)
        mx, my, d2 = _seg_closest(cx - ex, cy - ey, 2 * ex, 2 * ey, px, py, qx - px, qy - py)
        if d2 < best:
            best, bx, by = d2, mx, my
    return bx, by, 0.0, 0.0


@njit(cache=True, nogil=True)
def _face_corner(fx, fy, g1x, g1y, g2x, g2y, k):
    """Corner k (0..3, cyclic: + +, - +, - -, + -) of the parallelogram f +- g1 +- g2."""
    s1 = 1.0 if (k == 0 or k == 3) else -1.0
    s2 = 1.0 if k < 2 else -1.0
    return fx + s1 * g1x + s2 * g2x, fy + s1 * g1y + s2 * g2y


@njit(cache=True, nogil=True)
def _face_face(fa, fb, buf):
    """Area centroid of the overlap of face parallelograms fa, fb (features of _feature_2d):
    a's polygon clipped by each edge of b's (Sutherland-Hodgman; buf (4, W) holds the polygons).
    A zero-area overlap: its vertices' mean; no overlap: the midpoint of the two centres."""
    w = buf.shape[1]
    for k in range(4):
        buf[0, k], buf[1, k] = _face_corner(fa[0], fa[1], fa[3], fa[4], fa[5], fa[6], k)
    m = 4
    src = 0
    det_b = fb[3] * fb[6] - fb[4] * fb[5]
    orient = 1.0 if det_b >= 0 else -1.0  # b's corners run counter-clockwise when det_b > 0
    for e in range(4):
        px, py = _face_corner(fb[0], fb[1], fb[3], fb[4], fb[5], fb[6], e)
        qx, qy = _face_corner(fb[0], fb[1], fb[3], fb[4], fb[5], fb[6], (e + 1) % 4)
        ex, ey = qx - px, qy - py
        dst = 2 - src
        cnt = 0
        for i in range(m):
            ax, ay = buf[src, i], buf[src + 1, i]
            j = i + 1 if i + 1 < m else 0
            bx, by = buf[src, j], buf[src + 1, j]
            da = orient * (ex * (ay - py) - ey * (ax - px))  # >= 0: inside b's edge e
            db = orient * (ex * (by - py) - ey * (bx - px))
            if da >= 0 and cnt < w:
                buf[dst, cnt], buf[dst + 1, cnt] = ax, ay
                cnt += 1
            if ((da >= 0) != (db >= 0)) and cnt < w:
                t = da / (da - db)
                buf[dst, cnt], buf[dst + 1, cnt] = ax + t * (bx - ax), ay + t * (by - ay)
                cnt += 1
        m = cnt
        src = dst
        if m == 0:
            return 0.5 * (fa[0] + fb[0]), 0.5 * (fa[1] + fb[1])
    # area centroid by a fan of triangles from vertex 0
    x0, y0 = buf[src, 0], buf[src + 1, 0]
    a2 = sx = sy = 0.0
    mx, my = x0, y0
    for i in range(1, m):
        xi, yi = buf[src, i], buf[src + 1, i]
        mx += xi
        my += yi
        if i + 1 < m:
            xj, yj = buf[src, i + 1], buf[src + 1, i + 1]
            cr = (xi - x0) * (yj - y0) - (xj - x0) * (yi - y0)
            a2 += cr
            sx += cr * (xi + xj - 2 * x0)
            sy += cr * (yi + yj - 2 * y0)
    det_a = fa[3] * fa[6] - fa[4] * fa[5]
    if abs(a2) > 1e-9 * min(abs(det_a), abs(det_b)):
        return x0 + sx / (3 * a2), y0 + sy / (3 * a2)
    return mx / m, my / m


@njit(cache=True, nogil=True)
def _box_box_point(xa, ra, ha, xb, rb, hb, n0, n1, n2, buf):
    """Witness of boxes a, b touching along n (from b into a): the centre of the intersection of
    a's feature along -n and b's along +n in the contact plane, midway between the surfaces, and
    the patch's half-span (3,): half the part of an edge that lies on a face (the patch is the
    segment point +- span), else 0 (a point, or a face overlap judged at its centroid)."""
    o = (0.5 * (xa[0] + xb[0]), 0.5 * (xa[1] + xb[1]), 0.5 * (xa[2] + xb[2]))
    u, v = _plane_basis(n0, n1, n2)
    fa = _feature_2d(xa, ra, ha, -n0, -n1, -n2, o, u, v)
    fb = _feature_2d(xb, rb, hb, n0, n1, n2, o, u, v)
    na, nb = fa[2], fb[2]
    sx = sy = 0.0
    if na == 0 and nb == 0:  # corner on corner
        px, py = 0.5 * (fa[0] + fb[0]), 0.5 * (fa[1] + fb[1])
    elif na == 0:  # a's corner
        px, py = fa[0], fa[1]
    elif nb == 0:
        px, py = fb[0], fb[1]
    elif na == 1 and nb == 1:
        px, py = _edge_edge(fa[0], fa[1], fa[3], fa[4], fb[0], fb[1], fb[3], fb[4])
    elif na == 1:
        px, py, sx, sy = _edge_face(fa[0], fa[1], fa[3], fa[4], fb[0], fb[1], fb[3], fb[4], fb[5],
                                    fb[6])
    elif nb == 1:
        px, py, sx, sy = _edge_face(fb[0], fb[1], fb[3], fb[4], fa[0], fa[1], fa[3], fa[4], fa[5],
                                    fa[6])
    else:
        px, py = _face_face(fa, fb, buf)
    # along n: midway between a's extreme along -n and b's along +n
    z = 0.5 * (fb[7] - fa[7])
    return (o[0] + px * u[0] + py * v[0] + z * n0, o[1] + px * u[1] + py * v[1] + z * n1,
            o[2] + px * u[2] + py * v[2] + z * n2,
            sx * u[0] + sy * v[0], sx * u[1] + sy * v[1], sx * u[2] + sy * v[2])


@njit(cache=True, nogil=True)
def _pair(sa, xa, ra, ha, sb, xb, rb, hb, with_point, buf):
    """Dispatch on the shape pair: (sep, n from b into a, point, span), span the half-span of an
    edge patch (see _box_box_point; 0 for spheres); the box-box point and span only when
    ``with_point`` (else 0)."""
    if sa == SHAPE_SPHERE and sb == SHAPE_SPHERE:
        return _sphere_sphere(xa, ha[0], xb, hb[0]) + (0.0, 0.0, 0.0)
    if sa == SHAPE_SPHERE:
        return _sphere_box(xa, ha[0], xb, rb, hb) + (0.0, 0.0, 0.0)
    if sb == SHAPE_SPHERE:  # box a, sphere b: the sphere-box normal points into b; flip it
        s_, n0, n1, n2, p0, p1, p2 = _sphere_box(xb, hb[0], xa, ra, ha)
        return s_, -n0, -n1, -n2, p0, p1, p2, 0.0, 0.0, 0.0
    sep, n0, n1, n2 = _box_box(xa, ra, ha, xb, rb, hb)
    p0 = p1 = p2 = e0 = e1 = e2 = 0.0
    if with_point:
        p0, p1, p2, e0, e1, e2 = _box_box_point(xa, ra, ha, xb, rb, hb, n0, n1, n2, buf)
    return sep, n0, n1, n2, p0, p1, p2, e0, e1, e2


@njit(cache=True, nogil=True)
def _vec(a, i, j):
    return a[i, j, 0], a[i, j, 1], a[i, j, 2]


@njit(cache=True, nogil=True)
def _mat(a, i, j):
    return (a[i, j, 0, 0], a[i, j, 0, 1], a[i, j, 0, 2], a[i, j, 1, 0], a[i, j, 1, 1],
            a[i, j, 1, 2], a[i, j, 2, 0], a[i, j, 2, 1], a[i, j, 2, 2])


@njit(cache=True, nogil=True)
def _pairs_kernel(ks, a, b, position, rotation, shape, size, s_pos, s_rot, s_half, sep, nrm, pt,
                  spn, with_points):
    """Geometry of rows (ks, a, b): b < N a body at sample ks, else static box b - N.

    position (T, E, 3), rotation (T, E, 3, 3) and size (E, 3) cover bodies only; s_* the static
    boxes as (1, M, 3), (1, M, 3, 3), (M, 3)."""
    nb = position.shape[1]
    buf = np.empty((4, 32))  # polygons of the face-face witness
    for r in range(ks.shape[0]):
        k, ia, ib = ks[r], a[r], b[r]
        xa, ra, ha = _vec(position, k, ia), _mat(rotation, k, ia), (size[ia, 0], size[ia, 1],
                                                                     size[ia, 2])
        if ib < nb:
            xb, rb, hb = _vec(position, k, ib), _mat(rotation, k, ib), (size[ib, 0], size[ib, 1],
                                                                        size[ib, 2])
            sb = shape[ib]
        else:
            m = ib - nb
            xb, rb, hb = _vec(s_pos, 0, m), _mat(s_rot, 0, m), (s_half[m, 0], s_half[m, 1],
                                                                 s_half[m, 2])
            sb = SHAPE_BOX
        out = _pair(shape[ia], xa, ra, ha, sb, xb, rb, hb, with_points, buf)
        sep[r] = out[0]
        if with_points:
            nrm[r, 0], nrm[r, 1], nrm[r, 2] = out[1], out[2], out[3]
            pt[r, 0], pt[r, 1], pt[r, 2] = out[4], out[5], out[6]
            if spn.shape[0]:
                spn[r, 0], spn[r, 1], spn[r, 2] = out[7], out[8], out[9]


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
    _pairs_kernel(c(ks, dtype=np.int64), c(a, dtype=np.int64), c(b, dtype=np.int64),
                  c(position, dtype=np.float64), c(rotation, dtype=np.float64),
                  c(model.body_shape, dtype=np.int64), c(model.body_size, dtype=np.float64),
                  c(sx[None]), c(sr[None]), c(sh), sep, nrm, pt, spn, with_points)
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


@njit(cache=True, nogil=True)
def _shell_sort(order, key):
    """Sort the index array ``order`` by ``key`` in place (Shell sort, Ciura's gaps: short to
    compile, O(n^1.3) in practice)."""
    n = order.shape[0]
    for gap in (701, 301, 132, 57, 23, 10, 4, 1):
        for i in range(gap, n):
            cur = order[i]
            kv = key[cur]
            j = i
            while j >= gap and key[order[j - gap]] > kv:
                order[j] = order[j - gap]
                j -= gap
            order[j] = cur


@njit(cache=True, nogil=True)
def _sweep_kernel(position, grow, s_lo, s_hi, group, axis, out_k, out_a, out_b):
    """Sort-and-sweep over every interval [k, k+1]: the AABB of a body is its centre's box over
    the two samples grown by ``grow[k, i]``; static boxes have fixed AABBs. Pairs overlapping on
    all three axes (not static-static, not in different non-zero groups) whose bounding spheres
    also meet (for two bodies: spheres about the middle of each centre's chord, radius half the
    chord plus ``grow``) are written to out_* while they fit; returns how many there are (call
    again with room for them when more).

    The order of the previous interval seeds an insertion sort, so a scene that moves little
    between samples sorts in linear time."""
    t_n, n = position.shape[0], position.shape[1]
    m = s_lo.shape[0]
    e = n + m
    k_n = t_n - 1 if t_n > 1 else 1
    lo = np.empty((e, 3))
    hi = np.empty((e, 3))
    mid = np.empty((n, 3))
    reach = np.empty(n)
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
            half2 = 0.0
            for d in range(3):
                a = position[k, i, d]
                b = position[k1, i, d]
                lo[i, d] = min(a, b) - g
                hi[i, d] = max(a, b) + g
                mid[i, d] = 0.5 * (a + b)
                half2 += 0.25 * (b - a) * (b - a)
            reach[i] = g + math.sqrt(half2)  # a sphere about the chord's middle holds the path
        # insertion sort of the previous order on lo[:, axis]; a full sort when that would take
        # more than a few moves per entity (the first interval, bodies that jump around)
        moves = 0
        for p in range(1, e):
            cur = order[p]
            key = lo[cur, axis]
            q = p - 1
            while q >= 0 and lo[order[q], axis] > key:
                order[q + 1] = order[q]
                q -= 1
            order[q + 1] = cur
            moves += p - 1 - q
            if moves > 8 * e + 64:
                _shell_sort(order, lo[:, axis])
                break
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
                if b < n:
                    if group[a] != 0 and group[b] != 0 and group[a] != group[b]:
                        continue
                    dd = 0.0
                    for d in range(3):
                        dd += (mid[a, d] - mid[b, d]) ** 2
                    if dd > (reach[a] + reach[b]) ** 2:
                        continue
                if cnt < cap:
                    out_k[cnt] = k
                    out_a[cnt] = a
                    out_b[cnt] = b
                cnt += 1
    return cnt


@njit(cache=True, nogil=True)
def _spread(x):
    """(3,) max - min of the rows of x (P, 3) (np.ptp(x, axis=0) in one pass; NaN in a column
    makes its spread NaN, as there)."""
    lo = x[0].copy()
    hi = x[0].copy()
    for p in range(1, x.shape[0]):
        for d in range(3):
            v = x[p, d]
            if v < lo[d]:
                lo[d] = v
            if v > hi[d]:
                hi[d] = v
            if v != v:
                lo[d] = v
                hi[d] = v
    out = hi - lo
    for d in range(3):
        for p in range(x.shape[0]):
            if x[p, d] != x[p, d]:
                out[d] = np.nan
                break
    return out


def sweep_pairs(model: Model, position: np.ndarray, grow: np.ndarray, pad: float = 0.0):
    """Candidate pairs (k, a, b) per interval (see _sweep_kernel); b >= N is static box b - N.

    grow: (K, N) how much each body's AABB is grown (m); static boxes are grown by ``pad``."""
    t_n, n = position.shape[:2]
    sx, sr, sh = static_boxes(model)
    ext = (np.abs(sr) * sh[:, None, :]).sum(-1) if len(sx) else np.zeros((0, 3))
    s_lo, s_hi = sx - ext - pad, sx + ext + pad
    spread = _spread(np.ascontiguousarray(position, dtype=np.float64).reshape(-1, 3)) \
        if position.size else np.zeros(3)
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

    # separations of every candidate at both ends of its interval
    k1 = k + 1 if t_n > 1 else k
    sep0 = pair_geometry(model, position, rotation, k, a, b, with_points=False)
    sep1 = pair_geometry(model, position, rotation, k1, a, b, with_points=False)
    return Proximity(
        model=model, position=position, rotation=rotation,
        n_bodies=n, n_static=m, ground_sep=ground_sep, ground_height=ground_height,
        iv_k=k, iv_a=a, iv_b=b, iv_sep0=sep0, iv_sep1=sep1,
    )
