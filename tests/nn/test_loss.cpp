// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <cmath>

#include "core/rng.h"
#include "gradcheck.h"
#include "nn/ops/loss.h"
#include "nn/ops/softmax.h"
#include "opsa_helpers.h"

using namespace g2l;
using testing::opsa::f64;
using testing::opsa::i32;
using testing::opsa::require_close;
using testing::opsa::values;

namespace {

Tensor req(Tensor t) {
    t.set_requires_grad();
    return t;
}

}  // namespace

TEST_CASE("nll_loss: hand-computed values, weights and both layouts", "[nn][opsa]") {
    const Tensor logp = f64({-1, -2, -3, -4}, {2, 2});
    const Tensor t = i32({1, 0}, {2});
    REQUIRE(nn::nll_loss(logp, t).item<double>() == 2.5);  // (2 + 3) / 2
    // Weights [1, 3]: (3 * 2 + 1 * 3) / (3 + 1).
    REQUIRE(nn::nll_loss(logp, t, f64({1, 3}, {2})).item<double>() == 2.25);
    // [B, K, N] = [1, 2, 3] with targets [0, 1, 1]: picks -1, -5, -6 -> 12 / 3.
    const Tensor lp3 = f64({-1, -2, -3, -4, -5, -6}, {1, 2, 3});
    REQUIRE(nn::nll_loss(lp3, i32({0, 1, 1}, {1, 3})).item<double>() == 4.0);
    // Gradient: -w[t] / sum(w) at the target entries.
    Tensor lg = req(logp.clone());
    nn::nll_loss(lg, t, f64({1, 3}, {2})).backward();
    require_close(values(lg.grad()), {0, -0.75, -0.25, 0});
    const Tensor loss_f32 = nn::nll_loss(logp.to(DType::F32), t);
    REQUIRE(loss_f32.dtype() == DType::F32);
    REQUIRE(loss_f32.dim() == 0);
}

TEST_CASE("cross_entropy equals nll of log_softmax and ln K for equal logits", "[nn][opsa]") {
    REQUIRE(std::fabs(nn::cross_entropy(Tensor::zeros({3, 4}, DType::F64), i32({0, 3, 2}, {3}))
                          .item<double>() -
                      std::log(4.0)) < 1e-14);
    Rng rng(3);
    const Tensor logits = Tensor::randn({2, 5, 6}, rng, DType::F64);
    Tensor t = Tensor::empty({2, 6}, DType::I32);
    for (int64_t i = 0; i < 12; ++i) t.data<int32_t>()[i] = int32_t(rng.below(5));
    // Reference by definition: mean over (b, n) of -(x_t - log sum_k exp x_k).
    const auto v = values(logits);
    double ref = 0;
    for (int64_t b = 0; b < 2; ++b)
        for (int64_t n = 0; n < 6; ++n) {
            double z = 0;
            for (int64_t k = 0; k < 5; ++k) z += std::exp(v[size_t((b * 5 + k) * 6 + n)]);
            const int32_t c = t.data<int32_t>()[b * 6 + n];
            ref -= v[size_t((b * 5 + c) * 6 + n)] - std::log(z);
        }
    REQUIRE(std::fabs(nn::cross_entropy(logits, t).item<double>() - ref / 12) < 1e-13);
}

TEST_CASE("mse_loss and smooth_l1_loss: hand-computed values", "[nn][opsa]") {
    const Tensor a = f64({1, 2, 3}, {3}), b = f64({1, 0, 0}, {3});
    REQUIRE(std::fabs(nn::mse_loss(a, b).item<double>() - 13.0 / 3) < 1e-15);
    // beta 1, d = [0.5, -2, 0] -> [0.125, 1.5, 0].
    const Tensor c = f64({0.5, -2, 0}, {3}), z = Tensor::zeros({3}, DType::F64);
    REQUIRE(std::fabs(nn::smooth_l1_loss(c, z, 1.0).item<double>() - 1.625 / 3) < 1e-15);
    // beta 0 is the L1 loss; beta 4: all quadratic -> (0.25 + 4) / 8 / 3.
    REQUIRE(std::fabs(nn::smooth_l1_loss(c, z, 0.0).item<double>() - 2.5 / 3) < 1e-15);
    REQUIRE(std::fabs(nn::smooth_l1_loss(c, z, 4.0).item<double>() - 4.25 / 24) < 1e-15);
    Tensor cg = req(c.clone());
    nn::smooth_l1_loss(cg, z, 1.0).backward();
    require_close(values(cg.grad()), {0.5 / 3, -1.0 / 3, 0});
}

TEST_CASE("argmax: indices with ties to the lowest index, i32, no gradient", "[nn][opsa]") {
    const Tensor x = f64({1, 5, 5, 0, -2, -1}, {2, 3});
    const Tensor i = nn::argmax(x, 1);
    REQUIRE(i.dtype() == DType::I32);
    REQUIRE(i.to_vector<int32_t>() == std::vector<int32_t>{1, 0});
    REQUIRE(nn::argmax(x, 0).to_vector<int32_t>() == std::vector<int32_t>{0, 0, 0});
    REQUIRE_FALSE(nn::argmax(req(x.clone()), -1).requires_grad());
}

