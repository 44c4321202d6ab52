// SPDX-License-Identifier: MIT
// softmax / log_softmax: the dispatch points (kernels/dispatch.h); CPU kernels in softmax_cpu.cpp.
#include "kernels/softmax.h"

#include "kernels/dispatch.h"

namespace g2l::kernels {

void softmax_fwd(const Tensor& x, Tensor& y, int64_t outer, int64_t D, int64_t inner, bool log) {
    dispatch(log ? "log_softmax" : "softmax", {&x, &y}, [&](auto tag) {
        using T = decltype(tag);
        softmax_fwd_cpu<T>(x.data<T>(), y.data<T>(), outer, D, inner, log);
    });
}

void softmax_bwd(const Tensor& y, const Tensor& dy, Tensor& dx, int64_t outer, int64_t D,
                 int64_t inner, bool log) {
    dispatch(log ? "log_softmax backward" : "softmax backward", {&dy, &y, &dx}, [&](auto tag) {
        using T = decltype(tag);
        softmax_bwd_cpu<T>(y.data<T>(), dy.data<T>(), dx.data<T>(), outer, D, inner, log);
    });
}

}  // namespace g2l::kernels
