// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include "core/rng.h"
#include "gradcheck.h"
#include "nn/ops/reduce.h"
#include "nn/ops/shape.h"
#include "opsa_helpers.h"

using namespace g2l;
using testing::opsa::f64;
using testing::opsa::i32;
using testing::opsa::require_close;
using testing::opsa::values;

namespace {

Tensor randn_req(const Shape& s, uint64_t seed) {
    Rng rng(seed);
    Tensor t = Tensor::randn(s, rng, DType::F64);
    t.set_requires_grad();
    return t;
}

// x = [[0, 1, 2], [3, 4, 5]].
Tensor arange23() { return f64({0, 1, 2, 3, 4, 5}, {2, 3}); }

}  // namespace

TEST_CASE("concat and stack: values and shapes", "[nn][opsa]") {
    const Tensor a = arange23(), b = f64({6, 7, 8}, {1, 3}), c = f64({9, 10}, {2, 1});
    const Tensor r = nn::concat({a, b}, 0);
    REQUIRE(r.shape() == (Shape{3, 3}));
    require_close(values(r), {0, 1, 2, 3, 4, 5, 6, 7, 8});
    const Tensor col = nn::concat({a, c}, -1);
    REQUIRE(col.shape() == (Shape{2, 4}));
    require_close(values(col), {0, 1, 2, 9, 3, 4, 5, 10});
    const Tensor s = nn::stack({f64({1, 2}, {2}), f64({3, 4}, {2}), f64({5, 6}, {2})}, 1);
    REQUIRE(s.shape() == (Shape{2, 3}));
    require_close(values(s), {1, 3, 5, 2, 4, 6});
    REQUIRE(nn::stack({a, a}, 0).shape() == (Shape{2, 2, 3}));
    REQUIRE(nn::stack({a, a}, -1).shape() == (Shape{2, 3, 2}));
    // i32 tensors are copied too (no gradient).
    REQUIRE(nn::concat({i32({1, 2}, {2}), i32({3}, {1})}, 0).to_vector<int32_t>() ==
            std::vector<int32_t>{1, 2, 3});
}

TEST_CASE("slice: Python-style negative and clamped bounds", "[nn][opsa]") {
    const Tensor x = arange23();
    require_close(values(nn::slice(x, 1, 1, 3)), {1, 2, 4, 5});
    require_close(values(nn::slice(x, 1, -2, 100)), {1, 2, 4, 5});
    require_close(values(nn::slice(x, 0, -1, 2)), {3, 4, 5});
    require_close(values(nn::slice(x, -1, -100, 1)), {0, 3});
    REQUIRE(nn::slice(x, 1, 2, 1).shape() == (Shape{2, 0}));
    REQUIRE(nn::slice(x, 1, 5, 9).shape() == (Shape{2, 0}));
    Tensor xg = x.clone();
    xg.set_requires_grad();
    nn::sum(nn::slice(xg, 1, 1, 2)).backward();
    require_close(values(xg.grad()), {0, 1, 0, 0, 1, 0});
}

