// SPDX-License-Identifier: MIT
#include <omp.h>

#include <catch2/catch.hpp>

#include "core/rng.h"
#include "gradcheck.h"
#include "nn/ops/concat_conv.h"
#include "nn/ops/elementwise.h"
#include "nn/ops/linear.h"
#include "nn/ops/reduce.h"
#include "nn/ops/shape.h"

using namespace g2l;

namespace {

Tensor rnd(const Shape& s, uint64_t seed, DType dt = DType::F64, bool grad = true) {
    Rng rng(seed);
    Tensor t = Tensor::randn(s, rng, dt);
    if (grad) t.set_requires_grad();
    return t;
}

// The reference: materialise the concatenation with the globals tiled N times, then conv1x1.
Tensor reference(const std::vector<Tensor>& xs, const std::vector<Tensor>& gs, const Tensor& w,
                 const Tensor& b) {
    std::vector<Tensor> all = xs;
    const int64_t N = xs[0].size(2);
    for (const Tensor& g : gs) all.push_back(nn::repeat(nn::unsqueeze(g, 2), 2, N));
    return nn::conv1x1(nn::concat(all, 1), w, b);
}

}  // namespace

TEST_CASE("concat_conv1x1: forward equals conv1x1 of the tiled concatenation",
          "[models][concat_conv]") {
    const std::vector<Tensor> xs = {rnd({2, 3, 5}, 1), rnd({2, 4, 5}, 2)};
    const std::vector<Tensor> gs = {rnd({2, 6}, 3), rnd({2, 2}, 4)};
    const Tensor w = rnd({7, 15}, 5), b = rnd({7}, 6);
    for (bool with_bias : {true, false}) {
        const Tensor bb = with_bias ? b : Tensor();
        const Tensor y = nn::concat_conv1x1(xs, gs, w, bb);
        REQUIRE(y.shape() == Shape{2, 7, 5});
        REQUIRE(testing::max_abs_diff(y, reference(xs, gs, w, bb)) < 1e-12);
    }
    // No global features: plain conv1x1 of the per-point concatenation.
    const Tensor w2 = rnd({7, 7}, 7);
    REQUIRE(testing::max_abs_diff(nn::concat_conv1x1(xs, {}, w2, b),
                                  nn::conv1x1(nn::concat(xs, 1), w2, b)) < 1e-12);
    // A hand-computed value: one point channel, one global channel, B = 1, N = 2.
    const Tensor x = Tensor::from_vector<float>({1.f, 2.f}, {1, 1, 2});
    const Tensor g = Tensor::from_vector<float>({10.f}, {1, 1});
    const Tensor wh = Tensor::from_vector<float>({3.f, 0.5f}, {1, 2});
    const Tensor bh = Tensor::from_vector<float>({-1.f}, {1});
    // y[n] = 3 x[n] + 0.5 * 10 - 1 = {7, 10}
    REQUIRE(nn::concat_conv1x1({x}, {g}, wh, bh).to_vector<float>() ==
            std::vector<float>{7.f, 10.f});
}

TEST_CASE("concat_conv1x1: gradients match finite differences", "[models][concat_conv][grad]") {
    testing::gradcheck(
        [](const std::vector<Tensor>& in) {
            return nn::concat_conv1x1({in[0], in[1]}, {in[2], in[3]}, in[4], in[5]);
        },
        {rnd({2, 3, 4}, 11), rnd({2, 2, 4}, 12), rnd({2, 3}, 13), rnd({2, 1}, 14),
         rnd({5, 9}, 15), rnd({5}, 16)});
    testing::gradcheck(
        [](const std::vector<Tensor>& in) { return nn::concat_conv1x1({in[0]}, {in[1]}, in[2]); },
        {rnd({3, 2, 6}, 17), rnd({3, 4}, 18), rnd({3, 6}, 19)});
}

