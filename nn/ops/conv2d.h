// SPDX-License-Identifier: MIT
// Differentiable 2D convolution (NCHW), the building block of the 2D detector.
#pragma once

#include <array>
#include <cstdint>

#include "core/tensor.h"

namespace g2l::nn {

/// PyTorch-style Conv2d (cross-correlation with zero padding):
///   y[b, co, oh, ow] = b[co] + sum_{c,i,j} w[co, c, i, j] *
///                      x[b, g*Cin_g + c, oh*sh - ph + i*dh, ow*sw - pw + j*dw],
/// g = co / (Cout / groups), Cin_g = Cin / groups.
///
/// x: [B, Cin, H, W]; w: [Cout, Cin / groups, kh, kw]; b: [Cout] or undefined (no bias);
/// stride {sh, sw} >= 1, padding {ph, pw} >= 0, dilation {dh, dw} >= 1, groups >= 1 dividing
/// Cin and Cout. Returns y: [B, Cout, Ho, Wo] with Ho = floor((H + 2ph - dh(kh-1) - 1)/sh) + 1
/// (Wo likewise). f32 or f64 (all tensors the same dtype), CPU. Differentiable in x, w and b;
/// each gradient is computed only when that input requires it. Results are bitwise identical
/// for any OpenMP thread count.
/// Throws g2l::Error (naming the shapes) on a wrong rank, a channel mismatch, a bias that is not
/// [Cout], a stride/dilation < 1, negative padding, groups not dividing the channels, an empty
/// input, a kernel larger than the padded input (Ho or Wo <= 0), or mixed dtypes.
Tensor conv2d(const Tensor& x, const Tensor& w, const Tensor& b = Tensor(),
              std::array<int64_t, 2> stride = {1, 1}, std::array<int64_t, 2> padding = {0, 0},
              std::array<int64_t, 2> dilation = {1, 1}, int64_t groups = 1);

}  // namespace g2l::nn
