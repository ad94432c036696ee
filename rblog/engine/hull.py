"""Convex hull bodies: the hull of a scene's vertices or of a mesh file, in the engine's body frame.

A ``shape = "hull"`` body gives ``vertices = [[x, y, z], ...]`` (m, in the frame its ``position``
and orientation place) or ``mesh = "file.obj"`` (any format trimesh reads; the path relative to
the scene file), of which the convex hull is the shape. The engine's body frame is the hull's
centre of mass with its principal axes (rblog.engine.mass_properties.principal_axes), so the
scene's pose is turned into the logged one:

    x_logged = x_scene + R_scene c,    R_logged = R_scene Q,    vertices_logged = Q^T (v - c)

(c the centre of mass and Q the principal axes, both in the scene's vertex frame; Q = 1 when
the given axes are already principal, e.g. a box's corners). ``velocity`` is the centre of
mass's. The hull's boundary is qhull's triangles (scipy.spatial.ConvexHull), merged into its
polygonal faces (coplanar to FACE_COPLANAR_RTOL), each an ordered loop of vertex indices.

Hulling uses scipy's qhull (a dependency of rblog); a mesh file needs the ``meshes`` extra
(trimesh): ``pip install rblog[meshes]``; without it a mesh hull is refused in one line.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rblog.engine import mass_properties as mp

#: two boundary triangles whose unit normals differ by at most this (and whose planes' offsets by
#: this times the hull's size) are one face of the hull
FACE_COPLANAR_RTOL = 1e-9
#: the most vertices one face of a hull may have (the narrowphase's clipping buffers hold it)
HULL_MAX_FACE_VERTICES = 64
#: a hull thinner than this times its size in some direction is refused as flat
HULL_MIN_THICKNESS_RTOL = 1e-9

MESHES_HINT = "install rblog[meshes] (pip install 'rblog[meshes]': trimesh)"


@dataclass
class Hull:
    """A convex hull in its body frame (centre of mass, principal axes).

    vertices (V, 3) m; triangles (T, 3) vertex indices, counter-clockwise seen from outside;
    faces: list of F index arrays, each a face's vertices counter-clockwise about its outward
    normal; face_normal (F, 3) unit, face_offset (F,) m (n . x = offset on the face);
    volume m^3; moments (3,) principal second moments int x_k^2 dV summed as inertia per unit
    density (kg m^2 per kg/m^3); com (3,) and axes (3, 3) Q: the body frame in the given frame.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    faces: list
    face_normal: np.ndarray
    face_offset: np.ndarray
    volume: float
    inertia_per_density: np.ndarray
    com: np.ndarray
    axes: np.ndarray

    def inertia_diag(self, mass: float) -> np.ndarray:
        return self.inertia_per_density * (mass / self.volume)


def _scipy_hull(points: np.ndarray):
    try:
        from scipy.spatial import ConvexHull, QhullError
    except ImportError:
        return None, None
    return ConvexHull, QhullError


