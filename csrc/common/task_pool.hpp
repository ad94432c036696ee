// The core's own task pool: std::thread workers, blocks claimed from an atomic counter.
//
// run(n_blocks, fn) calls fn(block, worker) once for every block in [0, n_blocks), on the
// caller's thread (worker 0) and the pool's workers (1..threads()-1), and returns when every
// block is done. Which worker runs which block depends on timing; a block writes only its own
// part of the output (a range of bodies or pairs, say) and per-worker scratch is indexed by
// `worker`, so the result is bitwise the same for any thread count. This is Box2D v3's scheme
// (solver.c: b2ExecuteMainStage hands a stage's blocks out through an atomic, the main thread
// takes part and waits for the completion count, not for the workers): a worker that the
// operating system has descheduled holds up a call only while it holds a block, never by not
// having woken up (the caller then claims every block itself). Box2D and Jolt leave the pool to
// the user; rblog owns one per process, sized by set_threads (rblog run --threads N,
// RBLOG_THREADS, default: the machine's cores).
//
// Waking: a worker spins on the call generation for WAKE_SPIN_US after its last block (a step's
// stages follow each other within microseconds, and a futex wake-up costs tens of them), then
// sleeps on a condition variable.
//
// Resizing keeps the threads: a smaller size parks the workers past it (they sleep until a
// larger size wakes them), a larger one wakes parked workers and starts new ones only past every
// thread started so far. So a caller that switches sizes (bench_pile.py's interleaved 1- and
// 2-thread worlds set theirs before every chunk) meets warm, sleeping workers, not threads that
// are still starting when the first call's blocks are handed out (which looked like a
// descheduled worker to the solve's hand-over test, solve_stages.cpp).
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include <time.h>  // clock_gettime (POSIX)

#if defined(__x86_64__) || defined(_M_X64)
#include <immintrin.h>
#define RB_CPU_RELAX() _mm_pause()
#else
#define RB_CPU_RELAX() std::this_thread::yield()
#endif

namespace rb {

// How long a waiting thread spins with a pause only, before it yields its core between checks
// (microseconds). Not shorter: a yield on a machine where other processes wait for the core hands
// it to them for a whole time slice (milliseconds under Linux's CFS), and the wait it was in
// then takes that long (measured: with a yield after 256 pauses the pool's worker took part in
// 2 % of the 500-box pile's blocks at load 5). Not much longer: the thread we wait for may need
// the core (an oversubscribed machine).
constexpr int SPIN_US = 200;

// Wait until ready() holds: spin with a pause for SPIN_US, then yield between checks. Not
// inlined, so that a profile (callgrind) puts every wait of the pool and the threaded solve
// under one name.
template <class Ready>
[[gnu::noinline]] void spin_until(const Ready& ready) {
    std::chrono::steady_clock::time_point t0;
    bool timed = false, yielding = false;
    for (int spin = 0; !ready(); ++spin) {
        if (yielding) {
            std::this_thread::yield();
            continue;
        }
        RB_CPU_RELAX();
        if ((spin & 255) == 255) {
            auto now = std::chrono::steady_clock::now();
            if (!timed) {
                t0 = now;
                timed = true;
            } else if (now - t0 > std::chrono::microseconds(SPIN_US)) {
                yielding = true;
            }
        }
    }
}

// RBLOG_THREAD_STATIC=1: block b of a call (and of a threaded solve's stage) runs on worker
// b % threads(), as an OpenMP static schedule, instead of whichever claims it first. For
// measurements only (valgrind runs one thread at a time, so with claims the caller would take
// nearly every block); the results are the same, but a descheduled worker then stalls the call.
inline bool static_blocks() {
    static const bool on = [] {
        const char* e = std::getenv("RBLOG_THREAD_STATIC");
        return e != nullptr && e[0] == '1';
    }();
    return on;
}

// Wall-clock and this thread's CPU time, nanoseconds (a thread whose CPU time falls behind the
// wall clock was descheduled: the machine's cores are taken by other work).
inline std::int64_t wall_ns() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
}
inline std::int64_t thread_cpu_ns() {
    timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return std::int64_t(t.tv_sec) * 1000000000 + t.tv_nsec;
}

class TaskPool {
public:
    // How long an idle worker spins before it sleeps (microseconds).
    static constexpr int WAKE_SPIN_US = 300;

    explicit TaskPool(int n_threads = 1) { resize(n_threads); }
    ~TaskPool() { stop(); }
    TaskPool(const TaskPool&) = delete;
    TaskPool& operator=(const TaskPool&) = delete;

