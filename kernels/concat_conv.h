// SPDX-License-Identifier: MIT
// concat_conv1x1 (nn/ops/concat_conv.h): a 1x1 convolution of the channel concatenation of
// per-point features xs[i] [B, Ci, N] and per-sample global features gs[j] [B, Cj] (broadcast
// over N), without materialising the concatenation. w: [Cout, sum Ci + sum Cj] (point columns
// first, then global ones), b: [Cout] or undefined, y: [B, Cout, N]. The caller checks shapes.
#pragma once

#include <vector>

#include "core/tensor.h"

namespace g2l::kernels {

void concat_conv1x1_fwd(const std::vector<Tensor>& xs, const std::vector<Tensor>& gs,
                        const Tensor& w, const Tensor& b, Tensor& y);
/// Writes dxs[i] / dgs[j] / dw / db for each defined tensor the caller allocated (dxs and dgs
/// have one entry per input; leave an entry undefined to skip it; dw / db may be null).
void concat_conv1x1_bwd(const std::vector<Tensor>& xs, const std::vector<Tensor>& gs,
                        const Tensor& w, const Tensor& dy, std::vector<Tensor>& dxs,
                        std::vector<Tensor>& dgs, Tensor* dw, Tensor* db);

}  // namespace g2l::kernels
