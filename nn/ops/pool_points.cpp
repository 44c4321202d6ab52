// SPDX-License-Identifier: MIT
#include "nn/ops/pool_points.h"

#include "core/autograd.h"
#include "core/dispatch.h"
#include "kernels/pool_points.h"

namespace g2l::nn {

Tensor max_pool_points(const Tensor& x, Tensor* argmax) {
    require_rank("max_pool_points", "x", x, 3, "[B, C, N]");
    const int64_t B = x.size(0), C = x.size(1), N = x.size(2);
    G2L_CHECK(N > 0, "max_pool_points: empty point set (N == 0) for x ", x.desc());
    // argmax is stored as i32.
    G2L_CHECK(N < (int64_t(1) << 31), "max_pool_points: N = ", N, " does not fit i32 indices");
    Tensor y = Tensor::empty({B, C}, x.dtype(), x.device());
    Tensor arg = Tensor::empty({B, C}, DType::I32, x.device());
    kernels::max_pool_points_fwd(x, y, arg);
    if (argmax) *argmax = arg;
    return autograd::record("max_pool_points", y, {x}, [arg, N](const Tensor& dy,
                                                                autograd::Grads& g) {
        const int64_t B = dy.size(0), C = dy.size(1);
        Tensor dx = Tensor::empty({B, C, N}, dy.dtype(), dy.device());
        kernels::max_pool_points_bwd(dy, arg, dx);
        g.add(0, dx);
    });
}

}  // namespace g2l::nn
