// SPDX-License-Identifier: MIT
#include <omp.h>

#include <catch2/catch.hpp>
#include <cmath>

#include "core/rng.h"
#include "gradcheck.h"
#include "nn/ops/batch_norm.h"
#include "nn/ops/pool_points.h"

using namespace g2l;

TEST_CASE("batch_norm: training normalises per channel and updates running stats",
          "[nn][batchnorm]") {
    // x: [2, 2, 2]; channel 0 values {1, 3, 5, 7}, channel 1 values {0, 0, 2, 2}.
    const Tensor x = Tensor::from_vector<double>({1, 3, 0, 0, 5, 7, 2, 2}, {2, 2, 2});
    Tensor rm = Tensor::zeros({2}, DType::F64), rv = Tensor::ones({2}, DType::F64);
    const Tensor y = nn::batch_norm(x, Tensor(), Tensor(), rm, rv, true, 0.1, 0.0 + 1e-12);
    // channel 0: mean 4, biased var 5 -> (1-4)/sqrt(5)
    REQUIRE(y.data<double>()[0] == Approx(-3 / std::sqrt(5.0)));
    REQUIRE(y.data<double>()[2] == Approx(-1.0));  // channel 1: mean 1, var 1
    REQUIRE(rm.data<double>()[0] == Approx(0.4));
    REQUIRE(rv.data<double>()[0] == Approx(0.9 + 0.1 * 20.0 / 3.0));  // unbiased var 20/3
    REQUIRE(rv.data<double>()[1] == Approx(0.9 + 0.1 * 4.0 / 3.0));
    // eval mode uses the running statistics
    const Tensor ye = nn::batch_norm(x, Tensor(), Tensor(), rm, rv, false, 0.1, 1e-12);
    REQUIRE(ye.data<double>()[0] == Approx((1 - 0.4) / std::sqrt(rv.data<double>()[0])));
}

TEST_CASE("batch_norm: gradients match finite differences in train and eval modes",
          "[nn][grad][batchnorm]") {
    Rng rng(2);
    Tensor x = Tensor::randn({3, 4, 5}, rng, DType::F64);
    Tensor gamma = Tensor::randn({4}, rng, DType::F64), beta = Tensor::randn({4}, rng, DType::F64);
    x.set_requires_grad();
    gamma.set_requires_grad();
    beta.set_requires_grad();
    for (bool training : {true, false}) {
        Tensor rm = Tensor::zeros({4}, DType::F64), rv = Tensor::full({4}, 2.0, DType::F64);
        testing::gradcheck(
            [&](const std::vector<Tensor>& in) {
                return nn::batch_norm(in[0], in[1], in[2], training ? Tensor() : rm,
                                      training ? Tensor() : rv, training);
            },
            {x, gamma, beta});
    }
    Tensor x2 = Tensor::randn({6, 3}, rng, DType::F64);  // [B, C] (BatchNorm1d on rows)
    x2.set_requires_grad();
    testing::gradcheck([&](const std::vector<Tensor>& in) {
        return nn::batch_norm(in[0], in[1], in[2], Tensor(), Tensor(), true);
    }, {x2, Tensor::ones({3}, DType::F64).set_requires_grad(),
        Tensor::zeros({3}, DType::F64).set_requires_grad()});
}

TEST_CASE("batch_norm: bad input is rejected with the shapes", "[nn][errors][batchnorm]") {
    const Tensor x = Tensor::zeros({2, 3, 4});
    REQUIRE_THROWS_WITH(nn::batch_norm(x, Tensor::ones({4}), Tensor(), Tensor(), Tensor(), true),
                        Catch::Contains("[C] = [3]"));
    REQUIRE_THROWS_WITH(nn::batch_norm(Tensor::zeros({1, 3}), Tensor(), Tensor(), Tensor(),
                                       Tensor(), true),
                        Catch::Contains("more than one value"));
    REQUIRE_THROWS_WITH(nn::batch_norm(x, Tensor(), Tensor(), Tensor(), Tensor(), false),
                        Catch::Contains("running statistics"));
    REQUIRE_THROWS_WITH(nn::batch_norm(Tensor::zeros({3}), Tensor(), Tensor(), Tensor(), Tensor(),
                                       true),
                        Catch::Contains("[B, C, N]"));
}

TEST_CASE("max_pool_points: values, argmax and gradient", "[nn][grad][maxpool]") {
    const Tensor x = Tensor::from_vector<float>({1, 5, 2, -1, -3, -2}, {1, 2, 3});
    Tensor arg;
    const Tensor y = nn::max_pool_points(x, &arg);
    REQUIRE(y.to_vector<float>() == std::vector<float>{5, -1});
    REQUIRE(arg.to_vector<int32_t>() == std::vector<int32_t>{1, 0});
    Tensor xd = testing::distinct_values({2, 3, 7}, 9);
    xd.set_requires_grad();
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::max_pool_points(in[0]); },
                       {xd});
    REQUIRE_THROWS_WITH(nn::max_pool_points(Tensor::zeros({2, 3, 0})),
                        Catch::Contains("empty point set"));
    REQUIRE_THROWS_WITH(nn::max_pool_points(Tensor::zeros({2, 3})), Catch::Contains("[B, C, N]"));
}

TEST_CASE("batch_norm and max_pool_points: identical with 1 and 2 threads", "[nn][threads]") {
    Rng rng(4);
    Tensor x = Tensor::randn({4, 256, 1000}, rng);
    x.set_requires_grad();
    auto run = [&](int threads) {
        omp_set_num_threads(threads);
        x.zero_grad();
        Tensor rm = Tensor::zeros({256}), rv = Tensor::ones({256});
        Tensor y = nn::max_pool_points(nn::batch_norm(x, Tensor(), Tensor(), rm, rv, true));
        Rng r2(1);
        y.backward(Tensor::randn(y.shape(), r2));
        return std::vector<std::vector<float>>{y.to_vector<float>(), x.grad().to_vector<float>(),
                                               rv.to_vector<float>()};
    };
    const auto one = run(1), two = run(2);
    omp_set_num_threads(2);
    REQUIRE(one == two);
}
