// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>

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

// Reference broadcast: out index -> input flat index, written with explicit multi-indices.
std::vector<double> brute_binary(const Tensor& a, const Tensor& b, const Shape& out,
                                 double (*f)(double, double)) {
    const auto va = values(a), vb = values(b);
    const int64_t r = int64_t(out.size()), n = shape_numel(out);
    std::vector<double> y(static_cast<size_t>(n));
    for (int64_t k = 0; k < n; ++k) {
        std::vector<int64_t> idx(static_cast<size_t>(r));
        int64_t rem = k;
        for (int64_t d = r - 1; d >= 0; --d) {
            idx[size_t(d)] = rem % out[size_t(d)];
            rem /= out[size_t(d)];
        }
        auto flat = [&](const Shape& s) {
            int64_t off = 0;
            for (size_t d = 0; d < s.size(); ++d) {
                const int64_t i = idx[size_t(r) - s.size() + d];
                off = off * s[d] + (s[d] == 1 ? 0 : i);
            }
            return off;
        };
        y[size_t(k)] = f(va[size_t(flat(a.shape()))], vb[size_t(flat(b.shape()))]);
    }
    return y;
}

Tensor grad_input(const Shape& s, uint64_t seed, double offset = 0) {
    Rng rng(seed);
    Tensor t = Tensor::randn(s, rng, DType::F64);
    if (offset != 0) t = nn::add_scalar(t, offset).detach();
    t.set_requires_grad();
    return t;
}

}  // namespace

TEST_CASE("broadcast binary ops match a brute-force reference", "[nn][opsa]") {
    struct Case {
        Shape a, b, out;
    };
    const std::vector<Case> cases = {{{2, 3, 4}, {3, 1}, {2, 3, 4}}, {{4}, {2, 3, 4}, {2, 3, 4}},
                                     {{}, {2, 3}, {2, 3}},           {{2, 1, 4}, {3, 1}, {2, 3, 4}},
                                     {{3, 5}, {3, 5}, {3, 5}},       {{5, 1}, {1, 6}, {5, 6}}};
    Rng rng(3);
    for (const Case& c : cases) {
        const Tensor a = Tensor::randn(c.a, rng, DType::F64);
        const Tensor b = Tensor::rand(c.b, rng, 0.5, 2.0, DType::F64);
        INFO("a " << shape_str(c.a) << " b " << shape_str(c.b));
        REQUIRE(nn::broadcast_shape("test", c.a, c.b) == c.out);
        const Tensor s = nn::add(a, b);
        REQUIRE(s.shape() == c.out);
        require_close(values(s),
                      brute_binary(a, b, c.out, [](double u, double v) { return u + v; }));
        require_close(values(nn::sub(a, b)),
                      brute_binary(a, b, c.out, [](double u, double v) { return u - v; }));
        require_close(values(nn::mul(a, b)),
                      brute_binary(a, b, c.out, [](double u, double v) { return u * v; }));
        require_close(values(nn::div(a, b)),
                      brute_binary(a, b, c.out, [](double u, double v) { return u / v; }));
    }
    // Hand-computed: [[1, 2, 3]] + [[10], [20]] -> [[11, 12, 13], [21, 22, 23]].
    const Tensor y = nn::add(f64({1, 2, 3}, {1, 3}), f64({10, 20}, {2, 1}));
    REQUIRE(y.shape() == Shape{2, 3});
    require_close(values(y), {11, 12, 13, 21, 22, 23});
}

TEST_CASE("broadcast binary ops: gradients match finite differences", "[nn][grad][opsa]") {
    struct Case {
        Shape a, b;
    };
    const std::vector<Case> cases = {{{2, 3, 4}, {3, 1}}, {{4}, {2, 3, 4}},    {{}, {2, 3}},
                                     {{2, 3}, {}},        {{2, 1, 4}, {3, 1}}, {{3, 4}, {3, 4}}};
    uint64_t seed = 10;
    for (const Case& c : cases) {
        INFO("a " << shape_str(c.a) << " b " << shape_str(c.b));
        const Tensor a = grad_input(c.a, seed++), b = grad_input(c.b, seed++);
        // Divisors kept away from 0 so the finite differences are well conditioned.
        const Tensor bd = grad_input(c.b, seed++, 3.0);
        testing::gradcheck([](const std::vector<Tensor>& in) { return nn::add(in[0], in[1]); },
                           {a, b});
        testing::gradcheck([](const std::vector<Tensor>& in) { return nn::sub(in[0], in[1]); },
                           {a, b});
        testing::gradcheck([](const std::vector<Tensor>& in) { return nn::mul(in[0], in[1]); },
                           {a, b});
        testing::gradcheck([](const std::vector<Tensor>& in) { return nn::div(in[0], in[1]); },
                           {a, bd});
    }
    // The same tensor on both sides: gradients of both uses add up (d(x*x)/dx = 2x).
    const Tensor x = grad_input({3}, 99);
    nn::sum(nn::mul(x, x)).backward();
    require_close(values(x.grad()), values(nn::mul_scalar(x.detach(), 2.0)));
}

