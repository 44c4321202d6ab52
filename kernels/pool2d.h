// SPDX-License-Identifier: MIT
// 2D max / average pooling over NCHW planes (PyTorch MaxPool2d / AvgPool2d, floor mode).
//
// Window (oh, ow) covers rows oh*sh - ph .. oh*sh - ph + kh - 1 and columns likewise; padded
// positions are never a max-pool candidate and count as 0 in an average. Shapes (contiguous):
// x / dx [B, C, H, W], y / dy / argmax [B, C, Ho, Wo], Ho = floor((H + 2ph - kh) / sh) + 1.
// The caller (nn/ops/pool2d.cpp) checks the sizes, including 2*ph <= kh and 2*pw <= kw, which
// guarantees every window holds at least one input element. Planes (b, c) are independent
// OpenMP tasks, so results do not depend on the thread count.
#pragma once

#include <cstdint>

#include "core/tensor.h"

namespace g2l::kernels {

/// Every size of one pooling call. B*C planes of H x W in, Ho x Wo out.
struct Pool2dGeom {
    int64_t B = 0, C = 0, H = 0, W = 0;  ///< input x: [B, C, H, W]
    int64_t kh = 1, kw = 1;              ///< window
    int64_t sh = 1, sw = 1;              ///< stride (>= 1)
    int64_t ph = 0, pw = 0;              ///< implicit padding on each side
    int64_t Ho = 0, Wo = 0;              ///< output size
};

/// y = window max; argmax = flat index ih*W + iw of the winner inside its plane. Ties go to the
/// first element in row-major window order; a NaN wins (and propagates) like in PyTorch.
template <class T>
void max_pool2d_fwd_cpu(const T* x, T* y, int32_t* argmax, const Pool2dGeom& g);
/// dx[plane, argmax] += dy (dx is zeroed first, i.e. written).
template <class T>
void max_pool2d_bwd_cpu(const T* dy, const int32_t* argmax, T* dx, const Pool2dGeom& g);

/// y = window sum / divisor, divisor = kh*kw if count_include_pad, else the number of in-image
/// elements of the window.
template <class T>
void avg_pool2d_fwd_cpu(const T* x, T* y, const Pool2dGeom& g, bool count_include_pad);
/// dx[in-image element of window] += dy / divisor (dx is zeroed first, i.e. written).
template <class T>
void avg_pool2d_bwd_cpu(const T* dy, T* dx, const Pool2dGeom& g, bool count_include_pad);

// ---- tensor-level entry points: one dispatch on (device, dtype) each ----

void max_pool2d_fwd(const Tensor& x, Tensor& y, Tensor& argmax, const Pool2dGeom& g);
void max_pool2d_bwd(const Tensor& dy, const Tensor& argmax, Tensor& dx, const Pool2dGeom& g);
void avg_pool2d_fwd(const Tensor& x, Tensor& y, const Pool2dGeom& g, bool count_include_pad);
void avg_pool2d_bwd(const Tensor& dy, Tensor& dx, const Pool2dGeom& g, bool count_include_pad);

}  // namespace g2l::kernels
