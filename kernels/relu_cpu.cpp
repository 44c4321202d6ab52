// SPDX-License-Identifier: MIT
#include "kernels/relu.h"

namespace g2l::kernels {

// Element-wise and memory bound: a static schedule keeps each element on a fixed thread, so the
// result does not depend on the thread count (there is no reduction).
template <class T>
void relu_fwd_cpu(const T* x, T* y, int64_t n) {
#pragma omp parallel for schedule(static) if (n > 32768)
    for (int64_t i = 0; i < n; ++i) y[i] = x[i] > T(0) ? x[i] : T(0);
}

template <class T>
void relu_bwd_cpu(const T* y, const T* dy, T* dx, int64_t n) {
#pragma omp parallel for schedule(static) if (n > 32768)
    // Masked by y, not x: y > 0 exactly where x > 0, so the op keeps only its output alive. The
    // derivative at 0 is taken as 0, as in PyTorch.
    for (int64_t i = 0; i < n; ++i) dx[i] = y[i] > T(0) ? dy[i] : T(0);
}

template void relu_fwd_cpu<float>(const float*, float*, int64_t);
template void relu_fwd_cpu<double>(const double*, double*, int64_t);
template void relu_bwd_cpu<float>(const float*, const float*, float*, int64_t);
template void relu_bwd_cpu<double>(const double*, const double*, double*, int64_t);

}  // namespace g2l::kernels
