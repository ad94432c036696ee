"""Narrowphase: contact manifolds of a pair of shapes, through a table keyed by the shape pair.

Conventions (the :class:`rblog.contract.trajectory.Contacts` record uses the same ones):

* A collider ``collide_X_Y(shape X = "a", shape Y = "b", ...)`` returns a manifold of up to four
  points sharing one ``normal``, a unit world vector pointing **from b into a** (the direction in
  which a must move to separate).
* ``separation`` is the signed gap along the normal (m): > 0 apart, < 0 penetration. Points are
  kept while the gap is below ``spec`` (speculative contacts), so a point can have separation > 0.
* ``point`` is the midpoint between the two surfaces (Box2D's convention), world frame.
* ``fid`` is a feature id (which vertex, edge or clip produced the point) used to carry the
  solver's impulses from one step to the next (warm starting).

Dispatch: geometry types are ``GEOM_SPHERE``, ``GEOM_BOX`` (dynamic or static boxes) and
``GEOM_PLANE`` (the ground). :data:`COLLIDE_TABLE` maps (lower type, higher type) to a collider
code; the pair is swapped (and the normal negated) when the lower type is on body b. A pair with
no entry is an error (:class:`UnsupportedShapePair`), raised when the world is built, never a
silent skip.

Box-box follows the separating-axis test of Gottschalk et al. (15 axes) with the face/edge
preference tolerances of Gregorius (GDC 2013, 2015): a face axis is kept unless an edge axis is
clearly better, so manifolds stay coherent from step to step. A face contact clips the incident
face against the side planes of the reference face (Sutherland-Hodgman) and reduces the clipped
polygon to four points (deepest point, farthest point, largest triangle, largest quad).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rblog.errors import RblogError
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE

GEOM_SPHERE = 0
GEOM_BOX = 1
GEOM_PLANE = 2
GEOM_NAMES = {GEOM_SPHERE: "sphere", GEOM_BOX: "box", GEOM_PLANE: "plane"}
#: Model.body_shape -> geometry type
SHAPE_TO_GEOM = {SHAPE_SPHERE: GEOM_SPHERE, SHAPE_BOX: GEOM_BOX}

COLLIDE_NONE = -1
COLLIDE_SPHERE_SPHERE = 0
COLLIDE_SPHERE_BOX = 1
COLLIDE_BOX_BOX = 2
COLLIDE_SPHERE_PLANE = 3
COLLIDE_BOX_PLANE = 4

#: (lower geometry type, higher geometry type) -> (collider code, collider name)
NARROWPHASE_TABLE = {
    (GEOM_SPHERE, GEOM_SPHERE): (COLLIDE_SPHERE_SPHERE, "collide_sphere_sphere"),
    (GEOM_SPHERE, GEOM_BOX): (COLLIDE_SPHERE_BOX, "collide_sphere_box"),
    (GEOM_BOX, GEOM_BOX): (COLLIDE_BOX_BOX, "collide_box_box"),
    (GEOM_SPHERE, GEOM_PLANE): (COLLIDE_SPHERE_PLANE, "collide_sphere_plane"),
    (GEOM_BOX, GEOM_PLANE): (COLLIDE_BOX_PLANE, "collide_box_plane"),
}
#: the same table as an array for the kernels: COLLIDE_TABLE[lo, hi] -> collider code or -1
COLLIDE_TABLE = np.full((3, 3), COLLIDE_NONE, np.int64)
for (_lo, _hi), (_code, _name) in NARROWPHASE_TABLE.items():
    COLLIDE_TABLE[_lo, _hi] = _code

#: rows of the collider's point buffer: a first manifold (rows 0..3 after reduction, up to 8
#: while clipping) and a box pair's second manifold (rows 4.., up to 8 while clipping)
MAX_CLIP_POINTS = 12
MAX_MANIFOLD_POINTS = 4

# Box-box axis preference (Gregorius): an edge axis replaces the best face axis only when its
# separation exceeds the face's by (1 - EDGE_REL_TOL) |face separation| + AXIS_ABS_TOL; face B
# replaces face A only when it exceeds it by (1 - FACE_REL_TOL) |sep A| + AXIS_ABS_TOL. (Gregorius
# writes rel * sep + abs, which is right for overlaps only; |sep| keeps it right for gaps.) Prevents flip-flopping between nearly
# equal axes, which would change the manifold (and lose warm starting) every step.
EDGE_REL_TOL = 0.90
FACE_REL_TOL = 0.98
AXIS_ABS_TOL = 1e-5  # m
#: edge axes a_i x b_j shorter than this (sin of the angle between the edges) are skipped:
#: parallel edges are covered by the face axes.
EDGE_PARALLEL_TOL = 1e-6


class UnsupportedShapePair(RblogError):
    """The scene holds two shapes that may touch but have no collider in the narrowphase table."""

    def __init__(self, geom_a: int, geom_b: int, where: str):
        na = GEOM_NAMES.get(geom_a, f"shape code {geom_a}")
        nb = GEOM_NAMES.get(geom_b, f"shape code {geom_b}")
        supported = ", ".join(f"{GEOM_NAMES[a]}-{GEOM_NAMES[b]}" for a, b in NARROWPHASE_TABLE)
        super().__init__(f"no contact generation for {na}-{nb} ({where}); supported pairs: {supported}")


def collider_for(geom_a: int, geom_b: int) -> tuple[int, str]:
    """(code, name) of the collider for a pair of geometry types; raises KeyError if none."""
    key = (min(geom_a, geom_b), max(geom_a, geom_b))
    return NARROWPHASE_TABLE[key]


# ---- small vector helpers ---------------------------------------------------------------------

@njit(cache=True)
def _col(r, k):
    """Column k of a 3x3 rotation = body axis k in the world frame."""
    return r[0, k], r[1, k], r[2, k]


# ---- colliders ---------------------------------------------------------------------------------

@njit(cache=True)
def collide_sphere_sphere(ca, ra, cb, rb, spec, nrm, pts, sep, fid):
    """Sphere a (centre ca, radius ra) vs sphere b. One point on the line of centres."""
    dx, dy, dz = ca[0] - cb[0], ca[1] - cb[1], ca[2] - cb[2]
    d2 = dx * dx + dy * dy + dz * dz
    rr = ra + rb
    if d2 > (rr + spec) * (rr + spec):
        return 0
    d = math.sqrt(d2)
    if d > 1e-12 * rr:
        nx, ny, nz = dx / d, dy / d, dz / d
    else:  # concentric: any direction will do
        nx, ny, nz = 0.0, 0.0, 1.0
    s = d - rr
    nrm[0], nrm[1], nrm[2] = nx, ny, nz
    # midpoint between the surfaces: b's surface point plus half the gap
    k = rb + 0.5 * s
    pts[0, 0], pts[0, 1], pts[0, 2] = cb[0] + k * nx, cb[1] + k * ny, cb[2] + k * nz
    sep[0] = s
    fid[0] = 0
    return 1


@njit(cache=True)
def collide_sphere_box(ca, ra, cb, rotb, eb, spec, nrm, pts, sep, fid):
    """Sphere a vs box b (centre cb, rotation rotb body->world, half extents eb)."""
    dx, dy, dz = ca[0] - cb[0], ca[1] - cb[1], ca[2] - cb[2]
    # sphere centre in the box frame
    lx = rotb[0, 0] * dx + rotb[1, 0] * dy + rotb[2, 0] * dz
    ly = rotb[0, 1] * dx + rotb[1, 1] * dy + rotb[2, 1] * dz
    lz = rotb[0, 2] * dx + rotb[1, 2] * dy + rotb[2, 2] * dz
    qx = min(max(lx, -eb[0]), eb[0])
    qy = min(max(ly, -eb[1]), eb[1])
    qz = min(max(lz, -eb[2]), eb[2])
    ox, oy, oz = lx - qx, ly - qy, lz - qz
    o2 = ox * ox + oy * oy + oz * oz
    if o2 > 0.0:
        # centre outside the box: closest point q on the surface
        d = math.sqrt(o2)
        s = d - ra
        if s > spec:
            return 0
        nlx, nly, nlz = ox / d, oy / d, oz / d
    else:
        # centre inside: leave through the nearest face
        gx, gy, gz = eb[0] - abs(lx), eb[1] - abs(ly), eb[2] - abs(lz)
        nlx, nly, nlz = 0.0, 0.0, 0.0
        if gx <= gy and gx <= gz:
            nlx = 1.0 if lx >= 0.0 else -1.0
            qx = nlx * eb[0]
            s = -gx - ra
        elif gy <= gz:
            nly = 1.0 if ly >= 0.0 else -1.0
            qy = nly * eb[1]
            s = -gy - ra
        else:
            nlz = 1.0 if lz >= 0.0 else -1.0
            qz = nlz * eb[2]
            s = -gz - ra
    nx = rotb[0, 0] * nlx + rotb[0, 1] * nly + rotb[0, 2] * nlz
    ny = rotb[1, 0] * nlx + rotb[1, 1] * nly + rotb[1, 2] * nlz
    nz = rotb[2, 0] * nlx + rotb[2, 1] * nly + rotb[2, 2] * nlz
    px = cb[0] + rotb[0, 0] * qx + rotb[0, 1] * qy + rotb[0, 2] * qz
    py = cb[1] + rotb[1, 0] * qx + rotb[1, 1] * qy + rotb[1, 2] * qz
    pz = cb[2] + rotb[2, 0] * qx + rotb[2, 1] * qy + rotb[2, 2] * qz
    nrm[0], nrm[1], nrm[2] = nx, ny, nz
    pts[0, 0], pts[0, 1], pts[0, 2] = px + 0.5 * s * nx, py + 0.5 * s * ny, pz + 0.5 * s * nz
    sep[0] = s
    fid[0] = 0
    return 1


@njit(cache=True)
def collide_sphere_plane(ca, ra, pn, poff, spec, nrm, pts, sep, fid):
    """Sphere a vs the plane dot(pn, x) = poff (b); the normal is the plane's."""
    s = pn[0] * ca[0] + pn[1] * ca[1] + pn[2] * ca[2] - poff - ra
    if s > spec:
        return 0
    nrm[0], nrm[1], nrm[2] = pn[0], pn[1], pn[2]
    k = ra + 0.5 * s
    pts[0, 0], pts[0, 1], pts[0, 2] = ca[0] - k * pn[0], ca[1] - k * pn[1], ca[2] - k * pn[2]
    sep[0] = s
    fid[0] = 0
    return 1


