// SPDX-License-Identifier: MIT
// Inverted dropout.
#pragma once

#include "core/rng.h"
#include "core/tensor.h"

namespace g2l::nn {

/// Training: each element is zeroed with probability p, survivors are scaled by 1 / (1 - p), so
/// the expectation is unchanged. Evaluation (training == false) or p == 0: returns x unchanged
/// (the same handle). The keep/drop mask is drawn from `rng` sequentially in flat element order
/// (one uniform() per element, dropped where u < p), so a seed fixes it whatever the thread
/// count. The gradient is dy * mask. x: f32/f64 CPU, any shape. Throws unless 0 <= p < 1.
Tensor dropout(const Tensor& x, double p, bool training, Rng& rng);

}  // namespace g2l::nn
