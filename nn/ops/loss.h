// SPDX-License-Identifier: MIT
// Losses (all reduce to a 0-d tensor by the mean, like PyTorch's default reduction) and argmax.
#pragma once

#include <cstdint>

#include "core/tensor.h"

namespace g2l::nn {

/// Negative log-likelihood. logp: [M, K] with target i32 [M], or logp: [B, K, N] with target
/// i32 [B, N] (class dimension 1, as PyTorch). Returns sum(-w[t] * logp[.., t, ..]) / sum(w[t])
/// (w = 1 without `weight`), a 0-d tensor. weight: optional f32/f64 [K] per-class weights, same
/// dtype as logp, constant (it receives no gradient). Throws naming the position and value of a
/// target outside [0, K), and naming the shapes when they do not fit; throws for no elements or
/// a zero total weight.
Tensor nll_loss(const Tensor& logp, const Tensor& target, const Tensor& weight = Tensor());

/// nll_loss(log_softmax(logits, 1), target, weight); same layouts as nll_loss.
Tensor cross_entropy(const Tensor& logits, const Tensor& target, const Tensor& weight = Tensor());

/// mean((a - b)^2) -> 0-d. a and b must have exactly the same shape (no broadcasting) and
/// dtype; both receive gradients.
Tensor mse_loss(const Tensor& a, const Tensor& b);

/// Huber loss as PyTorch's smooth_l1_loss, mean over elements -> 0-d. With d = a - b:
/// 0.5 d^2 / beta where |d| < beta, else |d| - 0.5 beta; beta == 0 is the L1 loss.
/// Shapes must match exactly; beta must be finite and >= 0.
Tensor smooth_l1_loss(const Tensor& a, const Tensor& b, double beta = 1.0);

/// Index of the maximum along `dim` (lowest index on ties) as an i32 tensor with `dim` removed.
/// Not differentiable (for accuracy metrics).
Tensor argmax(const Tensor& x, int64_t dim);

}  // namespace g2l::nn