TEST_CASE("repeat, transpose, permute, squeeze and unsqueeze: values", "[nn][opsa]") {
    const Tensor x = arange23();
    const Tensor r = nn::repeat(x, 1, 2);
    REQUIRE(r.shape() == (Shape{2, 6}));
    require_close(values(r), {0, 1, 2, 0, 1, 2, 3, 4, 5, 3, 4, 5});
    require_close(values(nn::repeat(f64({1, 2}, {2, 1}), 1, 3)), {1, 1, 1, 2, 2, 2});
    require_close(values(nn::repeat(x, 0, 2)), {0, 1, 2, 3, 4, 5, 0, 1, 2, 3, 4, 5});
    REQUIRE(nn::repeat(x, 0, 0).shape() == (Shape{0, 3}));
    const Tensor t = nn::transpose(x, 0, 1);
    REQUIRE(t.shape() == (Shape{3, 2}));
    require_close(values(t), {0, 3, 1, 4, 2, 5});
    // permute [2, 3, 4] by (2, 0, 1): y[k, i, j] = x[i, j, k].
    std::vector<double> v(24);
    for (size_t i = 0; i < 24; ++i) v[i] = double(i);
    const Tensor x3 = f64(v, {2, 3, 4});
    const Tensor p = nn::permute(x3, {2, 0, -2});
    REQUIRE(p.shape() == (Shape{4, 2, 3}));
    const auto pv = values(p);
    for (int64_t k = 0; k < 4; ++k)
        for (int64_t i = 0; i < 2; ++i)
            for (int64_t j = 0; j < 3; ++j)
                REQUIRE(pv[size_t((k * 2 + i) * 3 + j)] == double((i * 3 + j) * 4 + k));
    REQUIRE(nn::unsqueeze(x, 0).shape() == (Shape{1, 2, 3}));
    REQUIRE(nn::unsqueeze(x, -1).shape() == (Shape{2, 3, 1}));
    REQUIRE(nn::squeeze(nn::unsqueeze(x, 1), 1).shape() == (Shape{2, 3}));
    REQUIRE(nn::squeeze(f64({4}, {1}), 0).dim() == 0);
}

TEST_CASE("index_select: values, repeated indices and scatter-add gradient", "[nn][opsa]") {
    const Tensor x = arange23();
    const Tensor idx = i32({2, 0, 2}, {3});
    const Tensor y = nn::index_select(x, 1, idx);
    REQUIRE(y.shape() == (Shape{2, 3}));
    require_close(values(y), {2, 0, 2, 5, 3, 5});
    require_close(values(nn::index_select(x, 0, i32({1, 1}, {2}))), {3, 4, 5, 3, 4, 5});
    REQUIRE(nn::index_select(x, 0, Tensor::empty({0}, DType::I32)).shape() == (Shape{0, 3}));
    Tensor xg = x.clone();
    xg.set_requires_grad();
    nn::sum(nn::index_select(xg, 1, idx)).backward();
    require_close(values(xg.grad()), {1, 0, 2, 1, 0, 2});
    REQUIRE(nn::index_select(i32({7, 8, 9}, {3}), 0, i32({2, 0}, {2})).to_vector<int32_t>() ==
            std::vector<int32_t>{9, 7});
}

TEST_CASE("shape ops: gradients match finite differences", "[nn][grad][opsa]") {
    const Tensor a = randn_req({2, 3, 4}, 1), b = randn_req({2, 1, 4}, 2),
                 c = randn_req({2, 2, 4}, 3);
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::concat(in, 1); }, {a, b, c});
    const Tensor d = randn_req({2, 3, 4}, 4);
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::stack(in, 2); }, {a, d});
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::slice(in[0], 2, 1, -1); },
                       {a});
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::repeat(in[0], 1, 3); }, {a});
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::repeat(in[0], 0, 2); }, {b});
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::transpose(in[0], 0, 2); },
                       {a});
    testing::gradcheck(
        [](const std::vector<Tensor>& in) {
            return nn::permute(in[0], {1, 2, 0});
        },
        {a});
    const Tensor idx = i32({3, 0, 3, 1, 3}, {5});
    testing::gradcheck(
        [&](const std::vector<Tensor>& in) { return nn::index_select(in[0], 2, idx); }, {a});
    testing::gradcheck(
        [&](const std::vector<Tensor>& in) {
            return nn::index_select(in[0], 0, i32({1, 1}, {2}));
        },
        {a});
    testing::gradcheck(
        [](const std::vector<Tensor>& in) { return nn::squeeze(nn::unsqueeze(in[0], 1), 2); }, {b});
}

