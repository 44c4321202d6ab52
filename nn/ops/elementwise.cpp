// SPDX-License-Identifier: MIT
#include "nn/ops/elementwise.h"

#include <cmath>

#include "core/autograd.h"
#include "kernels/elementwise.h"
#include "kernels/reduce.h"
#include "nn/ops/dim_utils.h"

namespace g2l::nn {

namespace {

using kernels::BinaryOp;
using kernels::UnaryOp;

// y = a op b at out_shape, no autograd. Also used by the backward closures (dout op b).
Tensor binary_raw(BinaryOp op, const Tensor& a, const Tensor& b, const Shape& out_shape) {
    Tensor y = Tensor::empty(out_shape, a.dtype(), a.device());
    kernels::binary(op, a, b, y);
    return y;
}

// The gradient of a broadcast input: g summed down to `shape` (g itself when nothing to sum).
Tensor sum_to(const Tensor& g, const Shape& shape) {
    // No copy when nothing was broadcast: the gradient is passed on by reference (Grads clones
    // before it ever accumulates into an aliased tensor).
    if (g.shape() == shape) return g;
    Tensor r = Tensor::empty(shape, g.dtype(), g.device());
    kernels::sum_to_shape(g, r);
    return r;
}

Tensor unary_raw(UnaryOp op, const Tensor& x, double p0, double p1) {
    Tensor y = Tensor::empty(x.shape(), x.dtype(), x.device());
    kernels::unary_fwd(op, x, y, p0, p1);
    return y;
}

Tensor binary(const char* name, BinaryOp op, const Tensor& a, const Tensor& b) {
    detail::check_float_input(name, "a", a);
    detail::check_float_input(name, "b", b);
    require_same(name, {&a, &b});
    const Shape out_shape = broadcast_shape(name, a.shape(), b.shape());
    const Tensor y = binary_raw(op, a, b, out_shape);
    // Captures: the input shapes (for sum_to), and only the tensors this op's derivative reads.
    const bool keep_a = op == BinaryOp::Mul;
    const bool keep_b = op == BinaryOp::Mul || op == BinaryOp::Div;
    return autograd::record(
        name, y, {a, b},
        [op, out_shape, sa = a.shape(), sb = b.shape(), ad = keep_a ? a.detach() : Tensor(),
         bd = keep_b ? b.detach() : Tensor(),
         yd = op == BinaryOp::Div ? y.detach() : Tensor()](const Tensor& dy, autograd::Grads& g) {
            switch (op) {
                case BinaryOp::Add:
                    if (g.needs(0)) g.add(0, sum_to(dy, sa));
                    if (g.needs(1)) g.add(1, sum_to(dy, sb));
                    return;
                case BinaryOp::Sub:
                    if (g.needs(0)) g.add(0, sum_to(dy, sa));
                    if (g.needs(1)) g.add(1, unary_raw(UnaryOp::Neg, sum_to(dy, sb), 0, 0));
                    return;
                case BinaryOp::Mul:
                    if (g.needs(0))
                        g.add(0, sum_to(binary_raw(BinaryOp::Mul, dy, bd, out_shape), sa));
                    if (g.needs(1))
                        g.add(1, sum_to(binary_raw(BinaryOp::Mul, dy, ad, out_shape), sb));
                    return;
                case BinaryOp::Div: {
                    // d(a/b)/da = 1/b; d(a/b)/db = -a/b^2 = -(1/b) * y.
                    const Tensor t = binary_raw(BinaryOp::Div, dy, bd, out_shape);
                    if (g.needs(0)) g.add(0, sum_to(t, sa));
                    if (g.needs(1)) {
                        const Tensor ty = binary_raw(BinaryOp::Mul, t, yd, out_shape);
                        g.add(1, unary_raw(UnaryOp::Neg, sum_to(ty, sb), 0, 0));
                    }
                    return;
                }
            }
        });
}

Tensor unary(const char* name, UnaryOp op, const Tensor& x, double p0 = 0, double p1 = 0) {
    detail::check_float_input(name, "x", x);
    const Tensor y = unary_raw(op, x, p0, p1);
    // Keep x or y alive only when the derivative reads it, so a chain of ops does not pin every
    // intermediate activation until backward.
    const Tensor xd = kernels::unary_bwd_needs_x(op) ? x.detach() : Tensor();
    const Tensor yd = kernels::unary_bwd_needs_y(op) ? y.detach() : Tensor();
    return autograd::record(
        name, y, {x}, [op, p0, p1, xd, yd](const Tensor& dy, autograd::Grads& g) {
            Tensor dx = Tensor::empty(dy.shape(), dy.dtype(), dy.device());
            kernels::unary_bwd(op, xd, yd, dy, dx, p0, p1);
            g.add(0, dx);
        });
}

}  // namespace

Shape broadcast_shape(const char* op, const Shape& a, const Shape& b) {
    const size_t r = std::max(a.size(), b.size());
    Shape out(r);
    for (size_t k = 0; k < r; ++k) {
        // k counts from the right.
        const int64_t na = k < a.size() ? a[a.size() - 1 - k] : 1;
        const int64_t nb = k < b.size() ? b[b.size() - 1 - k] : 1;
        G2L_CHECK(na == nb || na == 1 || nb == 1, op, ": shapes ", shape_str(a), " and ",
                  shape_str(b), " cannot be broadcast (dim -", k + 1, ": ", na, " vs ", nb, ")");
        out[r - 1 - k] = na == 1 ? nb : na;
    }
    return out;
}

Tensor add(const Tensor& a, const Tensor& b) { return binary("add", BinaryOp::Add, a, b); }
Tensor sub(const Tensor& a, const Tensor& b) { return binary("sub", BinaryOp::Sub, a, b); }
Tensor mul(const Tensor& a, const Tensor& b) { return binary("mul", BinaryOp::Mul, a, b); }
Tensor div(const Tensor& a, const Tensor& b) { return binary("div", BinaryOp::Div, a, b); }

Tensor add_scalar(const Tensor& x, double s) {
    return unary("add_scalar", UnaryOp::AddScalar, x, s);
}
Tensor mul_scalar(const Tensor& x, double s) {
    return unary("mul_scalar", UnaryOp::MulScalar, x, s);
}
Tensor neg(const Tensor& x) { return unary("neg", UnaryOp::Neg, x); }
Tensor exp(const Tensor& x) { return unary("exp", UnaryOp::Exp, x); }
Tensor log(const Tensor& x) { return unary("log", UnaryOp::Log, x); }
Tensor sqrt(const Tensor& x) { return unary("sqrt", UnaryOp::Sqrt, x); }
Tensor square(const Tensor& x) { return unary("square", UnaryOp::Square, x); }
Tensor pow_scalar(const Tensor& x, double p) {
    // A non-finite exponent would produce only inf/NaN values and gradients.
    G2L_CHECK(std::isfinite(p), "pow_scalar: exponent p must be finite, got ", p);
    return unary("pow_scalar", UnaryOp::Pow, x, p);
}
Tensor abs(const Tensor& x) { return unary("abs", UnaryOp::Abs, x); }
Tensor sigmoid(const Tensor& x) { return unary("sigmoid", UnaryOp::Sigmoid, x); }
Tensor tanh(const Tensor& x) { return unary("tanh", UnaryOp::Tanh, x); }
Tensor clamp(const Tensor& x, double lo, double hi) {
    G2L_CHECK(!std::isnan(lo) && !std::isnan(hi) && lo <= hi,
              "clamp: needs lo <= hi (no NaN), got lo ", lo, ", hi ", hi);
    return unary("clamp", UnaryOp::Clamp, x, lo, hi);
}

}  // namespace g2l::nn

