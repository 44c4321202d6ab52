// SPDX-License-Identifier: MIT
#include "nn/ops/reduce.h"

#include <cmath>

#include "core/autograd.h"
#include "kernels/reduce.h"
#include "nn/ops/dim_utils.h"
#include "nn/ops/elementwise.h"

namespace g2l::nn {

namespace {

Shape reduced_shape(const Shape& s, int64_t d, bool keepdim) {
    Shape out = s;
    if (keepdim)
        out[size_t(d)] = 1;
    else
        out.erase(out.begin() + d);
    return out;
}

// Sum (scale 1) or mean (scale 1/D) over the middle of [outer, D, inner]; out_shape is the
// caller's result shape. Backward broadcasts dy * scale back over D.
Tensor sum_impl(const char* op, const Tensor& x, const detail::DimSplit& p, const Shape& out_shape,
                double scale) {
    Tensor y = Tensor::empty(out_shape, x.dtype(), x.device());
    kernels::sum_dim(x, y, p.outer, p.D, p.inner, scale);
    return autograd::record(op, y, {x},
                            [p, scale, xs = x.shape()](const Tensor& dy, autograd::Grads& g) {
                                Tensor dx = Tensor::empty(xs, dy.dtype(), dy.device());
                                kernels::broadcast_dim(dy, dx, p.outer, p.D, p.inner, scale);
                                g.add(0, dx);
                            });
}

}  // namespace

Tensor sum(const Tensor& x) {
    detail::check_float_input("sum", "x", x);
    // A full reduction is the [1, numel, 1] case of the same kernel, so sum() and sum(dim) share
    // one summation order.
    return sum_impl("sum", x, {1, x.numel(), 1}, {}, 1.0);
}

Tensor sum(const Tensor& x, int64_t dim, bool keepdim) {
    detail::check_float_input("sum", "x", x);
    const int64_t d = detail::wrap_dim("sum", dim, x.shape());
    return sum_impl("sum", x, detail::split_at(x.shape(), d), reduced_shape(x.shape(), d, keepdim),
                    1.0);
}

Tensor mean(const Tensor& x) {
    detail::check_float_input("mean", "x", x);
    G2L_CHECK(x.numel() > 0, "mean: tensor ", x.desc(), " is empty");
    return sum_impl("mean", x, {1, x.numel(), 1}, {}, 1.0 / double(x.numel()));
}

Tensor mean(const Tensor& x, int64_t dim, bool keepdim) {
    detail::check_float_input("mean", "x", x);
    const int64_t d = detail::wrap_dim("mean", dim, x.shape());
    G2L_CHECK(x.shape()[size_t(d)] > 0, "mean: dim ", dim, " of ", x.desc(), " is empty");
    const detail::DimSplit p = detail::split_at(x.shape(), d);
    return sum_impl("mean", x, p, reduced_shape(x.shape(), d, keepdim), 1.0 / double(p.D));
}

MaxResult max(const Tensor& x, int64_t dim, bool keepdim) {
    detail::check_float_input("max", "x", x);
    const int64_t d = detail::wrap_dim("max", dim, x.shape());
    G2L_CHECK(x.shape()[size_t(d)] > 0, "max: dim ", dim, " of ", x.desc(),
              " is empty (no maximum)");
    const detail::DimSplit p = detail::split_at(x.shape(), d);
    const Shape out_shape = reduced_shape(x.shape(), d, keepdim);
    Tensor y = Tensor::empty(out_shape, x.dtype(), x.device());
    // The winners are kept for backward (only they get gradient) and also returned to the caller.
    Tensor arg = Tensor::empty(out_shape, DType::I32, x.device());
    kernels::max_dim_fwd(x, y, arg, p.outer, p.D, p.inner);
    y = autograd::record("max", y, {x},
                         [p, arg, xs = x.shape()](const Tensor& dy, autograd::Grads& g) {
                             Tensor dx = Tensor::empty(xs, dy.dtype(), dy.device());
                             kernels::max_dim_bwd(dy, arg, dx, p.outer, p.D, p.inner);
                             g.add(0, dx);
                         });
    return {y, arg};
}

Tensor norm(const Tensor& x, int64_t dim, bool keepdim, double eps) {
    detail::check_float_input("norm", "x", x);
    G2L_CHECK(std::isfinite(eps) && eps >= 0, "norm: eps must be finite and >= 0, got ", eps);
    const int64_t d = detail::wrap_dim("norm", dim, x.shape());
    const detail::DimSplit p = detail::split_at(x.shape(), d);
    Tensor y = Tensor::empty(reduced_shape(x.shape(), d, keepdim), x.dtype(), x.device());
    kernels::norm_dim_fwd(x, y, p.outer, p.D, p.inner, eps);
    return autograd::record(
        "norm", y, {x},
        // Backward reads y (with its eps) rather than recomputing the norm: the same values as the
        // forward used.
        [p, xd = x.detach(), yd = y.detach()](const Tensor& dy, autograd::Grads& g) {
            Tensor dx = Tensor::empty(xd.shape(), dy.dtype(), dy.device());
            kernels::norm_dim_bwd(xd, yd, dy, dx, p.outer, p.D, p.inner);
            g.add(0, dx);
        });
}

Tensor normalize(const Tensor& x, int64_t dim, double eps) {
    // keepdim so the norm broadcasts back over `dim`; eps > 0 keeps a zero vector finite.
    return div(x, norm(x, dim, /*keepdim=*/true, eps));
}

}  // namespace g2l::nn
