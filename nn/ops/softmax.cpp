// SPDX-License-Identifier: MIT
#include "nn/ops/softmax.h"

#include "core/autograd.h"
#include "kernels/softmax.h"
#include "nn/ops/dim_utils.h"

namespace g2l::nn {

namespace {

// Both backward formulas need only the forward output (see kernels/softmax.h), so the closure
// captures y detached and never x.
Tensor softmax_impl(const char* op, const Tensor& x, int64_t dim, bool log) {
    detail::check_float_input(op, "x", x);
    const int64_t d = detail::wrap_dim(op, dim, x.shape());
    G2L_CHECK(x.shape()[size_t(d)] > 0, op, ": dim ", dim, " of ", x.desc(), " is empty");
    const detail::DimSplit p = detail::split_at(x.shape(), d);
    Tensor y = Tensor::empty(x.shape(), x.dtype(), x.device());
    kernels::softmax_fwd(x, y, p.outer, p.D, p.inner, log);
    return autograd::record(
        op, y, {x}, [p, log, yd = y.detach()](const Tensor& dy, autograd::Grads& g) {
            Tensor dx = Tensor::empty(dy.shape(), dy.dtype(), dy.device());
            kernels::softmax_bwd(yd, dy, dx, p.outer, p.D, p.inner, log);
            g.add(0, dx);
        });
}

}  // namespace

Tensor softmax(const Tensor& x, int64_t dim) { return softmax_impl("softmax", x, dim, false); }

Tensor log_softmax(const Tensor& x, int64_t dim) {
    return softmax_impl("log_softmax", x, dim, true);
}

}  // namespace g2l::nn
