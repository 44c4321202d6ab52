// SPDX-License-Identifier: MIT
// Dispatch helpers used by nn/ops: pick the kernel instantiation from a tensor's dtype and
// device, and refuse (loudly) what has no kernel. Never falls back silently.
#pragma once

#include <initializer_list>

#include "core/tensor.h"

namespace g2l {

/// Calls f(T{}) with T = float or double according to `dt`; throws naming `op` otherwise.
/// Usage: dispatch_float(x.dtype(), "relu", [&](auto tag) { using T = decltype(tag); ... });
template <class F>
void dispatch_float(DType dt, const char* op, F&& f) {
    switch (dt) {
        case DType::F32: f(float{}); return;
        case DType::F64: f(double{}); return;
        default: break;
    }
    G2L_CHECK(false, op, ": expected an f32 or f64 tensor, got ", dtype_name(dt));
}

/// Throws unless every defined tensor is on the CPU (for ops that have no CUDA kernel yet).
void require_cpu(const char* op, std::initializer_list<const Tensor*> ts);

/// Throws unless all defined tensors share dtype and device; names the op and both tensors.
void require_same(const char* op, std::initializer_list<const Tensor*> ts);

/// Throws unless t.dim() == rank; `layout` names the expected layout, e.g. "[B, C, N]".
void require_rank(const char* op, const char* name, const Tensor& t, int64_t rank,
                  const char* layout);

}  // namespace g2l
