// SPDX-License-Identifier: MIT
// The one dispatch point of every op. nn/ calls the tensor-level entry points of kernels/
// (relu_fwd, conv2d_bwd, ...); each of them makes exactly one dispatch(...) call, which picks the
// backend from the tensors' device and the element type from the first tensor's dtype, then
// runs that backend's kernel (the *_cpu templates next to it; a CUDA backend adds its kernels
// at the same call). A tensor on a device that has no kernel for the op is a clear error naming
// the op and the tensor, never a silent copy to the CPU.
#pragma once

#include <cstdint>
#include <initializer_list>

#include "core/tensor.h"

namespace g2l::kernels {

/// Element types an op is instantiated for.
enum class Types { Float, FloatOrI32 };

namespace detail {
/// The tensor whose device and dtype select the kernel: the first defined one of ts. Throws
/// (naming the op) if none is defined, or unless every defined tensor is on its device.
const Tensor& dispatch_key(const char* op, std::initializer_list<const Tensor*> ts);
/// Throws: `op` has no kernel on t's device (names the op, the tensor and the device).
[[noreturn]] void no_kernel(const char* op, const Tensor& t);
/// Throws: `op` has no kernel for t's dtype.
[[noreturn]] void bad_dtype(const char* op, const Tensor& t, Types types);
}  // namespace detail

/// Calls cpu(T{}) with T the element type of the first defined tensor of `ts` (float or double;
/// also int32_t with Types::FloatOrI32) when the tensors live on the CPU. Every defined tensor
/// of `ts` must be on the same device. `types` is a template argument so that an op without an
/// int32 kernel never instantiates one (any compiler, any optimisation level).
template <Types types = Types::Float, class Cpu>
void dispatch(const char* op, std::initializer_list<const Tensor*> ts, Cpu&& cpu) {
    const Tensor& key = detail::dispatch_key(op, ts);
    if (!key.device().is_cpu()) detail::no_kernel(op, key);
    switch (key.dtype()) {
        case DType::F32: cpu(float{}); return;
        case DType::F64: cpu(double{}); return;
        case DType::I32:
            if constexpr (types == Types::FloatOrI32) {
                cpu(int32_t{});
                return;
            }
            break;
    }
    detail::bad_dtype(op, key, types);
}

/// Pointer to the data of an optional tensor (nullptr when undefined).
template <class T> T* data_or_null(Tensor* t) { return t && t->defined() ? t->data<T>() : nullptr; }
template <class T> const T* data_or_null(const Tensor& t) {
    return t.defined() ? t.data<T>() : nullptr;
}

}  // namespace g2l::kernels
