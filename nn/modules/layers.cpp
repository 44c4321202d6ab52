// SPDX-License-Identifier: MIT
#include "nn/modules/layers.h"

#include "core/autograd.h"
#include "nn/ops/linear.h"
#include "nn/ops/norm.h"

namespace g2l::nn {

Linear::Linear(int64_t in, int64_t out, Rng& rng, bool use_bias, DType dtype) {
    G2L_CHECK(in > 0 && out > 0, "Linear: sizes must be > 0, got in ", in, " out ", out);
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

BatchNorm::BatchNorm(int64_t channels, double eps_, double momentum_, DType dtype)
    : eps(eps_), momentum(momentum_) {
    G2L_CHECK(channels > 0, "BatchNorm: channels must be > 0, got ", channels);
    weight = register_parameter("weight", Tensor::ones({channels}, dtype));
    bias = register_parameter("bias", Tensor::zeros({channels}, dtype));
    running_mean = register_buffer("running_mean", Tensor::zeros({channels}, dtype));
    running_var = register_buffer("running_var", Tensor::ones({channels}, dtype));
    num_batches_tracked = register_buffer("num_batches_tracked", Tensor::zeros({1}, DType::I32));
}

Tensor BatchNorm::forward(const Tensor& x) {
    if (is_training()) {
        autograd::NoGradGuard no_grad;
        num_batches_tracked.fill_(num_batches_tracked.item<int32_t>() + 1);
    }
    return batch_norm(x, weight, bias, running_mean, running_var, is_training(), momentum, eps);
}

}  // namespace g2l::nn
