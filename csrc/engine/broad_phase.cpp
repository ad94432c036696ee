// Broad phase: swept AABBs and sort-and-sweep, N log N (rblog/engine/contact/broadphase.py, the
// same formulas in the same order).
//
// Shape ids: the bodies' geoms 0..G-1 (collision.hpp Geoms; G = N, geom i = body i when every
// body is one shape), static boxes G..G+M-1, the ground G+M. A pair is always (lower id, higher
// id), so a dynamic geom is a and static geometry is b; two geoms of one body never pair.
//
// Each awake body's geom's box is its world AABB grown by half the speculative distance (margin) and
// swept along its displacement over the step (h v, and h |omega| rho for rotation, capped at the
// bounding sphere): two bodies whose boxes do not overlap cannot come within the speculative
// distance during the step. reach is how far any point of the body can move in the step; the
// narrowphase keeps points closer than margin + reach_a + reach_b. |omega| is bounded cheaply by
// |L| max(1/I) (a rotating box stays in its bounding sphere).
//
// Collision groups: bodies in different non-zero groups never collide; group 0 collides with
// everything, and static geometry (ground, static boxes) collides with every body.
//
// The sweep runs along the axis where the AABB centres spread most; the sort is stable (numpy's
// argsort kind="mergesort"; NaN keys last, as numpy sorts them), so the pairs are a deterministic
// function of the state. Overlap tests are written as "not overlapping" so that a NaN box never
// pairs with anything.
#include <algorithm>
#include <cmath>
#include <vector>

#include "common/task_pool.hpp"
#include "engine/collision.hpp"
#include "engine/hull.hpp"

