// rblog.adapters._hook: the per-step hook of rblog.adapters.mujoco in one call (the Python
// version is StepImpulses.__call__ in rblog/adapters/_mujoco_step.py; the derivation is in
// rblog/adapters/mujoco.py). After mj_step, with Euler or the implicit integrators, mjData holds
// the step's start in everything but qpos and qvel; the hook
//   1. puts the step's start velocity v0 and the acceleration MuJoCo integrated, a = (v1 - v0)/h,
//      into d->qvel and d->qacc, calls mj_rnePostConstraint (and mj_mulM(a) for the implicit
//      integrators), and puts qvel and qacc back;
//   2. copies the pieces of mjData's buffer that hold the row's fields into row k (Rows in
//      Python decides the pieces), and v1 into its row; v0 = v1.
// ContactCapture copies (or decodes) the contacts of the logged steps (below); mujoco_resolve.cpp turns a
// block's rows into impulses and states.
// It holds raw addresses: of d's arrays (mjData's buffer stays where it is for d's life), of the
// Python-owned buffers (never reallocated while the hook lives), and of MuJoCo's two functions
// (looked up by ctypes in the libmujoco the bindings loaded). No MuJoCo header is needed.
#include <nanobind/nanobind.h>
#include <nanobind/stl/vector.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/ndarray.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <tuple>
#include <utility>
#include <vector>

#include "common/py.hpp"

namespace nb = nanobind;

namespace rb {
void bind_resolve(nb::module_& m);  // mujoco_resolve.cpp
}

namespace {

using RneFn = void (*)(const void*, void*);
using MulMFn = void (*)(const void*, void*, double*, const double*);

struct StepHook {
    RneFn rne;
    MulMFn mulm;  // null: not an implicit integrator
    const void* m;
    void* d;
    double* qvel;
    double* qacc;
    int nv;
    double inv_h;
    double* rows;  // (cap, width)
    long width;
    double* v1;  // (cap, nv)
    double* v0;  // (nv,)
    double* ma;  // (cap, nv) or null
    int cap;
    std::vector<std::tuple<double*, long, long>> pieces;  // source, length, offset in the row
    std::vector<double> qacc_save;

    StepHook(std::uintptr_t rne_fn, std::uintptr_t mulm_fn, std::uintptr_t m_, std::uintptr_t d_,
             std::uintptr_t qvel_, std::uintptr_t qacc_, int nv_, double h,
             std::uintptr_t rows_, long width_, std::uintptr_t v1_, std::uintptr_t v0_,
             std::uintptr_t ma_, int cap_, std::vector<std::tuple<std::uintptr_t, long, long>> p)
        : rne(reinterpret_cast<RneFn>(rne_fn)), mulm(reinterpret_cast<MulMFn>(mulm_fn)),
          m(reinterpret_cast<const void*>(m_)), d(reinterpret_cast<void*>(d_)),
          qvel(reinterpret_cast<double*>(qvel_)), qacc(reinterpret_cast<double*>(qacc_)), nv(nv_),
          inv_h(1.0 / h), rows(reinterpret_cast<double*>(rows_)), width(width_),
          v1(reinterpret_cast<double*>(v1_)), v0(reinterpret_cast<double*>(v0_)),
          ma(reinterpret_cast<double*>(ma_)), cap(cap_), qacc_save(nv_ > 0 ? nv_ : 1) {
        for (auto& [src, n, off] : p) {
            if (off < 0 || n < 0 || off + n > width) throw std::invalid_argument("piece outside the row");
            pieces.emplace_back(reinterpret_cast<double*>(src), n, off);
        }
        if (!rne || !m || !d) throw std::invalid_argument("null function or model");
    }

