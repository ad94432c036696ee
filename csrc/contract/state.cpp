// The state a writer gives (quaternion, velocities) turned into the state the log holds
// (rotation, momenta), T samples x N bodies in one pass: what rblog.Recorder derives when an
// engine hands it q, v and w (rblog/record/recorder.py, build_block).
//
// Per body i of sample t, with m its mass, I its principal moments (body frame) and q the
// writer's quaternion (w, x, y, z):
//
//   q_hat = q / |q|                                  (|q| = 0: q as given)
//   R     = the rotation of q_hat (body to world)    (orientation.quat_wxyz_to_matrix's formula)
//   P     = m v
//   L     = R (I * (R^T omega))                      (world, about the centre of mass)
//
// Inputs and outputs (T, N, ...) float64 C-contiguous, outputs preallocated.
#include <nanobind/nanobind.h>

#include <cmath>

#include "common/py.hpp"

namespace rb {

void state_from_velocities(V1<double> mass, V2<double> inertia, V3<double> quat_wxyz,
                           V3<double> velocity, V3<double> omega, V4<double> rotation,
                           V3<double> linear_momentum, V3<double> angular_momentum) {
    const i64 n_t = quat_wxyz.n0, n_b = quat_wxyz.n1;
    for (i64 t = 0; t < n_t; ++t) {
        for (i64 i = 0; i < n_b; ++i) {
            const double* q = &quat_wxyz(t, i, 0);
            double nq = std::sqrt(((q[0] * q[0] + q[1] * q[1]) + q[2] * q[2]) + q[3] * q[3]);
            double s = nq > 0.0 ? nq : 1.0;
            double w = q[0] / s, x = q[1] / s, y = q[2] / s, z = q[3] / s;
            double r[3][3] = {
                {1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}};
            const double* om = &omega(t, i, 0);
            const double* v = &velocity(t, i, 0);
            double wb[3];
            for (int k = 0; k < 3; ++k)  // I * (R^T omega): body frame
                wb[k] = inertia(i, k) * ((r[0][k] * om[0] + r[1][k] * om[1]) + r[2][k] * om[2]);
            for (int a = 0; a < 3; ++a) {
                for (int b = 0; b < 3; ++b) rotation(t, i, a, b) = r[a][b];
                linear_momentum(t, i, a) = mass[i] * v[a];
                angular_momentum(t, i, a) = (r[a][0] * wb[0] + r[a][1] * wb[1]) + r[a][2] * wb[2];
            }
        }
    }
}

void bind_state(nanobind::module_& m) {
    namespace nb = nanobind;
    m.def(
        "state_from_velocities",
        [](nb::handle mass, nb::handle inertia, nb::handle quat_wxyz, nb::handle velocity,
           nb::handle omega, nb::handle rotation, nb::handle linear_momentum,
           nb::handle angular_momentum) {
            auto ms = v1<double>(mass, "mass");
            auto in = v2<double>(inertia, "inertia");
            auto q = v3<double>(quat_wxyz, "quat_wxyz");
            auto v = v3<double>(velocity, "velocity");
            auto w = v3<double>(omega, "omega");
            auto r = v4<double>(rotation, "rotation");
            auto p = v3<double>(linear_momentum, "linear_momentum");
            auto l = v3<double>(angular_momentum, "angular_momentum");
            const i64 T = q.n0, N = q.n1;
            bool ok = q.n2 == 4 && ms.n0 >= N && in.n0 >= N && in.n1 == 3;
            for (auto* a : {&v, &w, &p, &l}) ok = ok && a->n0 == T && a->n1 == N && a->n2 == 3;
            ok = ok && r.n0 == T && r.n1 == N && r.n2 == 3 && r.n3 == 3;
            if (!ok) throw nb::value_error("state_from_velocities: arrays of mismatched shapes");
            nb::gil_scoped_release release;
            state_from_velocities(ms, in, q, v, w, r, p, l);
        },
        "R, P and L (T, N, ...) from quaternions, velocities and world angular velocities, "
        "written into the outputs (see csrc/contract/state.cpp). Releases the GIL.");
}

}  // namespace rb
