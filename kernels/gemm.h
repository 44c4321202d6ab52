// SPDX-License-Identifier: MIT
// Dense GEMM on row-major matrices: C = alpha * op(A) * op(B) + beta * C.
// op(A) is [M, K] (A stored [M, K] with lda, or [K, M] when trans_a), op(B) is [K, N], C [M, N].
// float: our packed GEMM (an MR x NR register-blocked micro-kernel for AVX-512, AVX2, SSE2 or
// any other target; K blocks of 384); double: Eigen's GEBP on 512 x 512 tiles of C. Both spread
// over OpenMP threads and give bitwise identical results for any thread count (gemm_cpu.cpp).
#pragma once

#include <cstdint>

namespace g2l::kernels {

template <class T>
void gemm_cpu(bool trans_a, bool trans_b, int64_t M, int64_t N, int64_t K, T alpha, const T* A,
              int64_t lda, const T* B, int64_t ldb, T beta, T* C, int64_t ldc);

}  // namespace g2l::kernels
