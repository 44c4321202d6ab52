// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <cmath>

#include "core/rng.h"
#include "gradcheck.h"
#include "nn/ops/elementwise.h"
#include "nn/ops/reduce.h"
#include "opsa_helpers.h"

using namespace g2l;
using testing::opsa::f64;
using testing::opsa::require_close;
using testing::opsa::values;

namespace {

// x = [[0, 1, 2], [3, 4, 5]].
Tensor arange23() { return f64({0, 1, 2, 3, 4, 5}, {2, 3}); }

Tensor req(Tensor t) {
    t.set_requires_grad();
    return t;
}

}  // namespace

TEST_CASE("sum and mean: values, dims, keepdim", "[nn][opsa]") {
    const Tensor x = arange23();
    const Tensor s = nn::sum(x);
    REQUIRE(s.dim() == 0);
    REQUIRE(s.item<double>() == 15.0);
    require_close(values(nn::sum(x, 0)), {3, 5, 7});
    require_close(values(nn::sum(x, 1)), {3, 12});
    require_close(values(nn::sum(x, -1)), {3, 12});
    REQUIRE(nn::sum(x, 1).shape() == Shape{2});
    REQUIRE(nn::sum(x, 1, true).shape() == (Shape{2, 1}));
    REQUIRE(nn::sum(x, -2, true).shape() == (Shape{1, 3}));
    REQUIRE(nn::mean(x).item<double>() == 2.5);
    require_close(values(nn::mean(x, 0)), {1.5, 2.5, 3.5});
    require_close(values(nn::mean(x, 1, true)), {1, 4});
    REQUIRE(nn::sum(Tensor::zeros({0, 3})).item<float>() == 0.f);
    require_close(values(nn::sum(Tensor::zeros({2, 0}), 1)), {0, 0});
    // Middle dimension of a 3-d tensor: [2, 2, 2] = 0..7 summed over dim 1.
    require_close(values(nn::sum(f64({0, 1, 2, 3, 4, 5, 6, 7}, {2, 2, 2}), 1)), {2, 4, 10, 12});
}

TEST_CASE("sum over long dimensions matches a double reference", "[nn][opsa]") {
    // D > the kernel's chunk size (2048) with inner > 1 exercises the chunked partial sums.
    Rng rng(5);
    const Tensor x = Tensor::randn({3, 5000, 7}, rng);
    const auto v = x.to_vector<float>();
    std::vector<double> ref(21, 0.0);
    for (int64_t o = 0; o < 3; ++o)
        for (int64_t d = 0; d < 5000; ++d)
            for (int64_t i = 0; i < 7; ++i)
                ref[size_t(o * 7 + i)] += v[size_t((o * 5000 + d) * 7 + i)];
    require_close(values(nn::sum(x, 1)), ref, 1e-3);
    double all = 0;
    for (float f : v) all += f;
    REQUIRE(std::fabs(nn::sum(x).item<double>() - all) < 1e-2);
    REQUIRE(std::fabs(nn::mean(x).item<double>() - all / 105000.0) < 1e-7);
}

TEST_CASE("max: values, indices, ties and gradient to the argmax", "[nn][opsa]") {
    const Tensor x = f64({1, 3, 3, 2, 7, -1}, {2, 3});
    const nn::MaxResult m = nn::max(x, 1);
    require_close(values(m.values), {3, 7});
    REQUIRE(m.indices.dtype() == DType::I32);
    REQUIRE(m.indices.to_vector<int32_t>() == std::vector<int32_t>{1, 1});  // tie -> lowest index
    const nn::MaxResult m0 = nn::max(x, 0, true);
    REQUIRE(m0.values.shape() == (Shape{1, 3}));
    require_close(values(m0.values), {2, 7, 3});
    REQUIRE(m0.indices.to_vector<int32_t>() == std::vector<int32_t>{1, 1, 0});
    Tensor xg = req(x.clone());
    nn::sum(nn::max(xg, -1).values).backward();
    require_close(values(xg.grad()), {0, 1, 0, 0, 1, 0});
    // NaN counts as the maximum (propagates like PyTorch).
    const nn::MaxResult mn = nn::max(f64({1, NAN, 5}, {3}), 0);
    REQUIRE(std::isnan(mn.values.item<double>()));
    REQUIRE(mn.indices.item<int32_t>() == 1);
}

