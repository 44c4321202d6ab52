// SPDX-License-Identifier: MIT
// gemm_cpu against a plain double-precision reference, for every transpose combination, with
// leading dimensions larger than the rows, alpha and beta, on shapes that span several C tiles
// and K blocks with partial micro-panels at every edge (float: 12 or 6 rows x 2 vectors, K blocks
// of 384; double: 512 x 512 tiles); and 1 vs 2 threads bitwise.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstring>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "core/rng.h"
#include "kernels/gemm.h"
#include "testing.h"

using namespace g2l;

namespace {

template <class T>
std::vector<T> rnd(size_t n, uint64_t seed) {
    Rng r(seed);
    std::vector<T> v(n);
    for (auto& x : v) x = T(r.uniform(-1, 1));
    return v;
}

// C = alpha op(A) op(B) + beta C in double, op(A) [M, K], op(B) [K, N].
template <class T>
std::vector<double> reference(bool ta, bool tb, int64_t M, int64_t N, int64_t K, double alpha,
                              const std::vector<T>& A, int64_t lda, const std::vector<T>& B,
                              int64_t ldb, double beta, const std::vector<T>& C, int64_t ldc) {
    std::vector<double> out(size_t(M * ldc));
    for (int64_t i = 0; i < M; ++i)
        for (int64_t j = 0; j < N; ++j) {
            double s = 0;
            for (int64_t k = 0; k < K; ++k) {
                const double a = ta ? A[size_t(k * lda + i)] : A[size_t(i * lda + k)];
                const double b = tb ? B[size_t(j * ldb + k)] : B[size_t(k * ldb + j)];
                s += a * b;
            }
            out[size_t(i * ldc + j)] = alpha * s + beta * double(C[size_t(i * ldc + j)]);
        }
    return out;
}

template <class T>
void check_shape(bool ta, bool tb, int64_t M, int64_t N, int64_t K, double tol) {
    const int64_t lda = (ta ? M : K) + 3, ldb = (tb ? K : N) + 5, ldc = N + 2;
    const auto A = rnd<T>(size_t((ta ? K : M) * lda), 1);
    const auto B = rnd<T>(size_t((tb ? N : K) * ldb), 2);
    auto C = rnd<T>(size_t(M * ldc), 3);
    const auto ref = reference(ta, tb, M, N, K, 0.75, A, lda, B, ldb, -0.5, C, ldc);
    kernels::gemm_cpu<T>(ta, tb, M, N, K, T(0.75), A.data(), lda, B.data(), ldb, T(-0.5), C.data(), ldc);
    double worst = 0;
    for (int64_t i = 0; i < M; ++i)
        for (int64_t j = 0; j < N; ++j) {
            const double e = std::fabs(double(C[size_t(i * ldc + j)]) - ref[size_t(i * ldc + j)]);
            worst = std::max(worst, e / (1.0 + std::fabs(ref[size_t(i * ldc + j)])));
        }
    INFO("trans_a " << ta << " trans_b " << tb << " M " << M << " N " << N << " K " << K);
    CHECK(worst < tol);
}

}  // namespace

TEST_CASE("gemm_cpu matches a double reference across tiles, K blocks and partial panels",
          "[kernels][gemm]") {
    for (bool ta : {false, true})
        for (bool tb : {false, true}) {
            check_shape<float>(ta, tb, 1100, 1030, 70, 2e-5);   // many tiles, partial edges
            check_shape<float>(ta, tb, 37, 45, 900, 6e-5);      // 3 K blocks, the last partial
            check_shape<double>(ta, tb, 530, 1025, 33, 1e-12);
        }
    check_shape<float>(false, false, 1, 1, 1, 1e-6);
    check_shape<float>(false, false, 513, 7, 600, 3e-5);
}

TEST_CASE("gemm_cpu: 1 and 2 threads give bitwise identical results", "[kernels][gemm]") {
#ifndef _OPENMP
    testing::mark_skipped("built without OpenMP: one thread count only");
#else
    // A big product (many tiles), batch-1 layer shapes (a few tiles, one or three K blocks), a
    // product smaller than one tile; beta 0 and beta != 0.
    struct Case { int64_t M, N, K; float beta; };
    for (const Case c : {Case{1100, 700, 300, 0.f}, Case{1100, 700, 300, 0.5f},
                         Case{1024, 1000, 128, 0.f}, Case{256, 1000, 1152, 0.5f},
                         Case{40, 1000, 300, 0.f}}) {
        INFO("M " << c.M << " N " << c.N << " K " << c.K << " beta " << c.beta);
        const auto A = rnd<float>(size_t(c.M * c.K), 4), B = rnd<float>(size_t(c.K * c.N), 5);
        const auto C0 = rnd<float>(size_t(c.M * c.N), 6);
        std::vector<float> c1 = C0, c2 = C0, ref = C0;
        const int prev = omp_get_max_threads();
        omp_set_num_threads(1);
        kernels::gemm_cpu<float>(false, false, c.M, c.N, c.K, 1.f, A.data(), c.K, B.data(), c.N,
                                 c.beta, c1.data(), c.N);
        omp_set_num_threads(2);
        kernels::gemm_cpu<float>(false, false, c.M, c.N, c.K, 1.f, A.data(), c.K, B.data(), c.N,
                                 c.beta, c2.data(), c.N);
        omp_set_num_threads(prev);
        CHECK(std::memcmp(c1.data(), c2.data(), c1.size() * sizeof(float)) == 0);
        // And the value is the product (a tiling that dropped or doubled a tile would differ).
        for (int64_t i = 0; i < c.M; i += 97)
            for (int64_t j = 0; j < c.N; j += 89) {
                double s = 0;
                for (int64_t k = 0; k < c.K; ++k) s += double(A[size_t(i * c.K + k)]) * B[size_t(k * c.N + j)];
                s += c.beta * C0[size_t(i * c.N + j)];
                REQUIRE(c1[size_t(i * c.N + j)] == Approx(s).epsilon(0).margin(1e-3));
            }
    }
#endif
}