    int threads() const { return n_threads_.load(std::memory_order_relaxed); }
    // Calls handed to the workers so far (each ends with a wait for its last block), and the
    // blocks of those calls that workers other than the caller ran.
    std::int64_t calls() const { return calls_.load(std::memory_order_relaxed); }
    std::int64_t worker_blocks() const { return worker_blocks_.load(std::memory_order_relaxed); }

    // Run every call on the caller's thread alone for the next `ns` nanoseconds (the caller saw
    // that the threads do not run at once: an oversubscribed machine; the workers then sleep
    // instead of taking the cores from the caller), and whether that is so now.
    void hold_off(std::int64_t ns) {
        hold_until_.store(wall_ns() + ns, std::memory_order_relaxed);
    }
    bool held() const { return wall_ns() < hold_until_.load(std::memory_order_relaxed); }

    // Number of threads, including the caller's; 1 = no workers.
    // Called between calls (not during one).
    void resize(int n_threads) {
        if (n_threads < 1) n_threads = 1;
        if (n_threads == threads()) return;
        {
            std::lock_guard<std::mutex> lk(m_);
            n_threads_.store(n_threads, std::memory_order_release);
        }
        park_cv_.notify_all();
        const std::uint32_t seen = gen_.load();
        for (int w = int(workers_.size()) + 1; w < n_threads; ++w)
            workers_.emplace_back([this, w, seen] { loop(w, seen); });
    }

    // fn(block, worker) for block in [0, n_blocks); returns when all are done. The first
    // exception a block throws is rethrown here (the others' are dropped). Not reentrant: one
    // call at a time per pool (others wait).
    void run(std::int64_t n_blocks, const std::function<void(std::int64_t, int)>& fn) {
        if (n_blocks <= 0) return;
        if (threads() <= 1 || n_blocks == 1 || held()) {
            for (std::int64_t b = 0; b < n_blocks; ++b) fn(b, 0);
            return;
        }
        std::lock_guard<std::mutex> serial(call_);
        calls_.fetch_add(1, std::memory_order_relaxed);
        const std::uint32_t g = gen_.load(std::memory_order_relaxed) + 1;
        fn_.store(&fn, std::memory_order_relaxed);
        // release: a worker that reads this count sees the previous call closed (below)
        n_blocks_.store(n_blocks, std::memory_order_release);
        error_ = nullptr;
        done_.store(0, std::memory_order_relaxed);
        claim_.store(std::uint64_t(g) << 32, std::memory_order_release);
        {
            std::lock_guard<std::mutex> lk(m_);
            gen_.store(g, std::memory_order_release);
        }
        if (sleepers_.load(std::memory_order_acquire) > 0) cv_.notify_all();
        work(g, 0);
        // the blocks others claimed: they take microseconds
        spin_until([&] { return done_.load(std::memory_order_acquire) >= n_blocks; });
        // Close the call before the next one rewrites n_blocks_: an open word would stay
        // (g, n_blocks), and a worker still in work(g) (descheduled after its last block) that
        // read the next call's larger count before the next call's word is stored would claim
        // blocks n_blocks, n_blocks + 1, ... of the next call under g's word. Those blocks would
        // run twice, and its done_ counts would let the next call return while a block still
        // runs (through a dangling or null fn_: a SIGSEGV).
        claim_.store((std::uint64_t(g) << 32) | CLOSED, std::memory_order_release);
        fn_.store(nullptr, std::memory_order_relaxed);
        if (error_) std::rethrow_exception(error_);
    }

    // fn(task) for task in [0, n_tasks), in any order on any threads (run without the worker).
    void parallel_for(std::int64_t n_tasks, const std::function<void(std::int64_t)>& fn) {
        run(n_tasks, [&fn](std::int64_t t, int) { fn(t); });
    }

    // Blocks of about `per_block` items for n items: 1 below min_items (a loop that small is not
    // worth a hand-off: the scene is small, the caller's thread does it alone), else n /
    // per_block rounded up, so that the claims even out the threads' loads.
    static std::int64_t blocks_for(std::int64_t n, std::int64_t per_block,
                                   std::int64_t min_items = 0) {
        if (n < min_items) return 1;
        if (per_block < 1) per_block = 1;
        std::int64_t b = (n + per_block - 1) / per_block;
        return b < 1 ? 1 : b;
    }

private:
    // The claim word's block field once a call is over (run() closes it): above any count.
    static constexpr std::uint64_t CLOSED = 0xffffffffu;

