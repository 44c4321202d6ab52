// SPDX-License-Identifier: MIT
// relu: the dispatch point (kernels/dispatch.h); CPU kernels in relu_cpu.cpp.
#include "kernels/relu.h"

#include "kernels/dispatch.h"

namespace g2l::kernels {

void relu_fwd(const Tensor& x, Tensor& y) {
    dispatch("relu", {&x, &y}, [&](auto tag) {
        using T = decltype(tag);
        relu_fwd_cpu<T>(x.data<T>(), y.data<T>(), x.numel());
    });
}

void relu_bwd(const Tensor& y, const Tensor& dy, Tensor& dx) {
    dispatch("relu backward", {&dy, &y, &dx}, [&](auto tag) {
        using T = decltype(tag);
        relu_bwd_cpu<T>(y.data<T>(), dy.data<T>(), dx.data<T>(), dy.numel());
    });
}

}  // namespace g2l::kernels
