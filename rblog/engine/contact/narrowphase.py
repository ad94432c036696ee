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

Dispatch: geometry types are ``GEOM_SPHERE``, ``GEOM_BOX`` (dynamic or static boxes),
``GEOM_CAPSULE``, ``GEOM_CYLINDER``, ``GEOM_HULL`` and ``GEOM_PLANE`` (the ground). :data:`COLLIDE_TABLE` maps (lower type, higher type) to a collider
code; the pair is swapped (and the normal negated) when the lower type is on body b. A pair with
no entry is an error (:class:`UnsupportedShapePair`), raised when the world is built, never a
silent skip.

The colliders are C++ (csrc/engine/narrowphase.cpp; box-box in csrc/engine/box_box.cpp, the
capsule pairs in csrc/engine/capsule.cpp, the cylinder pairs and every hull pair but hull - plane in
csrc/engine/cylinder.cpp, hull - plane in csrc/engine/hull.cpp, each with its derivation), dispatched through a table of function pointers with the same keys as
:data:`NARROWPHASE_TABLE` (a test checks that they agree). This module keeps the registry, the
codes and the names, and hands the narrowphase tolerances of :mod:`rblog.engine.constants` (their
one home) to the C++ core at import.
"""

from __future__ import annotations

import numpy as np

from rblog.contract.model import GEOM_BOX as C_GEOM_BOX
from rblog.contract.model import GEOM_CAPSULE as C_GEOM_CAPSULE
from rblog.contract.model import GEOM_CYLINDER as C_GEOM_CYLINDER
from rblog.contract.model import GEOM_MESH as C_GEOM_MESH
from rblog.contract.model import GEOM_SPHERE as C_GEOM_SPHERE
from rblog.contract.model import SHAPE_BOX, SHAPE_SPHERE
from rblog.contract.trajectory import STATIC_BODY
from rblog.engine import _core
from rblog.engine.constants import (
    AXIS_ABS_TOL, CONVEX_EPA_TOL_M, CONVEX_GJK_TOL_M, CONVEX_MAX_ITER, EDGE_PARALLEL_TOL,
    EDGE_REL_TOL, FACE_REL_TOL, FRICTION_ANCHOR_MAX_DRIFT_M, MANIFOLD_TOUCH_BAND_M,
)
from rblog.errors import RblogError, UnsupportedShapePair

#: the engine's geometry types; size rows (m): sphere [r, 0, 0], box half extents, capsule
#: [r, h, 0] (the segment |z| <= h of the body's z axis grown by r), cylinder [r, h, 0] (radius
#: r, |z| <= h), hull [id, 0, 0] (the C++ core's hull table, rblog.engine.hull.register). The
#: plane is the highest code: always shape b.
GEOM_SPHERE = 0
GEOM_BOX = 1
GEOM_CAPSULE = 2
GEOM_CYLINDER = 3
GEOM_HULL = 4
GEOM_PLANE = 5
N_GEOM = 6
GEOM_NAMES = {GEOM_SPHERE: "sphere", GEOM_BOX: "box", GEOM_CAPSULE: "capsule",
              GEOM_CYLINDER: "cylinder", GEOM_HULL: "hull", GEOM_PLANE: "plane"}
#: Model.body_shape -> geometry type
SHAPE_TO_GEOM = {SHAPE_SPHERE: GEOM_SPHERE, SHAPE_BOX: GEOM_BOX}
#: the contract's geom_type of a body's one geom -> the engine's geometry type
CONTRACT_TO_GEOM = {C_GEOM_SPHERE: GEOM_SPHERE, C_GEOM_BOX: GEOM_BOX,
                    C_GEOM_CAPSULE: GEOM_CAPSULE, C_GEOM_CYLINDER: GEOM_CYLINDER,
                    C_GEOM_MESH: GEOM_HULL}

COLLIDE_NONE = -1
COLLIDE_SPHERE_SPHERE = 0
COLLIDE_SPHERE_BOX = 1
COLLIDE_BOX_BOX = 2
COLLIDE_SPHERE_PLANE = 3
COLLIDE_BOX_PLANE = 4
COLLIDE_SPHERE_CAPSULE = 5
COLLIDE_BOX_CAPSULE = 6
COLLIDE_CAPSULE_CAPSULE = 7
COLLIDE_CAPSULE_PLANE = 8
COLLIDE_SPHERE_CYLINDER = 9
COLLIDE_BOX_CYLINDER = 10
COLLIDE_CAPSULE_CYLINDER = 11
COLLIDE_CYLINDER_CYLINDER = 12
COLLIDE_CYLINDER_PLANE = 13
COLLIDE_SPHERE_HULL = 14
COLLIDE_BOX_HULL = 15
COLLIDE_CAPSULE_HULL = 16
COLLIDE_CYLINDER_HULL = 17
COLLIDE_HULL_HULL = 18
COLLIDE_HULL_PLANE = 19

#: (lower geometry type, higher geometry type) -> (collider code, collider name)
NARROWPHASE_TABLE = {
    (GEOM_SPHERE, GEOM_SPHERE): (COLLIDE_SPHERE_SPHERE, "collide_sphere_sphere"),
    (GEOM_SPHERE, GEOM_BOX): (COLLIDE_SPHERE_BOX, "collide_sphere_box"),
    (GEOM_BOX, GEOM_BOX): (COLLIDE_BOX_BOX, "collide_box_box"),
    (GEOM_SPHERE, GEOM_PLANE): (COLLIDE_SPHERE_PLANE, "collide_sphere_plane"),
    (GEOM_BOX, GEOM_PLANE): (COLLIDE_BOX_PLANE, "collide_box_plane"),
    (GEOM_SPHERE, GEOM_CAPSULE): (COLLIDE_SPHERE_CAPSULE, "collide_sphere_capsule"),
    (GEOM_BOX, GEOM_CAPSULE): (COLLIDE_BOX_CAPSULE, "collide_capsule_box"),
    (GEOM_CAPSULE, GEOM_CAPSULE): (COLLIDE_CAPSULE_CAPSULE, "collide_capsule_capsule"),
    (GEOM_CAPSULE, GEOM_PLANE): (COLLIDE_CAPSULE_PLANE, "collide_capsule_plane"),
    (GEOM_SPHERE, GEOM_CYLINDER): (COLLIDE_SPHERE_CYLINDER, "collide_sphere_cylinder"),
    (GEOM_BOX, GEOM_CYLINDER): (COLLIDE_BOX_CYLINDER, "collide_convex"),
    (GEOM_CAPSULE, GEOM_CYLINDER): (COLLIDE_CAPSULE_CYLINDER, "collide_convex"),
    (GEOM_CYLINDER, GEOM_CYLINDER): (COLLIDE_CYLINDER_CYLINDER, "collide_convex"),
    (GEOM_CYLINDER, GEOM_PLANE): (COLLIDE_CYLINDER_PLANE, "collide_cylinder_plane"),
    (GEOM_SPHERE, GEOM_HULL): (COLLIDE_SPHERE_HULL, "collide_convex"),
    (GEOM_BOX, GEOM_HULL): (COLLIDE_BOX_HULL, "collide_convex"),
    (GEOM_CAPSULE, GEOM_HULL): (COLLIDE_CAPSULE_HULL, "collide_convex"),
    (GEOM_CYLINDER, GEOM_HULL): (COLLIDE_CYLINDER_HULL, "collide_convex"),
    (GEOM_HULL, GEOM_HULL): (COLLIDE_HULL_HULL, "collide_convex"),
    (GEOM_HULL, GEOM_PLANE): (COLLIDE_HULL_PLANE, "collide_hull_plane"),
}
#: the same table as an array: COLLIDE_TABLE[lo, hi] -> collider code or -1
COLLIDE_TABLE = np.full((N_GEOM, N_GEOM), COLLIDE_NONE, np.int64)
for (_lo, _hi), (_code, _name) in NARROWPHASE_TABLE.items():
    COLLIDE_TABLE[_lo, _hi] = _code
# the error's words come from this table, their one home
UnsupportedShapePair.names = GEOM_NAMES
UnsupportedShapePair.supported = ", ".join(f"{GEOM_NAMES[a]}-{GEOM_NAMES[b]}"
                                           for a, b in NARROWPHASE_TABLE)

# the collision tolerances reach the C++ core once, from their one home (constants.py)
_core.set_collision_constants(
    manifold_touch_band_m=MANIFOLD_TOUCH_BAND_M, edge_rel_tol=EDGE_REL_TOL,
    face_rel_tol=FACE_REL_TOL, axis_abs_tol=AXIS_ABS_TOL, edge_parallel_tol=EDGE_PARALLEL_TOL,
    friction_anchor_max_drift_m=FRICTION_ANCHOR_MAX_DRIFT_M, static_body=STATIC_BODY,
    convex_gjk_tol_m=CONVEX_GJK_TOL_M, convex_epa_tol_m=CONVEX_EPA_TOL_M,
    convex_max_iter=CONVEX_MAX_ITER)


def collider_for(geom_a: int, geom_b: int) -> tuple[int, str]:
    """(code, name) of the collider for a pair of geometry types; raises KeyError if none."""
    key = (min(geom_a, geom_b), max(geom_a, geom_b))
    return NARROWPHASE_TABLE[key]


def parted_along_np(geom_a, a_center, a_rot, a_size, geom_b, b_center, b_rot, b_size, axis, spec):
    """Python entry for tests: True when ``collide_np`` of the same pair at ``spec`` provably
    returns no point, decided from the gap along ``axis`` (from b into a) alone; False for the
    pairs whose colliders the proof does not cover (csrc/engine/narrowphase.cpp, parted_along)."""
    f = lambda v: np.ascontiguousarray(np.asarray(v, float))
    sa, sb = np.zeros(3), np.zeros(3)
    sa[: np.size(a_size)] = np.ravel(a_size)
    sb[: np.size(b_size)] = np.ravel(b_size)
    return bool(_core.parted_along_np(int(geom_a), int(geom_b), f(a_center), f(a_rot), sa,
                                      f(b_center), f(b_rot), sb, f(axis), float(spec)))


def collide_np(geom_a, a_center, a_rot, a_size, geom_b, b_center=None, b_rot=None, b_size=None,
               plane_normal=(0.0, 0.0, 1.0), plane_offset=0.0, spec=0.0, second=False):
    """Python entry for tests and tools: the manifold of shape a vs shape b (or the plane).

    Returns (normal (3,), points (K, 3), separations (K,), feature ids (K,)); normal from b
    into a; ``second=True`` returns the second manifold of a box-box edge contact (K = 0 when
    there is none). Raises UnsupportedShapePair for a pair with no collider."""
    key = (min(geom_a, geom_b), max(geom_a, geom_b))
    if key not in NARROWPHASE_TABLE:
        raise UnsupportedShapePair(geom_a, geom_b, "collide_np")
    f = lambda v, n: np.ascontiguousarray(np.zeros(n) if v is None else np.asarray(v, float))
    ca, cb = f(a_center, 3), f(b_center, 3)
    ra = np.eye(3) if a_rot is None else np.ascontiguousarray(np.asarray(a_rot, float))
    rb = np.eye(3) if b_rot is None else np.ascontiguousarray(np.asarray(b_rot, float))
    sa = np.zeros(3)
    sa[: np.size(a_size)] = np.ravel(a_size)
    sb = np.zeros(3)
    if b_size is not None:
        sb[: np.size(b_size)] = np.ravel(b_size)
    n, nrm, pts, sep, fid = _core.collide_np(int(geom_a), int(geom_b), ca, ra, sa, cb, rb, sb,
                                             f(plane_normal, 3), float(plane_offset), float(spec))
    n1, n2 = n % 8, n // 8
    if not second:
        return nrm[:3].copy(), pts[:n1].copy(), sep[:n1].copy(), fid[:n1].copy()
    return nrm[3:].copy(), pts[4:4 + n2].copy(), sep[4:4 + n2].copy(), fid[4:4 + n2].copy()
