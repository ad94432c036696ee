// The integrators' non-inline entry points (rblog/engine/integrators.py), used by the contact
// step for every body and by the tests through the bindings (bind_free.cpp). The stages
// themselves are inline in integrators.hpp.
#include "engine/integrators.hpp"

namespace rb {

void drift_rotation(int method, int ortho, V2<double> quat_wxyz, V3<double> rotation,
                    V2<double> angular_momentum, V2<double> inv_inertia, i64 i, double h,
                    double tx, double ty, double tz) {
    if (method == METHOD_SEED)
        drift_seed(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h);
    else if (method == METHOD_SEED_QUAT)
        drift_seed_quat(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h);
    else if (method == METHOD_SPLITTING)
        drift_splitting(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h);
    else if (method == METHOD_EXACT || method == METHOD_EXACT4)
        drift_exact(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h);
    else
        drift_rk4(ortho, quat_wxyz, rotation, angular_momentum, inv_inertia, i, h, tx, ty, tz);
}

// The exact torque-free rotation over h (L world fixed), evaluated from body i's anchor (the
// arrays of a rblog.engine.state.FlowAnchors) at the elapsed time (anchor_steps + 1) h: no
// rounding is carried from step to step (exact.cpp).
//
// The anchor is valid while anchor_steps >= 0, L equals anchor_L_world bitwise and h equals
// anchor_dt_s; otherwise the current (q, L) becomes the anchor (so a torque kick or a contact
// impulse, which change L, start a new one). Row r of fc ((rows, N_FLOW)) caches the anchor's
// flow constants within a call: fc_ok[r] says they are the current anchor's (the caller clears it
// when the row is given to another body); a new anchor recomputes them. The free-body kernel of
// the exact integrators does the same arithmetic written out (free.cpp; bitwise equal,
// tests/engine/test_exact_anchored.py).
void drift_exact_anchored(V2<double> quat_wxyz, V3<double> rotation, V2<double> angular_momentum,
                          V2<double> inv_inertia, i64 i, double h, V2<double> anchor_quat_wxyz,
                          V2<double> anchor_L_world, V1<i64> anchor_steps, V1<double> anchor_dt_s,
                          V2<double> fc, i64 r, V1<bool> fc_ok) {
    const double lx = angular_momentum(i, 0), ly = angular_momentum(i, 1), lz = angular_momentum(i, 2);
    if (!anchor_holds(anchor_steps[i], anchor_dt_s[i], anchor_L_world(i, 0), anchor_L_world(i, 1),
                      anchor_L_world(i, 2), h, lx, ly, lz)) {
        for (int k = 0; k < 4; ++k) anchor_quat_wxyz(i, k) = quat_wxyz(i, k);
        anchor_L_world(i, 0) = lx; anchor_L_world(i, 1) = ly; anchor_L_world(i, 2) = lz;
        anchor_steps[i] = 0;
        anchor_dt_s[i] = h;
        fc_ok[r] = false;
    }
    const double aw = anchor_quat_wxyz(i, 0), ax = anchor_quat_wxyz(i, 1),
                 ay = anchor_quat_wxyz(i, 2), az = anchor_quat_wxyz(i, 3);
    double* row = fc.row(r);
    if (!fc_ok[r]) {
        anchor_constants(row, aw, ax, ay, az, lx, ly, lz, inv_inertia(i, 0), inv_inertia(i, 1),
                         inv_inertia(i, 2), h);
        fc_ok[r] = true;
    }
    const i64 n = anchor_steps[i] + 1;
    double rj_c;
    const Quat q = anchored_quat(row, aw, ax, ay, az, static_cast<double>(n) * std::fabs(h),
                                 quat_wxyz(i, 0), quat_wxyz(i, 1), quat_wxyz(i, 2),
                                 quat_wxyz(i, 3), rj_c);
    if (rj_c >= 0.0 && row[FC_RJC] < 0.0) row[FC_RJC] = rj_c;
    anchor_steps[i] = n;
    store_quat(quat_wxyz, i, q[0], q[1], q[2], q[3]);
    store_mat(rotation, i, quat_to_mat(q[0], q[1], q[2], q[3]));
}

void sync_quat(int method, V2<double> quat_wxyz, V3<double> rotation, i64 i) {
    if (method == METHOD_SEED) sync_quat_seed(quat_wxyz, rotation, i);
}

bool turn_within_bound(double dt, i64 i, V2<double> inv_inertia, V3<double> rotation,
                       V2<double> angular_momentum) {
    return turn_within_bound_m(dt, inv_inertia(i, 0), inv_inertia(i, 1), inv_inertia(i, 2),
                               angular_momentum(i, 0), angular_momentum(i, 1),
                               angular_momentum(i, 2), load_mat(rotation, i));
}

void write_sample(int method, i64 j, i64 i, V2<double> position, V2<double> linear_momentum,
                  V2<double> quat_wxyz, V3<double> rotation, V2<double> angular_momentum,
                  V3<double> out_position, V3<double> out_linear_momentum,
                  V3<double> out_quat_wxyz, V4<double> out_rotation,
                  V3<double> out_angular_momentum) {
    if (method == METHOD_SEED)
        write_sample_t<METHOD_SEED>(j, i, position, linear_momentum, quat_wxyz, rotation,
                                    angular_momentum, out_position, out_linear_momentum,
                                    out_quat_wxyz, out_rotation, out_angular_momentum);
    else
        write_sample_t<METHOD_SPLITTING>(j, i, position, linear_momentum, quat_wxyz, rotation,
                                         angular_momentum, out_position, out_linear_momentum,
                                         out_quat_wxyz, out_rotation, out_angular_momentum);
}

}  // namespace rb
