// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>


#include "core/rng.h"
#include "gradcheck.h"
#include "nn/ops/upsample.h"
#include "opsa_helpers.h"

using namespace g2l;

namespace {

void require_approx(const std::vector<float>& got, const std::vector<float>& want) {
    REQUIRE(got.size() == want.size());
    for (size_t i = 0; i < got.size(); ++i) {
        INFO("element " << i);
        CHECK(got[i] == Approx(want[i]).margin(1e-6));
    }
}

}  // namespace

TEST_CASE("upsample_nearest2d: values and block-summed gradient", "[nn][opsb]") {
    Tensor x = Tensor::from_vector<float>({1, 2, 3, 4, 5, 6}, {1, 1, 2, 3});
    const Tensor y = nn::upsample_nearest2d(x, 2);
    REQUIRE(y.shape() == Shape{1, 1, 4, 6});
    REQUIRE(y.to_vector<float>() == std::vector<float>{1, 1, 2, 2, 3, 3, 1, 1, 2, 2, 3, 3,
                                                       4, 4, 5, 5, 6, 6, 4, 4, 5, 5, 6, 6});
    x.set_requires_grad();
    std::vector<float> dyv(24);
    for (size_t i = 0; i < 24; ++i) dyv[i] = float(i);
    nn::upsample_nearest2d(x, 2).backward(Tensor::from_vector(dyv, {1, 1, 4, 6}));
    // dx[h, w] = dy[2h, 2w] + dy[2h, 2w+1] + dy[2h+1, 2w] + dy[2h+1, 2w+1].
    REQUIRE(x.grad().to_vector<float>() == std::vector<float>{14, 22, 30, 62, 70, 78});
    REQUIRE(nn::upsample_nearest2d(x.detach(), 1).to_vector<float>() ==
            std::vector<float>{1, 2, 3, 4, 5, 6});
}

TEST_CASE("upsample_bilinear2d: PyTorch's index convention on hand-made inputs", "[nn][opsb]") {
    const Tensor x = Tensor::from_vector<float>({1, 2, 3, 4}, {1, 1, 2, 2});
    // F.interpolate(x, size=(4, 4), mode="bilinear", align_corners=False).
    require_approx(nn::upsample_bilinear2d(x, 4, 4).to_vector<float>(),
                   {1.0f, 1.25f, 1.75f, 2.0f, 1.5f, 1.75f, 2.25f, 2.5f, 2.5f, 2.75f, 3.25f,
                    3.5f, 3.0f, 3.25f, 3.75f, 4.0f});
    // align_corners=True, 2x2 -> 3x3: corners kept, midpoints averaged.
    require_approx(nn::upsample_bilinear2d(x, 3, 3, true).to_vector<float>(),
                   {1.0f, 1.5f, 2.0f, 2.0f, 2.5f, 3.0f, 3.0f, 3.5f, 4.0f});
    // Downsampling 1x4 -> 1x2: sources 0.5 and 2.5.
    const Tensor r = Tensor::from_vector<float>({1, 2, 3, 4}, {1, 1, 1, 4});
    require_approx(nn::upsample_bilinear2d(r, 1, 2).to_vector<float>(), {1.5f, 3.5f});
    // Non-integer ratio 3 -> 5: sources max(-0.2, 0), 0.4, 1.0, 1.6, 2.2 (clamped to the edge).
    const Tensor s = Tensor::from_vector<float>({0, 10, 20}, {1, 1, 1, 3});
    require_approx(nn::upsample_bilinear2d(s, 1, 5).to_vector<float>(), {0, 4, 10, 16, 20});
    // Same size is the identity.
    require_approx(nn::upsample_bilinear2d(x, 2, 2).to_vector<float>(), {1, 2, 3, 4});
}

TEST_CASE("upsample_bilinear2d: gradient spreads dy with the interpolation weights",
          "[nn][opsb]") {
    Tensor s = Tensor::from_vector<float>({0, 10, 20}, {1, 1, 1, 3});
    s.set_requires_grad();
    nn::upsample_bilinear2d(s, 1, 5).backward(Tensor::ones({1, 1, 1, 5}));
    // Weights per output: (1,0,0), (0.6,0.4,0), (0,1,0), (0,0.4,0.6), (0,0,1).
    require_approx(s.grad().to_vector<float>(), {1.6f, 1.8f, 1.6f});
}

TEST_CASE("upsampling: analytic grads match finite differences", "[nn][grad][opsb]") {
    Rng rng(8);
    Tensor x = Tensor::randn({2, 3, 4, 5}, rng, DType::F64);
    x.set_requires_grad();
    testing::gradcheck([](const std::vector<Tensor>& t) { return nn::upsample_nearest2d(t[0], 3); },
                       {x});
    for (const bool ac : {false, true}) {
        for (const auto& hw : {std::pair<int64_t, int64_t>{7, 11}, {3, 2}, {1, 1}, {8, 10}}) {
            testing::gradcheck(
                [ac, hw](const std::vector<Tensor>& t) {
                    return nn::upsample_bilinear2d(t[0], hw.first, hw.second, ac);
                },
                {x});
        }
    }
}

TEST_CASE("upsampling: results are bitwise identical with 1 and 2 threads", "[nn][opsb]") {
    std::vector<Tensor> runs[2];
    for (int threads = 1; threads <= 2; ++threads) {
        testing::opsa::with_threads(threads, [&] {
            Rng rng(4);
            Tensor x = Tensor::randn({2, 8, 13, 11}, rng);
            x.set_requires_grad();
            const Tensor y1 = nn::upsample_nearest2d(x, 2);
            const Tensor y2 = nn::upsample_bilinear2d(x, 26, 22);
            y1.backward(Tensor::randn(y1.shape(), rng));
            y2.backward(Tensor::randn(y2.shape(), rng));
            runs[threads - 1] = {y1, y2, x.grad()};
        });
    }
    for (size_t k = 0; k < 3; ++k) CHECK(testing::opsa::bitwise_equal(runs[0][k], runs[1][k]));
}

TEST_CASE("upsampling: bad shapes and arguments throw naming the shapes", "[nn][errors][opsb]") {
    const Tensor x = Tensor::zeros({1, 2, 3, 3});
    REQUIRE_THROWS_WITH(nn::upsample_nearest2d(x, 0),
                        Catch::Contains("scale must be >= 1, got 0") &&
                            Catch::Contains("[1, 2, 3, 3]"));
    REQUIRE_THROWS_WITH(nn::upsample_nearest2d(Tensor::zeros({2, 3, 3}), 2),
                        Catch::Contains("[B, C, H, W]") && Catch::Contains("[2, 3, 3]"));
    REQUIRE_THROWS_WITH(nn::upsample_bilinear2d(x, 0, 4),
                        Catch::Contains("output size must be >= 1, got 0x4"));
    REQUIRE_THROWS_WITH(nn::upsample_bilinear2d(Tensor::zeros({1, 2, 3, 3, 1}), 4, 4),
                        Catch::Contains("upsample_bilinear2d") &&
                            Catch::Contains("[1, 2, 3, 3, 1]"));
    REQUIRE_THROWS_WITH(nn::upsample_bilinear2d(Tensor::zeros({1, 0, 3, 3}), 4, 4),
                        Catch::Contains("empty"));
    REQUIRE_THROWS_WITH(nn::upsample_nearest2d(Tensor::zeros({1, 1, 2, 2}, DType::I32), 2),
                        Catch::Contains("i32"));
}
