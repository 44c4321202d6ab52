// SPDX-License-Identifier: MIT
// Max over points: y[b, c] = max_n x[b, c, n], with the argmax kept for backward.
#pragma once

#include <cstdint>

namespace g2l::kernels {

/// x: [R, N] rows (R = B*C) -> y: [R], arg: [R]. Ties go to the lowest n. N must be > 0.
template <class T> void max_points_fwd_cpu(const T* x, int64_t R, int64_t N, T* y, int32_t* arg);
/// dx (zeroed by the caller): dx[r, arg[r]] += dy[r].
template <class T>
void max_points_bwd_cpu(const T* dy, const int32_t* arg, int64_t R, int64_t N, T* dx);

}  // namespace g2l::kernels
