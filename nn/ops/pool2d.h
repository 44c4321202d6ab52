// SPDX-License-Identifier: MIT
// Differentiable 2D pooling over NCHW tensors (PyTorch MaxPool2d / AvgPool2d, floor mode).
#pragma once

#include <array>
#include <cstdint>

#include "core/tensor.h"

namespace g2l::nn {

/// Max over kh x kw windows. x: [B, C, H, W] f32/f64, CPU -> y: [B, C, Ho, Wo],
/// Ho = floor((H + 2ph - kh) / sh) + 1 (Wo likewise). Padding is implicit -inf: a padded position
/// never wins. The winners' indices are kept for backward, which routes dy to the winner only;
/// ties go to the first element in row-major window order; NaN propagates.
/// kernel {kh, kw} >= 1, stride {sh, sw} >= 1, padding {ph, pw} with 0 <= p <= k / 2.
/// Throws g2l::Error naming the shapes on a wrong rank, an empty input, a bad kernel, stride or
/// padding, or a window larger than the padded input.
Tensor max_pool2d(const Tensor& x, std::array<int64_t, 2> kernel, std::array<int64_t, 2> stride,
                  std::array<int64_t, 2> padding = {0, 0});

/// Mean over kh x kw windows, same shapes and argument rules as max_pool2d. Padding counts as 0.
/// The divisor is kh*kw when count_include_pad, else the number of in-image elements of the
/// window. Differentiable in x.
Tensor avg_pool2d(const Tensor& x, std::array<int64_t, 2> kernel, std::array<int64_t, 2> stride,
                  std::array<int64_t, 2> padding = {0, 0}, bool count_include_pad = true);

/// Mean over each whole H x W plane. x: [B, C, H, W] f32/f64, CPU -> [B, C, 1, 1].
/// Differentiable. Throws g2l::Error on a wrong rank or an empty input.
Tensor global_avg_pool2d(const Tensor& x);

}  // namespace g2l::nn
