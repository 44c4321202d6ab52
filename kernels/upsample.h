// SPDX-License-Identifier: MIT
// 2D upsampling of NCHW planes: nearest (integer scale) and bilinear (PyTorch's
// F.interpolate(mode="bilinear") index convention). x / dx: `planes` (= B*C) contiguous planes of
// H x W; y / dy: planes of Ho x Wo. The caller checks the sizes. Planes are independent OpenMP
// tasks, so results do not depend on the thread count.
#pragma once

#include <cstdint>

#include "core/tensor.h"

namespace g2l::kernels {

/// y[oh, ow] = x[oh / s, ow / s], Ho = H*s, Wo = W*s.
template <class T>
void upsample_nearest2d_fwd_cpu(const T* x, T* y, int64_t planes, int64_t H, int64_t W,
                                int64_t s);
/// dx[h, w] = sum of dy over the s x s block it was copied to (written, not added).
template <class T>
void upsample_nearest2d_bwd_cpu(const T* dy, T* dx, int64_t planes, int64_t H, int64_t W,
                                int64_t s);

/// Bilinear interpolation to Ho x Wo. Source coordinate of output index o along an axis of input
/// size n: align_corners ? o*(n-1)/(No-1) (0 if No == 1) : max((o + 0.5)*n/No - 0.5, 0); it is
/// split into i0 = floor(src), i1 = min(i0 + 1, n - 1) with weights 1 - f and f, f = src - i0.
template <class T>
void upsample_bilinear2d_fwd_cpu(const T* x, T* y, int64_t planes, int64_t H, int64_t W,
                                 int64_t Ho, int64_t Wo, bool align_corners);
/// Adjoint of the forward: each dy is spread onto its four source pixels (dx written).
template <class T>
void upsample_bilinear2d_bwd_cpu(const T* dy, T* dx, int64_t planes, int64_t H, int64_t W,
                                 int64_t Ho, int64_t Wo, bool align_corners);

// ---- tensor-level entry points: one dispatch on (device, dtype) each ----

/// x [B, C, H, W] -> y [B, C, H * scale, W * scale].
void upsample_nearest2d_fwd(const Tensor& x, Tensor& y, int64_t scale);
void upsample_nearest2d_bwd(const Tensor& dy, Tensor& dx, int64_t scale);
/// x [B, C, H, W] -> y [B, C, Ho, Wo] (sizes from the tensors).
void upsample_bilinear2d_fwd(const Tensor& x, Tensor& y, bool align_corners);
void upsample_bilinear2d_bwd(const Tensor& dy, Tensor& dx, bool align_corners);

}  // namespace g2l::kernels
