// SPDX-License-Identifier: MIT
#include "nn/ops/upsample.h"

#include "core/autograd.h"
#include "core/dispatch.h"
#include "kernels/upsample.h"

namespace g2l::nn {

Tensor upsample_nearest2d(const Tensor& x, int64_t scale) {
    require_rank("upsample_nearest2d", "x", x, 4, "[B, C, H, W]");
    G2L_CHECK(x.numel() > 0, "upsample_nearest2d: empty input x ", x.shape());
    G2L_CHECK(scale >= 1, "upsample_nearest2d: scale must be >= 1, got ", scale, " for x ",
              x.shape());
    const int64_t B = x.size(0), C = x.size(1), H = x.size(2), W = x.size(3);
    Tensor y = Tensor::empty({B, C, H * scale, W * scale}, x.dtype(), x.device());
    kernels::upsample_nearest2d_fwd(x, y, scale);
    // Backward needs only sizes and the scale, so no tensor is kept alive by the closure.
    return autograd::record("upsample_nearest2d", y, {x}, [=](const Tensor& dy,
                                                              autograd::Grads& g) {
        Tensor dx = Tensor::empty({B, C, H, W}, dy.dtype(), dy.device());
        kernels::upsample_nearest2d_bwd(dy, dx, scale);
        g.add(0, dx);
    });
}

Tensor upsample_bilinear2d(const Tensor& x, int64_t out_h, int64_t out_w, bool align_corners) {
    require_rank("upsample_bilinear2d", "x", x, 4, "[B, C, H, W]");
    G2L_CHECK(x.numel() > 0, "upsample_bilinear2d: empty input x ", x.shape());
    G2L_CHECK(out_h >= 1 && out_w >= 1, "upsample_bilinear2d: output size must be >= 1, got ",
              out_h, "x", out_w, " for x ", x.shape());
    const int64_t B = x.size(0), C = x.size(1), H = x.size(2), W = x.size(3);
    Tensor y = Tensor::empty({B, C, out_h, out_w}, x.dtype(), x.device());
    kernels::upsample_bilinear2d_fwd(x, y, align_corners);
    return autograd::record("upsample_bilinear2d", y, {x}, [=](const Tensor& dy,
                                                               autograd::Grads& g) {
        Tensor dx = Tensor::empty({B, C, H, W}, dy.dtype(), dy.device());
        kernels::upsample_bilinear2d_bwd(dy, dx, align_corners);
        g.add(0, dx);
    });
}

}  // namespace g2l::nn
