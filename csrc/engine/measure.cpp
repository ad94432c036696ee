// Penetration audits: the narrowphase run on a given configuration, nothing else
// (rblog/engine/contact/measure.py: separations, max_penetration).
//
// The bodies are taken at rest (unswept AABBs padded by margin, no reach), the broad phase pairs
// them (body_aabbs, sweep_and_prune, ground_pairs: the step's own), and each pair's collider runs
// with speculative distance margin. A pair's least separation is the minimum over its FIRST
// manifold, which holds the pair's separating-axis normal (an edge contact's second, face
// manifold measures along another direction, conservatively). Any state (rblog's, or another
// engine's converted to rblog's model) is measured with the same geometry code, so penetration
// statistics of two engines are comparable.
#include <algorithm>
#include <vector>

#include "engine/collision.hpp"

namespace rb {

std::vector<double> pair_min_separations(const Geoms& gm, V1<double> inv_mass,
                                         V2<double> inv_inertia,
                                         V1<i64> group, i64 n_static, V2<double> sb_pos,
                                         V3<double> sb_rot, V2<double> sb_ext, V2<double> sb_lo,
                                         V2<double> sb_hi, bool ground, V1<double> gn,
                                         double goff, V2<double> position, V3<double> rotation,
                                         double margin) {
    require_collision_constants();
    const i64 nb = position.n0;  // bodies
    const i64 n = gm.n();        // geoms: the dynamic shape ids
    const i64 ns = n_static;
    // the step's broadphase with every body asleep and at rest: boxes unswept
    std::vector<double> lo_buf((n + ns) * 3), hi_buf((n + ns) * 3), reach_buf(n + ns);
    V2<double> lo{lo_buf.data(), n + ns, 3}, hi{hi_buf.data(), n + ns, 3};
    for (i64 k = 0; k < ns; ++k)
        for (int c = 0; c < 3; ++c) {
            lo(n + k, c) = sb_lo(k, c);
            hi(n + k, c) = sb_hi(k, c);
        }
    std::vector<i64> awake_buf(nb, 0);
    std::vector<double> zeros(nb * 3, 0.0);
    V1<i64> awake{awake_buf.data(), nb};
    V2<double> z3{zeros.data(), nb, 3};
    body_aabbs(gm, inv_mass, inv_inertia, awake, position, z3, rotation, z3, 0.0, margin, lo, hi,
               V1<double>{reach_buf.data(), n + ns});
    Buf2<i64> pairs(std::max<i64>(16, 4 * n), 2);
    i64 n_pairs = sweep_and_prune(n + ns, n, lo, hi, gm.body, group, awake, pairs);
    if (ground) n_pairs = ground_pairs(n, ns, gn, goff, lo, hi, pairs, n_pairs);
    std::vector<double> out;
    out.reserve(n_pairs);
    ColliderBuffers buf = collider_buffers();
    for (i64 k = 0; k < n_pairs; ++k) {
        const i64 a = pairs(k, 0);
        const i64 b = pairs(k, 1);
        double pc[2][3], pr[2][9];
        const GeomPose pa = geom_pose(gm, a, position, rotation, pc[0], pr[0]);
        const PairGeometry g = pair_geometry(a, b, n, ns, gm, pa, position, rotation, sb_pos,
                                             sb_rot, sb_ext, pc[1], pr[1]);
        const i64 res = collide(gm.code[a], g.geom, pa.centre, pa.rotation, gm.size.row(a),
                                g.centre, g.rotation, g.size, gn.p, goff, margin, buf);
        const i64 n1 = manifold_part(res, 0).count;
        if (n1 <= 0) continue;
        // the first manifold holds the pair's separating-axis normal
        double smin = buf.sep[0];
        for (i64 q = 1; q < n1; ++q) smin = std::min(smin, buf.sep[q]);
        out.push_back(smin);
    }
    return out;
}

}  // namespace rb
