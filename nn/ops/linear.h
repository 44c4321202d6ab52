// SPDX-License-Identifier: MIT
// Dense layers as GEMMs: linear (fully connected) and conv1x1 (the PointNet shared MLP).
#pragma once

#include "core/tensor.h"

namespace g2l::nn {

/// y = x w^T + b. x: [M, Cin], w: [Cout, Cin], b: [Cout] or undefined -> y: [M, Cout].
Tensor linear(const Tensor& x, const Tensor& w, const Tensor& b = Tensor());

/// Shared MLP over points (1x1 convolution): y[b] = w x[b] + bias.
/// x: [B, Cin, N], w: [Cout, Cin], b: [Cout] or undefined -> y: [B, Cout, N].
Tensor conv1x1(const Tensor& x, const Tensor& w, const Tensor& b = Tensor());

/// Plain matrix product a @ b for a: [M, K], b: [K, N] -> [M, N] (differentiable).
Tensor matmul(const Tensor& a, const Tensor& b);

}  // namespace g2l::nn
