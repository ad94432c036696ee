// Bindings of the contact step (world_step.cpp) and its stages, and of the solver functions the
// tests call directly (rblog/engine/contact/{step,solver,relax,restitution,project}.py wrap them
// under their Python names). The records arrive as the Python namedtuples and are read into
// views (records.hpp, from_py); the ContactCache and the stages' Scratch are C++ objects whose
// fields read as numpy views of the live buffers.
#include <nanobind/stl/pair.h>
#include <nanobind/stl/tuple.h>

#include <string>
#include <tuple>
#include <vector>

#include "common/py.hpp"
#include "engine/bind.hpp"
#include "engine/contact_solver.hpp"
#include "engine/profile.hpp"
#include "engine/project.hpp"
#include "engine/records.hpp"
#include "engine/world_step.hpp"

namespace rb {
namespace nb = nanobind;

namespace {

template <class T>
using NpArr = nb::ndarray<nb::numpy, T>;

// A numpy view of a C++-owned buffer, kept alive by `owner` (the Python object holding it).
template <class T>
NpArr<T> view2(Buf2<T>& b, nb::handle owner) {
    size_t shape[2] = {(size_t)b.rows, (size_t)b.cols};
    return NpArr<T>(b.data.data(), 2, shape, owner);
}
template <class T>
NpArr<T> view1(Buf2<T>& b, nb::handle owner) {
    size_t shape[1] = {(size_t)(b.rows * b.cols)};
    return NpArr<T>(b.data.data(), 1, shape, owner);
}

// A numpy (K, C) array copied into a C++ buffer (the stages that grow a buffer take a Buf2&).
template <class T>
Buf2<T> buf_from(nb::handle h, const char* name) {
    V2<T> v = v2<T>(h, name);
    Buf2<T> b(v.n0, v.n1);
    for (i64 k = 0; k < v.n0 * v.n1; ++k) b.data[(size_t)k] = v.p[k];
    return b;
}

template <class T>
NpArr<T> copy_out(const Buf2<T>& b) {
    return rows_to_numpy<T>(b, b.rows);
}

void check(bool ok, const std::string& what) {
    if (!ok) throw nb::value_error(what.c_str());
}

// The checks world_advance needs before it writes through raw views.
void check_advance(const Bodies& bd, const BodyState& x, const SampleState& out,
                   const SleepState& sl, const FlowAnchors& an, V1<i64> stats, V1<i64> prof,
                   i64 n_steps, i64 stride, bool sample_last) {
    i64 n = x.position.n0;
    check(stride >= 1, "stride must be >= 1");
    check(n_steps >= 0, "n_steps must be >= 0");
    check(x.position.n1 == 3 && x.linear_momentum.n0 == n && x.quat_wxyz.n0 == n &&
              x.rotation.n0 == n && x.angular_momentum.n0 == n,
          "state arrays: N rows each");
    check(bd.inv_mass.n0 == n && bd.radius.n0 == n, "Bodies: N rows");
    const i64 g = bd.geom.n0;
    check(bd.size.n0 == g && bd.geom_body.n0 == g && bd.geom_offset.n0 == g &&
              bd.geom_pos.n0 == g && bd.geom_rot.n0 == g && bd.geom_radius.n0 == g,
          "Bodies: G rows of geoms");
    for (i64 k = 0; k < g; ++k)
        check(bd.geom_body[k] >= 0 && bd.geom_body[k] < n, "Bodies: geom_body in 0..N-1");
    check(sl.awake.n0 == n && sl.timer.n0 == n && sl.island_of.n0 == n &&
              sl.island_counter.n0 >= 1,
          "SleepState: N rows");
    check(an.anchor_steps.n0 == n && an.anchor_quat_wxyz.n0 == n, "FlowAnchors: N rows");
    i64 need = n_steps / stride + (sample_last ? 1 : 0);
    check(out.position.n0 >= need && out.linear_momentum.n0 >= need && out.quat_wxyz.n0 >= need &&
              out.rotation.n0 >= need && out.angular_momentum.n0 >= need,
          "sample buffers: fewer rows than samples");
    check(need == 0 || (out.position.n1 == n && out.rotation.n1 == n), "sample buffers: N bodies");
    check(stats.n0 >= N_STATS, "stats: N_STATS counters");
    check(prof.n0 == 0 || prof.n0 >= N_PROF, "prof: empty or N_PROF counters");
}

}  // namespace

void bind_contact(nb::module_& m) {
    m.attr("N_PROF") = (int)N_PROF;
    m.attr("N_STATS") = (int)N_STATS;
    m.attr("CONTACT_RESTING") = CONTACT_RESTING;
    m.attr("CONTACT_IMPACT") = CONTACT_IMPACT;
    m.def("ticks", &ticks, "The profile's cycle counter (profile.hpp).");

    // ---- the records kept between calls ----------------------------------------------------
    nb::class_<Scratch>(m, "Scratch", "The contact stages' work arrays (step.make_scratch).")
#define RB_FIELD2(name) .def_prop_ro(#name, [](nb::handle self) { \
        return view2(nb::cast<Scratch&>(self).name, self); })
