// SPDX-License-Identifier: MIT
// Batch normalisation over channel dim 1 of x: [B, C, S] (S = N points, H*W pixels, or 1).
// Each channel is handled by one thread with sums in a fixed order: thread-count independent.
#pragma once

#include <cstdint>

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

// ---- tensor-level entry points: one dispatch on (device, dtype) each ----

/// Batch normalisation of x [B, C, S...] over all but dim 1. training: batch statistics into
/// mean / invstd ([C]) and, when defined, running_mean / running_var updated with `momentum`
/// (unbiased variance, versions bumped); eval: mean / invstd from the running statistics.
/// y = gamma (x - mean) invstd + beta (gamma / beta may be undefined).
void batch_norm_fwd(const Tensor& x, const Tensor& gamma, const Tensor& beta, Tensor& running_mean,
                    Tensor& running_var, bool training, double momentum, double eps, Tensor& mean,
                    Tensor& invstd, Tensor& y);
/// Backward (see bn_backward_cpu): dx when dx is non-null and defined; dgamma = sum dy xhat and
/// dbeta = sum dy ([C], both always written).
void batch_norm_bwd(const Tensor& x, const Tensor& dy, const Tensor& mean, const Tensor& invstd,
                    const Tensor& gamma, bool training, Tensor* dx, Tensor& dgamma, Tensor& dbeta);

}  // namespace g2l::kernels
