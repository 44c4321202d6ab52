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
// Tiles start at 512 x 512; a product with fewer than 8 tiles (a batch-1 layer: [64..1024] x
// [512..1500] points) has its tile width and then height halved, down to 128 x 64, so that
// both cores get work. The tile shape is a function of (M, N) only.
constexpr int64_t kTileM = 512, kTileN = 512, kMinTileM = 64, kMinTileN = 128, kWantTiles = 8;

void tile_shape(int64_t M, int64_t N, int64_t* tm, int64_t* tn) {
    *tm = kTileM, *tn = kTileN;
    auto tiles = [&] { return ((M + *tm - 1) / *tm) * ((N + *tn - 1) / *tn); };
    while (tiles() < kWantTiles) {
        if (*tn > kMinTileN && *tn >= N / 2) *tn /= 2;
        else if (*tm > kMinTileM && *tm >= M / 2) *tm /= 2;
        else if (*tn > kMinTileN) *tn /= 2;
        else if (*tm > kMinTileM) *tm /= 2;
        else break;
    }
}

template <class T>
void gemm_cpu(bool trans_a, bool trans_b, int64_t M, int64_t N, int64_t K, T alpha, const T* A,
              int64_t lda, const T* B, int64_t ldb, T beta, T* C, int64_t ldc) {
    static const bool single = [] { Eigen::setNbThreads(1); return true; }();
    (void)single;
    MMap<T> c(C, M, N, Eigen::OuterStride<>(ldc));
    if (beta == T(0)) c.setZero();
    else if (beta != T(1)) c *= beta;
    if (M == 0 || N == 0 || K == 0) return;
    int64_t sm = kTileM, sn = kTileN;
    if (M * N * K > (int64_t(1) << 20)) tile_shape(M, N, &sm, &sn);
    const int64_t tm = (M + sm - 1) / sm, tn = (N + sn - 1) / sn;
    const int64_t tiles = tm * tn;
    const bool parallel = tiles > 1 && M * N * K > (int64_t(1) << 20);
#pragma omp parallel for schedule(dynamic) if (parallel)
    for (int64_t t = 0; t < tiles; ++t) {
        const int64_t i0 = (t / tn) * sm, j0 = (t % tn) * sn;
        gemm_tile<T>(trans_a, trans_b, i0, std::min(sm, M - i0), j0, std::min(sn, N - j0), K,
                     alpha, A, lda, B, ldb, C, ldc);
    }
}

template void gemm_cpu<float>(bool, bool, int64_t, int64_t, int64_t, float, const float*,
                              int64_t, const float*, int64_t, float, float*, int64_t);
template void gemm_cpu<double>(bool, bool, int64_t, int64_t, int64_t, double, const double*,
                               int64_t, const double*, int64_t, double, double*, int64_t);

}  // namespace g2l::kernels
