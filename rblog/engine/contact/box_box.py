"""Box-box contact: follows the separating-axis test of Gottschalk et al. (15 axes) with the face/edge
preference tolerances of Gregorius (GDC 2013, 2015): a face axis is kept unless an edge axis is
clearly better, so manifolds stay coherent from step to step. A face contact clips the incident
face against the side planes of the reference face (Sutherland-Hodgman) and reduces the clipped
polygon to four points (deepest point, farthest point, largest triangle, largest quad).

Tolerances (EDGE_REL_TOL, FACE_REL_TOL, AXIS_ABS_TOL, EDGE_PARALLEL_TOL) are in rblog.engine.constants.
"""

from __future__ import annotations

import math

from numba import njit

from rblog.engine.constants import AXIS_ABS_TOL, EDGE_PARALLEL_TOL, EDGE_REL_TOL, FACE_REL_TOL
from rblog.engine.contact.manifold import reduce_manifold


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


