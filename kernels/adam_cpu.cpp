// SPDX-License-Identifier: MIT
#include "kernels/adam.h"

#include <cmath>

namespace g2l::kernels {

// Follows torch.optim.adam._single_tensor_adam term by term (same operation order), so that a
// float parameter sees the same roundings: the scalars are rounded to T once, the per-element
// math runs in T. Element-wise with a static schedule: no cross-element reduction, results are
// independent of the thread count.
template <class T>
void adam_update_cpu(T* p, const T* g, T* m, T* v, int64_t n, const AdamArgs& a) {
    const T beta1 = T(a.beta1), beta2 = T(a.beta2);
    const T one_m_beta1 = T(1.0 - a.beta1), one_m_beta2 = T(1.0 - a.beta2);
    const T wd = T(a.weight_decay), eps = T(a.eps);
    // AdamW: param.mul_(1 - lr * weight_decay), the factor formed in double on the host.
    const T decay = T(1.0 - a.lr * a.weight_decay);
    const T step_size = T(a.lr / a.bias_corr1);
    const T bc2_sqrt = T(std::sqrt(a.bias_corr2));
    const bool decoupled = a.decoupled;
    const bool has_wd = a.weight_decay != 0.0;
    // Threads only pay off on large tensors; biases and BatchNorm parameters run serially.
#pragma omp parallel for schedule(static) if (n > 32768)
    for (int64_t i = 0; i < n; ++i) {
        T gi = g[i];
        // Decay before the moments, in PyTorch's order. Adam's L2 term goes into the gradient (and
        // so into m and v); AdamW's shrinks the weight directly and leaves the moments alone.
        if (has_wd) {
            if (decoupled) p[i] = p[i] * decay;
            else gi = gi + wd * p[i];
        }
        m[i] = beta1 * m[i] + one_m_beta1 * gi;
        v[i] = beta2 * v[i] + one_m_beta2 * gi * gi;
        // eps is added to the bias-corrected sqrt(v) (Kingma & Ba Alg. 1, PyTorch's order), not to
        // the raw sqrt(v) as in the paper's eps-hat variant, so eps means what it means in PyTorch.
        const T denom = std::sqrt(v[i]) / bc2_sqrt + eps;
        p[i] = p[i] - step_size * (m[i] / denom);
    }
}

template void adam_update_cpu<float>(float*, const float*, float*, float*, int64_t,
                                     const AdamArgs&);
template void adam_update_cpu<double>(double*, const double*, double*, double*, int64_t,
                                      const AdamArgs&);

}  // namespace g2l::kernels
