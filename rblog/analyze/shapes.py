"""Signed distances between geoms of every shape, recomputed from the logged poses.

The audit's own geometry (csrc/audit/shapes.hpp, shapes.cpp, convex.cpp, broadphase.cpp), apart
from every engine's narrowphase: sphere, capsule, ellipsoid, cylinder, box, convex mesh (the hull
of its vertices) and plane (a half-space). Conventions, for every pair (a, b):

* ``sep`` (P,): signed distance between the surfaces (m), > 0 apart, < 0 the penetration depth.
* ``normal`` (P, 3): unit world vector from b into a.
* ``pa``, ``pb`` (P, 3): witness points on a's and b's surface (world, m), ``pa - pb = sep n``.
* ``status`` (P,): ``OK``, ``NOT_CONVERGED`` (GJK/EPA hit their iteration cap), or
  ``UNSUPPORTED`` (plane-plane: sep is NaN).

A geom's frame: ``position`` (.., 3) its centre in the world, ``rotation`` (.., 3, 3) geom->world
(columns are its axes in the world frame). ``size`` (3,) per type:

==========  ===========  ===========  ===========  =====================================
type        size[0]      size[1]      size[2]      in the geom frame
==========  ===========  ===========  ===========  =====================================
plane       -            -            -            the half-space z <= 0 (normal +z)
sphere      radius       -            -            |p| <= r
capsule     radius       half-length  -            the z segment [-h, h] grown by r
ellipsoid   semi-axis x  semi-axis y  semi-axis z  sum (p_i / a_i)^2 <= 1
cylinder    radius       half-length  -            x^2 + y^2 <= r^2, |z| <= h
box         half x       half y       half z       |p_i| <= h_i
mesh        -            -            -            hull of its vertices (V, 3)
==========  ===========  ===========  ===========  =====================================

Which pairs are exact and which are within the GJK/EPA tolerances (rblog/analyze/tolerances.py)
is the table at the top of csrc/audit/shapes.cpp.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rblog.analyze import _audit
from rblog.analyze.tolerances import CONVEX_MAX_ITER, EPA_TOL_M, GJK_TOL_M, WITNESS_BAND_M

#: geom type names -> the compiled module's codes (csrc/audit/shapes.hpp)
GEOM_TYPES = {
    "plane": _audit.GEOM_PLANE,
    "sphere": _audit.GEOM_SPHERE,
    "capsule": _audit.GEOM_CAPSULE,
    "ellipsoid": _audit.GEOM_ELLIPSOID,
    "cylinder": _audit.GEOM_CYLINDER,
    "box": _audit.GEOM_BOX,
    "mesh": _audit.GEOM_MESH,
}
assert sorted(GEOM_TYPES.values()) == list(range(len(GEOM_TYPES)))
OK, NOT_CONVERGED, UNSUPPORTED = _audit.DIST_OK, _audit.DIST_NOT_CONVERGED, _audit.DIST_UNSUPPORTED
#: edge cross products shorter than this are parallel edges in the box-box axis test
_AXIS_EPS = 1e-6


@dataclass
class Geoms:
    """G geoms' fixed data.

    Attributes:
        type: (G,) int64 codes of GEOM_TYPES.
        size: (G, 3) per type (module docstring), m.
        mesh_start, mesh_count: (G,) rows of ``verts`` that hold each mesh's vertices (0, 0 for
            other types).
        verts: (V, 3) mesh vertices in their geom's frame (m).
        body: (G,) the body each geom belongs to (pairs of one body are never tested), < 0 for
            static geoms (pairs of two are never tested).
    """

    type: np.ndarray
    size: np.ndarray
    mesh_start: np.ndarray
    mesh_count: np.ndarray
    verts: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    body: np.ndarray | None = None

    @classmethod
    def build(cls, types, sizes, meshes=None, body=None) -> "Geoms":
        """From type names (G,), sizes (G, 3) and, for each mesh geom, its (V_g, 3) vertices
        (``meshes``: a dict geom index -> vertices, or a list with None for other geoms)."""
        codes = np.array([GEOM_TYPES[t] if isinstance(t, str) else int(t) for t in types],
                         np.int64)
        g = len(codes)
        start, count = np.zeros(g, np.int64), np.zeros(g, np.int64)
        rows = []
        items = meshes.items() if isinstance(meshes, dict) else enumerate(meshes or [])
        n = 0
        for i, v in items:
            if v is None:
                continue
            v = np.asarray(v, float).reshape(-1, 3)
            start[i], count[i] = n, len(v)
            rows.append(v)
            n += len(v)
        verts = np.concatenate(rows) if rows else np.zeros((0, 3))
        body = np.arange(g, dtype=np.int64) if body is None else np.asarray(body, np.int64)
        return cls(codes, np.asarray(sizes, float).reshape(g, 3), start, count, verts, body)


def _c(x, dtype=np.float64):
    return np.ascontiguousarray(x, dtype=dtype)


def pair_distance(geoms: Geoms, position, rotation, k, i, j, with_points: bool = True,
                  gjk_tol: float = GJK_TOL_M, epa_tol: float = EPA_TOL_M,
                  max_iter: int = CONVEX_MAX_ITER):
    """Rows (k, i, j): geoms i and j at sample k of position (T, G, 3), rotation (T, G, 3, 3).

    Returns dict of sep (R,), status (R,), iters (R,) and, with ``with_points``, normal, pa, pb
    (R, 3) (conventions: module docstring)."""
    r = len(k)
    sep = np.empty(r)
    status = np.empty(r, np.int64)
    iters = np.empty(r, np.int64)
    m = r if with_points else 0
    n, pa, pb = np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3))
    _audit.geom_pairs_kernel(_c(k, np.int64), _c(i, np.int64), _c(j, np.int64), _c(position),
                             _c(rotation), _c(geoms.type, np.int64), _c(geoms.size),
                             _c(geoms.mesh_start, np.int64), _c(geoms.mesh_count, np.int64),
                             _c(geoms.verts).reshape(-1, 3), float(gjk_tol), float(epa_tol),
                             int(max_iter), WITNESS_BAND_M, _AXIS_EPS, sep, n, pa, pb, status,
                             iters)
    out = dict(sep=sep, status=status, iters=iters)
    if with_points:
        out.update(normal=n, pa=pa, pb=pb)
    return out


def distance(type_a, xa, ra, sa, type_b, xb, rb, sb, verts_a=None, verts_b=None, **kw):
    """P explicit pairs: geom a of ``type_a`` (a name) at xa (P, 3), ra (P, 3, 3), size sa (3,)
    or (P, 3) against geom b likewise; ``verts_*`` (V, 3) for a mesh. Returns pair_distance's
    dict."""
    xa, xb = np.asarray(xa, float).reshape(-1, 3), np.asarray(xb, float).reshape(-1, 3)
    p = len(xa)
    sa = np.broadcast_to(np.asarray(sa, float), (p, 3))
    sb = np.broadcast_to(np.asarray(sb, float), (p, 3))
    # one mesh's vertices, shared by its P copies
    geoms = _shared_meshes([type_a] * p + [type_b] * p, np.concatenate([sa, sb]), p, verts_a,
                           verts_b)
    pos = np.concatenate([xa, xb])[None]
    rot = np.concatenate([np.broadcast_to(ra, (p, 3, 3)), np.broadcast_to(rb, (p, 3, 3))])[None]
    return pair_distance(geoms, pos, rot, np.zeros(p, np.int64), np.arange(p),
                         np.arange(p, 2 * p), **kw)


def _shared_meshes(types, sizes, p, verts_a, verts_b) -> Geoms:
    g = Geoms.build(types, sizes)
    rows = []
    n = 0
    for half, v in ((0, verts_a), (1, verts_b)):
        if v is None:
            continue
        v = np.asarray(v, float).reshape(-1, 3)
        sl = slice(half * p, (half + 1) * p)
        g.mesh_start[sl], g.mesh_count[sl] = n, len(v)
        rows.append(v)
        n += len(v)
    if rows:
        g.verts = np.concatenate(rows)
    return g


def broadphase(geoms: Geoms, position, rotation, pad: float):
    """Candidate pairs (k, i < j) whose tight world AABBs grown by ``pad`` (m) overlap at sample k
    (a plane: whose geom reaches within ``pad`` of it), by sort-and-sweep
    (csrc/audit/broadphase.cpp); pairs of one body or of two static geoms are left out."""
    t_n, g_n = np.shape(position)[:2]
    cap = max(1024, 8 * g_n * t_n)
    args = (_c(position), _c(rotation), _c(geoms.type, np.int64), _c(geoms.size),
            _c(geoms.mesh_start, np.int64), _c(geoms.mesh_count, np.int64),
            _c(geoms.verts).reshape(-1, 3), _c(geoms.body, np.int64), float(pad))
    while True:
        out = [np.empty(cap, np.int64) for _ in range(3)]
        cnt = _audit.geom_broadphase(*args, *out)
        if cnt <= cap:
            return tuple(o[:cnt] for o in out)
        cap = cnt


# --- the log's geoms (contract v3 geom_* tables) -----------------------------------------------
def _contract_codes() -> np.ndarray:
    from rblog.contract import model as M

    table = np.full(max(M.GEOM_NAMES) + 1, -1, np.int64)
    for code, name in M.GEOM_NAMES.items():
        table[code] = GEOM_TYPES[name]
    return table


def model_geoms(model) -> Geoms:
    """The log's geoms (G,) in the audit's codes, with their bodies (-1: static)."""
    codes = _contract_codes()[np.asarray(model.geom_type, np.int64)]
    verts = np.asarray(model.mesh_vert, float).reshape(-1, 3) if model.mesh_vert is not None \
        else np.zeros((0, 3))
    return Geoms(codes, np.asarray(model.geom_size, float).reshape(-1, 3),
                 np.asarray(model.geom_vert_adr, np.int64), np.asarray(model.geom_vert_num, np.int64),
                 verts, np.asarray(model.geom_body, np.int64))


def geom_poses(model, position: np.ndarray, rotation: np.ndarray):
    """World frames of every geom at every sample: (T, G, 3) centres, (T, G, 3, 3) geom->world,
    from the bodies' logged poses (T, N, 3), (T, N, 3, 3) and each geom's frame in its body's
    frame (a static geom's is its world frame)."""
    from rblog.contract.orientation import quat_wxyz_to_matrix as quat_to_matrix

    body = np.asarray(model.geom_body, np.int64)
    gp = np.asarray(model.geom_pos_body, float).reshape(-1, 3)
    gr = quat_to_matrix(np.asarray(model.geom_quat_wxyz_body, float).reshape(-1, 4)) \
        if len(body) else np.zeros((0, 3, 3))
    t_n = len(position)
    pos = np.broadcast_to(gp, (t_n,) + gp.shape).copy()
    rot = np.broadcast_to(gr, (t_n,) + gr.shape).copy()
    m = body >= 0
    if m.any():
        rb = rotation[:, body[m]]
        pos[:, m] = position[:, body[m]] + np.einsum("tgij,gj->tgi", rb, gp[m])
        rot[:, m] = np.einsum("tgij,gjk->tgik", rb, gr[m])
    return pos, rot


def weld_root(model) -> np.ndarray:
    """(N,) the body each body is welded to (-1: the world): itself for a body that moves on a
    joint or is free, its parent's weld root for one whose joints are all fixed, -1 for a static
    body (MuJoCo's body_weldid: a body without joints moves with its parent)."""
    from rblog.contract.model import BODY_STATIC, JOINT_FIXED

    n = int(model.n_bodies)
    parent = np.asarray(model.body_parent, np.int64)
    jb = np.asarray(model.joint_body, np.int64)
    jt = np.asarray(model.joint_type, np.int64)
    moving = np.zeros(n, bool)
    moving[jb[(jt != JOINT_FIXED) & (jb >= 0) & (jb < n)]] = True
    fixed = np.zeros(n, bool)
    fixed[jb[(jt == JOINT_FIXED) & (jb >= 0) & (jb < n)]] = True
    welded = fixed & ~moving
    static = np.asarray(model.body_kind, np.int64) == BODY_STATIC
    root = np.where(static, -1, np.arange(n, dtype=np.int64))
    w = welded & ~static
    for _ in range(n):  # one level of the tree per pass
        nxt = root.copy()
        nxt[w] = np.where(parent[w] >= 0, root[np.maximum(parent[w], 0)], -1)
        if (nxt == root).all():
            break
        root = nxt
    return root


def collide_mask(model, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """(P,) whether geoms i and j may touch by the model's filter: the collide_rule on their
    group/mask bits, never two geoms of one body or of bodies welded together (a fixed joint, a
    static body with the world: :func:`weld_root`), and, unless the log's ``collide_parent``
    says otherwise, never a body and its parent body (the bodies a joint links, through their
    weld roots: MuJoCo's default filterparent, Bullet's default between linked links; a body on
    the world still touches static geoms)."""
    g = np.asarray(model.geom_collide_group, np.int64)
    m = np.asarray(model.geom_collide_mask, np.int64)
    a = (g[i] & m[j]) != 0
    b = (g[j] & m[i]) != 0
    ok = (a | b) if model.collide_rule == "or" else (a & b)
    body = np.asarray(model.geom_body, np.int64)
    parent = np.asarray(model.body_parent, np.int64)
    n = len(parent)
    root = np.append(weld_root(model), -1)  # (N + 1,): row N is the world's
    wi = root[np.where(body[i] >= 0, body[i], n)]
    wj = root[np.where(body[j] >= 0, body[j], n)]
    ok &= wi != wj
    if getattr(model, "collide_parent", False):
        return ok
    # the weld root of each body's parent (-1: the world), row N the world's
    up = np.append(root[np.where(parent >= 0, parent, n)], -1)
    pi_ = up[np.where(wi >= 0, wi, n)]
    pj = up[np.where(wj >= 0, wj, n)]
    linked = (wi >= 0) & (wj >= 0) & ((pi_ == wj) | (pj == wi))
    return ok & ~linked


def bodies_may_touch(model, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(P,) whether bodies a and b (indices < N) may touch: some geom of a and some geom of b
    pass :func:`collide_mask` (Bullet's links of one multibody, MuJoCo's parent and child: no).
    Bodies without geoms (a log before contract v3) may touch anything, as their shapes say."""
    a, b = np.asarray(a, np.int64), np.asarray(b, np.int64)
    out = np.ones(len(a), bool)
    if not getattr(model, "n_geoms", 0) or model.geom_collide_group is None or not len(a):
        return out
    body = np.asarray(model.geom_body, np.int64)
    n = int(max(a.max(), b.max())) + 1
    key = a * n + b
    uniq, inv = np.unique(key, return_inverse=True)
    ua, ub = uniq // n, uniq % n
    order = np.argsort(body, kind="stable")
    lo = np.searchsorted(body[order], np.arange(n), "left")
    hi = np.searchsorted(body[order], np.arange(n), "right")
    na, nb = hi[ua] - lo[ua], hi[ub] - lo[ub]
    has = (na > 0) & (nb > 0)
    ok = np.ones(len(uniq), bool)
    u = np.flatnonzero(has)
    if len(u):
        cnt = na[u] * nb[u]
        pair = np.repeat(np.arange(len(u)), cnt)
        r = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        gi = order[lo[ua[u]][pair] + r // nb[u][pair]]
        gj = order[lo[ub[u]][pair] + r % nb[u][pair]]
        any_ = np.zeros(len(u), bool)
        np.logical_or.at(any_, pair, collide_mask(model, gi, gj))
        ok[u] = any_
    return ok[inv]


def inner_half_extent(geoms: Geoms) -> np.ndarray:
    """(G,) each geom's smallest half-extent (m): a sphere's or capsule's radius, a box's or
    ellipsoid's smallest semi-axis, min(radius, half-length) of a cylinder; inf for meshes and
    planes (no fraction of them caps a depth tolerance)."""
    t, s = geoms.type, geoms.size
    out = np.full(len(t), np.inf)
    out = np.where((t == GEOM_TYPES["sphere"]) | (t == GEOM_TYPES["capsule"]), s[:, 0], out)
    out = np.where((t == GEOM_TYPES["box"]) | (t == GEOM_TYPES["ellipsoid"]), s.min(axis=1), out)
    out = np.where(t == GEOM_TYPES["cylinder"], np.minimum(s[:, 0], s[:, 1]), out)
    return out


def partner_codes(model) -> np.ndarray:
    """(G,) each geom as the penetration analyzer names a contact partner: its body's index
    (>= 0) for a geom on a body; for a world geom, -1 for the ground (the plane the v2 fields take
    as it, rblog.contract.model: the first world plane most opposed to gravity), N + m for the
    m-th world box (static box m, in geom order as the v2 fields list them), and N + M + w for the
    w-th of the other world geoms in geom order (M static boxes: another plane, a wall, a world
    sphere, capsule or mesh), which the v2 fields do not describe."""
    gb = np.asarray(model.geom_body, np.int64)
    gt = _contract_codes()[np.asarray(model.geom_type, np.int64)] if len(gb) else gb
    n = int(model.n_bodies)
    out = gb.copy()
    world = gb < 0
    boxes = np.flatnonzero(world & (gt == GEOM_TYPES["box"]))
    out[boxes] = n + np.arange(len(boxes))
    planes = np.flatnonzero(world & (gt == GEOM_TYPES["plane"]))
    ground = -1
    if len(planes) and model.ground:
        from rblog.contract.orientation import quat_wxyz_to_matrix

        quat = np.asarray(model.geom_quat_wxyz_body, float).reshape(-1, 4)[planes]
        normals = quat_wxyz_to_matrix(quat)[:, :, 2]
        g = np.asarray(model.gravity, float)
        up = -g / np.linalg.norm(g) if np.linalg.norm(g) > 0 else np.array([0.0, 0.0, 1.0])
        ground = int(planes[int(np.argmax(normals @ up))])
    other = np.flatnonzero(world & (gt != GEOM_TYPES["box"]) & (np.arange(len(gb)) != ground))
    out[other] = n + len(boxes) + np.arange(len(other))
    if ground >= 0:
        out[ground] = -1
    return out


def nearest_static_geom(model, geoms: Geoms, point: np.ndarray) -> np.ndarray:
    """(P,) the world geom whose surface is nearest each world point (P, 3), by the audit's own
    signed distance of a point (a sphere of radius 0) to it: -1 where the model has none."""
    world = np.flatnonzero(geoms.body < 0)
    p = len(point)
    if not len(world) or not p:
        return np.full(p, -1, np.int64)
    w = len(world)
    sub = Geoms(np.r_[geoms.type[world], GEOM_TYPES["sphere"]],
                np.r_[geoms.size[world], np.zeros((1, 3))], np.r_[geoms.mesh_start[world], 0],
                np.r_[geoms.mesh_count[world], 0], geoms.verts,
                np.r_[np.full(w, -1, np.int64), 0])
    from rblog.contract.orientation import quat_wxyz_to_matrix

    gp = np.asarray(model.geom_pos_body, float).reshape(-1, 3)[world]
    gr = quat_wxyz_to_matrix(np.asarray(model.geom_quat_wxyz_body, float).reshape(-1, 4)[world])
    pos = np.empty((p, w + 1, 3))
    pos[:, :w] = gp
    pos[:, w] = point
    rot = np.empty((p, w + 1, 3, 3))
    rot[:, :w] = gr
    rot[:, w] = np.eye(3)
    k = np.repeat(np.arange(p), w)
    i = np.tile(np.arange(w), p)
    d = pair_distance(sub, pos, rot, k, i, np.full(len(k), w), with_points=False)
    return world[np.argmin(np.abs(d["sep"]).reshape(p, w), axis=1)]


#: MuJoCo's mjtDisableBit bits that switch every contact off: mjDSBL_CONSTRAINT (1), mjDSBL_CONTACT
#: (16) (MuJoCo's documentation of mjtDisableBit)
_MUJOCO_NO_CONTACT_BITS = 1 | 16


def contacts_disabled(info) -> bool:
    """Whether the log's engine settings (RunInfo.engine_settings) say the engine made no contacts
    at all: MuJoCo with ``disableflags`` holding mjDSBL_CONTACT or mjDSBL_CONSTRAINT (dm_control's
    cartpole: its cart box runs through its rail capsules by design)."""
    es = getattr(info, "engine_settings", None) or {}
    return es.get("engine") == "mujoco" and bool(int(es.get("disableflags", 0))
                                                 & _MUJOCO_NO_CONTACT_BITS)
