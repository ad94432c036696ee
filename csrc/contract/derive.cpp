// The derived channels of the log contract (rblog/contract/derive.py names them), computed from
// the state channels in one pass: T samples x N bodies.
//
// Per body i of sample t, with m its mass, P its linear momentum, x its position, R the logged
// rotation (body to world), L the world angular momentum, q the logged quaternion (w, x, y, z):
//
//   velocity = P / m
//   e_trans  = 1/2 |P|^2 / m
//   e_pot    = -m g.x                                  (zero of potential at the world origin)
//   omega    = R diag(inv_inertia) R^T L               (the logged R, as the integrators do), or,
//              when `stretched` (the quaternion scheme without normalization, whose R = |q|^2 Q
//              is no rotation), omega = I_world^-1 L with I_world = R I_body R^T, i.e.
//              C diag(inv_inertia) C^T L / det(R)^2 (C the cofactors of R: R^-1 = C^T / det,
//              R^-T = C / det); the two agree for an orthonormal R
//   e_rot    = 1/2 L.omega
//   ortho    = ||R^T R - I||_F
//   qnorm    = |q| - 1
//
// Totals per sample (summed over bodies in index order): total_p (T, 3) = sum P, total_l (T, 3)
// = sum x cross P + L (about the world origin), total_e (T,) = sum e_trans + e_rot + e_pot.
// Inputs (T, N, ...) float64 C-contiguous; outputs preallocated alike. The operation order is
// the numba kernel's it replaces, so the channels (and the logs' bytes) are unchanged.
#include <nanobind/nanobind.h>

#include <cmath>

#include "common/py.hpp"

namespace rb {

void derive_channels(V1<double> mass, V2<double> inv_inertia, V1<double> gravity,
                     V3<double> position, V3<double> linear_momentum, V3<double> quat_wxyz,
                     V4<double> rotation, V3<double> angular_momentum, V3<double> velocity,
                     V3<double> omega, V2<double> e_trans, V2<double> e_rot, V2<double> e_pot,
                     V2<double> ortho, V2<double> qnorm, V2<double> total_p, V2<double> total_l,
                     V1<double> total_e, bool stretched) {
    const i64 n_t = position.n0, n_b = position.n1;
    for (i64 t = 0; t < n_t; ++t) {
        double sp0 = 0.0, sp1 = 0.0, sp2 = 0.0, sl0 = 0.0, sl1 = 0.0, sl2 = 0.0, se = 0.0;
        for (i64 i = 0; i < n_b; ++i) {
            const double m = mass[i];
            const double px = linear_momentum(t, i, 0), py = linear_momentum(t, i, 1),
                         pz = linear_momentum(t, i, 2);
            velocity(t, i, 0) = px / m;
            velocity(t, i, 1) = py / m;
            velocity(t, i, 2) = pz / m;
            e_trans(t, i) = 0.5 * (px * px + py * py + pz * pz) / m;
            e_pot(t, i) = -m * (gravity[0] * position(t, i, 0) + gravity[1] * position(t, i, 1)
                                + gravity[2] * position(t, i, 2));
            auto r = [&](int a, int b) { return rotation(t, i, a, b); };
            const double lx = angular_momentum(t, i, 0), ly = angular_momentum(t, i, 1),
                         lz = angular_momentum(t, i, 2);
            double ox, oy, oz;
            if (stretched) {
                // cofactors of R: R^-1 = C^T / det, R^-T = C / det
                const double c00 = r(1, 1) * r(2, 2) - r(1, 2) * r(2, 1);
                const double c01 = r(1, 2) * r(2, 0) - r(1, 0) * r(2, 2);
                const double c02 = r(1, 0) * r(2, 1) - r(1, 1) * r(2, 0);
                const double c10 = r(0, 2) * r(2, 1) - r(0, 1) * r(2, 2);
                const double c11 = r(0, 0) * r(2, 2) - r(0, 2) * r(2, 0);
                const double c12 = r(0, 1) * r(2, 0) - r(0, 0) * r(2, 1);
                const double c20 = r(0, 1) * r(1, 2) - r(0, 2) * r(1, 1);
                const double c21 = r(0, 2) * r(1, 0) - r(0, 0) * r(1, 2);
                const double c22 = r(0, 0) * r(1, 1) - r(0, 1) * r(1, 0);
                const double det = r(0, 0) * c00 + r(0, 1) * c01 + r(0, 2) * c02;
                const double f = 1.0 / (det * det);
                const double b0 = (c00 * lx + c10 * ly + c20 * lz) * inv_inertia(i, 0) * f;
                const double b1 = (c01 * lx + c11 * ly + c21 * lz) * inv_inertia(i, 1) * f;
                const double b2 = (c02 * lx + c12 * ly + c22 * lz) * inv_inertia(i, 2) * f;
                ox = c00 * b0 + c01 * b1 + c02 * b2;
                oy = c10 * b0 + c11 * b1 + c12 * b2;
                oz = c20 * b0 + c21 * b1 + c22 * b2;
            } else {
                const double b0 = (r(0, 0) * lx + r(1, 0) * ly + r(2, 0) * lz) * inv_inertia(i, 0);
                const double b1 = (r(0, 1) * lx + r(1, 1) * ly + r(2, 1) * lz) * inv_inertia(i, 1);
                const double b2 = (r(0, 2) * lx + r(1, 2) * ly + r(2, 2) * lz) * inv_inertia(i, 2);
                ox = r(0, 0) * b0 + r(0, 1) * b1 + r(0, 2) * b2;
                oy = r(1, 0) * b0 + r(1, 1) * b1 + r(1, 2) * b2;
                oz = r(2, 0) * b0 + r(2, 1) * b1 + r(2, 2) * b2;
            }
            omega(t, i, 0) = ox;
            omega(t, i, 1) = oy;
            omega(t, i, 2) = oz;
            e_rot(t, i) = 0.5 * (lx * ox + ly * oy + lz * oz);
            double acc = 0.0;
            for (int a = 0; a < 3; ++a) {
                for (int b = 0; b < 3; ++b) {
                    double g = r(0, a) * r(0, b) + r(1, a) * r(1, b) + r(2, a) * r(2, b);
                    if (a == b) g -= 1.0;
                    acc += g * g;
                }
            }
            ortho(t, i) = std::sqrt(acc);
            const double q0 = quat_wxyz(t, i, 0), q1 = quat_wxyz(t, i, 1), q2 = quat_wxyz(t, i, 2),
                         q3 = quat_wxyz(t, i, 3);
            qnorm(t, i) = std::sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3) - 1.0;
            const double x0 = position(t, i, 0), x1 = position(t, i, 1), x2 = position(t, i, 2);
            sp0 += px;
            sp1 += py;
            sp2 += pz;
            sl0 += x1 * pz - x2 * py + lx;
            sl1 += x2 * px - x0 * pz + ly;
            sl2 += x0 * py - x1 * px + lz;
            se += e_trans(t, i) + e_rot(t, i) + e_pot(t, i);
        }
        total_p(t, 0) = sp0;
        total_p(t, 1) = sp1;
        total_p(t, 2) = sp2;
        total_l(t, 0) = sl0;
        total_l(t, 1) = sl1;
        total_l(t, 2) = sl2;
        total_e[t] = se;
    }
}

