// SPDX-License-Identifier: MIT
#include "nn/ops/pool2d.h"

#include <limits>

#include "core/autograd.h"
#include "core/dispatch.h"
#include "kernels/pool2d.h"

namespace g2l::nn {

namespace {

// Validates a pooling call and derives every size; messages name the op and the shapes.
kernels::Pool2dGeom pool2d_geom(const char* op, const Tensor& x, std::array<int64_t, 2> kernel,
                                std::array<int64_t, 2> stride, std::array<int64_t, 2> padding) {
    require_rank(op, "x", x, 4, "[B, C, H, W]");
    G2L_CHECK(x.numel() > 0, op, ": empty input x ", x.shape());
    G2L_CHECK(kernel[0] >= 1 && kernel[1] >= 1, op, ": kernel must be >= 1, got (", kernel[0],
              ", ", kernel[1], ")");
    G2L_CHECK(stride[0] >= 1 && stride[1] >= 1, op, ": stride must be >= 1, got (", stride[0],
              ", ", stride[1], ")");
    // PyTorch's rule; it also guarantees every window overlaps the image, which the kernels rely
    // on (a max window starts from an in-image element, an average never divides by 0).
    G2L_CHECK(padding[0] >= 0 && padding[1] >= 0 && 2 * padding[0] <= kernel[0] &&
                  2 * padding[1] <= kernel[1],
              op, ": padding must be in [0, kernel / 2], got padding (", padding[0], ", ",
              padding[1], ") for kernel (", kernel[0], ", ", kernel[1], ")");
    kernels::Pool2dGeom g;
    g.B = x.size(0), g.C = x.size(1), g.H = x.size(2), g.W = x.size(3);
    g.kh = kernel[0], g.kw = kernel[1], g.sh = stride[0], g.sw = stride[1];
    g.ph = padding[0], g.pw = padding[1];
    const int64_t hp = g.H + 2 * g.ph, wp = g.W + 2 * g.pw;
    G2L_CHECK(g.kh <= hp && g.kw <= wp, op, ": kernel ", g.kh, "x", g.kw,
              " is larger than the padded input ", hp, "x", wp, " (x ", x.shape(), ", padding ",
              g.ph, "x", g.pw, ")");
    // argmax stores flat in-plane offsets as i32.
    G2L_CHECK(int64_t(g.H) * g.W <= std::numeric_limits<int32_t>::max(), op, ": plane ", g.H, "x",
              g.W, " too large for i32 indices");
    g.Ho = (hp - g.kh) / g.sh + 1;
    g.Wo = (wp - g.kw) / g.sw + 1;
    return g;
}

Tensor avg_pool_impl(const char* op, const Tensor& x, const kernels::Pool2dGeom& g,
                     bool count_include_pad) {
    Tensor y = Tensor::empty({g.B, g.C, g.Ho, g.Wo}, x.dtype(), x.device());
    kernels::avg_pool2d_fwd(x, y, g, count_include_pad);
    return autograd::record(op, y, {x}, [g, count_include_pad](const Tensor& dy,
                                                               autograd::Grads& gr) {
        Tensor dx = Tensor::empty({g.B, g.C, g.H, g.W}, dy.dtype(), dy.device());
        kernels::avg_pool2d_bwd(dy, dx, g, count_include_pad);
        gr.add(0, dx);
    });
}

}  // namespace

Tensor max_pool2d(const Tensor& x, std::array<int64_t, 2> kernel, std::array<int64_t, 2> stride,
                  std::array<int64_t, 2> padding) {
    const kernels::Pool2dGeom g = pool2d_geom("max_pool2d", x, kernel, stride, padding);
    Tensor y = Tensor::empty({g.B, g.C, g.Ho, g.Wo}, x.dtype(), x.device());
    // Backward routes each output's gradient to the input the forward chose, so the choice is
    // kept rather than recomputed.
    Tensor arg = Tensor::empty({g.B, g.C, g.Ho, g.Wo}, DType::I32, x.device());
    kernels::max_pool2d_fwd(x, y, arg, g);
    return autograd::record("max_pool2d", y, {x}, [arg, g](const Tensor& dy,
                                                           autograd::Grads& gr) {
        Tensor dx = Tensor::empty({g.B, g.C, g.H, g.W}, dy.dtype(), dy.device());
        kernels::max_pool2d_bwd(dy, arg, dx, g);
        gr.add(0, dx);
    });
}

Tensor avg_pool2d(const Tensor& x, std::array<int64_t, 2> kernel, std::array<int64_t, 2> stride,
                  std::array<int64_t, 2> padding, bool count_include_pad) {
    const kernels::Pool2dGeom g = pool2d_geom("avg_pool2d", x, kernel, stride, padding);
    return avg_pool_impl("avg_pool2d", x, g, count_include_pad);
}

Tensor global_avg_pool2d(const Tensor& x) {
    require_rank("global_avg_pool2d", "x", x, 4, "[B, C, H, W]");
    // One window covering the whole plane: kernel H x W, stride 1, no padding -> [B, C, 1, 1].
    const kernels::Pool2dGeom g =
        pool2d_geom("global_avg_pool2d", x, {x.size(2), x.size(3)}, {1, 1}, {0, 0});
    return avg_pool_impl("global_avg_pool2d", x, g, true);
}

}  // namespace g2l::nn
