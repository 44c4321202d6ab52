// SPDX-License-Identifier: MIT
#include "kernels/reduce.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/error.h"
#include "kernels/cpu_util.h"

namespace g2l::kernels {

namespace {

constexpr int64_t kParallelMin = 32768;
constexpr int64_t kChunk =
    2048;  // rows of D per partial sum (fixed: part of the result's definition)
constexpr int64_t kBlock = 256;  // inner elements handled together (stack accumulators)

}  // namespace

template <class T>
void sum_dim_cpu(const T* x, T* y, int64_t outer, int64_t D, int64_t inner, double scale) {
    const int64_t n_out = outer * inner;
    if (n_out == 0) return;
    if (D == 0) {
        std::fill(y, y + n_out, T(0));
        return;
    }
    // Tasks = (o, chunk of D, block of inner). Each task writes its own partial sums; a second
    // pass adds the chunks of each output in chunk order.
    // Chunking D lets a long reduction with few outputs (the mean of a whole loss tensor) use
    // every thread, while the chunk bounds, and so the order of the sums, depend only on D.
    const int64_t n_chunk = ceil_div(D, kChunk), n_block = ceil_div(inner, kBlock);
    // Partial sums stay in double until the final rounding to T.
    std::vector<double> part(size_t(outer * n_chunk * inner));
    const int64_t tasks = outer * n_chunk * n_block;
#pragma omp parallel for schedule(static) if (outer * D * inner > kParallelMin)
    for (int64_t t = 0; t < tasks; ++t) {
        const int64_t blk = t % n_block, c = (t / n_block) % n_chunk, o = t / (n_block * n_chunk);
        const int64_t i0 = blk * kBlock, i1 = std::min(inner, i0 + kBlock);
        const int64_t d0 = c * kChunk, d1 = std::min(D, d0 + kChunk);
        double acc[kBlock] = {};
        const int64_t w = i1 - i0;
        if (w == 1) {
            double s = 0;
            for (int64_t d = d0; d < d1; ++d) s += double(x[(o * D + d) * inner + i0]);
            acc[0] = s;
        } else {
            for (int64_t d = d0; d < d1; ++d) {
                const T* row = x + (o * D + d) * inner + i0;
                for (int64_t i = 0; i < w; ++i) acc[i] += double(row[i]);
            }
        }
        double* dst = part.data() + (o * n_chunk + c) * inner + i0;
        std::copy(acc, acc + w, dst);
    }
#pragma omp parallel for schedule(static) if (n_out > kParallelMin)
    for (int64_t k = 0; k < n_out; ++k) {
        const int64_t o = k / inner, i = k % inner;
        double s = 0;
        for (int64_t c = 0; c < n_chunk; ++c) s += part[size_t((o * n_chunk + c) * inner + i)];
        y[k] = T(s * scale);
    }
}

template <class T>
void sum_to_shape_cpu(const T* x, const std::vector<int64_t>& x_shape, T* y,
                      const std::vector<int64_t>& y_shape) {
    const size_t r = x_shape.size();
    G2L_ASSERT(y_shape.size() <= r);
    std::vector<int64_t> cur = x_shape;
    std::vector<int64_t> target(r, 1);
    for (size_t k = 0; k < y_shape.size(); ++k) target[r - y_shape.size() + k] = y_shape[k];
    int64_t n = 1;
    for (int64_t s : x_shape) n *= s;
    // Each run of adjacent reduced dimensions is one sum_dim call on [outer, D, inner]; the
    // first reads x directly, later ones read the previous (smaller) result.
    const T* src = x;
    std::vector<T> cur_buf, next_buf;
    size_t k = 0;
    while (k < r) {
        // Dim k is reduced where the target has 1 and x does not (a broadcast dimension).
        if (!(target[k] == 1 && cur[k] != 1)) {
            G2L_ASSERT(target[k] == cur[k]);
            ++k;
            continue;
        }
        size_t e = k;
        int64_t D = 1;
        while (e < r && target[e] == 1) D *= cur[e++];
        int64_t outer = 1, inner = 1;
        for (size_t j = 0; j < k; ++j) outer *= cur[j];
        for (size_t j = e; j < r; ++j) inner *= cur[j];
        next_buf.assign(size_t(outer * inner), T(0));
        sum_dim_cpu(src, next_buf.data(), outer, D, inner);
        cur_buf.swap(next_buf);
        src = cur_buf.data();
        n = outer * inner;
        for (size_t j = k; j < e; ++j) cur[j] = 1;
        k = e;
    }
    std::copy(src, src + n, y);
}

template <class T>
void broadcast_dim_cpu(const T* y, T* x, int64_t outer, int64_t D, int64_t inner, double scale) {
    const T sc = T(scale);
#pragma omp parallel for schedule(static) if (outer * D * inner > kParallelMin)
    // The backward of sum / mean: every input along D receives the same scaled output gradient.
    for (int64_t od = 0; od < outer * D; ++od) {
        const T* src = y + (od / D) * inner;
        T* dst = x + od * inner;
        for (int64_t i = 0; i < inner; ++i) dst[i] = sc * src[i];
    }
}

template <class T>
void max_dim_fwd_cpu(const T* x, T* y, int32_t* arg, int64_t outer, int64_t D, int64_t inner) {
    G2L_ASSERT(D >= 1);
    const int64_t n_block = ceil_div(inner, kBlock), tasks = outer * n_block;
#pragma omp parallel for schedule(static) if (outer * D * inner > kParallelMin)
    for (int64_t t = 0; t < tasks; ++t) {
        const int64_t o = t / n_block, i0 = (t % n_block) * kBlock;
        const int64_t w = std::min(inner, i0 + kBlock) - i0;
        // A block of inner columns advances together, so each of the D rows is read contiguously
        // rather than with stride `inner`.
        T best[kBlock];
        int32_t where[kBlock];
        const T* base = x + o * D * inner + i0;
        for (int64_t i = 0; i < w; ++i) {
            best[i] = base[i];
            where[i] = 0;
        }
        for (int64_t d = 1; d < D; ++d) {
            const T* row = base + d * inner;
            for (int64_t i = 0; i < w; ++i) {
                const T v = row[i];
                // Strictly greater keeps the lowest index on ties; a NaN wins and stays.
                if (v > best[i] || (std::isnan(v) && !std::isnan(best[i]))) {
                    best[i] = v;
                    where[i] = int32_t(d);
                }
            }
        }
        std::copy(best, best + w, y + o * inner + i0);
        std::copy(where, where + w, arg + o * inner + i0);
    }
}

template <class T>
void max_dim_bwd_cpu(const T* dy, const int32_t* arg, T* dx, int64_t outer, int64_t D,
                     int64_t inner) {
#pragma omp parallel for schedule(static) if (outer * D * inner > kParallelMin)
    for (int64_t o = 0; o < outer; ++o) {
        T* base = dx + o * D * inner;
        // Exactly one winner per output, so the winner's slot is assigned, not accumulated.
        std::fill(base, base + D * inner, T(0));
        for (int64_t i = 0; i < inner; ++i)
            base[int64_t(arg[o * inner + i]) * inner + i] = dy[o * inner + i];
    }
}

template <class T>
void norm_dim_fwd_cpu(const T* x, T* y, int64_t outer, int64_t D, int64_t inner, double eps) {
    const int64_t n_block = ceil_div(inner, kBlock), tasks = outer * n_block;
#pragma omp parallel for schedule(static) if (outer * D * inner > kParallelMin)
    for (int64_t t = 0; t < tasks; ++t) {
        const int64_t o = t / n_block, i0 = (t % n_block) * kBlock;
        const int64_t w = std::min(inner, i0 + kBlock) - i0;
        double acc[kBlock] = {};
        for (int64_t d = 0; d < D; ++d) {
            const T* row = x + (o * D + d) * inner + i0;
            for (int64_t i = 0; i < w; ++i) acc[i] += double(row[i]) * double(row[i]);
        }
        // eps inside the sqrt keeps y > 0, so the backward x / y stays finite for a zero vector.
        for (int64_t i = 0; i < w; ++i) y[o * inner + i0 + i] = T(std::sqrt(acc[i] + eps));
    }
}

template <class T>
void norm_dim_bwd_cpu(const T* x, const T* y, const T* dy, T* dx, int64_t outer, int64_t D,
                      int64_t inner) {
    const int64_t n = outer * D * inner;
#pragma omp parallel for schedule(static) if (n > kParallelMin)
    for (int64_t k = 0; k < n; ++k) {
        const int64_t i = k % inner, o = k / (D * inner);
        // d||x||/dx = x / ||x||, using the stored y (eps included) as the forward used it.
        dx[k] = dy[o * inner + i] * x[k] / y[o * inner + i];
    }
}

#define G2L_REDUCE_INST(T)                                                                     \
    template void sum_dim_cpu<T>(const T*, T*, int64_t, int64_t, int64_t, double);             \
    template void sum_to_shape_cpu<T>(const T*, const std::vector<int64_t>&, T*,               \
                                      const std::vector<int64_t>&);                            \
    template void broadcast_dim_cpu<T>(const T*, T*, int64_t, int64_t, int64_t, double);       \
    template void max_dim_fwd_cpu<T>(const T*, T*, int32_t*, int64_t, int64_t, int64_t);       \
    template void max_dim_bwd_cpu<T>(const T*, const int32_t*, T*, int64_t, int64_t, int64_t); \
    template void norm_dim_fwd_cpu<T>(const T*, T*, int64_t, int64_t, int64_t, double);        \
    template void norm_dim_bwd_cpu<T>(const T*, const T*, const T*, T*, int64_t, int64_t, int64_t);
G2L_REDUCE_INST(float)
G2L_REDUCE_INST(double)
#undef G2L_REDUCE_INST

}  // namespace g2l::kernels
