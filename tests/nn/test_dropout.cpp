// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <cmath>

#include "core/rng.h"
#include "gradcheck.h"
#include "nn/ops/dropout.h"
#include "nn/ops/reduce.h"
#include "opsa_helpers.h"

using namespace g2l;
using testing::opsa::values;

TEST_CASE("dropout: identity at eval and for p = 0", "[nn][opsa]") {
    Rng rng(1);
    const Tensor x = Tensor::ones({4, 5});
    const Tensor e = nn::dropout(x, 0.5, false, rng);
    REQUIRE(e.shares_storage_with(x));
    REQUIRE(nn::dropout(x, 0.0, true, rng).shares_storage_with(x));
    // Neither call drew from the stream.
    Rng fresh(1);
    REQUIRE(rng.next_u64() == fresh.next_u64());
}

TEST_CASE("dropout: mask follows the rng stream, scale 1/(1-p)", "[nn][opsa]") {
    const double p = 0.3;
    Rng rng(42);
    Tensor x = Tensor::rand({100, 1000}, rng, 1.0, 2.0, DType::F64);
    x.set_requires_grad();
    Rng r1(7);
    const Tensor y = nn::dropout(x, p, true, r1);
    // Replay the documented draw order: one uniform per element, dropped where u < p.
    Rng r2(7);
    const auto xv = values(x), yv = values(y);
    int64_t dropped = 0;
    for (size_t i = 0; i < xv.size(); ++i) {
        const bool drop = r2.uniform() < p;
        dropped += drop;
        REQUIRE(yv[i] == (drop ? 0.0 : xv[i] * (1.0 / (1.0 - p))));
    }
    REQUIRE(std::fabs(double(dropped) / 1e5 - p) < 0.01);
    REQUIRE(r1.next_u64() == r2.next_u64());  // consumed exactly numel draws
    // Gradient = mask: 0 where dropped, 1/(1-p) elsewhere.
    nn::sum(y).backward();
    const auto g = values(x.grad());
    for (size_t i = 0; i < g.size(); ++i) REQUIRE(g[i] == (yv[i] == 0.0 ? 0.0 : 1.0 / (1.0 - p)));
    // Same seed, same result; f32 input gives the same mask.
    Rng r3(7);
    REQUIRE(testing::opsa::bitwise_equal(nn::dropout(x.detach(), p, true, r3), y));
    Rng r4(7);
    const auto yf = values(nn::dropout(x.detach().to(DType::F32), p, true, r4));
    for (size_t i = 0; i < yf.size(); ++i) REQUIRE((yf[i] == 0.0) == (yv[i] == 0.0));
}

TEST_CASE("dropout: gradcheck with a re-seeded rng and thread invariance", "[nn][grad][opsa]") {
    Rng rng(3);
    Tensor x = Tensor::randn({4, 6}, rng, DType::F64);
    x.set_requires_grad();
    testing::gradcheck(
        [](const std::vector<Tensor>& in) {
            Rng r(11);
            return nn::dropout(in[0], 0.4, true, r);
        },
        {x});
    const Tensor big = Tensor::randn({300, 400}, rng);
    Tensor one, two;
    testing::opsa::with_threads(1, [&] {
        Rng r(5);
        one = nn::dropout(big, 0.5, true, r);
    });
    testing::opsa::with_threads(2, [&] {
        Rng r(5);
        two = nn::dropout(big, 0.5, true, r);
    });
    REQUIRE(testing::opsa::bitwise_equal(one, two));
}

TEST_CASE("dropout rejects bad p and non-float input", "[nn][opsa][errors]") {
    Rng rng(1);
    const Tensor x = Tensor::ones({3});
    REQUIRE_THROWS_WITH(nn::dropout(x, 1.0, true, rng),
                        Catch::Contains("p must be in [0, 1), got 1"));
    REQUIRE_THROWS_WITH(nn::dropout(x, -0.1, true, rng), Catch::Contains("got -0.1"));
    REQUIRE_THROWS_WITH(nn::dropout(x, NAN, false, rng), Catch::Contains("got nan"));
    REQUIRE_THROWS_WITH(nn::dropout(Tensor::ones({3}, DType::I32), 0.5, true, rng),
                        Catch::Contains("dropout") && Catch::Contains("i32"));
}
