// SPDX-License-Identifier: MIT
// Differentiable element-wise ops. All take f32/f64 CPU tensors of any shape (0-d included) and
// throw g2l::Error naming the op and the offending tensor for undefined, i32 or non-CPU input.
//
// Binary ops broadcast like NumPy: shapes are aligned from the right, a missing or size-1
// dimension stretches to the other's size; anything else throws naming both shapes. The gradient
// of each input is summed back to that input's shape. Equal shapes take a fast path.
#pragma once

#include "core/tensor.h"

namespace g2l::nn {

/// The broadcast of two shapes (e.g. [2, 3, 4] and [3, 1] -> [2, 3, 4]); throws naming `op`
/// and both shapes when they are incompatible.
Shape broadcast_shape(const char* op, const Shape& a, const Shape& b);

/// a + b with broadcasting. Both inputs must share dtype.
Tensor add(const Tensor& a, const Tensor& b);
/// a - b with broadcasting.
Tensor sub(const Tensor& a, const Tensor& b);
/// a * b (element-wise) with broadcasting.
Tensor mul(const Tensor& a, const Tensor& b);
/// a / b with broadcasting (IEEE semantics for division by 0).
Tensor div(const Tensor& a, const Tensor& b);

/// x + s.
Tensor add_scalar(const Tensor& x, double s);
/// x * s.
Tensor mul_scalar(const Tensor& x, double s);
/// -x.
Tensor neg(const Tensor& x);
/// e^x.
Tensor exp(const Tensor& x);
/// Natural log (x <= 0 gives -inf / NaN like std::log; no check).
Tensor log(const Tensor& x);
/// Square root (gradient 1 / (2 sqrt x); infinite at 0).
Tensor sqrt(const Tensor& x);
/// x^2.
Tensor square(const Tensor& x);
/// x^p for a finite p (throws naming p otherwise). Gradient p x^(p-1); 0 when p == 0.
Tensor pow_scalar(const Tensor& x, double p);
/// |x| (gradient sign(x), 0 at 0).
Tensor abs(const Tensor& x);
/// 1 / (1 + e^-x), overflow-free for large |x|.
Tensor sigmoid(const Tensor& x);
/// Hyperbolic tangent.
Tensor tanh(const Tensor& x);
/// min(max(x, lo), hi). Throws if lo or hi is NaN or lo > hi. Gradient passes where
/// lo <= x <= hi (as PyTorch).
Tensor clamp(const Tensor& x, double lo, double hi);

}  // namespace g2l::nn

namespace g2l {

// Operators live in namespace g2l (Tensor's namespace) so argument-dependent lookup finds them.

/// nn::add.
Tensor operator+(const Tensor& a, const Tensor& b);
/// nn::sub.
Tensor operator-(const Tensor& a, const Tensor& b);
/// nn::mul.
Tensor operator*(const Tensor& a, const Tensor& b);
/// nn::div.
Tensor operator/(const Tensor& a, const Tensor& b);
/// nn::neg.
Tensor operator-(const Tensor& x);
/// x + s.
Tensor operator+(const Tensor& x, double s);
/// x - s.
Tensor operator-(const Tensor& x, double s);
/// x * s.
Tensor operator*(const Tensor& x, double s);
/// x * (1 / s) (s == 0 gives inf / NaN, IEEE).
Tensor operator/(const Tensor& x, double s);
/// s + x.
Tensor operator+(double s, const Tensor& x);
/// s - x.
Tensor operator-(double s, const Tensor& x);
/// s * x.
Tensor operator*(double s, const Tensor& x);
/// s / x (element-wise; gradient -s / x^2).
Tensor operator/(double s, const Tensor& x);

}  // namespace g2l
