// Project stage: a nonlinear (NGS) position pass on fresh contact geometry after the drift.
//
// The velocity solve works on the manifolds of the start of the step and their first-order gap
// rates. A box that tumbles or is struck hard within the step can bring a feature into contact
// that none of those manifolds holds: a corner swinging over the edge of the box below, an
// incident edge sliding past the rim of a reference face (the deepest point then lies on a clip
// point that did not exist at the start), or a pair whose clipped face was empty at the start.
// Such a feature is unconstrained for the step and ends it up to ~|v| h deep (1 mm at 1 m/s and
// dt = 1 ms in the 500-box pile).
//
// This stage runs the narrowphase again at the end-of-step configuration, first with a *negative*
// speculative distance ``-depth``, so only points deeper than ``depth`` come back (the separating
// axis test rejects every other pair on its first axis, which keeps the pass cheap; a GJK pair or
// capsule - box, whose colliders have no such axis, is passed over when it is parted by more
// than -depth along the normal this step's collide stage found, or the line of centres: the
// collider would return nothing, narrowphase.cpp parted_along). Around the
// bodies of those points it gathers every contact of the bodies and of their neighbours (two
// rings, see project_positions), and pushes all gathered points to ``s >= -depth`` by
// Gauss-Seidel on position-level impulses (Box2D v2's ``SolvePositionConstraints``, Catto's
// "nonlinear Gauss-Seidel", on fresh geometry). The neighbours hold: a body pushed out of one
// overlap is not pushed into the body under it. Per point k, per sweep::
//
//     lambda_k += max(-(s_k + n . (dx_a + dth_a x r_a - dx_b - dth_b x r_b) + depth) / K_k, -lambda_k)
//     dx_a += m_a^-1 lambda n,  dth_a += I_a^-1 (r_a x lambda n)   (b gets the negatives)
//
// with K_k the point's effective inverse mass (as in the velocity solve), clamped accumulated
// ``lambda >= 0`` (pushes only). There is no cap on the push per step (unlike the split
// impulses' ``max_correction_speed``): an overlap that a step made is undone in that step, up to
// the ~2 mm that a box struck at 2 m/s can make in 1 ms; a scene that starts with overlaps has
// them pushed out to ``depth`` in its first step, without any velocity.
//
// Only positions and orientations move; the momenta P and L are untouched (but for the hand-back
// below), so the pass injects no momentum, and no kinetic energy into isotropic bodies (for
// others the turned inertia changes the spin energy by O(|dth|) of it, as the split-impulse
// pseudo spin does); the next step's contacts, at the corrected depth, stop the approach. The
// pair's impulses are equal and opposite at one point, so its centre of mass stays put; the
// world step hands the orbital change ``dx x P`` back to the spin, as after the split-impulse
// shift, so that ``sum(x x P + L)`` stays exact.
//
// Shapes and frames: ``pairs`` (K, 2) shape ids (bodies, static boxes, ground; see broadphase),
// ``position`` (N, 3) and ``rotation`` (N, 3, 3) body -> world at the end of the step;
// corrections ``dx`` and ``dth`` are (N+1, 3) world displacements and rotation vectors (row N:
// the static dummy, which stands for static geometry and sleeping bodies and never moves).

#include <algorithm>
#include <vector>

#include "common/task_pool.hpp"

#include "engine/integrators.hpp"
#include "engine/project.hpp"
#include "engine/rotation.hpp"

