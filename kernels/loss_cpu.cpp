// SPDX-License-Identifier: MIT
#include "kernels/loss.h"

#include <algorithm>
#include <cmath>

namespace g2l::kernels {

namespace {
constexpr int64_t kParallelMin = 32768;
}

template <class T>
void nll_fwd_cpu(const T* logp, const int32_t* target, const T* weight, int64_t B, int64_t K,
                 int64_t N, double* num, double* den) {
    // Serial in a fixed (b, n) order, in double: the loss is bitwise reproducible and the sum of
    // B x N (e.g. 1500 points per sample) terms loses no precision.
    double s = 0, w_sum = 0;
    for (int64_t b = 0; b < B; ++b) {
        for (int64_t n = 0; n < N; ++n) {
            const int64_t t = target[b * N + n];
            // den sums the targets' weights, not a count: PyTorch's weighted-mean reduction.
            const double w = weight ? double(weight[t]) : 1.0;
            s -= w * double(logp[(b * K + t) * N + n]);
            w_sum += w;
        }
    }
    *num = s;
    *den = w_sum;
}

template <class T>
void nll_bwd_cpu(const int32_t* target, const T* weight, int64_t B, int64_t K, int64_t N,
                 double scale, T* dlogp) {
    // Only the target class of each (b, n) has a non-zero gradient: zero all, then set those.
    std::fill(dlogp, dlogp + B * K * N, T(0));
#pragma omp parallel for schedule(static) if (B * K * N > kParallelMin)
    for (int64_t b = 0; b < B; ++b) {
        for (int64_t n = 0; n < N; ++n) {
            const int64_t t = target[b * N + n];
            const double w = weight ? double(weight[t]) : 1.0;
            dlogp[(b * K + t) * N + n] = T(-w * scale);
        }
    }
}

template <class T>
void smooth_l1_fwd_cpu(const T* a, const T* b, T* y, int64_t n, double beta) {
    const T bt = T(beta);
#pragma omp parallel for schedule(static) if (n > kParallelMin)
    for (int64_t i = 0; i < n; ++i) {
        const T d = a[i] - b[i], ad = std::fabs(d);
        // beta == 0 never takes the quadratic branch (ad < 0 is false): plain L1, no division by 0.
        y[i] = ad < bt ? T(0.5) * d * d / bt : ad - T(0.5) * bt;
    }
}

template <class T>
void smooth_l1_bwd_cpu(const T* a, const T* b, const T* dy, T* da, T* db, int64_t n, double beta) {
    const T bt = T(beta);
#pragma omp parallel for schedule(static) if (n > kParallelMin)
    for (int64_t i = 0; i < n; ++i) {
        const T d = a[i] - b[i];
        // sign(d) outside the quadratic zone, with sign(0) = 0 as PyTorch.
        const T g = std::fabs(d) < bt ? d / bt : (d > T(0) ? T(1) : (d < T(0) ? T(-1) : T(0)));
        if (da) da[i] = dy[i] * g;
        if (db) db[i] = -dy[i] * g;
    }
}

#define G2L_LOSS_INST(T)                                                                           \
    template void nll_fwd_cpu<T>(const T*, const int32_t*, const T*, int64_t, int64_t, int64_t,    \
                                 double*, double*);                                                \
    template void nll_bwd_cpu<T>(const int32_t*, const T*, int64_t, int64_t, int64_t, double, T*); \
    template void smooth_l1_fwd_cpu<T>(const T*, const T*, T*, int64_t, double);                   \
    template void smooth_l1_bwd_cpu<T>(const T*, const T*, const T*, T*, T*, int64_t, double);
G2L_LOSS_INST(float)
G2L_LOSS_INST(double)
#undef G2L_LOSS_INST

}  // namespace g2l::kernels
