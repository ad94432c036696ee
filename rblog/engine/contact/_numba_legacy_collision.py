"""The numba collision kernels, kept only while the numba world step (step.py) and project stage
(project.py) still import them (issue 28: the C++ core, csrc/engine/{manifold,box_box,narrowphase,
broad_phase,collide,island}.cpp, replaces them; delete this file when step.py and project.py run on
C++). The public modules (manifold, narrowphase, broadphase, collide, island) re-export these
names for those importers; nothing else should use them. Same code as before the port.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rblog.contract.trajectory import STATIC_BODY
from rblog.engine.constants import (
    AXIS_ABS_TOL, EDGE_PARALLEL_TOL, EDGE_REL_TOL, FACE_REL_TOL, FRICTION_ANCHOR_MAX_DRIFT_M,
    MANIFOLD_TOUCH_BAND_M,
)
from rblog.engine.contact.manifold import (
    _AREA_EPS, MAX_CLIP_POINTS, MAX_MANIFOLD_POINTS,
    MF_ACC, MF_AOK, MF_AR, MF_AT, MF_COLS, MF_E, MF_MU, MF_N, MF_T1, MF_T2, MI_A, MI_ACTIVE, MI_B,
    MI_COLS, MI_COUNT, MI_KEY, MI_REC_A, MI_REC_B, MI_START, PF_COLS, PF_D, PF_F, PF_IMPACT, PF_L1,
    PF_L2, PF_LN, PF_LP, PF_LWS, PF_P, PF_RA, PF_RB, PF_S, PF_SEND, PF_W0, PF_WT,
)
from rblog.engine.contact.narrowphase import (
    COLLIDE_BOX_BOX, COLLIDE_BOX_PLANE, COLLIDE_SPHERE_BOX, COLLIDE_SPHERE_PLANE,
    COLLIDE_SPHERE_SPHERE, COLLIDE_TABLE, GEOM_BOX, GEOM_PLANE, GEOM_SPHERE,
)

# ---- manifold.py ----

@njit(cache=True)
def swap_point(pts, sep, fid, i, j):
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
    largest triangle, the one adding the most area outside that triangle (Gregorius), each chosen
    among the touching points first (within MANIFOLD_TOUCH_BAND_M of the deepest) and among all
    of them only when no touching point is left that adds length or area. Returns 4."""
    if count <= MAX_MANIFOLD_POINTS:
        return count
    nx, ny, nz = nrm[0], nrm[1], nrm[2]
    # 1: deepest
    best = 0
    for j in range(1, count):
        if sep[j] < sep[best]:
            best = j
    swap_point(pts, sep, fid, 0, best)
    touch = sep[0] + MANIFOLD_TOUCH_BAND_M
    # 2: farthest from point 0 (touching first)
    best = -1
    bd = 0.0
    for only_touching in (True, False):
        for j in range(1, count):
            if only_touching and sep[j] > touch:
                continue
            dx, dy, dz = pts[j, 0] - pts[0, 0], pts[j, 1] - pts[0, 1], pts[j, 2] - pts[0, 2]
            d = dx * dx + dy * dy + dz * dz
            if d > bd:
                bd = d
                best = j
        if best >= 0:
            break
    swap_point(pts, sep, fid, 1, max(best, 1))
    # 3: largest |triangle area| with 0, 1 (measured about the normal; touching first)
    ax, ay, az = pts[1, 0] - pts[0, 0], pts[1, 1] - pts[0, 1], pts[1, 2] - pts[0, 2]
    best = -1
    ba = _AREA_EPS
    sgn = 1.0
    for only_touching in (True, False):
        for j in range(2, count):
            if only_touching and sep[j] > touch:
                continue
            bx, by, bz = pts[j, 0] - pts[0, 0], pts[j, 1] - pts[0, 1], pts[j, 2] - pts[0, 2]
            area = nx * (ay * bz - az * by) + ny * (az * bx - ax * bz) + nz * (ax * by - ay * bx)
            if abs(area) > ba:
                ba = abs(area)
                best = j
                sgn = 1.0 if area >= 0.0 else -1.0
        if best >= 0:
            break
    swap_point(pts, sep, fid, 2, max(best, 2))
    # 4: the point farthest outside the triangle (most negative signed area over its edges;
    # touching first)
    best = -1
    ba = -_AREA_EPS
    for only_touching in (True, False):
        for j in range(3, count):
            if only_touching and sep[j] > touch:
                continue
            worst = 0.0
            for e in range(3):
                i0 = e
                i1 = (e + 1) % 3
                ex, ey, ez = pts[i1, 0] - pts[i0, 0], pts[i1, 1] - pts[i0, 1], pts[i1, 2] - pts[i0, 2]
                qx, qy, qz = pts[j, 0] - pts[i0, 0], pts[j, 1] - pts[i0, 1], pts[j, 2] - pts[i0, 2]
                area = sgn * (nx * (ey * qz - ez * qy) + ny * (ez * qx - ex * qz)
                              + nz * (ex * qy - ey * qx))
                if area < worst:
                    worst = area
            if worst < ba:
                ba = worst
                best = j
        if best >= 0:
            break
    swap_point(pts, sep, fid, 3, max(best, 3))
    return MAX_MANIFOLD_POINTS


