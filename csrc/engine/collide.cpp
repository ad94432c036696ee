// Collide stage: narrowphase over the candidate pairs into manifold records, with warm starting
// (rblog/engine/contact/collide.py, the same formulas in the same order).
//
// For each candidate pair (lower shape id a, higher id b; shape ids are geoms, then the statics,
// collision.hpp Geoms; the manifold's a and b are the geoms' bodies):
//
// * neither side awake (sleeping or static): the previous step's manifolds of the pair are
//   carried over unchanged (inactive: not solved, still logged);
// * otherwise the collider from the narrowphase table runs with a speculative distance of
//   margin + reach_a + reach_b (a GJK or capsule - box pair with no manifold last step is first
//   tried along its line of centres: parted by more than that, the collider would return no
//   point, narrowphase.cpp parted_along); each new point takes over the impulses of the previous step's
//   point with the same feature id (or, failing that, the nearest one within anchor_distance),
//   normal impulse as is (the velocity solve's, lws) and friction projected on the new
//   tangents;
// * the manifold keeps its friction anchor, the pose of a in b's frame when the pair started
//   sticking (contact_solver.cpp, "Friction anchor": A_R = R_b^T R_a, A_t = R_b^T (x_a - x_b), b's frame
//   the world for the ground), whatever its points do (a one-point contact that becomes a face
//   keeps it), and every point gets its drift from it: with y = R_a^T (p - x_a) a's material
//   point at the contact, the anchor pose puts it at x_b + R_b (A_R y + A_t), and
//   D = p - that (world). When the largest tangential drift |D - (D.n) n| exceeds
//   FRICTION_ANCHOR_MAX_DRIFT_M (the pair was struck) the anchor is set anew where the pair is and
//   D = 0. A sphere's pair, which rolls, has no anchor (a rolling sphere brings a new material
//   point to the contact every step; its friction rows target zero slip).
//
// Manifold keys are 2 (a n_shapes + b) + part (part 1: a box pair's second manifold), a and b
// shape ids, so a compound body's every pair of parts keeps its own manifold and warm start; the
// previous step's manifolds are found by binary search in their sorted keys (sort_manifolds).
// Materials combine as restitution max(e_a, e_b) and friction sqrt(mu_a mu_b) (the analyzers use
// the same rule).
#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include "common/task_pool.hpp"
#include "engine/collision.hpp"

