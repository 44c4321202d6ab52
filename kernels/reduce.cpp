// SPDX-License-Identifier: MIT
// sum / mean / max / norm over one dimension: the dispatch points (kernels/dispatch.h); CPU
// kernels in reduce_cpu.cpp.
#include "kernels/reduce.h"

#include "kernels/dispatch.h"

namespace g2l::kernels {

void sum_dim(const Tensor& x, Tensor& y, int64_t outer, int64_t D, int64_t inner, double scale) {
    dispatch("sum", {&x, &y}, [&](auto tag) {
        using T = decltype(tag);
        sum_dim_cpu<T>(x.data<T>(), y.data<T>(), outer, D, inner, scale);
    });
}

void sum_to_shape(const Tensor& x, Tensor& y) {
    dispatch("sum_to", {&x, &y}, [&](auto tag) {
        using T = decltype(tag);
        sum_to_shape_cpu<T>(x.data<T>(), x.shape(), y.data<T>(), y.shape());
    });
}

void broadcast_dim(const Tensor& y, Tensor& x, int64_t outer, int64_t D, int64_t inner,
                   double scale) {
    // Named after its only use: broadcast_dim is the adjoint of sum / mean.
    dispatch("sum backward", {&y, &x}, [&](auto tag) {
        using T = decltype(tag);
        broadcast_dim_cpu<T>(y.data<T>(), x.data<T>(), outer, D, inner, scale);
    });
}

void max_dim_fwd(const Tensor& x, Tensor& y, Tensor& arg, int64_t outer, int64_t D,
                 int64_t inner) {
    dispatch("max", {&x, &y, &arg}, [&](auto tag) {
        using T = decltype(tag);
        max_dim_fwd_cpu<T>(x.data<T>(), y.data<T>(), arg.data<int32_t>(), outer, D, inner);
    });
}

void max_dim_bwd(const Tensor& dy, const Tensor& arg, Tensor& dx, int64_t outer, int64_t D,
                 int64_t inner) {
    dispatch("max backward", {&dy, &arg, &dx}, [&](auto tag) {
        using T = decltype(tag);
        max_dim_bwd_cpu<T>(dy.data<T>(), arg.data<int32_t>(), dx.data<T>(), outer, D, inner);
    });
}

void norm_dim_fwd(const Tensor& x, Tensor& y, int64_t outer, int64_t D, int64_t inner,
                  double eps) {
    dispatch("norm", {&x, &y}, [&](auto tag) {
        using T = decltype(tag);
        norm_dim_fwd_cpu<T>(x.data<T>(), y.data<T>(), outer, D, inner, eps);
    });
}

void norm_dim_bwd(const Tensor& x, const Tensor& y, const Tensor& dy, Tensor& dx, int64_t outer,
                  int64_t D, int64_t inner) {
    dispatch("norm backward", {&dy, &x, &y, &dx}, [&](auto tag) {
        using T = decltype(tag);
        norm_dim_bwd_cpu<T>(x.data<T>(), y.data<T>(), dy.data<T>(), dx.data<T>(), outer, D,
                            inner);
    });
}

}  // namespace g2l::kernels
