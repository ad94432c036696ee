// Bindings of the collision stages (broad_phase, narrowphase, box_box, manifold, collide, island,
// measure), each callable on its own from Python for the tests and tools; the Python modules of
// rblog/engine/contact/ wrap them under their documented names.
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <cstddef>  // offsetof
#include <cstring>
#include <string>

#include "common/py.hpp"
#include "engine/bind.hpp"
#include "engine/collision.hpp"
#include "engine/hull.hpp"
#include "engine/records.hpp"

namespace rb {
namespace nb = nanobind;

namespace {

// A (rows, 2) int64 numpy array's first `keep` rows, as a Buf2 of at least its capacity.
Buf2<i64> pairs_from(nb::handle h, i64 keep) {
    V2<i64> p = v2<i64>(h, "pairs");
    Buf2<i64> b(p.n0, 2);
    if (p.n1 != 2) throw nb::type_error("pairs: expected 2 columns");
    std::memcpy(b.data.data(), p.p, sizeof(i64) * 2 * keep);
    return b;
}

// The pairs back in Python: the given array when they fit (written in place), else a new one.
nb::object pairs_to(nb::handle h, const Buf2<i64>& b, i64 count) {
    V2<i64> p = v2<i64>(h, "pairs");
    if (b.rows <= p.n0) {
        std::memcpy(p.p, b.data.data(), sizeof(i64) * 2 * count);
        return nb::borrow(h);
    }
    return nb::cast(rows_to_numpy(b, b.rows));
}

// The contact records' fields, in order (manifold.hpp): {"head": ..., "manifold": ...,
// "point": ..., "log_ids": ..., "log_values": ...}, each a list of (name, offset, width) in values of 8 bytes, for numpy structured
// dtypes (rblog/engine/contact/manifold.py).
nb::dict contact_fields() {
#define RB_F(R, f) nb::make_tuple(#f, (i64)(offsetof(R, f) / 8), (i64)(sizeof(R::f) / 8))
    nb::dict d;
    d["head"] = nb::make_tuple(RB_F(ManifoldHead, key), RB_F(ManifoldHead, a),
                               RB_F(ManifoldHead, b), RB_F(ManifoldHead, rec_a),
                               RB_F(ManifoldHead, rec_b), RB_F(ManifoldHead, start),
                               RB_F(ManifoldHead, count), RB_F(ManifoldHead, active));
    d["manifold"] = nb::make_tuple(
        RB_F(Manifold, normal), RB_F(Manifold, t1), RB_F(Manifold, t2), RB_F(Manifold, mu),
        RB_F(Manifold, e), RB_F(Manifold, acc), RB_F(Manifold, lu), RB_F(Manifold, piv),
        RB_F(Manifold, lu_ok), RB_F(Manifold, anchor_rot), RB_F(Manifold, anchor_pos),
        RB_F(Manifold, anchor_ok));
    d["point"] = nb::make_tuple(
        RB_F(ContactPoint, point), RB_F(ContactPoint, ra), RB_F(ContactPoint, rb),
        RB_F(ContactPoint, s), RB_F(ContactPoint, normal_mass), RB_F(ContactPoint, tangent_k),
        RB_F(ContactPoint, ln), RB_F(ContactPoint, l1), RB_F(ContactPoint, l2),
        RB_F(ContactPoint, lp), RB_F(ContactPoint, lws), RB_F(ContactPoint, w0),
        RB_F(ContactPoint, friction), RB_F(ContactPoint, s_end), RB_F(ContactPoint, impact),
        RB_F(ContactPoint, wt), RB_F(ContactPoint, kn), RB_F(ContactPoint, slip),
        RB_F(ContactPoint, slip_bias));
    d["log_ids"] = nb::make_tuple(RB_F(ContactLogIds, step), RB_F(ContactLogIds, a),
                                  RB_F(ContactLogIds, b), RB_F(ContactLogIds, kind));
    d["log_values"] = nb::make_tuple(
        RB_F(ContactLogValues, point), RB_F(ContactLogValues, normal),
        RB_F(ContactLogValues, separation), RB_F(ContactLogValues, normal_impulse),
        RB_F(ContactLogValues, friction));
#undef RB_F
    return d;
}

nb::dict collision_layout() {
    nb::dict d;
#define RB_PUT(name) d[#name] = name
    RB_PUT(MI_COLS); RB_PUT(MF_COLS); RB_PUT(PF_COLS);
    RB_PUT(LOG_I_COLS); RB_PUT(LOG_F_COLS);
    RB_PUT(MAX_CLIP_POINTS); RB_PUT(MAX_MANIFOLD_POINTS);
    RB_PUT(GEOM_SPHERE); RB_PUT(GEOM_BOX); RB_PUT(GEOM_CAPSULE); RB_PUT(GEOM_CYLINDER);
    RB_PUT(GEOM_HULL); RB_PUT(GEOM_PLANE);
#undef RB_PUT
    d["_AREA_EPS"] = AREA_EPS;
    nb::list table;  // (lower code, higher code) pairs that have a collider
    for (i64 lo = 0; lo < N_GEOM; ++lo)
        for (i64 hi = lo; hi < N_GEOM; ++hi)
            if (narrowphase_fn(lo, hi) != nullptr) table.append(nb::make_tuple(lo, hi));
    d["NARROWPHASE_TABLE"] = table;
    return d;
}


// One pair's arguments from numpy for the single-pair bindings (collide_np, parted_along_np):
// centres and sizes (3,), rotations (3, 3), and one more (3,) vector (`w_name`: the plane's
// normal, an axis), checked; `fn` names the binding in the error.
struct PairNp {
    V1<double> ca, sa, cb, sb, w;
    V2<double> ra, rb;
};
PairNp pair_np(const char* fn, nb::handle ca, nb::handle ra, nb::handle sa, nb::handle cb,
               nb::handle rb, nb::handle sb, nb::handle w, const char* w_name) {
    require_collision_constants();
    PairNp q{v1<double>(ca, "a_center"), v1<double>(sa, "a_size"), v1<double>(cb, "b_center"),
             v1<double>(sb, "b_size"),   v1<double>(w, w_name),    v2<double>(ra, "a_rot"),
             v2<double>(rb, "b_rot")};
    if (q.ca.n0 != 3 || q.cb.n0 != 3 || q.sa.n0 != 3 || q.sb.n0 != 3 || q.w.n0 != 3 ||
        q.ra.n0 != 3 || q.ra.n1 != 3 || q.rb.n0 != 3 || q.rb.n1 != 3)
        throw nb::value_error((std::string(fn) + ": centres, sizes, " + w_name +
                               " (3,), rotations (3, 3)").c_str());
    return q;
}

}  // namespace


void bind_collision(nb::module_& m) {
    m.def(
        "set_collision_constants",
        [](double manifold_touch_band_m, double edge_rel_tol, double face_rel_tol,
           double axis_abs_tol, double edge_parallel_tol, double friction_anchor_max_drift_m,
           i64 static_body, double convex_gjk_tol_m, double convex_epa_tol_m,
           i64 convex_max_iter) {
            CollisionConstants& c = collision_constants();
            c.manifold_touch_band_m = manifold_touch_band_m;
            c.edge_rel_tol = edge_rel_tol;
            c.face_rel_tol = face_rel_tol;
            c.axis_abs_tol = axis_abs_tol;
            c.edge_parallel_tol = edge_parallel_tol;
            c.friction_anchor_max_drift_m = friction_anchor_max_drift_m;
            c.static_body = static_body;
            c.convex_gjk_tol_m = convex_gjk_tol_m;
            c.convex_epa_tol_m = convex_epa_tol_m;
            c.convex_max_iter = convex_max_iter;
            c.set = true;
        },
        nb::arg("manifold_touch_band_m"), nb::arg("edge_rel_tol"), nb::arg("face_rel_tol"),
        nb::arg("axis_abs_tol"), nb::arg("edge_parallel_tol"),
        nb::arg("friction_anchor_max_drift_m"), nb::arg("static_body"),
        nb::arg("convex_gjk_tol_m"), nb::arg("convex_epa_tol_m"), nb::arg("convex_max_iter"),
        "The collision tolerances of rblog.engine.constants (their one home), set once at import "
        "of rblog.engine.contact.narrowphase.");
    m.def(
        "collision_constants",
        []() {
            const CollisionConstants& c = collision_constants();
            nb::dict d;
            d["MANIFOLD_TOUCH_BAND_M"] = c.manifold_touch_band_m;
            d["EDGE_REL_TOL"] = c.edge_rel_tol;
            d["FACE_REL_TOL"] = c.face_rel_tol;
            d["AXIS_ABS_TOL"] = c.axis_abs_tol;
            d["EDGE_PARALLEL_TOL"] = c.edge_parallel_tol;
            d["FRICTION_ANCHOR_MAX_DRIFT_M"] = c.friction_anchor_max_drift_m;
            d["STATIC_BODY"] = c.static_body;
            d["CONVEX_GJK_TOL_M"] = c.convex_gjk_tol_m;
            d["CONVEX_EPA_TOL_M"] = c.convex_epa_tol_m;
            d["CONVEX_MAX_ITER"] = c.convex_max_iter;
            d["set"] = c.set;
            return d;
        },
        "The collision constants as C++ holds them (tests).");
    m.def("collision_layout", &collision_layout,
          "The records' row widths, the contact log's columns, the GEOM_* codes and the "
          "narrowphase table's keys, as C++ holds them (manifold.py and narrowphase.py read "
          "them).");
    m.def("contact_fields", &contact_fields,
          "The contact records' fields (manifold.hpp): {'head' | 'manifold' | 'point': "
          "((name, offset, width), ...)}, offsets and widths in 8-byte values.");

    m.def(
        "register_hull",
        [](nb::handle vert, nb::handle fnrm, nb::handle foff, nb::handle fstart,
           nb::handle fvert) {
            return register_hull(v2<double>(vert, "vertices"), v2<double>(fnrm, "face_normal"),
                                 v1<double>(foff, "face_offset"), v1<i64>(fstart, "face_start"),
                                 v1<i64>(fvert, "face_vertices"));
        },
        nb::arg("vertices"), nb::arg("face_normal"), nb::arg("face_offset"),
        nb::arg("face_start"), nb::arg("face_vertices"),
        "Add a hull to the process's hull table (hull.hpp), or find the same one: its id, the "
        "first entry of a hull body's size row.");
    m.def("hull_max_face_vertices", []() { return HULL_MAX_FACE_VERTICES; });

    m.def(
        "collide_np",
        [](i64 ga, i64 gb, nb::handle ca, nb::handle ra, nb::handle sa, nb::handle cb,
           nb::handle rb_, nb::handle sb, nb::handle pn, double poff, double spec) {
            const PairNp q = pair_np("collide_np", ca, ra, sa, cb, rb_, sb, pn, "plane_normal");
            ColliderBuffers buf = collider_buffers();
            i64 res = collide(ga, gb, q.ca.p, q.ra.p, q.sa.p, q.cb.p, q.rb.p, q.sb.p, q.w.p, poff,
                              spec, buf);
            std::vector<double> nrm(buf.nrm, buf.nrm + 6);
            std::vector<double> pts(&buf.pts[0][0], &buf.pts[0][0] + 3 * MAX_CLIP_POINTS);
            std::vector<double> sep(buf.sep, buf.sep + MAX_CLIP_POINTS);
            std::vector<i64> fid(buf.fid, buf.fid + MAX_CLIP_POINTS);
            return nb::make_tuple(res, to_numpy(std::move(nrm), {6}),
                                  to_numpy(std::move(pts), {(size_t)MAX_CLIP_POINTS, 3}),
                                  to_numpy(std::move(sep), {(size_t)MAX_CLIP_POINTS}),
                                  to_numpy(std::move(fid), {(size_t)MAX_CLIP_POINTS}));
        },
        nb::arg("geom_a"), nb::arg("geom_b"), nb::arg("a_center"), nb::arg("a_rot"),
        nb::arg("a_size"), nb::arg("b_center"), nb::arg("b_rot"), nb::arg("b_size"),
        nb::arg("plane_normal"), nb::arg("plane_offset"), nb::arg("spec"),
        "collide() on one pair: (res = n1 + 8 n2 or -1, nrm (6,), pts (12, 3), sep (12,), "
        "fid (12,)), the collider buffers after the call.");

    m.def(
        "parted_along_np",
        [](i64 ga, i64 gb, nb::handle ca, nb::handle ra, nb::handle sa, nb::handle cb,
           nb::handle rb_, nb::handle sb, nb::handle u, double spec) {
            const PairNp q = pair_np("parted_along_np", ca, ra, sa, cb, rb_, sb, u, "axis");
            return parted_along(ga, gb, q.ca.p, q.ra.p, q.sa.p, q.cb.p, q.rb.p, q.sb.p, q.w.p,
                                spec);
        },
        nb::arg("geom_a"), nb::arg("geom_b"), nb::arg("a_center"), nb::arg("a_rot"),
        nb::arg("a_size"), nb::arg("b_center"), nb::arg("b_rot"), nb::arg("b_size"),
        nb::arg("axis"), nb::arg("spec"),
        "parted_along() on one pair: True when collide() at spec provably returns no point, "
        "from the gap along the axis (from b into a).");

    m.def(
        "tangent_basis",
        [](double nx, double ny, double nz) {
            std::array<double, 6> t = tangent_basis(nx, ny, nz);
            return nb::make_tuple(t[0], t[1], t[2], t[3], t[4], t[5]);
        },
        nb::arg("nx"), nb::arg("ny"), nb::arg("nz"));

    m.def(
        "body_aabbs",
        [](nb::handle geom, nb::handle size, nb::handle radius, nb::handle inv_mass,
           nb::handle inv_inertia, nb::handle awake, nb::handle position,
           nb::handle linear_momentum, nb::handle rotation, nb::handle angular_momentum,
           double h, double margin, nb::handle lo, nb::handle hi, nb::handle reach) {
            auto a = std::make_tuple(
                v1<i64>(geom, "geom"), v2<double>(size, "size"), v1<double>(radius, "radius"),
                v1<double>(inv_mass, "inv_mass"), v2<double>(inv_inertia, "inv_inertia"),
                v1<i64>(awake, "awake"), v2<double>(position, "position"),
                v2<double>(linear_momentum, "linear_momentum"), v3<double>(rotation, "rotation"),
                v2<double>(angular_momentum, "angular_momentum"), v2<double>(lo, "lo"),
                v2<double>(hi, "hi"), v1<double>(reach, "reach"));
            nb::gil_scoped_release r;
            const IdentityGeoms ig(std::get<0>(a), std::get<1>(a), &std::get<2>(a));
            body_aabbs(ig.g, std::get<3>(a), std::get<4>(a), std::get<5>(a), std::get<6>(a),
                       std::get<7>(a), std::get<8>(a), std::get<9>(a), h, margin,
                       std::get<10>(a), std::get<11>(a), std::get<12>(a));
        },
        "broadphase.body_aabbs, in place (lo, hi, reach).");

    m.def(
        "sweep_and_prune",
        [](i64 n_items, i64 n_dyn, nb::handle lo, nb::handle hi, nb::handle group,
           nb::handle awake, nb::handle pairs, nb::handle body) {
            V2<double> vlo = v2<double>(lo, "lo"), vhi = v2<double>(hi, "hi");
            V1<i64> vg = v1<i64>(group, "group"), va = v1<i64>(awake, "awake");
            if (vlo.n0 < n_items || vhi.n0 < n_items || vlo.n1 != 3 || vhi.n1 != 3)
                throw nb::value_error("sweep_and_prune: lo, hi must be (>= n_items, 3)");
            // the items' bodies: given, or item i = body i
            std::vector<i64> own;
            V1<i64> vb;
            if (body.is_none()) {
                own.resize((size_t)std::max<i64>(n_dyn, 0));
                for (i64 i = 0; i < n_dyn; ++i) own[(size_t)i] = i;
                vb = V1<i64>{own.data(), n_dyn};
            } else {
                vb = v1<i64>(body, "body");
                if (vb.n0 < n_dyn) throw nb::value_error("sweep_and_prune: body (>= n_dyn,)");
            }
            Buf2<i64> b = pairs_from(pairs, 0);
            i64 count;
            {
                nb::gil_scoped_release r;
                count = sweep_and_prune(n_items, n_dyn, vlo, vhi, vb, vg, va, b);
            }
            return nb::make_tuple(pairs_to(pairs, b, count), count);
        },
        nb::arg("n_items"), nb::arg("n_dyn"), nb::arg("lo"), nb::arg("hi"), nb::arg("group"),
        nb::arg("awake"), nb::arg("pairs"), nb::arg("body") = nb::none(),
        "broadphase.sweep_and_prune (body: the items' bodies, None: item i is body i): (pairs, "
        "count); pairs is a new array when it had to grow.");

    m.def(
        "ground_pairs",
        [](i64 n_dyn, i64 n_static, nb::handle gn, double goff, nb::handle lo, nb::handle hi,
           nb::handle pairs, i64 n_pairs) {
            V1<double> vgn = v1<double>(gn, "gn");
            V2<double> vlo = v2<double>(lo, "lo"), vhi = v2<double>(hi, "hi");
            Buf2<i64> b = pairs_from(pairs, n_pairs);
            i64 count = ground_pairs(n_dyn, n_static, vgn, goff, vlo, vhi, b, n_pairs);
            return nb::make_tuple(pairs_to(pairs, b, count), count);
        },
        "broadphase.ground_pairs (gn, goff: the Statics' ground): (pairs, count).");

    m.def(
        "pair_min_separations",
        [](nb::handle bodies, i64 n_static, nb::handle sb_pos,
           nb::handle sb_rot, nb::handle sb_ext, nb::handle sb_lo, nb::handle sb_hi, bool ground,
           nb::handle gn, double goff, nb::handle position, nb::handle rotation, double margin) {
            const Bodies bd = Bodies::from_py(bodies);
            V1<i64> vgroup = bd.group;
            V2<double> vinvi = bd.inv_inertia;
            V1<double> vim = bd.inv_mass;
            V2<double> vsp = v2<double>(sb_pos, "sb_pos"), vse = v2<double>(sb_ext, "sb_ext");
            V3<double> vsr = v3<double>(sb_rot, "sb_rot");
            V2<double> vsl = v2<double>(sb_lo, "sb_lo"), vsh = v2<double>(sb_hi, "sb_hi");
            V1<double> vgn = v1<double>(gn, "gn");
            V2<double> vpos = v2<double>(position, "position");
            V3<double> vrot = v3<double>(rotation, "rotation");
            const i64 n = vim.n0;
            if (vpos.n0 != n || vpos.n1 != 3 || vrot.n0 != n || vrot.n1 != 3 || vrot.n2 != 3)
                throw nb::value_error("pair_min_separations: position (N, 3), rotation (N, 3, 3)");
            for (i64 k = 0; k < bd.geom.n0; ++k)
                if (bd.geom_body[k] < 0 || bd.geom_body[k] >= n)
                    throw nb::value_error("pair_min_separations: geom_body in 0..N-1");
            std::vector<double> out;
            {
                nb::gil_scoped_release r;
                out = pair_min_separations(bd.geoms(), vim, vinvi, vgroup, n_static, vsp,
                                           vsr, vse, vsl, vsh, ground, vgn, goff, vpos, vrot,
                                           margin);
            }
            size_t k = out.size();
            return to_numpy(std::move(out), {k});
        },
        "measure.separations' kernel: least separation of every touching pair (m).");
    // ---- the step's stage kernels on numpy arrays (tests, benchmarks, cross-checks) ----------
    m.def(
        "collide_pairs",
        [](nb::handle pairs, i64 n_pairs, i64 n_dyn, i64 n_static, nb::handle geom,
           nb::handle size, nb::handle awake, nb::handle position, nb::handle rotation,
           nb::handle reach, double margin, nb::handle restitution, nb::handle friction,
           nb::handle accel, nb::handle sb_pos, nb::handle sb_rot, nb::handle sb_ext,
           nb::handle sb_e, nb::handle sb_mu, nb::handle gn, double goff, double g_e, double g_mu,
           nb::handle prev_mi, nb::handle prev_mf, nb::handle prev_pf, nb::handle prev_pid,
           nb::handle prev_keys, nb::handle prev_idx, i64 prev_n, nb::handle mi, nb::handle mf,
           nb::handle pf, nb::handle pid, bool warm, double anchor_distance) {
            V2<i64> vpairs = v2<i64>(pairs, "pairs");
            V1<i64> vgeom = v1<i64>(geom, "geom"), vawake = v1<i64>(awake, "awake");
            V2<double> vsize = v2<double>(size, "size"), vpos = v2<double>(position, "position");
            V3<double> vrot = v3<double>(rotation, "rotation");
            V1<double> vreach = v1<double>(reach, "reach");
            V1<double> vrest = v1<double>(restitution, "restitution"),
                       vfric = v1<double>(friction, "friction");
            V2<double> vacc = v2<double>(accel, "accel");
            V2<double> vsp = v2<double>(sb_pos, "sb_pos"), vse = v2<double>(sb_ext, "sb_ext");
            V3<double> vsr = v3<double>(sb_rot, "sb_rot");
            V1<double> vsbe = v1<double>(sb_e, "sb_e"), vsbmu = v1<double>(sb_mu, "sb_mu");
            V1<double> vgn = v1<double>(gn, "gn");
            V1<ManifoldHead> vpmi = mi_arg(prev_mi, "prev_mi");
            V1<Manifold> vpmf = mf_arg(prev_mf, "prev_mf");
            V1<ContactPoint> vppf = pf_arg(prev_pf, "prev_pf");
            V1<i64> vppid = v1<i64>(prev_pid, "prev_pid"), vpk = v1<i64>(prev_keys, "prev_keys"),
                    vpi = v1<i64>(prev_idx, "prev_idx");
            V1<ManifoldHead> vmi = mi_arg(mi);
            V1<Manifold> vmf = mf_arg(mf);
            V1<ContactPoint> vpf = pf_arg(pf);
            V1<i64> vpid = v1<i64>(pid, "pid");
            if (vmi.n0 < 2 * n_pairs || vmf.n0 < 2 * n_pairs || vpf.n0 < 8 * n_pairs ||
                vpid.n0 < 8 * n_pairs)
                throw nb::value_error("collide_pairs: room for 2 n_pairs manifolds and 8 n_pairs "
                                      "points needed");
            CollideCount r;
            {
                nb::gil_scoped_release g;
                ColliderBuffers buf = collider_buffers();
                const IdentityGeoms ig(vgeom, vsize);
                r = collide_pairs(vpairs, n_pairs, n_dyn, n_static, ig.g, vawake, vpos,
                                  vrot, vreach, margin, vrest, vfric, vacc, vsp, vsr, vse, vsbe,
                                  vsbmu, vgn, goff, g_e, g_mu, vpmi, vpmf, vppf, vppid, vpk, vpi,
                                  prev_n, vmi, vmf, vpf, vpid, warm, anchor_distance, buf);
            }
            return nb::make_tuple(r.n_man, r.n_pts);
        },
        "collide.collide_pairs on numpy arrays (mi, mf, pf, pid with room for 2 n_pairs "
        "manifolds and 8 n_pairs points): (n_man, n_pts).");

    m.def(
        "sort_manifolds",
        [](nb::handle mi, i64 n_man, nb::handle keys, nb::handle idx) {
            V1<ManifoldHead> vmi = mi_arg(mi);
            V1<i64> vk = v1<i64>(keys, "sorted_keys"), vi = v1<i64>(idx, "sorted_idx");
            if (vk.n0 < n_man || vi.n0 < n_man || vmi.n0 < n_man)
                throw nb::value_error("sort_manifolds: arrays shorter than n_man");
            sort_manifolds(vmi, n_man, vk, vi);
        });

    m.def(
        "update_sleep",
        [](i64 n_dyn, nb::handle mi, nb::handle pf, i64 n_man, nb::handle awake,
           nb::handle sleep_timer, nb::handle island_of, nb::handle island_counter,
           nb::handle linear_momentum, nb::handle angular_momentum, nb::handle inv_mass,
           nb::handle inv_inertia, nb::handle radius, double h, double sleep_speed,
           double sleep_time, nb::handle parent, nb::handle island_min_time,
           nb::handle island_supported) {
            return update_sleep(
                n_dyn, mi_arg(mi), pf_arg(pf), n_man, v1<i64>(awake, "awake"),
                v1<double>(sleep_timer, "sleep_timer"), v1<i64>(island_of, "island_of"),
                v1<i64>(island_counter, "island_counter"),
                v2<double>(linear_momentum, "linear_momentum"),
                v2<double>(angular_momentum, "angular_momentum"), v1<double>(inv_mass, "inv_mass"),
                v2<double>(inv_inertia, "inv_inertia"), v1<double>(radius, "radius"), h,
                sleep_speed, sleep_time, v1<i64>(parent, "parent"),
                v1<double>(island_min_time, "island_min_time"),
                v1<i64>(island_supported, "island_supported"));
        });

    m.def(
        "wake_pushed",
        [](nb::handle mi, nb::handle mf, nb::handle pf, i64 n_man, i64 n_dyn, nb::handle awake,
           nb::handle sleep_timer, nb::handle island_of, nb::handle position,
           nb::handle linear_momentum, nb::handle angular_momentum, nb::handle force,
           nb::handle torque, double h) {
            return wake_pushed(mi_arg(mi), mf_arg(mf), pf_arg(pf),
                               n_man, n_dyn, v1<i64>(awake, "awake"),
                               v1<double>(sleep_timer, "sleep_timer"),
                               v1<i64>(island_of, "island_of"), v2<double>(position, "position"),
                               v2<double>(linear_momentum, "linear_momentum"),
                               v2<double>(angular_momentum, "angular_momentum"),
                               v2<double>(force, "force"), v2<double>(torque, "torque"), h);
        });

    m.def(
        "wake_touched",
        [](nb::handle pairs, i64 n_pairs, i64 n_dyn, i64 n_static, nb::handle geom,
           nb::handle size, nb::handle awake, nb::handle sleep_timer, nb::handle island_of,
           nb::handle position, nb::handle rotation, nb::handle reach,
           double speculative_distance, double allowed_penetration, nb::handle sb_pos,
           nb::handle sb_rot, nb::handle sb_ext, nb::handle gn,
           double goff, nb::handle linear_momentum, nb::handle angular_momentum,
           nb::handle force, nb::handle torque, double h, bool do_kick, nb::handle inv_mass,
           nb::handle accel, nb::handle radius, nb::handle inv_inertia) {
            ColliderBuffers buf = collider_buffers();
            const IdentityGeoms ig(v1<i64>(geom, "geom"), v2<double>(size, "size"));
            return wake_touched(
                v2<i64>(pairs, "pairs"), n_pairs, n_dyn, n_static, ig.g, v1<i64>(awake, "awake"),
                v1<double>(sleep_timer, "sleep_timer"), v1<i64>(island_of, "island_of"),
                v2<double>(position, "position"), v3<double>(rotation, "rotation"),
                v1<double>(reach, "reach"), speculative_distance, allowed_penetration,
                v2<double>(sb_pos, "sb_pos"),
                v3<double>(sb_rot, "sb_rot"), v2<double>(sb_ext, "sb_ext"), v1<double>(gn, "gn"),
                goff, v2<double>(linear_momentum, "linear_momentum"),
                v2<double>(angular_momentum, "angular_momentum"), v2<double>(force, "force"),
                v2<double>(torque, "torque"), h, do_kick, buf, v1<double>(inv_mass, "inv_mass"),
                v2<double>(accel, "accel"), v1<double>(radius, "radius"),
                v2<double>(inv_inertia, "inv_inertia"));
        });
}

}  // namespace rb
