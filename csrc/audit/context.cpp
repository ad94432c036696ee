// The shared values of a check (rblog/analyze/base.py, Context): per-sample kinematics, the
// inferred contact impulses, contact groups, and the finiteness scan of the channels.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "audit/audit.hpp"

namespace rb {
namespace audit {

namespace {

// Root of a in the union-find forest, halving the path on the way.
inline i64 find(i64* parent, i64 a) {
    while (parent[a] != a) {
        parent[a] = parent[parent[a]];
        a = parent[a];
    }
    return a;
}

}  // namespace

// Contact groups, interval by interval (edges (ek, ea, eb) sorted by interval): union-find over
// the bodies joined by possible contacts, keeping the components with a jumped member (jump
// (T-1, N)). Writes groups (interval g_k, size g_size, static features in reach g_nstat, static
// id g_sid) and their members (m_k, m_i, m_g) contiguous per group, groups and members in body
// order; returns (groups, members).
std::tuple<i64, i64> groups_kernel(V2<bool> jump, V2<i64> n_static, V2<i64> static_id, V1<i64> ek,
                                   V1<i64> ea, V1<i64> eb, V1<i64> g_k, V1<i64> g_size,
                                   V1<i64> g_nstat, V1<i64> g_sid, V1<i64> m_k, V1<i64> m_i,
                                   V1<i64> m_g) {
    const i64 kn = jump.n0, n = jump.n1;
    std::vector<i64> parent(n), gid(n, -1), fill(n, 0);
    std::vector<char> touched(n, 0), has(n, 0);
    for (i64 v = 0; v < n; ++v) parent[v] = v;
    i64* par = parent.data();
    i64 c = 0, q = 0, e = 0;
    const i64 ne = ek.n0;
    for (i64 k = 0; k < kn; ++k) {
        bool any_node = false;
        while (e < ne && ek[e] == k) {
            const i64 a = ea[e], b = eb[e];
            touched[a] = 1;
            touched[b] = 1;
            any_node = true;
            const i64 ra = find(par, a), rb = find(par, b);
            if (ra < rb) parent[rb] = ra;
            else if (rb < ra) parent[ra] = rb;
            e += 1;
        }
        for (i64 v = 0; v < n; ++v) {
            if (jump(k, v)) {
                touched[v] = 1;
                any_node = true;
            }
        }
        if (!any_node) continue;
        for (i64 v = 0; v < n; ++v)
            if (touched[v] && jump(k, v)) has[find(par, v)] = 1;
        const i64 c0 = c;
        for (i64 v = 0; v < n; ++v) {  // groups in the order of their smallest body
            if (!touched[v]) continue;
            const i64 r = find(par, v);
            if (has[r]) {
                if (gid[r] < 0) {
                    gid[r] = c;
                    g_k[c] = k;
                    g_size[c] = 0;
                    g_nstat[c] = 0;
                    g_sid[c] = -2;
                    c += 1;
                }
                const i64 g = gid[r];
                g_size[g] += 1;
                g_nstat[g] += n_static(k, v);
                if (n_static(k, v) > 0) g_sid[g] = static_id(k, v);
            }
        }
        // members, contiguous per group
        i64 start = q;
        for (i64 g = c0; g < c; ++g) {
            fill[g - c0] = start;
            start += g_size[g];
        }
        for (i64 v = 0; v < n; ++v) {
            if (!touched[v]) continue;
            const i64 r = find(par, v);
            if (has[r]) {
                const i64 g = gid[r];
                const i64 pos = fill[g - c0];
                m_k[pos] = k;
                m_i[pos] = v;
                m_g[pos] = g;
                fill[g - c0] += 1;
            }
        }
        q = start;
        for (i64 v = 0; v < n; ++v) {  // reset what this interval touched
            if (touched[v]) {
                const i64 r = find(par, v);
                has[r] = 0;
                gid[r] = -1;
            }
        }
        for (i64 v = 0; v < n; ++v) {
            if (touched[v]) {
                parent[v] = v;
                touched[v] = 0;
            }
        }
    }
    return {c, q};
}

// One pass over the samples: |v|, |w|, kinetic energy P.P/2m + L.w/2, potential -(m g + F).x
// (T, N); and per interval (T-1, N): jump (momentum change beyond (m g + F) dt or torque dt) and
// sweep (how far any point of the body can move). force (N, 3) is m g + F.
void kinematics(V1<double> t, V3<double> position, V3<double> velocity, V3<double> momentum,
                V3<double> ang_momentum, V3<double> omega, V1<double> mass, V2<double> force,
                V2<double> torque, V1<double> rho, V1<double> inertia_max, double jump_rel,
                V2<double> speed, V2<double> spin, V2<double> ke, V2<double> u, V2<bool> jump,
                V2<double> sweep) {
    const i64 t_n = position.n0, n = position.n1;
    for (i64 k = 0; k < t_n; ++k) {
        for (i64 b = 0; b < n; ++b) {
            const double* v = &velocity(k, b, 0);
            const double* w = &omega(k, b, 0);
            const double* p = &momentum(k, b, 0);
            const double* l_ = &ang_momentum(k, b, 0);
            const double* x = &position(k, b, 0);
            speed(k, b) = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            spin(k, b) = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
            ke(k, b) = 0.5 * (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) / mass[b] +
                       0.5 * (l_[0] * w[0] + l_[1] * w[1] + l_[2] * w[2]);
            u(k, b) = -(force(b, 0) * x[0] + force(b, 1) * x[1] + force(b, 2) * x[2]);
        }
    }
    for (i64 k = 0; k < t_n - 1; ++k) {
        const double dt = t[k + 1] - t[k];
        for (i64 b = 0; b < n; ++b) {
            const double a2 = (force(b, 0) * force(b, 0) + force(b, 1) * force(b, 1) +
                               force(b, 2) * force(b, 2)) /
                              (mass[b] * mass[b]);
            const double amag = std::sqrt(a2);
            double jj = 0.0, hh = 0.0, l0 = 0.0, l1 = 0.0;
            for (int d = 0; d < 3; ++d) {
                double jd = momentum(k + 1, b, d) - momentum(k, b, d) - force(b, d) * dt;
                double hd = ang_momentum(k + 1, b, d) - ang_momentum(k, b, d) - torque(b, d) * dt;
                jj += jd * jd;
                hh += hd * hd;
                l0 += ang_momentum(k, b, d) * ang_momentum(k, b, d);
                l1 += ang_momentum(k + 1, b, d) * ang_momentum(k + 1, b, d);
            }
            const double sp = std::max(speed(k, b), speed(k + 1, b));
            const double p_scale = mass[b] * (sp + amag * dt + 1e-9);
            const double l_scale = std::sqrt(std::max(l0, l1)) + inertia_max[b] * 1e-9;
            jump(k, b) = (std::sqrt(jj) > jump_rel * p_scale || std::sqrt(hh) > jump_rel * l_scale);
            sweep(k, b) = dt * (sp + rho[b] * std::max(spin(k, b), spin(k + 1, b))) +
                          0.5 * amag * dt * dt;
        }
    }
}

// out[r] = P(k+1) - P(k) - dt (m a) for body i[r] over interval k[r] (Context.impulse).
void impulse_kernel(V3<double> p, V1<double> dts, V1<double> mass, V2<double> accel, V1<i64> k,
                    V1<i64> i, V2<double> out) {
    for (i64 r = 0; r < k.n0; ++r) {
        const i64 kr = k[r], b = i[r];
        for (int d = 0; d < 3; ++d)
            out(r, d) = (p(kr + 1, b, d) - p(kr, b, d)) - dts[kr] * (mass[b] * accel(b, d));
    }
}

// True when no value of x (n float64) is an inf or a NaN (all exponent bits set), checked per
// block of 4,096 (stops at the first block with one). Branch-free and vectorisable with SSE2 alone
// (no 64-bit compare): (u & exp_bits) + 2^52 reaches bit 63 exactly when the exponent bits are all
// set (0x7FF0... + 0x0010... = 0x8000...; any smaller exponent stays below 2^63), so OR-ing those
// sums over a block and testing bit 63 tells whether the block holds one.
// Built twice (GCC/Clang function multiversioning, resolved once at load): an AVX2 clone reads 4
// values per instruction where the CPU has it, the default clone runs everywhere. Integer-only, so
// both give the same answer.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("avx2", "default")))
#endif
bool all_finite(const double* x, i64 n) {
    const std::uint64_t exp_bits = 0x7FF0000000000000ull, exp_one = 0x0010000000000000ull;
    i64 i = 0;
    while (i < n) {
        const i64 j = std::min(n, i + 4096);
        std::uint64_t acc = 0;
        for (i64 m = i; m < j; ++m) {
            std::uint64_t u;
            std::memcpy(&u, x + m, sizeof u);
            acc |= (u & exp_bits) + exp_one;
        }
        if (acc >> 63) return false;
        i = j;
    }
    return true;
}

}  // namespace audit
}  // namespace rb
