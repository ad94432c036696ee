// The engine module's bindings, one function per area (each in its bind_*.cpp); module.cpp calls
// them all.
#pragma once

#include <nanobind/nanobind.h>

#include "common/task_pool.hpp"

namespace rb {
void bind_threads(nanobind::module_& m);
void bind_free(nanobind::module_& m);
void bind_collision(nanobind::module_& m);
void bind_contact(nanobind::module_& m);
// The process's task pool (rblog run --threads N / RBLOG_THREADS), threads.cpp.
TaskPool& pool();
}  // namespace rb
