// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>

#include "core/rng.h"
#include "gradcheck.h"
#include "nn/ops/pool2d.h"
#include "opsa_helpers.h"

using namespace g2l;

namespace {

Tensor iota_plane(int64_t h, int64_t w, float start, float step) {
    std::vector<float> v(size_t(h * w));
    for (size_t i = 0; i < v.size(); ++i) v[i] = start + step * float(i);
    return Tensor::from_vector(v, {1, 1, h, w});
}

std::vector<float> grad_of(const Tensor& x0, const std::function<Tensor(const Tensor&)>& f,
                           const Tensor& dy) {
    Tensor x = x0.clone();
    x.set_requires_grad();
    f(x).backward(dy);
    return x.grad().to_vector<float>();
}

}  // namespace

TEST_CASE("max_pool2d: hand-made windows, padding never wins", "[nn][opsb]") {
    // 4x4 plane 0..15, 2x2 windows, stride 2.
    const Tensor x = iota_plane(4, 4, 0.f, 1.f);
    REQUIRE(nn::max_pool2d(x, {2, 2}, {2, 2}).to_vector<float>() ==
            std::vector<float>{5, 7, 13, 15});
    // All-negative plane -1..-16 with kernel 3, stride 2, pad 1: Ho = (4 + 2 - 3) / 2 + 1 = 2.
    // A zero pad would win every window; the in-image maxima are the windows' top-left pixels.
    const Tensor xn = iota_plane(4, 4, -1.f, -1.f);
    const Tensor y = nn::max_pool2d(xn, {3, 3}, {2, 2}, {1, 1});
    REQUIRE(y.shape() == Shape{1, 1, 2, 2});
    REQUIRE(y.to_vector<float>() == std::vector<float>{-1, -2, -5, -6});
    // Gradient goes to the winners only: (0,0), (0,1), (1,0), (1,1) of the plane.
    const auto dx = grad_of(
        xn, [](const Tensor& t) { return nn::max_pool2d(t, {3, 3}, {2, 2}, {1, 1}); },
        Tensor::from_vector<float>({1, 2, 3, 4}, {1, 1, 2, 2}));
    REQUIRE(dx == std::vector<float>{1, 2, 0, 0, 3, 4, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0});
}

TEST_CASE("max_pool2d: ties go to the first element, overlapping windows accumulate",
          "[nn][opsb]") {
    const Tensor x = Tensor::full({1, 1, 3, 3}, 2.0);
    const auto dx = grad_of(
        x, [](const Tensor& t) { return nn::max_pool2d(t, {2, 2}, {1, 1}); },
        Tensor::from_vector<float>({1, 10, 100, 1000}, {1, 1, 2, 2}));
    // Each 2x2 window's first (top-left) element wins: (0,0), (0,1), (1,0), (1,1).
    REQUIRE(dx == std::vector<float>{1, 10, 0, 100, 1000, 0, 0, 0, 0});
    // Distinct values where one pixel wins four overlapping windows.
    const Tensor xs = Tensor::from_vector<float>({0, 1, 0, 2, 9, 3, 0, 4, 0}, {1, 1, 3, 3});
    REQUIRE(nn::max_pool2d(xs, {2, 2}, {1, 1}).to_vector<float>() ==
            std::vector<float>{9, 9, 9, 9});
    const auto dxs = grad_of(
        xs, [](const Tensor& t) { return nn::max_pool2d(t, {2, 2}, {1, 1}); },
        Tensor::from_vector<float>({1, 10, 100, 1000}, {1, 1, 2, 2}));
    REQUIRE(dxs == std::vector<float>{0, 0, 0, 0, 1111, 0, 0, 0, 0});
}

TEST_CASE("max_pool2d: NaN propagates", "[nn][opsb]") {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const Tensor x = Tensor::from_vector<float>({1, nan, 3, 2}, {1, 1, 2, 2});
    const auto y = nn::max_pool2d(x, {2, 2}, {2, 2}).to_vector<float>();
    REQUIRE(std::isnan(y[0]));
}

TEST_CASE("avg_pool2d: hand-made windows with and without counting the padding", "[nn][opsb]") {
    // 3x3 plane 1..9, kernel 3, stride 1, pad 1 -> 3x3 output.
    const Tensor x = iota_plane(3, 3, 1.f, 1.f);
    const auto inc = nn::avg_pool2d(x, {3, 3}, {1, 1}, {1, 1}, true).to_vector<float>();
    const auto exc = nn::avg_pool2d(x, {3, 3}, {1, 1}, {1, 1}, false).to_vector<float>();
    // Window sums: corners 12, 16, 24, 28; edges 21, 27, 33, 39; centre 45.
    const std::vector<double> sums = {12, 21, 16, 27, 45, 33, 24, 39, 28};
    const std::vector<double> counts = {4, 6, 4, 6, 9, 6, 4, 6, 4};
    for (size_t i = 0; i < 9; ++i) {
        CHECK(inc[i] == Approx(sums[i] / 9).epsilon(1e-6));
        CHECK(exc[i] == Approx(sums[i] / counts[i]).epsilon(1e-6));
    }
    // Backward spreads dy / divisor over the in-image part of each window.
    const auto dx = grad_of(
        iota_plane(2, 3, 0.f, 1.f),
        [](const Tensor& t) { return nn::avg_pool2d(t, {2, 2}, {1, 1}, {0, 0}, true); },
        Tensor::from_vector<float>({4, 8}, {1, 1, 1, 2}));
    REQUIRE(dx == std::vector<float>{1, 3, 2, 1, 3, 2});
}