# ---- box_box.py ----

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




# ---- narrowphase.py ----

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




# ---- broadphase.py ----

@njit(cache=True)
def body_aabbs(geom, size, radius, inv_mass, inv_inertia, awake, position, linear_momentum,
               rotation, angular_momentum, h, margin, lo, hi, reach):
    """World AABBs of the dynamic bodies (rows 0..N-1 of lo, hi), swept over the step."""
    n = position.shape[0]
    pad = 0.5 * margin
    for i in range(n):
        if geom[i] == GEOM_SPHERE:
            ex = ey = ez = size[i, 0]
        else:
            r = rotation[i]
            e0, e1, e2 = size[i, 0], size[i, 1], size[i, 2]
            ex = abs(r[0, 0]) * e0 + abs(r[0, 1]) * e1 + abs(r[0, 2]) * e2
            ey = abs(r[1, 0]) * e0 + abs(r[1, 1]) * e1 + abs(r[1, 2]) * e2
            ez = abs(r[2, 0]) * e0 + abs(r[2, 1]) * e1 + abs(r[2, 2]) * e2
        dx = dy = dz = 0.0
        rho = 0.0
        if awake[i]:
            im = inv_mass[i]
            dx = h * linear_momentum[i, 0] * im
            dy = h * linear_momentum[i, 1] * im
            dz = h * linear_momentum[i, 2] * im
            if geom[i] != GEOM_SPHERE:
                # |omega| <= |L| max(1/I): a cheap bound; a rotating box stays in its sphere
                lx, ly, lz = angular_momentum[i, 0], angular_momentum[i, 1], angular_momentum[i, 2]
                wmax = math.sqrt(lx * lx + ly * ly + lz * lz) * max(
                    inv_inertia[i, 0], max(inv_inertia[i, 1], inv_inertia[i, 2]))
                rho = min(h * wmax * radius[i], radius[i])
                ex = min(ex + rho, radius[i])
                ey = min(ey + rho, radius[i])
                ez = min(ez + rho, radius[i])
            reach[i] = math.sqrt(dx * dx + dy * dy + dz * dz) + rho
        else:
            reach[i] = 0.0
        x, y, z = position[i, 0], position[i, 1], position[i, 2]
        lo[i, 0] = x - ex - pad + min(dx, 0.0)
        lo[i, 1] = y - ey - pad + min(dy, 0.0)
        lo[i, 2] = z - ez - pad + min(dz, 0.0)
        hi[i, 0] = x + ex + pad + max(dx, 0.0)
        hi[i, 1] = y + ey + pad + max(dy, 0.0)
        hi[i, 2] = z + ez + pad + max(dz, 0.0)


@njit(cache=True)
def _grow_pairs(pairs):
    out = np.empty((2 * pairs.shape[0] + 16, 2), np.int64)
    for k in range(pairs.shape[0]):
        out[k, 0] = pairs[k, 0]
        out[k, 1] = pairs[k, 1]
    return out


