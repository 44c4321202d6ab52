// SPDX-License-Identifier: MIT
// Shape ops. Everything except unsqueeze / squeeze (reshape views) copies into a new contiguous
// tensor. They accept f32, f64 and i32 CPU tensors; gradients flow for f32/f64. A `dim` may be
// negative (counts from the end); out-of-range dims throw naming the dim and the shape.
#pragma once

#include <cstdint>
#include <vector>

#include "core/tensor.h"

namespace g2l::nn {

/// Joins tensors along `dim`. All must share dtype and rank (>= 1) and agree on every other
/// dimension (throws naming the index and both shapes). Gradient: the matching slice of dy.
Tensor concat(const std::vector<Tensor>& xs, int64_t dim);

/// Stacks equal-shaped tensors along a new dimension `dim` in [-(rank+1), rank]:
/// n tensors [A, B] stacked at dim 1 -> [A, n, B].
Tensor stack(const std::vector<Tensor>& xs, int64_t dim);

/// x[..., start:end, ...] along `dim` (step 1, copied). Negative start/end count from the end
/// and both are clamped to [0, size] like Python slicing; end <= start gives an empty dim.
Tensor slice(const Tensor& x, int64_t dim, int64_t start, int64_t end);

/// Tiles x n times along `dim` (n >= 0): [A, B] repeated 3 times at dim 1 -> [A, 3B] with
/// y[a, r*B + b] = x[a, b]. Gradient: the sum over the n tiles.
Tensor repeat(const Tensor& x, int64_t dim, int64_t n);

/// Swaps dimensions d0 and d1 (copy).
Tensor transpose(const Tensor& x, int64_t d0, int64_t d1);

/// Reorders dimensions: y's dimension k is x's dimension dims[k]. dims must be a permutation of
/// 0..rank-1 (negative entries allowed); throws naming dims otherwise.
Tensor permute(const Tensor& x, const std::vector<int64_t>& dims);

/// Gathers entries along `dim`: y[.., l, ..] = x[.., idx[l], ..]. idx: i32 [L] with values in
/// [0, size(dim)) (throws naming the position and value). Repeated indices are allowed; the
/// gradient scatter-adds them in a deterministic order.
Tensor index_select(const Tensor& x, int64_t dim, const Tensor& idx);

/// Inserts a size-1 dimension at `dim` in [-(rank+1), rank] (a reshape view).
Tensor unsqueeze(const Tensor& x, int64_t dim);

/// Removes dimension `dim`, which must have size 1 (throws naming the shape otherwise).
Tensor squeeze(const Tensor& x, int64_t dim);

}  // namespace g2l::nn
