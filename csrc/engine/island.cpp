// Sleeping: islands of touching bodies at rest stop being simulated until touched (Box2D's
// island.c / solver_set.c, with union-find islands rebuilt each step; rblog/engine/contact/
// island.py, the same formulas in the same order).
//
// A body is resting while its speed (the larger of |v| and |omega|max * bounding radius, with
// |omega| <= |L| max(1/I)) stays below sleep_speed; its timer counts how long. An island is a
// connected set of awake bodies linked by touching manifolds (a point with a positive impulse
// lws or a closed gap s_end <= 0). An island goes to sleep when every member has rested for
// sleep_time and it touches something (the ground, a static box, a sleeping body, or another
// body): its momenta are zeroed and the step skips it.
//
// An awake body wakes a sleeping island when its motion (before this step's force kick) can close
// the gap to a member within the step (wake_touched); the island's bodies then get this step's
// kick and rejoin the solve. A sleeping body that an awake one pushes on anyway (it stood in as a
// static body in this step's solve) wakes after the step (wake_pushed), and gets the impulses
// its neighbours received from it, equal and opposite at the same contact point: J on body a is
// lambda_n n + f, the sleeper gets -J if it is b (+J if a) into P and (p - x) x (-J) into L, so
// linear and angular momentum are conserved exactly, as between two awake bodies. Sleeping
// bodies keep their manifolds (carried over), so their resting contacts still appear in the
// contact log.
#include <algorithm>
#include <cmath>
#include <limits>

#include "engine/collision.hpp"

