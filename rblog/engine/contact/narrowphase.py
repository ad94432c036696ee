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

Box-box lives in :mod:`rblog.engine.contact.box_box` (separating axes, clipping, reduction).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rblog.errors import RblogError
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE
from rblog.engine.contact.box_box import collide_box_box
from rblog.engine.contact.manifold import MAX_CLIP_POINTS, MAX_MANIFOLD_POINTS, swap_point

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
            swap_point(pts, sep, fid, i, best)
        count = MAX_MANIFOLD_POINTS
    return count


@njit(cache=True)
def collider_buffers():
    """The work buffers every collider call takes: (nrm (6,) two manifolds' normals, pts
    (MAX_CLIP_POINTS, 3), sep (MAX_CLIP_POINTS,), fid (MAX_CLIP_POINTS,) int64, work (32,), poly
    (2, 2 MAX_CLIP_POINTS, 4) clipping polygons)."""
    return (np.zeros(6), np.zeros((MAX_CLIP_POINTS, 3)), np.zeros(MAX_CLIP_POINTS),
            np.zeros(MAX_CLIP_POINTS, np.int64), np.zeros(32),
            np.zeros((2, 2 * MAX_CLIP_POINTS, 4)))


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
    nrm, pts, sep, fid, work, poly = collider_buffers()
    n = collide(code, swap, ca, ra, sa, cb, rb, sb, f(plane_normal, 3), float(plane_offset),
                float(spec), nrm, pts, sep, fid, work, poly)
    n1, n2 = n % 8, n // 8
    if not second:
        return nrm[:3].copy(), pts[:n1].copy(), sep[:n1].copy(), fid[:n1].copy()
    return nrm[3:].copy(), pts[4:4 + n2].copy(), sep[4:4 + n2].copy(), fid[4:4 + n2].copy()