    // gather the step that just ended into row k; returns k + 1
    int step(int k) {
        if (k < 0 || k >= cap) throw std::out_of_range("row index outside the block");
        double* v1k = v1 + (long)k * nv;
        std::memcpy(v1k, qvel, sizeof(double) * nv);
        std::memcpy(qacc_save.data(), qacc, sizeof(double) * nv);
        for (int i = 0; i < nv; ++i) {
            qacc[i] = (v1k[i] - v0[i]) * inv_h;
            qvel[i] = v0[i];
        }
        rne(m, d);
        if (mulm && ma) mulm(m, d, ma + (long)k * nv, qacc);
        std::memcpy(qvel, v1k, sizeof(double) * nv);
        std::memcpy(qacc, qacc_save.data(), sizeof(double) * nv);
        double* row = rows + (long)k * width;
        for (auto& [src, n, off] : pieces) std::memcpy(row + off, src, sizeof(double) * n);
        std::memcpy(v0, v1k, sizeof(double) * nv);
        return k + 1;
    }
};

// ContactCapture: at a logged step, the contacts of an MjData: its first ncon mjContact structs
// (at `base`, `stride` bytes each: the start of mjData's arena, which stays where it is) and its
// efc_force. Raw (copied as they are, decoded a block at a time in Python: decode_contacts in
// rblog/adapters/_mujoco_model.py), or, once decode_with() is set, decoded right there into the
// contract's contact rows (rows()), the formulas of decode_contacts in the same order.
struct ContactCapture {
    const std::uint8_t* con_base = nullptr;
    long con_stride = 0, con_count = 0;
    std::vector<std::int64_t> cap_step, cap_ncon, cap_nefc;
    std::vector<std::uint8_t> cap_raw;
    std::vector<double> cap_efc;
    // the decoder: byte offsets of the mjContact fields dist, pos, frame, friction, dim, geom,
    // exclude, efc_address (float64, int32), the log body of each geom (-1: static), the cone
    bool decoding = false, pyramidal = false;
    double dt = 0.0;
    long off[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    std::vector<std::int64_t> geom_index;
    // the decoded rows since the last rows()
    std::vector<std::int64_t> o_step, o_a, o_b;
    std::vector<double> o_point, o_normal, o_sep, o_ni, o_fi;

    void contacts_at(std::uintptr_t base, long stride, long count) {
        if (!base || stride <= 0 || count <= 0) throw std::invalid_argument("contacts_at: bad view");
        con_base = reinterpret_cast<const std::uint8_t*>(base);
        con_stride = stride;
        con_count = count;
    }

    void decode_with(std::vector<long> offsets, std::vector<std::int64_t> gi, bool pyramidal_,
                     double dt_) {
        if (offsets.size() != 8) throw std::invalid_argument("decode_with: 8 field offsets");
        if (!con_base) throw std::logic_error("decode_with: contacts_at first");
        for (size_t i = 0; i < 8; ++i) {
            if (offsets[i] < 0 || offsets[i] + 8 > con_stride)
                throw std::invalid_argument("decode_with: a field outside the struct");
            off[i] = offsets[i];
        }
        if (!cap_step.empty()) throw std::logic_error("decode_with: raw captures pending");
        geom_index = std::move(gi);
        pyramidal = pyramidal_;
        dt = dt_;
        decoding = true;
    }

    void capture(std::int64_t step, long ncon,
                 nb::ndarray<const double, nb::ndim<1>, nb::c_contig, nb::device::cpu> efc) {
        if (!con_base) throw std::logic_error("capture: contacts_at first");
        if (ncon < 0 || ncon > con_count) throw std::out_of_range("capture: ncon outside the arena");
        append(step, ncon, efc.data(), (long)efc.shape(0));
    }

    void append(std::int64_t step, long ncon, const double* efc, long nefc) {
        if (decoding) {
            decode_step(step, ncon, efc, nefc);
            return;
        }
        cap_step.push_back(step);
        cap_ncon.push_back(ncon);
        cap_nefc.push_back((std::int64_t)nefc);
        cap_raw.insert(cap_raw.end(), con_base, con_base + ncon * con_stride);
        if (nefc > 0) cap_efc.insert(cap_efc.end(), efc, efc + nefc);
    }

    static double rd(const std::uint8_t* p, long o) {
        double v;
        std::memcpy(&v, p + o, 8);
        return v;
    }
    static std::int32_t ri(const std::uint8_t* p, long o) {
        std::int32_t v;
        std::memcpy(&v, p + o, 4);
        return v;
    }

    // decode_contacts on one step's contacts: local (normal, tangent 1, tangent 2) force on geom2
    // in the contact frame from efc_force (pyramidal: the sum of the 2 (dim - 1) edges, numpy's
    // pairwise order over the 10 gathered rows, zeros past the edges; tangent j = mu_j (f_2j -
    // f_2j+1); elliptic: the first three rows), the static geometry as body_b (normal and friction
    // flipped), kept when in the constraint, not excluded, on a logged body and not a separated
    // contact without push; impulses = force dt
    void decode_step(std::int64_t step, long ncon, const double* efc, long nefc) {
        constexpr int W = 10;  // _EFC_WIDTH
        const long ngeom = (long)geom_index.size();
        const std::uint8_t* rec = con_base;
        // room for every contact of the step, written in place; cut to the rows kept at the end
        const size_t n0 = o_step.size();
        size_t n = n0;
        auto size_to = [this](size_t rows) {
            for (auto* v : {&o_step, &o_a, &o_b}) v->resize(rows);
            for (auto* v : {&o_sep, &o_ni}) v->resize(rows);
            for (auto* v : {&o_point, &o_normal, &o_fi}) v->resize(3 * rows);
        };
        size_to(n0 + (size_t)ncon);
        for (long c = 0; c < ncon; ++c, rec += con_stride) {
            const std::int64_t adr = ri(rec, off[7]);
            if (adr < 0 || ri(rec, off[6]) != 0) continue;
            const int dim = ri(rec, off[4]);
            auto f = [&](int j) { return adr + j < nefc ? efc[adr + j] : 0.0; };
            double local[3] = {0.0, 0.0, 0.0};
            if (dim == 1) {
                local[0] = f(0);
            } else if (dim > 1) {
                if (pyramidal) {
                    const long width = 2L * (dim - 1);
                    double e[W];
                    for (int j = 0; j < W; ++j) e[j] = j < width ? f(j) : 0.0;
                    local[0] = ((((e[0] + e[1]) + (e[2] + e[3])) + ((e[4] + e[5]) + (e[6] + e[7]))) +
                                e[8]) + e[9];
                    local[1] = rd(rec, off[3]) * (e[0] - e[1]);
                    local[2] = rd(rec, off[3] + 8) * (e[2] - e[3]);
                } else {
                    local[0] = f(0);
                    local[1] = f(1);
                    local[2] = f(2);
                }
            }
            const int g0 = ri(rec, off[5]), g1 = ri(rec, off[5] + 4);
            if (g0 < 0 || g0 >= ngeom || g1 < 0 || g1 >= ngeom) {
                size_to(n);  // the rows decoded before it stay
                throw std::out_of_range("ContactCapture: a contact's geom outside the model");
            }
            std::int64_t a = geom_index[g1], b = geom_index[g0];
            double normal[3], fric[3];
            for (int i = 0; i < 3; ++i) {
                normal[i] = rd(rec, off[2] + 8 * i);
                fric[i] = local[1] * rd(rec, off[2] + 8 * (3 + i)) +
                          local[2] * rd(rec, off[2] + 8 * (6 + i));
            }
            if (a < 0) {
                std::swap(a, b);
                for (int i = 0; i < 3; ++i) {
                    normal[i] *= -1.0;
                    fric[i] *= -1.0;
                }
            }
            const double dist = rd(rec, off[0]);
            if (a < 0 || (local[0] <= 0.0 && dist > 0.0)) continue;
            o_step[n] = step;
            o_a[n] = a;
            o_b[n] = b;
            for (int i = 0; i < 3; ++i) {
                o_point[3 * n + i] = rd(rec, off[1] + 8 * i);
                o_normal[3 * n + i] = normal[i];
                o_fi[3 * n + i] = fric[i] * dt;
            }
            o_sep[n] = dist;
            o_ni[n] = local[0] * dt;
            ++n;
        }
        size_to(n);
    }

    // the decoded rows since the last call, as a dict for Recorder.write (None: no rows); cleared
    nb::object rows() {
        const size_t n = o_step.size();
        if (!n) return nb::none();
        nb::dict out;
        out["step"] = rb::to_numpy(std::move(o_step), {n});
        out["body_a"] = rb::to_numpy(std::move(o_a), {n});
        out["body_b"] = rb::to_numpy(std::move(o_b), {n});
        out["point"] = rb::to_numpy(std::move(o_point), {n, 3});
        out["normal"] = rb::to_numpy(std::move(o_normal), {n, 3});
        out["separation"] = rb::to_numpy(std::move(o_sep), {n});
        out["normal_impulse"] = rb::to_numpy(std::move(o_ni), {n});
        out["friction_impulse"] = rb::to_numpy(std::move(o_fi), {n, 3});
        for (auto* v : {&o_step, &o_a, &o_b}) {
            v->clear();
            v->reserve(n);
        }
        for (auto* v : {&o_sep, &o_ni}) {
            v->clear();
            v->reserve(n);
        }
        for (auto* v : {&o_point, &o_normal, &o_fi}) {
            v->clear();
            v->reserve(3 * n);
        }
        return out;
    }

    // the raw captures so far, as (step, ncon, nefc (S,) int64, raw bytes, efc_force), then cleared
    nb::tuple take() {

        return nb::make_tuple(to_numpy(cap_step), to_numpy(cap_ncon), to_numpy(cap_nefc),
                              to_numpy(cap_raw), to_numpy(cap_efc));
    }

    // v's contents, moved into an array numpy owns; v is left empty with the same capacity
    template <class T>
    static nb::ndarray<nb::numpy, T> to_numpy(std::vector<T>& v) {
        auto* owned = new std::vector<T>(std::move(v));
        v = std::vector<T>();
        v.reserve(owned->size());
        nb::capsule owner(owned, [](void* p) noexcept { delete static_cast<std::vector<T>*>(p); });
        size_t shape[1] = {owned->size()};
        return nb::ndarray<nb::numpy, T>(owned->data(), 1, shape, owner);
    }
};

// StepRecord: MujocoRecorder.__call__ in one call, for the common case (the step right after the
// last one seen, the samples' states deferred to the next step's row, rblog/adapters/mujoco.py):
// reads d->time, ncon, nefc and efc_force at byte offsets checked in Python
// (rblog/adapters/_mjdata_offsets.py), gathers the step (StepHook::step) and, at a logged step,
// appends the sample (its step, hook row, gap flag) and its raw contacts (ContactCapture).
// Anything else (a step not after the last, a step before 0, contacts not yet located, the
// arena holding more contacts than the view): returns 2 having done nothing, and the Python
// path handles that call. The counters are an int64 array Python shares:
// [rows gathered k, samples waiting ns, the last step seen, the carried gap flag].
struct StepRecord {
    StepHook* hook;
    ContactCapture* cap;
    const std::uint8_t* d;
    long off_time, off_ncon, off_nefc, off_efc;
    double dt;
    std::int64_t every, ns_cap;
    std::int64_t* counters;     // (4,)
    std::int64_t* hook_steps;   // (hook cap,) the step each gathered row ended
    std::int64_t* steps;        // (ns_cap,) each waiting sample's step
    std::int64_t* rows;         // (ns_cap,) the hook row of the sample's own step
    std::uint8_t* gap;          // (ns_cap,) numpy bool

