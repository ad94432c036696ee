// Bindings of the audit kernels (audit.hpp): arrays are taken as views over the numpy buffers
// (common/py.hpp: a wrong dtype, shape or layout is a TypeError naming the argument), with the GIL
// held; the kernel then runs with the GIL released, so analyzers in threads run in parallel.
// Outputs are written in place into the arrays Python passes, as the numba kernels did.
#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>  // (common/py.hpp's error message casts to std::string)
#include <nanobind/stl/tuple.h>

#include <cstdint>
#include <string>
#include <vector>

#include "audit/audit.hpp"
#include "audit/shapes.hpp"
#include "common/py.hpp"

namespace rb {
namespace nb = nanobind;
using nb::handle;
using std::int8_t;

// Inputs are taken read-only: a log read from an .rrd holds immutable (Arrow-backed) arrays, which
// the numba kernels read as they were. The kernels never write an input, so the view's pointer
// drops the const (the V* views have one element type for inputs and outputs). Outputs go through
// v1..v4 (common/py.hpp), which require a writable array.
template <class T>
using CIn = nb::ndarray<const T, nb::c_contig, nb::device::cpu>;

template <class T>
CIn<T> in_array(nb::handle h, const char* name, size_t ndim) {
    CIn<T> a;
    if (!nb::try_cast(h, a, false) || a.ndim() != ndim) {
        nb::str got = nb::str(nb::getattr(h, "dtype", nb::none()));
        nb::str shape = nb::str(nb::getattr(h, "shape", nb::none()));
        throw nb::type_error((std::string(name) + ": expected a C-contiguous " + dtype_name<T>() +
                              " array of " + std::to_string(ndim) + " dimensions, got dtype " +
                              got.c_str() + ", shape " + shape.c_str())
                                 .c_str());
    }
    return a;
}
template <class T> V1<T> in1(nb::handle h, const char* name) {
    auto a = in_array<T>(h, name, 1);
    return V1<T>{const_cast<T*>(a.data()), (i64)a.shape(0)};
}
template <class T> V2<T> in2(nb::handle h, const char* name) {
    auto a = in_array<T>(h, name, 2);
    return V2<T>{const_cast<T*>(a.data()), (i64)a.shape(0), (i64)a.shape(1)};
}
template <class T> V3<T> in3(nb::handle h, const char* name) {
    auto a = in_array<T>(h, name, 3);
    return V3<T>{const_cast<T*>(a.data()), (i64)a.shape(0), (i64)a.shape(1), (i64)a.shape(2)};
}
template <class T> V4<T> in4(nb::handle h, const char* name) {
    auto a = in_array<T>(h, name, 4);
    return V4<T>{const_cast<T*>(a.data()), (i64)a.shape(0), (i64)a.shape(1), (i64)a.shape(2),
                 (i64)a.shape(3)};
}


void bind_audit(nb::module_& m) {
    using namespace rb::audit;
    m.attr("SHAPE_SPHERE") = SHAPE_SPHERE;
    m.attr("SHAPE_BOX") = SHAPE_BOX;

    // --- geometry.cpp
    m.def("plane_kernel", [](handle position, handle rotation, handle is_sphere, handle size,
                             handle n, double offset, handle sep, handle height) {
        auto a = in3<double>(position, "position");
        auto b = in4<double>(rotation, "rotation");
        auto c = in1<bool>(is_sphere, "is_sphere");
        auto d = in2<double>(size, "size");
        auto e = in1<double>(n, "n");
        auto f = v2<double>(sep, "sep");
        auto g = v2<double>(height, "height");
        nb::gil_scoped_release r;
        plane_kernel(a, b, c, d, e, offset, f, g);
    });
    m.def("witness_kernel", [](handle position, handle rotation, handle k, handle j, handle body,
                               handle is_sphere, handle size, handle n, double band, handle out,
                               handle spn) {
        auto a = in3<double>(position, "position");
        auto b = in4<double>(rotation, "rotation");
        auto c = in1<i64>(k, "k");
        auto d = in1<i64>(j, "j");
        auto e = in1<i64>(body, "body");
        auto f = in1<bool>(is_sphere, "is_sphere");
        auto g = in2<double>(size, "size");
        auto h = in1<double>(n, "n");
        auto o = v2<double>(out, "out");
        auto s = v2<double>(spn, "spn");
        nb::gil_scoped_release r;
        witness_kernel(a, b, c, d, e, f, g, h, band, o, s);
    });
    m.def("pairs_kernel", [](handle ks, handle a, handle b, handle position, handle rotation,
                             handle shape, handle size, handle s_pos, handle s_rot,
                             handle s_half, handle sep, handle nrm, handle pt, handle spn,
                             bool with_points, double band, double axis_eps) {
        auto ks_ = in1<i64>(ks, "ks");
        auto a_ = in1<i64>(a, "a");
        auto b_ = in1<i64>(b, "b");
        auto pos = in3<double>(position, "position");
        auto rot = in4<double>(rotation, "rotation");
        auto sh = in1<i64>(shape, "shape");
        auto sz = in2<double>(size, "size");
        auto sp = in3<double>(s_pos, "s_pos");
        auto sr = in4<double>(s_rot, "s_rot");
        auto shh = in2<double>(s_half, "s_half");
        auto sep_ = v1<double>(sep, "sep");
        auto nrm_ = v2<double>(nrm, "nrm");
        auto pt_ = v2<double>(pt, "pt");
        auto spn_ = v2<double>(spn, "spn");
        nb::gil_scoped_release r;
        pairs_kernel(ks_, a_, b_, pos, rot, sh, sz, sp, sr, shh, sep_, nrm_, pt_, spn_,
                     with_points, band, axis_eps);
    });
    m.def("edge_edge", &edge_edge);
    m.def("sweep_kernel", [](handle position, handle grow, handle s_lo, handle s_hi, handle group,
                             i64 axis, handle out_k, handle out_a, handle out_b) {
        auto pos = in3<double>(position, "position");
        auto gr = in2<double>(grow, "grow");
        auto lo = in2<double>(s_lo, "s_lo");
        auto hi = in2<double>(s_hi, "s_hi");
        auto grp = in1<i64>(group, "group");
        auto ok = v1<i64>(out_k, "out_k");
        auto oa = v1<i64>(out_a, "out_a");
        auto ob = v1<i64>(out_b, "out_b");
        if (axis < 0 || axis > 2) throw nb::value_error("sweep_kernel: axis must be 0, 1 or 2");
        nb::gil_scoped_release r;
        return sweep_kernel(pos, gr, lo, hi, grp, axis, ok, oa, ob);
    });
    m.def("spread", [](handle x) {
        auto xv = in2<double>(x, "x");
        if (xv.n0 < 1 || xv.n1 != 3) throw nb::value_error("spread: x must be (P >= 1, 3)");
        double out[3];
        {
            nb::gil_scoped_release r;
            spread(xv, out);
        }
        return std::make_tuple(out[0], out[1], out[2]);
    });

    // --- consistency.cpp
    m.def("interval_rotvec", [](handle rot, i64 k1, i64 k0, i64 b) {
        auto rv = in4<double>(rot, "rot");
        double tx, ty, tz;
        interval_rotvec(rv, k1, k0, b, tx, ty, tz);
        return std::make_tuple(tx, ty, tz);
    });
    m.def("kinematic_rel", [](handle rot, handle omega, handle dts, double min_angle,
                              double smooth_frac, double corr, handle rel) {
        auto a = in4<double>(rot, "rot");
        auto b = in3<double>(omega, "omega");
        auto c = in1<double>(dts, "dts");
        auto d = v2<double>(rel, "rel");
        nb::gil_scoped_release r;
        kinematic_rel(a, b, c, min_angle, smooth_frac, corr, d);
    });
    m.def("linear_rel", [](handle pos, handle vel, handle dts, double min_move, double smooth_frac,
                           handle acc, double corr, handle rel) {
        auto a = in3<double>(pos, "pos");
        auto b = in3<double>(vel, "vel");
        auto c = in1<double>(dts, "dts");
        auto d = in1<double>(acc, "acc");
        auto e = v2<double>(rel, "rel");
        nb::gil_scoped_release r;
        linear_rel(a, b, c, min_move, smooth_frac, d, corr, e);
    });
    m.def("pointwise", [](handle quat, handle rot, handle mom, handle vel, handle omega, handle lw,
                          handle mass, handle inertia, handle err_qm, handle ortho, handle dp,
                          handle p_mag, handle rel_l, handle l_scale) {
        auto a = in3<double>(quat, "quat");
        auto b = in4<double>(rot, "rot");
        auto c = in3<double>(mom, "mom");
        auto d = in3<double>(vel, "vel");
        auto e = in3<double>(omega, "omega");
        auto f = in3<double>(lw, "lw");
        auto g = in1<double>(mass, "mass");
        auto h = in2<double>(inertia, "inertia");
        auto o1 = v2<double>(err_qm, "err_qm");
        auto o2 = v2<double>(ortho, "ortho");
        auto o3 = v2<double>(dp, "dp");
        auto o4 = v2<double>(p_mag, "p_mag");
        auto o5 = v2<double>(rel_l, "rel_l");
        auto o6 = v2<double>(l_scale, "l_scale");
        nb::gil_scoped_release r;
        pointwise(a, b, c, d, e, f, g, h, o1, o2, o3, o4, o5, o6);
    });

    // --- context.cpp
    m.def("groups_kernel", [](handle jump, handle n_static, handle static_id, handle ek, handle ea,
                              handle eb, handle g_k, handle g_size, handle g_nstat, handle g_sid,
                              handle m_k, handle m_i, handle m_g) {
        auto a = in2<bool>(jump, "jump");
        auto b = in2<i64>(n_static, "n_static");
        auto c = in2<i64>(static_id, "static_id");
        auto d = in1<i64>(ek, "ek");
        auto e = in1<i64>(ea, "ea");
        auto f = in1<i64>(eb, "eb");
        auto o1 = v1<i64>(g_k, "g_k");
        auto o2 = v1<i64>(g_size, "g_size");
        auto o3 = v1<i64>(g_nstat, "g_nstat");
        auto o4 = v1<i64>(g_sid, "g_sid");
        auto o5 = v1<i64>(m_k, "m_k");
        auto o6 = v1<i64>(m_i, "m_i");
        auto o7 = v1<i64>(m_g, "m_g");
        nb::gil_scoped_release r;
        return groups_kernel(a, b, c, d, e, f, o1, o2, o3, o4, o5, o6, o7);
    });
    m.def("kinematics", [](handle t, handle position, handle velocity, handle momentum,
                           handle ang_momentum, handle omega, handle mass, handle force,
                           handle torque, handle rho, handle inertia_max, double jump_rel,
                           handle speed, handle spin, handle ke, handle u, handle jump,
                           handle sweep) {
        auto a = in1<double>(t, "t");
        auto b = in3<double>(position, "position");
        auto c = in3<double>(velocity, "velocity");
        auto d = in3<double>(momentum, "momentum");
        auto e = in3<double>(ang_momentum, "ang_momentum");
        auto f = in3<double>(omega, "omega");
        auto g = in1<double>(mass, "mass");
        auto h = in2<double>(force, "force");
        auto i = in2<double>(torque, "torque");
        auto j = in1<double>(rho, "rho");
        auto k = in1<double>(inertia_max, "inertia_max");
        auto o1 = v2<double>(speed, "speed");
        auto o2 = v2<double>(spin, "spin");
        auto o3 = v2<double>(ke, "ke");
        auto o4 = v2<double>(u, "u");
        auto o5 = v2<bool>(jump, "jump");
        auto o6 = v2<double>(sweep, "sweep");
        nb::gil_scoped_release r;
        kinematics(a, b, c, d, e, f, g, h, i, j, k, jump_rel, o1, o2, o3, o4, o5, o6);
    });
    m.def("impulse_kernel", [](handle p, handle dts, handle mass, handle accel, handle k, handle i,
                               handle out) {
        auto a = in3<double>(p, "p");
        auto b = in1<double>(dts, "dts");
        auto c = in1<double>(mass, "mass");
        auto d = in2<double>(accel, "accel");
        auto e = in1<i64>(k, "k");
        auto f = in1<i64>(i, "i");
        auto o = v2<double>(out, "out");
        nb::gil_scoped_release r;
        impulse_kernel(a, b, c, d, e, f, o);
    });
    m.def("all_finite", [](CIn<double> a) {
        const double* p = a.data();
        const i64 n = (i64)a.size();
        nb::gil_scoped_release r;
        return all_finite(p, n);
    }, nb::arg("a").noconvert());

    // --- penetration.cpp
    m.def("deepest", [](handle ground, double cd, handle pk, handle pa, handle pb, handle ps, i64 n,
                        handle kind, handle ref) {
        auto a = in2<double>(ground, "ground");
        auto b = in1<i64>(pk, "pk");
        auto c = in1<i64>(pa, "pa");
        auto d = in1<i64>(pb, "pb");
        auto e = in1<double>(ps, "ps");
        auto o1 = v2<int8_t>(kind, "kind");
        auto o2 = v2<i64>(ref, "ref");
        nb::gil_scoped_release r;
        deepest(a, cd, b, c, d, e, n, o1, o2);
    });
    m.def("contact_velocity", [](handle pk, handle pi_, handle pb, handle point, handle normal,
                                 handle position, handle velocity, handle omega, i64 n, handle cv,
                                 handle slip, handle cspeed, handle wspeed) {
        auto a = in1<i64>(pk, "pk");
        auto b = in1<i64>(pi_, "pi_");
        auto c = in1<i64>(pb, "pb");
        auto d = in2<double>(point, "point");
        auto e = in2<double>(normal, "normal");
        auto f = in3<double>(position, "position");
        auto g = in3<double>(velocity, "velocity");
        auto h = in3<double>(omega, "omega");
        auto o1 = v2<double>(cv, "cv");
        auto o2 = v2<double>(slip, "slip");
        auto o3 = v1<double>(cspeed, "cspeed");
        auto o4 = v1<double>(wspeed, "wspeed");
        nb::gil_scoped_release r;
        contact_velocity(a, b, c, d, e, f, g, h, n, o1, o2, o3, o4);
    });
    m.def("contact_slide", [](handle pk, handle pi_, handle pb, handle point, handle span,
                              handle normal, handle position, handle rotation, i64 n, handle nxt,
                              handle disp, handle is_box, handle size, handle s_pos, handle s_rot,
                              handle s_half, double band, handle nload) {
        auto a = in1<i64>(pk, "pk");
        auto b = in1<i64>(pi_, "pi_");
        auto c = in1<i64>(pb, "pb");
        auto d = in2<double>(point, "point");
        auto e = in2<double>(span, "span");
        auto f = in2<double>(normal, "normal");
        auto g = in3<double>(position, "position");
        auto h = in4<double>(rotation, "rotation");
        auto i = in1<bool>(nxt, "nxt");
        auto o = v2<double>(disp, "disp");
        auto j = in1<bool>(is_box, "is_box");
        auto k = in2<double>(size, "size");
        auto l = in2<double>(s_pos, "s_pos");
        auto mm = in3<double>(s_rot, "s_rot");
        auto nn = in2<double>(s_half, "s_half");
        auto q = in1<i64>(nload, "nload");
        nb::gil_scoped_release r;
        contact_slide(a, b, c, d, e, f, g, h, n, i, o, j, k, l, mm, nn, band, q);
    });
    m.def("impact_jump", [](handle velocity, handle omega, handle reach) {
        auto a = in3<double>(velocity, "velocity");
        auto b = in3<double>(omega, "omega");
        auto c = in1<double>(reach, "reach");
        const i64 rows = a.n0 > 1 ? a.n0 - 1 : 0, cols = a.n1;
        std::vector<double> out(static_cast<size_t>(rows * cols), 0.0);
        {
            nb::gil_scoped_release r;
            impact_jump(a, b, c, V2<double>{out.data(), rows, cols});
        }
        return to_numpy<double>(std::move(out), {(size_t)rows, (size_t)cols});
    });

    // --- momentum.cpp
    m.def("cone_kernel", [](handle jv, handle nrm, handle mu, handle mass, handle speed,
                            handle accel_norm, handle dts, handle k, handle i, double floor_ns,
                            double res_eps, double tiny, handle jn, handle jt, handle excess) {
        auto a = in2<double>(jv, "jv");
        auto b = in2<double>(nrm, "nrm");
        auto c = in1<double>(mu, "mu");
        auto d = in1<double>(mass, "mass");
        auto e = in2<double>(speed, "speed");
        auto f = in1<double>(accel_norm, "accel_norm");
        auto g = in1<double>(dts, "dts");
        auto h = in1<i64>(k, "k");
        auto ii = in1<i64>(i, "i");
        auto o1 = v1<double>(jn, "jn");
        auto o2 = v1<double>(jt, "jt");
        auto o3 = v1<double>(excess, "excess");
        nb::gil_scoped_release r;
        cone_kernel(a, b, c, d, e, f, g, h, ii, floor_ns, res_eps, tiny, o1, o2, o3);
    });
    m.def("flight_drift", [](handle free, handle t, handle p, handle l, handle speed, handle mass,
                             handle force, handle tau, handle p_floor, handle l_floor, handle segs,
                             handle vals) {
        auto a = in2<bool>(free, "free");
        auto b = in1<double>(t, "t");
        auto c = in3<double>(p, "p");
        auto d = in3<double>(l, "l");
        auto e = in2<double>(speed, "speed");
        auto f = in1<double>(mass, "mass");
        auto g = in2<double>(force, "force");
        auto h = in2<double>(tau, "tau");
        auto i = in1<double>(p_floor, "p_floor");
        auto j = in1<double>(l_floor, "l_floor");
        auto o1 = v2<i64>(segs, "segs");
        auto o2 = v2<double>(vals, "vals");
        nb::gil_scoped_release r;
        return flight_drift(a, b, c, d, e, f, g, h, i, j, o1, o2);
    });

    // --- events.cpp
    m.def("link_groups", [](handle gk, handle h, handle size, handle sid, handle mem0, i64 n,
                            handle eid, handle head_of, handle k1) {
        auto a = in1<i64>(gk, "gk");
        auto b = in1<i64>(h, "h");
        auto c = in1<i64>(size, "size");
        auto d = in1<i64>(sid, "sid");
        auto e = in1<i64>(mem0, "mem0");
        auto o1 = v1<i64>(eid, "eid");
        auto o2 = v1<i64>(head_of, "head_of");
        auto o3 = v1<i64>(k1, "k1");
        nb::gil_scoped_release r;
        return link_groups(a, b, c, d, e, n, o1, o2, o3);
    });

    // --- energy.cpp
    m.def("free_drift", [](handle free, handle t, handle e, handle ke, handle u, handle speed,
                           handle mass, handle amag, double dt, double drift_rel, double floor,
                           handle segs, handle vals) {
        auto a = in2<bool>(free, "free");
        auto b = in1<double>(t, "t");
        auto c = in2<double>(e, "e");
        auto d = in2<double>(ke, "ke");
        auto f = in2<double>(u, "u");
        auto g = in2<double>(speed, "speed");
        auto h = in1<double>(mass, "mass");
        auto i = in1<double>(amag, "amag");
        auto o1 = v2<i64>(segs, "segs");
        auto o2 = v2<double>(vals, "vals");
        nb::gil_scoped_release r;
        return free_drift(a, b, c, d, f, g, h, i, dt, drift_rel, floor, o1, o2);
    });

    // --- drift.cpp
    m.def("rigidity", [](handle rot, handle quat, handle out) {
        auto a = in4<double>(rot, "rot");
        auto b = in3<double>(quat, "quat");
        auto o = v3<double>(out, "out");
        nb::gil_scoped_release r;
        rigidity(a, b, o);
    });

    // --- tunneling.cpp
    m.def("chord_overlap", [](handle position, handle k, handle a, handle b, handle thr_part,
                              handle out) {
        auto p = in3<double>(position, "position");
        auto kk = in1<i64>(k, "k");
        auto aa = in1<i64>(a, "a");
        auto bb = in1<i64>(b, "b");
        auto t = in1<double>(thr_part, "thr_part");
        auto o = v1<double>(out, "out");
        nb::gil_scoped_release r;
        chord_overlap(p, kk, aa, bb, t, o);
    });

    // --- shapes.cpp, convex.cpp, broadphase.cpp (every shape of the contract)
    m.attr("GEOM_PLANE") = GEOM_PLANE;
    m.attr("GEOM_SPHERE") = GEOM_SPHERE;
    m.attr("GEOM_CAPSULE") = GEOM_CAPSULE;
    m.attr("GEOM_ELLIPSOID") = GEOM_ELLIPSOID;
    m.attr("GEOM_CYLINDER") = GEOM_CYLINDER;
    m.attr("GEOM_BOX") = GEOM_BOX;
    m.attr("GEOM_MESH") = GEOM_MESH;
    m.attr("DIST_OK") = DIST_OK;
    m.attr("DIST_NOT_CONVERGED") = DIST_NOT_CONVERGED;
    m.attr("DIST_UNSUPPORTED") = DIST_UNSUPPORTED;
    m.def("geom_pairs_kernel", [](handle k, handle i, handle j, handle position, handle rotation,
                                  handle type, handle size, handle mesh_start, handle mesh_count,
                                  handle verts, double gjk_tol, double epa_tol, i64 max_iter,
                                  double band, double axis_eps, handle sep, handle n, handle pa,
                                  handle pb, handle status, handle iters) {
        auto k_ = in1<i64>(k, "k");
        auto i_ = in1<i64>(i, "i");
        auto j_ = in1<i64>(j, "j");
        auto pos = in3<double>(position, "position");
        auto rot = in4<double>(rotation, "rotation");
        auto ty = in1<i64>(type, "type");
        auto sz = in2<double>(size, "size");
        auto ms = in1<i64>(mesh_start, "mesh_start");
        auto mc = in1<i64>(mesh_count, "mesh_count");
        auto vt = in2<double>(verts, "verts");
        auto o_sep = v1<double>(sep, "sep");
        auto o_n = v2<double>(n, "n");
        auto o_pa = v2<double>(pa, "pa");
        auto o_pb = v2<double>(pb, "pb");
        auto o_st = v1<i64>(status, "status");
        auto o_it = v1<i64>(iters, "iters");
        const i64 g_n = pos.n1;
        if (rot.n1 != g_n || ty.n0 != g_n || sz.n0 != g_n || ms.n0 != g_n || mc.n0 != g_n)
            throw nb::value_error("geom_pairs_kernel: position, rotation, type, size, mesh_start "
                                  "and mesh_count must cover the same geoms");
        for (i64 r = 0; r < k_.n0; ++r) {
            if (k_[r] < 0 || k_[r] >= pos.n0 || i_[r] < 0 || i_[r] >= g_n || j_[r] < 0 ||
                j_[r] >= g_n)
                throw nb::index_error("geom_pairs_kernel: a row's sample or geom is out of range");
        }
        for (i64 g = 0; g < g_n; ++g) {
            if (ty[g] < 0 || ty[g] >= GEOM_N_TYPES)
                throw nb::value_error("geom_pairs_kernel: unknown geom type code");
            if (ty[g] == GEOM_MESH && (mc[g] < 1 || ms[g] < 0 || ms[g] + mc[g] > vt.n0))
                throw nb::value_error("geom_pairs_kernel: a mesh's vertex rows are out of range");
        }
        nb::gil_scoped_release r;
        geom_pairs_kernel(k_, i_, j_, pos, rot, ty, sz, ms, mc, vt, gjk_tol, epa_tol, max_iter,
                          band, axis_eps, o_sep, o_n, o_pa, o_pb, o_st, o_it);
    });
    m.def("geom_broadphase", [](handle position, handle rotation, handle type, handle size,
                                handle mesh_start, handle mesh_count, handle verts, handle body,
                                double pad, handle out_k, handle out_i, handle out_j) {
        auto pos = in3<double>(position, "position");
        auto rot = in4<double>(rotation, "rotation");
        auto ty = in1<i64>(type, "type");
        auto sz = in2<double>(size, "size");
        auto ms = in1<i64>(mesh_start, "mesh_start");
        auto mc = in1<i64>(mesh_count, "mesh_count");
        auto vt = in2<double>(verts, "verts");
        auto bd = in1<i64>(body, "body");
        auto ok = v1<i64>(out_k, "out_k");
        auto oi = v1<i64>(out_i, "out_i");
        auto oj = v1<i64>(out_j, "out_j");
        nb::gil_scoped_release r;
        return geom_broadphase(pos, rot, ty, sz, ms, mc, vt, bd, pad, ok, oi, oj);
    });
    m.def("geom_sweep_broadphase", [](handle position, handle rotation, handle type,
                                      handle size, handle mesh_start, handle mesh_count,
                                      handle verts, handle body, handle mine, handle grow,
                                      handle out_k, handle out_i, handle out_j) {
        auto pos = in3<double>(position, "position");
        auto rot = in4<double>(rotation, "rotation");
        auto ty = in1<i64>(type, "type");
        auto sz = in2<double>(size, "size");
        auto ms = in1<i64>(mesh_start, "mesh_start");
        auto mc = in1<i64>(mesh_count, "mesh_count");
        auto vt = in2<double>(verts, "verts");
        auto bd = in1<i64>(body, "body");
        auto mn = in1<bool>(mine, "mine");
        auto gr = in2<double>(grow, "grow");
        auto ok = v1<i64>(out_k, "out_k");
        auto oi = v1<i64>(out_i, "out_i");
        auto oj = v1<i64>(out_j, "out_j");
        if (mn.n0 != pos.n1 || bd.n0 != pos.n1 || gr.n1 != pos.n1 || gr.n0 + 1 < pos.n0)
            throw nb::value_error("geom_sweep_broadphase: mine, body and grow need one entry "
                                  "per geom, grow one row per interval");
        nb::gil_scoped_release r;
        return geom_sweep_broadphase(pos, rot, ty, sz, ms, mc, vt, bd, mn, gr, ok, oi, oj);
    });
}

}  // namespace rb
