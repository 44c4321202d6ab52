// SPDX-License-Identifier: MIT
#include "core/job_pool.h"

#include <thread>
#include <utility>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace g2l {

namespace {

thread_local JobPool* tls_pool = nullptr;

inline void relax() {
#if defined(__x86_64__) || defined(__i386__)
    _mm_pause();
#endif
}

}  // namespace

void JobPool::submit(Group& group, std::function<void()> job) {
    group.pending_.fetch_add(1, std::memory_order_relaxed);
    std::lock_guard<std::mutex> lock(mu_);
    queue_.push_back({&group, std::move(job)});
}

void JobPool::close(Group& group) { group.open_.store(false, std::memory_order_release); }

bool JobPool::run_one(Group* prefer) {
    Entry e;
    {
        std::lock_guard<std::mutex> lock(mu_);
        if (queue_.empty()) return false;
        auto it = queue_.begin();
        if (prefer)
            for (auto j = queue_.begin(); j != queue_.end(); ++j)
                if (j->group == prefer) {
                    it = j;
                    break;
                }
        e = std::move(*it);
        queue_.erase(it);
    }
    try {
        e.job();
    } catch (...) {
        std::lock_guard<std::mutex> lock(mu_);
        if (!e.group->error_) e.group->error_ = std::current_exception();
    }
    // Release: the job's writes are seen by whoever sees the count drop.
    e.group->pending_.fetch_sub(1, std::memory_order_release);
    return true;
}

void JobPool::wait(Group& group) {
    int idle = 0;
    while (group.open_.load(std::memory_order_acquire) ||
           group.pending_.load(std::memory_order_acquire) > 0) {
        if (run_one(&group)) {
            idle = 0;
            continue;
        }
        // Nothing queued: the group's last jobs run on other threads (or jobs are still to
        // come). Spin a little, then give the core away between looks.
        if (++idle < 256)
            relax();
        else
            std::this_thread::yield();
    }
    std::exception_ptr error;
    {
        std::lock_guard<std::mutex> lock(mu_);
        error = group.error_;
    }
    if (error) std::rethrow_exception(error);
}

JobPool* current_job_pool() { return tls_pool; }

JobPoolScope::JobPoolScope(JobPool& pool) : previous_(tls_pool) { tls_pool = &pool; }

JobPoolScope::~JobPoolScope() { tls_pool = previous_; }

}  // namespace g2l