namespace rb {

TaskPool& pool();  // the engine's pool (threads.cpp)

namespace {

// The first pass's per-call work, kept by the calling thread: each pair's outcome (PAIR_*) and
// deepest overlap, and collider scratch per pool thread.
enum : char { PAIR_STILL = 0, PAIR_APART = 1, PAIR_DEEP = 2 };
struct ProjectWork {
    std::vector<char> what;
    std::vector<double> deep;
    std::vector<ColliderBuffers> scratch;
};

ProjectWork& project_work() {
    static thread_local ProjectWork w;
    return w;
}

// pairs per block of the first pass and the fewest worth a hand-off (~190 instructions a pair
// in the 500-box pile: most are rejected on their first axis)
constexpr i64 PAIRS_PER_BLOCK = 128;
constexpr i64 MIN_PAIRS = 1024;

// World inverse inertia of body i times (x, y, z): R diag(1/I) R^T v.
inline Vec3 inv_inertia_times(bool iso_shortcut, V1<i64> iso, V2<double> inv_inertia,
                              V3<double> rotation, i64 i, double x, double y, double z) {
    if (iso_shortcut && iso[i]) {
        double s = inv_inertia(i, 0);
        return Vec3{s * x, s * y, s * z};
    }
    return omega_world(load_mat(rotation, i), inv_inertia(i, 0), inv_inertia(i, 1),
                       inv_inertia(i, 2), x, y, z);
}

// Append the collider's points (both manifolds of res) to pts: solver rows ia / ib (the static
// dummy n_body for a static or sleeping side), anchors from the end-of-step positions of bodies
// a and b, the effective mass along the normal.
void add_points(i64 res, i64 a, i64 b, i64 ia, i64 ib, i64 n_body, const Bodies& bd,
                bool iso_shortcut, const BodyState& x, const ColliderBuffers& buf,
                std::vector<ProjectPoint>& pts) {
    V2<double> position = x.position;
    bool b_dyn = b < n_body;
    for (i64 part = 0; part < 2; ++part) {
        ManifoldPart mp = manifold_part(res, part);
        double nx = buf.nrm[3 * part], ny = buf.nrm[3 * part + 1], nz = buf.nrm[3 * part + 2];
        for (i64 q = 0; q < mp.count; ++q) {
            ProjectPoint& pt = pts.emplace_back();
            pt.a = ia;
            pt.b = ib;
            double px = buf.pts[mp.row + q][0], py = buf.pts[mp.row + q][1],
                   pz = buf.pts[mp.row + q][2];
            set3(pt.normal, nx, ny, nz);
            double rax = px - position(a, 0), ray = py - position(a, 1), raz = pz - position(a, 2);
            double rbx, rby, rbz;
            if (b_dyn) {
                rbx = px - position(b, 0); rby = py - position(b, 1); rbz = pz - position(b, 2);
            } else {
                rbx = 0.0; rby = 0.0; rbz = 0.0;
            }
            set3(pt.ra, rax, ray, raz);
            set3(pt.rb, rbx, rby, rbz);
            pt.s = buf.sep[mp.row + q];
            pt.lambda = 0.0;
            // body i's part of J M^-1 J^T along n at anchor r: 1/m + (r x n) . I^-1 (r x n)
            auto k_part = [&](i64 i, double rx, double ry, double rz) {
                double cx = ry * nz - rz * ny;
                double cy = rz * nx - rx * nz;
                double cz = rx * ny - ry * nx;
                Vec3 v = inv_inertia_times(iso_shortcut, bd.iso, bd.inv_inertia, x.rotation, i,
                                           cx, cy, cz);
                return bd.inv_mass[i] + cx * v[0] + cy * v[1] + cz * v[2];
            };
            double kk = 0.0;
            if (ia < n_body) kk += k_part(ia, rax, ray, raz);
            if (ib < n_body) kk += k_part(ib, rbx, rby, rbz);
            pt.normal_mass = kk > 0.0 ? 1.0 / kk : 0.0;
        }
    }
}

}  // namespace

// Find the bodies with points deeper than depth, gather the contacts around them, and
// Gauss-Seidel every gathered point to s >= -depth.
//
// Gathering: a first pass over the candidate pairs with speculative distance -depth marks the
// bodies of deep points (ring 1; nothing else is collided in full). Then, for PROJECTION_RINGS
// (cfg.projection_rings) rings, every pair with a body of the current ring is collided with speculative
// distance equal to the deepest penetration found (no correction can move a point farther than
// that) and all its points are gathered; its partner joins the next ring. So a body pushed out
// of one overlap is held by its other contacts instead of being pushed into them.
//
// The points go to sc.proj_points; sc.proj_dx / sc.proj_dth (N+1, 3) receive each body's
// correction (zeroed here for the bodies of the gathered points; read them only for those).
// sc.ring (N+1,) and sc.done (pairs) are work arrays. Returns the number of gathered points, 0
// when nothing is deeper than the depth.
i64 project_positions(const Settings& cfg, const Bodies& bd, const Statics& st, V1<i64> awake,
                      const BodyState& x, V2<i64> pairs, i64 n_pairs, V1<Manifold> mf,
                      V1<i64> keys, V1<i64> idx, i64 n_man, Scratch& sc) {
    const Geoms gm = bd.geoms();
    const i64 n_dyn = gm.code.n0, n_static = st.n_static;
    const i64 n_shapes = n_dyn + n_static + 1;  // manifold keys: 2 (a n_shapes + b) + part
    const bool iso_shortcut = cfg.iso_shortcut;
    const double depth = cfg.projection_depth;
    V2<double> position = x.position;
    V3<double> rotation = x.rotation;
    V2<double> dx = sc.proj_dx.view(), dth = sc.proj_dth.view();
    V1<double> inv_mass = bd.inv_mass;
    ColliderBuffers& buf = sc.cb;
    std::vector<ProjectPoint>& pts = sc.proj_points;
    std::vector<char>& done = sc.done;
    // shape ids: n_dyn geoms, then the statics; rings, points and corrections are per body
    const i64 n_body = position.n0;
    double deepest = 0.0;
    sc.ring.grow(n_body + 1);
    i64* ring = sc.ring.data.data();  // ring of each body (0: not gathered)
    for (i64 i = 0; i < n_body + 1; ++i) ring[i] = 0;
    done.assign(static_cast<size_t>(std::max<i64>(n_pairs, 1)), 0);  // pair already gathered
    // the first pass, pairs independent: blocks of pairs on the task pool, each pair's outcome
    // and deepest overlap into its slots, then the marks and the deepest in pair order
    ProjectWork& w = project_work();
    if ((i64)w.deep.size() < n_pairs) {
        w.deep.resize((size_t)n_pairs);
        w.what.resize((size_t)n_pairs);
    }
    const int nt = pool().threads();
    if ((int)w.scratch.size() < nt) w.scratch.resize((size_t)nt);
    const i64 n_blocks = nt > 1 ? TaskPool::blocks_for(n_pairs, PAIRS_PER_BLOCK, MIN_PAIRS) : 1;
    pool().run(n_blocks, [&](i64 blk, int worker) {
        ColliderBuffers& cb = worker == 0 ? buf : w.scratch[(size_t)worker];
        for (i64 k = n_pairs * blk / n_blocks; k < n_pairs * (blk + 1) / n_blocks; ++k) {
            i64 a = pairs(k, 0), b = pairs(k, 1);
            bool b_dyn = b < n_dyn;
            bool a_awake = awake[gm.body[a]] != 0;
            bool b_awake = b_dyn && awake[gm.body[b]] != 0;
            w.what[(size_t)k] = PAIR_STILL;
            if (!a_awake && !b_awake) continue;
            w.what[(size_t)k] = PAIR_APART;
            i64 ga = gm.code[a];
            double pc[2][3], pr[2][9];
            GeomPose pa = geom_pose(gm, a, position, rotation, pc[0], pr[0]);
            PairGeometry pg = pair_geometry(a, b, n_dyn, n_static, gm, pa, position,
                                            rotation, st.pos, st.rot, st.ext, pc[1], pr[1]);
            // parted along the normal this step's collide stage found (or, with none, the line
            // of centres): collide() below would return no point (parted_along, with its
            // proof), so the pair stays apart
            if (axis_parts(ga, pg.geom)) {
                const i64 j = find_manifold(keys, idx, n_man, 2 * (a * n_shapes + b));
                double u[3] = {pa.centre[0] - pg.centre[0], pa.centre[1] - pg.centre[1],
                               pa.centre[2] - pg.centre[2]};
                const double* axis = j >= 0 ? mf[j].normal : u;
                if ((j >= 0 || u[0] != 0.0 || u[1] != 0.0 || u[2] != 0.0) &&
                    parted_along(ga, pg.geom, pa.centre, M3(pa.rotation), gm.size.row(a),
                                 pg.centre, M3(pg.rotation), pg.size, axis, -depth))
                    continue;
            }
            i64 res = collide(ga, pg.geom, pa.centre, M3(pa.rotation), gm.size.row(a),
                              pg.centre, M3(pg.rotation), pg.size, st.gn.p, st.goff, -depth, cb);
            if (res <= 0) continue;
            double d = 0.0;
            for (i64 part = 0; part < 2; ++part) {
                ManifoldPart mp = manifold_part(res, part);
                for (i64 q = 0; q < mp.count; ++q) d = std::max(d, -cb.sep[mp.row + q]);
            }
            w.what[(size_t)k] = PAIR_DEEP;
            w.deep[(size_t)k] = d;
        }
    });
    for (i64 k = 0; k < n_pairs; ++k) {
        if (w.what[(size_t)k] == PAIR_STILL) {
            done[k] = 1;
            continue;
        }
        if (w.what[(size_t)k] == PAIR_APART) continue;
        deepest = std::max(deepest, w.deep[(size_t)k]);
        i64 a = gm.body[pairs(k, 0)], b = pairs(k, 1);
        bool b_dyn = b < n_dyn;
        if (b_dyn) b = gm.body[b];
        if (awake[a] != 0) ring[a] = 1;
        if (b_dyn && awake[b] != 0) ring[b] = 1;
    }
    if (deepest <= 0.0) return 0;
    pts.clear();
    for (i64 r = 1; r < cfg.projection_rings + 1; ++r) {
        for (i64 k = 0; k < n_pairs; ++k) {
            if (done[k]) continue;
            const i64 sa = pairs(k, 0), sb = pairs(k, 1);  // shape ids
            bool b_dyn = sb < n_dyn;
            i64 a = gm.body[sa], b = b_dyn ? gm.body[sb] : n_body;  // bodies
            if (ring[a] != r && !(b_dyn && ring[b] == r)) continue;
            done[k] = 1;
            bool a_awake = awake[a] != 0;
            bool b_awake = b_dyn && awake[b] != 0;
            i64 ga = gm.code[sa];
            double pc[2][3], pr[2][9];
            GeomPose pa = geom_pose(gm, sa, position, rotation, pc[0], pr[0]);
            PairGeometry pg = pair_geometry(sa, sb, n_dyn, n_static, gm, pa, position,
                                            rotation, st.pos, st.rot, st.ext, pc[1], pr[1]);
            i64 res = collide(ga, pg.geom, pa.centre, M3(pa.rotation), gm.size.row(sa),
                              pg.centre, M3(pg.rotation), pg.size, st.gn.p, st.goff, deepest, buf);
            if (res <= 0) continue;
            i64 ia = a_awake ? a : n_body;
            i64 ib = b_awake ? b : n_body;
            add_points(res, a, b, ia, ib, n_body, bd, iso_shortcut, x, buf, pts);
            if (a_awake && ring[a] == 0) ring[a] = r + 1;
            if (b_awake && ring[b] == 0) ring[b] = r + 1;
        }
    }
    const i64 n_pts = (i64)pts.size();
    if (n_pts == 0) return 0;
    for (const ProjectPoint& pt : pts) {
        for (i64 i : {pt.a, pt.b}) {
            for (int k = 0; k < 3; ++k) {
                dx(i, k) = 0.0;
                dth(i, k) = 0.0;
            }
        }
    }
    for (i64 it = 0; it < cfg.projection_iterations; ++it) {
        for (ProjectPoint& pt : pts) {
            const i64 ia = pt.a, ib = pt.b;
            const double nx = pt.normal[0], ny = pt.normal[1], nz = pt.normal[2];
            const double rax = pt.ra[0], ray = pt.ra[1], raz = pt.ra[2];
            const double rbx = pt.rb[0], rby = pt.rb[1], rbz = pt.rb[2];
            // separation now, to first order in this pass's corrections
            double ux = dx(ia, 0) + dth(ia, 1) * raz - dth(ia, 2) * ray - dx(ib, 0) - dth(ib, 1) * rbz + dth(ib, 2) * rby;
            double uy = dx(ia, 1) + dth(ia, 2) * rax - dth(ia, 0) * raz - dx(ib, 1) - dth(ib, 2) * rbx + dth(ib, 0) * rbz;
            double uz = dx(ia, 2) + dth(ia, 0) * ray - dth(ia, 1) * rax - dx(ib, 2) - dth(ib, 0) * rby + dth(ib, 1) * rbx;
            double s = pt.s + ux * nx + uy * ny + uz * nz;
            double old = pt.lambda;
            double nw = old - (s + depth) * pt.normal_mass;
            if (nw < 0.0) nw = 0.0;
            pt.lambda = nw;
            double d = nw - old;
            if (d == 0.0) continue;
            double px = d * nx, py = d * ny, pz = d * nz;
            if (ia < n_body) {
                double ma = inv_mass[ia];
                dx(ia, 0) += ma * px;
                dx(ia, 1) += ma * py;
                dx(ia, 2) += ma * pz;
                Vec3 e = inv_inertia_times(iso_shortcut, bd.iso, bd.inv_inertia, rotation, ia,
                                           ray * pz - raz * py, raz * px - rax * pz,
                                           rax * py - ray * px);
                dth(ia, 0) += e[0];
                dth(ia, 1) += e[1];
                dth(ia, 2) += e[2];
            }
            if (ib < n_body) {
                double mb = inv_mass[ib];
                dx(ib, 0) -= mb * px;
                dx(ib, 1) -= mb * py;
                dx(ib, 2) -= mb * pz;
                Vec3 e = inv_inertia_times(iso_shortcut, bd.iso, bd.inv_inertia, rotation, ib,
                                           rby * pz - rbz * py, rbz * px - rbx * pz,
                                           rbx * py - rby * px);
                dth(ib, 0) -= e[0];
                dth(ib, 1) -= e[1];
                dth(ib, 2) -= e[2];
            }
        }
    }
    return n_pts;
}

// Move the bodies of the project stage's points by their corrections: x += dx, the orientation
// by the rotation vector dth (through the run's integrator: a drift of unit duration with
// L = I_world dth), and L -= dx x P so that sum(x x P + L) stays exact. A moved body's exact-flow
// anchor is dropped (anchor_steps -1, see rblog.engine.state.FlowAnchors).
void apply_projection(V1<ProjectPoint> points, V2<double> dx, V2<double> dth, int method,
                      int ortho, const Bodies& bd, bool iso_shortcut, const BodyState& x,
                      V2<double> l_scratch, V1<i64> anchor_steps) {
    const i64 n = x.position.n0;
    V2<double> position = x.position, quat_wxyz = x.quat_wxyz;
    V2<double> linear_momentum = x.linear_momentum, angular_momentum = x.angular_momentum;
    V3<double> rotation = x.rotation;
    for (i64 p = 0; p < points.n0; ++p) {
        for (i64 i : {points[p].a, points[p].b}) {
            if (i >= n) continue;
            double ux = dx(i, 0), uy = dx(i, 1), uz = dx(i, 2);
            double tx = dth(i, 0), ty = dth(i, 1), tz = dth(i, 2);
            if (ux == 0.0 && uy == 0.0 && uz == 0.0 && tx == 0.0 && ty == 0.0 && tz == 0.0)
                continue;  // no correction, or already applied (a body can have many points)
            position(i, 0) += ux;
            position(i, 1) += uy;
            position(i, 2) += uz;
            anchor_steps[i] = -1;
            double qx = linear_momentum(i, 0), qy = linear_momentum(i, 1), qz = linear_momentum(i, 2);
            angular_momentum(i, 0) -= uy * qz - uz * qy;
            angular_momentum(i, 1) -= uz * qx - ux * qz;
            angular_momentum(i, 2) -= ux * qy - uy * qx;
            if (tx != 0.0 || ty != 0.0 || tz != 0.0) {
                double jx, jy, jz;
                if (iso_shortcut && bd.iso[i]) {
                    double s0 = bd.inertia(i, 0);
                    jx = s0 * tx; jy = s0 * ty; jz = s0 * tz;
                } else {
                    Vec3 j = omega_world(load_mat(rotation, i), bd.inertia(i, 0),
                                         bd.inertia(i, 1), bd.inertia(i, 2), tx, ty, tz);
                    jx = j[0]; jy = j[1]; jz = j[2];
                }
                l_scratch(i, 0) = jx;
                l_scratch(i, 1) = jy;
                l_scratch(i, 2) = jz;
                drift_rotation(method, ortho, quat_wxyz, rotation, l_scratch, bd.inv_inertia, i,
                               1.0);
            }
            for (int k = 0; k < 3; ++k) {
                dx(i, k) = 0.0;
                dth(i, k) = 0.0;
            }
        }
    }
}

}  // namespace rb
