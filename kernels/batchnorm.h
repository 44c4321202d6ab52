// SPDX-License-Identifier: MIT
// Batch normalisation over channel dim 1 of x: [B, C, S] (S = N points, H*W pixels, or 1).
// Each channel is handled by one thread with sums in a fixed order: thread-count independent.
#pragma once

#include <cstdint>

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

}  // namespace g2l::kernels