@njit(cache=True)
def sweep_and_prune(n_items, n_dyn, lo, hi, group, awake, pairs):
    """Candidate pairs (lo id, hi id) among items 0..n_items-1 whose AABBs overlap.

    Skips static-static pairs and pairs in different non-zero groups. Pairs of sleeping bodies
    are emitted too (the collide stage carries their manifolds over). Returns (pairs, count);
    ``pairs`` is reallocated when full."""
    if n_items < 2:
        return pairs, 0
    # sweep axis: largest spread of the centres
    best_axis = 0
    best_var = -1.0
    for ax in range(3):
        s = 0.0
        s2 = 0.0
        for i in range(n_items):
            c = 0.5 * (lo[i, ax] + hi[i, ax])
            s += c
            s2 += c * c
        var = s2 - s * s / n_items
        if var > best_var:
            best_var = var
            best_axis = ax
    ax1 = (best_axis + 1) % 3
    ax2 = (best_axis + 2) % 3
    keys = np.empty(n_items)
    for i in range(n_items):
        keys[i] = lo[i, best_axis]
    order = np.argsort(keys, kind="mergesort")
    count = 0
    for ii in range(n_items):
        i = order[ii]
        hi_i = hi[i, best_axis]
        for jj in range(ii + 1, n_items):
            j = order[jj]
            # written as "not overlapping" so that a NaN box never pairs with anything
            if not lo[j, best_axis] <= hi_i:
                break
            if i >= n_dyn and j >= n_dyn:
                continue
            if not (lo[j, ax1] <= hi[i, ax1] and lo[i, ax1] <= hi[j, ax1]):
                continue
            if not (lo[j, ax2] <= hi[i, ax2] and lo[i, ax2] <= hi[j, ax2]):
                continue
            a = min(i, j)
            b = max(i, j)
            if b < n_dyn:
                ga = group[a]
                gb = group[b]
                if ga != 0 and gb != 0 and ga != gb:
                    continue
            if count == pairs.shape[0]:
                pairs = _grow_pairs(pairs)
            pairs[count, 0] = a
            pairs[count, 1] = b
            count += 1
    return pairs, count


@njit(cache=True)
def ground_pairs(n_dyn, n_static, st, lo, hi, pairs, n_pairs):
    """Append (body, ground) for every body whose padded AABB reaches the plane."""
    gid = n_dyn + n_static
    gx, gy, gz = st.gn[0], st.gn[1], st.gn[2]
    for i in range(n_dyn):
        cx = 0.5 * (lo[i, 0] + hi[i, 0])
        cy = 0.5 * (lo[i, 1] + hi[i, 1])
        cz = 0.5 * (lo[i, 2] + hi[i, 2])
        ext = (abs(gx) * (hi[i, 0] - lo[i, 0]) + abs(gy) * (hi[i, 1] - lo[i, 1])
               + abs(gz) * (hi[i, 2] - lo[i, 2])) * 0.5
        if gx * cx + gy * cy + gz * cz - st.goff - ext > 0.0:
            continue
        if n_pairs == pairs.shape[0]:
            pairs = _grow_pairs(pairs)
        pairs[n_pairs, 0] = i
        pairs[n_pairs, 1] = gid
        n_pairs += 1
    return pairs, n_pairs


# ---- collide.py ----

@njit(cache=True)
def tangent_basis(nx, ny, nz):
    """Unit t1, t2 with (t1, t2, n) right-handed, a deterministic function of n (so the basis,
    and warm starting, stay put while the normal does)."""
    ax, ay, az = abs(nx), abs(ny), abs(nz)
    # cross n with the world axis least aligned with it
    if ax <= ay and ax <= az:
        tx, ty, tz = 0.0, nz, -ny  # n x e_x
    elif ay <= az:
        tx, ty, tz = -nz, 0.0, nx  # n x e_y
    else:
        tx, ty, tz = ny, -nx, 0.0  # n x e_z
    ln = 1.0 / math.sqrt(tx * tx + ty * ty + tz * tz)
    tx, ty, tz = tx * ln, ty * ln, tz * ln
    return tx, ty, tz, ny * tz - nz * ty, nz * tx - nx * tz, nx * ty - ny * tx


@njit(cache=True)
def find_manifold(sorted_keys, sorted_idx, n, key):
    """Index of the manifold with ``key`` among the first n sorted keys, or -1."""
    lo = 0
    hi = n
    while lo < hi:
        mid = (lo + hi) >> 1
        if sorted_keys[mid] < key:
            lo = mid + 1
        else:
            hi = mid
    if lo < n and sorted_keys[lo] == key:
        return sorted_idx[lo]
    return -1


@njit(cache=True)
def sort_manifolds(mi, n_man, sorted_keys, sorted_idx):
    """Fill sorted_keys/sorted_idx (length >= n_man) with the manifolds ordered by pair key."""
    keys = np.empty(n_man, np.int64)
    for m in range(n_man):
        keys[m] = mi[m, MI_KEY]
    order = np.argsort(keys, kind="mergesort")
    for k in range(n_man):
        sorted_idx[k] = order[k]
        sorted_keys[k] = keys[order[k]]


@njit(cache=True)
def grow_manifolds(mi, mf, cap):
    """Arrays with room for cap manifolds (contents copied)."""
    if mi.shape[0] >= cap:
        return mi, mf
    new_cap = max(cap, 2 * mi.shape[0])
    mi2 = np.zeros((new_cap, MI_COLS), np.int64)
    mf2 = np.zeros((new_cap, MF_COLS))
    for m in range(mi.shape[0]):
        for c in range(MI_COLS):
            mi2[m, c] = mi[m, c]
        for c in range(MF_COLS):
            mf2[m, c] = mf[m, c]
    return mi2, mf2