TEST_CASE("index_select and permute are identical with 1 and 2 threads", "[nn][opsa][threads]") {
    Rng rng(5);
    const Tensor x0 = Tensor::randn({3, 2000, 64}, rng);
    Tensor idx = Tensor::empty({5000}, DType::I32);
    for (int64_t i = 0; i < 5000; ++i) idx.data<int32_t>()[i] = int32_t(rng.below(2000));
    auto run = [&](int threads) {
        std::vector<Tensor> out;
        testing::opsa::with_threads(threads, [&] {
            Tensor x = x0.clone();
            x.set_requires_grad();
            const Tensor y = nn::index_select(x, 1, idx);
            const Tensor p = nn::permute(y, {2, 0, 1});
            Rng r(9);
            p.backward(Tensor::randn(p.shape(), r));
            out = {y, p, x.grad()};
        });
        return out;
    };
    const auto one = run(1), two = run(2);
    for (size_t i = 0; i < one.size(); ++i) REQUIRE(testing::opsa::bitwise_equal(one[i], two[i]));
}

TEST_CASE("shape ops reject bad input", "[nn][opsa][errors]") {
    const Tensor x = Tensor::zeros({2, 3});
    REQUIRE_THROWS_WITH(nn::concat({}, 0), Catch::Contains("no tensors"));
    REQUIRE_THROWS_WITH(nn::concat({x, Tensor::zeros({3, 3})}, 1), Catch::Contains("tensor 1") &&
                                                                       Catch::Contains("[3, 3]") &&
                                                                       Catch::Contains("dim 0"));
    REQUIRE_THROWS_WITH(nn::concat({x, Tensor::zeros({2, 3}, DType::F64)}, 0),
                        Catch::Contains("dtype or rank"));
    REQUIRE_THROWS_WITH(nn::concat({x, x}, 2),
                        Catch::Contains("concat") && Catch::Contains("dim 2"));
    REQUIRE_THROWS_WITH(nn::stack({x, Tensor::zeros({3, 2})}, 0),
                        Catch::Contains("stack") && Catch::Contains("tensor 1"));
    REQUIRE_THROWS_WITH(nn::stack({x}, 3), Catch::Contains("dim 3") && Catch::Contains("-3 .. 2"));
    REQUIRE_THROWS_WITH(nn::slice(x, 2, 0, 1),
                        Catch::Contains("slice") && Catch::Contains("dim 2"));
    REQUIRE_THROWS_WITH(nn::repeat(x, 0, -1), Catch::Contains("n must be >= 0, got -1"));
    REQUIRE_THROWS_WITH(nn::transpose(x, 0, 2), Catch::Contains("dim 2"));
    REQUIRE_THROWS_WITH(nn::permute(x, {0, 0}), Catch::Contains("appears twice"));
    REQUIRE_THROWS_WITH(nn::permute(x, {0}), Catch::Contains("1 dims given"));
    REQUIRE_THROWS_WITH(nn::index_select(x, 1, i32({0, 3}, {2})),
                        Catch::Contains("idx[1] = 3") && Catch::Contains("[0, 3)"));
    REQUIRE_THROWS_WITH(nn::index_select(x, 1, i32({-1}, {1})), Catch::Contains("idx[0] = -1"));
    REQUIRE_THROWS_WITH(nn::index_select(x, 0, Tensor::zeros({2})),
                        Catch::Contains("idx must be i32 [L]") && Catch::Contains("f32[2]"));
    REQUIRE_THROWS_WITH(nn::index_select(x, 0, i32({0, 1}, {1, 2})), Catch::Contains("i32[1, 2]"));
    REQUIRE_THROWS_WITH(nn::squeeze(x, 1), Catch::Contains("size 3, not 1"));
    REQUIRE_THROWS_WITH(nn::unsqueeze(x, 3),
                        Catch::Contains("unsqueeze") && Catch::Contains("dim 3"));
    REQUIRE_THROWS_WITH(nn::slice(Tensor(), 0, 0, 1), Catch::Contains("undefined"));
}