TEST_CASE("norm and normalize: values and the eps guard at zero", "[nn][opsa]") {
    const Tensor x = f64({3, 4, 0, 0, 5, 12}, {3, 2});
    require_close(values(nn::norm(x, 1, false, 0.0)), {5, 0, 13});
    require_close(values(nn::norm(x, 0, true, 0.0)), {std::sqrt(34.0), std::sqrt(160.0)});
    require_close(values(nn::norm(x, 1)), {5, 1e-6, 13}, 1e-12);
    require_close(values(nn::normalize(x, 1)), {0.6, 0.8, 0, 0, 5.0 / 13, 12.0 / 13}, 1e-12);
    // At x = 0 with eps > 0 the gradient is finite (0), not NaN.
    Tensor z = req(Tensor::zeros({2, 3}, DType::F64));
    nn::sum(nn::norm(z, 1)).backward();
    require_close(values(z.grad()), {0, 0, 0, 0, 0, 0});
}

TEST_CASE("reductions: gradients match finite differences", "[nn][grad][opsa]") {
    Rng rng(7);
    const Tensor x = req(Tensor::randn({2, 3, 4}, rng, DType::F64));
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::sum(in[0]); }, {x});
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::mean(in[0]); }, {x});
    for (int64_t d : {0, 1, 2, -1}) {
        INFO("dim " << d);
        for (bool keep : {false, true}) {
            testing::gradcheck(
                [d, keep](const std::vector<Tensor>& in) { return nn::sum(in[0], d, keep); }, {x});
            testing::gradcheck(
                [d, keep](const std::vector<Tensor>& in) { return nn::mean(in[0], d, keep); }, {x});
            testing::gradcheck(
                [d, keep](const std::vector<Tensor>& in) { return nn::norm(in[0], d, keep); }, {x});
        }
        testing::gradcheck([d](const std::vector<Tensor>& in) { return nn::normalize(in[0], d); },
                           {x});
    }
    const Tensor xd = req(testing::distinct_values({3, 4, 5}, 9));
    for (int64_t d : {0, 1, 2})
        testing::gradcheck([d](const std::vector<Tensor>& in) { return nn::max(in[0], d).values; },
                           {xd});
}

TEST_CASE("sum of 1e6 elements is identical with 1 and 2 threads", "[nn][opsa][threads]") {
    Rng rng(11);
    const Tensor x0 = Tensor::randn({1000, 1000}, rng);
    auto run = [&](int threads) {
        std::vector<Tensor> out;
        testing::opsa::with_threads(threads, [&] {
            Tensor x = x0.clone();
            x.set_requires_grad();
            const Tensor s = nn::sum(x);
            const Tensor loss =
                nn::add(nn::add(s, nn::sum(nn::sum(x, 0))), nn::sum(nn::norm(x, 0)));
            loss.backward();
            out = {s,
                   nn::sum(x, 0),
                   nn::sum(x, 1),
                   nn::mean(x, 1),
                   nn::max(x, 0).values,
                   nn::norm(x, 1),
                   x.grad()};
        });
        return out;
    };
    const auto one = run(1), two = run(2);
    for (size_t i = 0; i < one.size(); ++i) {
        INFO("output " << i);
        REQUIRE(testing::opsa::bitwise_equal(one[i], two[i]));
    }
}

TEST_CASE("reductions reject bad input", "[nn][opsa][errors]") {
    const Tensor x = Tensor::zeros({2, 3});
    REQUIRE_THROWS_WITH(nn::sum(x, 2), Catch::Contains("sum") && Catch::Contains("dim 2") &&
                                           Catch::Contains("[2, 3]"));
    REQUIRE_THROWS_WITH(nn::mean(x, -3), Catch::Contains("mean") && Catch::Contains("dim -3"));
    REQUIRE_THROWS_WITH(nn::max(x, 5), Catch::Contains("max") && Catch::Contains("dim 5"));
    REQUIRE_THROWS_WITH(nn::norm(x, 1, false, -1.0), Catch::Contains("eps"));
    REQUIRE_THROWS_WITH(nn::sum(Tensor::zeros({2}, DType::I32)),
                        Catch::Contains("sum") && Catch::Contains("i32"));
    REQUIRE_THROWS_WITH(nn::mean(Tensor::zeros({0})), Catch::Contains("empty"));
    REQUIRE_THROWS_WITH(nn::max(Tensor::zeros({2, 0}), 1),
                        Catch::Contains("max") && Catch::Contains("empty"));
    REQUIRE_THROWS_WITH(nn::sum(Tensor::scalar(1.0), 0), Catch::Contains("no dimension"));
    REQUIRE_THROWS_WITH(nn::normalize(Tensor(), 0), Catch::Contains("undefined"));
}
