// SPDX-License-Identifier: MIT
// max_pool2d / avg_pool2d: the dispatch points (kernels/dispatch.h); CPU kernels in pool2d_cpu.cpp.
#include "kernels/pool2d.h"

#include "kernels/dispatch.h"

namespace g2l::kernels {

void max_pool2d_fwd(const Tensor& x, Tensor& y, Tensor& argmax, const Pool2dGeom& g) {
    dispatch("max_pool2d", {&x, &y, &argmax}, [&](auto tag) {
        using T = decltype(tag);
        max_pool2d_fwd_cpu<T>(x.data<T>(), y.data<T>(), argmax.data<int32_t>(), g);
    });
}

void max_pool2d_bwd(const Tensor& dy, const Tensor& argmax, Tensor& dx, const Pool2dGeom& g) {
    dispatch("max_pool2d backward", {&dy, &argmax, &dx}, [&](auto tag) {
        using T = decltype(tag);
        max_pool2d_bwd_cpu<T>(dy.data<T>(), argmax.data<int32_t>(), dx.data<T>(), g);
    });
}

void avg_pool2d_fwd(const Tensor& x, Tensor& y, const Pool2dGeom& g, bool count_include_pad) {
    dispatch("avg_pool2d", {&x, &y}, [&](auto tag) {
        using T = decltype(tag);
        avg_pool2d_fwd_cpu<T>(x.data<T>(), y.data<T>(), g, count_include_pad);
    });
}

void avg_pool2d_bwd(const Tensor& dy, Tensor& dx, const Pool2dGeom& g, bool count_include_pad) {
    dispatch("avg_pool2d backward", {&dy, &dx}, [&](auto tag) {
        using T = decltype(tag);
        avg_pool2d_bwd_cpu<T>(dy.data<T>(), dx.data<T>(), g, count_include_pad);
    });
}

}  // namespace g2l::kernels