@njit(cache=True)
def collide_box_plane(ca, rota, ea, pn, poff, spec, nrm, pts, sep, fid):
    """Box a vs the plane dot(pn, x) = poff: the (up to four deepest) vertices within spec."""
    # plane normal in the box frame, and the centre's height
    nlx = rota[0, 0] * pn[0] + rota[1, 0] * pn[1] + rota[2, 0] * pn[2]
    nly = rota[0, 1] * pn[0] + rota[1, 1] * pn[1] + rota[2, 1] * pn[2]
    nlz = rota[0, 2] * pn[0] + rota[1, 2] * pn[1] + rota[2, 2] * pn[2]
    hc = pn[0] * ca[0] + pn[1] * ca[1] + pn[2] * ca[2] - poff
    # quick reject on the support distance
    if hc - (abs(nlx) * ea[0] + abs(nly) * ea[1] + abs(nlz) * ea[2]) > spec:
        return 0
    count = 0
    for k in range(8):
        sx = ea[0] if (k & 1) else -ea[0]
        sy = ea[1] if (k & 2) else -ea[1]
        sz = ea[2] if (k & 4) else -ea[2]
        s = hc + nlx * sx + nly * sy + nlz * sz
        if s > spec:
            continue
        vx = ca[0] + rota[0, 0] * sx + rota[0, 1] * sy + rota[0, 2] * sz
        vy = ca[1] + rota[1, 0] * sx + rota[1, 1] * sy + rota[1, 2] * sz
        vz = ca[2] + rota[2, 0] * sx + rota[2, 1] * sy + rota[2, 2] * sz
        pts[count, 0] = vx - 0.5 * s * pn[0]
        pts[count, 1] = vy - 0.5 * s * pn[1]
        pts[count, 2] = vz - 0.5 * s * pn[2]
        sep[count] = s
        fid[count] = k
        count += 1
    nrm[0], nrm[1], nrm[2] = pn[0], pn[1], pn[2]
    if count > MAX_MANIFOLD_POINTS:
        # keep the four deepest (a box within spec of a plane on more than four vertices is
        # thinner than spec; its lower face is what matters)
        for i in range(MAX_MANIFOLD_POINTS):
            best = i
            for j in range(i + 1, count):
                if sep[j] < sep[best]:
                    best = j
            _swap_point(pts, sep, fid, i, best)
        count = MAX_MANIFOLD_POINTS
    return count