TEST_CASE("binary ops give no gradient to inputs that do not need one", "[nn][opsa]") {
    const Tensor a = grad_input({2, 3}, 1);
    const Tensor b = f64({1, 2, 3}, {3});
    nn::sum(nn::mul(a, b)).backward();
    REQUIRE_FALSE(b.grad().defined());
    // d sum(a * b) / da = b broadcast over the rows.
    require_close(values(a.grad()), {1, 2, 3, 1, 2, 3});
}

TEST_CASE("unary ops: forward values", "[nn][opsa]") {
    const double e = std::exp(1.0);
    require_close(values(nn::neg(f64({1, -2}, {2}))), {-1, 2});
    require_close(values(nn::exp(f64({0, 1}, {2}))), {1, e}, 1e-15);
    require_close(values(nn::log(f64({1, e}, {2}))), {0, 1}, 1e-15);
    require_close(values(nn::sqrt(f64({4, 2.25}, {2}))), {2, 1.5});
    require_close(values(nn::square(f64({-3, 0.5}, {2}))), {9, 0.25});
    require_close(values(nn::pow_scalar(f64({2, 9}, {2}), 3)), {8, 729});
    require_close(values(nn::pow_scalar(f64({4}, {1}), -0.5)), {0.5});
    require_close(values(nn::abs(f64({-2, 0, 3}, {3}))), {2, 0, 3});
    require_close(values(nn::sigmoid(f64({0, 2, -1000, 1000}, {4}))),
                  {0.5, 1 / (1 + std::exp(-2.0)), 0, 1}, 1e-15);
    require_close(values(nn::tanh(f64({0, 1}, {2}))), {0, std::tanh(1.0)});
    require_close(values(nn::clamp(f64({-5, 0.5, 7}, {3}), -1, 2)), {-1, 0.5, 2});
    require_close(values(nn::add_scalar(f64({1, 2}, {2}), 0.5)), {1.5, 2.5});
    require_close(values(nn::mul_scalar(f64({1, 2}, {2}), -3)), {-3, -6});
    // f32 runs the same kernels.
    const Tensor xf = Tensor::from_vector<float>({0.f, 1.f}, {2});
    require_close(values(nn::exp(xf)), {1, e}, 1e-6);
    REQUIRE(nn::exp(xf).dtype() == DType::F32);
    // 0-d tensors work.
    REQUIRE(nn::square(Tensor::scalar(3.0, DType::F64)).item<double>() == 9.0);
}

TEST_CASE("unary ops: gradients match finite differences", "[nn][grad][opsa]") {
    using F = Tensor (*)(const Tensor&);
    const Tensor any = grad_input({3, 4}, 5);
    const Tensor pos = grad_input({3, 4}, 6);  // made positive below
    Tensor p = nn::add_scalar(nn::abs(pos.detach()), 0.5).detach();
    p.set_requires_grad();
    for (F f : {F(nn::neg), F(nn::exp), F(nn::square), F(nn::sigmoid), F(nn::tanh)})
        testing::gradcheck([f](const std::vector<Tensor>& in) { return f(in[0]); }, {any});
    for (F f : {F(nn::log), F(nn::sqrt)})
        testing::gradcheck([f](const std::vector<Tensor>& in) { return f(in[0]); }, {p});
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::pow_scalar(in[0], 2.5); },
                       {p});
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::pow_scalar(in[0], -1.5); },
                       {p});
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::add_scalar(in[0], 4); },
                       {any});
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::mul_scalar(in[0], -2); },
                       {any});
    // Non-smooth ops on inputs with no value near the kinks (distinct, gap 0.1).
    Tensor d = testing::distinct_values({4, 5}, 8, 0.1);
    d.set_requires_grad();
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::abs(in[0]); }, {d});
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::clamp(in[0], -0.52, 0.48); },
                       {d});
    // Conventions at the kinks: d|x|/dx = 0 at 0; clamp passes the gradient at the bounds.
    Tensor k = f64({0, -1, 2}, {3});
    k.set_requires_grad();
    nn::sum(nn::add(nn::abs(k), nn::clamp(k, -1, 2))).backward();
    require_close(values(k.grad()), {1, 0, 2});
}