@njit(cache=True)
def grow_points(pf, pid, cap):
    if pf.shape[0] >= cap:
        return pf, pid
    new_cap = max(cap, 2 * pf.shape[0])
    pf2 = np.zeros((new_cap, PF_COLS))
    pid2 = np.zeros(new_cap, np.int64)
    for p in range(pf.shape[0]):
        for c in range(PF_COLS):
            pf2[p, c] = pf[p, c]
        pid2[p] = pid[p]
    return pf2, pid2


@njit(cache=True)
def pair_geometry(a, b, n_dyn, n_static, geom, size, position, rotation, sb_pos, sb_rot, sb_ext):
    """(geom_b, centre_b, rotation_b, size_b) of shape id b (a's data stand in for the plane)."""
    if b < n_dyn:
        return geom[b], position[b], rotation[b], size[b]
    if b < n_dyn + n_static:
        k = b - n_dyn
        return GEOM_BOX, sb_pos[k], sb_rot[k], sb_ext[k]
    return GEOM_PLANE, position[a], rotation[a], size[a]


@njit(cache=True)
def collide_pairs(pairs, n_pairs, n_dyn, n_static, geom, size, awake, position, rotation, reach,
                  margin, restitution, friction, accel,
                  sb_pos, sb_rot, sb_ext, sb_e, sb_mu, gn, goff, g_e, g_mu,
                  prev_mi, prev_mf, prev_pf, prev_pid, prev_keys, prev_idx, prev_n,
                  mi, mf, pf, pid, warm, anchor_distance, nrm, pts, sep, fid, work, poly):
    """Manifolds of the candidate pairs into (mi, mf, pf, pid), which must have room for
    2 n_pairs manifolds and 8 n_pairs points. Returns (n_manifolds, n_points)."""
    n_shapes = n_dyn + n_static + 1
    n_man = 0
    n_pts = 0
    ad2 = anchor_distance * anchor_distance
    for k in range(n_pairs):
        a = pairs[k, 0]
        b = pairs[k, 1]
        key = a * n_shapes + b  # manifold keys are 2 key + part (part 1: a box pair's second)
        b_dyn = b < n_dyn
        a_awake = awake[a] != 0
        b_awake = b_dyn and awake[b] != 0
        if not a_awake and not b_awake:
            # both sides still: carry the manifolds over as they were
            for part in range(2):
                j = find_manifold(prev_keys, prev_idx, prev_n, 2 * key + part)
                if j < 0:
                    continue
                cnt = prev_mi[j, MI_COUNT]
                for c in range(MI_COLS):
                    mi[n_man, c] = prev_mi[j, c]
                for c in range(MF_COLS):
                    mf[n_man, c] = prev_mf[j, c]
                ps = prev_mi[j, MI_START]
                for q in range(cnt):
                    for c in range(PF_COLS):
                        pf[n_pts + q, c] = prev_pf[ps + q, c]
                    pid[n_pts + q] = prev_pid[ps + q]
                mi[n_man, MI_START] = n_pts
                mi[n_man, MI_ACTIVE] = 0
                n_man += 1
                n_pts += cnt
            continue
        ga = geom[a]
        gb, cb, rotb, sb = pair_geometry(a, b, n_dyn, n_static, geom, size, position, rotation,
                                         sb_pos, sb_rot, sb_ext)
        lo_g = min(ga, gb)
        hi_g = max(ga, gb)
        code = COLLIDE_TABLE[lo_g, hi_g]
        spec = margin + reach[a]
        if b_dyn:
            spec += reach[b]
        res = collide(code, ga > gb, position[a], rotation[a], size[a], cb, rotb, sb, gn, goff,
                      spec, nrm, pts, sep, fid, work, poly)
        if res <= 0:
            continue
        rolls = ga == GEOM_SPHERE or gb == GEOM_SPHERE
        for part in range(2):
            cnt, row = manifold_part(res, part)
            if cnt == 0:
                continue
            n_man, n_pts = _add_manifold(
                2 * key + part, a, b, n_dyn, n_static, a_awake, b_awake, b_dyn, cnt, row, part,
                rolls,
                position, rotation, sb_pos, sb_rot, restitution, friction, accel, sb_e, sb_mu,
                g_e, g_mu, prev_mi, prev_mf, prev_pf, prev_pid, prev_keys, prev_idx, prev_n,
                mi, mf, pf, pid, n_man, n_pts, warm, ad2, nrm, pts, sep, fid)
    return n_man, n_pts


