// SPDX-License-Identifier: MIT
// Softmax and log-softmax over one dimension of a contiguous tensor viewed as [outer, D, inner].
// Numerically stable: the maximum over d is subtracted before exponentiating. The caller checks
// shapes (D >= 1).
#pragma once

#include <cstdint>

#include "core/tensor.h"

namespace g2l::kernels {

/// y = softmax_d(x) (log_softmax when `log`).
template <class T>
void softmax_fwd_cpu(const T* x, T* y, int64_t outer, int64_t D, int64_t inner, bool log);

/// From the forward output y and dy: softmax: dx = y * (dy - sum_d dy * y);
/// log_softmax: dx = dy - exp(y) * sum_d dy. dx is written, not added.
template <class T>
void softmax_bwd_cpu(const T* y, const T* dy, T* dx, int64_t outer, int64_t D, int64_t inner,
                     bool log);

// ---- tensor-level entry points: one dispatch on (device, dtype) each ----

/// (log-)softmax over D of x seen as [outer, D, inner].
void softmax_fwd(const Tensor& x, Tensor& y, int64_t outer, int64_t D, int64_t inner, bool log);
void softmax_bwd(const Tensor& y, const Tensor& dy, Tensor& dx, int64_t outer, int64_t D,
                 int64_t inner, bool log);

}  // namespace g2l::kernels
