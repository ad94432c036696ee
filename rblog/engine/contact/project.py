"""Project stage: a nonlinear (NGS) position pass on fresh contact geometry after the drift.

The velocity solve works on the manifolds of the start of the step and their first-order gap
rates. A box that tumbles or is struck hard within the step can bring a feature into contact
that none of those manifolds holds: a corner swinging over the edge of the box below, an
incident edge sliding past the rim of a reference face (the deepest point then lies on a clip
point that did not exist at the start), or a pair whose clipped face was empty at the start.
Such a feature is unconstrained for the step and ends it up to ~|v| h deep (1 mm at 1 m/s and
dt = 1 ms in the 500-box pile).

This stage runs the narrowphase again at the end-of-step configuration, first with a *negative*
speculative distance ``-depth``, so only points deeper than ``depth`` come back (the separating
axis test rejects every other pair on its first axis, which keeps the pass cheap). Around the
bodies of those points it gathers every contact of the bodies and of their neighbours (two
rings, see project_positions), and pushes all gathered points to ``s >= -depth`` by
Gauss-Seidel on position-level impulses (Box2D v2's ``SolvePositionConstraints``, Catto's
"nonlinear Gauss-Seidel", on fresh geometry). The neighbours hold: a body pushed out of one
overlap is not pushed into the body under it. Per point k, per sweep::

    lambda_k += max(-(s_k + n . (dx_a + dth_a x r_a - dx_b - dth_b x r_b) + depth) / K_k, -lambda_k)
    dx_a += m_a^-1 lambda n,  dth_a += I_a^-1 (r_a x lambda n)   (b gets the negatives)

with K_k the point's effective inverse mass (as in the velocity solve), clamped accumulated
``lambda >= 0`` (pushes only). There is no cap on the push per step (unlike the split
impulses' ``max_correction_speed``): an overlap that a step made is undone in that step, up to
the ~2 mm that a box struck at 2 m/s can make in 1 ms; a scene that starts with overlaps has
them pushed out to ``depth`` in its first step, without any velocity.

Only positions and orientations move; the momenta P and L are untouched (but for the hand-back
below), so the pass injects no momentum, and no kinetic energy into isotropic bodies (for
others the turned inertia changes the spin energy by O(|dth|) of it, as the split-impulse
pseudo spin does); the next step's contacts, at the corrected depth, stop the approach. The
pair's impulses are equal and opposite at one point, so its centre of mass stays put; the
world step hands the orbital change ``dx x P`` back to the spin, as after the split-impulse
shift, so that ``sum(x x P + L)`` stays exact.

Shapes and frames: ``pairs`` (K, 2) shape ids (bodies, static boxes, ground; see broadphase),
``position`` (N, 3) and ``rotation`` (N, 3, 3) body -> world at the end of the step;
corrections ``dx`` and ``dth`` are (N+1, 3) world displacements and rotation vectors (row N:
the static dummy, which stands for static geometry and sleeping bodies and never moves).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rblog.engine.constants import PROJECTION_RINGS
from rblog.engine.integrators import drift_rotation
from rblog.engine.rotation import load_mat, omega_world
from rblog.engine.contact.collide import pair_geometry
from rblog.engine.contact.narrowphase import COLLIDE_TABLE, collide, manifold_part

# columns of the projection's point rows
_PN = 0  # normal from b into a (3)
_PRA = 3  # anchor on a (3): point - x_a
_PRB = 6  # anchor on b (3): point - x_b (0 for static)
_PS = 9  # separation at the end of the step (m), before this pass
_PK = 10  # 1 / effective inverse mass along the normal
_PL = 11  # accumulated position impulse (kg m)
_P_COLS = 12
#: columns of the point rows the world step allocates for this stage
PROJ_COLS = _P_COLS


@njit(cache=True)
def _inv_inertia_times(iso_shortcut, iso, inv_inertia, rotation, i, x, y, z):
    """World inverse inertia of body i times (x, y, z): R diag(1/I) R^T v."""
    if iso_shortcut and iso[i]:
        s = inv_inertia[i, 0]
        return s * x, s * y, s * z
    return omega_world(load_mat(rotation, i), inv_inertia[i, 0], inv_inertia[i, 1],
                       inv_inertia[i, 2], x, y, z)


@njit(cache=True)
def _grow(rows, ids):
    cap = 2 * rows.shape[0] + 16
    r2 = np.zeros((cap, _P_COLS))
    i2 = np.zeros((cap, 2), np.int64)
    for k in range(rows.shape[0]):
        for c in range(_P_COLS):
            r2[k, c] = rows[k, c]
        i2[k, 0] = ids[k, 0]
        i2[k, 1] = ids[k, 1]
    return r2, i2


@njit(cache=True)
def _add_points(res, a, b, ia, ib, n_dyn, inv_mass, inv_inertia, iso, iso_shortcut, position,
                rotation, nrm, pts, sep, rows, ids, n_pts):
    """Append the collider's points (both manifolds of ``res``) as projection rows."""
    b_dyn = b < n_dyn
    for part in range(2):
        cnt, row = manifold_part(res, part)
        nx, ny, nz = nrm[3 * part], nrm[3 * part + 1], nrm[3 * part + 2]
        for q in range(cnt):
            if n_pts == rows.shape[0]:
                rows, ids = _grow(rows, ids)
            p = n_pts
            n_pts += 1
            ids[p, 0] = ia
            ids[p, 1] = ib
            px, py, pz = pts[row + q, 0], pts[row + q, 1], pts[row + q, 2]
            rows[p, _PN], rows[p, _PN + 1], rows[p, _PN + 2] = nx, ny, nz
            rax, ray, raz = px - position[a, 0], py - position[a, 1], pz - position[a, 2]
            if b_dyn:
                rbx, rby, rbz = px - position[b, 0], py - position[b, 1], pz - position[b, 2]
            else:
                rbx, rby, rbz = 0.0, 0.0, 0.0
            rows[p, _PRA], rows[p, _PRA + 1], rows[p, _PRA + 2] = rax, ray, raz
            rows[p, _PRB], rows[p, _PRB + 1], rows[p, _PRB + 2] = rbx, rby, rbz
            rows[p, _PS] = sep[row + q]
            rows[p, _PL] = 0.0
            kk = 0.0
            if ia < n_dyn:
                cx = ray * nz - raz * ny
                cy = raz * nx - rax * nz
                cz = rax * ny - ray * nx
                ix, iy, iz = _inv_inertia_times(iso_shortcut, iso, inv_inertia, rotation, ia,
                                                cx, cy, cz)
                kk += inv_mass[ia] + cx * ix + cy * iy + cz * iz
            if ib < n_dyn:
                cx = rby * nz - rbz * ny
                cy = rbz * nx - rbx * nz
                cz = rbx * ny - rby * nx
                ix, iy, iz = _inv_inertia_times(iso_shortcut, iso, inv_inertia, rotation, ib,
                                                cx, cy, cz)
                kk += inv_mass[ib] + cx * ix + cy * iy + cz * iz
            rows[p, _PK] = 1.0 / kk if kk > 0.0 else 0.0
    return rows, ids, n_pts


