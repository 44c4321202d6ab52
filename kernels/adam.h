// SPDX-License-Identifier: MIT
// Adam / AdamW parameter update (one step), exactly as PyTorch's torch.optim.Adam / AdamW with
// amsgrad = false and maximize = false. p, g, m, v: n contiguous elements of the same dtype.
// The caller (nn/optim) checks sizes, dtypes and devices and computes the bias corrections.
#pragma once

#include <cstdint>

#include "core/tensor.h"

namespace g2l::kernels {

/// Scalars of one Adam step for one parameter tensor. All values are computed on the host.
struct AdamArgs {
    double lr = 1e-3;            ///< effective learning rate (base lr x group multiplier)
    double beta1 = 0.9;          ///< first-moment decay
    double beta2 = 0.999;        ///< second-moment decay
    double eps = 1e-8;           ///< added to sqrt(v_hat)
    double weight_decay = 0.0;   ///< L2 (Adam) or decoupled (AdamW) weight decay
    double bias_corr1 = 1.0;     ///< 1 - beta1^t (t = this parameter's step, starting at 1)
    double bias_corr2 = 1.0;     ///< 1 - beta2^t
    bool decoupled = false;      ///< true: AdamW (p -= lr*wd*p first); false: g += wd*p
};

/// One Adam step, in place on p, m, v (g is read only):
///   Adam  (decoupled = false): g' = g + wd*p
///   AdamW (decoupled = true):  p  = p * (1 - lr*wd), g' = g
///   m = beta1*m + (1-beta1)*g';  v = beta2*v + (1-beta2)*g'^2
///   p = p - (lr / bias_corr1) * m / (sqrt(v) / sqrt(bias_corr2) + eps)
/// The step size lr/bias_corr1 and sqrt(bias_corr2) are formed in double then rounded to T, as
/// PyTorch does with its Python-float scalars. Element-wise, so the result does not depend on
/// the OpenMP thread count. T is float or double.
template <class T>
void adam_update_cpu(T* p, const T* g, T* m, T* v, int64_t n, const AdamArgs& a);

// ---- tensor-level entry points: one dispatch on (device, dtype) each ----

/// One Adam step on parameter p in place (g, m, v same shape and device).
void adam_update(Tensor& p, const Tensor& g, Tensor& m, Tensor& v, const AdamArgs& a);

}  // namespace g2l::kernels