namespace rb {

TaskPool& pool();  // the engine's pool (threads.cpp)

namespace {
// bodies per block of body_aabbs on the task pool, and the fewest bodies worth a hand-off
// (~180 instructions a body: 1,024 bodies are ~60 us), boxes per block of the sweep and the
// fewest worth it (~1,000 instructions a box in the 500-box pile)
constexpr i64 BODIES_PER_BLOCK = 256;
constexpr i64 MIN_BODIES = 1024;
constexpr i64 ITEMS_PER_BLOCK = 128;
constexpr i64 MIN_ITEMS = 256;
}  // namespace

void body_aabbs(const Geoms& gm, V1<double> inv_mass, V2<double> inv_inertia, V1<i64> awake,
                V2<double> position, V2<double> linear_momentum, V3<double> rotation,
                V2<double> angular_momentum, double h, double margin, V2<double> lo,
                V2<double> hi, V1<double> reach) {
    const i64 n = gm.n();
    const double pad = 0.5 * margin;
    // each geom writes only its own rows: blocks of geoms on the task pool
    const i64 nb = pool().threads() > 1 ? TaskPool::blocks_for(n, BODIES_PER_BLOCK, MIN_BODIES) : 1;
    pool().run(nb, [&](i64 blk, int) {
    for (i64 g = n * blk / nb; g < n * (blk + 1) / nb; ++g) {
        const i64 i = gm.body[g];
        const i64 code = gm.code[g];
        const bool off = gm.offset[g] != 0;
        double cbuf[3], rbuf[9];
        const GeomPose pose = geom_pose(gm, g, position, rotation, cbuf, rbuf);
        const double* sz = gm.size.row(g);
        double ex, ey, ez;
        if (code == GEOM_SPHERE) {
            ex = ey = ez = sz[0];
        } else if (code == GEOM_CAPSULE || code == GEOM_CYLINDER) {
            // the axis z_w = R e_z: a capsule's segment +-h z_w grown by r; a cylinder's two
            // discs of radius r normal to z_w, whose extent along e_k is r sqrt(1 - z_k^2)
            M3 r = pose.rotation;
            const double rr = sz[0], hh = sz[1];
            const bool cap = code == GEOM_CAPSULE;
            double e3[3];
            for (int k = 0; k < 3; ++k) {
                const double zk = r(k, 2);
                e3[k] = std::fabs(zk) * hh + (cap ? rr : rr * std::sqrt(std::max(0.0, 1.0 - zk * zk)));
            }
            ex = e3[0];
            ey = e3[1];
            ez = e3[2];
        } else {
            // a box's half extents; a hull's geom-frame box about its centre (hull.hpp ext)
            M3 r = pose.rotation;
            const double* e = code == GEOM_HULL ? hull_of(sz).ext : sz;
            double e0 = e[0], e1 = e[1], e2 = e[2];
            ex = std::fabs(r(0, 0)) * e0 + std::fabs(r(0, 1)) * e1 + std::fabs(r(0, 2)) * e2;
            ey = std::fabs(r(1, 0)) * e0 + std::fabs(r(1, 1)) * e1 + std::fabs(r(1, 2)) * e2;
            ez = std::fabs(r(2, 0)) * e0 + std::fabs(r(2, 1)) * e1 + std::fabs(r(2, 2)) * e2;
        }
        double dx = 0.0, dy = 0.0, dz = 0.0;
        double rho = 0.0;
        const double rad = gm.radius[g];
        if (awake[i]) {
            double im = inv_mass[i];
            dx = h * linear_momentum(i, 0) * im;
            dy = h * linear_momentum(i, 1) * im;
            dz = h * linear_momentum(i, 2) * im;
            if (code != GEOM_SPHERE || off) {
                // |omega| <= |L| max(1/I): a cheap bound; a geom at the centre of mass stays in
                // its sphere of radius rad as it turns; an offset geom's points (within rad of
                // the centre of mass) move at most h |omega| rad, and at most the diameter 2 rad
                double lx = angular_momentum(i, 0), ly = angular_momentum(i, 1),
                       lz = angular_momentum(i, 2);
                double wmax = std::sqrt(lx * lx + ly * ly + lz * lz) *
                              std::max(inv_inertia(i, 0),
                                       std::max(inv_inertia(i, 1), inv_inertia(i, 2)));
                if (off) {
                    rho = std::min(h * wmax * rad, 2.0 * rad);
                    ex += rho;
                    ey += rho;
                    ez += rho;
                } else {
                    rho = std::min(h * wmax * rad, rad);
                    ex = std::min(ex + rho, rad);
                    ey = std::min(ey + rho, rad);
                    ez = std::min(ez + rho, rad);
                }
            }
            reach[g] = std::sqrt(dx * dx + dy * dy + dz * dz) + rho;
        } else {
            reach[g] = 0.0;
        }
        double x = pose.centre[0], y = pose.centre[1], z = pose.centre[2];
        lo(g, 0) = x - ex - pad + std::min(dx, 0.0);
        lo(g, 1) = y - ey - pad + std::min(dy, 0.0);
        lo(g, 2) = z - ez - pad + std::min(dz, 0.0);
        hi(g, 0) = x + ex + pad + std::max(dx, 0.0);
        hi(g, 1) = y + ey + pad + std::max(dy, 0.0);
        hi(g, 2) = z + ez + pad + std::max(dz, 0.0);
    }
    });
}

// broadphase.py's _grow_pairs: room for 2 rows + 16 more pairs, contents kept.
static void grow_pairs(Buf2<i64>& pairs) { pairs.grow(2 * pairs.rows + 16); }

i64 sweep_and_prune(i64 n_items, i64 n_dyn, V2<double> lo, V2<double> hi, V1<i64> body,
                    V1<i64> group, V1<i64> awake, Buf2<i64>& pairs) {
    (void)awake;  // pairs of sleeping bodies are emitted too (collide carries them over)
    if (n_items < 2) return 0;
    // sweep axis: largest spread of the centres
    int best_axis = 0;
    double best_var = -1.0;
    for (int ax = 0; ax < 3; ++ax) {
        double s = 0.0;
        double s2 = 0.0;
        for (i64 i = 0; i < n_items; ++i) {
            double c = 0.5 * (lo(i, ax) + hi(i, ax));
            s += c;
            s2 += c * c;
        }
        double var = s2 - s * s / n_items;
        if (var > best_var) {
            best_var = var;
            best_axis = ax;
        }
    }
    const int ax1 = (best_axis + 1) % 3;
    const int ax2 = (best_axis + 2) % 3;
    // stable argsort of the boxes' low ends on the sweep axis (NaN last, as numpy): a sort by
    // (key, index), which orders ties by index as a stable sort does
    struct Item {
        double key;
        i64 id;
    };
    std::vector<Item> order(n_items);
    for (i64 i = 0; i < n_items; ++i) order[i] = Item{lo(i, best_axis), i};
    std::sort(order.begin(), order.end(), [](const Item& a, const Item& b) {
        const bool an = std::isnan(a.key), bn = std::isnan(b.key);
        if (an || bn) return an != bn ? bn : a.id < b.id;
        if (a.key != b.key) return a.key < b.key;
        return a.id < b.id;
    });
    // the boxes in sweep order, contiguous (the same values; only the memory layout differs)
    std::vector<double> box(6 * n_items);
    for (i64 ii = 0; ii < n_items; ++ii) {
        const i64 i = order[ii].id;
        double* bx = box.data() + 6 * ii;
        bx[0] = lo(i, best_axis);
        bx[1] = hi(i, best_axis);
        bx[2] = lo(i, ax1);
        bx[3] = hi(i, ax1);
        bx[4] = lo(i, ax2);
        bx[5] = hi(i, ax2);
    }
    // the sweep: each box against the boxes after it in sweep order, in blocks of boxes on the
    // task pool, the first block's pairs straight into `pairs` (one block: the serial sweep),
    // the others' into lists of their own, joined after it in block order, so the pairs come
    // out in the serial sweep's order
    const i64 nb =
        pool().threads() > 1 ? TaskPool::blocks_for(n_items, ITEMS_PER_BLOCK, MIN_ITEMS) : 1;
    // (the calling thread's lists, kept: no allocation once grown; a reference, since a
    // lambda running on a worker would name the worker's own thread_local)
    static thread_local std::vector<std::vector<i64>> kept;
    std::vector<std::vector<i64>>& found = kept;
    if ((i64)found.size() < nb) found.resize((size_t)nb);
    i64 count = 0;
    pool().run(nb, [&](i64 blk, int) {
        std::vector<i64>& out = found[(size_t)blk];
        out.clear();
        auto emit = [&](i64 a, i64 b) {
            if (blk == 0) {
                if (count == pairs.rows) grow_pairs(pairs);
                pairs(count, 0) = a;
                pairs(count, 1) = b;
                count += 1;
            } else {
                out.push_back(a);
                out.push_back(b);
            }
        };
        // (locals, not the captures: the pair writes could alias them for all the compiler
        // knows, and it would reload them every test)
        const Item* ord = order.data();
        const double* bx = box.data();
        const i64 n_it = n_items, n_d = n_dyn;
        const V1<i64> grp = group, own = body;
        for (i64 ii = n_it * blk / nb; ii < n_it * (blk + 1) / nb; ++ii) {
            const i64 i = ord[ii].id;
            const double* bi = bx + 6 * ii;
            const double hi_i = bi[1], lo1 = bi[2], hi1 = bi[3], lo2 = bi[4], hi2 = bi[5];
            const bool i_static = i >= n_d;
            for (i64 jj = ii + 1; jj < n_it; ++jj) {
                const double* bj = bx + 6 * jj;
                // written as "not overlapping" so that a NaN box never pairs with anything
                // (the box tests before the id's: the same conjunction, cheapest first)
                if (!(bj[0] <= hi_i)) break;
                if (!(bj[2] <= hi1 && lo1 <= bj[3])) continue;
                if (!(bj[4] <= hi2 && lo2 <= bj[5])) continue;
                const i64 j = ord[jj].id;
                if (i_static && j >= n_d) continue;
                const i64 a = std::min(i, j);
                const i64 b = std::max(i, j);
                if (b < n_d) {
                    const i64 ba = own[a], bb = own[b];
                    if (ba == bb) continue;  // two parts of one body
                    i64 ga = grp[ba];
                    i64 gb = grp[bb];
                    if (ga != 0 && gb != 0 && ga != gb) continue;
                }
                emit(a, b);
            }
        }
    });
    for (i64 blk = 1; blk < nb; ++blk) {
        const std::vector<i64>& out = found[(size_t)blk];
        for (size_t k = 0; k < out.size(); k += 2) {
            if (count == pairs.rows) grow_pairs(pairs);
            pairs(count, 0) = out[k];
            pairs(count, 1) = out[k + 1];
            count += 1;
        }
    }
    return count;
}

i64 ground_pairs(i64 n_dyn, i64 n_static, V1<double> gn, double goff, V2<double> lo,
                 V2<double> hi, Buf2<i64>& pairs, i64 n_pairs) {
    const i64 gid = n_dyn + n_static;
    const double gx = gn[0], gy = gn[1], gz = gn[2];
    for (i64 i = 0; i < n_dyn; ++i) {
        double cx = 0.5 * (lo(i, 0) + hi(i, 0));
        double cy = 0.5 * (lo(i, 1) + hi(i, 1));
        double cz = 0.5 * (lo(i, 2) + hi(i, 2));
        double ext = (std::fabs(gx) * (hi(i, 0) - lo(i, 0)) +
                      std::fabs(gy) * (hi(i, 1) - lo(i, 1)) +
                      std::fabs(gz) * (hi(i, 2) - lo(i, 2))) *
                     0.5;
        if (gx * cx + gy * cy + gz * cz - goff - ext > 0.0) continue;
        if (n_pairs == pairs.rows) grow_pairs(pairs);
        pairs(n_pairs, 0) = i;
        pairs(n_pairs, 1) = gid;
        n_pairs += 1;
    }
    return n_pairs;
}

}  // namespace rb
