// SPDX-License-Identifier: MIT
#include "nn/ops/dropout.h"

#include "kernels/dropout.h"
#include "nn/ops/dim_utils.h"
#include "nn/ops/elementwise.h"

namespace g2l::nn {

Tensor dropout(const Tensor& x, double p, bool training, Rng& rng) {
    detail::check_float_input("dropout", "x", x);
    G2L_CHECK(p >= 0 && p < 1, "dropout: probability p must be in [0, 1), got ", p);
    if (!training || p == 0) return x;
    // The mask holds 0 or 1 / (1 - p), drawn on the host in a fixed stream order, then moved to
    // x's device. The product with x (a differentiable mul with a constant) gives dy * mask.
    Tensor mask = Tensor::empty(x.shape(), x.dtype());  // host: the Rng stream lives here
    kernels::dropout_mask(mask, p, rng);
    return mul(x, mask.to(x.device()));
}

}  // namespace g2l::nn
