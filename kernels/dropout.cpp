// SPDX-License-Identifier: MIT
#include "kernels/dropout.h"

#include "kernels/dispatch.h"

namespace g2l::kernels {

void dropout_mask(Tensor& mask, double p, Rng& rng) {
    // Inverted dropout (PyTorch's): survivors are scaled by 1/(1-p) at training time, so eval mode
    // is the identity and needs no rescaling.
    const double keep_scale = 1.0 / (1.0 - p);
    dispatch("dropout mask", {&mask}, [&](auto tag) {
        using T = decltype(tag);
        T* m = mask.data<T>();
        // Serial on purpose: one draw per element in index order keeps the Rng stream, and so a
        // training run, reproducible whatever the thread count.
        const int64_t n = mask.numel();
        for (int64_t i = 0; i < n; ++i) m[i] = rng.uniform() < p ? T(0) : T(keep_scale);
    });
}

}  // namespace g2l::kernels
