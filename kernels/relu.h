// SPDX-License-Identifier: MIT
// ReLU. x, y, dy, dx: n contiguous elements. The caller checks sizes.
#pragma once

#include <cstdint>

namespace g2l::kernels {

/// y[i] = max(x[i], 0).
template <class T> void relu_fwd_cpu(const T* x, T* y, int64_t n);
/// dx[i] = y[i] > 0 ? dy[i] : 0 (written, not added).
template <class T> void relu_bwd_cpu(const T* y, const T* dy, T* dx, int64_t n);

}  // namespace g2l::kernels
