// SPDX-License-Identifier: MIT
#include <omp.h>

#include <catch2/catch.hpp>

#include "core/rng.h"
#include "gradcheck.h"
#include "nn/ops/linear.h"

using namespace g2l;

namespace {
Tensor param(const Shape& s, uint64_t seed) {
    Rng rng(seed);
    Tensor t = Tensor::randn(s, rng, DType::F64);
    t.set_requires_grad();
    return t;
}
}  // namespace

TEST_CASE("linear: forward equals a hand-computed product", "[nn][linear]") {
    const Tensor x = Tensor::from_vector<float>({1, 2, 3, 4, 5, 6}, {2, 3});
    const Tensor w = Tensor::from_vector<float>({1, 0, -1, 2, 1, 0}, {2, 3});
    const Tensor b = Tensor::from_vector<float>({0.5f, -1}, {2});
    // row 0: [1-3, 2+2] + b = [-1.5, 3]; row 1: [4-6, 8+5] + b = [-1.5, 12]
    REQUIRE(nn::linear(x, w, b).to_vector<float>() == std::vector<float>{-1.5f, 3, -1.5f, 12});
}

TEST_CASE("conv1x1: forward equals a per-point loop", "[nn][linear]") {
    Rng rng(3);
    const Tensor x = Tensor::randn({2, 5, 7}, rng, DType::F64);
    const Tensor w = Tensor::randn({4, 5}, rng, DType::F64);
    const Tensor b = Tensor::randn({4}, rng, DType::F64);
    const Tensor y = nn::conv1x1(x, w, b);
    REQUIRE(y.shape() == Shape{2, 4, 7});
    const double *px = x.data<double>(), *pw = w.data<double>(), *pb = b.data<double>();
    for (int bi = 0; bi < 2; ++bi)
        for (int o = 0; o < 4; ++o)
            for (int n = 0; n < 7; ++n) {
                double s = pb[o];
                for (int c = 0; c < 5; ++c) s += pw[o * 5 + c] * px[(bi * 5 + c) * 7 + n];
                REQUIRE(y.data<double>()[(bi * 4 + o) * 7 + n] == Approx(s).epsilon(1e-12));
            }
}

TEST_CASE("linear, conv1x1, matmul: gradients match finite differences", "[nn][grad][linear]") {
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::linear(in[0], in[1], in[2]); },
                       {param({3, 4}, 1), param({5, 4}, 2), param({5}, 3)});
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::linear(in[0], in[1]); },
                       {param({3, 4}, 4), param({2, 4}, 5)});
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::conv1x1(in[0], in[1], in[2]); },
                       {param({2, 3, 6}, 6), param({4, 3}, 7), param({4}, 8)});
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::matmul(in[0], in[1]); },
                       {param({3, 5}, 9), param({5, 2}, 10)});
}

TEST_CASE("conv1x1: results are identical with 1 and 2 threads", "[nn][linear][threads]") {
    Rng rng(11);
    Tensor x = Tensor::randn({2, 96, 700}, rng);
    Tensor w = Tensor::randn({200, 96}, rng);
    Tensor b = Tensor::randn({200}, rng);
    w.set_requires_grad();
    x.set_requires_grad();
    auto run = [&](int threads) {
        omp_set_num_threads(threads);
        x.zero_grad();
        w.zero_grad();
        Tensor y = nn::conv1x1(x, w, b);
        Rng r2(5);
        y.backward(Tensor::randn(y.shape(), r2));
        return std::vector<std::vector<float>>{y.to_vector<float>(), x.grad().to_vector<float>(),
                                               w.grad().to_vector<float>()};
    };
    const auto one = run(1), two = run(2);
    omp_set_num_threads(2);
    REQUIRE(one == two);
}

TEST_CASE("linear, conv1x1, matmul: shape errors name the op and shapes", "[nn][errors]") {
    const Tensor x = Tensor::zeros({2, 3, 4}), w = Tensor::zeros({5, 6});
    REQUIRE_THROWS_WITH(nn::conv1x1(x, w), Catch::Contains("conv1x1") &&
                                               Catch::Contains("[5, 6]") &&
                                               Catch::Contains("[2, 3, 4]"));
    REQUIRE_THROWS_WITH(nn::conv1x1(Tensor::zeros({2, 3}), w), Catch::Contains("[B, Cin, N]"));
    REQUIRE_THROWS_WITH(nn::linear(Tensor::zeros({2, 6}), w, Tensor::zeros({4})),
                        Catch::Contains("bias") && Catch::Contains("[5]"));
    REQUIRE_THROWS_WITH(nn::matmul(Tensor::zeros({2, 3}), Tensor::zeros({4, 2})),
                        Catch::Contains("inner sizes"));
    REQUIRE_THROWS_WITH(nn::linear(Tensor::zeros({2, 6}), Tensor::zeros({5, 6}, DType::F64)),
                        Catch::Contains("dtype"));
}
