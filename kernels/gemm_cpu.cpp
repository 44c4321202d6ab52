// SPDX-License-Identifier: MIT
// CPU GEMM. float: our own packed GEMM (GotoBLAS / BLIS layout: op(A) and op(B) are packed into
// MR-row and NR-column micro-panels per K block, and an MR x NR register-blocked micro-kernel
// does the multiply-adds); double (gradient checks, geometry): Eigen's GEBP on fixed tiles.
#include "kernels/gemm.h"

#include <Eigen/Core>
#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <type_traits>

#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__)) || defined(__SSE2__)
#include <immintrin.h>
#endif

#include "core/error.h"
#include "kernels/cpu_util.h"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace g2l::kernels {

namespace {
template <class T>
using RowMat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
template <class T>
using CMap = Eigen::Map<const RowMat<T>, 0, Eigen::OuterStride<>>;
template <class T>
using MMap = Eigen::Map<RowMat<T>, 0, Eigen::OuterStride<>>;

// Products below this many multiply-adds run on one thread (a region costs more than it saves).
constexpr int64_t kParallelMacs = int64_t(1) << 20;

// ---------------------------------------------------------------------------------------------
// The float micro-kernel's vector type, one set per instruction set. The register block is
// MR rows x NR = 2 vectors of C: 24 of the 32 zmm registers on AVX-512, 12 of the 16 ymm/xmm
// registers on AVX2 and SSE2, plus the two B vectors and one broadcast A value.
// The x86 sets differ only in their intrinsics' prefix (and SSE2 has no FMA).
// vrelu(v) = max_ps(0, v) returns v when v is NaN or -0, as std::max(v, 0.f) does.
#define G2L_GEMM_X86_OPS(P)                                               \
    inline vec vload(const float* p) { return P##_loadu_ps(p); }          \
    inline void vstore(float* p, vec v) { P##_storeu_ps(p, v); }          \
    inline vec vset1(float x) { return P##_set1_ps(x); }                  \
    inline vec vzero() { return P##_setzero_ps(); }                       \
    inline vec vadd(vec a, vec b) { return P##_add_ps(a, b); }            \
    inline vec vrelu(vec v) { return P##_max_ps(P##_setzero_ps(), v); }
#if defined(__AVX512F__) && !defined(G2L_GEMM_GENERIC)
using vec = __m512;
constexpr int kVL = 16, kMR = 12;
G2L_GEMM_X86_OPS(_mm512)
inline vec vfma(vec a, vec b, vec c) { return _mm512_fmadd_ps(a, b, c); }
#elif defined(__AVX2__) && defined(__FMA__) && !defined(G2L_GEMM_GENERIC)
using vec = __m256;
constexpr int kVL = 8, kMR = 6;
G2L_GEMM_X86_OPS(_mm256)
inline vec vfma(vec a, vec b, vec c) { return _mm256_fmadd_ps(a, b, c); }
#elif defined(__SSE2__) && !defined(G2L_GEMM_GENERIC)
using vec = __m128;
constexpr int kVL = 4, kMR = 6;
G2L_GEMM_X86_OPS(_mm)
// No FMA on SSE2: the multiply and the add round separately, so an SSE2 build's results
// differ in the last bits from an AVX2 / AVX-512 build's (each build is still deterministic).
inline vec vfma(vec a, vec b, vec c) { return _mm_add_ps(_mm_mul_ps(a, b), c); }
#else  // other targets (or G2L_GEMM_GENERIC, to test this path): GCC/Clang vector extensions
typedef float vec __attribute__((vector_size(16)));
constexpr int kVL = 4, kMR = 6;
inline vec vload(const float* p) { vec v; std::memcpy(&v, p, sizeof v); return v; }
inline void vstore(float* p, vec v) { std::memcpy(p, &v, sizeof v); }
inline vec vset1(float x) { return vec{x, x, x, x}; }
inline vec vzero() { return vec{0, 0, 0, 0}; }
inline vec vfma(vec a, vec b, vec c) { return a * b + c; }
inline vec vadd(vec a, vec b) { return a + b; }
inline vec vrelu(vec v) { return v < vzero() ? vzero() : v; }
#endif
#undef G2L_GEMM_X86_OPS
constexpr int kNV = 2, kNR = kNV * kVL;

// Blocking: a K block of kKC keeps one packed A micro-panel (kMR x kKC) in L1 while the
// micro-kernel walks the B micro-panels of a tile (kKC x kNC, in L2). A C tile is kMC x kNC.
constexpr int64_t kKC = 384, kMC = 8 * kMR, kNC = 16 * kNR, kWantTiles = 8;

// The epilogue of a GEMM without column segments, done by the micro-kernel as it stores the
// last K block: + bias[row], then ReLU (the arithmetic of apply_epilogue, in registers).
struct Finish {
    const float* bias = nullptr;  // this micro-tile's first row's bias, or null
    bool relu = false;
    bool any() const { return bias || relu; }
    vec operator()(vec v, int i) const {
        if (bias) v = vadd(v, vset1(bias[i]));
        return relu ? vrelu(v) : v;
    }
};

// acc = sum_k pa[k][0..MR) (x) pb[k][0..NR) over one K block, then C[0..m, 0..n) += alpha acc
// (= alpha acc + 0 when `overwrite`: C is not read, and its value is the same as on a zeroed C),
// then `fin` on the result.
// Edge tiles (m < MR or n < NR) go through a full-size buffer so that every element of C gets
// the same arithmetic wherever it lies: the result does not depend on how C is partitioned.
void micro_kernel(int64_t kc, const float* pa, const float* pb, float alpha, float* c,
                  int64_t ldc, int m, int n, bool overwrite, const Finish& fin = {}) {
    vec acc[kMR][kNV];
    for (int i = 0; i < kMR; ++i)
        for (int j = 0; j < kNV; ++j) acc[i][j] = vzero();
    for (int64_t k = 0; k < kc; ++k) {
        vec b[kNV];
        for (int j = 0; j < kNV; ++j) b[j] = vload(pb + j * kVL);
        for (int i = 0; i < kMR; ++i) {
            const vec a = vset1(pa[i]);
            for (int j = 0; j < kNV; ++j) acc[i][j] = vfma(a, b[j], acc[i][j]);
        }
        pa += kMR;
        pb += kNR;
    }
    const vec va = vset1(alpha);
    if (m == kMR && n == kNR) {
        for (int i = 0; i < kMR; ++i)
            for (int j = 0; j < kNV; ++j) {
                float* d = c + i * ldc + j * kVL;
                const vec v = vfma(va, acc[i][j], overwrite ? vzero() : vload(d));
                vstore(d, fin.any() ? fin(v, i) : v);
            }
        return;
    }
    alignas(64) float buf[kMR * kNR] = {};
    if (!overwrite)
        for (int i = 0; i < m; ++i) std::memcpy(buf + i * kNR, c + i * ldc, size_t(n) * sizeof(float));
    for (int i = 0; i < m; ++i)  // rows past m are not stored (and have no bias)
        for (int j = 0; j < kNV; ++j) {
            const vec v = vfma(va, acc[i][j], vload(buf + i * kNR + j * kVL));
            vstore(buf + i * kNR + j * kVL, fin.any() ? fin(v, i) : v);
        }
    for (int i = 0; i < m; ++i) std::memcpy(c + i * ldc, buf + i * kNR, size_t(n) * sizeof(float));
}

// Packing. A matrix X of `rows` x K (op(A): rows M; op(B) transposed: rows N) is packed for one
// K block [k0, k0 + kc) into panels of R rows, panel p at dst + p * R * kc laid out [k][R]; rows
// past the end are zero. X is stored either with its rows contiguous (element (r, k) at
// X[k * ld + r]: A transposed, B not) or with K contiguous (X[r * ld + k]: A not transposed,
// B transposed), which needs a transpose.

// Rows contiguous: walks K in the outer loop, so each source row is read front to back.
template <int R>
void pack_rows_contiguous(const float* X, int64_t ld, int64_t rows, int64_t p0, int64_t p1,
                          int64_t k0, int64_t kc, float* dst) {
    for (int64_t k = 0; k < kc; ++k) {
        const float* src = X + (k0 + k) * ld;
        for (int64_t p = p0; p < p1; ++p) {
            const int64_t r = p * R;
            float* d = dst + (p * kc + k) * R;
            if (r + R <= rows) {
                std::memcpy(d, src + r, sizeof(float) * R);  // fixed size: inlined vector moves
            } else {
                const int64_t n = rows - r;
                std::memcpy(d, src + r, size_t(n) * sizeof(float));
                std::memset(d + n, 0, size_t(R - n) * sizeof(float));
            }
        }
    }
}

#if defined(__AVX2__) && !defined(G2L_GEMM_GENERIC)
// dst[j * ld_dst + i] = src[i * ld_src + j] for an 8 x 8 block; rows i >= nr read as zero and
// only the first `nw` floats of each output row are written.
inline void transpose8x8(const float* src, int64_t ld_src, int nr, float* dst, int64_t ld_dst,
                         int nw) {
    __m256 r[8];
    for (int i = 0; i < 8; ++i) r[i] = i < nr ? _mm256_loadu_ps(src + i * ld_src) : _mm256_setzero_ps();
    __m256 t[8], u[8];
    for (int i = 0; i < 8; i += 2) {
        t[i] = _mm256_unpacklo_ps(r[i], r[i + 1]);
        t[i + 1] = _mm256_unpackhi_ps(r[i], r[i + 1]);
    }
    for (int i = 0; i < 8; i += 4) {
        u[i] = _mm256_shuffle_ps(t[i], t[i + 2], _MM_SHUFFLE(1, 0, 1, 0));
        u[i + 1] = _mm256_shuffle_ps(t[i], t[i + 2], _MM_SHUFFLE(3, 2, 3, 2));
        u[i + 2] = _mm256_shuffle_ps(t[i + 1], t[i + 3], _MM_SHUFFLE(1, 0, 1, 0));
        u[i + 3] = _mm256_shuffle_ps(t[i + 1], t[i + 3], _MM_SHUFFLE(3, 2, 3, 2));
    }
    for (int j = 0; j < 4; ++j) {
        const __m256 lo = _mm256_permute2f128_ps(u[j], u[j + 4], 0x20);
        const __m256 hi = _mm256_permute2f128_ps(u[j], u[j + 4], 0x31);
        if (nw == 8) {
            _mm256_storeu_ps(dst + j * ld_dst, lo);
            _mm256_storeu_ps(dst + (j + 4) * ld_dst, hi);
        } else if (nw == 4) {
            _mm_storeu_ps(dst + j * ld_dst, _mm256_castps256_ps128(lo));
            _mm_storeu_ps(dst + (j + 4) * ld_dst, _mm256_castps256_ps128(hi));
        } else {
            alignas(32) float tmp[8];
            _mm256_store_ps(tmp, lo);
            std::memcpy(dst + j * ld_dst, tmp, size_t(nw) * sizeof(float));
            _mm256_store_ps(tmp, hi);
            std::memcpy(dst + (j + 4) * ld_dst, tmp, size_t(nw) * sizeof(float));
        }
    }
}
#endif

// K contiguous: a panel's R source rows are read together, 8 rows x 8 k at a time, and
// transposed in registers (AVX2); scalar for the tails and on other targets.
template <int R>
void pack_k_contiguous(const float* X, int64_t ld, int64_t rows, int64_t p0, int64_t p1,
                       int64_t k0, int64_t kc, float* dst) {
    for (int64_t p = p0; p < p1; ++p) {
        const int64_t r = p * R;
        const int n = int(std::min<int64_t>(R, rows - r));
        const float* src = X + r * ld + k0;
        float* d = dst + p * kc * R;
        int64_t k = 0;
#if defined(__AVX2__) && !defined(G2L_GEMM_GENERIC)
        for (; k + 8 <= kc; k += 8)
            for (int i0 = 0; i0 < R; i0 += 8)
                transpose8x8(src + i0 * ld + k, ld, std::max(0, std::min(8, n - i0)),
                             d + k * R + i0, R, std::min(8, R - i0));
#endif
        for (; k < kc; ++k)
            for (int i = 0; i < R; ++i) d[k * R + i] = i < n ? src[i * ld + k] : 0.f;
    }
}

// Packs panels [p0, p1) of op(A) (R = kMR) or of op(B) seen as its transpose (R = kNR).
template <int R>
void pack_panels(bool rows_contiguous, const float* X, int64_t ld, int64_t rows, int64_t p0,
                 int64_t p1, int64_t k0, int64_t kc, float* dst) {
    if (rows_contiguous) pack_rows_contiguous<R>(X, ld, rows, p0, p1, k0, kc, dst);
    else pack_k_contiguous<R>(X, ld, rows, p0, p1, k0, kc, dst);
}

// The calling thread's share [lo, hi) of n items among its team (contiguous, equal to within one).
void share(int64_t n, int64_t* lo, int64_t* hi) {
    int64_t t = 0, nt = 1;
#ifdef _OPENMP
    t = omp_get_thread_num(), nt = omp_get_num_threads();
#endif
    *lo = n * t / nt;
    *hi = n * (t + 1) / nt;
}

// The packing buffers of the calling thread, grown on demand, 64-byte aligned. In sgemm_packed
// the OpenMP workers share the caller's buffers; in sgemm_prepacked each thread packs into its
// own; two user threads calling gemm at once each have their own.
float* scratch(int which, size_t floats) {
    struct Buf {
        std::unique_ptr<float, decltype(&std::free)> p{nullptr, &std::free};
        size_t n = 0;
    };
    thread_local Buf bufs[2];
    Buf& b = bufs[which];
    if (b.n < floats) {
        // aligned_alloc requires a size that is a multiple of the alignment.
        const size_t bytes = ((floats * sizeof(float) + 63) / 64) * 64;
        b.p.reset(static_cast<float*>(std::aligned_alloc(64, bytes)));
        G2L_CHECK(b.p != nullptr, "gemm_cpu: out of memory for a ", bytes, "-byte packing buffer");
        b.n = floats;
    }
    return b.p.get();
}

// One float product (or a batch of them sharing op(A)):
//   C_b = alpha op(A) op(B_b) (+ C_b unless `overwrite`) for b < batch, X_b = X + b * stride_x,
// then the epilogue on each finished tile (bias, ReLU; while the tile is in cache).
struct Sgemm {
    bool trans_a = false, trans_b = false;
    int64_t M = 0, N = 0, K = 0;
    float alpha = 1.f;
    const float* A = nullptr;
    int64_t lda = 0;
    const float* prepacked = nullptr;  // op(A) already in panels (sgemm_prepacked only)
    const float* B = nullptr;
    int64_t ldb = 0, stride_b = 0;
    float* C = nullptr;
    int64_t ldc = 0, stride_c = 0;
    int64_t batch = 1;
    bool overwrite = false;  // beta == 0: the first K block stores instead of adding to C
    const GemmEpilogue* ep = nullptr;
};

// Packed B of a group of batch items up to this size: the group's panels are shared out in
// one barrier, and stay in the last-level cache.
constexpr int64_t kBatchPackFloats = int64_t(2) << 20;

// The epilogue on C rows [r0, r1) x columns [c0, c1).
void apply_epilogue(const GemmEpilogue& ep, int64_t M, float* C, int64_t ldc, int64_t r0,
                    int64_t r1, int64_t c0, int64_t c1) {
    const int64_t segs = ep.segments ? ep.num_segments : 1;
    for (int64_t s = 0; s < segs; ++s) {
        const int64_t a = ep.segments ? std::max(c0, ep.segments[s]) : c0;
        const int64_t z = ep.segments ? std::min(c1, ep.segments[s + 1]) : c1;
        if (a >= z) continue;
        for (int64_t r = r0; r < r1; ++r) {
            float* row = C + r * ldc;
            const float b = ep.bias ? ep.bias[s * M + r] : 0.f;
            if (ep.relu)
                for (int64_t n = a; n < z; ++n) row[n] = std::max(row[n] + b, 0.f);
            else
                for (int64_t n = a; n < z; ++n) row[n] += b;
        }
    }
}

// An epilogue without column segments (or with one) is done by the micro-kernel.
bool fusable(const GemmEpilogue* ep) {
    return ep && (ep->segments == nullptr || ep->num_segments == 1);
}
Finish finish(const GemmEpilogue& ep, int64_t r0) {
    return Finish{ep.bias ? ep.bias + r0 : nullptr, ep.relu};
}

std::atomic<uint64_t> g_sgemm_flops{0};  // sgemm_flops_done()
void count_flops(const Sgemm& g) {
    g_sgemm_flops.fetch_add(2 * uint64_t(g.M) * uint64_t(g.N) * uint64_t(g.K) * uint64_t(g.batch),
                            std::memory_order_relaxed);
}

// One K block of C's row panels [p0, p1) x column panels [q0, q1): pa holds the block's A
// panels, pb B's panels from q0 on. In the last K block each row panel is finished by the
// micro-kernel, or by apply_epilogue when the epilogue has column segments.
void run_block(const Sgemm& g, float* C, const float* pa, const float* pb, int64_t kc,
               int64_t p0, int64_t p1, int64_t q0, int64_t q1, bool first, bool last) {
    const bool fused = fusable(g.ep);
    for (int64_t p = p0; p < p1; ++p) {
        const int64_t r0 = p * kMR;
        const int m = int(std::min<int64_t>(kMR, g.M - r0));
        for (int64_t q = q0; q < q1; ++q)
            micro_kernel(kc, pa + p * kMR * kc, pb + (q - q0) * kNR * kc, g.alpha,
                         C + r0 * g.ldc + q * kNR, g.ldc, m,
                         int(std::min<int64_t>(kNR, g.N - q * kNR)), first,
                         last && fused ? finish(*g.ep, r0) : Finish{});
        if (last && g.ep && !fused)
            apply_epilogue(*g.ep, g.M, C, g.ldc, r0, r0 + m, q0 * kNR, std::min(g.N, q1 * kNR));
    }
}

void sgemm_packed(const Sgemm& g) {
    count_flops(g);
    const int64_t M = g.M, N = g.N, K = g.K;
    const int64_t pm = ceil_div(M, kMR), pn = ceil_div(N, kNR);  // micro-panels
    const int64_t kc_max = std::min(K, kKC);
    const int64_t group = std::clamp<int64_t>(kBatchPackFloats / (pn * kNR * kc_max), 1, g.batch);
    float* pa = scratch(0, size_t(pm * kMR * kc_max));
    float* pb = scratch(1, size_t(group * pn * kNR * kc_max));
    // Tiles of C: kMC x kNC, narrowed (width first) on a small product until there are
    // kWantTiles of them per batch group, so that the threads' shares come out even (3 tiles on
    // 2 threads leave one idle a third of the time: a batch-1 layer of 64 x 1500). Each
    // element's sum runs over the same K blocks in the same order whatever the tile, so the
    // partition (and the thread count) never changes a bit of the result.
    int64_t tpm = kMC / kMR, tpn = kNC / kNR;  // micro-panels per tile
    auto count = [&] { return ceil_div(pm, tpm) * ceil_div(pn, tpn) * group; };
    while (count() < kWantTiles && (tpn > 1 || tpm > 1)) {
        if (tpn > 1) tpn = (tpn + 1) / 2;
        else tpm = (tpm + 1) / 2;
    }
    const int64_t tn = ceil_div(pn, tpn), tiles = ceil_div(pm, tpm) * tn;
    [[maybe_unused]] const bool parallel = M * N * K * g.batch > kParallelMacs;
#pragma omp parallel if (parallel)
    {
        // K blocks are the outer loop for every thread: each C element adds its K blocks in the
        // same order whatever tile or thread computes it.
        for (int64_t k0 = 0; k0 < K; k0 += kKC) {
            const int64_t kc = std::min(kKC, K - k0);
            const bool first = k0 == 0 && g.overwrite, last = k0 + kc >= K;
            int64_t lo, hi;
            share(pm, &lo, &hi);
            // Each thread packs its share of A's panels; the barrier below publishes them with B's.
            pack_panels<kMR>(g.trans_a, g.A, g.lda, M, lo, hi, k0, kc, pa);
            for (int64_t b0 = 0; b0 < g.batch; b0 += group) {
                const int64_t nb = std::min(group, g.batch - b0);
                // This thread's share of the group's nb * pn panels, item by item.
                share(nb * pn, &lo, &hi);
                for (int64_t i = b0; i < b0 + nb; ++i) {
                    const int64_t base = (i - b0) * pn;
                    const int64_t q0 = std::max(lo, base) - base, q1 = std::min(hi, base + pn) - base;
                    if (q0 < q1)
                        pack_panels<kNR>(!g.trans_b, g.B + i * g.stride_b, g.ldb, N, q0, q1, k0,
                                         kc, pb + base * kNR * kc);
                }
                // Every packed panel must be complete before any thread's tiles read it.
#pragma omp barrier
                // Dynamic is safe: a tile's arithmetic does not depend on the thread that
                // runs it. The implicit barrier at the end of this loop keeps the next
                // group's or K block's packing from overwriting panels still being read.
#pragma omp for schedule(dynamic)
                for (int64_t job = 0; job < nb * tiles; ++job) {
                    const int64_t i = job / tiles, tile = job % tiles;
                    const int64_t p0 = (tile / tn) * tpm, p1 = std::min(pm, p0 + tpm);
                    const int64_t q0 = (tile % tn) * tpn, q1 = std::min(pn, q0 + tpn);
                    run_block(g, g.C + (b0 + i) * g.stride_c, pa, pb + (i * pn + q0) * kNR * kc,
                              kc, p0, p1, q0, q1, first, last);
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// double: Eigen's GEBP on tiles of C whose size depends only on the shape, Eigen itself kept
// single-threaded (its own threading picks its K blocking from the thread count), so results
// are bitwise identical for any thread count.
constexpr int64_t kTileM = 512, kTileN = 512;

void dgemm_tile(bool trans_a, bool trans_b, int64_t i0, int64_t m, int64_t j0, int64_t n,
                int64_t K, double alpha, const double* A, int64_t lda, const double* B,
                int64_t ldb, double* C, int64_t ldc) {
    MMap<double> c(C + i0 * ldc + j0, m, n, Eigen::OuterStride<>(ldc));
    // op(A) rows i0.. : A + i0*lda (not transposed) or A + i0 (transposed, A stored [K, M]).
    // op(B) cols j0.. : B + j0 (not transposed) or B + j0*ldb (transposed, B stored [N, K]).
    using M_ = CMap<double>;
    if (!trans_a && !trans_b) {
        c.noalias() += alpha * (M_(A + i0 * lda, m, K, Eigen::OuterStride<>(lda)) *
                                M_(B + j0, K, n, Eigen::OuterStride<>(ldb)));
    } else if (trans_a && !trans_b) {
        c.noalias() += alpha * (M_(A + i0, K, m, Eigen::OuterStride<>(lda)).transpose() *
                                M_(B + j0, K, n, Eigen::OuterStride<>(ldb)));
    } else if (!trans_a && trans_b) {
        c.noalias() += alpha * (M_(A + i0 * lda, m, K, Eigen::OuterStride<>(lda)) *
                                M_(B + j0 * ldb, n, K, Eigen::OuterStride<>(ldb)).transpose());
    } else {
        c.noalias() += alpha * (M_(A + i0, K, m, Eigen::OuterStride<>(lda)).transpose() *
                                M_(B + j0 * ldb, n, K, Eigen::OuterStride<>(ldb)).transpose());
    }
}

void dgemm_tiled(bool trans_a, bool trans_b, int64_t M, int64_t N, int64_t K, double alpha,
                 const double* A, int64_t lda, const double* B, int64_t ldb, double* C,
                 int64_t ldc) {
    static const bool single = [] { Eigen::setNbThreads(1); return true; }();
    (void)single;
    const int64_t tn = ceil_div(N, kTileN), tiles = ceil_div(M, kTileM) * tn;
    [[maybe_unused]] const bool parallel = tiles > 1 && M * N * K > kParallelMacs;
#pragma omp parallel for schedule(dynamic) if (parallel)
    for (int64_t t = 0; t < tiles; ++t) {
        const int64_t i0 = (t / tn) * kTileM, j0 = (t % tn) * kTileN;
        dgemm_tile(trans_a, trans_b, i0, std::min(kTileM, M - i0), j0, std::min(kTileN, N - j0),
                   K, alpha, A, lda, B, ldb, C, ldc);
    }
}

}  // namespace

template <class T>
void gemm_cpu(bool trans_a, bool trans_b, int64_t M, int64_t N, int64_t K, T alpha, const T* A,
              int64_t lda, const T* B, int64_t ldb, T beta, T* C, int64_t ldc) {
    gemm_batched_cpu<T>(trans_a, trans_b, M, N, K, alpha, A, lda, B, ldb, 0, beta, C, ldc, 0, 1);
}

template <class T>
void gemm_batched_cpu(bool trans_a, bool trans_b, int64_t M, int64_t N, int64_t K, T alpha,
                      const T* A, int64_t lda, const T* B, int64_t ldb, int64_t stride_b, T beta,
                      T* C, int64_t ldc, int64_t stride_c, int64_t batch,
                      const GemmEpilogue* epilogue) {
    if (M == 0 || N == 0 || batch == 0) return;
    if constexpr (std::is_same_v<T, float>) {
        // The packed kernel can only overwrite (beta 0) or add (beta 1); other betas scale C first.
        if (beta != 0.f && beta != 1.f)
            for (int64_t b = 0; b < batch; ++b)
                MMap<T>(C + b * stride_c, M, N, Eigen::OuterStride<>(ldc)) *= beta;
        if (K == 0) {  // no product: C = beta C (then the epilogue)
            for (int64_t b = 0; b < batch; ++b) {
                if (beta == 0.f) MMap<T>(C + b * stride_c, M, N, Eigen::OuterStride<>(ldc)).setZero();
                if (epilogue) apply_epilogue(*epilogue, M, C + b * stride_c, ldc, 0, M, 0, N);
            }
            return;
        }
        Sgemm g;
        g.trans_a = trans_a, g.trans_b = trans_b, g.M = M, g.N = N, g.K = K, g.alpha = alpha;
        g.A = A, g.lda = lda, g.B = B, g.ldb = ldb, g.stride_b = stride_b;
        g.C = C, g.ldc = ldc, g.stride_c = stride_c, g.batch = batch;
        // beta == 0 must not read C (BLAS convention): C is often fresh, uninitialised memory, and
        // 0 * NaN would be NaN.
        g.overwrite = beta == 0.f, g.ep = epilogue;
        sgemm_packed(g);
    } else {
        G2L_CHECK(epilogue == nullptr, "gemm_batched_cpu: the epilogue is float-only");
        for (int64_t b = 0; b < batch; ++b) {
            T* Cb = C + b * stride_c;
            MMap<T> c(Cb, M, N, Eigen::OuterStride<>(ldc));
            // setZero, not c *= 0, for the same reason: C may hold uninitialised NaNs.
            if (beta == T(0)) c.setZero();
            else if (beta != T(1)) c *= beta;
            if (K > 0) dgemm_tiled(trans_a, trans_b, M, N, K, alpha, A, lda, B + b * stride_b, ldb, Cb, ldc);
        }
    }
}

// C = op(A) B with op(A) packed beforehand (PackedGemmA): each thread takes its own columns
// of C (whole micro-panels), packs its own panels of B and runs every row of A over them, so no
// thread ever waits for another between K blocks. A thread's columns go in chunks of kNC (their
// packed B stays in L2); each row panel gets the epilogue once its last K block is done.
void sgemm_prepacked(const Sgemm& g) {
    count_flops(g);
    const int64_t M = g.M, N = g.N, K = g.K;
    const int64_t pm = ceil_div(M, kMR), pn = ceil_div(N, kNR), tpn = kNC / kNR;
    [[maybe_unused]] const bool parallel = M * N * K > kParallelMacs;
#pragma omp parallel if (parallel)
    {
        int64_t lo, hi;
        share(pn, &lo, &hi);
        // scratch() is thread_local, so each thread here gets its own B panel buffer.
        float* pb = scratch(1, size_t(std::min(tpn, hi - lo) * kNR * std::min(K, kKC)));
        for (int64_t q0 = lo; q0 < hi; q0 += tpn) {
            const int64_t q1 = std::min(hi, q0 + tpn), c0 = q0 * kNR, c1 = std::min(N, q1 * kNR);
            for (int64_t k0 = 0; k0 < K; k0 += kKC) {
                const int64_t kc = std::min(kKC, K - k0);
                const bool first = k0 == 0, last = k0 + kc >= K;
                pack_panels<kNR>(true, g.B + c0, g.ldb, c1 - c0, 0, q1 - q0, k0, kc, pb);
                run_block(g, g.C, g.prepacked + pm * kMR * k0, pb, kc, 0, pm, q0, q1, first, last);
            }
        }
    }
}

uint64_t sgemm_flops_done() { return g_sgemm_flops.load(std::memory_order_relaxed); }

PackedGemmA::PackedGemmA(bool trans_a, int64_t M, int64_t K, const float* A, int64_t lda)
    : M_(M), K_(K) {
    G2L_CHECK(M > 0 && K > 0, "PackedGemmA: an empty matrix (", M, " x ", K, ")");
    const int64_t pm = ceil_div(M, kMR);
    data_.resize(size_t(pm * kMR * K));
    for (int64_t k0 = 0; k0 < K; k0 += kKC)  // K block k0 at pm * kMR * k0, as sgemm_prepacked reads it
        pack_panels<kMR>(trans_a, A, lda, M, 0, pm, k0, std::min(kKC, K - k0),
                         data_.data() + pm * kMR * k0);
}

void gemm_packed_a_cpu(const PackedGemmA& a, int64_t N, const float* B, int64_t ldb, float* C,
                       int64_t ldc, const GemmEpilogue* epilogue) {
    G2L_CHECK(!a.empty(), "gemm_packed_a_cpu: an empty PackedGemmA");
    if (N == 0) return;
    Sgemm g;
    g.M = a.rows(), g.N = N, g.K = a.cols(), g.prepacked = a.data_.data();
    g.B = B, g.ldb = ldb, g.C = C, g.ldc = ldc, g.overwrite = true, g.ep = epilogue;
    sgemm_prepacked(g);
}

template void gemm_cpu<float>(bool, bool, int64_t, int64_t, int64_t, float, const float*,
                              int64_t, const float*, int64_t, float, float*, int64_t);
template void gemm_cpu<double>(bool, bool, int64_t, int64_t, int64_t, double, const double*,
                               int64_t, const double*, int64_t, double, double*, int64_t);
template void gemm_batched_cpu<float>(bool, bool, int64_t, int64_t, int64_t, float, const float*,
                                      int64_t, const float*, int64_t, int64_t, float, float*,
                                      int64_t, int64_t, int64_t, const GemmEpilogue*);
template void gemm_batched_cpu<double>(bool, bool, int64_t, int64_t, int64_t, double,
                                       const double*, int64_t, const double*, int64_t, int64_t,
                                       double, double*, int64_t, int64_t, int64_t,
                                       const GemmEpilogue*);

}  // namespace g2l::kernels
