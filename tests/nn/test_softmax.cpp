// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <cmath>

#include "core/rng.h"
#include "gradcheck.h"
#include "nn/ops/softmax.h"
#include "opsa_helpers.h"

using namespace g2l;
using testing::opsa::f64;
using testing::opsa::require_close;
using testing::opsa::values;

namespace {

// softmax over dim d of a [A, B, C] tensor, by definition (no max subtraction: small inputs).
std::vector<double> brute_softmax(const Tensor& x, int64_t d, bool log) {
    const Shape s = x.shape();
    const auto v = values(x);
    std::vector<double> y(v.size());
    const int64_t stride = d == 0 ? s[1] * s[2] : (d == 1 ? s[2] : 1);
    for (size_t k = 0; k < v.size(); ++k) {
        const int64_t pos = (int64_t(k) / stride) % s[size_t(d)];
        const int64_t base = int64_t(k) - pos * stride;
        double z = 0;
        for (int64_t j = 0; j < s[size_t(d)]; ++j) z += std::exp(v[size_t(base + j * stride)]);
        y[k] = log ? v[k] - std::log(z) : std::exp(v[k]) / z;
    }
    return y;
}

}  // namespace

TEST_CASE("softmax and log_softmax: hand values and stability", "[nn][opsa]") {
    const double e = std::exp(1.0);
    // softmax([0, 1]) = [1, e] / (1 + e); large logits give the same result without overflow.
    require_close(values(nn::softmax(f64({0, 1}, {2}), 0)), {1 / (1 + e), e / (1 + e)}, 1e-15);
    require_close(values(nn::softmax(f64({1000, 1001}, {1, 2}), 1)), {1 / (1 + e), e / (1 + e)},
                  1e-15);
    require_close(values(nn::log_softmax(f64({1000, 1001}, {2}), -1)),
                  {-std::log(1 + e), 1 - std::log(1 + e)}, 1e-12);
    require_close(values(nn::softmax(f64({-1000, 0}, {2}), 0)), {0, 1}, 1e-15);
    // Uniform rows.
    require_close(values(nn::softmax(Tensor::zeros({2, 4}, DType::F64), 1)),
                  std::vector<double>(8, 0.25));
    const Tensor f = nn::softmax(Tensor::from_vector<float>({0.f, 1.f}, {2}), 0);
    REQUIRE(f.dtype() == DType::F32);
    require_close(values(f), {1 / (1 + e), e / (1 + e)}, 1e-7);
}

TEST_CASE("softmax over each dim of a 3-d tensor matches the definition", "[nn][opsa]") {
    Rng rng(2);
    const Tensor x = Tensor::randn({2, 3, 4}, rng, DType::F64);
    for (int64_t d : {0, 1, 2}) {
        INFO("dim " << d);
        require_close(values(nn::softmax(x, d)), brute_softmax(x, d, false), 1e-14);
        require_close(values(nn::log_softmax(x, d)), brute_softmax(x, d, true), 1e-14);
        require_close(values(nn::softmax(x, d - 3)), brute_softmax(x, d, false), 1e-14);
    }
}

TEST_CASE("softmax and log_softmax: gradients match finite differences", "[nn][grad][opsa]") {
    Rng rng(4);
    Tensor x = Tensor::randn({2, 3, 4}, rng, DType::F64);
    x.set_requires_grad();
    for (int64_t d : {0, 1, 2, -1}) {
        INFO("dim " << d);
        testing::gradcheck([d](const std::vector<Tensor>& in) { return nn::softmax(in[0], d); },
                           {x});
        testing::gradcheck([d](const std::vector<Tensor>& in) { return nn::log_softmax(in[0], d); },
                           {x});
    }
}

TEST_CASE("softmax is identical with 1 and 2 threads", "[nn][opsa][threads]") {
    Rng rng(6);
    const Tensor x0 = Tensor::randn({16, 10, 2000}, rng);
    const Tensor dy = Tensor::randn({16, 10, 2000}, rng);
    auto run = [&](int threads) {
        std::vector<Tensor> out;
        testing::opsa::with_threads(threads, [&] {
            Tensor x = x0.clone();
            x.set_requires_grad();
            const Tensor a = nn::softmax(x, 1), b = nn::log_softmax(x, -1);
            a.backward(dy);
            b.backward(dy);
            out = {a, b, x.grad()};
        });
        return out;
    };
    const auto one = run(1), two = run(2);
    for (size_t i = 0; i < one.size(); ++i) REQUIRE(testing::opsa::bitwise_equal(one[i], two[i]));
}

TEST_CASE("softmax rejects bad input", "[nn][opsa][errors]") {
    REQUIRE_THROWS_WITH(nn::softmax(Tensor::zeros({2, 3}), 2), Catch::Contains("softmax") &&
                                                                   Catch::Contains("dim 2") &&
                                                                   Catch::Contains("[2, 3]"));
    REQUIRE_THROWS_WITH(nn::log_softmax(Tensor::zeros({2, 3}), -3),
                        Catch::Contains("log_softmax") && Catch::Contains("dim -3"));
    REQUIRE_THROWS_WITH(nn::softmax(Tensor::zeros({2}, DType::I32), 0),
                        Catch::Contains("softmax") && Catch::Contains("i32"));
    REQUIRE_THROWS_WITH(nn::softmax(Tensor::zeros({2, 0}), 1), Catch::Contains("empty"));
}