@njit(cache=True)
def _swap_point(pts, sep, fid, i, j):
    if i == j:
        return
    for k in range(3):
        t = pts[i, k]
        pts[i, k] = pts[j, k]
        pts[j, k] = t
    t = sep[i]
    sep[i] = sep[j]
    sep[j] = t
    f = fid[i]
    fid[i] = fid[j]
    fid[j] = f


@njit(cache=True)
def reduce_manifold(nrm, pts, sep, fid, count):
    """Keep four of ``count`` coplanar-ish points: deepest, farthest from it, the one making the
    largest triangle, the one adding the most area outside that triangle. Returns 4."""
    if count <= MAX_MANIFOLD_POINTS:
        return count
    nx, ny, nz = nrm[0], nrm[1], nrm[2]
    # 1: deepest
    best = 0
    for j in range(1, count):
        if sep[j] < sep[best]:
            best = j
    _swap_point(pts, sep, fid, 0, best)
    # 2: farthest from point 0
    best = 1
    bd = -1.0
    for j in range(1, count):
        dx, dy, dz = pts[j, 0] - pts[0, 0], pts[j, 1] - pts[0, 1], pts[j, 2] - pts[0, 2]
        d = dx * dx + dy * dy + dz * dz
        if d > bd:
            bd = d
            best = j
    _swap_point(pts, sep, fid, 1, best)
    # 3: largest |triangle area| with 0, 1 (measured about the normal)
    ax, ay, az = pts[1, 0] - pts[0, 0], pts[1, 1] - pts[0, 1], pts[1, 2] - pts[0, 2]
    best = 2
    ba = -1.0
    sgn = 1.0
    for j in range(2, count):
        bx, by, bz = pts[j, 0] - pts[0, 0], pts[j, 1] - pts[0, 1], pts[j, 2] - pts[0, 2]
        area = nx * (ay * bz - az * by) + ny * (az * bx - ax * bz) + nz * (ax * by - ay * bx)
        if abs(area) > ba:
            ba = abs(area)
            best = j
            sgn = 1.0 if area >= 0.0 else -1.0
    _swap_point(pts, sep, fid, 2, best)
    # 4: the point farthest outside the triangle (most negative signed area over its edges)
    best = 3
    ba = 1.0
    for j in range(3, count):
        worst = 0.0
        for e in range(3):
            i0 = e
            i1 = (e + 1) % 3
            ex, ey, ez = pts[i1, 0] - pts[i0, 0], pts[i1, 1] - pts[i0, 1], pts[i1, 2] - pts[i0, 2]
            qx, qy, qz = pts[j, 0] - pts[i0, 0], pts[j, 1] - pts[i0, 1], pts[j, 2] - pts[i0, 2]
            area = sgn * (nx * (ey * qz - ez * qy) + ny * (ez * qx - ex * qz) + nz * (ex * qy - ey * qx))
            if area < worst:
                worst = area
        if worst < ba:
            ba = worst
            best = j
    _swap_point(pts, sep, fid, 3, best)
    return MAX_MANIFOLD_POINTS


