// SPDX-License-Identifier: MIT
// Max over points: y[b, c] = max_n x[b, c, n], with the argmax kept for backward.
#pragma once

#include <cstdint>

#include "core/tensor.h"

namespace g2l::kernels {

/// x: [R, N] rows (R = B*C) -> y: [R], arg: [R]. Ties go to the lowest n. N must be > 0.
template <class T> void max_pool_points_fwd_cpu(const T* x, int64_t R, int64_t N, T* y, int32_t* arg);
/// dx (zeroed by the caller): dx[r, arg[r]] += dy[r].
template <class T>
void max_pool_points_bwd_cpu(const T* dy, const int32_t* arg, int64_t R, int64_t N, T* dx);

// ---- tensor-level entry points: one dispatch on (device, dtype) each ----

/// y[b, c] = max_n x[b, c, n] (x [B, C, N], y [B, C], arg i32 [B, C]).
void max_pool_points_fwd(const Tensor& x, Tensor& y, Tensor& arg);
/// dx [B, C, N] = 0 except dx[b, c, arg[b, c]] = dy[b, c].
void max_pool_points_bwd(const Tensor& dy, const Tensor& arg, Tensor& dx);

}  // namespace g2l::kernels
