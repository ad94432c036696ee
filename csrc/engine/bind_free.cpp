// Bindings of the free-body kernels (free.cpp) and of the rotation / integrator / exact-flow
// functions Python calls directly (rblog/engine/{rotation,integrators,exact,free}.py wrap them
// under their Python names, same arguments); and the engine tolerances, read from
// rblog/engine/constants.py (their one home) when the module is imported.
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "common/py.hpp"
#include "engine/bind.hpp"
#include "engine/exact.hpp"
#include "engine/free.hpp"
#include "engine/free_constants.hpp"
#include "engine/integrators.hpp"
#include "engine/lanes.hpp"

namespace rb {
namespace nb = nanobind;

FreeConstants free_constants;

static void load_free_constants() {
    nb::module_ c = nb::module_::import_("rblog.engine.constants");
    free_constants.polar_tol = nb::cast<double>(c.attr("POLAR_TOL"));
    free_constants.polar_max_iter = nb::cast<int>(c.attr("POLAR_MAX_ITER"));
    free_constants.max_rotation_per_step_rad = nb::cast<double>(c.attr("MAX_ROTATION_PER_STEP_RAD"));
    free_constants.landen_base_parameter = nb::cast<double>(c.attr("LANDEN_BASE_PARAMETER"));
    free_constants.landen_max_levels = nb::cast<int>(c.attr("LANDEN_MAX_LEVELS"));
    free_constants.carlson_series_tol = nb::cast<double>(c.attr("CARLSON_SERIES_TOL"));
    if (free_constants.landen_max_levels > N_LANDEN)
        throw std::runtime_error("LANDEN_MAX_LEVELS exceeds the flow row's mu slots (exact.N_FLOW)");
}

static void check_body(i64 i, i64 n, const char* what) {
    if (i < 0 || i >= n)
        throw nb::index_error((std::string(what) + " " + std::to_string(i) + " out of range for " +
                               std::to_string(n) + " bodies").c_str());
}

static void check_rows(const char* name, i64 rows, i64 need) {
    if (rows < need)
        throw nb::value_error((std::string(name) + ": " + std::to_string(rows) +
                               " rows, need " + std::to_string(need)).c_str());
}

// The advance_free / advance_free_range arguments as views, shapes checked against N bodies.
static FreeArgs free_args(int ortho, double dt, i64 n_steps, i64 stride, bool sample_last,
                          nb::handle inv_mass, nb::handle inv_inertia, nb::handle force_world,
                          nb::handle torque_world, nb::handle position, nb::handle linear_momentum,
                          nb::handle quat_wxyz, nb::handle rotation, nb::handle angular_momentum,
                          nb::handle out_position, nb::handle out_linear_momentum,
                          nb::handle out_quat_wxyz, nb::handle out_rotation,
                          nb::handle out_angular_momentum, nb::handle anchors, i64 tile) {
    FreeArgs a;
    a.ortho = ortho;
    a.dt = dt;
    a.n_steps = n_steps;
    a.stride = stride;
    a.sample_last = sample_last;
    a.tile = tile;
    if (stride < 1) throw nb::value_error("stride must be >= 1");
    if (tile < 1) throw nb::value_error("tile must be >= 1");
    a.inv_mass = v1<double>(inv_mass, "inv_mass");
    a.inv_inertia = v2<double>(inv_inertia, "inv_inertia");
    a.force_world = v2<double>(force_world, "force_world");
    a.torque_world = v2<double>(torque_world, "torque_world");
    a.position = v2<double>(position, "position");
    a.linear_momentum = v2<double>(linear_momentum, "linear_momentum");
    a.quat_wxyz = v2<double>(quat_wxyz, "quat_wxyz");
    a.rotation = v3<double>(rotation, "rotation");
    a.angular_momentum = v2<double>(angular_momentum, "angular_momentum");
    a.out_position = v3<double>(out_position, "out_position");
    a.out_linear_momentum = v3<double>(out_linear_momentum, "out_linear_momentum");
    a.out_quat_wxyz = v3<double>(out_quat_wxyz, "out_quat_wxyz");
    a.out_rotation = v4<double>(out_rotation, "out_rotation");
    a.out_angular_momentum = v3<double>(out_angular_momentum, "out_angular_momentum");
    a.a_q = f2<double>(anchors, "anchor_quat_wxyz");
    a.a_l = f2<double>(anchors, "anchor_L_world");
    a.a_n = f1<i64>(anchors, "anchor_steps");
    a.a_dt = f1<double>(anchors, "anchor_dt_s");
    const i64 n = a.position.n0;
    const bool shapes_ok =
        a.inv_mass.n0 == n && a.inv_inertia.n0 == n && a.inv_inertia.n1 == 3 &&
        a.force_world.n0 == n && a.force_world.n1 == 3 && a.torque_world.n0 == n &&
        a.torque_world.n1 == 3 && a.position.n1 == 3 && a.linear_momentum.n0 == n &&
        a.linear_momentum.n1 == 3 && a.quat_wxyz.n0 == n && a.quat_wxyz.n1 == 4 &&
        a.rotation.n0 == n && a.rotation.n1 == 3 && a.rotation.n2 == 3 &&
        a.angular_momentum.n0 == n && a.angular_momentum.n1 == 3 && a.a_q.n0 == n &&
        a.a_q.n1 == 4 && a.a_l.n0 == n && a.a_l.n1 == 3 && a.a_n.n0 == n && a.a_dt.n0 == n;
    if (!shapes_ok) throw nb::value_error("advance_free: state and parameter arrays must be (N, ...) for the same N");
    const bool out_ok =
        a.out_position.n1 == n && a.out_position.n2 == 3 && a.out_linear_momentum.n1 == n &&
        a.out_linear_momentum.n2 == 3 && a.out_quat_wxyz.n1 == n && a.out_quat_wxyz.n2 == 4 &&
        a.out_rotation.n1 == n && a.out_rotation.n2 == 3 && a.out_rotation.n3 == 3 &&
        a.out_angular_momentum.n1 == n && a.out_angular_momentum.n2 == 3;
    if (!out_ok) throw nb::value_error("advance_free: out_* buffers must be (S, N, ...)");
    const i64 need = n_steps > 0 ? n_steps / stride + ((sample_last && n_steps % stride) ? 1 : 0) : 0;
    check_rows("out_position", a.out_position.n0, need);
    check_rows("out_linear_momentum", a.out_linear_momentum.n0, need);
    check_rows("out_quat_wxyz", a.out_quat_wxyz.n0, need);
    check_rows("out_rotation", a.out_rotation.n0, need);
    check_rows("out_angular_momentum", a.out_angular_momentum.n0, need);
    return a;
}

static nb::tuple result_tuple(const FreeResult& r) {
    return nb::make_tuple(r.n_samples, r.bad_step, r.bad_body);
}

static void check_method(int method) {
    if (method < METHOD_SEED || method > METHOD_EXACT4)
        throw nb::value_error(("unknown integrator code " + std::to_string(method)).c_str());
}

void bind_free(nb::module_& m) {
    load_free_constants();

    m.attr("N_FLOW") = N_FLOW;
    m.attr("FC_RJC") = FC_RJC;
    m.attr("YOSHIDA_W1") = yoshida_w1();
    m.attr("YOSHIDA_W0") = yoshida_w0();

    // ---- free-body kernels ------------------------------------------------------------------
    m.def("free_lanes", &free_lanes,
          "Bodies per vector in the free kernel's sparse path: 4 (AVX2) or 2 (lanes.hpp).");
    m.def("set_free_lanes", &set_free_lanes, nb::arg("lanes"),
          "Use 2 or (on a CPU with AVX2) 4 lanes in the free kernel's sparse path; the results "
          "are bitwise the same (tests compare them).");
    m.def(
        "advance_free",
        [](int method, int ortho, double dt, i64 n_steps, i64 stride, bool sample_last,
           nb::handle inv_mass, nb::handle inv_inertia, nb::handle force_world,
           nb::handle torque_world, nb::handle position, nb::handle linear_momentum,
           nb::handle quat_wxyz, nb::handle rotation, nb::handle angular_momentum,
           nb::handle out_position, nb::handle out_linear_momentum, nb::handle out_quat_wxyz,
           nb::handle out_rotation, nb::handle out_angular_momentum, nb::handle anchors,
           std::vector<std::pair<i64, i64>> ranges, i64 tile) {
            check_method(method);
            FreeArgs a = free_args(ortho, dt, n_steps, stride, sample_last, inv_mass, inv_inertia,
                                   force_world, torque_world, position, linear_momentum,
                                   quat_wxyz, rotation, angular_momentum, out_position,
                                   out_linear_momentum, out_quat_wxyz, out_rotation,
                                   out_angular_momentum, anchors, tile);
            for (const auto& r : ranges)
                if (r.first < 0 || r.second > a.position.n0 || r.first > r.second)
                    throw nb::value_error("advance_free: a body range out of bounds");
            FreeResult res;
            {
                nb::gil_scoped_release release;
                res = advance_free(method, a, ranges);
            }
            return result_tuple(res);
        },
        "Advance the bodies of `ranges` ((b0, b1) pairs, one pool task each) n_steps steps "
        "(rblog.engine.free.advance_free). Returns (n_samples, bad_step, bad_body).");
    m.def(
        "advance_free_range",
        [](int method, int ortho, double dt, i64 n_steps, i64 stride, bool sample_last,
           nb::handle inv_mass, nb::handle inv_inertia, nb::handle force_world,
           nb::handle torque_world, nb::handle position, nb::handle linear_momentum,
           nb::handle quat_wxyz, nb::handle rotation, nb::handle angular_momentum,
           nb::handle out_position, nb::handle out_linear_momentum, nb::handle out_quat_wxyz,
           nb::handle out_rotation, nb::handle out_angular_momentum, nb::handle anchors, i64 b0,
           i64 b1, i64 tile) {
            check_method(method);
            FreeArgs a = free_args(ortho, dt, n_steps, stride, sample_last, inv_mass, inv_inertia,
                                   force_world, torque_world, position, linear_momentum,
                                   quat_wxyz, rotation, angular_momentum, out_position,
                                   out_linear_momentum, out_quat_wxyz, out_rotation,
                                   out_angular_momentum, anchors, tile);
            if (b0 < 0 || b1 > a.position.n0 || b0 > b1)
                throw nb::value_error("advance_free_range: body range out of bounds");
            FreeResult res;
            {
                nb::gil_scoped_release release;
                res = advance_free_range(method, a, b0, b1);
            }
            return result_tuple(res);
        },
        "Advance bodies b0 .. b1-1 on the calling thread (rblog.engine.free.advance_free_range).");

    // ---- integrators (what the contact step uses per body) -------------------------------
    m.def(
        "drift_rotation",
        [](int method, int ortho, nb::handle quat_wxyz, nb::handle rotation,
           nb::handle angular_momentum, nb::handle inv_inertia, i64 i, double h, double tx,
           double ty, double tz) {
            check_method(method);
            V2<double> q = v2<double>(quat_wxyz, "quat_wxyz");
            V3<double> r = v3<double>(rotation, "rotation");
            V2<double> l = v2<double>(angular_momentum, "angular_momentum");
            V2<double> k = v2<double>(inv_inertia, "inv_inertia");
            check_body(i, q.n0, "body");
            check_body(i, r.n0, "body");
            check_body(i, l.n0, "body");
            check_body(i, k.n0, "body");
            drift_rotation(method, ortho, q, r, l, k, i, h, tx, ty, tz);
        },
        nb::arg("method"), nb::arg("ortho"), nb::arg("quat_wxyz"), nb::arg("rotation"),
        nb::arg("angular_momentum"), nb::arg("inv_inertia"), nb::arg("i"), nb::arg("h"),
        nb::arg("tx") = 0.0, nb::arg("ty") = 0.0, nb::arg("tz") = 0.0);
    m.def(
        "drift_exact_anchored",
        [](nb::handle quat_wxyz, nb::handle rotation, nb::handle angular_momentum,
           nb::handle inv_inertia, i64 i, double h, nb::handle anchor_quat_wxyz,
           nb::handle anchor_L_world, nb::handle anchor_steps, nb::handle anchor_dt_s,
           nb::handle fc, i64 r, nb::handle fc_ok) {
            V2<double> q = v2<double>(quat_wxyz, "quat_wxyz");
            V3<double> rot = v3<double>(rotation, "rotation");
            V2<double> l = v2<double>(angular_momentum, "angular_momentum");
            V2<double> k = v2<double>(inv_inertia, "inv_inertia");
            V2<double> aq = v2<double>(anchor_quat_wxyz, "anchor_quat_wxyz");
            V2<double> al = v2<double>(anchor_L_world, "anchor_L_world");
            V1<i64> an = v1<i64>(anchor_steps, "anchor_steps");
            V1<double> adt = v1<double>(anchor_dt_s, "anchor_dt_s");
            V2<double> f = v2<double>(fc, "fc");
            V1<bool> ok = v1<bool>(fc_ok, "fc_ok");
            for (i64 n : {q.n0, rot.n0, l.n0, k.n0, aq.n0, al.n0, an.n0, adt.n0})
                check_body(i, n, "body");
            check_body(r, f.n0, "fc row");
            check_body(r, ok.n0, "fc_ok row");
            if (f.n1 != N_FLOW) throw nb::value_error("fc: expected (rows, N_FLOW)");
            drift_exact_anchored(q, rot, l, k, i, h, aq, al, an, adt, f, r, ok);
        });
    m.def(
        "sync_quat",
        [](int method, nb::handle quat_wxyz, nb::handle rotation, i64 i) {
            V2<double> q = v2<double>(quat_wxyz, "quat_wxyz");
            V3<double> r = v3<double>(rotation, "rotation");
            check_body(i, q.n0, "body");
            check_body(i, r.n0, "body");
            sync_quat(method, q, r, i);
        });
    m.def(
        "turn_within_bound",
        [](double dt, i64 i, nb::handle inv_inertia, nb::handle rotation,
           nb::handle angular_momentum) {
            V2<double> k = v2<double>(inv_inertia, "inv_inertia");
            V3<double> r = v3<double>(rotation, "rotation");
            V2<double> l = v2<double>(angular_momentum, "angular_momentum");
            check_body(i, k.n0, "body");
            check_body(i, r.n0, "body");
            check_body(i, l.n0, "body");
            return turn_within_bound(dt, i, k, r, l);
        });
    m.def(
        "write_sample",
        [](int method, i64 j, i64 i, nb::handle position, nb::handle linear_momentum,
           nb::handle quat_wxyz, nb::handle rotation, nb::handle angular_momentum,
           nb::handle out_position, nb::handle out_linear_momentum, nb::handle out_quat_wxyz,
           nb::handle out_rotation, nb::handle out_angular_momentum) {
            V3<double> op = v3<double>(out_position, "out_position");
            V3<double> om = v3<double>(out_linear_momentum, "out_linear_momentum");
            V3<double> oq = v3<double>(out_quat_wxyz, "out_quat_wxyz");
            V4<double> orr = v4<double>(out_rotation, "out_rotation");
            V3<double> ol = v3<double>(out_angular_momentum, "out_angular_momentum");
            V2<double> p = v2<double>(position, "position");
            check_body(i, p.n0, "body");
            check_body(j, op.n0, "sample row");
            write_sample(method, j, i, p, v2<double>(linear_momentum, "linear_momentum"),
                         v2<double>(quat_wxyz, "quat_wxyz"), v3<double>(rotation, "rotation"),
                         v2<double>(angular_momentum, "angular_momentum"), op, om, oq, orr, ol);
        });

    // ---- exact flow ------------------------------------------------------------------------
    m.def("sncndn", [](double u, double m_, double m1) {
        const SnCnDn r = sncndn(u, m_, m1);
        return nb::make_tuple(r.sn, r.cn, r.dn, r.j, r.big_k);
    });
    m.def("landen_descent", [](double m_, double m1) {
        const Landen d = landen_descent(m_, m1);
        return nb::make_tuple(d.lev, d.scale, d.m, d.mu[0], d.mu[1], d.mu[2], d.mu[3], d.mu[4],
                              d.mu[5], d.mu[6], d.mu[7], d.mu[8], d.mu[9], d.mu[10], d.mu[11]);
    });
    m.def("carlson_rf_rj", [](double x, double y, double z, double p) {
        double rf, rj;
        carlson_rf_rj(x, y, z, p, rf, rj);
        return nb::make_tuple(rf, rj);
    });
    m.def("carlson_rj1", [](double x, double y, double p) { return carlson_rj1(x, y, p); });
    m.def("flow_constants", [](nb::handle fc, i64 r, double b0, double b1, double b2, double k0,
                               double k1, double k2) {
        V2<double> f = v2<double>(fc, "fc");
        check_body(r, f.n0, "fc row");
        if (f.n1 != N_FLOW) throw nb::value_error("fc: expected (rows, N_FLOW)");
        flow_constants(f, r, b0, b1, b2, k0, k1, k2);
    });
    m.def("flow_rotation", [](nb::handle fc, i64 r, double t) {
        V2<double> f = v2<double>(fc, "fc");
        check_body(r, f.n0, "fc row");
        if (f.n1 != N_FLOW) throw nb::value_error("fc: expected (rows, N_FLOW)");
        double o[7];
        flow_rotation(f, r, t, o);
        return nb::make_tuple(o[0], o[1], o[2], o[3], o[4], o[5], o[6]);
    });
    m.def("free_flow_body", [](double b0, double b1, double b2, double k0, double k1, double k2,
                               double h) {
        double o[7];
        free_flow_body(b0, b1, b2, k0, k1, k2, h, o);
        return nb::make_tuple(o[0], o[1], o[2], o[3], o[4], o[5], o[6]);
    });
    m.def("free_flow_quat", [](double w, double x, double y, double z, double lx, double ly,
                               double lz, double k0, double k1, double k2, double h) {
        double o[4];
        free_flow_quat(w, x, y, z, lx, ly, lz, k0, k1, k2, h, o);
        return nb::make_tuple(o[0], o[1], o[2], o[3]);
    });
    // the one-step exact map repeated n_steps times from (q, L), q every stride steps (first row:
    // q0): what tests/engine/test_exact.py steps (it was a numba loop there)
    m.def("free_flow_quat_run", [](double w, double x, double y, double z, double lx, double ly,
                                   double lz, double k0, double k1, double k2, double h,
                                   i64 n_steps, i64 stride) {
        if (stride < 1) throw nb::value_error("stride must be >= 1");
        std::vector<double> out;
        out.reserve(static_cast<size_t>(4 * (n_steps / stride + 1)));
        out.insert(out.end(), {w, x, y, z});
        double q[4] = {w, x, y, z};
        for (i64 s = 1; s <= n_steps; ++s) {
            double o[4];
            free_flow_quat(q[0], q[1], q[2], q[3], lx, ly, lz, k0, k1, k2, h, o);
            q[0] = o[0]; q[1] = o[1]; q[2] = o[2]; q[3] = o[3];
            if (s % stride == 0) out.insert(out.end(), {q[0], q[1], q[2], q[3]});
        }
        const size_t rows = out.size() / 4;
        return to_numpy<double>(std::move(out), {rows, 4});
    });

    // ---- rotation math (scalars and tuples, as rotation.py's) -------------------------------
    m.def("quat_mul", [](double aw, double ax, double ay, double az, double bw, double bx,
                         double by, double bz) {
        const Quat q = quat_mul(aw, ax, ay, az, bw, bx, by, bz);
        return nb::make_tuple(q[0], q[1], q[2], q[3]);
    });
    auto mat_tuple = [](const Mat3& a) {
        return nb::make_tuple(a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8]);
    };
    auto to_mat = [](nb::handle t) {
        Mat3 a;
        for (size_t k = 0; k < 9; ++k) a[k] = nb::cast<double>(t[k]);
        return a;
    };
    m.def("quat_to_mat", [mat_tuple](double w, double x, double y, double z) {
        return mat_tuple(quat_to_mat(w, x, y, z));
    });
    m.def("mat_to_quat", [to_mat](nb::handle mm) {
        const Quat q = mat_to_quat(to_mat(mm));
        return nb::make_tuple(q[0], q[1], q[2], q[3]);
    });
    m.def("omega_world", [to_mat](nb::handle mm, double i0, double i1, double i2, double lx,
                                  double ly, double lz) {
        const Vec3 o = omega_world(to_mat(mm), i0, i1, i2, lx, ly, lz);
        return nb::make_tuple(o[0], o[1], o[2]);
    });
    m.def("omega_world_stretched", [to_mat](nb::handle mm, double i0, double i1, double i2,
                                            double lx, double ly, double lz) {
        const Vec3 o = omega_world_stretched(to_mat(mm), i0, i1, i2, lx, ly, lz);
        return nb::make_tuple(o[0], o[1], o[2]);
    });
    m.def("polar", [to_mat, mat_tuple](nb::handle mm) { return mat_tuple(polar(to_mat(mm))); });
    m.def("gram_schmidt", [to_mat, mat_tuple](nb::handle mm) {
        return mat_tuple(gram_schmidt(to_mat(mm)));
    });
    m.def("normalize4", [](double w, double x, double y, double z) {
        const Quat q = normalize4(w, x, y, z);
        return nb::make_tuple(q[0], q[1], q[2], q[3]);
    });
}

}  // namespace rb