namespace {

// Shapes are checked once here (the kernel indexes without bounds checks).
void check(bool ok, const char* what) {
    if (!ok) throw nanobind::value_error(what);
}

}  // namespace

void bind_derive(nanobind::module_& m) {
    namespace nb = nanobind;
    m.def(
        "derive_channels",
        [](nb::handle mass, nb::handle inv_inertia, nb::handle gravity, nb::handle position,
           nb::handle linear_momentum, nb::handle quat_wxyz, nb::handle rotation,
           nb::handle angular_momentum, nb::handle velocity, nb::handle omega, nb::handle e_trans,
           nb::handle e_rot, nb::handle e_pot, nb::handle ortho, nb::handle qnorm,
           nb::handle total_p, nb::handle total_l, nb::handle total_e, bool stretched) {
            auto ms = v1<double>(mass, "mass");
            auto ii = v2<double>(inv_inertia, "inv_inertia");
            auto g = v1<double>(gravity, "gravity");
            auto x = v3<double>(position, "position");
            auto p = v3<double>(linear_momentum, "linear_momentum");
            auto q = v3<double>(quat_wxyz, "quat_wxyz");
            auto r = v4<double>(rotation, "rotation");
            auto l = v3<double>(angular_momentum, "angular_momentum");
            auto v = v3<double>(velocity, "velocity");
            auto w = v3<double>(omega, "omega");
            auto et = v2<double>(e_trans, "e_trans");
            auto er = v2<double>(e_rot, "e_rot");
            auto ep = v2<double>(e_pot, "e_pot");
            auto ot = v2<double>(ortho, "ortho");
            auto qn = v2<double>(qnorm, "qnorm");
            auto tp = v2<double>(total_p, "total_p");
            auto tl = v2<double>(total_l, "total_l");
            auto te = v1<double>(total_e, "total_e");
            const i64 T = x.n0, N = x.n1;
            check(x.n2 == 3 && p.n0 == T && p.n1 == N && p.n2 == 3 && q.n0 == T && q.n1 == N &&
                      q.n2 == 4 && r.n0 == T && r.n1 == N && r.n2 == 3 && r.n3 == 3 && l.n0 == T &&
                      l.n1 == N && l.n2 == 3,
                  "derive_channels: state channels of mismatched shapes");
            check(ms.n0 >= N && ii.n0 >= N && ii.n1 == 3 && g.n0 == 3,
                  "derive_channels: model arrays too short for the bodies");
            check(v.n0 == T && v.n1 == N && v.n2 == 3 && w.n0 == T && w.n1 == N && w.n2 == 3 &&
                      et.n0 == T && et.n1 == N && er.n0 == T && er.n1 == N && ep.n0 == T &&
                      ep.n1 == N && ot.n0 == T && ot.n1 == N && qn.n0 == T && qn.n1 == N &&
                      tp.n0 == T && tp.n1 == 3 && tl.n0 == T && tl.n1 == 3 && te.n0 == T,
                  "derive_channels: outputs of the wrong shape");
            nb::gil_scoped_release release;
            derive_channels(ms, ii, g, x, p, q, r, l, v, w, et, er, ep, ot, qn, tp, tl, te,
                            stretched);
        },
        nb::arg("mass"), nb::arg("inv_inertia"), nb::arg("gravity"), nb::arg("position"),
        nb::arg("linear_momentum"), nb::arg("quat_wxyz"), nb::arg("rotation"),
        nb::arg("angular_momentum"), nb::arg("velocity"), nb::arg("omega"), nb::arg("e_trans"),
        nb::arg("e_rot"), nb::arg("e_pot"), nb::arg("ortho"), nb::arg("qnorm"),
        nb::arg("total_p"), nb::arg("total_l"), nb::arg("total_e"), nb::arg("stretched") = false,
        "Derived channels of T samples x N bodies, written into the outputs (see "
        "rblog.contract.derive). Releases the GIL.");
}

}  // namespace rb