namespace rb {

i64 update_sleep(i64 n_dyn, V1<ManifoldHead> mi, V1<ContactPoint> pf, i64 n_man, V1<i64> awake,
                 V1<double> sleep_timer, V1<i64> island_of, V1<i64> island_counter,
                 V2<double> linear_momentum, V2<double> angular_momentum, V1<double> inv_mass,
                 V2<double> inv_inertia, V1<double> radius, double h, double sleep_speed,
                 double sleep_time, V1<i64> parent, V1<double> island_min_time,
                 V1<i64> island_supported) {
    for (i64 i = 0; i < n_dyn; ++i) {
        parent[i] = i;
        island_supported[i] = 0;
        island_min_time[i] = std::numeric_limits<double>::infinity();
        if (!awake[i]) continue;
        double im = inv_mass[i];
        double px = linear_momentum(i, 0), py = linear_momentum(i, 1), pz = linear_momentum(i, 2);
        double v = std::sqrt(px * px + py * py + pz * pz) * im;
        double lx = angular_momentum(i, 0), ly = angular_momentum(i, 1),
               lz = angular_momentum(i, 2);
        double w = std::sqrt(lx * lx + ly * ly + lz * lz) *
                   std::max(inv_inertia(i, 0), std::max(inv_inertia(i, 1), inv_inertia(i, 2)));
        double speed = std::max(v, w * radius[i]);
        if (speed < sleep_speed)
            sleep_timer[i] += h;
        else
            sleep_timer[i] = 0.0;
    }
    // islands: union the bodies of touching manifolds
    bool any_ready = false;
    for (i64 i = 0; i < n_dyn; ++i) {
        if (awake[i] && sleep_timer[i] >= sleep_time) {
            any_ready = true;
            break;
        }
    }
    if (!any_ready) return 0;
    for (i64 m = 0; m < n_man; ++m) {
        if (!mi[m].active) continue;
        bool touching = false;
        const i64 start = mi[m].start;
        for (i64 p = start; p < start + mi[m].count; ++p) {
            if (pf[p].lws > 0.0 || pf[p].s_end <= 0.0) {
                touching = true;
                break;
            }
        }
        if (!touching) continue;
        const i64 a = mi[m].a;
        const i64 b = mi[m].b;
        if (a < n_dyn) island_supported[a] = 1;
        if (b < n_dyn) island_supported[b] = 1;
        if (a < n_dyn && b < n_dyn) {
            i64 ra = find_root(parent, a);
            i64 rb_ = find_root(parent, b);
            if (ra != rb_) parent[std::max(ra, rb_)] = std::min(ra, rb_);
        }
    }
    for (i64 i = 0; i < n_dyn; ++i) {
        if (!awake[i]) continue;
        i64 r = find_root(parent, i);
        island_min_time[r] = std::min(island_min_time[r], sleep_timer[i]);
        if (island_supported[i]) island_supported[r] = 1;
    }
    i64 n_slept = 0;
    const i64 base = island_counter[0];
    for (i64 i = 0; i < n_dyn; ++i) {
        if (!awake[i]) continue;
        i64 r = find_root(parent, i);
        if (island_min_time[r] >= sleep_time && island_supported[r]) {
            awake[i] = 0;
            island_of[i] = base + r;
            for (int k = 0; k < 3; ++k) {
                linear_momentum(i, k) = 0.0;
                angular_momentum(i, k) = 0.0;
            }
            n_slept += 1;
        }
    }
    island_counter[0] = base + n_dyn;
    return n_slept;
}

void wake_island(i64 island, i64 n_dyn, V1<i64> awake, V1<double> sleep_timer,
                 V1<i64> island_of, V2<double> linear_momentum, V2<double> angular_momentum,
                 V2<double> force, V2<double> torque, double h, bool do_kick) {
    for (i64 j = 0; j < n_dyn; ++j) {
        if (awake[j] || island_of[j] != island) continue;
        awake[j] = 1;
        sleep_timer[j] = 0.0;
        island_of[j] = -1;
        if (do_kick) {
            for (int k = 0; k < 3; ++k) {
                linear_momentum(j, k) += h * force(j, k);
                angular_momentum(j, k) += h * torque(j, k);
            }
        }
    }
}

i64 wake_touched(V2<i64> pairs, i64 n_pairs, i64 n_dyn, i64 n_static, const Geoms& gm,
                 V1<i64> awake, V1<double> sleep_timer, V1<i64> island_of,
                 V2<double> position, V3<double> rotation, V1<double> reach,
                 double speculative_distance, double allowed_penetration, V2<double> sb_pos,
                 V3<double> sb_rot, V2<double> sb_ext, V1<double> gn, double goff,
                 V2<double> linear_momentum,
                 V2<double> angular_momentum, V2<double> force, V2<double> torque, double h,
                 bool do_kick, ColliderBuffers& buf, V1<double> inv_mass, V2<double> accel,
                 V1<double> radius, V2<double> inv_inertia) {
    require_collision_constants();
    // shape ids a, b: geoms (n_dyn of them), their bodies ba, bb
    const i64 n_body = position.n0;
    i64 n_woken = 0;
    for (i64 k = 0; k < n_pairs; ++k) {
        const i64 a = pairs(k, 0);
        const i64 b = pairs(k, 1);
        if (b >= n_dyn) continue;
        const i64 ba = gm.body[a], bb = gm.body[b];
        if ((awake[ba] != 0) == (awake[bb] != 0)) continue;
        const i64 sleeper = awake[ba] ? bb : ba;
        const i64 mover = awake[ba] ? ba : bb;
        double im = inv_mass[mover];
        double vx = linear_momentum(mover, 0) * im;
        double vy = linear_momentum(mover, 1) * im;
        double vz = linear_momentum(mover, 2) * im;
        if (do_kick) {
            vx -= h * accel(mover, 0);
            vy -= h * accel(mover, 1);
            vz -= h * accel(mover, 2);
        }
        double lx = angular_momentum(mover, 0), ly = angular_momentum(mover, 1),
               lz = angular_momentum(mover, 2);
        double wmax = std::sqrt(lx * lx + ly * ly + lz * lz) *
                      std::max(inv_inertia(mover, 0),
                               std::max(inv_inertia(mover, 1), inv_inertia(mover, 2)));
        double close = h * (std::sqrt(vx * vx + vy * vy + vz * vz) + wmax * radius[mover]);
        if (close <= allowed_penetration) {
            // a (nearly) resting neighbour: if it does push, wake_pushed wakes the island
            continue;
        }
        double pc[2][3], pr[2][9];
        const GeomPose pa = geom_pose(gm, a, position, rotation, pc[0], pr[0]);
        const PairGeometry g = pair_geometry(a, b, n_dyn, n_static, gm, pa, position, rotation,
                                             sb_pos, sb_rot, sb_ext, pc[1], pr[1]);
        const i64 ga = gm.code[a];
        double spec = speculative_distance + reach[a] + reach[b];
        i64 res = collide(ga, g.geom, pa.centre, pa.rotation, gm.size.row(a), g.centre,
                          g.rotation, g.size, gn.p, goff, spec, buf);
        for (i64 q = 0; q < 8; ++q) {
            if ((q < 4 && q >= res % 8) || (q >= 4 && q - 4 >= res / 8)) continue;
            if (buf.sep[q] < close) {
                n_woken += 1;
                wake_island(island_of[sleeper], n_body, awake, sleep_timer, island_of,
                            linear_momentum, angular_momentum, force, torque, h, do_kick);
                break;
            }
        }
    }
    return n_woken;
}

i64 wake_pushed(V1<ManifoldHead> mi, V1<Manifold> mf, V1<ContactPoint> pf, i64 n_man, i64 n_dyn,
                V1<i64> awake,
                V1<double> sleep_timer, V1<i64> island_of, V2<double> position,
                V2<double> linear_momentum, V2<double> angular_momentum, V2<double> force,
                V2<double> torque, double h) {
    i64 n_woken = 0;
    for (i64 m = 0; m < n_man; ++m) {
        if (!mi[m].active) continue;
        const i64 a = mi[m].rec_a;
        const i64 b = mi[m].rec_b;
        i64 sleeper = -1;
        double sign = 0.0;
        if (mi[m].a == n_dyn && a >= 0) {
            sleeper = a;
            sign = 1.0;
        } else if (b >= 0 && mi[m].b == n_dyn) {
            sleeper = b;
            sign = -1.0;
        }
        if (sleeper < 0) continue;
        bool pushed = false;
        const double nx = mf[m].normal[0], ny = mf[m].normal[1], nz = mf[m].normal[2];
        const i64 start = mi[m].start;
        for (i64 p = start; p < start + mi[m].count; ++p) {
            double ln = pf[p].ln;
            if (ln <= 0.0) continue;
            pushed = true;
            double jx = sign * (ln * nx + pf[p].friction[0]);
            double jy = sign * (ln * ny + pf[p].friction[1]);
            double jz = sign * (ln * nz + pf[p].friction[2]);
            double rx = pf[p].point[0] - position(sleeper, 0);
            double ry = pf[p].point[1] - position(sleeper, 1);
            double rz = pf[p].point[2] - position(sleeper, 2);
            linear_momentum(sleeper, 0) += jx;
            linear_momentum(sleeper, 1) += jy;
            linear_momentum(sleeper, 2) += jz;
            angular_momentum(sleeper, 0) += ry * jz - rz * jy;
            angular_momentum(sleeper, 1) += rz * jx - rx * jz;
            angular_momentum(sleeper, 2) += rx * jy - ry * jx;
        }
        if (pushed && !awake[sleeper]) {
            n_woken += 1;
            wake_island(island_of[sleeper], n_dyn, awake, sleep_timer, island_of, linear_momentum,
                        angular_momentum, force, torque, h, false);
        }
    }
    return n_woken;
}

}  // namespace rb
