// SPDX-License-Identifier: MIT
// batch_norm: the dispatch point (kernels/dispatch.h); CPU kernels in batch_norm_cpu.cpp.
#include "kernels/batch_norm.h"

#include <algorithm>
#include <cmath>

#include "kernels/dispatch.h"

namespace g2l::kernels {

namespace {

// invstd from the batch variance and the running-statistics update (C values: host loops).
template <class T>
void bn_finish_stats_cpu(const T* var, int64_t C, int64_t M, double momentum, double eps,
                         const T* mean, T* invstd, T* running_mean, T* running_var) {
    for (int64_t c = 0; c < C; ++c) invstd[c] = T(1) / std::sqrt(var[c] + T(eps));
    if (!running_mean) return;
    const double unbias = double(M) / double(M - 1);
    for (int64_t c = 0; c < C; ++c) {
        running_mean[c] = T((1 - momentum) * running_mean[c] + momentum * mean[c]);
        running_var[c] = T((1 - momentum) * running_var[c] + momentum * var[c] * unbias);
    }
}

template <class T>
void bn_eval_stats_cpu(const T* running_mean, const T* running_var, int64_t C, double eps,
                       T* mean, T* invstd) {
    for (int64_t c = 0; c < C; ++c) {
        mean[c] = running_mean[c];
        invstd[c] = T(1) / std::sqrt(running_var[c] + T(eps));
    }
}

}  // namespace

void batch_norm_fwd(const Tensor& x, const Tensor& gamma, const Tensor& beta, Tensor& running_mean,
                    Tensor& running_var, bool training, double momentum, double eps, Tensor& mean,
                    Tensor& invstd, Tensor& y) {
    const int64_t B = x.size(0), C = x.size(1), S = x.numel() / std::max<int64_t>(1, B * C);
    dispatch("batch_norm", {&x, &gamma, &beta, &running_mean, &running_var, &mean, &invstd, &y},
             [&](auto tag) {
                 using T = decltype(tag);
                 if (training) {
                     Tensor var = Tensor::empty({C}, x.dtype(), x.device());
                     bn_stats_cpu<T>(x.data<T>(), B, C, S, mean.data<T>(), var.data<T>());
                     bn_finish_stats_cpu<T>(var.data<T>(), C, B * S, momentum, eps,
                                            mean.data<T>(), invstd.data<T>(),
                                            data_or_null<T>(&running_mean),
                                            data_or_null<T>(&running_var));
                 } else {
                     bn_eval_stats_cpu<T>(running_mean.data<T>(), running_var.data<T>(), C, eps,
                                          mean.data<T>(), invstd.data<T>());
                 }
                 bn_apply_cpu<T>(x.data<T>(), mean.data<T>(), invstd.data<T>(),
                                 data_or_null<T>(gamma), data_or_null<T>(beta), B, C, S,
                                 y.data<T>());
             });
    if (training && running_mean.defined()) {
        running_mean.impl()->storage->bump_version();
        running_var.impl()->storage->bump_version();
    }
}

void batch_norm_bwd(const Tensor& x, const Tensor& dy, const Tensor& mean, const Tensor& invstd,
                    const Tensor& gamma, bool training, Tensor* dx, Tensor& dgamma,
                    Tensor& dbeta) {
    const int64_t B = x.size(0), C = x.size(1), S = x.numel() / std::max<int64_t>(1, B * C);
    dispatch("batch_norm backward", {&dy, &x, &mean, &invstd, &gamma, dx, &dgamma, &dbeta},
             [&](auto tag) {
                 using T = decltype(tag);
                 bn_backward_cpu<T>(x.data<T>(), dy.data<T>(), mean.data<T>(), invstd.data<T>(),
                                    data_or_null<T>(gamma), B, C, S, training,
                                    data_or_null<T>(dx), dbeta.data<T>(), dgamma.data<T>());
             });
}

}  // namespace g2l::kernels
