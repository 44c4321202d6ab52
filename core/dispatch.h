// SPDX-License-Identifier: MIT
// Argument checks shared by the ops of nn/: same dtype and device, expected rank. The choice of
// kernel by (device, dtype) is made once per op in kernels/ (kernels/dispatch.h).
#pragma once

#include <initializer_list>

#include "core/tensor.h"

namespace g2l {

/// Throws unless all defined tensors share dtype and device; names the op and both tensors.
void require_same(const char* op, std::initializer_list<const Tensor*> ts);

/// Throws unless t.dim() == rank; `layout` names the expected layout, e.g. "[B, C, N]".
void require_rank(const char* op, const char* name, const Tensor& t, int64_t rank,
                  const char* layout);

}  // namespace g2l