@njit(cache=True)
def _clip_polygon(src, n_src, dst, axis, sign, limit, plane_id):
    """Sutherland-Hodgman: keep the part of polygon src (rows x, y, z, id) with
    sign * src[:, axis] <= limit. Returns the number of vertices written to dst."""
    n_dst = 0
    if n_src == 0:
        return 0
    for i in range(n_src):
        j = (i + 1) % n_src
        di = sign * src[i, axis] - limit
        dj = sign * src[j, axis] - limit
        if di <= 0.0:
            for k in range(4):
                dst[n_dst, k] = src[i, k]
            n_dst += 1
        if (di <= 0.0) != (dj <= 0.0):
            t = di / (di - dj)
            for k in range(3):
                dst[n_dst, k] = src[i, k] + t * (src[j, k] - src[i, k])
            # id: which edge (by its start vertex's id) crossed which clip plane
            dst[n_dst, 3] = 16.0 * (plane_id + 1) + (src[i, 3] % 16.0)
            n_dst += 1
    return n_dst


@njit(cache=True)
def _face_contact(cr, rotr, er, ci, roti, ei, axis, nsign, spec, flip, face_code,
                  nrm, pts, sep, fid, poly):
    """Clip the incident face of box i against reference face ``axis`` of box r.

    The reference normal n_ref = nsign * (axis column of rotr) points from r towards i. The
    manifold normal (from b into a) is -n_ref when r is a (flip False), n_ref when r is b."""
    rx, ry, rz = nsign * rotr[0, axis], nsign * rotr[1, axis], nsign * rotr[2, axis]
    # incident face: the face of i whose normal is most anti-parallel to n_ref
    best = 0
    bd = -1.0
    for j in range(3):
        d = abs(rx * roti[0, j] + ry * roti[1, j] + rz * roti[2, j])
        if d > bd:
            bd = d
            best = j
    dj = rx * roti[0, best] + ry * roti[1, best] + rz * roti[2, best]
    msign = -1.0 if dj > 0.0 else 1.0
    u = (best + 1) % 3
    v = (best + 2) % 3
    icx = ci[0] + msign * ei[best] * roti[0, best]
    icy = ci[1] + msign * ei[best] * roti[1, best]
    icz = ci[2] + msign * ei[best] * roti[2, best]
    # reference face frame: tangents t1, t2 and its centre
    k1 = (axis + 1) % 3
    k2 = (axis + 2) % 3
    fcx = cr[0] + er[axis] * rx
    fcy = cr[1] + er[axis] * ry
    fcz = cr[2] + er[axis] * rz
    t1x, t1y, t1z = rotr[0, k1], rotr[1, k1], rotr[2, k1]
    t2x, t2y, t2z = rotr[0, k2], rotr[1, k2], rotr[2, k2]
    # incident polygon in reference coordinates (x along t1, y along t2, z along n_ref)
    src = poly[0]
    for k in range(4):
        su = 1.0 if (k == 0 or k == 3) else -1.0
        sv = 1.0 if k < 2 else -1.0
        px = icx + su * ei[u] * roti[0, u] + sv * ei[v] * roti[0, v] - fcx
        py = icy + su * ei[u] * roti[1, u] + sv * ei[v] * roti[1, v] - fcy
        pz = icz + su * ei[u] * roti[2, u] + sv * ei[v] * roti[2, v] - fcz
        src[k, 0] = px * t1x + py * t1y + pz * t1z
        src[k, 1] = px * t2x + py * t2y + pz * t2z
        src[k, 2] = px * rx + py * ry + pz * rz
        src[k, 3] = k
    n = 4
    n = _clip_polygon(poly[0], n, poly[1], 0, 1.0, er[k1], 0)
    n = _clip_polygon(poly[1], n, poly[0], 0, -1.0, er[k1], 1)
    n = _clip_polygon(poly[0], n, poly[1], 1, 1.0, er[k2], 2)
    n = _clip_polygon(poly[1], n, poly[0], 1, -1.0, er[k2], 3)
    out = poly[0]
    count = 0
    for k in range(n):
        z = out[k, 2]
        if z > spec:
            continue
        x, y = out[k, 0], out[k, 1]
        # incident point, moved half the gap back towards the reference face
        zh = 0.5 * z
        pts[count, 0] = fcx + x * t1x + y * t2x + zh * rx
        pts[count, 1] = fcy + x * t1y + y * t2y + zh * ry
        pts[count, 2] = fcz + x * t1z + y * t2z + zh * rz
        sep[count] = z
        fid[count] = ((face_code * 3 + best) * 2 + (1 if msign > 0.0 else 0)) * 128 + int(out[k, 3])
        count += 1
    if flip:
        nrm[0], nrm[1], nrm[2] = rx, ry, rz
    else:
        nrm[0], nrm[1], nrm[2] = -rx, -ry, -rz
    return reduce_manifold(nrm, pts, sep, fid, count)


