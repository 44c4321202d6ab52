// SPDX-License-Identifier: MIT
// nll_loss / smooth_l1_loss: the dispatch points (kernels/dispatch.h); CPU kernels in loss_cpu.cpp.
#include "kernels/loss.h"

#include "kernels/dispatch.h"

namespace g2l::kernels {

// num and den come back separately (in double) so the op divides once by the total target
// weight, PyTorch's weighted mean, and reuses den for the backward scale.
void nll_fwd(const Tensor& logp, const Tensor& target, const Tensor& weight, int64_t B,
             int64_t K, int64_t N, double* num, double* den) {
    dispatch("nll_loss", {&logp, &target, &weight}, [&](auto tag) {
        using T = decltype(tag);
        nll_fwd_cpu<T>(logp.data<T>(), target.data<int32_t>(), data_or_null<T>(weight), B, K, N,
                       num, den);
    });
}

void nll_bwd(const Tensor& target, const Tensor& weight, int64_t B, int64_t K, int64_t N,
             double scale, Tensor& dlogp) {
    dispatch("nll_loss backward", {&dlogp, &target, &weight}, [&](auto tag) {
        using T = decltype(tag);
        nll_bwd_cpu<T>(target.data<int32_t>(), data_or_null<T>(weight), B, K, N, scale,
                       dlogp.data<T>());
    });
}

void smooth_l1_fwd(const Tensor& a, const Tensor& b, Tensor& y, double beta) {
    dispatch("smooth_l1_loss", {&a, &b, &y}, [&](auto tag) {
        using T = decltype(tag);
        smooth_l1_fwd_cpu<T>(a.data<T>(), b.data<T>(), y.data<T>(), a.numel(), beta);
    });
}

void smooth_l1_bwd(const Tensor& a, const Tensor& b, const Tensor& dy, Tensor* da, Tensor* db,
                   double beta) {
    dispatch("smooth_l1_loss backward", {&dy, &a, &b, da, db}, [&](auto tag) {
        using T = decltype(tag);
        smooth_l1_bwd_cpu<T>(a.data<T>(), b.data<T>(), dy.data<T>(), data_or_null<T>(da),
                             data_or_null<T>(db), dy.numel(), beta);
    });
}

}  // namespace g2l::kernels
