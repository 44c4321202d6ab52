// SPDX-License-Identifier: MIT
// gemm_cpu against a plain double-precision reference, for every transpose combination, with
// leading dimensions larger than the rows, alpha and beta, on shapes that span several C tiles
// and K blocks with partial micro-panels at every edge (float: 12 or 6 rows x 2 vectors, K blocks
// of 384; double: 512 x 512 tiles); and 1 vs 2 threads bitwise.
#include <catch2/catch.hpp>
#include <algorithm>
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
        if (c.beta == 0.f) {  // the prepacked product (columns per thread) and a batch of 2
            const kernels::PackedGemmA pa(false, c.M, c.K, A.data(), c.K);
            std::vector<float> p1(C0.size()), p2(C0.size()), b1(2 * C0.size()), b2(2 * C0.size());
            const auto B2 = rnd<float>(size_t(2 * c.K * c.N), 17);
            for (const int nt : {1, 2}) {
                omp_set_num_threads(nt);
                kernels::gemm_packed_a_cpu(pa, c.N, B.data(), c.N, (nt == 1 ? p1 : p2).data(), c.N);
                kernels::gemm_batched_cpu<float>(false, false, c.M, c.N, c.K, 1.f, A.data(), c.K,
                                                 B2.data(), c.N, c.K * c.N, 0.f,
                                                 (nt == 1 ? b1 : b2).data(), c.N, c.M * c.N, 2);
            }
            omp_set_num_threads(prev);
            CHECK(std::memcmp(p1.data(), p2.data(), p1.size() * sizeof(float)) == 0);
            CHECK(std::memcmp(p1.data(), c1.data(), p1.size() * sizeof(float)) == 0);
            CHECK(std::memcmp(b1.data(), b2.data(), b1.size() * sizeof(float)) == 0);
        }
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

TEST_CASE("gemm_batched_cpu equals one gemm_cpu per batch item, bitwise", "[kernels][gemm]") {
    // Shapes of a 1x1 convolution's forward and dx (op(A) shared by the batch), a batch packed
    // in two groups (5 + 2 items of 8 MB of panels), one K block and three, beta 0, 1 and 0.5;
    // and double.
    struct Case { bool ta; int64_t M, N, K, batch; float beta; };
    for (const Case c : {Case{false, 64, 1500, 64, 8, 0.f}, Case{true, 40, 1000, 900, 3, 0.5f},
                         Case{false, 100, 1000, 500, 7, 1.f}, Case{false, 5, 3, 2, 2, 0.f}}) {
        INFO("trans_a " << c.ta << " M " << c.M << " N " << c.N << " K " << c.K << " batch "
                        << c.batch << " beta " << c.beta);
        const int64_t lda = c.ta ? c.M : c.K, sb = c.K * c.N + 11, sc = c.M * c.N + 7;
        const auto A = rnd<float>(size_t(c.M * c.K), 7), B = rnd<float>(size_t(sb * c.batch), 8);
        const auto C0 = rnd<float>(size_t(sc * c.batch), 9);
        std::vector<float> one = C0, batched = C0;
        for (int64_t b = 0; b < c.batch; ++b)
            kernels::gemm_cpu<float>(c.ta, false, c.M, c.N, c.K, 0.75f, A.data(), lda,
                                     B.data() + b * sb, c.N, c.beta, one.data() + b * sc, c.N);
        kernels::gemm_batched_cpu<float>(c.ta, false, c.M, c.N, c.K, 0.75f, A.data(), lda,
                                         B.data(), c.N, sb, c.beta, batched.data(), c.N, sc,
                                         c.batch);
        CHECK(std::memcmp(one.data(), batched.data(), one.size() * sizeof(float)) == 0);
        // And each item is its own product (a wrong stride would give another item's).
        const int64_t b = c.batch - 1, i = c.M - 1, j = c.N / 2;
        double s = 0;
        for (int64_t k = 0; k < c.K; ++k)
            s += double(c.ta ? A[size_t(k * lda + i)] : A[size_t(i * lda + k)]) *
                 B[size_t(b * sb + k * c.N + j)];
        const double want = 0.75 * s + c.beta * C0[size_t(b * sc + i * c.N + j)];
        CHECK(batched[size_t(b * sc + i * c.N + j)] == Approx(want).margin(1e-4));
        // The gaps between the items' C are not written.
        CHECK(batched[size_t(sc - 1)] == C0[size_t(sc - 1)]);
    }
    const auto A = rnd<double>(6 * 5, 10), B = rnd<double>(2 * 5 * 4, 11);
    std::vector<double> one(2 * 6 * 4, 1.0), batched = one;
    for (int64_t b = 0; b < 2; ++b)
        kernels::gemm_cpu<double>(false, false, 6, 4, 5, 2.0, A.data(), 5, B.data() + b * 20, 4,
                                  0.5, one.data() + b * 24, 4);
    kernels::gemm_batched_cpu<double>(false, false, 6, 4, 5, 2.0, A.data(), 5, B.data(), 4, 20,
                                      0.5, batched.data(), 4, 24, 2);
    CHECK(one == batched);
}

