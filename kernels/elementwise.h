// SPDX-License-Identifier: MIT
// Element-wise math: unary maps with their derivatives, and binary ops with NumPy broadcasting.
// All buffers are contiguous row-major; the caller (nn/ops/elementwise.cpp) checks shapes.
#pragma once

#include <cstdint>
#include <vector>

#include "core/tensor.h"

namespace g2l::kernels {

/// Unary maps. Parameters p0/p1: Pow exponent p0; Clamp bounds [p0, p1]; AddScalar/MulScalar p0.
enum class UnaryOp {
    Neg,
    Exp,
    Log,
    Sqrt,
    Square,
    Pow,
    Abs,
    Sigmoid,
    Tanh,
    Clamp,
    AddScalar,
    MulScalar
};

/// Whether unary_bwd_cpu reads x (the input) for `op`.
bool unary_bwd_needs_x(UnaryOp op);
/// Whether unary_bwd_cpu reads y (the forward output) for `op`.
bool unary_bwd_needs_y(UnaryOp op);

/// y[i] = op(x[i]) for n elements.
template <class T>
void unary_fwd_cpu(UnaryOp op, const T* x, T* y, int64_t n, double p0, double p1);

/// dx[i] = dy[i] * op'(x[i]) (written, not added). x / y may be null when the op does not need
/// them (see unary_bwd_needs_x / _y). Conventions: d|x|/dx = 0 at 0; clamp passes the gradient
/// where lo <= x <= hi; pow with p == 0 has gradient 0.
template <class T>
void unary_bwd_cpu(UnaryOp op, const T* x, const T* y, const T* dy, T* dx, int64_t n, double p0,
                   double p1);

enum class BinaryOp { Add, Sub, Mul, Div };

/// Index plan for y = a op b with broadcasting. Dimensions of size 1 are dropped and adjacent
/// dimensions that are contiguous for both inputs are merged, so the inner loop is as long as
/// possible. Strides are in elements, 0 where an input is broadcast.
struct BroadcastPlan {
    std::vector<int64_t> shape;     ///< collapsed output shape (at least one dimension)
    std::vector<int64_t> a_stride;  ///< per collapsed dimension
    std::vector<int64_t> b_stride;
    int64_t numel = 1;
};

/// Builds the plan. out_shape must be the broadcast of a_shape and b_shape (shapes are aligned
/// from the right; a missing or size-1 dimension broadcasts). The caller checks compatibility.
BroadcastPlan make_broadcast_plan(const std::vector<int64_t>& out_shape,
                                  const std::vector<int64_t>& a_shape,
                                  const std::vector<int64_t>& b_shape);

/// y[k] = a[.] op b[.] over plan.numel output elements (y is contiguous in the output shape).
template <class T>
void binary_cpu(BinaryOp op, const T* a, const T* b, T* y, const BroadcastPlan& plan);

// ---- tensor-level entry points: one dispatch on (device, dtype) each ----

/// y = op(x) (x, y same shape).
void unary_fwd(UnaryOp op, const Tensor& x, Tensor& y, double p0, double p1);
/// dx = dy op'(x); x / y may be undefined when the op does not read them.
void unary_bwd(UnaryOp op, const Tensor& x, const Tensor& y, const Tensor& dy, Tensor& dx,
               double p0, double p1);
/// y = a op b with broadcasting to y's shape.
void binary(BinaryOp op, const Tensor& a, const Tensor& b, Tensor& y);

}  // namespace g2l::kernels