@njit(cache=True)
def project_positions(pairs, n_pairs, n_dyn, n_static, geom, size, inv_mass, inv_inertia, iso,
                      iso_shortcut, awake, position, rotation, sb_pos, sb_rot, sb_ext, gn, goff,
                      depth, n_iter, rows, ids, nrm, pts, sep, fid, work, poly, dx, dth):
    """Find the bodies with points deeper than ``depth``, gather the contacts around them, and
    Gauss-Seidel every gathered point to ``s >= -depth``.

    Gathering: a first pass over the candidate ``pairs`` with speculative distance ``-depth``
    marks the bodies of deep points (ring 1; nothing else is collided in full). Then, for
    PROJECTION_RINGS rings, every pair with a body of the current ring is collided with
    speculative distance equal to the deepest penetration found (no correction can move a
    point farther than that) and all its points are gathered; its partner joins the next
    ring. So a body pushed out of one overlap is held by its other contacts instead of being
    pushed into them.

    ``rows`` (R, 12) / ``ids`` (R, 2) are scratch point rows (grown when full); ``dx``/``dth``
    (N+1, 3) receive each body's correction (zeroed here for the bodies of the gathered points;
    read them only for those). Returns (number of gathered points, rows, ids); the number is 0
    when nothing is deeper than ``depth``.
    """
    deepest = 0.0
    ring = np.zeros(n_dyn + 1, np.int64)  # ring of each body (0: not gathered)
    done = np.zeros(max(n_pairs, 1), np.bool_)  # pair already gathered (or asleep)
    for k in range(n_pairs):
        a = pairs[k, 0]
        b = pairs[k, 1]
        b_dyn = b < n_dyn
        a_awake = awake[a] != 0
        b_awake = b_dyn and awake[b] != 0
        if not a_awake and not b_awake:
            done[k] = True
            continue
        ga = geom[a]
        gb, cb, rotb, sb = pair_geometry(a, b, n_dyn, n_static, geom, size, position, rotation,
                                         sb_pos, sb_rot, sb_ext)
        code = COLLIDE_TABLE[min(ga, gb), max(ga, gb)]
        res = collide(code, ga > gb, position[a], rotation[a], size[a], cb, rotb, sb, gn, goff,
                      -depth, nrm, pts, sep, fid, work, poly)
        if res <= 0:
            continue
        for part in range(2):
            cnt, row = manifold_part(res, part)
            for q in range(cnt):
                deepest = max(deepest, -sep[row + q])
        if a_awake:
            ring[a] = 1
        if b_awake:
            ring[b] = 1
    if deepest <= 0.0:
        return 0, rows, ids
    n_pts = 0
    for r in range(1, PROJECTION_RINGS + 1):
        for k in range(n_pairs):
            if done[k]:
                continue
            a = pairs[k, 0]
            b = pairs[k, 1]
            b_dyn = b < n_dyn
            if ring[a] != r and not (b_dyn and ring[b] == r):
                continue
            done[k] = True
            a_awake = awake[a] != 0
            b_awake = b_dyn and awake[b] != 0
            ga = geom[a]
            gb, cb, rotb, sb = pair_geometry(a, b, n_dyn, n_static, geom, size, position,
                                             rotation, sb_pos, sb_rot, sb_ext)
            code = COLLIDE_TABLE[min(ga, gb), max(ga, gb)]
            res = collide(code, ga > gb, position[a], rotation[a], size[a], cb, rotb, sb, gn,
                          goff, deepest, nrm, pts, sep, fid, work, poly)
            if res <= 0:
                continue
            ia = a if a_awake else n_dyn
            ib = b if b_awake else n_dyn
            rows, ids, n_pts = _add_points(res, a, b, ia, ib, n_dyn, inv_mass, inv_inertia, iso,
                                           iso_shortcut, position, rotation, nrm, pts, sep,
                                           rows, ids, n_pts)
            if a_awake and ring[a] == 0:
                ring[a] = r + 1
            if b_awake and ring[b] == 0:
                ring[b] = r + 1
    if n_pts == 0:
        return 0, rows, ids
    for p in range(n_pts):
        for c in range(2):
            i = ids[p, c]
            for k in range(3):
                dx[i, k] = 0.0
                dth[i, k] = 0.0
    for _ in range(n_iter):
        for p in range(n_pts):
            ia = ids[p, 0]
            ib = ids[p, 1]
            nx, ny, nz = rows[p, _PN], rows[p, _PN + 1], rows[p, _PN + 2]
            rax, ray, raz = rows[p, _PRA], rows[p, _PRA + 1], rows[p, _PRA + 2]
            rbx, rby, rbz = rows[p, _PRB], rows[p, _PRB + 1], rows[p, _PRB + 2]
            # separation now, to first order in this pass's corrections
            ux = dx[ia, 0] + dth[ia, 1] * raz - dth[ia, 2] * ray - dx[ib, 0] - dth[ib, 1] * rbz + dth[ib, 2] * rby
            uy = dx[ia, 1] + dth[ia, 2] * rax - dth[ia, 0] * raz - dx[ib, 1] - dth[ib, 2] * rbx + dth[ib, 0] * rbz
            uz = dx[ia, 2] + dth[ia, 0] * ray - dth[ia, 1] * rax - dx[ib, 2] - dth[ib, 0] * rby + dth[ib, 1] * rbx
            s = rows[p, _PS] + ux * nx + uy * ny + uz * nz
            old = rows[p, _PL]
            new = old - (s + depth) * rows[p, _PK]
            if new < 0.0:
                new = 0.0
            rows[p, _PL] = new
            d = new - old
            if d == 0.0:
                continue
            px, py, pz = d * nx, d * ny, d * nz
            if ia < n_dyn:
                ma = inv_mass[ia]
                dx[ia, 0] += ma * px
                dx[ia, 1] += ma * py
                dx[ia, 2] += ma * pz
                ex, ey, ez = _inv_inertia_times(iso_shortcut, iso, inv_inertia, rotation, ia,
                                                ray * pz - raz * py, raz * px - rax * pz,
                                                rax * py - ray * px)
                dth[ia, 0] += ex
                dth[ia, 1] += ey
                dth[ia, 2] += ez
            if ib < n_dyn:
                mb = inv_mass[ib]
                dx[ib, 0] -= mb * px
                dx[ib, 1] -= mb * py
                dx[ib, 2] -= mb * pz
                ex, ey, ez = _inv_inertia_times(iso_shortcut, iso, inv_inertia, rotation, ib,
                                                rby * pz - rbz * py, rbz * px - rbx * pz,
                                                rbx * py - rby * px)
                dth[ib, 0] -= ex
                dth[ib, 1] -= ey
                dth[ib, 2] -= ez
    return n_pts, rows, ids