#define RB_FIELD1(name) .def_prop_ro(#name, [](nb::handle self) { \
        return view1(nb::cast<Scratch&>(self).name, self); })
        RB_FIELD2(lo) RB_FIELD2(hi) RB_FIELD1(reach) RB_FIELD1(in_contact) RB_FIELD1(bm)
        RB_FIELD2(bI) RB_FIELD2(bv) RB_FIELD2(bw) RB_FIELD2(bv0) RB_FIELD2(bw0) RB_FIELD2(pv)
        RB_FIELD2(pw) RB_FIELD2(p0) RB_FIELD2(l0) RB_FIELD2(l_drift) RB_FIELD1(parent)
        RB_FIELD1(isl_time) RB_FIELD1(isl_sup) RB_FIELD1(hot)
        RB_FIELD2(dx_step) RB_FIELD2(proj_dx) RB_FIELD2(proj_dth) RB_FIELD1(pushed)
        RB_FIELD1(push_root) RB_FIELD1(exact_man) RB_FIELD2(flow_c);
#undef RB_FIELD1
#undef RB_FIELD2

    nb::class_<ContactCache>(
        m, "ContactCache",
        "What the contact step keeps between calls (step.ContactCache): the previous step's "
        "manifolds sorted by key (mi0, mf0, pf0, pid0, n_man0, keys0, idx0), spare buffers for "
        "this step's (mi1, mf1, pf1, pid1), the broadphase's pairs. Fields read as numpy views "
        "of the live buffers (a call may grow them: read them again after it).")
        .def(nb::init<i64, i64>(), nb::arg("cap_manifolds"), nb::arg("cap_points"))
#define RB_FIELD2(name) .def_prop_ro(#name, [](nb::handle self) { \
        return view2(nb::cast<ContactCache&>(self).name, self); })
#define RB_FIELD1(name) .def_prop_ro(#name, [](nb::handle self) { \
        return view1(nb::cast<ContactCache&>(self).name, self); })
        RB_FIELD2(mi0) RB_FIELD2(mf0) RB_FIELD2(pf0) RB_FIELD1(pid0) RB_FIELD1(keys0)
        RB_FIELD1(idx0) RB_FIELD2(mi1) RB_FIELD2(mf1) RB_FIELD2(pf1) RB_FIELD1(pid1)
        RB_FIELD2(pairs)
