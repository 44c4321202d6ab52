// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <numeric>
#include <stdexcept>
#include <thread>
#include <vector>

#include "core/job_pool.h"

using g2l::JobPool;

namespace {

// Spins until `flag` is set or `seconds` pass; false on the timeout.
bool await(const std::atomic<bool>& flag, double seconds = 20) {
    const auto t0 = std::chrono::steady_clock::now();
    while (!flag.load()) {
        if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > seconds)
            return false;
        std::this_thread::yield();
    }
    return true;
}

}  // namespace

TEST_CASE("JobPool: every job of a group runs once before wait returns, nested groups too") {
    JobPool pool;
    g2l::JobPoolScope scope(pool);
    REQUIRE(g2l::current_job_pool() == &pool);
    std::vector<int> hits(50, 0), inner(50 * 4, 0);
    JobPool::Group outer;
    for (int i = 0; i < 50; ++i)
        pool.submit(outer, [&, i] {
            hits[size_t(i)] += 1;
            JobPool::Group sub;  // a job that waits on jobs of its own
            for (int k = 0; k < 4; ++k) pool.submit(sub, [&, i, k] { inner[size_t(4 * i + k)] += i + k; });
            pool.close(sub);
            pool.wait(sub);
        });
    pool.close(outer);
    pool.wait(outer);
    CHECK(std::accumulate(hits.begin(), hits.end(), 0) == 50);
    CHECK(*std::min_element(hits.begin(), hits.end()) == 1);
    for (int i = 0; i < 50; ++i)
        for (int k = 0; k < 4; ++k) CHECK(inner[size_t(4 * i + k)] == i + k);
    // An empty, closed group: nothing to wait for.
    JobPool::Group none;
    pool.close(none);
    pool.wait(none);
}

TEST_CASE("JobPool: a thread waiting for a group whose last job runs elsewhere runs other queued jobs") {
    // Thread B takes the one job of group 1, which cannot finish before a job of group 2 has
    // run; the main thread then waits for group 1 and must run group 2's job itself meanwhile
    // (a wait that only ran its own group's jobs would never return).
    JobPool pool;
    JobPool::Group g1, g2;
    std::atomic<bool> slow_started{false}, other_done{false}, slow_timed_out{false};
    std::thread::id other_ran_on;
    pool.submit(g1, [&] {
        slow_started = true;
        if (!await(other_done)) slow_timed_out = true;
    });
    pool.close(g1);
    std::thread b([&] {
        g2l::JobPoolScope scope(pool);
        pool.wait(g1);
    });
    REQUIRE(await(slow_started));
    pool.submit(g2, [&] {
        other_ran_on = std::this_thread::get_id();
        other_done = true;
    });
    pool.close(g2);
    pool.wait(g1);
    b.join();
    pool.wait(g2);
    CHECK_FALSE(slow_timed_out.load());
    CHECK(other_ran_on == std::this_thread::get_id());
}

TEST_CASE("JobPool: a job's exception reaches wait, and the group's other jobs still run") {
    JobPool pool;
    JobPool::Group g;
    std::atomic<int> ran{0};
    for (int i = 0; i < 10; ++i)
        pool.submit(g, [&, i] {
            ++ran;
            if (i == 3) throw std::runtime_error("job 3 failed");
        });
    pool.close(g);
    CHECK_THROWS_WITH(pool.wait(g), "job 3 failed");
    CHECK(ran.load() == 10);
}

TEST_CASE("JobPool: the scope sets the thread's pool and restores the one before") {
    CHECK(g2l::current_job_pool() == nullptr);
    JobPool a, b;
    {
        g2l::JobPoolScope sa(a);
        CHECK(g2l::current_job_pool() == &a);
        {
            g2l::JobPoolScope sb(b);
            CHECK(g2l::current_job_pool() == &b);
            JobPool* seen = &a;  // per thread: none on a new thread
            std::thread t([&seen] { seen = g2l::current_job_pool(); });
            t.join();
            CHECK(seen == nullptr);
        }
        CHECK(g2l::current_job_pool() == &a);
    }
    CHECK(g2l::current_job_pool() == nullptr);
}

TEST_CASE("PieceErrors: every piece runs, the lowest failed piece's error is rethrown") {
    // Pieces run on two threads in reverse order: pieces 7 and 2 fail; 2's error comes back.
    g2l::PieceErrors errors(10);
    std::atomic<int> ran{0};
    std::thread t([&] {
        for (int i = 9; i >= 5; --i)
            errors.run(size_t(i), [&, i] {
                ++ran;
                if (i == 7) throw std::runtime_error("piece 7 failed");
            });
    });
    for (int i = 4; i >= 0; --i)
        errors.run(size_t(i), [&, i] {
            ++ran;
            if (i == 2) throw std::invalid_argument("piece 2 failed");
        });
    t.join();
    CHECK(ran.load() == 10);
    CHECK(errors.failed(2));
    CHECK(errors.failed(7));
    CHECK_FALSE(errors.failed(0));
    CHECK_THROWS_AS(errors.rethrow_first(), std::invalid_argument);
    CHECK_THROWS_WITH(errors.rethrow_first(), "piece 2 failed");
    // None failed: nothing is thrown.
    g2l::PieceErrors fine(3);
    for (size_t i = 0; i < 3; ++i) fine.run(i, [] {});
    CHECK_NOTHROW(fine.rethrow_first());
    CHECK_FALSE(fine.failed(1));
}
