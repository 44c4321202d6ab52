// SPDX-License-Identifier: MIT
// Jobs the threads of one parallel region share, with a wait that works instead of idling.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <vector>

namespace g2l {

/// A queue of jobs shared by the threads of one parallel region (each thread enters it with a
/// JobPoolScope). A thread waiting for a group of jobs runs queued jobs meanwhile — its own
/// group's first, else the oldest job of any group — so no thread idles while any job is
/// queued. (An OpenMP taskgroup's wait only runs that group's tasks: a thread that finished its
/// share of one object's refinement slept while the other ran that object's last piece, though
/// other objects' work was queued; ~7 % of a 4-object frame on two cores, issue 37.)
///
/// Jobs must not wait on anything but their own groups (then every wait ends: the jobs it waits
/// for are queued or running, and a running job only waits in turn). A job's exception is kept
/// by its group (the first one) and rethrown by wait(). Results never depend on which thread
/// runs which job as long as each job writes only its own outputs.
class JobPool {
public:
    /// A set of jobs to wait for. Open while jobs may still be added: wait() returns only once
    /// the group is closed and all its jobs have finished.
    class Group {
    public:
        Group() = default;
        Group(const Group&) = delete;
        Group& operator=(const Group&) = delete;

    private:
        friend class JobPool;
        std::atomic<int64_t> pending_{0};
        std::atomic<bool> open_{true};
        std::exception_ptr error_;  // guarded by the pool's mutex
    };

    JobPool() = default;
    JobPool(const JobPool&) = delete;
    JobPool& operator=(const JobPool&) = delete;

    /// Queues `job` in `group` (which must outlive the job: wait for it).
    void submit(Group& group, std::function<void()> job);
    /// No more jobs will be added to `group`.
    void close(Group& group);
    /// Runs queued jobs until `group` is closed and its jobs have finished; then rethrows the
    /// first exception one of its jobs threw, if any.
    void wait(Group& group);

private:
    struct Entry {
        Group* group;
        std::function<void()> job;
    };
    // Runs one queued job (of `prefer` when it has one queued); false when the queue is empty.
    bool run_one(Group* prefer);

    std::mutex mu_;
    std::deque<Entry> queue_;
};

/// The exceptions of n pieces of work run side by side (threads, jobs, tasks), one slot per
/// piece: run(i, f) runs f and keeps what it throws in slot i (each piece writes only its own
/// slot), rethrow_first() rethrows the lowest slot's after all the pieces ran — the error a
/// sequential loop would have stopped at, whatever the threads' order.
class PieceErrors {
public:
    explicit PieceErrors(size_t n) : failed_(n) {}
    template <class F>
    void run(size_t i, F&& f) {
        try {
            f();
        } catch (...) {
            failed_[i] = std::current_exception();
        }
    }
    bool failed(size_t i) const { return bool(failed_[i]); }
    void rethrow_first() const {
        for (const auto& e : failed_)
            if (e) std::rethrow_exception(e);
    }

private:
    std::vector<std::exception_ptr> failed_;
};

/// The job pool of the calling thread's innermost JobPoolScope, or nullptr.
JobPool* current_job_pool();

/// Makes `pool` the calling thread's job pool for the scope's life (each thread of a parallel
/// region opens its own scope).
class JobPoolScope {
public:
    explicit JobPoolScope(JobPool& pool);
    ~JobPoolScope();
    JobPoolScope(const JobPoolScope&) = delete;
    JobPoolScope& operator=(const JobPoolScope&) = delete;

private:
    JobPool* previous_;
};

}  // namespace g2l