@njit(cache=True)
def collide_box_box(ca, rota, ea, cb, rotb, eb, spec, nrm, pts, sep, fid, work, poly):
    """Box a vs box b: separating-axis test over 15 axes, then a clipped face manifold (up to
    four points) or a single edge-edge point. ``work`` (>= 24 floats) and ``poly`` (2, 8, 4)
    are scratch."""
    dx, dy, dz = cb[0] - ca[0], cb[1] - ca[1], cb[2] - ca[2]
    c = work  # c[3 i + j] = a_i . b_j ; c[9 + ...] = |c| + eps
    for i in range(3):
        for j in range(3):
            v = rota[0, i] * rotb[0, j] + rota[1, i] * rotb[1, j] + rota[2, i] * rotb[2, j]
            c[3 * i + j] = v
            c[9 + 3 * i + j] = abs(v) + 1e-14
    da0 = rota[0, 0] * dx + rota[1, 0] * dy + rota[2, 0] * dz
    da1 = rota[0, 1] * dx + rota[1, 1] * dy + rota[2, 1] * dz
    da2 = rota[0, 2] * dx + rota[1, 2] * dy + rota[2, 2] * dz
    work[18], work[19], work[20] = da0, da1, da2
    # faces of a
    sep_a = -1e300
    ax_a = 0
    for i in range(3):
        s = abs(work[18 + i]) - ea[i] - (c[9 + 3 * i] * eb[0] + c[10 + 3 * i] * eb[1]
                                          + c[11 + 3 * i] * eb[2])
        if s > spec:
            return 0
        if s > sep_a:
            sep_a = s
            ax_a = i
    # faces of b
    sep_b = -1e300
    ax_b = 0
    for j in range(3):
        dbj = rotb[0, j] * dx + rotb[1, j] * dy + rotb[2, j] * dz
        s = abs(dbj) - eb[j] - (c[9 + j] * ea[0] + c[12 + j] * ea[1] + c[15 + j] * ea[2])
        if s > spec:
            return 0
        if s > sep_b:
            sep_b = s
            ax_b = j
    # edges: axis a_i x b_j, expressed in a's frame: e_i x c[:, j]
    sep_e = -1e300
    ei_best = -1
    ej_best = -1
    for i in range(3):
        for j in range(3):
            c0, c1, c2 = c[j], c[3 + j], c[6 + j]
            if i == 0:
                l0, l1, l2 = 0.0, -c2, c1
            elif i == 1:
                l0, l1, l2 = c2, 0.0, -c0
            else:
                l0, l1, l2 = -c1, c0, 0.0
            ln = math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
            if ln < EDGE_PARALLEL_TOL:
                continue
            r_a = ea[0] * abs(l0) + ea[1] * abs(l1) + ea[2] * abs(l2)
            r_b = 0.0
            for m in range(3):
                r_b += eb[m] * abs(l0 * c[m] + l1 * c[3 + m] + l2 * c[6 + m])
            s = (abs(l0 * da0 + l1 * da1 + l2 * da2) - r_a - r_b) / ln
            if s > spec:
                return 0
            if s > sep_e:
                sep_e = s
                ei_best = i
                ej_best = j
    face_sep = max(sep_a, sep_b)
    # relative margins taken on |separation| so that they favour faces for gaps and overlaps alike
    edge_best = ei_best >= 0 and sep_e > face_sep + (1.0 - EDGE_REL_TOL) * abs(face_sep) + AXIS_ABS_TOL
    if edge_best:
        cnt = _edge_contact(ca, rota, ea, cb, rotb, eb, ei_best, ej_best, dx, dy, dz,
                            spec, nrm, pts, sep, fid)
        if cnt == 0 or face_sep > spec or face_sep < sep_e - spec:
            return cnt
        # The edges touch first, but a face is within reach of this step: a tumbling box would
        # swing that face's corners in. Its face manifold goes in rows 4.. as a second manifold
        # of the pair, with its own normal (nrm[3:6]), so both features are guarded.
        cnt2 = _best_face_contact(ca, rota, ea, cb, rotb, eb, sep_a, ax_a, sep_b, ax_b, work,
                                  dx, dy, dz, spec, nrm[3:6], pts[4:], sep[4:], fid[4:], poly)
        return cnt + 8 * cnt2
    return _best_face_contact(ca, rota, ea, cb, rotb, eb, sep_a, ax_a, sep_b, ax_b, work,
                              dx, dy, dz, spec, nrm, pts, sep, fid, poly)


