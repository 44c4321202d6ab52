// SPDX-License-Identifier: MIT
#include "kernels/dispatch.h"

namespace g2l::kernels::detail {

const Tensor& dispatch_key(const char* op, std::initializer_list<const Tensor*> ts) {
    const Tensor* key = nullptr;
    for (const Tensor* t : ts) {
        // Null or undefined entries are optional arguments (a missing bias, an unwanted gradient).
        if (!t || !t->defined()) continue;
        if (!key) {
            key = t;
            continue;
        }
        G2L_CHECK(t->device() == key->device(), op, ": tensors must be on one device, got ",
                  key->desc(), " and ", t->desc());
    }
    // The first defined tensor picks the device and dtype for the whole call.
    G2L_CHECK(key, op, ": no defined tensor to dispatch on");
    return *key;
}

void no_kernel(const char* op, const Tensor& t) {
    ::g2l::fail(__FILE__, __LINE__, __func__, "kernel registered",
                cat(op, ": no ", t.device().str(), " kernel for this op (tensor ", t.desc(),
                    "); move the tensors with .to(Device::cpu())"));
}

void bad_dtype(const char* op, const Tensor& t, Types types) {
    ::g2l::fail(__FILE__, __LINE__, __func__, "supported dtype",
                cat(op, ": expected an f32 or f64", types == Types::FloatOrI32 ? " or i32" : "",
                    " tensor, got ", t.desc()));
}

}  // namespace g2l::kernels::detail