TEST_CASE("tensor operators call the element-wise ops", "[nn][opsa]") {
    const Tensor a = f64({1, 2, 4}, {3}), b = f64({2}, {1});
    require_close(values(a + b), {3, 4, 6});
    require_close(values(a - b), {-1, 0, 2});
    require_close(values(a * b), {2, 4, 8});
    require_close(values(a / b), {0.5, 1, 2});
    require_close(values(-a), {-1, -2, -4});
    require_close(values(a + 1.0), {2, 3, 5});
    require_close(values(a - 1.0), {0, 1, 3});
    require_close(values(a * 3.0), {3, 6, 12});
    require_close(values(a / 4.0), {0.25, 0.5, 1});
    require_close(values(1.0 + a), {2, 3, 5});
    require_close(values(1.0 - a), {0, -1, -3});
    require_close(values(2.0 * a), {2, 4, 8});
    require_close(values(8.0 / a), {8, 4, 2});
    Tensor x = grad_input({2, 3}, 12, 3.0);
    testing::gradcheck([](const std::vector<Tensor>& in) { return (2.0 - in[0]) * (1.0 / in[0]); },
                       {x});
}

TEST_CASE("broadcast gradient reduction is identical with 1 and 2 threads", "[nn][opsa][threads]") {
    Rng rng(21);
    const Tensor a0 = Tensor::randn({400, 3, 500}, rng), b0 = Tensor::randn({3, 1}, rng);
    const Tensor c0 = Tensor::randn({500}, rng);
    auto run = [&](int threads) {
        std::vector<Tensor> out;
        testing::opsa::with_threads(threads, [&] {
            Tensor a = a0.clone(), b = b0.clone(), c = c0.clone();
            a.set_requires_grad();
            b.set_requires_grad();
            c.set_requires_grad();
            const Tensor y = nn::mul(nn::add(a, b), c);
            nn::sum(y).backward();
            out = {y, a.grad(), b.grad(), c.grad()};
        });
        return out;
    };
    const auto one = run(1), two = run(2);
    for (size_t i = 0; i < one.size(); ++i) REQUIRE(testing::opsa::bitwise_equal(one[i], two[i]));
    // b's gradient sums 200000 terms c[k]: compare with a double reference.
    const auto vc = c0.to_vector<float>();
    double sc = 0;
    for (float v : vc) sc += v;
    require_close(values(one[2]), {400 * sc, 400 * sc, 400 * sc}, 1e-2);
}

TEST_CASE("element-wise ops reject bad input", "[nn][opsa][errors]") {
    const Tensor a = Tensor::zeros({2, 3}), b = Tensor::zeros({4});
    REQUIRE_THROWS_WITH(nn::add(a, b), Catch::Contains("add") && Catch::Contains("[2, 3]") &&
                                           Catch::Contains("[4]"));
    REQUIRE_THROWS_WITH(
        nn::mul(Tensor::zeros({2, 3, 4}), Tensor::zeros({2, 4})),
        Catch::Contains("mul") && Catch::Contains("[2, 3, 4]") && Catch::Contains("[2, 4]"));
    REQUIRE_THROWS_WITH(a / b, Catch::Contains("div") && Catch::Contains("cannot be broadcast"));
    REQUIRE_THROWS_WITH(nn::sub(a, Tensor::zeros({2, 3}, DType::F64)),
                        Catch::Contains("sub") && Catch::Contains("f64"));
    REQUIRE_THROWS_WITH(nn::add(Tensor::zeros({2}, DType::I32), Tensor::zeros({2}, DType::I32)),
                        Catch::Contains("add") && Catch::Contains("i32"));
    REQUIRE_THROWS_WITH(nn::exp(Tensor::zeros({2}, DType::I32)),
                        Catch::Contains("exp") && Catch::Contains("i32"));
    REQUIRE_THROWS_WITH(nn::tanh(Tensor()),
                        Catch::Contains("tanh") && Catch::Contains("undefined"));
    REQUIRE_THROWS_WITH(nn::add(a, Tensor()), Catch::Contains("undefined"));
    const double nan = std::numeric_limits<double>::quiet_NaN();
    REQUIRE_THROWS_WITH(nn::pow_scalar(a, nan),
                        Catch::Contains("pow_scalar") && Catch::Contains("nan"));
    REQUIRE_THROWS_WITH(nn::clamp(a, 2, 1), Catch::Contains("lo 2") && Catch::Contains("hi 1"));
    REQUIRE_THROWS_WITH(nn::clamp(a, nan, 1), Catch::Contains("clamp"));
}
