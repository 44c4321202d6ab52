// SPDX-License-Identifier: MIT
// Layout copies for concat / slice / repeat / permute / index_select. All buffers are contiguous
// row-major; a tensor cut along dimension d is viewed as [outer, D, inner]. Instantiated for
// float, double and int32_t. The caller checks shapes and index ranges.
#pragma once

#include <cstdint>
#include <vector>

#include "core/tensor.h"

namespace g2l::kernels {

/// For every o < outer: dst[o, dst_off + j, :] = src[o, src_off + j, :] for j < len, where src
/// is [outer, src_D, inner] and dst is [outer, dst_D, inner]. Other dst rows are untouched.
template <class T>
void copy_slab_cpu(const T* src, int64_t src_D, int64_t src_off, T* dst, int64_t dst_D,
                   int64_t dst_off, int64_t outer, int64_t len, int64_t inner);

/// y = x permuted: y's dimension k is x's dimension perm[k]. x_shape: x's sizes; perm is a
/// permutation of 0..rank-1.
template <class T>
void permute_cpu(const T* x, const std::vector<int64_t>& x_shape, const std::vector<int64_t>& perm,
                 T* y);

/// y[o, l, :] = x[o, idx[l], :] for l < L; x: [outer, D, inner] -> y: [outer, L, inner].
template <class T>
void index_select_fwd_cpu(const T* x, const int32_t* idx, int64_t L, T* y, int64_t outer, int64_t D,
                          int64_t inner);

/// dx = 0, then dx[o, idx[l], :] += dy[o, l, :] in increasing l (deterministic: each (o, i) is
/// owned by one thread).
template <class T>
void index_select_bwd_cpu(const T* dy, const int32_t* idx, int64_t L, T* dx, int64_t outer,
                          int64_t D, int64_t inner);

// ---- tensor-level entry points: one dispatch on (device, dtype) each ----

/// Layout copies (f32, f64 and i32).
void copy_slab(const Tensor& src, int64_t src_D, int64_t src_off, Tensor& dst, int64_t dst_D,
               int64_t dst_off, int64_t outer, int64_t len, int64_t inner);
void permute(const Tensor& x, const std::vector<int64_t>& perm, Tensor& y);
/// idx: i32 [L] on x's device, values already checked to lie in [0, D).
void index_select_fwd(const Tensor& x, const Tensor& idx, Tensor& y, int64_t outer, int64_t D,
                      int64_t inner);
void index_select_bwd(const Tensor& dy, const Tensor& idx, Tensor& dx, int64_t outer, int64_t D,
                      int64_t inner);

}  // namespace g2l::kernels
