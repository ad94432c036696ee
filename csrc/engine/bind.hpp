// The engine module's bindings, one function per area (each in its bind_*.cpp); module.cpp calls
// them all.
#pragma once

#include <nanobind/nanobind.h>

#include "common/py.hpp"
#include "common/task_pool.hpp"
#include "engine/collision.hpp"
#include "engine/manifold.hpp"

#include <vector>

namespace rb {
void bind_threads(nanobind::module_& m);
void bind_free(nanobind::module_& m);
void bind_collision(nanobind::module_& m);
void bind_contact(nanobind::module_& m);
// The process's task pool (rblog run --threads N / RBLOG_THREADS), threads.cpp.
TaskPool& pool();

// numpy arrays of the contact records (manifold.hpp): (M, MI_COLS) int64 as ManifoldHeads,
// (M, MF_COLS) float64 as Manifolds, (K, PF_COLS) float64 as ContactPoints (a wrong width is a
// ValueError naming the argument)
inline V1<ManifoldHead> mi_arg(nanobind::handle h, const char* name = "mi") {
    return heads(v2<i64>(h, name), name);
}
inline V1<Manifold> mf_arg(nanobind::handle h, const char* name = "mf") {
    return manifolds(v2<double>(h, name), name);
}
inline V1<ContactPoint> pf_arg(nanobind::handle h, const char* name = "pf") {
    return points(v2<double>(h, name), name);
}

// One geom per body at its centre of mass (geom i = body i): the Geoms of the stage bindings
// that take per-body arrays (geom, size and, where the stage reads it, radius).
struct IdentityGeoms {
    std::vector<i64> body, offset;
    std::vector<double> rad;
    Geoms g;
    IdentityGeoms(V1<i64> code, V2<double> size, const V1<double>* radius = nullptr)
        : body((size_t)code.n0), offset((size_t)code.n0, 0), rad((size_t)code.n0, 0.0) {
        for (i64 i = 0; i < code.n0; ++i) {
            body[(size_t)i] = i;
            if (radius) rad[(size_t)i] = (*radius)[i];
        }
        g = Geoms{code, size, V1<i64>{body.data(), code.n0}, V1<i64>{offset.data(), code.n0},
                  V2<double>{nullptr, code.n0, 3}, V3<double>{nullptr, code.n0, 3, 3},
                  V1<double>{rad.data(), code.n0}};
    }
    IdentityGeoms(const IdentityGeoms&) = delete;
};
}  // namespace rb