TEST_CASE("global_avg_pool2d: per-plane means", "[nn][opsb]") {
    std::vector<float> v(24);
    for (size_t i = 0; i < 24; ++i) v[i] = float(i * i % 7);
    const Tensor x = Tensor::from_vector(v, {2, 3, 2, 2});
    const Tensor y = nn::global_avg_pool2d(x);
    REQUIRE(y.shape() == Shape{2, 3, 1, 1});
    const auto yv = y.to_vector<float>();
    for (size_t p = 0; p < 6; ++p)
        CHECK(yv[p] == Approx((v[4 * p] + v[4 * p + 1] + v[4 * p + 2] + v[4 * p + 3]) / 4.0));
}

TEST_CASE("pooling: analytic grads match finite differences", "[nn][grad][opsb]") {
    Tensor x = testing::distinct_values({2, 3, 7, 6}, 21);
    x.set_requires_grad();
    testing::gradcheck(
        [](const std::vector<Tensor>& t) { return nn::max_pool2d(t[0], {3, 2}, {2, 1}, {1, 1}); },
        {x});
    testing::gradcheck(
        [](const std::vector<Tensor>& t) { return nn::max_pool2d(t[0], {2, 2}, {2, 2}); }, {x});
    for (const bool inc : {true, false}) {
        testing::gradcheck(
            [inc](const std::vector<Tensor>& t) {
                return nn::avg_pool2d(t[0], {3, 3}, {2, 2}, {1, 1}, inc);
            },
            {x});
    }
    testing::gradcheck([](const std::vector<Tensor>& t) { return nn::global_avg_pool2d(t[0]); },
                       {x});
}

TEST_CASE("pooling: results are bitwise identical with 1 and 2 threads", "[nn][opsb]") {
    std::vector<Tensor> runs[2];
    for (int threads = 1; threads <= 2; ++threads) {
        testing::opsa::with_threads(threads, [&] {
            Rng rng(3);
            Tensor x = Tensor::randn({3, 8, 17, 15}, rng);
            x.set_requires_grad();
            const Tensor y1 = nn::max_pool2d(x, {3, 3}, {2, 2}, {1, 1});
            const Tensor y2 = nn::avg_pool2d(x, {3, 3}, {2, 2}, {1, 1}, false);
            const Tensor dy = Tensor::randn(y1.shape(), rng);
            y1.backward(dy);
            y2.backward(dy);
            runs[threads - 1] = {y1, y2, x.grad()};
        });
    }
    for (size_t k = 0; k < 3; ++k) CHECK(testing::opsa::bitwise_equal(runs[0][k], runs[1][k]));
}

TEST_CASE("pooling: bad shapes and arguments throw naming the shapes", "[nn][errors][opsb]") {
    const Tensor x = Tensor::zeros({1, 2, 5, 5});
    REQUIRE_THROWS_WITH(nn::max_pool2d(Tensor::zeros({2, 5, 5}), {2, 2}, {2, 2}),
                        Catch::Contains("[B, C, H, W]") && Catch::Contains("[2, 5, 5]"));
    REQUIRE_THROWS_WITH(nn::max_pool2d(x, {2, 2}, {0, 2}),
                        Catch::Contains("stride must be >= 1, got (0, 2)"));
    REQUIRE_THROWS_WITH(nn::avg_pool2d(x, {0, 2}, {1, 1}), Catch::Contains("kernel must be >= 1"));
    REQUIRE_THROWS_WITH(nn::max_pool2d(x, {3, 3}, {1, 1}, {2, 1}),
                        Catch::Contains("padding (2, 1)") && Catch::Contains("kernel (3, 3)"));
    REQUIRE_THROWS_WITH(nn::avg_pool2d(x, {7, 2}, {1, 1}),
                        Catch::Contains("kernel 7x2 is larger than the padded input 5x5") &&
                            Catch::Contains("[1, 2, 5, 5]"));
    REQUIRE_NOTHROW(nn::avg_pool2d(x, {7, 2}, {1, 1}, {1, 0}));  // 7 <= 5 + 2
    REQUIRE_THROWS_WITH(nn::max_pool2d(Tensor::zeros({1, 0, 5, 5}), {2, 2}, {2, 2}),
                        Catch::Contains("empty"));
    REQUIRE_THROWS_WITH(nn::global_avg_pool2d(Tensor::zeros({2, 5})),
                        Catch::Contains("global_avg_pool2d") && Catch::Contains("[2, 5]"));
    REQUIRE_THROWS_WITH(nn::max_pool2d(Tensor::zeros({1, 1, 2, 2}, DType::I32), {2, 2}, {2, 2}),
                        Catch::Contains("max_pool2d") && Catch::Contains("i32"));
}
