// SPDX-License-Identifier: MIT
#include "nn/ops/batch_norm.h"

#include <algorithm>
#include <initializer_list>

#include "core/autograd.h"
#include "core/dispatch.h"
#include "kernels/batch_norm.h"
#include "nn/data_parallel.h"

namespace g2l::nn {

Tensor batch_norm(const Tensor& x, const Tensor& gamma, const Tensor& beta, Tensor running_mean,
                  Tensor running_var, bool training, double momentum, double eps) {
    G2L_CHECK(x.defined() && x.dim() >= 2 && x.dim() <= 4,
              "batch_norm: expected x as [B, C], [B, C, N] or [B, C, H, W], got ", x.desc());
    require_same("batch_norm", {&x, &gamma, &beta, &running_mean, &running_var});
    const int64_t B = x.size(0), C = x.size(1), S = x.numel() / std::max<int64_t>(1, B * C);
    for (const Tensor* p : std::initializer_list<const Tensor*>{&gamma, &beta, &running_mean,
                                                                &running_var}) {
        if (p->defined())
            G2L_CHECK(p->dim() == 1 && p->size(0) == C, "batch_norm: parameter ", p->desc(),
                      " must be [C] = [", C, "] for x ", x.desc());
    }
    G2L_CHECK(running_mean.defined() == running_var.defined(),
              "batch_norm: running_mean and running_var must both be given or both omitted");
    G2L_CHECK(training || running_mean.defined(),
              "batch_norm: eval mode needs running statistics");
    // Data-parallel training (nn/data_parallel.h): the statistics of the global batch, and the
    // matching backward terms, summed over the processes. The reduce is captured now, so the
    // backward pass sums with the processes of the forward pass.
    const DataParallel* dp = data_parallel();
    const kernels::BnReduce reduce = training && dp ? dp->sum : kernels::BnReduce();
    // One value per channel has zero variance and no unbiased estimate (M - 1 = 0); PyTorch
    // refuses it too. With a shared batch the kernel checks the global count instead.
    G2L_CHECK(!training || reduce || B * S > 1, "batch_norm: training needs more than one value per "
                                      "channel, got x ", x.desc());
    G2L_CHECK(eps > 0 && momentum >= 0 && momentum <= 1, "batch_norm: bad eps ", eps,
              " or momentum ", momentum);

    Tensor mean = Tensor::empty({C}, x.dtype(), x.device());
    Tensor invstd = Tensor::empty({C}, x.dtype(), x.device());
    Tensor y = Tensor::empty(x.shape(), x.dtype(), x.device());
    kernels::batch_norm_fwd(x, gamma, beta, running_mean, running_var, training, momentum, eps,
                            mean, invstd, y, &reduce);
    // The running buffers are not inputs of the graph: eval-mode backward uses the copies in
    // `mean` / `invstd`, so later running-stat updates cannot corrupt it.
    return autograd::record(
        "batch_norm", y, {x, gamma, beta},
        [x, gamma, mean, invstd, training, reduce](const Tensor& dy, autograd::Grads& g) {
            const int64_t C = x.size(1);
            Tensor sdy = Tensor::empty({C}, dy.dtype(), dy.device());
            Tensor sdyx = Tensor::empty({C}, dy.dtype(), dy.device());
            Tensor dx;
            if (g.needs(0)) dx = Tensor::empty(x.shape(), dy.dtype(), dy.device());
            kernels::batch_norm_bwd(x, dy, mean, invstd, gamma, training, &dx, sdyx, sdy,
                                    &reduce);
            if (g.needs(0)) g.add(0, dx);
            if (g.needs(1)) g.add(1, sdyx);
            if (g.needs(2)) g.add(2, sdy);
        });
}

}  // namespace g2l::nn
