// SPDX-License-Identifier: MIT
#include "nn/ops/conv2d.h"

#include "core/autograd.h"
#include "core/dispatch.h"
#include "kernels/conv2d.h"

namespace g2l::nn {

namespace {

// Validates the arguments and derives every size; all messages name the op and the shapes.
kernels::Conv2dGeom conv2d_geom(const Tensor& x, const Tensor& w, const Tensor& b,
                                std::array<int64_t, 2> stride, std::array<int64_t, 2> padding,
                                std::array<int64_t, 2> dilation, int64_t groups) {
    require_rank("conv2d", "x", x, 4, "[B, Cin, H, W]");
    require_rank("conv2d", "w", w, 4, "[Cout, Cin/groups, kh, kw]");
    require_same("conv2d", {&x, &w, &b});
    G2L_CHECK(stride[0] >= 1 && stride[1] >= 1, "conv2d: stride must be >= 1, got (", stride[0],
              ", ", stride[1], ")");
    G2L_CHECK(dilation[0] >= 1 && dilation[1] >= 1, "conv2d: dilation must be >= 1, got (",
              dilation[0], ", ", dilation[1], ")");
    G2L_CHECK(padding[0] >= 0 && padding[1] >= 0, "conv2d: padding must be >= 0, got (",
              padding[0], ", ", padding[1], ")");
    G2L_CHECK(groups >= 1, "conv2d: groups must be >= 1, got ", groups);
    G2L_CHECK(x.numel() > 0, "conv2d: empty input x ", x.shape());
    G2L_CHECK(w.numel() > 0, "conv2d: empty weight w ", w.shape());
    kernels::Conv2dGeom g;
    g.B = x.size(0), g.Cin = x.size(1), g.H = x.size(2), g.W = x.size(3);
    g.Cout = w.size(0), g.kh = w.size(2), g.kw = w.size(3);
    g.sh = stride[0], g.sw = stride[1], g.ph = padding[0], g.pw = padding[1];
    g.dh = dilation[0], g.dw = dilation[1], g.groups = groups;
    G2L_CHECK(g.Cin % groups == 0 && g.Cout % groups == 0, "conv2d: groups = ", groups,
              " must divide Cin = ", g.Cin, " and Cout = ", g.Cout, " (x ", x.shape(), ", w ",
              w.shape(), ")");
    G2L_CHECK(w.size(1) == g.Cin / groups, "conv2d: channel mismatch: x ", x.shape(), " has Cin = ",
              g.Cin, " so w must be [Cout, ", g.Cin / groups, ", kh, kw] with groups = ", groups,
              ", got w ", w.shape());
    if (b.defined())
        G2L_CHECK(b.dim() == 1 && b.size(0) == g.Cout, "conv2d: bias must be [Cout] = [", g.Cout,
                  "] for w ", w.shape(), ", got ", b.shape());
    // Effective (dilated) kernel extent vs padded input.
    const int64_t ekh = g.dh * (g.kh - 1) + 1, ekw = g.dw * (g.kw - 1) + 1;
    const int64_t hp = g.H + 2 * g.ph, wp = g.W + 2 * g.pw;
    G2L_CHECK(ekh <= hp && ekw <= wp, "conv2d: kernel ", g.kh, "x", g.kw, " (dilation ", g.dh,
              "x", g.dw, ", extent ", ekh, "x", ekw, ") is larger than the padded input ", hp,
              "x", wp, " (x ", x.shape(), ", padding ", g.ph, "x", g.pw, ")");
    // Floor division, as PyTorch: trailing rows / columns that no full stride reaches are dropped.
    g.Ho = (hp - ekh) / g.sh + 1;
    g.Wo = (wp - ekw) / g.sw + 1;
    return g;
}

}  // namespace

Tensor conv2d(const Tensor& x, const Tensor& w, const Tensor& b, std::array<int64_t, 2> stride,
              std::array<int64_t, 2> padding, std::array<int64_t, 2> dilation, int64_t groups) {
    const kernels::Conv2dGeom g = conv2d_geom(x, w, b, stride, padding, dilation, groups);
    Tensor y = Tensor::empty({g.B, g.Cout, g.Ho, g.Wo}, x.dtype(), x.device());
    kernels::conv2d_fwd(x, w, b, y, g);
    // dw needs x and dx needs w: keep each only when the other input will want a gradient, so
    // inference-time frozen weights do not pin activations.
    const bool grad_on = autograd::grad_enabled();
    const Tensor xs = grad_on && w.requires_grad() ? x.detach() : Tensor();
    const Tensor ws = grad_on && x.requires_grad() ? w.detach() : Tensor();
    return autograd::record("conv2d", y, {x, w, b}, [xs, ws, g](const Tensor& dy,
                                                                autograd::Grads& gr) {
        const bool need_x = gr.needs(0), need_w = gr.needs(1), need_b = gr.needs(2);
        Tensor dx, dw, db;
        if (need_x) dx = Tensor::empty({g.B, g.Cin, g.H, g.W}, dy.dtype(), dy.device());
        if (need_w)
            dw = Tensor::empty({g.Cout, g.Cin / g.groups, g.kh, g.kw}, dy.dtype(), dy.device());
        if (need_b) db = Tensor::empty({g.Cout}, dy.dtype(), dy.device());
        kernels::conv2d_bwd(xs, ws, dy, &dx, &dw, &db, g);
        if (need_x) gr.add(0, dx);
        if (need_w) gr.add(1, dw);
        if (need_b) gr.add(2, db);
    });
}

}  // namespace g2l::nn
