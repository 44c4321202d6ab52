// SPDX-License-Identifier: MIT
#include "kernels/shape.h"

#include <algorithm>

namespace g2l::kernels {

namespace {
constexpr int64_t kParallelMin = 32768;
constexpr int64_t kBlock = 256;
}  // namespace

template <class T>
void copy_slab_cpu(const T* src, int64_t src_D, int64_t src_off, T* dst, int64_t dst_D,
                   int64_t dst_off, int64_t outer, int64_t len, int64_t inner) {
    const int64_t w = len * inner;  // one contiguous run per o
#pragma omp parallel for schedule(static) if (outer * w > kParallelMin)
    for (int64_t o = 0; o < outer; ++o) {
        const T* s = src + (o * src_D + src_off) * inner;
        std::copy(s, s + w, dst + (o * dst_D + dst_off) * inner);
    }
}

template <class T>
void permute_cpu(const T* x, const std::vector<int64_t>& x_shape, const std::vector<int64_t>& perm,
                 T* y) {
    const int64_t r = int64_t(x_shape.size());
    int64_t n = 1;
    for (int64_t s : x_shape) n *= s;
    if (n == 0) return;
    if (r == 0) {
        y[0] = x[0];
        return;
    }
    const size_t rr = static_cast<size_t>(r);
    std::vector<int64_t> x_stride(rr, 1), y_shape(rr), y_in_stride(rr);
    for (int64_t k = r - 2; k >= 0; --k)
        x_stride[size_t(k)] = x_stride[size_t(k + 1)] * x_shape[size_t(k + 1)];
    for (int64_t k = 0; k < r; ++k) {
        y_shape[size_t(k)] = x_shape[size_t(perm[size_t(k)])];
        y_in_stride[size_t(k)] = x_stride[size_t(perm[size_t(k)])];
    }
    // Walk y row by row (its last dimension); the source offset of each row comes from its
    // multi-index, and the inner loop reads x with a fixed stride.
    const int64_t inner = y_shape[size_t(r - 1)], step = y_in_stride[size_t(r - 1)];
    const int64_t rows = n / inner;
#pragma omp parallel for schedule(static) if (n > kParallelMin)
    for (int64_t row = 0; row < rows; ++row) {
        int64_t off = 0, rem = row;
        for (int64_t k = r - 2; k >= 0; --k) {
            off += (rem % y_shape[size_t(k)]) * y_in_stride[size_t(k)];
            rem /= y_shape[size_t(k)];
        }
        const T* s = x + off;
        T* d = y + row * inner;
        for (int64_t i = 0; i < inner; ++i) d[i] = s[i * step];
    }
}

template <class T>
void index_select_fwd_cpu(const T* x, const int32_t* idx, int64_t L, T* y, int64_t outer, int64_t D,
                          int64_t inner) {
#pragma omp parallel for schedule(static) if (outer * L * inner > kParallelMin)
    for (int64_t ol = 0; ol < outer * L; ++ol) {
        const int64_t o = ol / L, l = ol % L;
        // idx is trusted: nn::index_select checked every id against D on the host.
        const T* s = x + (o * D + idx[l]) * inner;
        std::copy(s, s + inner, y + ol * inner);
    }
}

template <class T>
void index_select_bwd_cpu(const T* dy, const int32_t* idx, int64_t L, T* dx, int64_t outer,
                          int64_t D, int64_t inner) {
    const int64_t n_block = (inner + kBlock - 1) / kBlock, tasks = outer * n_block;
    // A task owns (o, block of inner) for every l: an index that repeats adds into its dx row in
    // l order on one thread, so there are no races and the sum order is fixed.
#pragma omp parallel for schedule(static) if (outer * (L + D) * inner > kParallelMin)
    for (int64_t t = 0; t < tasks; ++t) {
        const int64_t o = t / n_block, i0 = (t % n_block) * kBlock;
        const int64_t i1 = std::min(inner, i0 + kBlock);
        for (int64_t d = 0; d < D; ++d)
            std::fill(dx + (o * D + d) * inner + i0, dx + (o * D + d) * inner + i1, T(0));
        for (int64_t l = 0; l < L; ++l) {
            const T* g = dy + (o * L + l) * inner;
            T* dst = dx + (o * D + idx[l]) * inner;
            for (int64_t i = i0; i < i1; ++i) dst[i] += g[i];
        }
    }
}

#define G2L_SHAPE_INST(T)                                                                          \
    template void copy_slab_cpu<T>(const T*, int64_t, int64_t, T*, int64_t, int64_t, int64_t,      \
                                   int64_t, int64_t);                                              \
    template void permute_cpu<T>(const T*, const std::vector<int64_t>&,                            \
                                 const std::vector<int64_t>&, T*);                                 \
    template void index_select_fwd_cpu<T>(const T*, const int32_t*, int64_t, T*, int64_t, int64_t, \
                                          int64_t);                                                \
    template void index_select_bwd_cpu<T>(const T*, const int32_t*, int64_t, T*, int64_t, int64_t, \
                                          int64_t);
G2L_SHAPE_INST(float)
G2L_SHAPE_INST(double)
// i32 too: concat, slice and permute also move index and label tensors.
G2L_SHAPE_INST(int32_t)
#undef G2L_SHAPE_INST

}  // namespace g2l::kernels