namespace g2l {

Tensor operator+(const Tensor& a, const Tensor& b) { return nn::add(a, b); }
Tensor operator-(const Tensor& a, const Tensor& b) { return nn::sub(a, b); }
Tensor operator*(const Tensor& a, const Tensor& b) { return nn::mul(a, b); }
Tensor operator/(const Tensor& a, const Tensor& b) { return nn::div(a, b); }
Tensor operator-(const Tensor& x) { return nn::neg(x); }
Tensor operator+(const Tensor& x, double s) { return nn::add_scalar(x, s); }
Tensor operator-(const Tensor& x, double s) { return nn::add_scalar(x, -s); }
Tensor operator*(const Tensor& x, double s) { return nn::mul_scalar(x, s); }
// A multiplication by the reciprocal (one unary op); it may differ from a true division by s
// in the last bit.
Tensor operator/(const Tensor& x, double s) { return nn::mul_scalar(x, 1.0 / s); }
Tensor operator+(double s, const Tensor& x) { return nn::add_scalar(x, s); }
Tensor operator-(double s, const Tensor& x) { return nn::add_scalar(nn::neg(x), s); }
Tensor operator*(double s, const Tensor& x) { return nn::mul_scalar(x, s); }
// s / x as s * x^-1, reusing the differentiable pow rather than adding a kernel.
Tensor operator/(double s, const Tensor& x) { return nn::mul_scalar(nn::pow_scalar(x, -1.0), s); }

}  // namespace g2l
