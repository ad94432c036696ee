// The broadphase of the audit's geometry (shapes.hpp): which geoms may be within pad of each
// other at each sample. Sort-and-sweep over the geoms' tight world AABBs (aabb: the support
// along each world axis) on the axis along which the AABB centres spread most, then the other
// two axes; planes apart, each tested against every other geom by the exact support distance.
// Cost per sample: O(G log G) for the sort plus one test per overlapping pair on the sweep axis.
// geom_sweep_broadphase does the same per sample interval with each geom's AABBs at the two
// samples united and grown by the caller's bound on the rotation's bulge (the tunneling
// analyzer's candidates: pairs that may meet between the samples, planes apart).
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

namespace rb {
namespace audit {

i64 geom_sweep_broadphase(V3<double> position, V4<double> rotation, V1<i64> type, V2<double> size,
                          V1<i64> mesh_start, V1<i64> mesh_count, V2<double> verts, V1<i64> body,
                          V1<bool> mine, V2<double> grow, V1<i64> out_k, V1<i64> out_i,
                          V1<i64> out_j) {
    const i64 t_n = position.n0, g_n = position.n1;
    i64 cnt = 0;
    std::vector<i64> solid;
    for (i64 g = 0; g < g_n; ++g)
        if (type[g] != GEOM_PLANE) solid.push_back(g);
    if (t_n < 2 || solid.size() < 2) return 0;
    // the tight AABBs at the interval's two samples (the end one carried to the next interval)
    std::vector<Vec> lo0(g_n), hi0(g_n), lo1(g_n), hi1(g_n), slo(g_n), shi(g_n);
    auto bounds = [&](i64 k, std::vector<Vec>& lo, std::vector<Vec>& hi) {
        for (i64 g : solid) {
            const double* x = &position(k, g, 0);
            const double* vp = mesh_count[g] > 0 ? &verts(mesh_start[g], 0) : nullptr;
            aabb(Geom{type[g], {x[0], x[1], x[2]}, &rotation(k, g, 0, 0), &size(g, 0), vp,
                      mesh_count[g]},
                 lo[g], hi[g]);
        }
    };
    auto comp = [](const Vec& v, int q) { return q == 0 ? v.x : q == 1 ? v.y : v.z; };
    std::vector<i64> order = solid;
    bounds(0, lo0, hi0);
    for (i64 k = 0; k + 1 < t_n; ++k) {
        bounds(k + 1, lo1, hi1);
        double mean[3] = {0, 0, 0}, sq[3] = {0, 0, 0};
        for (i64 g : solid) {
            const double e = grow(k, g);
            slo[g] = {std::min(lo0[g].x, lo1[g].x) - e, std::min(lo0[g].y, lo1[g].y) - e,
                      std::min(lo0[g].z, lo1[g].z) - e};
            shi[g] = {std::max(hi0[g].x, hi1[g].x) + e, std::max(hi0[g].y, hi1[g].y) + e,
                      std::max(hi0[g].z, hi1[g].z) + e};
            for (int q = 0; q < 3; ++q) {
                const double c = 0.5 * (comp(slo[g], q) + comp(shi[g], q));
                mean[q] += c;
                sq[q] += c * c;
            }
        }
        // sweep axis: the largest spread of the swept boxes' centres
        int ax = 0;
        double best = -1;
        for (int q = 0; q < 3; ++q) {
            const double var = sq[q] - mean[q] * mean[q] / solid.size();
            if (var > best) {
                best = var;
                ax = q;
            }
        }
        std::sort(order.begin(), order.end(),
                  [&](i64 a, i64 b) { return comp(slo[a], ax) < comp(slo[b], ax); });
        for (size_t p = 0; p < order.size(); ++p) {
            const i64 a = order[p];
            const double reach = comp(shi[a], ax);
            for (size_t q = p + 1; q < order.size() && comp(slo[order[q]], ax) <= reach; ++q) {
                const i64 b = order[q];
                if (body[a] == body[b] || (body[a] < 0 && body[b] < 0) || !(mine[a] || mine[b]))
                    continue;
                if (slo[a].x > shi[b].x || slo[b].x > shi[a].x) continue;
                if (slo[a].y > shi[b].y || slo[b].y > shi[a].y) continue;
                if (slo[a].z > shi[b].z || slo[b].z > shi[a].z) continue;
                if (cnt < out_k.n0) {
                    out_k[cnt] = k;
                    out_i[cnt] = std::min(a, b);
                    out_j[cnt] = std::max(a, b);
                }
                ++cnt;
            }
        }
        std::swap(lo0, lo1);
        std::swap(hi0, hi1);
    }
    return cnt;
}

}  // namespace audit
}  // namespace rb
