// The engine module's bindings, one function per area (each in its bind_*.cpp); module.cpp calls
// them all.
#pragma once

#include <nanobind/nanobind.h>

#include "common/py.hpp"
#include "common/task_pool.hpp"
#include "engine/manifold.hpp"

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
}  // namespace rb
