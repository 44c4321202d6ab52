// SPDX-License-Identifier: MIT
// Batch normalisation over channel dim 1 of x: [B, C, S] (S = N points, H*W pixels, or 1).
// Each channel is handled by one thread with sums in a fixed order: thread-count independent.
#pragma once

#include <cstdint>
#include <functional>

#include "core/tensor.h"

namespace g2l::kernels {

/// mean[c] and biased var[c] over the B*S values of channel c.
template <class T>
void bn_stats_cpu(const T* x, int64_t B, int64_t C, int64_t S, T* mean, T* var);

/// y = gamma[c] * (x - mean[c]) * invstd[c] + beta[c]; gamma/beta may be null (1 and 0).
template <class T>
void bn_apply_cpu(const T* x, const T* mean, const T* invstd, const T* gamma, const T* beta,
                  int64_t B, int64_t C, int64_t S, T* y);

/// Backward. xhat = (x - mean) * invstd. Writes sum_dy[c] and sum_dy_xhat[c] (needed for
/// dgamma = sum_dy_xhat, dbeta = sum_dy) and, if dx != null:
///   training: dx = gamma invstd (dy - sum_dy / M - xhat sum_dy_xhat / M), M = B*S
///   eval:     dx = gamma invstd dy
template <class T>
void bn_backward_cpu(const T* x, const T* dy, const T* mean, const T* invstd, const T* gamma,
                     int64_t B, int64_t C, int64_t S, bool training, T* dx, T* sum_dy,
                     T* sum_dy_xhat);

/// out[c] = sum over the B*S values of channel c of (x - shift[c]) (square false) or
/// (x - shift[c])^2 (square true), in double; shift null = 0. The partial sums a data-parallel
/// BatchNorm adds over processes (one pass each: the sum, then squared deviations from the
/// global mean, as bn_stats_cpu's two passes).
template <class T>
void bn_moment_cpu(const T* x, int64_t B, int64_t C, int64_t S, const double* shift, bool square,
                   double* out);

/// Training-mode dx from given channel sums (e.g. summed over processes) over M values:
/// dx = gamma invstd (dy - sum_dy / M - xhat sum_dy_xhat / M).
template <class T>
void bn_backward_dx_cpu(const T* x, const T* dy, const T* mean, const T* invstd, const T* gamma,
                        int64_t B, int64_t C, int64_t S, const double* sum_dy,
                        const double* sum_dy_xhat, double M, T* dx);

/// Sums `n` doubles element-wise over the processes that share one batch, in place (a
/// data-parallel BatchNorm; nn/data_parallel.h). Null or empty: the batch is this one alone.
using BnReduce = std::function<void(double* values, int64_t n)>;

// ---- tensor-level entry points: one dispatch on (device, dtype) each ----

/// Batch normalisation of x [B, C, S...] over all but dim 1. training: batch statistics into
/// mean / invstd ([C]) and, when defined, running_mean / running_var updated with `momentum`
/// (unbiased variance, versions bumped); eval: mean / invstd from the running statistics.
/// y = gamma (x - mean) invstd + beta (gamma / beta may be undefined). With `reduce` (training
/// only) the statistics are those of the global batch: the count, the sums and the squared
/// deviations are summed over the processes (two reduce calls).
void batch_norm_fwd(const Tensor& x, const Tensor& gamma, const Tensor& beta, Tensor& running_mean,
                    Tensor& running_var, bool training, double momentum, double eps, Tensor& mean,
                    Tensor& invstd, Tensor& y, const BnReduce* reduce = nullptr);
/// Backward (see bn_backward_cpu): dx when dx is non-null and defined; dgamma = sum dy xhat and
/// dbeta = sum dy ([C], both always written) over THIS process's values (the optimiser's
/// gradient sum adds the other processes'). With `reduce` (training only) dx uses the sums and
/// the count of the global batch (one reduce call).
void batch_norm_bwd(const Tensor& x, const Tensor& dy, const Tensor& mean, const Tensor& invstd,
                    const Tensor& gamma, bool training, Tensor* dx, Tensor& dgamma, Tensor& dbeta,
                    const BnReduce* reduce = nullptr);

}  // namespace g2l::kernels
