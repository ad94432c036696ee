"""Collide stage: narrowphase over the candidate pairs into packed manifolds, with warm starting.

For each candidate pair (lower shape id a, higher id b):

* neither side awake (sleeping or static): the previous step's manifold is carried over
  unchanged (inactive: not solved, still logged);
* otherwise the collider from the narrowphase table runs with a speculative distance of
  ``margin + reach_a + reach_b``; each new point takes over the impulses of the previous step's
  point with the same feature id (or, failing that, the nearest one within
  ``anchor_distance``), normal impulse as is and friction projected on the new tangents;
* the manifold keeps its friction anchor, the pose of a in b's frame when the pair started
  sticking (solver.py, "Friction anchor"), whatever its points do (a one-point contact that
  becomes a face keeps it), and every point gets its drift from it: where a's material point at
  the contact is now, minus where the anchor pose puts it (a sphere's pair, which rolls, has
  none).

Materials combine as restitution max(e_a, e_b) and friction sqrt(mu_a mu_b) (the analyzers use
the same rule).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rblog.contract.trajectory import STATIC_BODY
from rblog.engine.constants import FRICTION_ANCHOR_MAX_DRIFT_M
from rblog.engine.contact.manifold import (
    MF_ACC, MF_AOK, MF_AR, MF_AT, MF_E, MF_MU, MF_N, MF_T1, MF_T2, MI_A, MI_ACTIVE, MI_B, MI_COLS, MI_COUNT, MI_KEY,
    MI_REC_A, MI_REC_B, MI_START, MF_COLS, PF_COLS, PF_D, PF_F, PF_L1, PF_L2, PF_LN, PF_LP, PF_LWS,
    PF_P, PF_RA, PF_RB, PF_S, PF_SEND, PF_IMPACT, PF_W0, PF_WT,
)
from rblog.engine.contact.narrowphase import (
    COLLIDE_TABLE, GEOM_BOX, GEOM_PLANE, GEOM_SPHERE, collide, manifold_part,
)


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
