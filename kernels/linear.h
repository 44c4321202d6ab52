// SPDX-License-Identifier: MIT
// Dense layers on GEMM (kernels/gemm.h) and the per-channel bias (kernels/bias.h):
//   linear:  x [M, Cin], w [Cout, Cin], b [Cout] -> y [M, Cout] = x w^T + b
//   conv1x1: x [B, Cin, N], w [Cout, Cin], b [Cout] -> y [B, Cout, N] = w x[b] + b
//   matmul:  a [M, K], b [K, N] -> y [M, N]
// The caller (nn/ops/linear.cpp) checks shapes. Backward entries write each gradient whose
// pointer is non-null and whose tensor is defined (allocated by the caller); batch sums run in a
// fixed order, so results do not depend on the thread count.
#pragma once

#include "core/tensor.h"

namespace g2l::kernels {

void linear_fwd(const Tensor& x, const Tensor& w, const Tensor& b, Tensor& y);
void linear_bwd(const Tensor& x, const Tensor& w, const Tensor& dy, Tensor* dx, Tensor* dw,
                Tensor* db);
void conv1x1_fwd(const Tensor& x, const Tensor& w, const Tensor& b, Tensor& y);
void conv1x1_bwd(const Tensor& x, const Tensor& w, const Tensor& dy, Tensor* dx, Tensor* dw,
                 Tensor* db);
void matmul_fwd(const Tensor& a, const Tensor& b, Tensor& y);
void matmul_bwd(const Tensor& a, const Tensor& b, const Tensor& dy, Tensor* da, Tensor* db);

}  // namespace g2l::kernels
