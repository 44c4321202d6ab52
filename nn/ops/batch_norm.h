// SPDX-License-Identifier: MIT
// Batch normalisation (PyTorch semantics: biased variance to normalise, unbiased variance in the
// running estimate, running = (1 - momentum) * running + momentum * batch).
#pragma once

#include "core/tensor.h"

namespace g2l::nn {

/// Normalises x over every dim except 1 (channels). x: [B, C], [B, C, N] or [B, C, H, W].
/// gamma, beta: [C] or undefined (no affine). running_mean, running_var: [C] buffers (may be
/// undefined only when training). training: batch statistics, and the running buffers are
/// updated in place (no autograd); eval: running statistics. Throws when training with a single
/// value per channel (B * spatial == 1), naming the shape.
Tensor batch_norm(const Tensor& x, const Tensor& gamma, const Tensor& beta, Tensor running_mean,
                  Tensor running_var, bool training, double momentum = 0.1, double eps = 1e-5);

}  // namespace g2l::nn
