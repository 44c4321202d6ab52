// SPDX-License-Identifier: MIT
#include "nn/ops/linear.h"

#include "core/autograd.h"
#include "core/dispatch.h"
#include "kernels/linear.h"

namespace g2l::nn {

namespace {

void check_weight(const char* op, const Tensor& x, int64_t cin, const Tensor& w, const Tensor& b) {
    require_rank(op, "w", w, 2, "[Cout, Cin]");
    require_same(op, {&x, &w, &b});
    G2L_CHECK(w.size(1) == cin, op, ": w ", w.desc(), " expects Cin = ", w.size(1),
              " input channels, x ", x.desc(), " has ", cin);
    if (b.defined())
        G2L_CHECK(b.dim() == 1 && b.size(0) == w.size(0), op, ": bias ", b.desc(),
                  " must be [Cout] = [", w.size(0), "]");
}

// A gradient buffer shaped like `like` on dy's device, or undefined when slot i needs none.
Tensor grad_for(const autograd::Grads& g, size_t i, const Shape& like, const Tensor& dy) {
    return g.needs(i) ? Tensor::empty(like, dy.dtype(), dy.device()) : Tensor();
}

void add_grads(autograd::Grads& g, std::initializer_list<Tensor> gs) {
    size_t i = 0;
    for (const Tensor& t : gs) {
        if (t.defined()) g.add(i, t);
        ++i;
    }
}

}  // namespace

Tensor linear(const Tensor& x, const Tensor& w, const Tensor& b) {
    require_rank("linear", "x", x, 2, "[M, Cin]");
    check_weight("linear", x, x.size(1), w, b);
    Tensor y = Tensor::empty({x.size(0), w.size(0)}, x.dtype(), x.device());
    kernels::linear_fwd(x, w, b, y);
    return autograd::record("linear", y, {x, w, b}, [x, w](const Tensor& dy, autograd::Grads& g) {
        Tensor dx = grad_for(g, 0, x.shape(), dy), dw = grad_for(g, 1, w.shape(), dy),
               db = grad_for(g, 2, {w.size(0)}, dy);
        kernels::linear_bwd(x, w, dy, &dx, &dw, &db);
        add_grads(g, {dx, dw, db});
    });
}

// The shared per-point MLP layer: every G2L-Net layer is a 1x1 convolution over the points
// (spec §4), one [Cout, Cin] x [Cin, N] GEMM per sample.
Tensor conv1x1(const Tensor& x, const Tensor& w, const Tensor& b) {
    require_rank("conv1x1", "x", x, 3, "[B, Cin, N]");
    check_weight("conv1x1", x, x.size(1), w, b);
    Tensor y = Tensor::empty({x.size(0), w.size(0), x.size(2)}, x.dtype(), x.device());
    kernels::conv1x1_fwd(x, w, b, y);
    return autograd::record("conv1x1", y, {x, w, b}, [x, w](const Tensor& dy,
                                                            autograd::Grads& g) {
        Tensor dx = grad_for(g, 0, x.shape(), dy), dw = grad_for(g, 1, w.shape(), dy),
               db = grad_for(g, 2, {w.size(0)}, dy);
        kernels::conv1x1_bwd(x, w, dy, &dx, &dw, &db);
        add_grads(g, {dx, dw, db});
    });
}

Tensor matmul(const Tensor& a, const Tensor& b) {
    require_rank("matmul", "a", a, 2, "[M, K]");
    require_rank("matmul", "b", b, 2, "[K, N]");
    require_same("matmul", {&a, &b});
    G2L_CHECK(a.size(1) == b.size(0), "matmul: inner sizes differ: a ", a.desc(), " b ",
              b.desc());
    Tensor y = Tensor::empty({a.size(0), b.size(1)}, a.dtype(), a.device());
    kernels::matmul_fwd(a, b, y);
    return autograd::record("matmul", y, {a, b}, [a, b](const Tensor& dy, autograd::Grads& g) {
        Tensor da = grad_for(g, 0, a.shape(), dy), db = grad_for(g, 1, b.shape(), dy);
        kernels::matmul_bwd(a, b, dy, &da, &db);
        add_grads(g, {da, db});
    });
}

}  // namespace g2l::nn
