// SPDX-License-Identifier: MIT
// ReLU. x, y, dy, dx: n contiguous elements. The caller checks sizes.
#pragma once

#include <cstdint>

#include "core/tensor.h"

namespace g2l::kernels {

/// y[i] = max(x[i], 0).
template <class T> void relu_fwd_cpu(const T* x, T* y, int64_t n);
/// dx[i] = y[i] > 0 ? dy[i] : 0 (written, not added).
template <class T> void relu_bwd_cpu(const T* y, const T* dy, T* dx, int64_t n);

// ---- tensor-level entry points: one dispatch on (device, dtype) each ----

/// y = relu(x); x, y same shape and device.
void relu_fwd(const Tensor& x, Tensor& y);
/// dx = y > 0 ? dy : 0.
void relu_bwd(const Tensor& y, const Tensor& dy, Tensor& dx);

}  // namespace g2l::kernels
