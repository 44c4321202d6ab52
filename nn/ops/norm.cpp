// SPDX-License-Identifier: MIT
#include "nn/ops/norm.h"

#include <algorithm>
#include <cmath>
#include <initializer_list>

#include "core/autograd.h"
#include "core/dispatch.h"
#include "kernels/batchnorm.h"

namespace g2l::nn {

Tensor batch_norm(const Tensor& x, const Tensor& gamma, const Tensor& beta, Tensor running_mean,
                  Tensor running_var, bool training, double momentum, double eps) {
    G2L_CHECK(x.defined() && x.dim() >= 2 && x.dim() <= 4,
              "batch_norm: expected x as [B, C], [B, C, N] or [B, C, H, W], got ", x.desc());
    require_same("batch_norm", {&x, &gamma, &beta, &running_mean, &running_var});
    require_cpu("batch_norm", {&x, &gamma, &beta, &running_mean, &running_var});
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
    G2L_CHECK(!training || B * S > 1, "batch_norm: training needs more than one value per "
                                      "channel, got x ", x.desc());
    G2L_CHECK(eps > 0 && momentum >= 0 && momentum <= 1, "batch_norm: bad eps ", eps,
              " or momentum ", momentum);

    Tensor mean = Tensor::empty({C}, x.dtype()), invstd = Tensor::empty({C}, x.dtype());
    Tensor y = Tensor::empty(x.shape(), x.dtype());
    dispatch_float(x.dtype(), "batch_norm", [&](auto tag) {
        using T = decltype(tag);
        T* pm = mean.data<T>();
        T* pis = invstd.data<T>();
        if (training) {
            Tensor var = Tensor::empty({C}, x.dtype());
            kernels::bn_stats_cpu<T>(x.data<T>(), B, C, S, pm, var.data<T>());
            const T* pv = var.data<T>();
            for (int64_t c = 0; c < C; ++c) pis[c] = T(1) / std::sqrt(pv[c] + T(eps));
            if (running_mean.defined()) {
                const double unbias = double(B * S) / double(B * S - 1);
                T* rm = running_mean.data<T>();
                T* rv = running_var.data<T>();
                for (int64_t c = 0; c < C; ++c) {
                    rm[c] = T((1 - momentum) * rm[c] + momentum * pm[c]);
                    rv[c] = T((1 - momentum) * rv[c] + momentum * pv[c] * unbias);
                }
                running_mean.impl()->storage->bump_version();
                running_var.impl()->storage->bump_version();
            }
        } else {
            const T* rm = running_mean.data<T>();
            const T* rv = running_var.data<T>();
            for (int64_t c = 0; c < C; ++c) {
                pm[c] = rm[c];
                pis[c] = T(1) / std::sqrt(rv[c] + T(eps));
            }
        }
        kernels::bn_apply_cpu<T>(x.data<T>(), pm, pis, gamma.defined() ? gamma.data<T>() : nullptr,
                                 beta.defined() ? beta.data<T>() : nullptr, B, C, S, y.data<T>());
    });
    // The running buffers are not inputs of the graph: eval-mode backward uses the copies in
    // `mean` / `invstd`, so later running-stat updates cannot corrupt it.
    return autograd::record(
        "batch_norm", y, {x, gamma, beta},
        [x, gamma, mean, invstd, training](const Tensor& dy, autograd::Grads& g) {
            const int64_t B = x.size(0), C = x.size(1), S = x.numel() / (B * C);
            dispatch_float(dy.dtype(), "batch_norm backward", [&](auto tag) {
                using T = decltype(tag);
                Tensor sdy = Tensor::empty({C}, dy.dtype()), sdyx = Tensor::empty({C}, dy.dtype());
                Tensor dx;
                if (g.needs(0)) dx = Tensor::empty(x.shape(), dy.dtype());
                kernels::bn_backward_cpu<T>(x.data<T>(), dy.data<T>(), mean.data<T>(),
                                            invstd.data<T>(),
                                            gamma.defined() ? gamma.data<T>() : nullptr, B, C, S,
                                            training, dx.defined() ? dx.data<T>() : nullptr,
                                            sdy.data<T>(), sdyx.data<T>());
                if (g.needs(0)) g.add(0, dx);
                if (g.needs(1)) g.add(1, sdyx);
                if (g.needs(2)) g.add(2, sdy);
            });
        });
}

}  // namespace g2l::nn
