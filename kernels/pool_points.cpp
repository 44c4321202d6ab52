// SPDX-License-Identifier: MIT
// max_pool_points: the dispatch point (kernels/dispatch.h); CPU kernels in pool_points_cpu.cpp.
#include "kernels/pool_points.h"

#include <algorithm>

#include "kernels/dispatch.h"

namespace g2l::kernels {

void max_pool_points_fwd(const Tensor& x, Tensor& y, Tensor& arg) {
    const int64_t R = x.size(0) * x.size(1), N = x.size(2);
    dispatch("max_pool_points", {&x, &y, &arg}, [&](auto tag) {
        using T = decltype(tag);
        max_pool_points_fwd_cpu<T>(x.data<T>(), R, N, y.data<T>(), arg.data<int32_t>());
    });
}

void max_pool_points_bwd(const Tensor& dy, const Tensor& arg, Tensor& dx) {
    const int64_t R = dx.size(0) * dx.size(1), N = dx.size(2);
    dispatch("max_pool_points backward", {&dy, &arg, &dx}, [&](auto tag) {
        using T = decltype(tag);
        T* p = dx.data<T>();
        // Zeroed here: the kernel only adds at each row's argmax, every other point gets 0.
        std::fill(p, p + dx.numel(), T(0));
        max_pool_points_bwd_cpu<T>(dy.data<T>(), arg.data<int32_t>(), R, N, p);
    });
}

}  // namespace g2l::kernels