#undef RB_FIELD1
#undef RB_FIELD2
        .def_rw("n_man0", &ContactCache::n_man0)
        .def_prop_ro("scratch", [](nb::handle self) -> Scratch& {
            return nb::cast<ContactCache&>(self).sc;
        }, nb::rv_policy::reference_internal);

    // ---- the step ----------------------------------------------------------------------------
    m.def(
        "world_advance",
        [](nb::handle bd_, nb::handle st_, nb::handle cfg_, int method, int ortho, double dt,
           i64 n_steps, i64 stride, bool sample_last, nb::handle x_, nb::handle out_,
           nb::handle sl_, ContactCache& c, nb::handle stats_, nb::handle prof_, nb::handle an_,
           nb::handle im_) {
            Bodies bd = Bodies::from_py(bd_);
            Statics st = Statics::from_py(st_);
            Settings cfg = Settings::from_py(cfg_);
            BodyState x = BodyState::from_py(x_);
            SampleState out = SampleState::from_py(out_);
            SleepState sl = SleepState::from_py(sl_);
            FlowAnchors an = FlowAnchors::from_py(an_);
            IntervalImpulses im = IntervalImpulses::from_py(im_);
            V1<i64> stats = v1<i64>(stats_, "stats");
            V1<i64> prof = v1<i64>(prof_, "prof");
            check_advance(bd, x, out, sl, an, stats, prof, n_steps, stride, sample_last);
            if (im.on()) {
                i64 n = x.position.n0;
                check(im.acc.n0 == n && im.acc.n1 == 6 && im.start.n0 == n && im.start.n1 == 6 &&
                          im.kicked.n0 == n && im.out.n0 == out.position.n0 && im.out.n1 == n &&
                          im.out.n2 == 6,
                      "impulses: acc and start (N, 6), kicked (N,), out (S, N, 6) expected");
            }
            AdvanceResult r;
            {
                nb::gil_scoped_release release;
                r = world_advance(bd, st, cfg, method, ortho, dt, n_steps, stride, sample_last, x,
                                  out, sl, c, stats, prof, an, im);
            }
            std::vector<i64> li(c.log_i.data.begin(), c.log_i.data.begin() + r.n_log * LOG_I_COLS);
            std::vector<double> lf(c.log_f.data.begin(),
                                   c.log_f.data.begin() + r.n_log * LOG_F_COLS);
            return std::make_tuple(r.n_samples, r.bad_step, r.bad_body,
                                   to_numpy<i64>(std::move(li), {(size_t)r.n_log, (size_t)LOG_I_COLS}),
                                   to_numpy<double>(std::move(lf), {(size_t)r.n_log, (size_t)LOG_F_COLS}));
        },
        "world_advance(bd, st, cfg, method, ortho, dt, n_steps, stride, sample_last, x, out, sl, "
        "cache, stats, prof, an, impulses) -> (n_samples, bad_step, bad_body, log_i, log_f) "
        "(step.py).");

    // ---- the stages on their own (step.py wraps them under their names) ----------------------
    m.def("make_scratch", [](i64 n, nb::handle st_, i64 n_geoms) {
        Scratch sc;
        sc.make(n, n_geoms < 0 ? n : n_geoms, Statics::from_py(st_));
        return sc;
    }, nb::arg("n"), nb::arg("st"), nb::arg("n_geoms") = -1);
    m.def("stage_kick", [](nb::handle bd, nb::handle awake, nb::handle x, double h) {
        step::kick(Bodies::from_py(bd), v1<i64>(awake, "awake"), BodyState::from_py(x), h);
    });
    m.def("stage_broadphase", [](nb::handle bd, nb::handle st, double margin, nb::handle awake,
                                 nb::handle x, double h, Scratch& sc, nb::handle pairs_) {
        Buf2<i64> pairs = buf_from<i64>(pairs_, "pairs");
        i64 n_pairs = step::broadphase(Bodies::from_py(bd), Statics::from_py(st), margin,
                                       v1<i64>(awake, "awake"), BodyState::from_py(x), h, sc,
                                       pairs);
        return std::make_pair(copy_out(pairs), n_pairs);
    });
    m.def("stage_collide", [](nb::handle bd, nb::handle st, nb::handle cfg, nb::handle awake,
                              nb::handle x, Scratch& sc, nb::handle pairs, i64 n_pairs,
                              ContactCache& c) {
        CollideCount r = step::collide(Bodies::from_py(bd), Statics::from_py(st),
                                       Settings::from_py(cfg), v1<i64>(awake, "awake"),
                                       BodyState::from_py(x), sc, v2<i64>(pairs, "pairs"),
                                       n_pairs, c);
        return std::make_pair(r.n_man, r.n_pts);
    });
    m.def("stage_prepare", [](nb::handle bd, nb::handle cfg, nb::handle x, Scratch& sc,
                              nb::handle mi, nb::handle mf, nb::handle pf, i64 n_man, double h) {
        step::prepare(Bodies::from_py(bd), Settings::from_py(cfg), BodyState::from_py(x), sc,
                      mi_arg(mi), mf_arg(mf), pf_arg(pf), n_man, h);
    });
    m.def("stage_integrate_positions",
          [](int method, int ortho, nb::handle bd, nb::handle cfg, nb::handle awake, nb::handle x,
             Scratch& sc, double h, nb::handle an) {
              step::integrate_positions(method, ortho, Bodies::from_py(bd), Settings::from_py(cfg),
                                        v1<i64>(awake, "awake"), BodyState::from_py(x), sc, h,
                                        FlowAnchors::from_py(an));
          });
    m.def("stage_first_diverged", [](nb::handle awake, nb::handle x, nb::handle inv_inertia,
                                     double h) {
        return step::first_diverged(v1<i64>(awake, "awake"), BodyState::from_py(x),
                                    v2<double>(inv_inertia, "inv_inertia"), h);
    });

    // ---- the solver's stages (contact_solver.hpp) and the project stage (project.hpp) ---------
    // the stages one by one (the tests): the settings each reads given as arguments
    auto cons_of = [](nb::handle mi, nb::handle mf, nb::handle pf, i64 n_man) {
        return ContactConstraints{mi_arg(mi), mf_arg(mf), pf_arg(pf), n_man};
    };
    auto bodies_of = [](nb::handle bm, nb::handle bI, nb::handle bv, nb::handle bw) {
        return SolverBodies{v1<double>(bm, "bm"), v2<double>(bI, "bI"), v2<double>(bv, "bv"),
                            v2<double>(bw, "bw")};
    };
    m.def("prepare_contacts", [=](nb::handle mi, nb::handle mf, nb::handle pf, i64 n_man,
                                  nb::handle bm, nb::handle bI, nb::handle bv, nb::handle bw,
                                  double h, double friction_anchor_rate, double block_reg) {
        Settings cfg;
        cfg.friction_anchor_rate = friction_anchor_rate;
        cfg.block_reg = block_reg;
        prepare_contacts(StepContext{h, 1.0 / h, cfg}, cons_of(mi, mf, pf, n_man),
                         bodies_of(bm, bI, bv, bw));
    });
    m.def("warm_start", [=](nb::handle mi, nb::handle mf, nb::handle pf, i64 n_man, nb::handle bm,
                            nb::handle bI, nb::handle bv, nb::handle bw) {
        warm_start(cons_of(mi, mf, pf, n_man), bodies_of(bm, bI, bv, bw));
    });
    m.def("solve_velocities", [=](nb::handle mi, nb::handle mf, nb::handle pf, i64 n_man,
                                  nb::handle bm, nb::handle bI, nb::handle bv, nb::handle bw,
                                  double inv_h, i64 velocity_iterations,
                                  i64 max_velocity_iterations, double velocity_tolerance,
                                  nb::handle hot, nb::handle degree, double over_relaxation,
                                  i64 friction_newton_iters, double friction_newton_tol) {
        Settings cfg;
        cfg.velocity_iterations = velocity_iterations;
        cfg.max_velocity_iterations = max_velocity_iterations;
        cfg.velocity_tolerance = velocity_tolerance;
        cfg.over_relaxation = over_relaxation;
        cfg.friction_newton_iters = friction_newton_iters;
        cfg.friction_newton_tol = friction_newton_tol;
        // the world step colours in a stage of its own; a call from Python colours here
        ContactConstraints c = cons_of(mi, mf, pf, n_man);
        SolverBodies b = bodies_of(bm, bI, bv, bw);
        ConstraintGraph g;
        SolverLanes lanes;
        colour_manifolds(c.mi, n_man, b.inv_mass.n0 - 1, g);
        return solve_velocities(StepContext{1.0 / inv_h, inv_h, cfg}, c, b, v1<i64>(hot, "hot"),
                                v1<i64>(degree, "degree"), g, lanes);
    });
    m.def("anchor_friction", [=](nb::handle mi, nb::handle mf, nb::handle pf, i64 n_man,
                                 nb::handle bm, nb::handle bI, nb::handle bv, nb::handle bw,
                                 i64 friction_newton_iters, double friction_newton_tol) {
        Settings cfg;
        cfg.friction_newton_iters = friction_newton_iters;
        cfg.friction_newton_tol = friction_newton_tol;
        anchor_friction(StepContext{0.0, 0.0, cfg}, cons_of(mi, mf, pf, n_man),
                        bodies_of(bm, bI, bv, bw));
    });
    m.def("store_impulses", [=](nb::handle mi, nb::handle mf, nb::handle pf, i64 n_man,
                                double friction_anchor_slide_frac) {
        Settings cfg;
        cfg.friction_anchor_slide_frac = friction_anchor_slide_frac;
        store_impulses(StepContext{0.0, 0.0, cfg}, cons_of(mi, mf, pf, n_man));
    });
    m.def("restitution", [=](nb::handle mi, nb::handle mf, nb::handle pf, i64 n_man,
                             nb::handle bm, nb::handle bI, nb::handle bv, nb::handle bw,
                             nb::handle pv, nb::handle pw, double h,
                             double restitution_threshold, i64 velocity_iterations,
                             nb::handle dx, nb::handle lm, nb::handle am) {
        Settings cfg;
        cfg.restitution_threshold = restitution_threshold;
        cfg.velocity_iterations = velocity_iterations;
        return restitution(StepContext{h, 1.0 / h, cfg}, cons_of(mi, mf, pf, n_man),
                           bodies_of(bm, bI, bv, bw), v2<double>(pv, "pv"), v2<double>(pw, "pw"),
                           v2<double>(dx, "dx"), v2<double>(lm, "linear_momentum"),
                           v2<double>(am, "angular_momentum"));
    });
    // the project stage's last part, for the points of bodies ids (K, 2) (solver rows; n: the
    // static dummy); the state's arrays change in place
    m.def("apply_projection",
          [](nb::handle ids, nb::handle dx, nb::handle dth, int method, int ortho, nb::handle bd,
             bool iso_shortcut, nb::handle position, nb::handle rotation, nb::handle quat_wxyz,
             nb::handle lm, nb::handle am, nb::handle l_scratch, nb::handle anchor_steps) {
              V2<i64> id = v2<i64>(ids, "ids");
              check(id.n1 == 2, "ids (K, 2)");
              std::vector<ProjectPoint> pts((size_t)id.n0);
              for (i64 k = 0; k < id.n0; ++k) {
                  pts[(size_t)k].a = id(k, 0);
                  pts[(size_t)k].b = id(k, 1);
              }
              const BodyState x{v2<double>(position, "position"), v2<double>(lm, "linear_momentum"),
                                v2<double>(quat_wxyz, "quat_wxyz"), v3<double>(rotation, "rotation"),
                                v2<double>(am, "angular_momentum")};
              apply_projection(V1<ProjectPoint>{pts.data(), id.n0}, v2<double>(dx, "dx"),
                               v2<double>(dth, "dth"), method, ortho, Bodies::from_py(bd),
                               iso_shortcut, x, v2<double>(l_scratch, "l_scratch"),
                               v1<i64>(anchor_steps, "anchor_steps"));
          });
}

}  // namespace rb
