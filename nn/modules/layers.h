// SPDX-License-Identifier: MIT
// Basic layers. Parameter names follow PyTorch ("weight", "bias", "running_mean", ...), so
// state dicts read naturally and map onto imported weights.
#pragma once

#include <array>

#include "nn/module.h"

namespace g2l::nn {

/// Fully connected: x [M, in] -> [M, out].
class Linear : public Module {
public:
    Linear(int64_t in, int64_t out, Rng& rng, bool bias = true, DType dtype = DType::F32);
    Tensor forward(const Tensor& x) const;
    Tensor weight, bias;  ///< [out, in], [out] (bias undefined if disabled)
};

/// 1x1 convolution over points (one layer of a PointNet shared MLP): x [B, in, N] -> [B, out, N].
class Conv1x1 : public Module {
public:
    Conv1x1(int64_t in, int64_t out, Rng& rng, bool bias = true, DType dtype = DType::F32);
    Tensor forward(const Tensor& x) const;
    Tensor weight, bias;  ///< [out, in], [out]
};

/// 2D convolution (NCHW): x [B, in, H, W] -> [B, out, Ho, Wo] (nn/ops/conv2d.h).
class Conv2d : public Module {
public:
    Conv2d(int64_t in, int64_t out, std::array<int64_t, 2> kernel, Rng& rng,
           std::array<int64_t, 2> stride = {1, 1}, std::array<int64_t, 2> padding = {0, 0},
           std::array<int64_t, 2> dilation = {1, 1}, int64_t groups = 1, bool bias = true,
           DType dtype = DType::F32);
    Tensor forward(const Tensor& x) const;
    Tensor weight, bias;  ///< [out, in / groups, kh, kw], [out]
    std::array<int64_t, 2> stride, padding, dilation;
    int64_t groups;
};

/// Max over the points of [B, C, N] features -> [B, C] (the PointNet global feature).
class MaxPoolPoints : public Module {
public:
    Tensor forward(const Tensor& x) const;
};

/// BatchNorm over channel dim 1 for [B, C], [B, C, N] (BatchNorm1d) and [B, C, H, W]
/// (BatchNorm2d). PyTorch defaults: eps 1e-5, momentum 0.1, affine, running stats.
class BatchNorm : public Module {
public:
    explicit BatchNorm(int64_t channels, double eps = 1e-5, double momentum = 0.1,
                       DType dtype = DType::F32);
    /// Training mode updates running_mean / running_var in place.
    Tensor forward(const Tensor& x);
    Tensor weight, bias, running_mean, running_var, num_batches_tracked;
    double eps, momentum;
};

/// Inverted dropout with its own random stream, stored as the buffer "rng_state" so that a
/// checkpoint resumes the exact same masks.
class Dropout : public Module {
public:
    Dropout(double p, uint64_t seed);
    Tensor forward(const Tensor& x);
    double p;
    Tensor rng_state;  ///< i32 [8]: the 4 x u64 xoshiro state
};

}  // namespace g2l::nn
