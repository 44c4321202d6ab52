// SPDX-License-Identifier: MIT
#include "kernels/pool_points.h"

namespace g2l::kernels {

template <class T>
// PointNet's symmetric max over the points: G2L's global feature g (spec §4.1) and the max in
// the T-net, Rotation_pre and R_res heads (§4.3-4.6). It makes the output independent of point
// order.
void max_pool_points_fwd_cpu(const T* x, int64_t R, int64_t N, T* y, int32_t* arg) {
#pragma omp parallel for schedule(static) if (R * N > 32768)
    for (int64_t r = 0; r < R; ++r) {
        const T* row = x + r * N;
        T best = row[0];
        int32_t bi = 0;
        for (int64_t n = 1; n < N; ++n) {
            // Strictly greater: ties go to the lowest n, so exactly one point gets the gradient.
            if (row[n] > best) { best = row[n]; bi = int32_t(n); }
        }
        y[r] = best;
        arg[r] = bi;
    }
}

template <class T>
void max_pool_points_bwd_cpu(const T* dy, const int32_t* arg, int64_t R, int64_t N, T* dx) {
#pragma omp parallel for schedule(static) if (R > 4096)
    // One argmax per row and rows are disjoint, so parallel writes never collide.
    for (int64_t r = 0; r < R; ++r) dx[r * N + arg[r]] += dy[r];
}

template void max_pool_points_fwd_cpu<float>(const float*, int64_t, int64_t, float*, int32_t*);
template void max_pool_points_fwd_cpu<double>(const double*, int64_t, int64_t, double*, int32_t*);
template void max_pool_points_bwd_cpu<float>(const float*, const int32_t*, int64_t, int64_t, float*);
template void max_pool_points_bwd_cpu<double>(const double*, const int32_t*, int64_t, int64_t,
                                         double*);

}  // namespace g2l::kernels
