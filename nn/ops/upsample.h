// SPDX-License-Identifier: MIT
// Differentiable 2D upsampling of NCHW tensors (the detector's feature-pyramid path).
#pragma once

#include <cstdint>

#include "core/tensor.h"

namespace g2l::nn {

/// Nearest-neighbour upsampling by an integer factor: y[b, c, oh, ow] = x[b, c, oh/s, ow/s].
/// x: [B, C, H, W] f32/f64, CPU -> [B, C, H*s, W*s]. Backward sums dy over each s x s block.
/// Throws g2l::Error on a wrong rank, an empty input or scale < 1.
Tensor upsample_nearest2d(const Tensor& x, int64_t scale);

/// Bilinear resize to [B, C, out_h, out_w] with PyTorch's F.interpolate(mode="bilinear")
/// convention: source coordinate (o + 0.5) * in / out - 0.5 clamped at 0 (align_corners false),
/// or o * (in - 1) / (out - 1) (align_corners true). x: [B, C, H, W] f32/f64, CPU.
/// Differentiable. Throws g2l::Error on a wrong rank, an empty input or out_h/out_w < 1.
Tensor upsample_bilinear2d(const Tensor& x, int64_t out_h, int64_t out_w,
                           bool align_corners = false);

}  // namespace g2l::nn