@njit(cache=True)
def _add_manifold(key, a, b, n_dyn, n_static, a_awake, b_awake, b_dyn, cnt, row, part, rolls,
                  position, rotation, sb_pos, sb_rot, restitution, friction, accel, sb_e, sb_mu,
                  g_e, g_mu, prev_mi, prev_mf, prev_pf, prev_pid, prev_keys, prev_idx, prev_n,
                  mi, mf, pf, pid, n_man, n_pts, warm, ad2, nrm, pts, sep, fid):
    """Append one manifold (points rows row.. of the collider's output) with warm starting.
    ``rolls``: a sphere's pair, which gets no friction anchor (a rolling sphere brings a new
    material point to the contact every step, so a pose anchor would resist rolling; its friction
    rows target zero slip, as without anchors)."""
    m = n_man
    n_man += 1
    mi[m, MI_KEY] = key
    mi[m, MI_A] = a if a_awake else n_dyn
    mi[m, MI_B] = b if b_awake else n_dyn
    mi[m, MI_REC_A] = a
    mi[m, MI_REC_B] = b if b_dyn else STATIC_BODY
    mi[m, MI_START] = n_pts
    mi[m, MI_COUNT] = cnt
    mi[m, MI_ACTIVE] = 1
    nx, ny, nz = nrm[3 * part], nrm[3 * part + 1], nrm[3 * part + 2]
    t1x, t1y, t1z, t2x, t2y, t2z = tangent_basis(nx, ny, nz)
    mf[m, MF_N], mf[m, MF_N + 1], mf[m, MF_N + 2] = nx, ny, nz
    mf[m, MF_T1], mf[m, MF_T1 + 1], mf[m, MF_T1 + 2] = t1x, t1y, t1z
    mf[m, MF_T2], mf[m, MF_T2 + 1], mf[m, MF_T2 + 2] = t2x, t2y, t2z
    # materials and the gap acceleration n . (a_a - a_b) from external forces
    ax, ay, az = 0.0, 0.0, 0.0
    if a_awake:
        ax, ay, az = accel[a, 0], accel[a, 1], accel[a, 2]
    if b_dyn:
        mu = math.sqrt(friction[a] * friction[b])
        e = max(restitution[a], restitution[b])
        if b_awake:
            ax -= accel[b, 0]
            ay -= accel[b, 1]
            az -= accel[b, 2]
    elif b < n_dyn + n_static:
        mu = math.sqrt(friction[a] * sb_mu[b - n_dyn])
        e = max(restitution[a], sb_e[b - n_dyn])
    else:
        mu = math.sqrt(friction[a] * g_mu)
        e = max(restitution[a], g_e)
    mf[m, MF_MU] = mu
    mf[m, MF_E] = e
    mf[m, MF_ACC] = nx * ax + ny * ay + nz * az
    # warm starting from the previous step's manifold of this pair
    j = -1
    if warm:
        j = find_manifold(prev_keys, prev_idx, prev_n, key)
    pa = position[a]
    # the friction anchor: b's frame (the world for the ground), a's pose in it now, and the
    # pose it had when the pair started sticking (carried over while store_impulses keeps it)
    if b_dyn:
        xb, rb = position[b], rotation[b]
    elif b < n_dyn + n_static:
        xb, rb = sb_pos[b - n_dyn], sb_rot[b - n_dyn]
    else:
        xb, rb = np.zeros(3), np.eye(3)
    ra = rotation[a]
    anchored = j >= 0 and prev_mf[j, MF_AOK] > 0.0 and not rolls
    for r in range(3):
        for c in range(3):
            # R_b^T R_a
            v = rb[0, r] * ra[0, c] + rb[1, r] * ra[1, c] + rb[2, r] * ra[2, c]
            mf[m, MF_AR + 3 * r + c] = prev_mf[j, MF_AR + 3 * r + c] if anchored else v
        v = rb[0, r] * (pa[0] - xb[0]) + rb[1, r] * (pa[1] - xb[1]) + rb[2, r] * (pa[2] - xb[2])
        mf[m, MF_AT + r] = prev_mf[j, MF_AT + r] if anchored else v
    mf[m, MF_AOK] = 0.0 if rolls else 1.0
    drift_max = 0.0
    for q in range(cnt):
        p = n_pts + q
        px, py, pz = pts[row + q, 0], pts[row + q, 1], pts[row + q, 2]
        pf[p, PF_P], pf[p, PF_P + 1], pf[p, PF_P + 2] = px, py, pz
        pf[p, PF_RA], pf[p, PF_RA + 1], pf[p, PF_RA + 2] = px - pa[0], py - pa[1], pz - pa[2]
        if b_dyn:
            pb = position[b]
            pf[p, PF_RB], pf[p, PF_RB + 1], pf[p, PF_RB + 2] = px - pb[0], py - pb[1], pz - pb[2]
        else:
            pf[p, PF_RB], pf[p, PF_RB + 1], pf[p, PF_RB + 2] = 0.0, 0.0, 0.0
        pf[p, PF_S] = sep[row + q]
        pf[p, PF_SEND] = sep[row + q]
        pid[p] = fid[row + q]
        ln = 0.0
        l1 = 0.0
        l2 = 0.0
        if j >= 0:
            ps = prev_mi[j, MI_START]
            pc = prev_mi[j, MI_COUNT]
            match = -1
            for r in range(ps, ps + pc):
                if prev_pid[r] == fid[row + q]:
                    match = r
                    break
            if match < 0:
                best = ad2
                for r in range(ps, ps + pc):
                    dx = prev_pf[r, PF_P] - px
                    dy = prev_pf[r, PF_P + 1] - py
                    dz = prev_pf[r, PF_P + 2] - pz
                    d2 = dx * dx + dy * dy + dz * dz
                    if d2 <= best:
                        best = d2
                        match = r
            if match >= 0:
                ln = prev_pf[match, PF_LWS]
                fx, fy, fz = prev_pf[match, PF_F], prev_pf[match, PF_F + 1], prev_pf[match, PF_F + 2]
                l1 = fx * t1x + fy * t1y + fz * t1z
                l2 = fx * t2x + fy * t2y + fz * t2z
        # drift of a's material point at the contact: y = R_a^T (p - x_a) in a's frame, put by
        # the anchor pose at x_b + R_b (A_R y + A_t); D = p minus that (world)
        y0, y1, y2 = 0.0, 0.0, 0.0
        for r in range(3):
            e = (ra[0, r] * (px - pa[0]) + ra[1, r] * (py - pa[1]) + ra[2, r] * (pz - pa[2]))
            if r == 0:
                y0 = e
            elif r == 1:
                y1 = e
            else:
                y2 = e
        q0 = mf[m, MF_AR] * y0 + mf[m, MF_AR + 1] * y1 + mf[m, MF_AR + 2] * y2 + mf[m, MF_AT]
        q1 = mf[m, MF_AR + 3] * y0 + mf[m, MF_AR + 4] * y1 + mf[m, MF_AR + 5] * y2 + mf[m, MF_AT + 1]
        q2 = mf[m, MF_AR + 6] * y0 + mf[m, MF_AR + 7] * y1 + mf[m, MF_AR + 8] * y2 + mf[m, MF_AT + 2]
        dx = px - (xb[0] + rb[0, 0] * q0 + rb[0, 1] * q1 + rb[0, 2] * q2)
        dy = py - (xb[1] + rb[1, 0] * q0 + rb[1, 1] * q1 + rb[1, 2] * q2)
        dz = pz - (xb[2] + rb[2, 0] * q0 + rb[2, 1] * q1 + rb[2, 2] * q2)
        if rolls:
            dx, dy, dz = 0.0, 0.0, 0.0
        pf[p, PF_D], pf[p, PF_D + 1], pf[p, PF_D + 2] = dx, dy, dz
        dn = dx * nx + dy * ny + dz * nz
        drift_max = max(drift_max, dx * dx + dy * dy + dz * dz - dn * dn)
        pf[p, PF_LN] = ln
        pf[p, PF_L1] = l1
        pf[p, PF_L2] = l2
        pf[p, PF_LWS] = ln
        pf[p, PF_LP] = 0.0
        pf[p, PF_W0] = 0.0
        pf[p, PF_WT] = -1.0
        pf[p, PF_IMPACT] = 0.0
        pf[p, PF_F], pf[p, PF_F + 1], pf[p, PF_F + 2] = 0.0, 0.0, 0.0
    if drift_max > FRICTION_ANCHOR_MAX_DRIFT_M * FRICTION_ANCHOR_MAX_DRIFT_M:
        # drifted too far to be pulled back (the pair was struck): anchored anew where it is
        for r in range(3):
            for c in range(3):
                mf[m, MF_AR + 3 * r + c] = (rb[0, r] * ra[0, c] + rb[1, r] * ra[1, c]
                                            + rb[2, r] * ra[2, c])
            mf[m, MF_AT + r] = (rb[0, r] * (pa[0] - xb[0]) + rb[1, r] * (pa[1] - xb[1])
                                + rb[2, r] * (pa[2] - xb[2]))
        for p in range(n_pts, n_pts + cnt):
            pf[p, PF_D], pf[p, PF_D + 1], pf[p, PF_D + 2] = 0.0, 0.0, 0.0
    n_pts += cnt
    return n_man, n_pts


