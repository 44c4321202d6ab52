// SPDX-License-Identifier: MIT
// Symmetric aggregation over a point set (the PointNet global feature).
#pragma once

#include "core/tensor.h"

namespace g2l::nn {

/// y[b, c] = max_n x[b, c, n]. x: [B, C, N] with N > 0 -> y: [B, C]. Only the winning point
/// receives gradient; ties go to the lowest n. If `argmax` is given it receives the i32 [B, C]
/// indices of the winners.
Tensor max_pool_points(const Tensor& x, Tensor* argmax = nullptr);

}  // namespace g2l::nn
