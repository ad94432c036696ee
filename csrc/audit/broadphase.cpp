// The broadphase of the audit's geometry (shapes.hpp): which geoms may be within pad of each
// other at each sample. Sort-and-sweep over the geoms' tight world AABBs (aabb: the support
// along each world axis) on the axis along which the AABB centres spread most, then the other
// two axes; planes apart, each tested against every other geom by the exact support distance.
// Cost per sample: O(G log G) for the sort plus one test per overlapping pair on the sweep axis.
#include <algorithm>
#include <numeric>
#include <vector>

#include "audit/shapes.hpp"

namespace rb {
namespace audit {

void aabb(const Geom& g, Vec& lo, Vec& hi) {
    double r = core_radius(g);
    Vec px = core_support(g, {1, 0, 0}), nx = core_support(g, {-1, 0, 0});
    Vec py = core_support(g, {0, 1, 0}), ny = core_support(g, {0, -1, 0});
    Vec pz = core_support(g, {0, 0, 1}), nz = core_support(g, {0, 0, -1});
    lo = {nx.x - r, ny.y - r, nz.z - r};
    hi = {px.x + r, py.y + r, pz.z + r};
}

i64 geom_broadphase(V3<double> position, V4<double> rotation, V1<i64> type, V2<double> size,
                    V1<i64> mesh_start, V1<i64> mesh_count, V2<double> verts, V1<i64> body,
                    double pad, V1<i64> out_k, V1<i64> out_i, V1<i64> out_j) {
    const i64 t_n = position.n0, g_n = position.n1;
    i64 cnt = 0;
    auto emit = [&](i64 k, i64 a, i64 b) {
        if (cnt < out_k.n0) {
            out_k[cnt] = k;
            out_i[cnt] = std::min(a, b);
            out_j[cnt] = std::max(a, b);
        }
        ++cnt;
    };
    auto skip = [&](i64 a, i64 b) {
        return body[a] == body[b] || (body[a] < 0 && body[b] < 0);
    };
    std::vector<Vec> lo(g_n), hi(g_n);
    std::vector<i64> order, planes;
    for (i64 g = 0; g < g_n; ++g)
        (type[g] == GEOM_PLANE ? planes : order).push_back(g);
    const std::vector<i64> solid = order;
    for (i64 k = 0; k < t_n; ++k) {
        auto geom = [&](i64 g) {
            const double* x = &position(k, g, 0);
            const double* vp = mesh_count[g] > 0 ? &verts(mesh_start[g], 0) : nullptr;
            return Geom{type[g], {x[0], x[1], x[2]}, &rotation(k, g, 0, 0), &size(g, 0), vp,
                        mesh_count[g]};
        };
        double mean[3] = {0, 0, 0}, sq[3] = {0, 0, 0};
        for (i64 g : solid) {
            aabb(geom(g), lo[g], hi[g]);
            double c[3] = {0.5 * (lo[g].x + hi[g].x), 0.5 * (lo[g].y + hi[g].y),
                           0.5 * (lo[g].z + hi[g].z)};
            for (int q = 0; q < 3; ++q) {
                mean[q] += c[q];
                sq[q] += c[q] * c[q];
            }
        }
        // sweep axis: the largest spread of the centres (sum of squares about the mean)
        int ax = 0;
        double best = -1;
        for (int q = 0; q < 3; ++q) {
            double m = solid.empty() ? 0 : mean[q] / solid.size();
            double var = sq[q] - m * mean[q];
            if (var > best) {
                best = var;
                ax = q;
            }
        }
        auto lo_ax = [&](i64 g) { return ax == 0 ? lo[g].x : ax == 1 ? lo[g].y : lo[g].z; };
        auto hi_ax = [&](i64 g) { return ax == 0 ? hi[g].x : ax == 1 ? hi[g].y : hi[g].z; };
        std::sort(order.begin(), order.end(), [&](i64 a, i64 b) { return lo_ax(a) < lo_ax(b); });
        for (size_t p = 0; p < order.size(); ++p) {
            i64 a = order[p];
            double reach = hi_ax(a) + 2 * pad;
            for (size_t q = p + 1; q < order.size() && lo_ax(order[q]) <= reach; ++q) {
                i64 b = order[q];
                if (skip(a, b)) continue;
                if (lo[a].x > hi[b].x + 2 * pad || lo[b].x > hi[a].x + 2 * pad) continue;
                if (lo[a].y > hi[b].y + 2 * pad || lo[b].y > hi[a].y + 2 * pad) continue;
                if (lo[a].z > hi[b].z + 2 * pad || lo[b].z > hi[a].z + 2 * pad) continue;
                emit(k, a, b);
            }
        }
        for (i64 pl : planes) {
            Geom gp = geom(pl);
            Vec u = axis(gp, 2);
            for (i64 g : solid) {
                if (skip(pl, g)) continue;
                Geom gg = geom(g);
                Vec p = core_support(gg, -u) - core_radius(gg) * u;
                if (dot(u, p - gp.x) <= pad) emit(k, pl, g);
            }
        }
    }
    return cnt;
}

}  // namespace audit
}  // namespace rb
