// SPDX-License-Identifier: MIT
#include "kernels/batch_norm.h"

#include "kernels/cpu_util.h"

namespace g2l::kernels {

// Statistics use a two-pass (mean, then squared deviations) scheme in double-width
// accumulators for float: one pass of E[x^2] - E[x]^2 loses precision on 1024-channel features
// with large means.
template <class T>
void bn_stats_cpu(const T* x, int64_t B, int64_t C, int64_t S, T* mean, T* var) {
    const double M = double(B * S);
    // One channel per iteration: its whole reduction runs on one thread in a fixed order.
#pragma omp parallel for schedule(static) if (B * C * S > 16384)
    for (int64_t c = 0; c < C; ++c) {
        Lanes<double> s;
        for (int64_t b = 0; b < B; ++b) {
            const T* row = x + (b * C + c) * S;
            s.add(S, [row](int64_t i) { return double(row[i]); });
        }
        const double m = s.total() / M;
        Lanes<double> q;
        for (int64_t b = 0; b < B; ++b) {
            const T* row = x + (b * C + c) * S;
            q.add(S, [row, m](int64_t i) {
                const double d = double(row[i]) - m;
                return d * d;
            });
        }
        mean[c] = T(m);
        var[c] = T(q.total() / M);
    }
}

template <class T>
void bn_apply_cpu(const T* x, const T* mean, const T* invstd, const T* gamma, const T* beta,
                  int64_t B, int64_t C, int64_t S, T* y) {
#pragma omp parallel for schedule(static) if (B * C * S > 16384)
    for (int64_t bc = 0; bc < B * C; ++bc) {
        const int64_t c = bc % C;
        // gamma, invstd, beta and mean folded into one scale and shift per channel, so the inner
        // loop is a single multiply-add per element.
        const T scale = (gamma ? gamma[c] : T(1)) * invstd[c];
        const T shift = (beta ? beta[c] : T(0)) - mean[c] * scale;
        const T* xr = x + bc * S;
        T* yr = y + bc * S;
        for (int64_t i = 0; i < S; ++i) yr[i] = xr[i] * scale + shift;
    }
}

template <class T>
void bn_backward_cpu(const T* x, const T* dy, const T* mean, const T* invstd, const T* gamma,
                     int64_t B, int64_t C, int64_t S, bool training, T* dx, T* sum_dy,
                     T* sum_dy_xhat) {
    const T M = T(B * S);
#pragma omp parallel for schedule(static) if (B * C * S > 16384)
    for (int64_t c = 0; c < C; ++c) {
        const T m = mean[c], is = invstd[c];
        Lanes<T> ldy, ldyx;
        for (int64_t b = 0; b < B; ++b) {
            const T* xr = x + (b * C + c) * S;
            const T* dr = dy + (b * C + c) * S;
            ldy.add(S, [dr](int64_t i) { return dr[i]; });
            ldyx.add(S, [dr, xr, m, is](int64_t i) { return dr[i] * (xr[i] - m) * is; });
        }
        // These two sums are dbeta and dgamma (the caller passes those buffers) and also feed dx.
        const T sdy = ldy.total(), sdyx = ldyx.total();
        sum_dy[c] = sdy;
        sum_dy_xhat[c] = sdyx;
        if (!dx) continue;
        const T k = (gamma ? gamma[c] : T(1)) * is;
        for (int64_t b = 0; b < B; ++b) {
            const T* xr = x + (b * C + c) * S;
            const T* dr = dy + (b * C + c) * S;
            T* out = dx + (b * C + c) * S;
            // Training: mean and invstd are functions of x, which adds the two correction terms
            // (Ioffe & Szegedy 2015, §3). Eval: the running statistics are constants, so dx = k dy.
            if (training) {
                const T a = sdy / M, bq = sdyx / M;
                for (int64_t i = 0; i < S; ++i) out[i] = k * (dr[i] - a - (xr[i] - m) * is * bq);
            } else {
                for (int64_t i = 0; i < S; ++i) out[i] = k * dr[i];
            }
        }
    }
}

template <class T>
void bn_moment_cpu(const T* x, int64_t B, int64_t C, int64_t S, const double* shift, bool square,
                   double* out) {
#pragma omp parallel for schedule(static) if (B * C * S > 16384)
    for (int64_t c = 0; c < C; ++c) {
        // First pass: plain sums (shift null); second pass: squared deviations from the global
        // mean, the same two-pass scheme as bn_stats_cpu.
        const double m = shift ? shift[c] : 0.0;
        Lanes<double> s;
        for (int64_t b = 0; b < B; ++b) {
            const T* row = x + (b * C + c) * S;
            if (square) {
                s.add(S, [row, m](int64_t i) {
                    const double d = double(row[i]) - m;
                    return d * d;
                });
            } else {
                s.add(S, [row, m](int64_t i) { return double(row[i]) - m; });
            }
        }
        out[c] = s.total();
    }
}

template <class T>
void bn_backward_dx_cpu(const T* x, const T* dy, const T* mean, const T* invstd, const T* gamma,
                        int64_t B, int64_t C, int64_t S, const double* sum_dy,
                        const double* sum_dy_xhat, double M, T* dx) {
#pragma omp parallel for schedule(static) if (B * C * S > 16384)
    for (int64_t c = 0; c < C; ++c) {
        const T m = mean[c], is = invstd[c];
        const T k = (gamma ? gamma[c] : T(1)) * is;
        const T a = T(sum_dy[c] / M), bq = T(sum_dy_xhat[c] / M);
        for (int64_t b = 0; b < B; ++b) {
            const T* xr = x + (b * C + c) * S;
            const T* dr = dy + (b * C + c) * S;
            T* out = dx + (b * C + c) * S;
            for (int64_t i = 0; i < S; ++i) out[i] = k * (dr[i] - a - (xr[i] - m) * is * bq);
        }
    }
}

#define G2L_BN_INST(T)                                                                        \
    template void bn_stats_cpu<T>(const T*, int64_t, int64_t, int64_t, T*, T*);               \
    template void bn_apply_cpu<T>(const T*, const T*, const T*, const T*, const T*, int64_t,   \
                                  int64_t, int64_t, T*);                                      \
    template void bn_backward_cpu<T>(const T*, const T*, const T*, const T*, const T*, int64_t, \
                                     int64_t, int64_t, bool, T*, T*, T*);             \
    template void bn_moment_cpu<T>(const T*, int64_t, int64_t, int64_t, const double*, bool,   \
                                   double*);                                                  \
    template void bn_backward_dx_cpu<T>(const T*, const T*, const T*, const T*, const T*,      \
                                        int64_t, int64_t, int64_t, const double*,             \
                                        const double*, double, T*);
G2L_BN_INST(float)
G2L_BN_INST(double)
#undef G2L_BN_INST

}  // namespace g2l::kernels
