// SPDX-License-Identifier: MIT
#include "nn/modules/layers.h"

#include "core/autograd.h"
#include "nn/ops/conv2d.h"
#include "nn/ops/linear.h"
#include "nn/ops/batch_norm.h"
#include "nn/ops/pool_points.h"

namespace g2l::nn {

Linear::Linear(int64_t in, int64_t out, Rng& rng, bool use_bias, DType dtype) {
    G2L_CHECK(in > 0 && out > 0, "Linear: sizes must be > 0, got in ", in, " out ", out);
    // [out, in] as PyTorch stores it, so converted weights load without transposing.
    weight = register_parameter("weight", uniform_init({out, in}, in, rng, dtype));
    if (use_bias) bias = register_parameter("bias", uniform_init({out}, in, rng, dtype));
}

Tensor Linear::forward(const Tensor& x) const { return linear(x, weight, bias); }

Conv1x1::Conv1x1(int64_t in, int64_t out, Rng& rng, bool use_bias, DType dtype) {
    G2L_CHECK(in > 0 && out > 0, "Conv1x1: sizes must be > 0, got in ", in, " out ", out);
    weight = register_parameter("weight", uniform_init({out, in}, in, rng, dtype));
    if (use_bias) bias = register_parameter("bias", uniform_init({out}, in, rng, dtype));
}

Tensor Conv1x1::forward(const Tensor& x) const { return conv1x1(x, weight, bias); }

Conv2d::Conv2d(int64_t in, int64_t out, std::array<int64_t, 2> kernel, Rng& rng,
               std::array<int64_t, 2> stride_, std::array<int64_t, 2> padding_,
               std::array<int64_t, 2> dilation_, int64_t groups_, bool use_bias, DType dtype)
    : stride(stride_), padding(padding_), dilation(dilation_), groups(groups_) {
    G2L_CHECK(in > 0 && out > 0 && kernel[0] > 0 && kernel[1] > 0 && groups > 0 &&
                  in % groups == 0 && out % groups == 0,
              "Conv2d: bad sizes in ", in, " out ", out, " kernel ", kernel[0], "x", kernel[1],
              " groups ", groups);
    // PyTorch's fan_in for a grouped convolution: the inputs one output actually sees.
    const int64_t fan_in = in / groups * kernel[0] * kernel[1];
    weight = register_parameter(
        "weight", uniform_init({out, in / groups, kernel[0], kernel[1]}, fan_in, rng, dtype));
    if (use_bias) bias = register_parameter("bias", uniform_init({out}, fan_in, rng, dtype));
}

Tensor Conv2d::forward(const Tensor& x) const {
    return conv2d(x, weight, bias, stride, padding, dilation, groups);
}

Tensor MaxPoolPoints::forward(const Tensor& x) const { return max_pool_points(x); }

BatchNorm::BatchNorm(int64_t channels, double eps_, double momentum_, DType dtype)
    : eps(eps_), momentum(momentum_) {
    G2L_CHECK(channels > 0, "BatchNorm: channels must be > 0, got ", channels);
    // host: modules are built on the CPU (as every layer's uniform_init), then moved
    // gamma 1, beta 0, running mean 0 and variance 1: PyTorch's BatchNorm initial state.
    weight = register_parameter("weight", Tensor::ones({channels}, dtype));  // host
    bias = register_parameter("bias", Tensor::zeros({channels}, dtype));  // host
    running_mean = register_buffer("running_mean", Tensor::zeros({channels}, dtype));  // host
    running_var = register_buffer("running_var", Tensor::ones({channels}, dtype));  // host
    // PyTorch's BatchNorm has this buffer too; keeping it makes the key sets of converted state
    // dicts match under strict loading.
    num_batches_tracked =
        register_buffer("num_batches_tracked", Tensor::zeros({1}, DType::I32));  // host
}

Tensor BatchNorm::forward(const Tensor& x) {
    if (is_training()) {
        autograd::NoGradGuard no_grad;
        num_batches_tracked.fill_(num_batches_tracked.item<int32_t>() + 1);
    }
    return batch_norm(x, weight, bias, running_mean, running_var, is_training(), momentum, eps);
}

}  // namespace g2l::nn
