// The engine's task pool and its size.
#include <atomic>
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

// What the threaded velocity solves did since the last thread_stats(reset=True): solves run on
// threads, stages (a colour of a sweep) handed to the threads (each ends with a wait for its
// last block: the solve's barriers), solves the driver finished alone (contact_solver.cpp).
namespace {
std::atomic<i64> g_solves{0}, g_stages{0}, g_handovers{0}, g_wait{0}, g_solve_ticks{0},
    g_helped{0};
i64 g_calls0 = 0, g_wblocks0 = 0;  // pool().calls(), worker_blocks() at the last reset
}

void set_thread_fallback(bool on);  // solve_stages.cpp

void thread_stats_add(i64 stages_shared, i64 worker_blocks, bool handover, i64 wait_ticks,
                      i64 solve_ticks) {
    g_helped.fetch_add(worker_blocks, std::memory_order_relaxed);
    g_wait.fetch_add(wait_ticks, std::memory_order_relaxed);
    g_solve_ticks.fetch_add(solve_ticks, std::memory_order_relaxed);
    g_solves.fetch_add(1, std::memory_order_relaxed);
    g_stages.fetch_add(stages_shared, std::memory_order_relaxed);
    if (handover) g_handovers.fetch_add(1, std::memory_order_relaxed);
}

void bind_threads(nb::module_& m) {
    m.def("set_thread_fallback", &set_thread_fallback, nb::arg("on"),
          "The oversubscribed machine's fallback (contact_solver.cpp: a threaded solve whose "
          "driver waited or was descheduled too long hands over, and every stage runs on one "
          "thread for a while): on by default (RBLOG_THREAD_HANDOVER=0: off); off clears a hold. "
          "Results do not depend on it.");
    m.def("thread_stats", [](bool reset) {
              nb::dict d;
              d["threaded_solves"] = g_solves.load();
              d["shared_stages"] = g_stages.load();
              d["handovers"] = g_handovers.load();
              d["pool_calls"] = pool().calls() - g_calls0;
              d["pool_worker_blocks"] = pool().worker_blocks() - g_wblocks0;
              d["solve_worker_blocks"] = g_helped.load();
              d["wait_share"] = g_solve_ticks.load() > 0
                                    ? double(g_wait.load()) / double(g_solve_ticks.load())
                                    : 0.0;
              if (reset) {
                  g_helped.store(0);
                  g_wblocks0 = pool().worker_blocks();
                  g_wait.store(0);
                  g_solve_ticks.store(0);
                  g_calls0 = pool().calls();
                  g_solves.store(0);
                  g_stages.store(0);
                  g_handovers.store(0);
              }
              return d;
          }, nb::arg("reset") = false,
          "Counts of the threaded velocity solves: threaded_solves, shared_stages (stages of a "
          "sweep handed to the threads, each ended by a wait for its last block), handovers "
          "(solves the driver finished alone because the threads did not run at once), wait_share "
          "(of the threaded solves' time, the driver's waits for blocks others held), pool_calls "
          "(the stages' loops handed to the pool: collide, prepare, relax colours ...; each ends "
          "with a wait for its last block, as a shared solve stage does).");
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
