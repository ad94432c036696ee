// The engine's task pool and its size.
#include <thread>

#include "engine/bind.hpp"

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
}

}  // namespace rb
