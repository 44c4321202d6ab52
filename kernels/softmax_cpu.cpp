// SPDX-License-Identifier: MIT
#include "kernels/softmax.h"

#include <algorithm>
#include <cmath>

namespace g2l::kernels {

namespace {
constexpr int64_t kParallelMin = 32768;
constexpr int64_t kBlock = 256;  // inner positions processed together (stack accumulators)
}  // namespace

// Each task owns (o, block of inner) and walks d three times (max, sum of exp, write). Sums are
// accumulated in double in d order, so results do not depend on the thread count.
template <class T>
void softmax_fwd_cpu(const T* x, T* y, int64_t outer, int64_t D, int64_t inner, bool log) {
    const int64_t n_block = (inner + kBlock - 1) / kBlock, tasks = outer * n_block;
#pragma omp parallel for schedule(static) if (outer * D * inner > kParallelMin)
    for (int64_t t = 0; t < tasks; ++t) {
        const int64_t o = t / n_block, i0 = (t % n_block) * kBlock;
        const int64_t w = std::min(inner, i0 + kBlock) - i0;
        const T* xb = x + o * D * inner + i0;
        T* yb = y + o * D * inner + i0;
        T m[kBlock];
        double s[kBlock] = {};
        // Subtracting the column max keeps every exp() <= 1: no overflow for large logits.
        for (int64_t i = 0; i < w; ++i) m[i] = xb[i];
        for (int64_t d = 1; d < D; ++d)
            for (int64_t i = 0; i < w; ++i) m[i] = std::max(m[i], xb[d * inner + i]);
        // One exp per element: softmax stores e = exp(x - m) and rescales it afterwards.
        for (int64_t d = 0; d < D; ++d) {
            const T* xr = xb + d * inner;
            T* yr = yb + d * inner;
            for (int64_t i = 0; i < w; ++i) {
                const T e = std::exp(xr[i] - m[i]);
                if (!log) yr[i] = e;
                s[i] += double(e);
            }
        }
        if (log) {
            // log_softmax as (x - m) - log(sum): never the log of a probability that rounded to 0.
            T lse[kBlock];
            for (int64_t i = 0; i < w; ++i) lse[i] = T(std::log(s[i]));
            for (int64_t d = 0; d < D; ++d)
                for (int64_t i = 0; i < w; ++i)
                    yb[d * inner + i] = (xb[d * inner + i] - m[i]) - lse[i];
        } else {
            T inv[kBlock];
            // One division per column, then multiplies.
            for (int64_t i = 0; i < w; ++i) inv[i] = T(1.0 / s[i]);
            for (int64_t d = 0; d < D; ++d)
                for (int64_t i = 0; i < w; ++i) yb[d * inner + i] *= inv[i];
        }
    }
}

template <class T>
void softmax_bwd_cpu(const T* y, const T* dy, T* dx, int64_t outer, int64_t D, int64_t inner,
                     bool log) {
    const int64_t n_block = (inner + kBlock - 1) / kBlock, tasks = outer * n_block;
#pragma omp parallel for schedule(static) if (outer * D * inner > kParallelMin)
    for (int64_t t = 0; t < tasks; ++t) {
        const int64_t o = t / n_block, i0 = (t % n_block) * kBlock;
        const int64_t w = std::min(inner, i0 + kBlock) - i0;
        const int64_t base = o * D * inner + i0;
        double s[kBlock] = {};
        // softmax:     dx = y (dy - sum_d dy y)
        // log_softmax: dx = dy - exp(y) sum_d dy      (exp(y) is the softmax)
        // Both only need y, so the op keeps its output, not x.
        for (int64_t d = 0; d < D; ++d) {
            const int64_t r = base + d * inner;
            for (int64_t i = 0; i < w; ++i)
                s[i] += log ? double(dy[r + i]) : double(dy[r + i]) * double(y[r + i]);
        }
        for (int64_t d = 0; d < D; ++d) {
            const int64_t r = base + d * inner;
            for (int64_t i = 0; i < w; ++i) {
                if (log)
                    dx[r + i] = T(double(dy[r + i]) - std::exp(double(y[r + i])) * s[i]);
                else
                    dx[r + i] = T(double(y[r + i]) * (double(dy[r + i]) - s[i]));
            }
        }
    }
}

template void softmax_fwd_cpu<float>(const float*, float*, int64_t, int64_t, int64_t, bool);
template void softmax_fwd_cpu<double>(const double*, double*, int64_t, int64_t, int64_t, bool);
template void softmax_bwd_cpu<float>(const float*, const float*, float*, int64_t, int64_t, int64_t,
                                     bool);
template void softmax_bwd_cpu<double>(const double*, const double*, double*, int64_t, int64_t,
                                      int64_t, bool);

}  // namespace g2l::kernels
