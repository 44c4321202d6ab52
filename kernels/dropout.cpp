// SPDX-License-Identifier: MIT
#include "kernels/dropout.h"

#include "kernels/dispatch.h"

namespace g2l::kernels {

void dropout_mask(Tensor& mask, double p, Rng& rng) {
    const double keep_scale = 1.0 / (1.0 - p);
    dispatch("dropout mask", {&mask}, [&](auto tag) {
        using T = decltype(tag);
        T* m = mask.data<T>();
        const int64_t n = mask.numel();
        for (int64_t i = 0; i < n; ++i) m[i] = rng.uniform() < p ? T(0) : T(keep_scale);
    });
}

}  // namespace g2l::kernels
