// SPDX-License-Identifier: MIT
// Unary and binary element-wise ops: the dispatch points (kernels/dispatch.h); CPU kernels in
// elementwise_cpu.cpp.
#include "kernels/elementwise.h"

#include "kernels/dispatch.h"

namespace g2l::kernels {

void unary_fwd(UnaryOp op, const Tensor& x, Tensor& y, double p0, double p1) {
    dispatch("unary op", {&x, &y}, [&](auto tag) {
        using T = decltype(tag);
        unary_fwd_cpu<T>(op, x.data<T>(), y.data<T>(), x.numel(), p0, p1);
    });
}

void unary_bwd(UnaryOp op, const Tensor& x, const Tensor& y, const Tensor& dy, Tensor& dx,
               double p0, double p1) {
    dispatch("unary op backward", {&dy, &x, &y, &dx}, [&](auto tag) {
        using T = decltype(tag);
        // The op saves only the tensor its derivative needs (unary_bwd_needs_x / _y); the other one
        // may be undefined.
        unary_bwd_cpu<T>(op, data_or_null<T>(x), data_or_null<T>(y), dy.data<T>(), dx.data<T>(),
                         dy.numel(), p0, p1);
    });
}

void binary(BinaryOp op, const Tensor& a, const Tensor& b, Tensor& y) {
    // Planned once here, outside the per-dtype kernel; a plan is a few small vectors.
    const BroadcastPlan plan = make_broadcast_plan(y.shape(), a.shape(), b.shape());
    dispatch("binary op", {&a, &b, &y}, [&](auto tag) {
        using T = decltype(tag);
        binary_cpu<T>(op, a.data<T>(), b.data<T>(), y.data<T>(), plan);
    });
}

}  // namespace g2l::kernels
