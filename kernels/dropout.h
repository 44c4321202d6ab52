// SPDX-License-Identifier: MIT
// The dropout mask (nn/ops/dropout.h): drawn serially from one host Rng so the stream order, and
// with it every training run, is fixed. The mask lives on the CPU; the op moves it to the input's
// device before the product.
#pragma once

#include "core/rng.h"
#include "core/tensor.h"

namespace g2l::kernels {

/// mask (f32 or f64, on the CPU) [i] = 0 with probability p, else 1 / (1 - p), in index order.
void dropout_mask(Tensor& mask, double p, Rng& rng);

}  // namespace g2l::kernels
