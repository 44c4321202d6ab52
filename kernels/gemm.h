// SPDX-License-Identifier: MIT
// Dense GEMM on row-major matrices: C = alpha * op(A) * op(B) + beta * C.
// op(A) is [M, K] (A stored [M, K] with lda, or [K, M] when trans_a), op(B) is [K, N], C [M, N].
// float: our packed GEMM (an MR x NR register-blocked micro-kernel for AVX-512, AVX2, SSE2 or
// any other target; K blocks of 384); double: Eigen's GEBP on 512 x 512 tiles of C. Both spread
// over OpenMP threads and give bitwise identical results for any thread count (gemm_cpu.cpp).
// Also: batches sharing op(A) (a 1x1 convolution's samples), an op(A) packed once (inference
// weights), and a bias / ReLU epilogue applied to each tile of C while it is in cache.
#pragma once

#include <cstdint>
#include <vector>

namespace g2l::kernels {

/// What a float GEMM does to C once its sum is complete (in the micro-kernel's registers without
/// segments, else in a pass over each finished tile while it is in cache):
/// C[r, n] = relu?(C[r, n] + bias), bias = bias[r], or bias[s * M + r] for the columns n of
/// segment s, [segments[s], segments[s + 1]) (num_segments + 1 starts, the first 0, the last N).
struct GemmEpilogue {
    const float* bias = nullptr;  // null: no bias
    const int64_t* segments = nullptr;
    int64_t num_segments = 0;
    bool relu = false;
};

template <class T>
void gemm_cpu(bool trans_a, bool trans_b, int64_t M, int64_t N, int64_t K, T alpha, const T* A,
              int64_t lda, const T* B, int64_t ldb, T beta, T* C, int64_t ldc);

/// `batch` products sharing op(A): C_b = alpha op(A) op(B_b) + beta C_b, B_b = B + b * stride_b,
/// C_b = C + b * stride_c, then the epilogue (float only). op(A) is packed once per K block and
/// the batch shares one thread team: faster than `batch` gemm_cpu calls, bitwise the same.
template <class T>
void gemm_batched_cpu(bool trans_a, bool trans_b, int64_t M, int64_t N, int64_t K, T alpha,
                      const T* A, int64_t lda, const T* B, int64_t ldb, int64_t stride_b, T beta,
                      T* C, int64_t ldc, int64_t stride_c, int64_t batch,
                      const GemmEpilogue* epilogue = nullptr);

/// op(A) [M, K] packed once for the float GEMM's micro-kernel, for many products with it (a
/// layer's weights at inference). The layout is this build's (its micro-kernel's row count).
class PackedGemmA {
public:
    PackedGemmA() = default;
    PackedGemmA(bool trans_a, int64_t M, int64_t K, const float* A, int64_t lda);
    int64_t rows() const { return M_; }
    int64_t cols() const { return K_; }
    bool empty() const { return data_.empty(); }

private:
    friend void gemm_packed_a_cpu(const PackedGemmA&, int64_t, const float*, int64_t, float*,
                                  int64_t, const GemmEpilogue*);
    std::vector<float> data_;
    int64_t M_ = 0, K_ = 0;
};

/// The FLOPs (2 per multiply-add) of every float product this process has run so far, all
/// threads together (gemm_cpu, gemm_batched_cpu, gemm_packed_a_cpu): what a benchmark divides by
/// its time to get the rate of useful GEMM work.
uint64_t sgemm_flops_done();

/// C [M, N] = op(A) B (B [K, N] with ldb; C overwritten), then the epilogue. Bitwise the same as
/// gemm_cpu(trans_a, false, M, N, K, 1, A, lda, B, ldb, 0, C, ldc) and the epilogue after it.
void gemm_packed_a_cpu(const PackedGemmA& a, int64_t N, const float* B, int64_t ldb, float* C,
                       int64_t ldc, const GemmEpilogue* epilogue = nullptr);

}  // namespace g2l::kernels