TEST_CASE("losses: gradients match finite differences", "[nn][grad][opsa]") {
    Rng rng(8);
    const Tensor lp2 = req(Tensor::randn({4, 3}, rng, DType::F64));
    const Tensor lp3 = req(Tensor::randn({2, 3, 5}, rng, DType::F64));
    const Tensor t2 = i32({0, 2, 1, 2}, {4});
    const Tensor t3 = i32({0, 1, 2, 2, 1, 0, 0, 1, 1, 2}, {2, 5});
    const Tensor w = f64({0.5, 2, 1.25}, {3});
    testing::gradcheck([&](const std::vector<Tensor>& in) { return nn::nll_loss(in[0], t2); },
                       {lp2});
    testing::gradcheck([&](const std::vector<Tensor>& in) { return nn::nll_loss(in[0], t3, w); },
                       {lp3});
    testing::gradcheck(
        [&](const std::vector<Tensor>& in) { return nn::cross_entropy(in[0], t2, w); }, {lp2});
    testing::gradcheck([&](const std::vector<Tensor>& in) { return nn::cross_entropy(in[0], t3); },
                       {lp3});
    const Tensor a = req(Tensor::randn({3, 4}, rng, DType::F64));
    const Tensor b = req(Tensor::randn({3, 4}, rng, DType::F64));
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::mse_loss(in[0], in[1]); },
                       {a, b});
    // |a - b| stays away from beta = 0.05 (gap 0.1 between distinct values, b = 0).
    const Tensor d = req(testing::distinct_values({3, 4}, 2, 0.1));
    const Tensor zero = req(Tensor::zeros({3, 4}, DType::F64));
    testing::gradcheck(
        [](const std::vector<Tensor>& in) { return nn::smooth_l1_loss(in[0], in[1], 0.05); },
        {d, zero});
    testing::gradcheck(
        [](const std::vector<Tensor>& in) { return nn::smooth_l1_loss(in[0], in[1], 10.0); },
        {a, b});
}

TEST_CASE("losses reject bad input", "[nn][opsa][errors]") {
    const Tensor lp = Tensor::zeros({2, 3});
    REQUIRE_THROWS_WITH(nn::nll_loss(lp, i32({1, 3}, {2})),
                        Catch::Contains("target[1] = 3") && Catch::Contains("[0, 3)"));
    REQUIRE_THROWS_WITH(nn::nll_loss(lp, i32({-1, 0}, {2})), Catch::Contains("target[0] = -1"));
    REQUIRE_THROWS_WITH(nn::nll_loss(Tensor::zeros({1, 3, 2}), i32({0, 7}, {1, 2})),
                        Catch::Contains("target[0, 1] = 7"));
    REQUIRE_THROWS_WITH(nn::nll_loss(lp, Tensor::zeros({2})),
                        Catch::Contains("target must be i32") && Catch::Contains("f32[2]"));
    REQUIRE_THROWS_WITH(nn::nll_loss(lp, i32({0, 1, 2}, {3})),
                        Catch::Contains("needs target [M] = [2]") && Catch::Contains("i32[3]"));
    REQUIRE_THROWS_WITH(nn::nll_loss(Tensor::zeros({2, 3, 4}), i32({0, 1}, {2})),
                        Catch::Contains("[B, N] = [2, 4]"));
    REQUIRE_THROWS_WITH(nn::nll_loss(Tensor::zeros({2, 3, 4, 5}), i32({0}, {1})),
                        Catch::Contains("[M, K] or [B, K, N]"));
    REQUIRE_THROWS_WITH(nn::nll_loss(lp, i32({0, 1}, {2}), Tensor::ones({2})),
                        Catch::Contains("weight") && Catch::Contains("[K] = [3]"));
    REQUIRE_THROWS_WITH(nn::nll_loss(lp, i32({0, 0}, {2}), Tensor::zeros({3})),
                        Catch::Contains("total weight"));
    REQUIRE_THROWS_WITH(nn::cross_entropy(Tensor::zeros({3}), i32({0}, {1})),
                        Catch::Contains("cross_entropy") && Catch::Contains("f32[3]"));
    REQUIRE_THROWS_WITH(
        nn::mse_loss(Tensor::zeros({2, 3}), Tensor::zeros({3})),
        Catch::Contains("mse_loss") && Catch::Contains("[2, 3]") && Catch::Contains("f32[3]"));
    REQUIRE_THROWS_WITH(
        nn::mse_loss(Tensor::zeros({2}, DType::I32), Tensor::zeros({2}, DType::I32)),
        Catch::Contains("i32"));
    REQUIRE_THROWS_WITH(nn::smooth_l1_loss(Tensor::zeros({2}), Tensor::zeros({2}), -1.0),
                        Catch::Contains("beta") && Catch::Contains("-1"));
    REQUIRE_THROWS_WITH(nn::smooth_l1_loss(Tensor::zeros({2}), Tensor::zeros({2}), NAN),
                        Catch::Contains("beta"));
    REQUIRE_THROWS_WITH(nn::argmax(lp, 2), Catch::Contains("dim 2"));
}
