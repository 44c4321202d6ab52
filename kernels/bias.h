// SPDX-License-Identifier: MIT
// Per-channel bias for channel-first tensors y: [B, C, N] (N = 1 for [B, C] rows... see below).
#pragma once

#include <cstdint>

namespace g2l::kernels {

/// y[b, c, n] += bias[c] for y: [B, C, N] contiguous.
template <class T> void add_bias_bcn_cpu(T* y, const T* bias, int64_t B, int64_t C, int64_t N);
/// db[c] (+)= sum_{b, n} dy[b, c, n]; accumulate selects += over =. Per-channel sums run in a
/// fixed order on one thread, so the result does not depend on the thread count.
template <class T>
void bias_grad_bcn_cpu(const T* dy, T* db, int64_t B, int64_t C, int64_t N, bool accumulate);

}  // namespace g2l::kernels