# ---- island.py ----

@njit(cache=True)
def find_root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True)
def update_sleep(n_dyn, mi, pf, n_man, awake, sleep_timer, island_of, island_counter,
                 linear_momentum, angular_momentum, inv_mass, inv_inertia, radius, h,
                 sleep_speed, sleep_time, parent, island_min_time, island_supported):
    """Advance rest timers, build islands, put islands at rest to sleep. Returns how many
    bodies fell asleep."""
    for i in range(n_dyn):
        parent[i] = i
        island_supported[i] = 0
        island_min_time[i] = math.inf
        if not awake[i]:
            continue
        im = inv_mass[i]
        px, py, pz = linear_momentum[i, 0], linear_momentum[i, 1], linear_momentum[i, 2]
        v = math.sqrt(px * px + py * py + pz * pz) * im
        lx, ly, lz = angular_momentum[i, 0], angular_momentum[i, 1], angular_momentum[i, 2]
        w = math.sqrt(lx * lx + ly * ly + lz * lz) * max(
            inv_inertia[i, 0], max(inv_inertia[i, 1], inv_inertia[i, 2]))
        speed = max(v, w * radius[i])
        if speed < sleep_speed:
            sleep_timer[i] += h
        else:
            sleep_timer[i] = 0.0
    # islands: union the bodies of touching manifolds
    any_ready = False
    for i in range(n_dyn):
        if awake[i] and sleep_timer[i] >= sleep_time:
            any_ready = True
            break
    if not any_ready:
        return 0
    for m in range(n_man):
        if not mi[m, MI_ACTIVE]:
            continue
        touching = False
        start = mi[m, MI_START]
        for p in range(start, start + mi[m, MI_COUNT]):
            if pf[p, PF_LWS] > 0.0 or pf[p, PF_SEND] <= 0.0:
                touching = True
                break
        if not touching:
            continue
        a = mi[m, MI_A]
        b = mi[m, MI_B]
        if a < n_dyn:
            island_supported[a] = 1
        if b < n_dyn:
            island_supported[b] = 1
        if a < n_dyn and b < n_dyn:
            ra = find_root(parent, a)
            rb = find_root(parent, b)
            if ra != rb:
                parent[max(ra, rb)] = min(ra, rb)
    for i in range(n_dyn):
        if not awake[i]:
            continue
        r = find_root(parent, i)
        island_min_time[r] = min(island_min_time[r], sleep_timer[i])
        if island_supported[i]:
            island_supported[r] = 1
    n_slept = 0
    base = island_counter[0]
    for i in range(n_dyn):
        if not awake[i]:
            continue
        r = find_root(parent, i)
        if island_min_time[r] >= sleep_time and island_supported[r]:
            awake[i] = 0
            island_of[i] = base + r
            for k in range(3):
                linear_momentum[i, k] = 0.0
                angular_momentum[i, k] = 0.0
            n_slept += 1
    island_counter[0] = base + n_dyn
    return n_slept


