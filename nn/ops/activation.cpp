// SPDX-License-Identifier: MIT
#include "nn/ops/activation.h"

#include "core/autograd.h"
#include "core/dispatch.h"
#include "kernels/relu.h"

namespace g2l::nn {

Tensor relu(const Tensor& x) {
    G2L_CHECK(x.defined(), "relu: input is undefined");
    require_cpu("relu", {&x});
    Tensor y = Tensor::empty(x.shape(), x.dtype(), x.device());
    dispatch_float(x.dtype(), "relu", [&](auto tag) {
        using T = decltype(tag);
        kernels::relu_fwd_cpu<T>(x.data<T>(), y.data<T>(), x.numel());
    });
    // Backward needs only the output (y > 0 <=> x > 0): capture a detached alias, never y itself.
    return autograd::record("relu", y, {x}, [yd = y.detach()](const Tensor& dy,
                                                              autograd::Grads& g) {
        Tensor dx = Tensor::empty(dy.shape(), dy.dtype(), dy.device());
        dispatch_float(dy.dtype(), "relu backward", [&](auto tag) {
            using T = decltype(tag);
            kernels::relu_bwd_cpu<T>(yd.data<T>(), dy.data<T>(), dx.data<T>(), dy.numel());
        });
        g.add(0, dx);
    });
}

}  // namespace g2l::nn
