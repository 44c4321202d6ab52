// SPDX-License-Identifier: MIT
#include "nn/ops/relu.h"

#include "core/autograd.h"
#include "kernels/relu.h"

namespace g2l::nn {

Tensor relu(const Tensor& x) {
    G2L_CHECK(x.defined(), "relu: input is undefined");
    Tensor y = Tensor::empty(x.shape(), x.dtype(), x.device());
    kernels::relu_fwd(x, y);
    // Backward needs only the output (y > 0 <=> x > 0): capture a detached alias, never y itself.
    return autograd::record("relu", y, {x}, [yd = y.detach()](const Tensor& dy,
                                                              autograd::Grads& g) {
        Tensor dx = Tensor::empty(dy.shape(), dy.dtype(), dy.device());
        kernels::relu_bwd(yd, dy, dx);
        g.add(0, dx);
    });
}

}  // namespace g2l::nn
