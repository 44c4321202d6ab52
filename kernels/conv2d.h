// SPDX-License-Identifier: MIT
// 2D convolution (cross-correlation, PyTorch's Conv2d), NCHW, as im2col + GEMM.
//
//   y[b, co, oh, ow] = bias[co] + sum_{c, i, j} w[co, c, i, j] *
//                      x[b, g*Cin_g + c, oh*sh - ph + i*dh, ow*sw - pw + j*dw]
// where g = co / Cout_g is the group of output channel co, Cin_g = Cin / groups,
// Cout_g = Cout / groups, and x reads as 0 outside [0, H) x [0, W) (zero padding).
//
// Shapes (all contiguous, row-major): x [B, Cin, H, W], w [Cout, Cin_g, kh, kw], bias [Cout],
// y / dy [B, Cout, Ho, Wo]. The caller (nn/ops/conv2d.cpp) checks every size; the kernels trust
// Conv2dGeom. Results do not depend on the OpenMP thread count: the work is cut into pieces whose
// sizes depend only on the shapes, and every output element is produced by one piece.
#pragma once

#include <cstdint>

#include "core/tensor.h"

namespace g2l::kernels {

/// Every size of one conv2d call. Ho, Wo = floor((H + 2p - d(k - 1) - 1) / s) + 1, > 0.
struct Conv2dGeom {
    int64_t B = 0, Cin = 0, H = 0, W = 0;  ///< input x: [B, Cin, H, W]
    int64_t Cout = 0, kh = 1, kw = 1;      ///< weight w: [Cout, Cin / groups, kh, kw]
    int64_t sh = 1, sw = 1;                ///< stride (>= 1)
    int64_t ph = 0, pw = 0;                ///< zero padding on each side (>= 0)
    int64_t dh = 1, dw = 1;                ///< dilation (>= 1)
    int64_t groups = 1;                    ///< divides Cin and Cout
    int64_t Ho = 0, Wo = 0;                ///< output size
};

/// y = conv2d(x, w) + bias. `bias` may be nullptr (no bias). y is written, not added.
template <class T>
void conv2d_fwd_cpu(const T* x, const T* w, const T* bias, T* y, const Conv2dGeom& g);

/// Gradients of conv2d given dy [B, Cout, Ho, Wo]. Each of dx [B, Cin, H, W],
/// dw [Cout, Cin_g, kh, kw], dbias [Cout] is computed only when non-null, and is written (not
/// added). x is needed only for dw and w only for dx (the other may be nullptr).
template <class T>
void conv2d_bwd_cpu(const T* x, const T* w, const T* dy, T* dx, T* dw, T* dbias,
                    const Conv2dGeom& g);

// ---- tensor-level entry points: one dispatch on (device, dtype) each ----

/// y = conv2d(x, w) + bias (bias may be undefined); shapes from g.
void conv2d_fwd(const Tensor& x, const Tensor& w, const Tensor& bias, Tensor& y,
                const Conv2dGeom& g);
/// Writes each non-null, defined gradient; x is read only for dw and w only for dx.
void conv2d_bwd(const Tensor& x, const Tensor& w, const Tensor& dy, Tensor* dx, Tensor* dw,
                Tensor* dbias, const Conv2dGeom& g);

}  // namespace g2l::kernels