@njit(cache=True)
def apply_projection(n_deep, ids, dx, dth, n, method, ortho, bd, iso_shortcut, position,
                      rotation, quat_wxyz, linear_momentum, angular_momentum, l_scratch,
                      anchor_steps):
    """Move the bodies of the project stage's points by their corrections: x += dx, the
    orientation by the rotation vector dth (through the run's integrator: a drift of unit
    duration with L = I_world dth), and L -= dx x P so that sum(x x P + L) stays exact. A moved
    body's exact-flow anchor is dropped (anchor_steps -1, see rblog.engine.state.FlowAnchors)."""
    for p in range(n_deep):
        for c in range(2):
            i = ids[p, c]
            if i >= n:
                continue
            ux, uy, uz = dx[i, 0], dx[i, 1], dx[i, 2]
            tx, ty, tz = dth[i, 0], dth[i, 1], dth[i, 2]
            if ux == 0.0 and uy == 0.0 and uz == 0.0 and tx == 0.0 and ty == 0.0 and tz == 0.0:
                continue  # no correction, or already applied (a body can have many points)
            position[i, 0] += ux
            position[i, 1] += uy
            position[i, 2] += uz
            anchor_steps[i] = -1
            qx, qy, qz = linear_momentum[i, 0], linear_momentum[i, 1], linear_momentum[i, 2]
            angular_momentum[i, 0] -= uy * qz - uz * qy
            angular_momentum[i, 1] -= uz * qx - ux * qz
            angular_momentum[i, 2] -= ux * qy - uy * qx
            if tx != 0.0 or ty != 0.0 or tz != 0.0:
                if iso_shortcut and bd.iso[i]:
                    s0 = bd.inertia[i, 0]
                    jx, jy, jz = s0 * tx, s0 * ty, s0 * tz
                else:
                    jx, jy, jz = omega_world(load_mat(rotation, i), bd.inertia[i, 0],
                                             bd.inertia[i, 1], bd.inertia[i, 2], tx, ty, tz)
                l_scratch[i, 0], l_scratch[i, 1], l_scratch[i, 2] = jx, jy, jz
                drift_rotation(method, ortho, quat_wxyz, rotation, l_scratch, bd.inv_inertia, i,
                               1.0)
            for k in range(3):
                dx[i, k] = 0.0
                dth[i, k] = 0.0
