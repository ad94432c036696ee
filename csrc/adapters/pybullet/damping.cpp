// Bullet's multibody damping as impulses (btMultiBody.cpp,
// computeAccelerationsArticulatedBodyAlgorithmMultiDof): a link of mass m, principal moments I
// (its inertial frame, rotation R = the link's orientation) and velocities v, w (world) at the
// start of a step of dt receives the force -m v (k_l + k_l |v|) and the torque
// -R I R^T w (k_a + k_a |w|). Here c_lin = m k_l dt and c_ang = k_a dt per row, so the impulses
// are -c_lin (1 + |v|) v and -c_ang (1 + |w|) R I R^T w, subtracted from lin and ang.
// Their work over the step, added to work (N,): impulse . (v + v1) / 2 + angular impulse .
// (w + w1) / 2, with v1, w1 the velocities at the step's end. A semi-implicit step changes the
// kinetic energy by (u0 + u1)/2 . M (u1 - u0) (M over the step constant), and M (u1 - u0) is the
// sum of the step's generalized impulses, so each one's work is taken at the mean velocity
// (docs/log-format.md, "Work and the discrete energy").
#include <nanobind/nanobind.h>

#include <cmath>

#include "common/py.hpp"

namespace rb {
namespace nb = nanobind;

static void damping(nb::handle q_h, nb::handle v_h, nb::handle w_h, nb::handle v1_h,
                    nb::handle w1_h, nb::handle inertia_h, nb::handle c_lin_h, nb::handle c_ang_h,
                    nb::handle lin_h, nb::handle ang_h, nb::handle work_h) {
    V2<double> q = v2<double>(q_h, "q_xyzw"), v = v2<double>(v_h, "v"), w = v2<double>(w_h, "w");
    V2<double> v_end = v2<double>(v1_h, "v1"), w_end = v2<double>(w1_h, "w1");
    V1<double> work = v1<double>(work_h, "work");
    V2<double> inertia = v2<double>(inertia_h, "inertia");
    V1<double> c_lin = v1<double>(c_lin_h, "c_lin"), c_ang = v1<double>(c_ang_h, "c_ang");
    V2<double> lin = v2<double>(lin_h, "lin"), ang = v2<double>(ang_h, "ang");
    const i64 n = v.n0;
    if (q.n0 != n || q.n1 != 4 || w.n0 != n || inertia.n0 != n || c_lin.n0 != n || c_ang.n0 != n ||
        lin.n0 != n || ang.n0 != n || v.n1 != 3 || w.n1 != 3 || inertia.n1 != 3 || lin.n1 != 3 ||
        ang.n1 != 3 || v_end.n0 != n || v_end.n1 != 3 || w_end.n0 != n || w_end.n1 != 3 ||
        work.n0 != n)
        throw nb::type_error("damping: q (N, 4), v, w, v1, w1, inertia, lin, ang (N, 3), c_lin, "
                             "c_ang, work (N,)");
    for (i64 i = 0; i < n; ++i) {
        const double* vi = v.row(i);
        const double sv = std::sqrt(vi[0] * vi[0] + vi[1] * vi[1] + vi[2] * vi[2]);
        const double cl = c_lin(i) * (1.0 + sv);
        const double* vb = v_end.row(i);
        double wk = 0.0;
        for (int c = 0; c < 3; ++c) {
            lin(i, c) -= cl * vi[c];
            wk -= cl * vi[c] * 0.5 * (vi[c] + vb[c]);
        }
        if (c_ang(i) == 0.0) {
            work(i) += wk;
            continue;
        }
        const double x = q(i, 0), y = q(i, 1), z = q(i, 2), s = q(i, 3);
        const double r[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * s), 2 * (x * z + y * s)},
                                {2 * (x * y + z * s), 1 - 2 * (x * x + z * z), 2 * (y * z - x * s)},
                                {2 * (x * z - y * s), 2 * (y * z + x * s), 1 - 2 * (x * x + y * y)}};
        const double* wi = w.row(i);
        const double sw = std::sqrt(wi[0] * wi[0] + wi[1] * wi[1] + wi[2] * wi[2]);
        double lb[3];  // I R^T w: the angular momentum in the link's frame
        for (int a = 0; a < 3; ++a)
            lb[a] = inertia(i, a) * (r[0][a] * wi[0] + r[1][a] * wi[1] + r[2][a] * wi[2]);
        const double ca = c_ang(i) * (1.0 + sw);
        const double* wb = w_end.row(i);
        for (int a = 0; a < 3; ++a) {
            const double t = ca * (r[a][0] * lb[0] + r[a][1] * lb[1] + r[a][2] * lb[2]);
            ang(i, a) -= t;
            wk -= t * 0.5 * (wi[a] + wb[a]);
        }
        work(i) += wk;
    }
}

void bind_pybullet_damping(nb::module_& m) {
    m.def("pybullet_damping", &damping, nb::arg("q_xyzw"), nb::arg("v"), nb::arg("w"),
          nb::arg("v1"), nb::arg("w1"), nb::arg("inertia"), nb::arg("c_lin"), nb::arg("c_ang"),
          nb::arg("lin"), nb::arg("ang"), nb::arg("work"),
          "Subtract Bullet's multibody damping impulses from lin, ang (N, 3), world frame, and add "
          "their work at the step's mean velocity to work (N,) (see "
          "csrc/adapters/pybullet/damping.cpp).");
}

}  // namespace rb
