// SPDX-License-Identifier: MIT
// kernels::dispatch, the one point where an op picks its kernel by (device, dtype): the element
// type follows the first defined tensor, i32 only where the op allows it, undefined tensors are
// skipped, and an op with nothing to dispatch on, a dtype without a kernel or (on a machine with
// a GPU) a device without a kernel is a clear error naming the op.
#include <catch2/catch.hpp>

#include "kernels/dispatch.h"
#include "kernels/relu.h"
#include "kernels/shape.h"
#include "testing.h"

using namespace g2l;
using Catch::Contains;

TEST_CASE("dispatch: the element type follows the first defined tensor", "[kernels][dispatch]") {
    const Tensor f = Tensor::zeros({3});
    const Tensor d = Tensor::zeros({3}, DType::F64);
    const Tensor i = Tensor::zeros({3}, DType::I32);
    const Tensor none;
    size_t seen = 0;
    auto record = [&](auto tag) { seen = sizeof(tag); };
    kernels::dispatch("op", {&f}, record);
    REQUIRE(seen == sizeof(float));
    kernels::dispatch("op", {&none, &d, &f}, record);  // undefined skipped: d decides
    REQUIRE(seen == sizeof(double));
    kernels::dispatch<kernels::Types::FloatOrI32>("op", {nullptr, &i}, record);
    REQUIRE(seen == sizeof(int32_t));
    seen = 0;
    REQUIRE_THROWS_WITH(kernels::dispatch("my_op", {&i}, record),
                        Contains("my_op: expected an f32 or f64 tensor, got") && Contains("i32"));
    REQUIRE(seen == 0);
    REQUIRE_THROWS_WITH(kernels::dispatch("my_op", {&none, nullptr}, record),
                        Contains("my_op: no defined tensor to dispatch on"));
}

TEST_CASE("dispatch: tensor-level entry points compute what their CPU kernels compute",
          "[kernels][dispatch]") {
    Tensor x = Tensor::from_vector(std::vector<float>{-1.f, 2.f, 0.f, 3.5f}, {4});
    Tensor y = Tensor::empty({4});
    kernels::relu_fwd(x, y);
    REQUIRE(y.to_vector<float>() == std::vector<float>{0.f, 2.f, 0.f, 3.5f});
    // Layout copies take i32 too.
    Tensor idx = Tensor::from_vector(std::vector<int32_t>{7, 8, 9}, {3});
    Tensor out = Tensor::empty({3}, DType::I32);
    kernels::permute(idx, {0}, out);
    REQUIRE(out.to_vector<int32_t>() == std::vector<int32_t>{7, 8, 9});
    Tensor yi = Tensor::empty({3}, DType::I32);
    REQUIRE_THROWS_WITH(kernels::relu_fwd(idx, yi), Contains("relu: expected an f32 or f64"));
}

TEST_CASE("dispatch: a device without a kernel is an error, never a silent CPU fallback",
          "[kernels][dispatch][cuda]") {
    if (!cuda_available()) {
        testing::mark_skipped("needs a CUDA build and a GPU (this build or machine has none); "
                              "the CPU-only build refuses to create CUDA tensors at all "
                              "(test_tensor)");
        return;
    }
    const Tensor x = Tensor::zeros({4}).to(Device::cuda());
    Tensor y = Tensor::empty({4}, DType::F32, Device::cuda());
    Tensor yc = Tensor::empty({4});
    // Mixed devices are refused by name before any kernel runs.
    REQUIRE_THROWS_WITH(kernels::relu_fwd(x, yc), Contains("relu: tensors must be on one device"));
    // A CUDA relu kernel may exist: then it computes relu (checked on the host); if not, the
    // error names the op and the device. Either way something is asserted.
    const Tensor xs = Tensor::from_vector(std::vector<float>{-1.f, 2.f, -3.f, 3.5f}, {4})
                          .to(Device::cuda());
    bool ran = false;
    try {
        kernels::relu_fwd(xs, y);
        ran = true;
    } catch (const std::exception& e) {
        REQUIRE_THAT(e.what(), Contains("relu: no cuda:0 kernel for this op"));
    }
    if (ran)
        REQUIRE(y.to(Device::cpu()).to_vector<float>() == std::vector<float>{0.f, 2.f, 0.f, 3.5f});
}