@njit(cache=True)
def wake_island(island, n_dyn, awake, sleep_timer, island_of, linear_momentum,
                angular_momentum, force, torque, h, do_kick):
    """Wake every body of a sleeping island, giving it this step's force kick."""
    for j in range(n_dyn):
        if awake[j] or island_of[j] != island:
            continue
        awake[j] = 1
        sleep_timer[j] = 0.0
        island_of[j] = -1
        if do_kick:
            for k in range(3):
                linear_momentum[j, k] += h * force[j, k]
                angular_momentum[j, k] += h * torque[j, k]


@njit(cache=True)
def wake_touched(pairs, n_pairs, n_dyn, n_static, geom, size, awake, sleep_timer, island_of,
                 position, rotation, reach, margin, slop, sb_pos, sb_rot, sb_ext, gn, goff,
                 linear_momentum, angular_momentum, force, torque, h, do_kick,
                 nrm, pts, sep, fid, work, poly, inv_mass, accel, radius, inv_inertia):
    """Wake the sleeping islands that an awake body will reach within this step, by its motion
    before this step's force kick (a body resting beside a sleeper does not wake it; one that
    pushes on it wakes it after the solve, see wake_pushed). Returns the islands woken."""
    n_woken = 0
    for k in range(n_pairs):
        a = pairs[k, 0]
        b = pairs[k, 1]
        if b >= n_dyn:
            continue
        if (awake[a] != 0) == (awake[b] != 0):
            continue
        sleeper = b if awake[a] else a
        mover = a if awake[a] else b
        im = inv_mass[mover]
        vx = linear_momentum[mover, 0] * im
        vy = linear_momentum[mover, 1] * im
        vz = linear_momentum[mover, 2] * im
        if do_kick:
            vx -= h * accel[mover, 0]
            vy -= h * accel[mover, 1]
            vz -= h * accel[mover, 2]
        lx, ly, lz = (angular_momentum[mover, 0], angular_momentum[mover, 1],
                      angular_momentum[mover, 2])
        wmax = math.sqrt(lx * lx + ly * ly + lz * lz) * max(
            inv_inertia[mover, 0], max(inv_inertia[mover, 1], inv_inertia[mover, 2]))
        close = h * (math.sqrt(vx * vx + vy * vy + vz * vz) + wmax * radius[mover])
        if close <= slop:
            # a (nearly) resting neighbour: if it does push, wake_pushed wakes the island
            continue
        gb, cb, rotb, sb = pair_geometry(a, b, n_dyn, n_static, geom, size, position, rotation,
                                         sb_pos, sb_rot, sb_ext)
        ga = geom[a]
        code = COLLIDE_TABLE[min(ga, gb), max(ga, gb)]
        spec = margin + reach[a] + reach[b]
        res = collide(code, ga > gb, position[a], rotation[a], size[a], cb, rotb, sb, gn, goff,
                      spec, nrm, pts, sep, fid, work, poly)
        for q in range(8):
            if (q < 4 and q >= res % 8) or (q >= 4 and q - 4 >= res // 8):
                continue
            if sep[q] < close:
                n_woken += 1
                wake_island(island_of[sleeper], n_dyn, awake, sleep_timer, island_of,
                            linear_momentum, angular_momentum, force, torque, h, do_kick)
                break
    return n_woken


@njit(cache=True)
def wake_pushed(mi, mf, pf, n_man, n_dyn, awake, sleep_timer, island_of, position,
                linear_momentum, angular_momentum, force, torque, h):
    """Wake the sleeping islands that an awake body pushed on in this step's solve. Returns the
    islands woken.

    A sleeper stood in as static in this step's solve (solver index = the static dummy), so the
    impulses its awake neighbours received from it were applied to them alone. Each is handed to
    the sleeper now, equal and opposite at the same contact point: J on body a is
    ``lambda_n n + f`` (normal impulse, world friction impulse), the sleeper gets -J if it is b
    (+J if a) into P, and (p - x) x (-J) into L. Linear momentum and angular momentum about any
    point are then conserved exactly, as between two awake bodies; from the next step on the
    island moves (no kick now: it joins the next step's)."""
    n_woken = 0
    for m in range(n_man):
        if not mi[m, MI_ACTIVE]:
            continue
        a = mi[m, MI_REC_A]
        b = mi[m, MI_REC_B]
        sleeper = -1
        sign = 0.0
        if mi[m, MI_A] == n_dyn and a >= 0:
            sleeper, sign = a, 1.0
        elif b >= 0 and mi[m, MI_B] == n_dyn:
            sleeper, sign = b, -1.0
        if sleeper < 0:
            continue
        pushed = False
        nx, ny, nz = mf[m, MF_N], mf[m, MF_N + 1], mf[m, MF_N + 2]
        start = mi[m, MI_START]
        for p in range(start, start + mi[m, MI_COUNT]):
            ln = pf[p, PF_LN]
            if ln <= 0.0:
                continue
            pushed = True
            jx = sign * (ln * nx + pf[p, PF_F])
            jy = sign * (ln * ny + pf[p, PF_F + 1])
            jz = sign * (ln * nz + pf[p, PF_F + 2])
            rx = pf[p, PF_P] - position[sleeper, 0]
            ry = pf[p, PF_P + 1] - position[sleeper, 1]
            rz = pf[p, PF_P + 2] - position[sleeper, 2]
            linear_momentum[sleeper, 0] += jx
            linear_momentum[sleeper, 1] += jy
            linear_momentum[sleeper, 2] += jz
            angular_momentum[sleeper, 0] += ry * jz - rz * jy
            angular_momentum[sleeper, 1] += rz * jx - rx * jz
            angular_momentum[sleeper, 2] += rx * jy - ry * jx
        if pushed and not awake[sleeper]:
            n_woken += 1
            wake_island(island_of[sleeper], n_dyn, awake, sleep_timer, island_of,
                        linear_momentum, angular_momentum, force, torque, h, False)
    return n_woken