TEST_CASE("gemm epilogue: bias per row or per column segment, ReLU, on every tile",
          "[kernels][gemm]") {
    // No segments and one (done in the micro-kernel's stores) and three (a pass over each
    // finished tile); shapes with one tile, many tiles and partial edges; K 0 (C = bias only).
    for (const int64_t K : {int64_t(0), int64_t(3), int64_t(500)})
        for (const int64_t N : {int64_t(37), int64_t(1500)})
            for (const int segments : {0, 1, 3})
                for (const bool relu : {false, true}) {
                    const int64_t M = 50;
                    INFO("K " << K << " N " << N << " segments " << segments << " relu " << relu);
                    const auto A = rnd<float>(size_t(M * std::max<int64_t>(K, 1)), 12);
                    const auto B = rnd<float>(size_t(std::max<int64_t>(K, 1) * N), 13);
                    const std::vector<int64_t> seg =
                        segments == 3 ? std::vector<int64_t>{0, 5, N / 2, N} : std::vector<int64_t>{0, N};
                    const auto bias = rnd<float>(size_t(3 * M), 14);
                    kernels::GemmEpilogue ep;
                    ep.bias = bias.data();
                    ep.relu = relu;
                    if (segments) ep.segments = seg.data(), ep.num_segments = segments;
                    std::vector<float> plain(size_t(M * N), 7.f), fused(size_t(M * N), 7.f);
                    kernels::gemm_cpu<float>(false, false, M, N, K, 1.f, A.data(), K, B.data(), N,
                                             0.f, plain.data(), N);
                    for (int64_t r = 0; r < M; ++r)
                        for (int64_t n = 0; n < N; ++n) {
                            const int64_t s = segments < 3 ? 0 : n < 5 ? 0 : n < N / 2 ? 1 : 2;
                            float& v = plain[size_t(r * N + n)];
                            v += bias[size_t(s * M + r)];
                            if (relu) v = std::max(v, 0.f);
                        }
                    kernels::gemm_batched_cpu<float>(false, false, M, N, K, 1.f, A.data(), K,
                                                     B.data(), N, 0, 0.f, fused.data(), N, 0, 1, &ep);
                    CHECK(std::memcmp(plain.data(), fused.data(), plain.size() * sizeof(float)) == 0);
                    if (K > 0) {
                        std::vector<float> packed(size_t(M * N), 7.f);
                        const kernels::PackedGemmA pa(false, M, K, A.data(), K);
                        kernels::gemm_packed_a_cpu(pa, N, B.data(), N, packed.data(), N, &ep);
                        CHECK(std::memcmp(plain.data(), packed.data(), plain.size() * sizeof(float)) == 0);
                    }
                    // ReLU clipped something (and only with relu), and not everything.
                    const auto zeros = std::count(fused.begin(), fused.end(), 0.f);
                    CHECK((zeros > 0) == relu);
                    CHECK(zeros < int64_t(fused.size()));
                }
}

TEST_CASE("gemm epilogue: a NaN stays NaN through the bias and the ReLU, fused or not",
          "[kernels][gemm]") {
    // A NaN in B makes its column NaN; ReLU must not turn it into 0 (std::max(NaN, 0) is NaN).
    const int64_t M = 13, N = 40, K = 2;
    auto B = rnd<float>(size_t(K * N), 18);
    B[3] = std::nanf("");
    const auto A = rnd<float>(size_t(M * K), 19), bias = rnd<float>(size_t(2 * M), 20);
    const std::vector<int64_t> seg = {0, 20, N};
    for (const int segments : {0, 2}) {
        kernels::GemmEpilogue ep;
        ep.bias = bias.data();
        ep.relu = true;
        if (segments) ep.segments = seg.data(), ep.num_segments = segments;
        std::vector<float> c(size_t(M * N));
        kernels::gemm_batched_cpu<float>(false, false, M, N, K, 1.f, A.data(), K, B.data(), N, 0,
                                         0.f, c.data(), N, 0, 1, &ep);
        for (int64_t r = 0; r < M; ++r) {
            CHECK(std::isnan(c[size_t(r * N + 3)]));
            CHECK(c[size_t(r * N + 4)] >= 0.f);
        }
    }
}