@njit(cache=True)
def _best_face_contact(ca, rota, ea, cb, rotb, eb, sep_a, ax_a, sep_b, ax_b, work, dx, dy, dz,
                       spec, nrm, pts, sep, fid, poly):
    if sep_b > sep_a + (1.0 - FACE_REL_TOL) * abs(sep_a) + AXIS_ABS_TOL:
        dbj = rotb[0, ax_b] * dx + rotb[1, ax_b] * dy + rotb[2, ax_b] * dz
        # reference face on b; its normal points from b towards a
        nsign = -1.0 if dbj > 0.0 else 1.0
        return _face_contact(cb, rotb, eb, ca, rota, ea, ax_b, nsign, spec, True, 3 + ax_b,
                             nrm, pts, sep, fid, poly)
    nsign = 1.0 if work[18 + ax_a] > 0.0 else -1.0
    return _face_contact(ca, rota, ea, cb, rotb, eb, ax_a, nsign, spec, False, ax_a,
                         nrm, pts, sep, fid, poly)


@njit(cache=True)
def _edge_points(ca, rota, ea, cb, rotb, eb, i, j, dx, dy, dz):
    """Closest points of the supporting edges (a's edge along axis i, b's along axis j), and a
    feature id. Returns (qa, qb, id); the axis L = a_i x b_j is oriented from a to b."""
    uax, uay, uaz = rota[0, i], rota[1, i], rota[2, i]
    ubx, uby, ubz = rotb[0, j], rotb[1, j], rotb[2, j]
    lx = uay * ubz - uaz * uby
    ly = uaz * ubx - uax * ubz
    lz = uax * uby - uay * ubx
    if lx * dx + ly * dy + lz * dz < 0.0:  # orient from a to b
        lx, ly, lz = -lx, -ly, -lz
    # supporting edge of a (farthest along L) and of b (farthest along -L): their midpoints
    pax, pay, paz = ca[0], ca[1], ca[2]
    code_a = 0
    for k in range(3):
        if k == i:
            continue
        s = 1.0 if (lx * rota[0, k] + ly * rota[1, k] + lz * rota[2, k]) > 0.0 else -1.0
        if s > 0.0:
            code_a |= 1 << k
        pax += s * ea[k] * rota[0, k]
        pay += s * ea[k] * rota[1, k]
        paz += s * ea[k] * rota[2, k]
    pbx, pby, pbz = cb[0], cb[1], cb[2]
    code_b = 0
    for k in range(3):
        if k == j:
            continue
        s = -1.0 if (lx * rotb[0, k] + ly * rotb[1, k] + lz * rotb[2, k]) > 0.0 else 1.0
        if s > 0.0:
            code_b |= 1 << k
        pbx += s * eb[k] * rotb[0, k]
        pby += s * eb[k] * rotb[1, k]
        pbz += s * eb[k] * rotb[2, k]
    # closest points of the lines pa + ta ua, pb + tb ub, clamped to the edges
    rx, ry, rz = pax - pbx, pay - pby, paz - pbz
    b = uax * ubx + uay * uby + uaz * ubz
    d1 = uax * rx + uay * ry + uaz * rz
    d2 = ubx * rx + uby * ry + ubz * rz
    den = 1.0 - b * b
    ta = 0.0
    if den > 1e-12:
        ta = (b * d2 - d1) / den
    ta = min(max(ta, -ea[i]), ea[i])
    tb = min(max(b * ta + d2, -eb[j]), eb[j])
    ta = min(max(b * tb - d1, -ea[i]), ea[i])
    code = 100000 + ((i * 3 + j) * 8 + code_a) * 8 + code_b
    return (pax + ta * uax, pay + ta * uay, paz + ta * uaz,
            pbx + tb * ubx, pby + tb * uby, pbz + tb * ubz, code)


