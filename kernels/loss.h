// SPDX-License-Identifier: MIT
// Loss kernels. Negative log-likelihood over logp: [B, K, N] (class dimension in the middle; the
// [M, K] case is B = M, N = 1) with target: [B, N] class ids already checked to lie in [0, K).
#pragma once

#include <cstdint>

#include "core/tensor.h"

namespace g2l::kernels {

/// Sums over all (b, n): num += -w[t] * logp[b, t, n] and den += w[t] (w[t] = 1 when weight is
/// null). Accumulated in double in (b, n) order (serial: the work is B*N loads).
template <class T>
void nll_fwd_cpu(const T* logp, const int32_t* target, const T* weight, int64_t B, int64_t K,
                 int64_t N, double* num, double* den);

/// dlogp[b, k, n] = (k == t) ? -w[t] * scale : 0 (written, not added).
template <class T>
void nll_bwd_cpu(const int32_t* target, const T* weight, int64_t B, int64_t K, int64_t N,
                 double scale, T* dlogp);

/// Huber loss per element, as PyTorch's smooth_l1: with d = a - b,
/// y = 0.5 d^2 / beta if |d| < beta, else |d| - 0.5 beta (beta == 0: y = |d|).
template <class T>
void smooth_l1_fwd_cpu(const T* a, const T* b, T* y, int64_t n, double beta);

/// da = dy * (|d| < beta ? d / beta : sign(d)); db = -da. Either output may be null.
template <class T>
void smooth_l1_bwd_cpu(const T* a, const T* b, const T* dy, T* da, T* db, int64_t n, double beta);

// ---- tensor-level entry points: one dispatch on (device, dtype) each ----

/// Sums of the NLL terms (see nll_fwd_cpu): *num = -sum w[t] logp[t], *den = sum w[t] (host).
/// target i32 [B, N] (or [M]), weight [K] or undefined.
void nll_fwd(const Tensor& logp, const Tensor& target, const Tensor& weight, int64_t B,
             int64_t K, int64_t N, double* num, double* den);
/// dlogp [B, K, N] = -scale w[t] at the targets, 0 elsewhere.
void nll_bwd(const Tensor& target, const Tensor& weight, int64_t B, int64_t K, int64_t N,
             double scale, Tensor& dlogp);
void smooth_l1_fwd(const Tensor& a, const Tensor& b, Tensor& y, double beta);
void smooth_l1_bwd(const Tensor& a, const Tensor& b, const Tensor& dy, Tensor* da, Tensor* db,
                   double beta);

}  // namespace g2l::kernels
