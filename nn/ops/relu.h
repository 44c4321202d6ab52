// SPDX-License-Identifier: MIT
// relu (kernels/relu.h).
#pragma once

#include "core/tensor.h"

namespace g2l::nn {

/// y = max(x, 0), any shape, f32/f64, CPU. Gradient at 0 is 0.
Tensor relu(const Tensor& x);

}  // namespace g2l::nn