    StepRecord(StepHook& h, ContactCapture& c, std::uintptr_t d_, long ot, long onc, long one,
               long oef, double dt_, std::int64_t every_, std::int64_t ns_cap_,
               std::uintptr_t counters_, std::uintptr_t hook_steps_, std::uintptr_t steps_,
               std::uintptr_t rows_, std::uintptr_t gap_)
        : hook(&h), cap(&c), d(reinterpret_cast<const std::uint8_t*>(d_)), off_time(ot),
          off_ncon(onc), off_nefc(one), off_efc(oef), dt(dt_), every(every_), ns_cap(ns_cap_),
          counters(reinterpret_cast<std::int64_t*>(counters_)),
          hook_steps(reinterpret_cast<std::int64_t*>(hook_steps_)),
          steps(reinterpret_cast<std::int64_t*>(steps_)),
          rows(reinterpret_cast<std::int64_t*>(rows_)), gap(reinterpret_cast<std::uint8_t*>(gap_)) {
        if (!d || !counters || !hook_steps || !steps || !rows || !gap || every < 1 || ns_cap < 1)
            throw std::invalid_argument("StepRecord: null buffer or bad size");
    }

    // 0: done; 1: done, the block is full (flush); 2: nothing done (the Python path)
    int record() {
        double t;
        std::memcpy(&t, d + off_time, sizeof t);
        // Python's int(round(t / dt)): round half to even, as nearbyint in the default mode
        double s = std::nearbyint(t / dt);
        if (!(s >= 0.0 && s < 9.0e18)) return 2;
        std::int64_t step = (std::int64_t)s;
        if (step != counters[2] + 1) return 2;
        bool sample = step % every == 0;
        int ncon = 0;
        if (sample) {
            std::memcpy(&ncon, d + off_ncon, sizeof ncon);
            if (ncon < 0 || (ncon > 0 && (!cap->con_base || ncon > cap->con_count))) return 2;
            if (counters[1] >= ns_cap) return 2;
        }
        std::int64_t k = counters[0];
        if (k < 0 || k >= hook->cap) return 2;
        hook_steps[k] = step;
        counters[0] = hook->step((int)k);
        counters[2] = step;
        if (sample) {
            std::int64_t i = counters[1];
            gap[i] = counters[3] ? 1 : 0;
            steps[i] = step;
            rows[i] = k;
            counters[1] = i + 1;
            if (ncon > 0) {
                int nefc;
                const double* efc;
                std::memcpy(&nefc, d + off_nefc, sizeof nefc);
                std::memcpy(&efc, d + off_efc, sizeof efc);
                cap->append(step, ncon, efc, nefc > 0 ? nefc : 0);
            }
            counters[3] = 0;
        }
        return (counters[0] >= hook->cap || counters[1] >= ns_cap) ? 1 : 0;
    }
};

}  // namespace

NB_MODULE(_hook, mod) {
    mod.doc() = "rblog.adapters.mujoco's per-step hook in one call (C++, nanobind)";
    nb::class_<StepHook>(mod, "StepHook")
        .def(nb::init<std::uintptr_t, std::uintptr_t, std::uintptr_t, std::uintptr_t, std::uintptr_t,
                      std::uintptr_t, int, double, std::uintptr_t, long, std::uintptr_t,
                      std::uintptr_t, std::uintptr_t, int,
                      std::vector<std::tuple<std::uintptr_t, long, long>>>())
        .def("step", &StepHook::step, "Gather the step that just ended into row k; returns k + 1.");
    nb::class_<ContactCapture>(mod, "ContactCapture")
        .def(nb::init<>())
        .def("contacts_at", &ContactCapture::contacts_at,
             "contacts_at(base, stride, count): where d's mjContact structs are")
        .def("capture", &ContactCapture::capture,
             "capture(step, ncon, efc_force): append the logged step's raw contacts")
        .def("decode_with", &ContactCapture::decode_with,
             "decode_with(offsets, geom_index, pyramidal, dt): decode each capture into contact "
             "rows from now on (decode_contacts' formulas)")
        .def("rows", &ContactCapture::rows,
             "rows() -> dict | None: the decoded contact rows since the last call, then cleared")
        .def("take", &ContactCapture::take,
             "take() -> (step, ncon, nefc, raw bytes, efc_force): the captures, then cleared");
    nb::class_<StepRecord>(mod, "StepRecord")
        .def(nb::init<StepHook&, ContactCapture&, std::uintptr_t, long, long, long, long, double,
                      std::int64_t, std::int64_t, std::uintptr_t, std::uintptr_t, std::uintptr_t,
                      std::uintptr_t, std::uintptr_t>(),
             nb::keep_alive<1, 2>(), nb::keep_alive<1, 3>())
        .def("record", &StepRecord::record,
             "MujocoRecorder.__call__ for the step after the last: 0 done, 1 done and the block "
             "is full, 2 nothing done (the Python path)");
    rb::bind_resolve(mod);
}
