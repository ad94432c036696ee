// The audit's kernels (rblog.analyze._audit): declarations, one group per .cpp, and the two small
// helpers several of them inline (a box's touching feature, the rotation vector of an interval).
//
// The audit recomputes what it judges from the logged poses, apart from the engine: nothing here
// includes csrc/engine/ (an audit that shared the code it audits would inherit its bugs). Each
// kernel keeps the formulas of its analyzer in rblog/analyze/ in their order, so a report does
// not depend on which side computes a figure. Arrays are C-order float64 (int64 for indices, bool for masks) as Python holds them;
// shapes are in each kernel's comment. Tolerances are arguments (their one home is
// rblog/analyze/tolerances.py).
#pragma once

#include <cmath>
#include <cstdint>
#include <tuple>

#include "common/array.hpp"

namespace rb {
namespace audit {

// Shape codes of rblog.contract.model (SHAPE_SPHERE, SHAPE_BOX); rblog/analyze/geometry.py checks
// at import that these mirror them.
constexpr i64 SHAPE_SPHERE = 0;
constexpr i64 SHAPE_BOX = 1;

// --- geometry.cpp ---------------------------------------------------------------------------

// A box's touching feature along d, from p_j = d.A_j and the half extents h_j. Axis j is free (the
// feature spans it) when 2 h_j |p_j| <= band, s_j = 0; else s_j = sign(p_j) h_j. The feature's
// centre is x + sum_j s_j A_j; the box reaches further along d than that centre by
// drop = sum over free axes of h_j |p_j| (<= 1.5 band). A box thinner than the band along every
// axis keeps its axis most along d fixed (a face, not the whole box).
struct FeatureSigns {
    double s0, s1, s2;
    bool f0, f1, f2;
    double drop;
};

inline FeatureSigns feature_signs(double p0, double p1, double p2, double h0, double h1, double h2,
                                  double band) {
    bool f0 = 2.0 * h0 * std::fabs(p0) <= band;
    bool f1 = 2.0 * h1 * std::fabs(p1) <= band;
    bool f2 = 2.0 * h2 * std::fabs(p2) <= band;
    if (f0 && f1 && f2) {
        double a0 = std::fabs(p0), a1 = std::fabs(p1), a2 = std::fabs(p2);
        if (a0 >= a1 && a0 >= a2) f0 = false;
        else if (a1 >= a2) f1 = false;
        else f2 = false;
    }
    FeatureSigns o;
    o.s0 = f0 ? 0.0 : (p0 > 0 ? h0 : -h0);
    o.s1 = f1 ? 0.0 : (p1 > 0 ? h1 : -h1);
    o.s2 = f2 ? 0.0 : (p2 > 0 ? h2 : -h2);
    o.drop = ((f0 ? h0 * std::fabs(p0) : 0.0) + (f1 ? h1 * std::fabs(p1) : 0.0)) +
             (f2 ? h2 * std::fabs(p2) : 0.0);
    o.f0 = f0;
    o.f1 = f1;
    o.f2 = f2;
    return o;
}

// (sep, n from b into a, point, half-span) of one pair; see geometry.cpp.
struct PairOut {
    double sep, n0, n1, n2, p0, p1, p2, e0, e1, e2;
};

void plane_kernel(V3<double> position, V4<double> rotation, V1<bool> is_sphere, V2<double> size,
                  V1<double> n, double offset, V2<double> sep, V2<double> height);
void witness_kernel(V3<double> position, V4<double> rotation, V1<i64> k, V1<i64> j, V1<i64> body,
                    V1<bool> is_sphere, V2<double> size, V1<double> n, double band, V2<double> out,
                    V2<double> spn);
PairOut pair(i64 sa, const double* xa, const double* ra, const double* ha, i64 sb,
             const double* xb, const double* rb, const double* hb, bool with_point, double band,
             double axis_eps);
void pairs_kernel(V1<i64> ks, V1<i64> a, V1<i64> b, V3<double> position, V4<double> rotation,
                  V1<i64> shape, V2<double> size, V3<double> s_pos, V4<double> s_rot,
                  V2<double> s_half, V1<double> sep, V2<double> nrm, V2<double> pt,
                  V2<double> spn, bool with_points, double band, double axis_eps);
std::tuple<double, double> edge_edge(double ax, double ay, double eax, double eay, double bx,
                                     double by, double ebx, double eby, double band);
i64 sweep_kernel(V3<double> position, V2<double> grow, V2<double> s_lo, V2<double> s_hi,
                 V1<i64> group, i64 axis, V1<i64> out_k, V1<i64> out_a, V1<i64> out_b);
void spread(V2<double> x, double* out);

// --- consistency.cpp ------------------------------------------------------------------------

// (R(k1) R(k0)^T)_ij of body b: row i of R(k1) dot row j of R(k0).
inline double row_dot(const V4<double>& rot, i64 k1, i64 k0, i64 b, int i, int j) {
    return rot(k1, b, i, 0) * rot(k0, b, j, 0) + rot(k1, b, i, 1) * rot(k0, b, j, 1) +
           rot(k1, b, i, 2) * rot(k0, b, j, 2);
}

// Rotation vector (angle times axis, world frame, rad) of R(k1) R(k0)^T of body b.
inline void interval_rotvec(const V4<double>& rot, i64 k1, i64 k0, i64 b, double& tx, double& ty,
                            double& tz) {
    double d00 = row_dot(rot, k1, k0, b, 0, 0);
    double d11 = row_dot(rot, k1, k0, b, 1, 1);
    double d22 = row_dot(rot, k1, k0, b, 2, 2);
    double vx = 0.5 * (row_dot(rot, k1, k0, b, 2, 1) - row_dot(rot, k1, k0, b, 1, 2));
    double vy = 0.5 * (row_dot(rot, k1, k0, b, 0, 2) - row_dot(rot, k1, k0, b, 2, 0));
    double vz = 0.5 * (row_dot(rot, k1, k0, b, 1, 0) - row_dot(rot, k1, k0, b, 0, 1));
    double sn = std::sqrt(vx * vx + vy * vy + vz * vz);
    double ang = std::atan2(sn, 0.5 * (d00 + d11 + d22 - 1.0));
    double f = sn > 1e-300 ? ang / sn : 1.0;
    tx = vx * f;
    ty = vy * f;
    tz = vz * f;
}

void kinematic_rel(V4<double> rot, V3<double> omega, V1<double> dts, double min_angle,
                   double smooth_frac, double corr, V2<double> rel);
void linear_rel(V3<double> pos, V3<double> vel, V1<double> dts, double min_move,
                double smooth_frac, V1<double> acc, double corr, V2<double> rel);
void pointwise(V3<double> quat, V4<double> rot, V3<double> mom, V3<double> vel, V3<double> omega,
               V3<double> lw, V1<double> mass, V2<double> inertia, V2<double> err_qm,
               V2<double> ortho, V2<double> dp, V2<double> p_mag, V2<double> rel_l,
               V2<double> l_scale);

// --- context.cpp (rblog/analyze/base.py) ---------------------------------------------------
std::tuple<i64, i64> groups_kernel(V2<bool> jump, V2<i64> n_static, V2<i64> static_id, V1<i64> ek,
                                   V1<i64> ea, V1<i64> eb, V1<i64> g_k, V1<i64> g_size,
                                   V1<i64> g_nstat, V1<i64> g_sid, V1<i64> m_k, V1<i64> m_i,
                                   V1<i64> m_g);
void kinematics(V1<double> t, V3<double> position, V3<double> velocity, V3<double> momentum,
                V3<double> ang_momentum, V3<double> omega, V1<double> mass, V2<double> force,
                V2<double> torque, V1<double> rho, V1<double> inertia_max, double jump_rel,
                V2<double> speed, V2<double> spin, V2<double> ke, V2<double> u, V2<bool> jump,
                V2<double> sweep);
void impulse_kernel(V3<double> p, V1<double> dts, V1<double> mass, V2<double> accel, V1<i64> k,
                    V1<i64> i, V2<double> out);
bool all_finite(const double* x, i64 n);

// --- penetration.cpp ------------------------------------------------------------------------
void deepest(V2<double> ground, double cd, V1<i64> pk, V1<i64> pa, V1<i64> pb, V1<double> ps,
             i64 n, V2<std::int8_t> kind, V2<i64> ref);
void contact_velocity(V1<i64> pk, V1<i64> pi_, V1<i64> pb, V2<double> point, V2<double> normal,
                      V3<double> position, V3<double> velocity, V3<double> omega, i64 n,
                      V2<double> cv, V2<double> slip, V1<double> cspeed, V1<double> wspeed);
void contact_slide(V1<i64> pk, V1<i64> pi_, V1<i64> pb, V2<double> point, V2<double> span,
                   V2<double> normal, V3<double> position, V4<double> rotation, i64 n,
                   V1<bool> nxt, V2<double> disp, V1<bool> is_box, V2<double> size,
                   V2<double> s_pos, V3<double> s_rot, V2<double> s_half, double band,
                   V1<i64> nload);
void impact_jump(V3<double> velocity, V3<double> omega, V1<double> reach, V2<double> out);

// --- momentum.cpp ---------------------------------------------------------------------------
void cone_kernel(V2<double> jv, V2<double> nrm, V1<double> mu, V1<double> mass, V2<double> speed,
                 V1<double> accel_norm, V1<double> dts, V1<i64> k, V1<i64> i, double floor_ns,
                 double res_eps, double tiny, V1<double> jn, V1<double> jt, V1<double> excess);
i64 flight_drift(V2<bool> free, V1<double> t, V3<double> p, V3<double> l, V2<double> speed,
                 V1<double> mass, V2<double> force, V2<double> tau, V1<double> p_floor,
                 V1<double> l_floor, V2<i64> segs, V2<double> vals);

// --- events.cpp -----------------------------------------------------------------------------
i64 link_groups(V1<i64> gk, V1<i64> h, V1<i64> size, V1<i64> sid, V1<i64> mem0, i64 n,
                V1<i64> eid, V1<i64> head_of, V1<i64> k1);

// --- energy.cpp -----------------------------------------------------------------------------
i64 free_drift(V2<bool> free, V1<double> t, V2<double> e, V2<double> ke, V2<double> u,
               V2<double> speed, V1<double> mass, V1<double> amag, double dt, double drift_rel,
               double floor, V2<i64> segs, V2<double> vals);

// --- drift.cpp ------------------------------------------------------------------------------
void rigidity(V4<double> rot, V3<double> quat, V3<double> out);

// --- tunneling.cpp --------------------------------------------------------------------------
void chord_overlap(V3<double> position, V1<i64> k, V1<i64> a, V1<i64> b, V1<double> thr_part,
                   V1<double> out);

}  // namespace audit
}  // namespace rb
