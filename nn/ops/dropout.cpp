// SPDX-License-Identifier: MIT
#include "nn/ops/dropout.h"

#include "core/dispatch.h"
#include "nn/ops/dim_utils.h"
#include "nn/ops/elementwise.h"

namespace g2l::nn {

Tensor dropout(const Tensor& x, double p, bool training, Rng& rng) {
    detail::check_float_input("dropout", "x", x);
    G2L_CHECK(p >= 0 && p < 1, "dropout: probability p must be in [0, 1), got ", p);
    if (!training || p == 0) return x;
    // The mask holds 0 or 1 / (1 - p); drawing it serially keeps the stream order fixed. The
    // product with x (a differentiable mul with a constant) gives the gradient dy * mask.
    Tensor mask = Tensor::empty(x.shape(), x.dtype(), x.device());
    const double keep_scale = 1.0 / (1.0 - p);
    dispatch_float(x.dtype(), "dropout", [&](auto tag) {
        using T = decltype(tag);
        T* m = mask.data<T>();
        for (int64_t i = 0; i < mask.numel(); ++i) m[i] = rng.uniform() < p ? T(0) : T(keep_scale);
    });
    return mul(x, mask);
}

}  // namespace g2l::nn
