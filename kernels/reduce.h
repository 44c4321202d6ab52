// SPDX-License-Identifier: MIT
// Reductions over one dimension. A contiguous tensor reduced over dimension d is viewed as
// x: [outer, D, inner] (outer = product of the sizes before d, inner = after) -> y: [outer, inner].
// Every output is accumulated in a fixed order (in double), so results do not depend on the
// OpenMP thread count. The caller checks shapes.
#pragma once

#include <cstdint>
#include <vector>

#include "core/tensor.h"

namespace g2l::kernels {

/// y[o, i] = scale * sum_d x[o, d, i]. D is split into fixed-size chunks whose partial sums are
/// added in chunk order: parallel even for one long row, and identical for any thread count.
template <class T>
void sum_dim_cpu(const T* x, T* y, int64_t outer, int64_t D, int64_t inner, double scale = 1.0);

/// Sums x (shape x_shape) down to y_shape, which is x_shape with some dimensions set to 1 or
/// missing on the left (the gradient of a broadcast). y is written, not added.
template <class T>
void sum_to_shape_cpu(const T* x, const std::vector<int64_t>& x_shape, T* y,
                      const std::vector<int64_t>& y_shape);

/// x[o, d, i] = scale * y[o, i] for every d (the gradient of sum / mean over d).
template <class T>
void broadcast_dim_cpu(const T* y, T* x, int64_t outer, int64_t D, int64_t inner, double scale);

/// y[o, i] = max_d x[o, d, i], arg[o, i] = the lowest d reaching it (NaN wins, like PyTorch).
/// D >= 1.
template <class T>
void max_dim_fwd_cpu(const T* x, T* y, int32_t* arg, int64_t outer, int64_t D, int64_t inner);

/// dx[o, d, i] = (d == arg[o, i]) ? dy[o, i] : 0 (written, not added).
template <class T>
void max_dim_bwd_cpu(const T* dy, const int32_t* arg, T* dx, int64_t outer, int64_t D,
                     int64_t inner);

/// y[o, i] = sqrt(sum_d x[o, d, i]^2 + eps).
template <class T>
void norm_dim_fwd_cpu(const T* x, T* y, int64_t outer, int64_t D, int64_t inner, double eps);

/// dx[o, d, i] = dy[o, i] * x[o, d, i] / y[o, i] (written, not added).
template <class T>
void norm_dim_bwd_cpu(const T* x, const T* y, const T* dy, T* dx, int64_t outer, int64_t D,
                      int64_t inner);

// ---- tensor-level entry points: one dispatch on (device, dtype) each ----

/// The [outer, D, inner] reductions of a tensor (sizes given by the caller).
void sum_dim(const Tensor& x, Tensor& y, int64_t outer, int64_t D, int64_t inner,
             double scale = 1.0);
/// y (its shape) = x summed down to it.
void sum_to_shape(const Tensor& x, Tensor& y);
void broadcast_dim(const Tensor& y, Tensor& x, int64_t outer, int64_t D, int64_t inner,
                   double scale);
void max_dim_fwd(const Tensor& x, Tensor& y, Tensor& arg, int64_t outer, int64_t D, int64_t inner);
void max_dim_bwd(const Tensor& dy, const Tensor& arg, Tensor& dx, int64_t outer, int64_t D,
                 int64_t inner);
void norm_dim_fwd(const Tensor& x, Tensor& y, int64_t outer, int64_t D, int64_t inner, double eps);
void norm_dim_bwd(const Tensor& x, const Tensor& y, const Tensor& dy, Tensor& dx, int64_t outer,
                  int64_t D, int64_t inner);

}  // namespace g2l::kernels
