// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include "gradcheck.h"
#include "nn/ops/relu.h"

using namespace g2l;

TEST_CASE("relu: forward values and analytic grad matches finite differences", "[nn][grad]") {
    const Tensor x = Tensor::from_vector<float>({-2.f, -0.5f, 0.25f, 3.f}, {2, 2});
    const auto y = nn::relu(x).to_vector<float>();
    REQUIRE(y == std::vector<float>{0.f, 0.f, 0.25f, 3.f});

    Tensor xd = testing::distinct_values({3, 4, 5}, 7);
    xd.set_requires_grad();
    testing::gradcheck([](const std::vector<Tensor>& in) { return nn::relu(in[0]); }, {xd});
}

TEST_CASE("relu: rejects integer and undefined input", "[nn][errors]") {
    REQUIRE_THROWS_WITH(nn::relu(Tensor::zeros({2}, DType::I32)),
                        Catch::Contains("relu") && Catch::Contains("i32"));
    REQUIRE_THROWS_WITH(nn::relu(Tensor()), Catch::Contains("undefined"));
}