@njit(cache=True)
def _edge_contact(ca, rota, ea, cb, rotb, eb, i, j, dx, dy, dz, spec, nrm, pts, sep, fid):
    """One point between the supporting edges, normal along a_i x b_j (from b into a)."""
    qax, qay, qaz, qbx, qby, qbz, code = _edge_points(ca, rota, ea, cb, rotb, eb, i, j,
                                                      dx, dy, dz)
    lx = rota[1, i] * rotb[2, j] - rota[2, i] * rotb[1, j]
    ly = rota[2, i] * rotb[0, j] - rota[0, i] * rotb[2, j]
    lz = rota[0, i] * rotb[1, j] - rota[1, i] * rotb[0, j]
    ln = math.sqrt(lx * lx + ly * ly + lz * lz)
    lx, ly, lz = lx / ln, ly / ln, lz / ln
    if lx * dx + ly * dy + lz * dz < 0.0:
        lx, ly, lz = -lx, -ly, -lz
    s = (qbx - qax) * lx + (qby - qay) * ly + (qbz - qaz) * lz
    if s > spec:
        return 0
    nrm[0], nrm[1], nrm[2] = -lx, -ly, -lz
    pts[0, 0] = 0.5 * (qax + qbx)
    pts[0, 1] = 0.5 * (qay + qby)
    pts[0, 2] = 0.5 * (qaz + qbz)
    sep[0] = s
    fid[0] = code
    return 1