def hull_boundary(points, fail):
    """The boundary of the hull of ``points`` (n, 3), in their frame: (used (V,) indices of the
    hull's vertices into points, triangles (T, 3) into ``used``'s order, counter-clockwise seen
    from outside, faces (list of index loops into used's order), face normals (F, 3), face
    offsets (F,)). ``fail(expected)`` raises the caller's one-line error."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    ConvexHull, QhullError = _scipy_hull(p)
    if ConvexHull is None:
        fail("hull bodies need scipy (qhull), a dependency of rblog that is not installed: "
             "reinstall rblog (pip install rblog)")
    if len(p) < 4:
        fail(f"{len(p)} points, expected at least 4 points not all in one plane")
    scale = float(np.abs(p - p.mean(axis=0)).max())
    try:
        h = ConvexHull(p)
    except QhullError:
        fail(f"the {len(p)} points lie in one plane (or on a line), expected at least 4 "
             "points not all in one plane")
    # outward orientation of each triangle from qhull's facet normals
    tri = np.array(h.simplices, np.int64)
    nrm = h.equations[:, :3]
    off = -h.equations[:, 3]  # n . x = off on the facet
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    flip = np.einsum("ti,ti->t", np.cross(b - a, c - a), nrm) < 0
    tri[flip] = tri[flip][:, [0, 2, 1]]
    used = np.array(sorted(h.vertices.tolist()), np.int64)
    remap = np.full(len(p), -1, np.int64)
    remap[used] = np.arange(len(used))
    tri = remap[tri]
    verts = p[used]
    # faces: qhull's triangles grouped by plane
    groups: list[list[int]] = []
    for t in range(len(tri)):
        for g in groups:
            k = g[0]
            if (np.dot(nrm[k], nrm[t]) >= 1.0 - FACE_COPLANAR_RTOL
                    and abs(off[k] - off[t]) <= FACE_COPLANAR_RTOL * max(scale, 1e-300)):
                g.append(t)
                break
        else:
            groups.append([t])
    faces, fn, fo = [], [], []
    for g in groups:
        idx = np.unique(tri[g].reshape(-1))
        n = nrm[g[0]] / np.linalg.norm(nrm[g[0]])
        ctr = verts[idx].mean(axis=0)
        u = verts[idx[0]] - ctr
        u = u - np.dot(u, n) * n
        u /= np.linalg.norm(u)
        w = np.cross(n, u)
        d = verts[idx] - ctr
        loop = idx[np.argsort(np.arctan2(d @ w, d @ u), kind="stable")]
        if len(loop) > HULL_MAX_FACE_VERTICES:
            fail(f"a face of the hull has {len(loop)} vertices, expected at most "
                 f"{HULL_MAX_FACE_VERTICES} (simplify the mesh)")
        faces.append(loop)
        fn.append(n)
        fo.append(float(np.max(verts[loop] @ n)))
    return used, tri, faces, np.array(fn), np.array(fo)


def build_hull(points, fail) -> Hull:
    """The hull of ``points`` (n, 3) in its body frame (module docstring). ``fail(expected)``
    raises the caller's one-line error (it names the file and key)."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    used, tri, faces, fn, fo = hull_boundary(p, fail)
    vol, com, second = mp.hull_volume_com_second_moment(p[used], tri)
    ext = np.ptp(p, axis=0).max()
    if not vol > HULL_MIN_THICKNESS_RTOL * ext ** 3:
        fail(f"the {len(p)} points span a volume of {vol:.3g} m^3, expected at least 4 points "
             "not all in one plane")
    moments, q = mp.principal_axes(mp.hull_inertia_tensor(1.0, 1.0, second))
    return Hull(vertices=np.ascontiguousarray((p[used] - com) @ q), triangles=tri, faces=faces,
                face_normal=fn @ q, face_offset=fo - fn @ com, volume=vol,
                inertia_per_density=moments, com=com, axes=q)


def register(vertices, fail) -> int:
    """The engine's hull id of the hull of ``vertices`` (V, 3) (body frame, every one a vertex
    of the hull: a body's as the scene built it), its faces registered with the C++ core."""
    from rblog.engine import _core

    v = np.ascontiguousarray(np.asarray(vertices, np.float64).reshape(-1, 3))
    used, _, faces, fn, fo = hull_boundary(v, fail)
    if len(used) != len(v):
        fail(f"{len(v) - len(used)} of its {len(v)} vertices lie inside the hull, expected "
             "the hull's own vertices")
    start = np.concatenate([[0], np.cumsum([len(f) for f in faces])]).astype(np.int64)
    return int(_core.register_hull(v, np.ascontiguousarray(fn), np.ascontiguousarray(fo),
                                   start, np.concatenate(faces).astype(np.int64)))


def read_mesh_vertices(path: Path, fail) -> np.ndarray:
    """(n, 3) vertices of the mesh file ``path`` (read with trimesh, every part of a scene)."""
    try:
        import trimesh
    except ImportError:
        fail(f"reading a mesh file needs trimesh: {MESHES_HINT}")
    if not path.is_file():
        fail(f"no such file {str(path)!r}, expected a mesh file (.obj, .stl, ...) relative to "
             "the scene file")
    try:
        m = trimesh.load(str(path), force="mesh")
    except Exception as e:  # trimesh raises many kinds for a bad file
        fail(f"cannot read {str(path)!r} as a mesh ({type(e).__name__}: {e}), expected a mesh "
             "file trimesh reads (.obj, .stl, .ply, ...)")
    v = np.asarray(getattr(m, "vertices", np.zeros((0, 3))), np.float64).reshape(-1, 3)
    if not np.isfinite(v).all():
        fail(f"{str(path)!r} has non-finite vertices, expected finite coordinates (m)")
    return v