TEST_CASE("concat_conv1x1: gradients equal those of the materialised reference",
          "[models][concat_conv][grad]") {
    auto run = [](bool fused) {
        std::vector<Tensor> in = {rnd({3, 16, 40}, 21, DType::F32), rnd({3, 8, 40}, 22, DType::F32),
                                  rnd({3, 32}, 23, DType::F32),     rnd({3, 5}, 24, DType::F32),
                                  rnd({12, 61}, 25, DType::F32),    rnd({12}, 26, DType::F32)};
        const Tensor y = fused ? nn::concat_conv1x1({in[0], in[1]}, {in[2], in[3]}, in[4], in[5])
                               : reference({in[0], in[1]}, {in[2], in[3]}, in[4], in[5]);
        nn::sum(nn::mul(y, rnd(y.shape(), 27, DType::F32, false))).backward();
        return in;
    };
    const auto a = run(true), r = run(false);
    for (size_t i = 0; i < a.size(); ++i) {
        INFO("input " << i);
        REQUIRE(a[i].grad().defined());
        REQUIRE(testing::max_abs_diff(a[i].grad(), r[i].grad()) < 1e-3);
    }
}

TEST_CASE("concat_conv1x1: computes only the gradients that are needed", "[models][concat_conv]") {
    const Tensor x = rnd({2, 3, 4}, 31, DType::F32, false);
    const Tensor g = rnd({2, 2}, 32, DType::F32, false);
    const Tensor w = rnd({4, 5}, 33, DType::F32, true);
    nn::sum(nn::concat_conv1x1({x}, {g}, w)).backward();
    REQUIRE(w.grad().defined());
    REQUIRE_FALSE(x.grad().defined());
    REQUIRE_FALSE(g.grad().defined());
    // Nothing requires grad: no graph is recorded.
    const Tensor y = nn::concat_conv1x1({x}, {g}, w.detach());
    REQUIRE(y.grad_fn() == nullptr);
}

TEST_CASE("concat_conv1x1: results are identical with 1 and 2 threads",
          "[models][concat_conv][threads]") {
    const int prev = omp_get_max_threads();
    std::vector<std::vector<float>> out, dws, dgs;
    for (int threads : {1, 2}) {
        omp_set_num_threads(threads);
        const Tensor x = rnd({2, 70, 600}, 41, DType::F32, true);
        const Tensor g = rnd({2, 300}, 42, DType::F32, true);
        const Tensor w = rnd({520, 370}, 43, DType::F32, true);
        const Tensor y = nn::concat_conv1x1({x}, {g}, w);
        nn::sum(nn::mul(y, rnd(y.shape(), 44, DType::F32, false))).backward();
        out.push_back(y.to_vector<float>());
        dws.push_back(w.grad().to_vector<float>());
        dgs.push_back(x.grad().to_vector<float>());
    }
    omp_set_num_threads(prev);
    REQUIRE(out[0] == out[1]);
    REQUIRE(dws[0] == dws[1]);
    REQUIRE(dgs[0] == dgs[1]);
}

TEST_CASE("concat_conv1x1: rejects inputs that do not fit, naming them",
          "[models][concat_conv][errors]") {
    const Tensor x = Tensor::zeros({2, 3, 5}), g = Tensor::zeros({2, 4}), w = Tensor::zeros({6, 7});
    REQUIRE_THROWS_WITH(nn::concat_conv1x1({}, {g}, w), Catch::Contains("at least one"));
    REQUIRE_THROWS_WITH(nn::concat_conv1x1({Tensor::zeros({2, 3})}, {g}, w),
                        Catch::Contains("[B, Ci, N]") && Catch::Contains("[2, 3]"));
    REQUIRE_THROWS_WITH(
        nn::concat_conv1x1({x, Tensor::zeros({2, 3, 6})}, {}, Tensor::zeros({6, 6})),
                        Catch::Contains("point_feats[1]") && Catch::Contains("[2, 3, 6]"));
    REQUIRE_THROWS_WITH(nn::concat_conv1x1({x}, {Tensor::zeros({3, 4})}, w),
                        Catch::Contains("global_feats[0]") && Catch::Contains("[3, 4]"));
    REQUIRE_THROWS_WITH(nn::concat_conv1x1({x}, {g}, Tensor::zeros({6, 8})),
                        Catch::Contains("8 input columns") && Catch::Contains("= 7"));
    REQUIRE_THROWS_WITH(nn::concat_conv1x1({x}, {g}, w, Tensor::zeros({5})),
                        Catch::Contains("bias") && Catch::Contains("[6]"));
    REQUIRE_THROWS_WITH(nn::concat_conv1x1({x}, {Tensor::zeros({2, 4}, DType::F64)}, w),
                        Catch::Contains("f64"));
}
