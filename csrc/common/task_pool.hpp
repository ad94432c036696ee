// The core's own task pool: std::thread workers, static partitions, no work stealing.
//
// parallel_for(n_tasks, fn) runs fn(task) for task in [0, n_tasks): task t goes to worker
// t % n_workers, always, and the caller's thread is worker 0. A task writes only its own part of
// the output (a range of bodies, say), so the result is bitwise the same for any thread count
// (Box2D v3 hands fixed-size blocks to its task system for the same reason). Box2D and Jolt leave
// the pool to the user; rblog owns one per process, sized by set_threads (rblog run --threads N,
// RBLOG_THREADS, default: the machine's cores).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace rb {

class TaskPool {
public:
    explicit TaskPool(int n_threads = 1) { resize(n_threads); }
    ~TaskPool() { stop(); }
    TaskPool(const TaskPool&) = delete;
    TaskPool& operator=(const TaskPool&) = delete;

    int threads() const { return n_threads_; }

    // Number of threads, including the caller's; 1 = no workers.
    void resize(int n_threads) {
        if (n_threads < 1) n_threads = 1;
        if (n_threads == n_threads_) return;
        stop();
        n_threads_ = n_threads;
        quit_ = false;
        // a new worker has seen every generation so far: it must not run the last call's tasks
        // again (its fn_ is gone), only the next call's
        const std::uint64_t seen = generation_;
        for (int w = 1; w < n_threads_; ++w) workers_.emplace_back([this, w, seen] { loop(w, seen); });
    }

    // fn(task) for task in [0, n_tasks), task t on worker t % threads(); returns when all are
    // done. The first exception a task throws is rethrown here (the others' are dropped).
    // Not reentrant: one parallel_for at a time per pool.
    void parallel_for(std::int64_t n_tasks, const std::function<void(std::int64_t)>& fn) {
        if (n_tasks <= 0) return;
        int used = n_tasks < n_threads_ ? static_cast<int>(n_tasks) : n_threads_;
        if (used <= 1) {
            for (std::int64_t t = 0; t < n_tasks; ++t) fn(t);
            return;
        }
        std::lock_guard<std::mutex> serial(call_);
        {
            std::lock_guard<std::mutex> lk(m_);
            fn_ = &fn;
            n_tasks_ = n_tasks;
            used_ = used;
            pending_ = used - 1;
            error_ = nullptr;
            ++generation_;
        }
        cv_.notify_all();
        run_share(0);
        std::unique_lock<std::mutex> lk(m_);
        done_.wait(lk, [this] { return pending_ == 0; });
        fn_ = nullptr;
        if (error_) std::rethrow_exception(error_);
    }

private:
    void run_share(int w) {
        try {
            for (std::int64_t t = w; t < n_tasks_; t += used_) (*fn_)(t);
        } catch (...) {
            std::lock_guard<std::mutex> lk(m_);
            if (!error_) error_ = std::current_exception();
        }
    }

    void loop(int w, std::uint64_t seen) {
        for (;;) {
            {
                std::unique_lock<std::mutex> lk(m_);
                cv_.wait(lk, [&] { return quit_ || generation_ != seen; });
                if (quit_) return;
                seen = generation_;
                if (w >= used_) continue;
            }
            run_share(w);
            std::lock_guard<std::mutex> lk(m_);
            if (--pending_ == 0) done_.notify_one();
        }
    }

    void stop() {
        {
            std::lock_guard<std::mutex> lk(m_);
            quit_ = true;
        }
        cv_.notify_all();
        for (auto& t : workers_) t.join();
        workers_.clear();
        n_threads_ = 1;
    }

    int n_threads_ = 1;
    std::vector<std::thread> workers_;
    std::mutex m_, call_;
    std::condition_variable cv_, done_;
    const std::function<void(std::int64_t)>* fn_ = nullptr;
    std::int64_t n_tasks_ = 0;
    int used_ = 0;
    int pending_ = 0;
    std::uint64_t generation_ = 0;
    bool quit_ = false;
    std::exception_ptr error_;
};

// A barrier for the tasks of one parallel_for that must all run at once (n_tasks == threads():
// one task per worker), as the stages of Box2D v3's solver wait on each other: wait() returns
// once all n have called it, and what a task wrote before its wait() is seen by every task after
// theirs (release on arrival, acquire on leaving). Waiters spin a little, then yield (on a loaded
// machine a worker may not be running, and spinning would only keep it off its core).
class SpinBarrier {
public:
    explicit SpinBarrier(int n) : n_(n) {}
    void wait() {
        const std::uint32_t gen = gen_.load(std::memory_order_acquire);
        if (count_.fetch_add(1, std::memory_order_acq_rel) + 1 == n_) {
            count_.store(0, std::memory_order_relaxed);
            gen_.fetch_add(1, std::memory_order_release);
            return;
        }
        for (int spin = 0; gen_.load(std::memory_order_acquire) == gen; ++spin) {
            if (spin > 64) std::this_thread::yield();
        }
    }

private:
    const int n_;
    std::atomic<int> count_{0};
    std::atomic<std::uint32_t> gen_{0};
};

}  // namespace rb