namespace rb {

TaskPool& pool();  // the engine's pool (threads.cpp)

std::array<double, 6> tangent_basis(double nx, double ny, double nz) {
    double ax = std::fabs(nx), ay = std::fabs(ny), az = std::fabs(nz);
    double tx, ty, tz;
    // cross n with the world axis least aligned with it
    if (ax <= ay && ax <= az) {
        tx = 0.0;  // n x e_x
        ty = nz;
        tz = -ny;
    } else if (ay <= az) {
        tx = -nz;  // n x e_y
        ty = 0.0;
        tz = nx;
    } else {
        tx = ny;  // n x e_z
        ty = -nx;
        tz = 0.0;
    }
    double ln = 1.0 / std::sqrt(tx * tx + ty * ty + tz * tz);
    tx = tx * ln;
    ty = ty * ln;
    tz = tz * ln;
    return {tx, ty, tz, ny * tz - nz * ty, nz * tx - nx * tz, nx * ty - ny * tx};
}

i64 find_manifold(V1<i64> sorted_keys, V1<i64> sorted_idx, i64 n, i64 key) {
    i64 lo = 0;
    i64 hi = n;
    while (lo < hi) {
        i64 mid = (lo + hi) >> 1;
        if (sorted_keys[mid] < key)
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo < n && sorted_keys[lo] == key) return sorted_idx[lo];
    return -1;
}

void sort_manifolds(V1<ManifoldHead> mi, i64 n_man, V1<i64> sorted_keys, V1<i64> sorted_idx) {
    // (key, index) pairs in lexicographic order: the order of a stable sort by key
    struct KeyIdx {
        i64 key, idx;
    };
    static thread_local std::vector<KeyIdx> kept;
    std::vector<KeyIdx>& order = kept;
    order.resize((size_t)n_man);
    for (i64 m = 0; m < n_man; ++m) order[(size_t)m] = KeyIdx{mi[m].key, m};
    std::sort(order.begin(), order.end(), [](const KeyIdx& a, const KeyIdx& b) {
        return a.key < b.key || (a.key == b.key && a.idx < b.idx);
    });
    for (i64 k = 0; k < n_man; ++k) {
        sorted_idx[k] = order[(size_t)k].idx;
        sorted_keys[k] = order[(size_t)k].key;
    }
}

void grow_manifolds(Buf2<i64>& mi, Buf2<double>& mf, i64 cap) {
    if (mi.rows >= cap) return;
    mi.grow(cap);  // max(cap, 2 rows), as collide.py
    mf.grow(mi.rows);
}

void grow_points(Buf2<double>& pf, Buf2<i64>& pid, i64 cap) {
    if (pf.rows >= cap) return;
    pf.grow(cap);
    pid.grow(pf.rows);
}

namespace {

// What the collider returned for one pair (the output half of ColliderBuffers: a first manifold
// in rows 0..3, a box pair's second in rows 4..7), kept per pair between the two passes of
// collide_pairs; res as collide() returns it (0: no points; -2: both sides still, carried over).
struct PairOut {
    double nrm[6];
    double pts[2 * MAX_MANIFOLD_POINTS][3];
    double sep[2 * MAX_MANIFOLD_POINTS];
    i64 fid[2 * MAX_MANIFOLD_POINTS];
    i64 res;
    i64 n_man, n_pts;  // manifolds and points the pair adds
};

// The per-call work of collide_pairs, kept by the calling thread (worlds may step on several
// Python threads at once) so that a step allocates nothing once it has grown to the scene.
struct CollideWork {
    std::vector<PairOut> out;
    std::vector<i64> man_off, pts_off;    // (n_pairs + 1,) where each pair's rows start
    std::vector<ColliderBuffers> scratch;  // one per pool thread
};

CollideWork& collide_work() {
    static thread_local CollideWork w;
    return w;
}

// Pairs per block of the two passes, and the fewest pairs worth a hand-off to the pool (the
// 500-box pile's pairs cost ~1,400 instructions each in the two passes, most of them ground or
// rejected pairs; the 100-box pile's ~250 pairs stay on one thread)
constexpr i64 PAIRS_PER_BLOCK = 64;
constexpr i64 MIN_PAIRS = 512;

}  // namespace

// Append one manifold (points rows row.. of the collider's output) with warm starting. `rolls`:
// a sphere's pair, which gets no friction anchor.
[[gnu::always_inline]] static inline void add_manifold(i64 key, i64 a, i64 b, i64 n_dyn, i64 n_static, bool a_awake,
                         bool b_awake, bool b_dyn, i64 b_shape, i64 n_geom, i64 cnt, i64 row, i64 part, bool rolls,
                         V2<double> position, V3<double> rotation, V2<double> sb_pos,
                         V3<double> sb_rot, V1<double> restitution, V1<double> friction,
                         V2<double> accel, V1<double> sb_e, V1<double> sb_mu, double g_e,
                         double g_mu, V1<ManifoldHead> prev_mi, V1<Manifold> prev_mf,
                         V1<ContactPoint> prev_pf, V1<i64> prev_pid, V1<i64> prev_keys,
                         V1<i64> prev_idx, i64 prev_n, V1<ManifoldHead> mi, V1<Manifold> mf,
                         V1<ContactPoint> pf, V1<i64> pid, i64& n_man, i64& n_pts, bool warm,
                         double ad2, const PairOut& buf) {
    static const double IDENTITY[9] = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
    static const double ZERO3[3] = {0.0, 0.0, 0.0};
    const CollisionConstants& cc = collision_constants();
    const double* nrm = buf.nrm;
    const i64 m = n_man;
    n_man += 1;
    ManifoldHead& mim = mi[m];
    Manifold& mfm = mf[m];
    mim.key = key;
    mim.a = a_awake ? a : n_dyn;
    mim.b = b_awake ? b : n_dyn;
    mim.rec_a = a;
    mim.rec_b = b_dyn ? b : cc.static_body;
    mim.start = n_pts;
    mim.count = cnt;
    mim.active = 1;
    const double nx = nrm[3 * part], ny = nrm[3 * part + 1], nz = nrm[3 * part + 2];
    const std::array<double, 6> tb = tangent_basis(nx, ny, nz);
    const double t1x = tb[0], t1y = tb[1], t1z = tb[2], t2x = tb[3], t2y = tb[4], t2z = tb[5];
    set3(mfm.normal, nx, ny, nz);
    set3(mfm.t1, t1x, t1y, t1z);
    set3(mfm.t2, t2x, t2y, t2z);
    // materials and the gap acceleration n . (a_a - a_b) from external forces
    double ax = 0.0, ay = 0.0, az = 0.0;
    if (a_awake) {
        ax = accel(a, 0);
        ay = accel(a, 1);
        az = accel(a, 2);
    }
    double mu, e;
    if (b_dyn) {
        mu = std::sqrt(friction[a] * friction[b]);
        e = std::max(restitution[a], restitution[b]);
        if (b_awake) {
            ax -= accel(b, 0);
            ay -= accel(b, 1);
            az -= accel(b, 2);
        }
    } else if (b_shape < n_geom + n_static) {
        mu = std::sqrt(friction[a] * sb_mu[b_shape - n_geom]);
        e = std::max(restitution[a], sb_e[b_shape - n_geom]);
    } else {
        mu = std::sqrt(friction[a] * g_mu);
        e = std::max(restitution[a], g_e);
    }
    mfm.mu = mu;
    mfm.e = e;
    mfm.acc = nx * ax + ny * ay + nz * az;
    // warm starting from the previous step's manifold of this pair
    i64 j = -1;
    if (warm) j = find_manifold(prev_keys, prev_idx, prev_n, key);
    const double* pa = position.row(a);
    // the friction anchor: b's frame (the world for the ground), a's pose in it now, and the
    // pose it had when the pair started sticking (carried over while store_impulses keeps it)
    const double* xb;
    M3 rb_ = IDENTITY;
    if (b_dyn) {
        xb = position.row(b);
        rb_ = rotation.row(b);
    } else if (b_shape < n_geom + n_static) {
        xb = sb_pos.row(b_shape - n_geom);
        rb_ = sb_rot.row(b_shape - n_geom);
    } else {
        xb = ZERO3;
    }
    const M3 ra = rotation.row(a);
    const bool anchored = j >= 0 && prev_mf[j].anchor_ok > 0.0 && !rolls;
    if (anchored) {
        const Manifold& pm = prev_mf[j];
        for (int c = 0; c < 9; ++c) mfm.anchor_rot[c] = pm.anchor_rot[c];
        for (int r = 0; r < 3; ++r) mfm.anchor_pos[r] = pm.anchor_pos[r];
    } else {
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c)  // R_b^T R_a
                mfm.anchor_rot[3 * r + c] =
                    rb_(0, r) * ra(0, c) + rb_(1, r) * ra(1, c) + rb_(2, r) * ra(2, c);
            mfm.anchor_pos[r] = rb_(0, r) * (pa[0] - xb[0]) + rb_(1, r) * (pa[1] - xb[1]) +
                             rb_(2, r) * (pa[2] - xb[2]);
        }
    }
    mfm.anchor_ok = rolls ? 0.0 : 1.0;
    // what the points' loop reads, in locals (its stores into pf could alias these arrays for all
    // the compiler knows, and it would load them again for every point): the same values
    const double pa0 = pa[0], pa1 = pa[1], pa2 = pa[2];
    const double xb0 = xb[0], xb1 = xb[1], xb2 = xb[2];
    double pb0 = 0.0, pb1 = 0.0, pb2 = 0.0;
    if (b_dyn) {
        const double* pb = position.row(b);
        pb0 = pb[0];
        pb1 = pb[1];
        pb2 = pb[2];
    }
    double RA[3][3], RB[3][3], AR[9], AT[3];
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            RA[r][c] = ra(r, c);
            RB[r][c] = rb_(r, c);
        }
        AT[r] = mfm.anchor_pos[r];
    }
    for (int c = 0; c < 9; ++c) AR[c] = mfm.anchor_rot[c];
    double drift_max = 0.0;
    for (i64 q = 0; q < cnt; ++q) {
        const i64 p = n_pts + q;
        ContactPoint& pfp = pf[p];
        const double px = buf.pts[row + q][0], py = buf.pts[row + q][1], pz = buf.pts[row + q][2];
        // p - x_a: the anchor r_a and a's material point's offset
        const double rax = px - pa0, ray = py - pa1, raz = pz - pa2;
        set3(pfp.point, px, py, pz);
        set3(pfp.ra, rax, ray, raz);
        if (b_dyn) {
            set3(pfp.rb, px - pb0, py - pb1, pz - pb2);
        } else {
            set3(pfp.rb, 0.0, 0.0, 0.0);
        }
        pfp.s = buf.sep[row + q];
        pfp.s_end = buf.sep[row + q];
        pid[p] = buf.fid[row + q];
        double ln = 0.0;
        double l1 = 0.0;
        double l2 = 0.0;
        if (j >= 0) {
            const i64 ps = prev_mi[j].start;
            const i64 pc = prev_mi[j].count;
            i64 match = -1;
            for (i64 r = ps; r < ps + pc; ++r) {
                if (prev_pid[r] == buf.fid[row + q]) {
                    match = r;
                    break;
                }
            }
            if (match < 0) {
                double best = ad2;
                for (i64 r = ps; r < ps + pc; ++r) {
                    double dx = prev_pf[r].point[0] - px;
                    double dy = prev_pf[r].point[1] - py;
                    double dz = prev_pf[r].point[2] - pz;
                    double d2 = dx * dx + dy * dy + dz * dz;
                    if (d2 <= best) {
                        best = d2;
                        match = r;
                    }
                }
            }
            if (match >= 0) {
                ln = prev_pf[match].lws;
                double fx = prev_pf[match].friction[0], fy = prev_pf[match].friction[1],
                       fz = prev_pf[match].friction[2];
                l1 = fx * t1x + fy * t1y + fz * t1z;
                l2 = fx * t2x + fy * t2y + fz * t2z;
            }
        }
        // drift of a's material point at the contact: y = R_a^T (p - x_a) in a's frame, put by
        // the anchor pose at x_b + R_b (A_R y + A_t); D = p minus that (world)
        double y0 = RA[0][0] * rax + RA[1][0] * ray + RA[2][0] * raz;
        double y1 = RA[0][1] * rax + RA[1][1] * ray + RA[2][1] * raz;
        double y2 = RA[0][2] * rax + RA[1][2] * ray + RA[2][2] * raz;
        double q0 = AR[0] * y0 + AR[1] * y1 + AR[2] * y2 + AT[0];
        double q1 = AR[3] * y0 + AR[4] * y1 + AR[5] * y2 + AT[1];
        double q2 = AR[6] * y0 + AR[7] * y1 + AR[8] * y2 + AT[2];
        double dx = px - (xb0 + RB[0][0] * q0 + RB[0][1] * q1 + RB[0][2] * q2);
        double dy = py - (xb1 + RB[1][0] * q0 + RB[1][1] * q1 + RB[1][2] * q2);
        double dz = pz - (xb2 + RB[2][0] * q0 + RB[2][1] * q1 + RB[2][2] * q2);
        if (rolls) {
            dx = 0.0;
            dy = 0.0;
            dz = 0.0;
        }
        set3(pfp.slip, dx, dy, dz);
        double dn = dx * nx + dy * ny + dz * nz;
        drift_max = std::max(drift_max, dx * dx + dy * dy + dz * dz - dn * dn);
        pfp.ln = ln;
        pfp.l1 = l1;
        pfp.l2 = l2;
        pfp.lws = ln;
        pfp.lp = 0.0;
        pfp.w0 = 0.0;
        pfp.wt = -1.0;
        pfp.impact = 0.0;
        set3(pfp.friction, 0.0, 0.0, 0.0);
    }
    const double dmax = cc.friction_anchor_max_drift_m;
    if (drift_max > dmax * dmax) {
        // drifted too far to be pulled back (the pair was struck): anchored anew where it is
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c)
                mfm.anchor_rot[3 * r + c] = rb_(0, r) * ra(0, c) + rb_(1, r) * ra(1, c) +
                                         rb_(2, r) * ra(2, c);
            mfm.anchor_pos[r] = rb_(0, r) * (pa[0] - xb[0]) + rb_(1, r) * (pa[1] - xb[1]) +
                             rb_(2, r) * (pa[2] - xb[2]);
        }
        for (i64 p = n_pts; p < n_pts + cnt; ++p) {
            set3(pf[p].slip, 0.0, 0.0, 0.0);
        }
    }
    n_pts += cnt;
}

