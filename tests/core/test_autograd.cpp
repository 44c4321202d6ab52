// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include "core/autograd.h"
#include "core/tensor.h"

using namespace g2l;

namespace {
// y = a * b element-wise (a tiny op written with core alone, so core is tested without nn).
Tensor mul(const Tensor& a, const Tensor& b) {
    Tensor y = Tensor::empty(a.shape(), DType::F64);
    for (int64_t i = 0; i < a.numel(); ++i) y.data<double>()[i] = a.data<double>()[i] * b.data<double>()[i];
    return autograd::record("test_mul", y, {a, b}, [a, b](const Tensor& d, autograd::Grads& g) {
        if (g.needs(0)) g.add(0, mul(d.detach(), b.detach()));
        if (g.needs(1)) g.add(1, mul(d.detach(), a.detach()));
    });
}
Tensor vec(std::vector<double> v) { return Tensor::from_vector(v, {int64_t(v.size())}); }
}  // namespace

TEST_CASE("autograd: chain rule, accumulation over shared inputs, leaf gradient accumulation",
          "[core][autograd]") {
    Tensor x = vec({2, 3});
    x.set_requires_grad();
    // z = (x * x) * x  -> dz/dx = 3 x^2, seeded with ones
    Tensor z = mul(mul(x, x), x);
    z.backward(Tensor::ones({2}, DType::F64));
    REQUIRE(x.grad().to_vector<double>() == std::vector<double>{12, 27});
    // a second graph accumulates into the same leaf gradient
    Tensor w = mul(x, vec({1, 1}));
    w.backward(Tensor::ones({2}, DType::F64));
    REQUIRE(x.grad().to_vector<double>() == std::vector<double>{13, 28});
    x.zero_grad();
    REQUIRE_FALSE(x.grad().defined());
}

TEST_CASE("autograd: no-grad mode records nothing, graph is freed after backward",
          "[core][autograd]") {
    Tensor x = vec({1, 2});
    x.set_requires_grad();
    {
        autograd::NoGradGuard guard;
        REQUIRE_FALSE(mul(x, x).requires_grad());
    }
    Tensor y = mul(x, x);
    REQUIRE(y.grad_fn() != nullptr);
    Tensor s = y.reshape({2, 1});
    s.backward(Tensor::ones({2, 1}, DType::F64));
    REQUIRE_THROWS_WITH(s.backward(Tensor::ones({2, 1}, DType::F64)),
                        Catch::Contains("already freed"));
    Tensor y2 = mul(x, x);
    y2.backward(Tensor::ones({2}, DType::F64), /*retain_graph=*/true);
    y2.backward(Tensor::ones({2}, DType::F64));  // allowed once more
}

TEST_CASE("autograd: errors for non-scalar seeds, missing grad, in-place modification",
          "[core][autograd][errors]") {
    Tensor x = vec({1, 2});
    REQUIRE_THROWS_WITH(x.backward(), Catch::Contains("does not require grad"));
    x.set_requires_grad();
    Tensor y = mul(x, x);
    REQUIRE_THROWS_WITH(y.backward(), Catch::Contains("one element"));
    REQUIRE_THROWS_WITH(y.backward(Tensor::ones({3}, DType::F64)), Catch::Contains("does not match"));
    Tensor c = vec({5, 6});
    Tensor z = mul(x, c);
    c.fill_(0);  // modifies a saved input after use
    REQUIRE_THROWS_WITH(z.backward(Tensor::ones({2}, DType::F64)),
                        Catch::Contains("modified in place") && Catch::Contains("test_mul"));
    REQUIRE_THROWS_WITH(x.fill_(1), Catch::Contains("NoGradGuard"));
    REQUIRE_THROWS_WITH(y.set_requires_grad(), Catch::Contains("only leaves"));
}
