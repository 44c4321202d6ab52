// SPDX-License-Identifier: MIT
// Softmax and log-softmax over one dimension (numerically stable: the maximum along `dim` is
// subtracted first, so large logits do not overflow).
#pragma once

#include <cstdint>

#include "core/tensor.h"

namespace g2l::nn {

/// exp(x) / sum_dim exp(x), same shape as x. f32/f64 CPU; dim in [-rank, rank) else throws
/// naming the dim and the shape; throws if that dimension is empty.
Tensor softmax(const Tensor& x, int64_t dim);

/// x - log(sum_dim exp(x)), same shape as x; same rules as softmax.
Tensor log_softmax(const Tensor& x, int64_t dim);

}  // namespace g2l::nn
