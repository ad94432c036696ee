// The contact step's records (rblog/engine/contact/step.py's namedtuples, rblog/engine/state.py's
// FlowAnchors) as structs of views with the same field names, each read from its Python record
// by from_py (no copy: a view shares the numpy buffer; a wrong dtype, shape or layout is a
// TypeError naming the field). The records only hold views: the Python objects own the memory
// and outlive the call.
//
// What the step keeps between calls is C++-owned: ContactCache (the previous step's manifolds,
// the spare buffers for this step's, the broadphase's pairs, the contact log, the stages' work
// arrays), exposed to Python as an opaque object whose fields read as numpy views of the live
// buffers (stale after a call that grew them; read them again).
#pragma once

#include <cstddef>  // size_t, which common/array.hpp uses

#include <memory>
#include <vector>

#include "engine/constraint_graph.hpp"
#include "engine/contact_lanes.hpp"
#include "common/array.hpp"
#include "common/py.hpp"
#include "engine/collision.hpp"
#include "engine/step_context.hpp"

namespace rb {

// Per-body model arrays the kernel reads (N rows each; iso marks isotropic inertia), and the
// bodies' geoms (G rows each, collision.hpp Geoms: G = N and geom i = body i when every body is
// one shape at its centre of mass).
struct Bodies {
    V1<i64> geom;             // (G,) narrowphase GEOM_* code
    V2<double> size;          // (G, 3) size row (collision.hpp GEOM_*), m
    V1<i64> geom_body;        // (G,) owner body
    V1<i64> geom_offset;      // (G,) 1: the geom sits at geom_pos / geom_rot in its body
    V2<double> geom_pos;      // (G, 3) body frame, m
    V3<double> geom_rot;      // (G, 3, 3) geom -> body
    V1<double> geom_radius;   // (G,) farthest point of the geom from its body's centre, m
    V1<double> radius;        // (N,) bounding radius, m
    V1<double> inv_mass;      // (N,) 1/kg
    V2<double> inertia;       // (N, 3) principal moments, kg m^2
    V2<double> inv_inertia;   // (N, 3)
    V1<i64> iso;              // (N,) 1: isotropic inertia
    V2<double> force;         // (N, 3) m g + F, world, N
    V2<double> torque;        // (N, 3) world, N m
    V2<double> accel;         // (N, 3) g + F/m, m/s^2
    V1<double> restitution;   // (N,)
    V1<double> friction;      // (N,)
    V1<i64> group;            // (N,) collision group
    static Bodies from_py(nanobind::handle r);
    // The geoms as the collision stages read them (views of the fields above).
    Geoms geoms() const { return Geoms{geom, size, geom_body, geom_offset, geom_pos, geom_rot,
                                       geom_radius}; }
};

// Static geometry: static boxes (their AABBs precomputed) and the ground plane.
struct Statics {
    i64 n_static = 0;
    V2<double> pos;   // (S, 3)
    V3<double> rot;   // (S, 3, 3) body -> world
    V2<double> ext;   // (S, 3) half extents
    V1<double> e;     // (S,) restitution
    V1<double> mu;    // (S,) friction
    V2<double> lo;    // (S, 3) AABBs padded by the speculative distance
    V2<double> hi;
    bool ground = false;
    V1<double> gn;    // (3,) unit ground normal
    double goff = 0.0, g_e = 0.0, g_mu = 0.0;
    static Statics from_py(nanobind::handle r);
};

// The changing state of the bodies, world frame (rblog.engine.state.State's arrays).
struct BodyState {
    V2<double> position;          // (N, 3) m
    V2<double> linear_momentum;   // (N, 3) kg m/s
    V2<double> quat_wxyz;         // (N, 4)
    V3<double> rotation;          // (N, 3, 3) body -> world
    V2<double> angular_momentum;  // (N, 3) world, kg m^2/s
    static BodyState from_py(nanobind::handle r);
};

// The sample buffers: a BodyState with a leading sample axis (S, N, ...).
struct SampleState {
    V3<double> position;
    V3<double> linear_momentum;
    V3<double> quat_wxyz;
    V4<double> rotation;
    V3<double> angular_momentum;
    static SampleState from_py(nanobind::handle r);
};

// Sleep state kept between calls: awake (N,) 0/1, timer (N,) s at rest, island_of (N,) island id
// of a sleeping body (-1 awake), island_counter (1,) next island id.
struct SleepState {
    V1<i64> awake;
    V1<double> timer;
    V1<i64> island_of;
    V1<i64> island_counter;
    static SleepState from_py(nanobind::handle r);
};

// The exact integrators' flow anchors (rblog.engine.state.FlowAnchors).
struct FlowAnchors {
    V2<double> anchor_quat_wxyz;  // (N, 4)
    V2<double> anchor_L_world;    // (N, 3)
    V1<i64> anchor_steps;         // (N,) -1: none
    V1<double> anchor_dt_s;       // (N,)
    static FlowAnchors from_py(nanobind::handle r);
};

// ---- from Python records (namedtuples of numpy arrays, same field names) ----------------------

inline Bodies Bodies::from_py(nanobind::handle r) {
    Bodies b;
    b.geom = f1<i64>(r, "geom");
    b.size = f2<double>(r, "size");
    b.geom_body = f1<i64>(r, "geom_body");
    b.geom_offset = f1<i64>(r, "geom_offset");
    b.geom_pos = f2<double>(r, "geom_pos");
    b.geom_rot = f3<double>(r, "geom_rot");
    b.geom_radius = f1<double>(r, "geom_radius");
    b.radius = f1<double>(r, "radius");
    b.inv_mass = f1<double>(r, "inv_mass");
    b.inertia = f2<double>(r, "inertia");
    b.inv_inertia = f2<double>(r, "inv_inertia");
    b.iso = f1<i64>(r, "iso");
    b.force = f2<double>(r, "force");
    b.torque = f2<double>(r, "torque");
    b.accel = f2<double>(r, "accel");
    b.restitution = f1<double>(r, "restitution");
    b.friction = f1<double>(r, "friction");
    b.group = f1<i64>(r, "group");
    return b;
}

inline Statics Statics::from_py(nanobind::handle r) {
    Statics s;
    s.n_static = scalar<i64>(r, "n_static");
    s.pos = f2<double>(r, "pos");
    s.rot = f3<double>(r, "rot");
    s.ext = f2<double>(r, "ext");
    s.e = f1<double>(r, "e");
    s.mu = f1<double>(r, "mu");
    s.lo = f2<double>(r, "lo");
    s.hi = f2<double>(r, "hi");
    s.ground = scalar<bool>(r, "ground");
    s.gn = f1<double>(r, "gn");
    s.goff = scalar<double>(r, "goff");
    s.g_e = scalar<double>(r, "g_e");
    s.g_mu = scalar<double>(r, "g_mu");
    return s;
}

inline Settings Settings::from_py(nanobind::handle r) {
    Settings c;
    c.do_kick = scalar<bool>(r, "do_kick");
    c.do_sleep = scalar<bool>(r, "do_sleep");
    c.iso_shortcut = scalar<bool>(r, "iso_shortcut");
    c.velocity_iterations = scalar<i64>(r, "velocity_iterations");
    c.max_velocity_iterations = scalar<i64>(r, "max_velocity_iterations");
    c.velocity_tolerance = scalar<double>(r, "velocity_tolerance");
    c.over_relaxation = scalar<double>(r, "over_relaxation");
    c.position_iterations = scalar<i64>(r, "position_iterations");
    c.allowed_penetration = scalar<double>(r, "allowed_penetration");
    c.position_correction_rate = scalar<double>(r, "position_correction_rate");
    c.max_correction_speed = scalar<double>(r, "max_correction_speed");
    c.speculative_distance = scalar<double>(r, "speculative_distance");
    c.restitution_threshold = scalar<double>(r, "restitution_threshold");
    c.friction_anchor_distance = scalar<double>(r, "friction_anchor_distance");
    c.sleep_speed = scalar<double>(r, "sleep_speed");
    c.sleep_time = scalar<double>(r, "sleep_time");
    c.warm_starting = scalar<bool>(r, "warm_starting");
    c.projection_iterations = scalar<i64>(r, "projection_iterations");
    c.projection_depth = scalar<double>(r, "projection_depth");
    c.static_friction_anchors = scalar<bool>(r, "static_friction_anchors");
    c.exact_contact_motion = scalar<bool>(r, "exact_contact_motion");
    c.friction_newton_iters = scalar<i64>(r, "friction_newton_iters");
    c.friction_newton_tol = scalar<double>(r, "friction_newton_tol");
    c.block_reg = scalar<double>(r, "block_reg");
    c.friction_anchor_rate = scalar<double>(r, "friction_anchor_rate");
    c.friction_anchor_slide_frac = scalar<double>(r, "friction_anchor_slide_frac");
    c.projection_rings = scalar<i64>(r, "projection_rings");
    c.soft_step = scalar<bool>(r, "soft_step");
    c.substeps = scalar<i64>(r, "substeps");
    c.contact_hertz = scalar<double>(r, "contact_hertz");
    c.contact_damping_ratio = scalar<double>(r, "contact_damping_ratio");
    return c;
}

inline BodyState BodyState::from_py(nanobind::handle r) {
    BodyState x;
    x.position = f2<double>(r, "position");
    x.linear_momentum = f2<double>(r, "linear_momentum");
    x.quat_wxyz = f2<double>(r, "quat_wxyz");
    x.rotation = f3<double>(r, "rotation");
    x.angular_momentum = f2<double>(r, "angular_momentum");
    return x;
}

inline SampleState SampleState::from_py(nanobind::handle r) {
    SampleState x;
    x.position = f3<double>(r, "position");
    x.linear_momentum = f3<double>(r, "linear_momentum");
    x.quat_wxyz = f3<double>(r, "quat_wxyz");
    x.rotation = f4<double>(r, "rotation");
    x.angular_momentum = f3<double>(r, "angular_momentum");
    return x;
}

inline SleepState SleepState::from_py(nanobind::handle r) {
    SleepState s;
    s.awake = f1<i64>(r, "awake");
    s.timer = f1<double>(r, "timer");
    s.island_of = f1<i64>(r, "island_of");
    s.island_counter = f1<i64>(r, "island_counter");
    return s;
}

inline FlowAnchors FlowAnchors::from_py(nanobind::handle r) {
    FlowAnchors a;
    a.anchor_quat_wxyz = f2<double>(r, "anchor_quat_wxyz");
    a.anchor_L_world = f2<double>(r, "anchor_L_world");
    a.anchor_steps = f1<i64>(r, "anchor_steps");
    a.anchor_dt_s = f1<double>(r, "anchor_dt_s");
    return a;
}

// A 1-D view of a one-column Buf2 (pid, keys, idx, ...).
template <class T>
inline V1<T> col(Buf2<T>& b) {
    return V1<T>{b.data.data(), b.rows};
}

// A bool buffer (std::vector<bool> has no bool*).
struct BoolBuf {
    std::unique_ptr<bool[]> p;
    i64 n = 0;
    void resize(i64 m) {
        if (m != n) {
            p.reset(new bool[m > 0 ? m : 1]);
            n = m;
        }
        for (i64 i = 0; i < n; ++i) p[i] = false;
    }
    V1<bool> view() { return V1<bool>{p.get(), n}; }
};

// The stages' work arrays (step.py's Scratch; make_scratch). Rows G..G+S-1 of lo/hi: the static
// boxes; row N of the solver arrays: the static dummy with zero inverse mass. All zero after
// reset() but flow_c (filled before read); lo/hi rows of the static boxes copied from Statics.
struct Scratch {
    i64 n = -1, ns = -1;
    Buf2<double> lo, hi, reach;                       // (G+S, 3), (G+S, 3), (G+S,): geoms
    Buf2<i64> in_contact;                             // (N+1,)
    Buf2<double> bm, bI, bv, bw, bv0, bw0, pv, pw;    // (N+1,), (N+1, 6), (N+1, 3) ...
    Buf2<double> p0, l0, l_drift;                     // (N, 3)
    Buf2<i64> parent;                                 // (N,)
    Buf2<double> isl_time;                            // (N,)
    Buf2<i64> isl_sup;                                // (N,)
    ColliderBuffers cb;                               // nrm pts sep fid work poly
    ConstraintGraph graph;                            // the colouring of this step's manifolds
    SolverLanes lanes;                                // the velocity solve's packed groups
    Buf2<i64> hot;                                    // (N+1,)
    Buf2<double> dx_step, proj_dx, proj_dth;          // (N+1, 3)
    Buf2<i64> pushed, push_root;                      // (N+1,)
    Buf2<i64> exact_man;                              // (N+1,) mark_exact
    Buf2<double> flow_c;                              // (N, N_FLOW)
    BoolBuf flow_ok;                                  // (N,)
    // the project stage's own work arrays
    Buf2<i64> ring;                                   // (N+1,)
    std::vector<char> done;                           // (pairs,)
    std::vector<ProjectPoint> proj_points;            // the pass's points, grown

