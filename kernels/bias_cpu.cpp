// SPDX-License-Identifier: MIT
#include "kernels/bias.h"

#include "kernels/cpu_util.h"

namespace g2l::kernels {

template <class T>
void add_bias_bcn_cpu(T* y, const T* bias, int64_t B, int64_t C, int64_t N) {
#pragma omp parallel for schedule(static) if (B * C * N > 32768)
    // Rows of [B, C, N] are contiguous and share one bias value, so a (b, c) row is the unit.
    for (int64_t bc = 0; bc < B * C; ++bc) {
        const T v = bias[bc % C];
        T* row = y + bc * N;
        for (int64_t n = 0; n < N; ++n) row[n] += v;
    }
}

template <class T>
void bias_grad_bcn_cpu(const T* dy, T* db, int64_t B, int64_t C, int64_t N, bool accumulate) {
#pragma omp parallel for schedule(static) if (B * C * N > 32768)
    // Parallel over channels, never over the sum: each db[c] is reduced by one thread in a fixed
    // lane order, so the gradient is bitwise the same for any OMP_NUM_THREADS.
    for (int64_t c = 0; c < C; ++c) {
        Lanes<T> l;
        for (int64_t b = 0; b < B; ++b) {
            const T* row = dy + (b * C + c) * N;
            l.add(N, [row](int64_t n) { return row[n]; });
        }
        const T s = l.total();
        db[c] = accumulate ? db[c] + s : s;
    }
}

template void add_bias_bcn_cpu<float>(float*, const float*, int64_t, int64_t, int64_t);
template void add_bias_bcn_cpu<double>(double*, const double*, int64_t, int64_t, int64_t);
template void bias_grad_bcn_cpu<float>(const float*, float*, int64_t, int64_t, int64_t, bool);
template void bias_grad_bcn_cpu<double>(const double*, double*, int64_t, int64_t, int64_t, bool);

}  // namespace g2l::kernels
