// SPDX-License-Identifier: MIT
// Differentiable reductions. Inputs: f32/f64 CPU tensors; `dim` may be negative (counts from the
// end) and must lie in [-rank, rank), else g2l::Error names the op, the dim and the shape.
// Sums are accumulated in double in a fixed order: results are identical for any thread count.
#pragma once

#include <cstdint>

#include "core/tensor.h"

namespace g2l::nn {

/// Sum of all elements -> 0-d tensor (0 for an empty tensor).
Tensor sum(const Tensor& x);
/// Sum over `dim`; the dimension is removed unless keepdim (then it has size 1).
Tensor sum(const Tensor& x, int64_t dim, bool keepdim = false);
/// Mean of all elements -> 0-d tensor. Throws for an empty tensor.
Tensor mean(const Tensor& x);
/// Mean over `dim` (removed unless keepdim). Throws if that dimension has size 0.
Tensor mean(const Tensor& x, int64_t dim, bool keepdim = false);

/// Result of max over a dimension.
struct MaxResult {
    Tensor values;   ///< the maxima, x's dtype
    Tensor indices;  ///< i32 positions along dim (lowest index on ties), no gradient
};

/// Maximum over `dim` (removed unless keepdim). The gradient flows only to the argmax (the lowest
/// index on ties). A NaN counts as the maximum. Throws if that dimension has size 0.
MaxResult max(const Tensor& x, int64_t dim, bool keepdim = false);

/// L2 norm over `dim`: sqrt(sum x^2 + eps). eps >= 0 (finite) keeps the value and gradient
/// x / norm finite at x = 0 when eps > 0. Removes dim unless keepdim.
Tensor norm(const Tensor& x, int64_t dim, bool keepdim = false, double eps = 1e-12);

/// x / norm(x, dim, keepdim=true, eps): unit vectors along `dim` (differentiable).
Tensor normalize(const Tensor& x, int64_t dim, double eps = 1e-12);

}  // namespace g2l::nn
