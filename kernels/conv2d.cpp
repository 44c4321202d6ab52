// SPDX-License-Identifier: MIT
// conv2d: the dispatch point (kernels/dispatch.h); CPU kernels in conv2d_cpu.cpp.
#include "kernels/conv2d.h"

#include "kernels/dispatch.h"

namespace g2l::kernels {

void conv2d_fwd(const Tensor& x, const Tensor& w, const Tensor& bias, Tensor& y,
                const Conv2dGeom& g) {
    dispatch("conv2d", {&x, &w, &bias, &y}, [&](auto tag) {
        using T = decltype(tag);
        conv2d_fwd_cpu<T>(x.data<T>(), w.data<T>(), data_or_null<T>(bias), y.data<T>(), g);
    });
}

void conv2d_bwd(const Tensor& x, const Tensor& w, const Tensor& dy, Tensor* dx, Tensor* dw,
                Tensor* dbias, const Conv2dGeom& g) {
    const bool need_x = dx && dx->defined(), need_w = dw && dw->defined();
    // The op keeps x only when dw will be wanted and w only when dx will (nn/ops/conv2d.cpp),
    // so the other one may be undefined and must not be dereferenced.
    dispatch("conv2d backward", {&dy, &x, &w, dx, dw, dbias}, [&](auto tag) {
        using T = decltype(tag);
        conv2d_bwd_cpu<T>(need_w ? x.data<T>() : nullptr, need_x ? w.data<T>() : nullptr,
                          dy.data<T>(), data_or_null<T>(dx), data_or_null<T>(dw),
                          data_or_null<T>(dbias), g);
    });
}

}  // namespace g2l::kernels
