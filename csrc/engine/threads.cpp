// The engine's task pool and its size.
#include <string>
#include <thread>

#include <nanobind/stl/string.h>

#include "engine/bind.hpp"
#include "engine/contact_lanes.hpp"

namespace rb {
namespace nb = nanobind;

static int default_threads() {
    unsigned n = std::thread::hardware_concurrency();
    return n == 0 ? 1 : static_cast<int>(n);
}

TaskPool& pool() {
    static TaskPool p(1);
    return p;
}

void bind_threads(nb::module_& m) {
    m.def("set_threads", [](int n) { pool().resize(n < 1 ? 1 : n); }, nb::arg("n"),
          "Threads the core steps on (the caller's included); results do not depend on it.");
    m.def("threads", [] { return pool().threads(); }, "Threads the core steps on.");
    m.def("hardware_threads", &default_threads, "The machine's hardware threads.");
    m.def("set_solver_path", [](const std::string& path) {
              if (path == "auto") set_solver_path(PATH_AUTO);
              else if (path == "scalar") set_solver_path(PATH_SCALAR);
              else if (path == "sse2") set_solver_path(PATH_SSE2);
              else throw nb::value_error("solver path: expected auto, scalar or sse2");
          }, nb::arg("path"),
          "The velocity solve's kernel for the colours (contact_lanes.hpp): auto (AVX2 where the "
          "processor has it, else scalar), scalar, sse2 (4-wide vector types in 128-bit pairs, "
          "a check only); every path gives bitwise the same results. RBLOG_SOLVER_PATH sets it at "
          "import.");
    m.def("solver_kernel", [] { return std::string(solver_kernel()); },
          "The kernel the velocity solve's colours run on: avx2, sse2 or scalar.");
}

}  // namespace rb
