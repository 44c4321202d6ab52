// SPDX-License-Identifier: MIT
// Small helpers shared by the general ops (elementwise, reduce, softmax, loss, shape): input
// checks that name the op, dimension wrapping, and the [outer, D, inner] view of a dimension.
#pragma once

#include <cstdint>

#include "core/dispatch.h"
#include "core/tensor.h"

namespace g2l::nn::detail {

/// Throws unless x is defined and f32/f64; `what` names the argument ("x", "a"). The device is
/// the kernels' business (kernels/dispatch.h).
inline void check_float_input(const char* op, const char* what, const Tensor& x) {
    G2L_CHECK(x.defined(), op, ": ", what, " is undefined");
    G2L_CHECK(x.dtype() == DType::F32 || x.dtype() == DType::F64, op, ": ", what,
              " must be an f32 or f64 tensor, got ", x.desc());
}

/// dim in [-rank, rank) -> [0, rank). Throws naming the op, the dim and the shape.
inline int64_t wrap_dim(const char* op, int64_t dim, const Shape& shape) {
    const int64_t r = int64_t(shape.size());
    G2L_CHECK(r > 0, op, ": tensor of shape ", shape_str(shape), " has no dimension ", dim);
    G2L_CHECK(dim >= -r && dim < r, op, ": dim ", dim, " is out of range for shape ",
              shape_str(shape), " (valid: ", -r, " .. ", r - 1, ")");
    return dim < 0 ? dim + r : dim;
}

/// A contiguous tensor seen as [outer, D, inner] around dimension d.
struct DimSplit {
    int64_t outer = 1, D = 1, inner = 1;
};

inline DimSplit split_at(const Shape& s, int64_t d) {
    DimSplit p;
    for (int64_t k = 0; k < int64_t(s.size()); ++k) {
        if (k < d)
            p.outer *= s[size_t(k)];
        else if (k == d)
            p.D = s[size_t(k)];
        else
            p.inner *= s[size_t(k)];
    }
    return p;
}

}  // namespace g2l::nn::detail
