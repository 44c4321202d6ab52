// SPDX-License-Identifier: MIT
// upsample_nearest2d / upsample_bilinear2d: the dispatch points (kernels/dispatch.h); CPU
// kernels in upsample_cpu.cpp. Sizes come from the [B, C, H, W] tensors.
#include "kernels/upsample.h"

#include "kernels/dispatch.h"

namespace g2l::kernels {

void upsample_nearest2d_fwd(const Tensor& x, Tensor& y, int64_t scale) {
    dispatch("upsample_nearest2d", {&x, &y}, [&](auto tag) {
        using T = decltype(tag);
        upsample_nearest2d_fwd_cpu<T>(x.data<T>(), y.data<T>(), x.size(0) * x.size(1), x.size(2),
                                      x.size(3), scale);
    });
}

void upsample_nearest2d_bwd(const Tensor& dy, Tensor& dx, int64_t scale) {
    dispatch("upsample_nearest2d backward", {&dy, &dx}, [&](auto tag) {
        using T = decltype(tag);
        upsample_nearest2d_bwd_cpu<T>(dy.data<T>(), dx.data<T>(), dx.size(0) * dx.size(1),
                                      dx.size(2), dx.size(3), scale);
    });
}

void upsample_bilinear2d_fwd(const Tensor& x, Tensor& y, bool align_corners) {
    dispatch("upsample_bilinear2d", {&x, &y}, [&](auto tag) {
        using T = decltype(tag);
        upsample_bilinear2d_fwd_cpu<T>(x.data<T>(), y.data<T>(), x.size(0) * x.size(1), x.size(2),
                                       x.size(3), y.size(2), y.size(3), align_corners);
    });
}

void upsample_bilinear2d_bwd(const Tensor& dy, Tensor& dx, bool align_corners) {
    dispatch("upsample_bilinear2d backward", {&dy, &dx}, [&](auto tag) {
        using T = decltype(tag);
        upsample_bilinear2d_bwd_cpu<T>(dy.data<T>(), dx.data<T>(), dx.size(0) * dx.size(1),
                                       dx.size(2), dx.size(3), dy.size(2), dy.size(3),
                                       align_corners);
    });
}

}  // namespace g2l::kernels
