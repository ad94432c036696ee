// rblog.adapters._hook: the per-step hook of rblog.adapters.mujoco in one call (the Python
// version is StepImpulses.__call__ in rblog/adapters/_mujoco_step.py; the derivation is in
// rblog/adapters/mujoco.py). After mj_step, with Euler or the implicit integrators, mjData holds
// the step's start in everything but qpos and qvel; the hook
//   1. puts the step's start velocity v0 and the acceleration MuJoCo integrated, a = (v1 - v0)/h,
//      into d->qvel and d->qacc, calls mj_rnePostConstraint (and mj_mulM(a) for the implicit
//      integrators), and puts qvel and qacc back;
//   2. copies the pieces of mjData's buffer that hold the row's fields into row k (Rows in
//      Python decides the pieces), and v1 into its row; v0 = v1.
// ContactCapture copies the raw contacts of the logged steps (below); mujoco_resolve.cpp turns a
// block's rows into impulses and states.
// It holds raw addresses: of d's arrays (mjData's buffer stays where it is for d's life), of the
// Python-owned buffers (never reallocated while the hook lives), and of MuJoCo's two functions
// (looked up by ctypes in the libmujoco the bindings loaded). No MuJoCo header is needed.
#include <nanobind/nanobind.h>
#include <nanobind/stl/vector.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/ndarray.h>

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <tuple>
#include <vector>

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

// ContactCapture: at a logged step, the raw contacts of an MjData: its first ncon mjContact
// structs (at `base`, `stride` bytes each: the start of mjData's arena, which stays where it is)
// and its efc_force, appended to the block's capture; decoded a block at a time in Python
// (rblog/adapters/_mujoco_model.py, decode_contacts).
struct ContactCapture {
    const std::uint8_t* con_base = nullptr;
    long con_stride = 0, con_count = 0;
    std::vector<std::int64_t> cap_step, cap_ncon, cap_nefc;
    std::vector<std::uint8_t> cap_raw;
    std::vector<double> cap_efc;

    void contacts_at(std::uintptr_t base, long stride, long count) {
        if (!base || stride <= 0 || count <= 0) throw std::invalid_argument("contacts_at: bad view");
        con_base = reinterpret_cast<const std::uint8_t*>(base);
        con_stride = stride;
        con_count = count;
    }

    void capture(std::int64_t step, long ncon,
                 nb::ndarray<const double, nb::ndim<1>, nb::c_contig, nb::device::cpu> efc) {
        if (!con_base) throw std::logic_error("capture: contacts_at first");
        if (ncon < 0 || ncon > con_count) throw std::out_of_range("capture: ncon outside the arena");
        cap_step.push_back(step);
        cap_ncon.push_back(ncon);
        cap_nefc.push_back((std::int64_t)efc.shape(0));
        cap_raw.insert(cap_raw.end(), con_base, con_base + ncon * con_stride);
        cap_efc.insert(cap_efc.end(), efc.data(), efc.data() + efc.shape(0));
    }

    // the captures so far, as (step, ncon, nefc (S,) int64, raw bytes, efc_force), then cleared
    nb::tuple take() {
        auto out = nb::make_tuple(to_numpy(cap_step), to_numpy(cap_ncon), to_numpy(cap_nefc),
                                  to_numpy(cap_raw), to_numpy(cap_efc));
        cap_step.clear(), cap_ncon.clear(), cap_nefc.clear(), cap_raw.clear(), cap_efc.clear();
        return out;
    }

    template <class T>
    static nb::ndarray<nb::numpy, T> to_numpy(const std::vector<T>& v) {  // a copy numpy owns
        auto* owned = new std::vector<T>(v);
        nb::capsule owner(owned, [](void* p) noexcept { delete static_cast<std::vector<T>*>(p); });
        size_t shape[1] = {owned->size()};
        return nb::ndarray<nb::numpy, T>(owned->data(), 1, shape, owner);
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
        .def("take", &ContactCapture::take,
             "take() -> (step, ncon, nefc, raw bytes, efc_force): the captures, then cleared");
    rb::bind_resolve(mod);
}