    // Claim and run blocks of call generation g until none is left.
    void work(std::uint32_t g, int w) {
        if (static_blocks()) {  // (measurements: block b on worker b % threads)
            std::uint64_t c = claim_.load(std::memory_order_acquire);
            if (std::uint32_t(c >> 32) != g || (c & 0xffffffffu) == CLOSED) return;
            const std::int64_t n = n_blocks_.load(std::memory_order_acquire);
            // g still open after the count was read: the count is g's (a later call's count is
            // stored after g's close)
            if (claim_.load(std::memory_order_acquire) != c) return;
            for (std::int64_t b = w; b < n; b += threads()) {
                (*fn_.load(std::memory_order_relaxed))(b, w);
                done_.fetch_add(1, std::memory_order_acq_rel);
            }
            return;
        }
        for (;;) {
            std::uint64_t c = claim_.load(std::memory_order_acquire);
            if (std::uint32_t(c >> 32) != g) return;  // a later call: this one is over
            const std::int64_t b = std::int64_t(c & 0xffffffffu);
            // (a closed call's b is CLOSED, above any count; acquire: a count of a later call
            // makes g's close visible, and the exchange below then fails)
            if (b >= n_blocks_.load(std::memory_order_acquire)) return;
            if (!claim_.compare_exchange_weak(c, c + 1, std::memory_order_acq_rel)) continue;
            // a block of g was claimed, so g is not over and fn_ is still g's (the caller
            // rewrites it only after all of g's blocks are done)
            try {
                (*fn_.load(std::memory_order_relaxed))(b, w);
            } catch (...) {
                std::lock_guard<std::mutex> lk(m_);
                if (!error_) error_ = std::current_exception();
            }
            if (w != 0) worker_blocks_.fetch_add(1, std::memory_order_relaxed);
            done_.fetch_add(1, std::memory_order_acq_rel);
        }
    }

    // Spin (a pause, no yield: see SPIN_US) for WAKE_SPIN_US for a call after generation
    // `seen`, then return.
    [[gnu::noinline]] void idle_spin(std::uint32_t seen) {
        auto t0 = std::chrono::steady_clock::now();
        for (int spin = 0; gen_.load(std::memory_order_acquire) == seen &&
                           !quit_.load(std::memory_order_relaxed);
             ++spin) {
            RB_CPU_RELAX();
            if ((spin & 255) == 255 && std::chrono::steady_clock::now() - t0 >
                                           std::chrono::microseconds(WAKE_SPIN_US))
                return;
        }
    }

    void loop(int w, std::uint32_t seen) {
        for (;;) {
            idle_spin(seen);
            if (gen_.load(std::memory_order_acquire) == seen && !quit_.load()) {
                std::unique_lock<std::mutex> lk(m_);
                sleepers_.fetch_add(1, std::memory_order_acq_rel);
                cv_.wait(lk, [&] {
                    return quit_.load() || gen_.load(std::memory_order_acquire) != seen;
                });
                sleepers_.fetch_sub(1, std::memory_order_acq_rel);
            }
            if (quit_.load()) return;
            seen = gen_.load(std::memory_order_acquire);
            if (w >= n_threads_.load(std::memory_order_acquire)) {
                // parked (the pool is smaller than w + 1): asleep until a resize makes it larger;
                // the call that woke it is then over (resizes come between calls)
                std::unique_lock<std::mutex> lk(m_);
                park_cv_.wait(lk, [&] {
                    return quit_.load() || w < n_threads_.load(std::memory_order_acquire);
                });
                if (quit_.load()) return;
                seen = gen_.load(std::memory_order_acquire);
                continue;
            }
            work(seen, w);
        }
    }

    void stop() {
        {
            std::lock_guard<std::mutex> lk(m_);
            quit_.store(true);
        }
        cv_.notify_all();
        park_cv_.notify_all();
        for (auto& t : workers_) t.join();
        workers_.clear();
        n_threads_.store(1);
    }

    std::atomic<int> n_threads_{1};
    std::vector<std::thread> workers_;
    std::mutex m_, call_;
    std::condition_variable cv_, park_cv_;
    std::atomic<int> sleepers_{0};
    std::atomic<std::int64_t> calls_{0}, worker_blocks_{0};
    std::atomic<std::int64_t> hold_until_{0};
    std::atomic<bool> quit_{false};
    std::atomic<std::uint32_t> gen_{0};
    alignas(64) std::atomic<std::uint64_t> claim_{0};  // (generation << 32) | next block
    alignas(64) std::atomic<std::int64_t> done_{0};
    std::atomic<const std::function<void(std::int64_t, int)>*> fn_{nullptr};
    std::atomic<std::int64_t> n_blocks_{0};
    std::exception_ptr error_;
};

}  // namespace rb