// Two passes over the candidate pairs, each split in blocks over the task pool (pairs are
// independent): the first runs the colliders (or, for a pair whose sides both sleep, finds the
// manifolds to carry over) and keeps each pair's output and its manifold and point counts; a
// prefix sum gives each pair its rows; the second writes the manifolds there with warm
// starting. The rows are those of one pass in pair order, whichever thread ran which block.
CollideCount collide_pairs(V2<i64> pairs, i64 n_pairs, i64 n_dyn, i64 n_static, const Geoms& gm,
                           V1<i64> awake, V2<double> position,
                           V3<double> rotation, V1<double> reach, double margin,
                           V1<double> restitution, V1<double> friction, V2<double> accel,
                           V2<double> sb_pos, V3<double> sb_rot, V2<double> sb_ext,
                           V1<double> sb_e, V1<double> sb_mu, V1<double> gn, double goff,
                           double g_e, double g_mu, V1<ManifoldHead> prev_mi, V1<Manifold> prev_mf,
                           V1<ContactPoint> prev_pf, V1<i64> prev_pid, V1<i64> prev_keys,
                           V1<i64> prev_idx, i64 prev_n, V1<ManifoldHead> mi, V1<Manifold> mf,
                           V1<ContactPoint> pf, V1<i64> pid, bool warm, double anchor_distance,
                           ColliderBuffers& buf) {
    require_collision_constants();
    // shape ids: n_dyn geoms, then the statics; solver index n_body is the static dummy
    const i64 n_shapes = n_dyn + n_static + 1;
    const i64 n_body = position.n0;
    const double ad2 = anchor_distance * anchor_distance;
    CollideWork& w = collide_work();
    if ((i64)w.out.size() < n_pairs) w.out.resize((size_t)n_pairs);
    w.man_off.resize((size_t)n_pairs + 1);
    w.pts_off.resize((size_t)n_pairs + 1);
    const int nt = pool().threads();
    if ((int)w.scratch.size() < nt) w.scratch.resize((size_t)nt);
    const i64 n_blocks = TaskPool::blocks_for(n_pairs, PAIRS_PER_BLOCK, MIN_PAIRS);
    // pass 1: colliders
    pool().run(n_blocks, [&](i64 blk, int worker) {
        ColliderBuffers& cb = worker == 0 ? buf : w.scratch[(size_t)worker];
        const i64 k0 = n_pairs * blk / n_blocks, k1 = n_pairs * (blk + 1) / n_blocks;
        for (i64 k = k0; k < k1; ++k) {
            PairOut& o = w.out[(size_t)k];
            const i64 a = pairs(k, 0);
            const i64 b = pairs(k, 1);
            const i64 key = a * n_shapes + b;  // manifold keys are 2 key + part
            const bool b_dyn = b < n_dyn;
            const bool a_awake = awake[gm.body[a]] != 0;
            const bool b_awake = b_dyn && awake[gm.body[b]] != 0;
            o.n_man = 0;
            o.n_pts = 0;
            if (!a_awake && !b_awake) {
                // both sides still: the manifolds are carried over as they were (pass 2)
                o.res = -2;
                for (i64 part = 0; part < 2; ++part) {
                    i64 j = find_manifold(prev_keys, prev_idx, prev_n, 2 * key + part);
                    if (j < 0) continue;
                    o.n_man += 1;
                    o.n_pts += prev_mi[j].count;
                }
                continue;
            }
            const i64 ga = gm.code[a];
            double pc[2][3], pr[2][9];
            const GeomPose pa = geom_pose(gm, a, position, rotation, pc[0], pr[0]);
            const PairGeometry g = pair_geometry(a, b, n_dyn, n_static, gm, pa, position,
                                                 rotation, sb_pos, sb_rot, sb_ext, pc[1], pr[1]);
            double spec = margin + reach[a];
            if (b_dyn) spec += reach[b];
            // a pair new to the contact (no manifold last step) parted along the line of
            // centres: collide() would return no point (parted_along, with its proof)
            if (axis_parts(ga, g.geom) &&
                find_manifold(prev_keys, prev_idx, prev_n, 2 * key) < 0) {
                const double u[3] = {pa.centre[0] - g.centre[0], pa.centre[1] - g.centre[1],
                                     pa.centre[2] - g.centre[2]};
                if ((u[0] != 0.0 || u[1] != 0.0 || u[2] != 0.0) &&
                    parted_along(ga, g.geom, pa.centre, pa.rotation, gm.size.row(a), g.centre,
                                 g.rotation, g.size, u, spec)) {
                    o.res = 0;
                    continue;
                }
            }
            const i64 res = collide(ga, g.geom, pa.centre, pa.rotation, gm.size.row(a),
                                    g.centre, g.rotation, g.size, gn.p, goff, spec, cb);
            o.res = res;
            if (res <= 0) continue;
            for (int c = 0; c < 6; ++c) o.nrm[c] = cb.nrm[c];
            for (i64 part = 0; part < 2; ++part) {
                const ManifoldPart mp = manifold_part(res, part);
                if (mp.count == 0) continue;
                o.n_man += 1;
                o.n_pts += mp.count;
                for (i64 q = mp.row; q < mp.row + mp.count; ++q) {
                    for (int c = 0; c < 3; ++c) o.pts[q][c] = cb.pts[q][c];
                    o.sep[q] = cb.sep[q];
                    o.fid[q] = cb.fid[q];
                }
            }
        }
    });
    // each pair's first manifold and point row
    w.man_off[0] = 0;
    w.pts_off[0] = 0;
    for (i64 k = 0; k < n_pairs; ++k) {
        w.man_off[(size_t)k + 1] = w.man_off[(size_t)k] + w.out[(size_t)k].n_man;
        w.pts_off[(size_t)k + 1] = w.pts_off[(size_t)k] + w.out[(size_t)k].n_pts;
    }
    // pass 2: the manifolds, warm started, at their rows
    pool().run(n_blocks, [&](i64 blk, int) {
        const i64 k0 = n_pairs * blk / n_blocks, k1 = n_pairs * (blk + 1) / n_blocks;
        for (i64 k = k0; k < k1; ++k) {
            const PairOut& o = w.out[(size_t)k];
            if (o.n_man == 0) continue;
            i64 n_man = w.man_off[(size_t)k];
            i64 n_pts = w.pts_off[(size_t)k];
            const i64 a = pairs(k, 0);
            const i64 b = pairs(k, 1);
            const i64 key = a * n_shapes + b;
            const bool b_dyn = b < n_dyn;
            const i64 ba = gm.body[a], bb = b_dyn ? gm.body[b] : b;
            const bool a_awake = awake[ba] != 0;
            const bool b_awake = b_dyn && awake[bb] != 0;
            if (o.res == -2) {
                for (i64 part = 0; part < 2; ++part) {
                    i64 j = find_manifold(prev_keys, prev_idx, prev_n, 2 * key + part);
                    if (j < 0) continue;
                    const i64 cnt = prev_mi[j].count;
                    mi[n_man] = prev_mi[j];
                    mf[n_man] = prev_mf[j];
                    const i64 ps = prev_mi[j].start;
                    for (i64 q = 0; q < cnt; ++q) {
                        pf[n_pts + q] = prev_pf[ps + q];
                        pid[n_pts + q] = prev_pid[ps + q];
                    }
                    mi[n_man].start = n_pts;
                    mi[n_man].active = 0;
                    n_man += 1;
                    n_pts += cnt;
                }
                continue;
            }
            const i64 ga = gm.code[a];
            const i64 gb = b < n_dyn ? gm.code[b] : (b < n_dyn + n_static ? GEOM_BOX : GEOM_PLANE);
            const bool rolls = ga == GEOM_SPHERE || gb == GEOM_SPHERE || ga == GEOM_CAPSULE ||
                               gb == GEOM_CAPSULE || ga == GEOM_CYLINDER || gb == GEOM_CYLINDER;
            for (i64 part = 0; part < 2; ++part) {
                const ManifoldPart mp = manifold_part(o.res, part);
                if (mp.count == 0) continue;
                add_manifold(2 * key + part, ba, bb, n_body, n_static, a_awake, b_awake, b_dyn,
                             b, n_dyn, mp.count, mp.row, part, rolls, position, rotation, sb_pos, sb_rot,
                             restitution, friction, accel, sb_e, sb_mu, g_e, g_mu, prev_mi,
                             prev_mf, prev_pf, prev_pid, prev_keys, prev_idx, prev_n, mi, mf, pf,
                             pid, n_man, n_pts, warm, ad2, o);
            }
        }
    });
    return {w.man_off[(size_t)n_pairs], w.pts_off[(size_t)n_pairs]};
}

}  // namespace rb
