// SPDX-License-Identifier: MIT
// The data-parallel hook (nn/data_parallel.h) without MPI: two threads play two processes, each
// with half of a batch, and sum through an in-process exchange. BatchNorm's outputs, input
// gradients and running statistics, and the sum of the halves' parameter gradients, must equal
// the one-batch ones; dropout must keep its rows of the one-batch mask.
#include <catch2/catch.hpp>
#include <cmath>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

#include "core/error.h"
#include "core/rng.h"
#include "nn/data_parallel.h"
#include "nn/ops/batch_norm.h"
#include "nn/ops/dropout.h"
#include "nn/ops/elementwise.h"
#include "nn/ops/reduce.h"

using namespace g2l;

namespace {

// A two-party all-reduce (sum) for threads: each call blocks until both have called it.
class TwoPartySum {
public:
    void sum(double* v, int64_t n) {
        std::unique_lock<std::mutex> lock(m_);
        const int64_t gen = gen_;
        if (acc_.empty()) acc_.assign(size_t(n), 0.0);
        G2L_CHECK(int64_t(acc_.size()) == n, "TwoPartySum: ", acc_.size(), " vs ", n, " values");
        for (int64_t i = 0; i < n; ++i) acc_[size_t(i)] += v[i];
        if (++arrived_ == 2) {
            result_ = acc_;
            acc_.clear();
            arrived_ = 0;
            ++gen_;
            cv_.notify_all();
        } else {
            cv_.wait(lock, [&] { return gen_ != gen; });
        }
        for (int64_t i = 0; i < n; ++i) v[i] = result_[size_t(i)];
    }

private:
    std::mutex m_;
    std::condition_variable cv_;
    std::vector<double> acc_, result_;
    int arrived_ = 0;
    int64_t gen_ = 0;
};

// Rows [from, from + n) of x (dim 0), as a new leaf.
Tensor rows(const Tensor& x, int64_t from, int64_t n) {
    Shape s = x.shape();
    const int64_t row = x.numel() / s[0];
    s[0] = n;
    std::vector<double> v(x.data<double>() + from * row, x.data<double>() + (from + n) * row);
    return Tensor::from_vector<double>(v, s);
}

void require_close(const double* a, const double* b, int64_t n) {
    for (int64_t i = 0; i < n; ++i) REQUIRE(a[i] == Approx(b[i]).margin(1e-12).epsilon(1e-10));
}

}  // namespace

TEST_CASE("data_parallel: BatchNorm over two half batches equals BatchNorm over the batch",
          "[nn][batchnorm][data_parallel]") {
    Rng rng(11);
    const int64_t B = 4, C = 3, N = 5;
    const Tensor x = Tensor::randn({B, C, N}, rng, DType::F64);
    const Tensor R = Tensor::randn({B, C, N}, rng, DType::F64);  // L = sum(y * R)
    const Tensor g0 = Tensor::randn({C}, rng, DType::F64), b0 = Tensor::randn({C}, rng, DType::F64);

    // One batch.
    Tensor xf = x.clone(), gf = g0.clone(), bf = b0.clone();
    xf.set_requires_grad(), gf.set_requires_grad(), bf.set_requires_grad();
    Tensor rmf = Tensor::zeros({C}, DType::F64), rvf = Tensor::ones({C}, DType::F64);
    const Tensor yf = nn::batch_norm(xf, gf, bf, rmf, rvf, true);
    nn::sum(yf * R).backward();

    // Two halves on two threads, summing through the hook.
    TwoPartySum exchange;
    struct Half {
        Tensor x, g, b, rm, rv, y;
    };
    std::vector<Half> half(2);
    auto run = [&](int r) {
        nn::DataParallel dp;
        dp.sum = [&exchange](double* v, int64_t n) { exchange.sum(v, n); };
        dp.batch_offset = r * B / 2;
        dp.global_batch = B;
        const nn::DataParallelGuard on(&dp);
        Half& h = half[size_t(r)];
        h.x = rows(x, r * B / 2, B / 2);
        h.g = g0.clone(), h.b = b0.clone();
        h.x.set_requires_grad(), h.g.set_requires_grad(), h.b.set_requires_grad();
        h.rm = Tensor::zeros({C}, DType::F64), h.rv = Tensor::ones({C}, DType::F64);
        h.y = nn::batch_norm(h.x, h.g, h.b, h.rm, h.rv, true);
        nn::sum(h.y * rows(R, r * B / 2, B / 2)).backward();
    };
    std::thread t1(run, 1);
    run(0);
    t1.join();

    const int64_t half_n = B / 2 * C * N;
    for (int r = 0; r < 2; ++r) {
        require_close(half[size_t(r)].y.data<double>(), yf.data<double>() + r * half_n, half_n);
        require_close(half[size_t(r)].x.grad().data<double>(),
                      xf.grad().data<double>() + r * half_n, half_n);
        require_close(half[size_t(r)].rm.data<double>(), rmf.data<double>(), C);
        require_close(half[size_t(r)].rv.data<double>(), rvf.data<double>(), C);
    }
    // Parameter gradients stay per half: their sum is the batch's (the trainers' all-reduce).
    for (int64_t c = 0; c < C; ++c) {
        REQUIRE(half[0].g.grad().data<double>()[c] + half[1].g.grad().data<double>()[c] ==
                Approx(gf.grad().data<double>()[c]).margin(1e-12));
        REQUIRE(half[0].b.grad().data<double>()[c] + half[1].b.grad().data<double>()[c] ==
                Approx(bf.grad().data<double>()[c]).margin(1e-12));
    }
}

TEST_CASE("data_parallel: a BatchNorm1d row per half is allowed when the batch has more",
          "[nn][batchnorm][data_parallel]") {
    // [B, C] with B = 2 split 1 + 1: one value per channel per half, two in the batch.
    TwoPartySum exchange;
    std::vector<Tensor> y(2);
    auto run = [&](int r) {
        nn::DataParallel dp;
        dp.sum = [&exchange](double* v, int64_t n) { exchange.sum(v, n); };
        dp.batch_offset = r;
        dp.global_batch = 2;
        const nn::DataParallelGuard on(&dp);
        const Tensor x = Tensor::from_vector<double>({r == 0 ? 1.0 : 3.0}, {1, 1});
        y[size_t(r)] = nn::batch_norm(x, Tensor(), Tensor(), Tensor(), Tensor(), true, 0.1, 1e-12);
    };
    std::thread t1(run, 1);
    run(0);
    t1.join();
    REQUIRE(y[0].data<double>()[0] == Approx(-1.0));  // mean 2, biased var 1
    REQUIRE(y[1].data<double>()[0] == Approx(1.0));
}

TEST_CASE("data_parallel: dropout keeps this process's rows of the batch's mask",
          "[nn][data_parallel]") {
    Rng init(5);
    const Tensor x = Tensor::rand({6, 4, 7}, init, 1.0, 2.0, DType::F64);
    Rng rf(99);
    const Tensor yf = nn::dropout(x, 0.3, true, rf);
    for (const int64_t from : {int64_t(0), int64_t(2), int64_t(5)}) {
        const int64_t n = from == 5 ? 1 : 3;
        nn::DataParallel dp;  // no sum: dropout needs none
        dp.batch_offset = from;
        dp.global_batch = 6;
        const nn::DataParallelGuard on(&dp);
        Rng rh(99);
        const Tensor yh = nn::dropout(rows(x, from, n), 0.3, true, rh);
        require_close(yh.data<double>(), yf.data<double>() + from * 28, n * 28);
        REQUIRE(rh.state() == rf.state());  // the stream advanced as for the whole batch
    }
}
