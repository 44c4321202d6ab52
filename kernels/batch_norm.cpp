// SPDX-License-Identifier: MIT
// batch_norm: the dispatch point (kernels/dispatch.h); CPU kernels in batch_norm_cpu.cpp.
#include "kernels/batch_norm.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "kernels/dispatch.h"

namespace g2l::kernels {

namespace {

// invstd from the batch variance and the running-statistics update (C values: host loops).
template <class T>
void bn_finish_stats_cpu(const T* var, int64_t C, int64_t M, double momentum, double eps,
                         const T* mean, T* invstd, T* running_mean, T* running_var) {
    for (int64_t c = 0; c < C; ++c) invstd[c] = T(1) / std::sqrt(var[c] + T(eps));
    // No running statistics to update (the layer does not track them).
    if (!running_mean) return;
    // Normalisation uses the biased variance, but running_var stores the unbiased one
    // (x M/(M-1)), as PyTorch does; imported weights and eval mode rely on that convention.
    const double unbias = double(M) / double(M - 1);
    for (int64_t c = 0; c < C; ++c) {
        // PyTorch's momentum convention (new = (1-m) old + m batch, default 0.1; spec §4), which is
        // the opposite of Keras's; the blend is formed in double and rounded once.
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
                    Tensor& invstd, Tensor& y, const BnReduce* reduce) {
    // An empty BnReduce means this process's batch is the whole batch: no collective calls.
    const bool shared = training && reduce && *reduce;
    // S folds every dimension after C ([B,C,N] points, [B,C,H,W] pixels, [B,C] rows); the max()
    // keeps an empty batch from dividing by zero.
    const int64_t B = x.size(0), C = x.size(1), S = x.numel() / std::max<int64_t>(1, B * C);
    dispatch("batch_norm", {&x, &gamma, &beta, &running_mean, &running_var, &mean, &invstd, &y},
             [&](auto tag) {
                 using T = decltype(tag);
                 if (shared) {
                     // The global batch's statistics, two passes as bn_stats_cpu: the sums
                     // (and the count, last) added over the processes, then the squared
                     // deviations from the global mean.
                     std::vector<double> buf(static_cast<size_t>(C) + 1);
                     std::vector<double> gmean(static_cast<size_t>(C));
                     bn_moment_cpu<T>(x.data<T>(), B, C, S, nullptr, false, buf.data());
                     buf[size_t(C)] = double(B * S);
                     (*reduce)(buf.data(), C + 1);
                     const double M = buf[size_t(C)];
                     for (int64_t c = 0; c < C; ++c) gmean[size_t(c)] = buf[size_t(c)] / M;
                     bn_moment_cpu<T>(x.data<T>(), B, C, S, gmean.data(), true, buf.data());
                     (*reduce)(buf.data(), C);
                     G2L_CHECK(M > 1, "batch_norm: training needs more than one value per "
                                      "channel in the global batch, got ", M);
                     Tensor var = Tensor::empty({C}, x.dtype(), x.device());
                     for (int64_t c = 0; c < C; ++c) {
                         mean.data<T>()[c] = T(gmean[size_t(c)]);
                         var.data<T>()[c] = T(buf[size_t(c)] / M);
                     }
                     bn_finish_stats_cpu<T>(var.data<T>(), C, int64_t(M), momentum, eps,
                                            mean.data<T>(), invstd.data<T>(),
                                            data_or_null<T>(&running_mean),
                                            data_or_null<T>(&running_var));
                 } else if (training) {
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
    // Running statistics were written through raw pointers: bump their versions by hand.
    if (training && running_mean.defined()) {
        running_mean.impl()->storage->bump_version();
        running_var.impl()->storage->bump_version();
    }
}

void batch_norm_bwd(const Tensor& x, const Tensor& dy, const Tensor& mean, const Tensor& invstd,
                    const Tensor& gamma, bool training, Tensor* dx, Tensor& dgamma,
                    Tensor& dbeta, const BnReduce* reduce) {
    const bool shared = training && reduce && *reduce;
    const int64_t B = x.size(0), C = x.size(1), S = x.numel() / std::max<int64_t>(1, B * C);
    dispatch("batch_norm backward", {&dy, &x, &mean, &invstd, &gamma, dx, &dgamma, &dbeta},
             [&](auto tag) {
                 using T = decltype(tag);
                 T* dxp = data_or_null<T>(dx);
                 // Shared batch: this process's sums first (they are its dgamma / dbeta),
                 // then dx from the sums and count of the global batch.
                 bn_backward_cpu<T>(x.data<T>(), dy.data<T>(), mean.data<T>(), invstd.data<T>(),
                                    data_or_null<T>(gamma), B, C, S, training,
                                    shared ? nullptr : dxp, dbeta.data<T>(), dgamma.data<T>());
                 if (!shared) return;
                 std::vector<double> buf(2 * size_t(C) + 1);
                 for (int64_t c = 0; c < C; ++c) {
                     buf[size_t(c)] = double(dbeta.data<T>()[c]);
                     buf[size_t(C + c)] = double(dgamma.data<T>()[c]);
                 }
                 buf[2 * size_t(C)] = double(B * S);
                 (*reduce)(buf.data(), 2 * C + 1);  // every process calls it, dx or not
                 if (dxp)
                     bn_backward_dx_cpu<T>(x.data<T>(), dy.data<T>(), mean.data<T>(),
                                           invstd.data<T>(), data_or_null<T>(gamma), B, C, S,
                                           buf.data(), buf.data() + C, buf[2 * size_t(C)], dxp);
             });
}

}  // namespace g2l::kernels