TEST_CASE("PackedGemmA: the packed product equals gemm_cpu bitwise, and bad input throws",
          "[kernels][gemm]") {
    // Both storage orders of A, 1 K block and 3 (the last partial), M not a multiple of the
    // micro-kernel's rows, N of one column and of many tiles; ld larger than the row.
    struct Case { bool ta; int64_t M, N, K; };
    for (const Case c : {Case{false, 64, 1500, 3}, Case{false, 1024, 1000, 128},
                         Case{true, 37, 1, 900}, Case{false, 13, 700, 1152}}) {
        INFO("trans_a " << c.ta << " M " << c.M << " N " << c.N << " K " << c.K);
        const int64_t lda = (c.ta ? c.M : c.K) + 3, ldb = c.N + 2;
        const auto A = rnd<float>(size_t((c.ta ? c.K : c.M) * lda), 15);
        const auto B = rnd<float>(size_t(c.K * ldb), 16);
        std::vector<float> ref(size_t(c.M * ldb), 3.f), got = ref;
        kernels::gemm_cpu<float>(c.ta, false, c.M, c.N, c.K, 1.f, A.data(), lda, B.data(), ldb,
                                 0.f, ref.data(), ldb);
        const kernels::PackedGemmA pa(c.ta, c.M, c.K, A.data(), lda);
        CHECK(pa.rows() == c.M);
        CHECK(pa.cols() == c.K);
        kernels::gemm_packed_a_cpu(pa, c.N, B.data(), ldb, got.data(), ldb);
        CHECK(std::memcmp(ref.data(), got.data(), ref.size() * sizeof(float)) == 0);
        CHECK(got[size_t(c.N)] == 3.f);  // the padding after row 0 is not written
        double s = 0;
        for (int64_t k = 0; k < c.K; ++k)
            s += double(c.ta ? A[size_t(k * lda)] : A[size_t(k)]) * B[size_t(k * ldb)];
        CHECK(got[0] == Approx(s).margin(1e-4));
    }
    const float one = 1.f;
    CHECK_THROWS_WITH(kernels::PackedGemmA(false, 0, 4, &one, 4),
                      Catch::Contains("empty matrix (0 x 4)"));
    float c = 0.f;
    CHECK_THROWS_WITH(kernels::gemm_packed_a_cpu(kernels::PackedGemmA(), 1, &one, 1, &c, 1),
                      Catch::Contains("empty PackedGemmA"));
    kernels::GemmEpilogue ep;
    ep.relu = true;
    CHECK_THROWS_WITH(kernels::gemm_batched_cpu<double>(false, false, 1, 1, 1, 1.0, nullptr, 1,
                                                        nullptr, 1, 0, 0.0, nullptr, 1, 0, 1, &ep),
                      Catch::Contains("float-only"));
}

TEST_CASE("sgemm_flops_done counts 2 M N K per float product, batches and prepacked ones too",
          "[kernels][gemm]") {
    const auto A = rnd<float>(6 * 5, 21), B = rnd<float>(3 * 5 * 4, 22);
    std::vector<float> C(3 * 6 * 4);
    uint64_t before = kernels::sgemm_flops_done();
    kernels::gemm_cpu<float>(false, false, 6, 4, 5, 1.f, A.data(), 5, B.data(), 4, 0.f, C.data(), 4);
    CHECK(kernels::sgemm_flops_done() - before == 2 * 6 * 4 * 5);
    before = kernels::sgemm_flops_done();
    kernels::gemm_batched_cpu<float>(false, false, 6, 4, 5, 1.f, A.data(), 5, B.data(), 4, 20, 0.f,
                                     C.data(), 4, 24, 3);
    CHECK(kernels::sgemm_flops_done() - before == 3 * 2 * 6 * 4 * 5);
    before = kernels::sgemm_flops_done();
    kernels::gemm_packed_a_cpu(kernels::PackedGemmA(false, 6, 5, A.data(), 5), 4, B.data(), 4,
                               C.data(), 4);
    CHECK(kernels::sgemm_flops_done() - before == 2 * 6 * 4 * 5);
    before = kernels::sgemm_flops_done();  // double products and empty ones are not counted
    const std::vector<double> Ad(30, 1.0), Bd(20, 1.0);
    std::vector<double> Cd(24);
    kernels::gemm_cpu<double>(false, false, 6, 4, 5, 1.0, Ad.data(), 5, Bd.data(), 4, 0.0, Cd.data(), 4);
    kernels::gemm_cpu<float>(false, false, 6, 4, 0, 1.f, A.data(), 5, B.data(), 4, 0.f, C.data(), 4);
    CHECK(kernels::sgemm_flops_done() == before);
}
