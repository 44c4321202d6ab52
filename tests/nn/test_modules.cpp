// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include "core/autograd.h"
#include "nn/modules/layers.h"
#include "nn/modules/shared_mlp.h"
#include "nn/ops/conv2d.h"

using namespace g2l;

TEST_CASE("modules: dotted state dict names, load round trip, strict errors", "[nn][modules]") {
    Rng rng(1);
    nn::SharedMlp a({3, 8, 4}, rng);
    const auto sd = a.state_dict();
    REQUIRE(sd.count("conv1.weight"));
    REQUIRE(sd.count("bn2.running_var"));
    REQUIRE(sd.at("conv2.weight").shape() == Shape{4, 8});
    REQUIRE(a.num_parameters() == (3 * 8 + 8 + 16) + (8 * 4 + 4 + 8));
    Rng rng2(2);
    nn::SharedMlp b({3, 8, 4}, rng2);
    b.load_state_dict(sd);
    REQUIRE(b.state_dict().at("conv1.weight").to_vector<float>() ==
            sd.at("conv1.weight").to_vector<float>());
    nn::SharedMlp c({3, 8, 5}, rng2);
    REQUIRE_THROWS_WITH(c.load_state_dict(sd), Catch::Contains("conv2.weight") &&
                                                   Catch::Contains("mismatch"));
    auto partial = sd;
    partial.erase("bn1.weight");
    partial["extra.weight"] = Tensor::zeros({1});
    REQUIRE_THROWS_WITH(b.load_state_dict(partial), Catch::Contains("missing: bn1.weight") &&
                                                        Catch::Contains("unexpected: extra.weight"));
}

TEST_CASE("modules: train/eval switch BatchNorm and Dropout", "[nn][modules]") {
    Rng rng(3);
    nn::BatchNorm bn(2);
    nn::Dropout drop(0.5, 7);
    const Tensor x = Tensor::randn({4, 2, 5}, rng);
    bn.forward(x);
    REQUIRE(bn.num_batches_tracked.item<int32_t>() == 1);
    REQUIRE(bn.running_mean.to_vector<float>() != std::vector<float>{0, 0});
    bn.eval();
    drop.eval();
    const auto rm = bn.running_mean.to_vector<float>();
    bn.forward(x);
    REQUIRE(bn.running_mean.to_vector<float>() == rm);  // eval does not update
    REQUIRE(drop.forward(x).to_vector<float>() == x.to_vector<float>());
    drop.train();
    const auto y = drop.forward(x).to_vector<float>();
    int zeros = 0;
    for (float v : y) zeros += v == 0.f;
    REQUIRE(zeros > 5);
    REQUIRE(zeros < 35);
    REQUIRE_THROWS_WITH(nn::Dropout(1.0, 1), Catch::Contains("[0, 1)"));
}

TEST_CASE("modules: Conv2d and MaxPoolPoints wrap their ops", "[nn][modules]") {
    Rng rng(4);
    nn::Conv2d conv(4, 6, {3, 3}, rng, {2, 2}, {1, 1});
    const Tensor x = Tensor::randn({2, 4, 9, 7}, rng);
    const Tensor y = conv.forward(x);
    REQUIRE(y.shape() == Shape{2, 6, 5, 4});
    REQUIRE(y.to_vector<float>() ==
            nn::conv2d(x, conv.weight, conv.bias, {2, 2}, {1, 1}).to_vector<float>());
    REQUIRE(conv.named_parameters().size() == 2);
    y.backward(Tensor::ones(y.shape()));
    REQUIRE(conv.weight.grad().shape() == conv.weight.shape());
    REQUIRE_THROWS_WITH(nn::Conv2d(4, 6, {3, 3}, rng, {1, 1}, {0, 0}, {1, 1}, 3),
                        Catch::Contains("groups 3"));
    nn::MaxPoolPoints pool;
    REQUIRE(pool.forward(Tensor::from_vector<float>({1, 4, 2, 3}, {1, 2, 2})).to_vector<float>() ==
            std::vector<float>{4, 3});
}
