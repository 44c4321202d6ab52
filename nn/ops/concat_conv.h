// SPDX-License-Identifier: MIT
// 1x1 convolution of a channel concatenation of per-point features and global vectors tiled over
// the points, without materialising the concatenation or the tiling (the G2L-Net heads).
#pragma once

#include <vector>

#include "core/tensor.h"

namespace g2l::nn {

/// y[b] = sum_i W_i x_i[b] + (sum_j W_j g_j[b] + bias) broadcast over the N points.
///
/// Mathematically equal to conv1x1(concat({x_0, .., x_P-1, repeat(g_0), .., repeat(g_G-1)}, 1),
/// w, b), where repeat(g) tiles a [B, Cj] vector to [B, Cj, N]. The weight's columns follow that
/// channel order: point features in order, then global features in order. The tiled tensor is
/// never built: the global part costs one [B, Cg] x [Cg, Cout] product instead of N times that.
///
/// point_feats: P >= 1 tensors [B, Ci, N] (same B and N); global_feats: G >= 0 tensors [B, Cj];
/// w: [Cout, sum Ci + sum Cj]; b: [Cout] or undefined -> y: [B, Cout, N].
/// All f32 or all f64, CPU. Backward computes only the gradients that are needed:
/// dx_i[b] = W_i^T dy[b], dg_j = s W_j with s[b] = sum_n dy[b, :, n], dW_i = sum_b dy[b] x_i[b]^T,
/// dW_j = s^T g_j, db = sum_b s[b]. Deterministic for any thread count.
/// Throws g2l::Error naming the argument index and shapes when ranks, B, N, channel totals,
/// dtypes or devices do not fit, or when point_feats is empty.
Tensor concat_conv1x1(const std::vector<Tensor>& point_feats,
                      const std::vector<Tensor>& global_feats, const Tensor& w,
                      const Tensor& b = Tensor());

}  // namespace g2l::nn
