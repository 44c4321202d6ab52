// SPDX-License-Identifier: MIT
// Dense GEMM on row-major matrices: C = alpha * op(A) * op(B) + beta * C.
// op(A) is [M, K] (A stored [M, K] with lda, or [K, M] when trans_a), op(B) is [K, N], C [M, N].
// Eigen's GEBP kernels do the work on fixed 512 x 512 tiles of C, spread over OpenMP threads;
// results are bitwise identical for any thread count (see gemm_cpu.cpp).
#pragma once

#include <cstdint>

namespace g2l::kernels {

template <class T>
void gemm_cpu(bool trans_a, bool trans_b, int64_t M, int64_t N, int64_t K, T alpha, const T* A,
              int64_t lda, const T* B, int64_t ldb, T beta, T* C, int64_t ldc);

}  // namespace g2l::kernels