@njit(cache=True, inline="always")
def manifold_part(res, part):
    """(point count, first row) of manifold ``part`` (0 or 1) in a result of :func:`collide`:
    ``res = n1 + 8 n2``, the first manifold in rows 0..3, the second in rows 4..7."""
    if part == 0:
        return res % 8, 0
    return res // 8, 4


@njit(cache=True)
def collide(code, swap, ca, rota, sa, cb, rotb, sb, pn, poff, spec, nrm, pts, sep, fid, work,
            poly):
    """Run collider ``code`` for shapes a and b (size rows: radius in [0] or half extents).

    When ``swap`` the table's first shape is b: the collider runs as (b, a) and the normal is
    negated so that it still points from b into a. For a plane, b's data is (pn, poff).

    Returns n1 + 8 n2: n1 points (rows 0..3, normal nrm[0:3]) and, for box-box edge contacts
    with a face within reach, a second manifold of n2 points (rows 4..7, normal nrm[3:6])."""
    if code == COLLIDE_SPHERE_PLANE:
        return collide_sphere_plane(ca, sa[0], pn, poff, spec, nrm, pts, sep, fid)
    if code == COLLIDE_BOX_PLANE:
        return collide_box_plane(ca, rota, sa, pn, poff, spec, nrm, pts, sep, fid)
    if swap:
        ca, cb = cb, ca
        rota, rotb = rotb, rota
        sa, sb = sb, sa
    if code == COLLIDE_SPHERE_SPHERE:
        n = collide_sphere_sphere(ca, sa[0], cb, sb[0], spec, nrm, pts, sep, fid)
    elif code == COLLIDE_SPHERE_BOX:
        n = collide_sphere_box(ca, sa[0], cb, rotb, sb, spec, nrm, pts, sep, fid)
    elif code == COLLIDE_BOX_BOX:
        n = collide_box_box(ca, rota, sa, cb, rotb, sb, spec, nrm, pts, sep, fid, work, poly)
    else:
        n = -1  # no collider: the world checks the table up front, so this is a bug
    if swap and n > 0:
        for k in range(6):
            nrm[k] = -nrm[k]
    return n


def collide_np(geom_a, a_center, a_rot, a_size, geom_b, b_center=None, b_rot=None, b_size=None,
               plane_normal=(0.0, 0.0, 1.0), plane_offset=0.0, spec=0.0, second=False):
    """Python entry for tests and tools: the manifold of shape a vs shape b (or the plane).

    Returns (normal (3,), points (K, 3), separations (K,), feature ids (K,)); normal from b
    into a; ``second=True`` returns the second manifold of a box-box edge contact (K = 0 when
    there is none). Raises UnsupportedShapePair for a pair with no collider."""
    key = (min(geom_a, geom_b), max(geom_a, geom_b))
    if key not in NARROWPHASE_TABLE:
        raise UnsupportedShapePair(geom_a, geom_b, "collide_np")
    code = NARROWPHASE_TABLE[key][0]
    swap = geom_a > geom_b
    f = lambda v, n: np.ascontiguousarray(np.zeros(n) if v is None else np.asarray(v, float))
    ca, cb = f(a_center, 3), f(b_center, 3)
    ra = np.eye(3) if a_rot is None else np.ascontiguousarray(np.asarray(a_rot, float))
    rb = np.eye(3) if b_rot is None else np.ascontiguousarray(np.asarray(b_rot, float))
    sa = np.zeros(3)
    sa[: np.size(a_size)] = np.ravel(a_size)
    sb = np.zeros(3)
    if b_size is not None:
        sb[: np.size(b_size)] = np.ravel(b_size)
    nrm = np.zeros(6)
    pts = np.zeros((MAX_CLIP_POINTS, 3))
    sep = np.zeros(MAX_CLIP_POINTS)
    fid = np.zeros(MAX_CLIP_POINTS, np.int64)
    work = np.zeros(32)
    poly = np.zeros((2, 2 * MAX_CLIP_POINTS, 4))
    n = collide(code, swap, ca, ra, sa, cb, rb, sb, f(plane_normal, 3), float(plane_offset),
                float(spec), nrm, pts, sep, fid, work, poly)
    n1, n2 = n % 8, n // 8
    if not second:
        return nrm[:3].copy(), pts[:n1].copy(), sep[:n1].copy(), fid[:n1].copy()
    return nrm[3:].copy(), pts[4:4 + n2].copy(), sep[4:4 + n2].copy(), fid[4:4 + n2].copy()
