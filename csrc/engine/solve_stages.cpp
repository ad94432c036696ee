// The velocity solve's sweeps on the task pool (solve_stages.hpp): Box2D v3's stages
// (solver.c, b2SolverStage / b2ExecuteMainStage) and the measured choice between the threaded
// and the serial solve.
#include "engine/solve_stages.hpp"

#include <atomic>
#include <cstdlib>
#include <vector>

#include "common/task_pool.hpp"
#include "engine/profile.hpp"

namespace rb {

TaskPool& pool();  // the engine's pool (threads.cpp)
// counts of the threaded solves (threads.cpp, _core.thread_stats): stages handed to the threads,
// whether the driver went on alone
void thread_stats_add(i64 stages_shared, i64 worker_blocks, bool handover, i64 wait_ticks,
                      i64 solve_ticks);

namespace {

// The solve goes to threads only when the colours hold this many groups (a smaller scene, the
// 100-box pile's ~30 groups say, solves on one thread: ~1 us a group visit, and the threads
// would mostly wait for each other), and a colour's groups only when each thread gets
// MIN_STAGE_GROUPS_PER_THREAD to visit in the sweep (the driver's hand-off of a stage and the
// wait for its last block cost about as much as solving a group or two). The results do not
// depend on either, only the time.
constexpr i64 MIN_THREADED_GROUPS = 64;
constexpr i64 MIN_STAGE_GROUPS_PER_THREAD = 4;
// A shared colour is cut into blocks of about this many groups, at most BLOCKS_PER_THREAD blocks
// a thread (blocks are claimed one at a time: smaller ones even out the threads' loads, each
// claim costs an atomic on a shared cache line).
constexpr i64 GROUPS_PER_BLOCK = 2;
constexpr i64 BLOCKS_PER_THREAD = 4;

// The fallback for an oversubscribed machine. When, two sweeps or more into a threaded solve,
// the driver has spent more than half of it waiting for blocks that other threads claimed (a
// worker descheduled while it holds a block), or its own CPU time has fallen below
// THREAD_CPU_SHARE of the wall time (it was descheduled: the cores are busy with other
// processes, or the threads share a scheduler group's slice, Linux's autogroup, so that a
// spinning worker takes the driver's time), it finishes the solve alone and every stage runs on
// one thread for the next THREAD_HOLD_NS (the pool's hold_off: the workers sleep), after which
// threads are tried again. On a quiet machine the driver keeps its core (CPU time ~ wall time)
// and waits only for blocks in flight, so neither fires. The results do not depend on it (only
// which thread solves which group changes).
constexpr double THREAD_CPU_SHARE = 0.75;
constexpr i64 THREAD_HOLD_NS = 500000000;  // 0.5 s
// RBLOG_THREAD_HANDOVER=0 (or _core.set_thread_fallback(False)) turns the hand-over off: for
// measurements under valgrind, which runs one thread at a time, so that every driver wait looks
// like a descheduled worker, and for tests that must see the threads work on a loaded machine
std::atomic<bool> g_handover_on{[] {
    const char* e = std::getenv("RBLOG_THREAD_HANDOVER");
    return !(e && e[0] == '0');
}()};

// Measured choice between the threaded and the serial solve: the cost of each (nanoseconds of
// wall time per 1,000 manifold visits, a running mean over the solves that ran that way, 0:
// not measured yet) and a count of the eligible solves. An eligible solve runs the way whose
// cost is lower, and every PROBE_EVERY-th the other way, so that both stay measured as the
// scene and the machine change. On a machine where the second thread does not pay (measured on
// this session's 2-vCPU KVM guest: the 500-box pile's solve took 4.7-4.9 ms a step on one thread
// and 4.9-5.5 ms on two, both threads running), the solves stay serial. Results do not depend on
// it (RBLOG_THREAD_HANDOVER=0 or set_thread_fallback(False): always threaded).
constexpr i64 PROBE_EVERY = 32;
std::atomic<i64> g_cost_serial{0}, g_cost_threaded{0}, g_eligible{0};

bool choose_threaded() {
    if (!g_handover_on.load(std::memory_order_relaxed)) return true;
    i64 k = g_eligible.fetch_add(1, std::memory_order_relaxed);
    i64 cs = g_cost_serial.load(std::memory_order_relaxed);
    i64 ct = g_cost_threaded.load(std::memory_order_relaxed);
    if (ct == 0) return true;
    if (cs == 0) return false;
    bool threaded = ct < cs;
    return k % PROBE_EVERY == 0 ? !threaded : threaded;
}

void record_cost(bool threaded, i64 wall, i64 visits) {
    if (visits <= 0) return;
    i64 c = wall * 1000 / visits;
    std::atomic<i64>& m = threaded ? g_cost_threaded : g_cost_serial;
    i64 old = m.load(std::memory_order_relaxed);
    m.store(old == 0 ? c : (3 * old + c) / 4, std::memory_order_relaxed);
}

}  // namespace

void set_thread_fallback(bool on) {
    g_handover_on.store(on);
    if (!on) pool().hold_off(0);
}

SweepCount run_sweeps(const SweepPlan& p, const VisitFn& visit) {
    const i64 n_sets = p.n_sets;
    const i64 min_iter = p.min_iter, max_iter = p.max_iter;
    const double tol = p.tol;
    i64 it = 0, visits = 0;
    const i64 n_wide = p.set_group[n_sets] - p.set_group[1];
    const int n_threads = pool().threads();
    bool serial = n_threads < 2 || n_wide < MIN_THREADED_GROUPS || pool().held();
    const bool eligible = !serial;  // (the solve's cost is measured for the choice)
    if (eligible && !choose_threaded()) serial = true;
    const i64 solve_wall0 = eligible ? wall_ns() : 0;
    bool converged = false;
    if (!serial) {
        // Box2D v3's stages (solver.c, b2SolverStage / b2ExecuteMainStage): the calling thread
        // drives, the pool's workers follow. A stage is one set of one sweep; the driver posts it
        // (claim word = stage << 24), every thread claims its blocks of groups from the word,
        // and the driver waits until the stage's done count reaches its block count before it
        // posts the next (colour c + 1 must see colour c). So a worker the system has
        // descheduled holds the others up only while it holds a block, not by being late. The
        // driver runs a set alone when it is too small to share (the overflow set, always: its
        // manifolds one after another in order; a colour whose last sweep visited fewer than
        // MIN_STAGE_GROUPS_PER_THREAD groups a thread), and it decides when the sweeps stop (the
        // max of the blocks' changes). Which thread solves which block changes nothing: a block
        // reads and writes only its own manifolds' bodies (constraint_graph.hpp).
        const int nt = n_threads;
        // blocks of each set: [set_blk[s], set_blk[s + 1]) of a sweep's n_blk
        std::vector<i64> set_blk((size_t)n_sets + 1, 0);
        for (i64 s = 0; s < n_sets; ++s) {
            i64 n_g = p.set_group[s + 1] - p.set_group[s];
            i64 nb = s == 0 ? (n_g > 0 ? 1 : 0) : (n_g + GROUPS_PER_BLOCK - 1) / GROUPS_PER_BLOCK;
            if (nb > BLOCKS_PER_THREAD * nt) nb = BLOCKS_PER_THREAD * nt;
            set_blk[(size_t)s + 1] = set_blk[(size_t)s] + nb;
        }
        const i64 n_blk = set_blk[(size_t)n_sets];
        std::vector<double> blk_change((size_t)n_blk, 0.0);
        std::vector<i64> blk_visits((size_t)n_blk, 0), set_visits((size_t)n_sets, 0);
        struct alignas(64) Word {
            std::atomic<i64> v{0};
        };
        Word claim, done;  // claim: (stage << 24) | next block; done: blocks finished
        Word helped;       // blocks the workers (not the driver) solved
        constexpr i64 FINISH = i64(1) << 38;  // the stage that ends the solve
        auto stage_of = [&](i64 sweep, i64 s) { return (sweep - 1) * n_sets + s; };
        // solve block j of set s in sweep `sweep` (results into the block's slots)
        auto run_block = [&](i64 sweep, i64 s, i64 j) {
            double change = 0.0;
            i64 vis = 0;
            i64 g0 = p.set_group[s], n_g = p.set_group[s + 1] - g0;
            i64 nb = set_blk[(size_t)s + 1] - set_blk[(size_t)s];
            if (s == 0)
                visit(sweep, s, g0, g0 + n_g, &change, &vis);
            else
                visit(sweep, s, g0 + n_g * j / nb, g0 + n_g * (j + 1) / nb, &change, &vis);
            blk_change[(size_t)(set_blk[(size_t)s] + j)] = change;
            blk_visits[(size_t)(set_blk[(size_t)s] + j)] = vis;
        };
        // solve blocks of the posted stage until none is left (claimed, or with
        // RBLOG_THREAD_STATIC block j on thread j % nt); then `exhausted` is the stage. False
        // once the solve is finished.
        const bool fixed = static_blocks();
        auto claim_blocks = [&](i64& exhausted, int w) {
            i64 c = claim.v.load(std::memory_order_acquire);
            i64 stage = c >> 24;
            if (stage >= FINISH) return false;
            if (stage == exhausted) {
                spin_until(
                    [&] { return claim.v.load(std::memory_order_acquire) >> 24 != stage; });
                return true;
            }
            i64 s = stage % n_sets, sweep = stage / n_sets + 1;
            i64 nb = set_blk[(size_t)s + 1] - set_blk[(size_t)s];
            if (fixed) {
                for (i64 j = w; j < nb; j += nt) {
                    run_block(sweep, s, j);
                    if (w != 0) helped.v.fetch_add(1, std::memory_order_relaxed);
                    done.v.fetch_add(1, std::memory_order_acq_rel);
                }
                exhausted = stage;
                return true;
            }
            i64 j = c & 0xffffff;
            if (j >= nb) {
                exhausted = stage;
                return true;
            }
            if (claim.v.compare_exchange_weak(c, c + 1, std::memory_order_acq_rel)) {
                run_block(sweep, s, j);
                if (w != 0) helped.v.fetch_add(1, std::memory_order_relaxed);
                done.v.fetch_add(1, std::memory_order_acq_rel);
            }
            return true;
        };
        i64 waited = 0, n_posted = 0;  // the driver's ticks waiting for others' blocks; stages
        const i64 t_start = ticks();
        const i64 wall0 = wall_ns(), cpu0 = thread_cpu_ns();
        bool handover = false;
        auto drive = [&]() {
            i64 exhausted = -1;
            while (it < max_iter) {
                it += 1;
                for (i64 s = 0; s < n_sets; ++s) {
                    i64 b0 = set_blk[(size_t)s], nb = set_blk[(size_t)s + 1] - b0;
                    if (nb == 0) continue;
                    // shared when every thread gets MIN_STAGE_GROUPS_PER_THREAD groups to visit
                    // (the first min_iter sweeps visit all; later ones about what the last did)
                    i64 n_g = p.set_group[s + 1] - p.set_group[s];
                    i64 expect = it <= min_iter ? 4 * n_g : set_visits[(size_t)s];
                    bool share = !handover && s > 0 && nb > 1 &&
                                 expect >= 4 * MIN_STAGE_GROUPS_PER_THREAD * nt;
                    if (!share) {
                        for (i64 j = 0; j < nb; ++j) run_block(it, s, j);
                        continue;
                    }
                    n_posted += 1;
                    done.v.store(0, std::memory_order_relaxed);
                    claim.v.store(stage_of(it, s) << 24, std::memory_order_release);
                    while (exhausted != stage_of(it, s)) claim_blocks(exhausted, 0);
                    if (done.v.load(std::memory_order_acquire) < nb) {
                        i64 w0 = ticks();
                        spin_until([&] { return done.v.load(std::memory_order_acquire) >= nb; });
                        waited += ticks() - w0;
                    }
                }
                double all = 0.0;
                for (i64 s = 0; s < n_sets; ++s) {
                    i64 v = 0;
                    for (i64 b = set_blk[(size_t)s]; b < set_blk[(size_t)s + 1]; ++b) {
                        if (blk_change[(size_t)b] > all) all = blk_change[(size_t)b];
                        v += blk_visits[(size_t)b];
                    }
                    set_visits[(size_t)s] = v;
                    visits += v;
                }
                if (it >= min_iter && all <= tol) {
                    converged = true;
                    break;
                }
                // more than half of the time so far waiting for blocks that others hold, or
                // descheduled for more than 1 - THREAD_CPU_SHARE of it (past two sweeps): the
                // threads do not run at once, the driver goes on alone
                if (g_handover_on.load(std::memory_order_relaxed) && !handover && it >= 2 &&
                    (2 * waited > ticks() - t_start ||
                     double(thread_cpu_ns() - cpu0) < THREAD_CPU_SHARE * double(wall_ns() - wall0)))
                    handover = true;
            }
            claim.v.store(FINISH << 24, std::memory_order_release);
        };
        // nt blocks: the caller's first is the driver, the others (and any the caller claims
        // after the drive, when a worker never woke up for its own) help until FINISH
        bool driven = false;  // (the caller's thread alone reads and writes it)
        pool().run(nt, [&](i64, int w) {
            if (w == 0) {
                if (!driven) {
                    driven = true;
                    drive();
                }
                return;
            }
            i64 exhausted = -1;
            while (claim_blocks(exhausted, w)) {
            }
        });
        converged = converged || it >= max_iter;
        thread_stats_add(n_posted, helped.v.load(), handover, waited, ticks() - t_start);
        // handed over: the threads did not run at once (the machine's cores are taken by other
        // work), so every stage runs on one thread for THREAD_HOLD_NS. Either gives the same
        // bits as the threaded sweeps.
        if (handover) pool().hold_off(THREAD_HOLD_NS);
    }
    if (!converged) {
        while (it < max_iter) {
            it += 1;
            double change = 0.0;
            // the overflow set: one manifold after another
            visit(it, 0, p.set_group[0], p.set_group[1], &change, &visits);
            // the colours, one after another; a colour's groups in any order
            for (i64 s = 1; s < n_sets; ++s)
                visit(it, s, p.set_group[s], p.set_group[s + 1], &change, &visits);
            if (it >= min_iter && change <= tol) break;
        }
    }
    if (eligible) record_cost(!serial, wall_ns() - solve_wall0, visits);
    return SweepCount{it, visits};
}

}  // namespace rb
