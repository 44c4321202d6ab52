// SPDX-License-Identifier: MIT
#include "kernels/gemm.h"

#include <Eigen/Core>
#include <algorithm>

namespace g2l::kernels {

namespace {
template <class T>
using RowMat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
template <class T>
using CMap = Eigen::Map<const RowMat<T>, 0, Eigen::OuterStride<>>;
template <class T>
using MMap = Eigen::Map<RowMat<T>, 0, Eigen::OuterStride<>>;
}  // namespace

// One tile of C (rows [i0, i0 + m), cols [j0, j0 + n)) with Eigen running single-threaded.
template <class T>
void gemm_tile(bool trans_a, bool trans_b, int64_t i0, int64_t m, int64_t j0, int64_t n, int64_t K,
               T alpha, const T* A, int64_t lda, const T* B, int64_t ldb, T* C, int64_t ldc) {
    MMap<T> c(C + i0 * ldc + j0, m, n, Eigen::OuterStride<>(ldc));
    // op(A) rows i0.. : A + i0*lda (not transposed) or A + i0 (transposed, A stored [K, M]).
    // op(B) cols j0.. : B + j0 (not transposed) or B + j0*ldb (transposed, B stored [N, K]).
    if (!trans_a && !trans_b) {
        c.noalias() += alpha * (CMap<T>(A + i0 * lda, m, K, Eigen::OuterStride<>(lda)) *
                                CMap<T>(B + j0, K, n, Eigen::OuterStride<>(ldb)));
    } else if (trans_a && !trans_b) {
        c.noalias() += alpha * (CMap<T>(A + i0, K, m, Eigen::OuterStride<>(lda)).transpose() *
                                CMap<T>(B + j0, K, n, Eigen::OuterStride<>(ldb)));
    } else if (!trans_a && trans_b) {
        c.noalias() += alpha * (CMap<T>(A + i0 * lda, m, K, Eigen::OuterStride<>(lda)) *
                                CMap<T>(B + j0 * ldb, n, K, Eigen::OuterStride<>(ldb)).transpose());
    } else {
        c.noalias() += alpha * (CMap<T>(A + i0, K, m, Eigen::OuterStride<>(lda)).transpose() *
                                CMap<T>(B + j0 * ldb, n, K, Eigen::OuterStride<>(ldb)).transpose());
    }
}

// Eigen's own multi-threaded GEMM chooses its K blocking from the thread count, so results
// would change with OMP_NUM_THREADS. We keep Eigen single-threaded and split C into tiles
// whose size depends only on the shape; every tile is computed the same way by whichever
// thread takes it, so results are bitwise identical for any thread count.
constexpr int64_t kTileM = 512, kTileN = 512;

template <class T>
void gemm_cpu(bool trans_a, bool trans_b, int64_t M, int64_t N, int64_t K, T alpha, const T* A,
              int64_t lda, const T* B, int64_t ldb, T beta, T* C, int64_t ldc) {
    static const bool single = [] { Eigen::setNbThreads(1); return true; }();
    (void)single;
    MMap<T> c(C, M, N, Eigen::OuterStride<>(ldc));
    if (beta == T(0)) c.setZero();
    else if (beta != T(1)) c *= beta;
    if (M == 0 || N == 0 || K == 0) return;
    const int64_t tm = (M + kTileM - 1) / kTileM, tn = (N + kTileN - 1) / kTileN;
    const int64_t tiles = tm * tn;
    const bool parallel = tiles > 1 && M * N * K > (int64_t(1) << 20);
#pragma omp parallel for schedule(dynamic) if (parallel)
    for (int64_t t = 0; t < tiles; ++t) {
        const int64_t i0 = (t / tn) * kTileM, j0 = (t % tn) * kTileN;
        gemm_tile<T>(trans_a, trans_b, i0, std::min(kTileM, M - i0), j0,
                     std::min(kTileN, N - j0), K, alpha, A, lda, B, ldb, C, ldc);
    }
}

template void gemm_cpu<float>(bool, bool, int64_t, int64_t, int64_t, float, const float*,
                              int64_t, const float*, int64_t, float, float*, int64_t);
template void gemm_cpu<double>(bool, bool, int64_t, int64_t, int64_t, double, const double*,
                               int64_t, const double*, int64_t, double, double*, int64_t);

}  // namespace g2l::kernels