    // Work arrays for n bodies with n_geoms geoms and the statics' boxes, all zero (allocation
    // only when the sizes change).
    void make(i64 n_bodies, i64 n_geoms, const Statics& st);
};

// The contact cache kept between calls (step.py's ContactCache): the previous step's manifolds
// sorted by key (mi0, mf0, pf0, pid0, n_man0, keys0, idx0), spare buffers for this step's (mi1,
// mf1, pf1, pid1), and the broadphase's pair buffer; besides, the contact log of the last call
// and the stages' work arrays.
struct ContactCache {
    Buf2<i64> mi0;
    Buf2<double> mf0, pf0;
    Buf2<i64> pid0;  // one column
    i64 n_man0 = 0;
    // (N, 12) each body's position and row-major rotation at the start of the step that made
    // mi0 (the contact rows' separations carry the anchors from there: record_contacts)
    Buf2<double> pose0;
    Buf2<i64> keys0, idx0;  // one column
    Buf2<i64> mi1;
    Buf2<double> mf1, pf1;
    Buf2<i64> pid1;
    Buf2<i64> pairs;  // (K, 2)
    Buf2<i64> log_i;     // (rows, LOG_I_COLS)
    Buf2<double> log_f;  // (rows, LOG_F_COLS)
    Scratch sc;

    ContactCache(i64 cap_manifolds, i64 cap_points);
};

}  // namespace rb
