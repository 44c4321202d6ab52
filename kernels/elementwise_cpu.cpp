// SPDX-License-Identifier: MIT
#include "kernels/elementwise.h"

#include <cmath>

#include "core/error.h"

namespace g2l::kernels {

namespace {

constexpr int64_t kParallelMin = 32768;  // below this, thread start-up costs more than it saves

// Element-wise loops use a static schedule and no reductions, so every element is computed the
// same way whatever the thread count.
template <class T, class F>
void map1(const T* x, T* y, int64_t n, F f) {
#pragma omp parallel for schedule(static) if (n > kParallelMin)
    for (int64_t i = 0; i < n; ++i) y[i] = f(x[i]);
}

template <class T, class F>
void map2(const T* a, const T* b, T* y, int64_t n, F f) {
#pragma omp parallel for schedule(static) if (n > kParallelMin)
    for (int64_t i = 0; i < n; ++i) y[i] = f(a[i], b[i]);
}

// Broadcast loop: the output is walked row by row over the innermost collapsed dimension; each
// row's input offsets come from its multi-index. The common stride patterns of the inner loop
// (both contiguous, one input broadcast) get their own loops so the compiler can vectorise them.
template <class T, class F>
void bcast_loop(const T* a, const T* b, T* y, const BroadcastPlan& p, F f) {
    const int64_t r = int64_t(p.shape.size());
    const int64_t inner = p.shape[size_t(r - 1)];
    const int64_t sa = p.a_stride[size_t(r - 1)], sb = p.b_stride[size_t(r - 1)];
    const int64_t rows = p.numel / inner;
#pragma omp parallel for schedule(static) if (p.numel > kParallelMin)
    for (int64_t row = 0; row < rows; ++row) {
        int64_t oa = 0, ob = 0, rem = row;
        for (int64_t k = r - 2; k >= 0; --k) {
            const int64_t c = rem % p.shape[size_t(k)];
            rem /= p.shape[size_t(k)];
            oa += c * p.a_stride[size_t(k)];
            ob += c * p.b_stride[size_t(k)];
        }
        const T* pa = a + oa;
        const T* pb = b + ob;
        T* py = y + row * inner;
        if (sa == 1 && sb == 1) {
            for (int64_t i = 0; i < inner; ++i) py[i] = f(pa[i], pb[i]);
        } else if (sa == 1 && sb == 0) {
            const T vb = pb[0];
            for (int64_t i = 0; i < inner; ++i) py[i] = f(pa[i], vb);
        } else if (sa == 0 && sb == 1) {
            const T va = pa[0];
            for (int64_t i = 0; i < inner; ++i) py[i] = f(va, pb[i]);
        } else {
            for (int64_t i = 0; i < inner; ++i) py[i] = f(pa[i * sa], pb[i * sb]);
        }
    }
}

template <class T, class F>
void binary_dispatch(const T* a, const T* b, T* y, const BroadcastPlan& p, F f) {
    if (p.shape.size() == 1 && p.a_stride[0] == 1 && p.b_stride[0] == 1)
        map2(a, b, y, p.numel, f);  // equal shapes: no index math at all
    else
        bcast_loop(a, b, y, p, f);
}

}  // namespace

// Which tensor each backward reads, so that the op keeps only that one alive. exp, sqrt,
// sigmoid and tanh have derivatives that are cheapest in terms of their output y.
bool unary_bwd_needs_x(UnaryOp op) {
    return op == UnaryOp::Log || op == UnaryOp::Square || op == UnaryOp::Pow ||
           op == UnaryOp::Abs || op == UnaryOp::Clamp;
}

bool unary_bwd_needs_y(UnaryOp op) {
    return op == UnaryOp::Exp || op == UnaryOp::Sqrt || op == UnaryOp::Sigmoid ||
           op == UnaryOp::Tanh;
}

template <class T>
void unary_fwd_cpu(UnaryOp op, const T* x, T* y, int64_t n, double p0, double p1) {
    const T a = T(p0), b = T(p1);
    switch (op) {
        case UnaryOp::Neg: map1(x, y, n, [](T v) { return -v; }); return;
        case UnaryOp::Exp: map1(x, y, n, [](T v) { return std::exp(v); }); return;
        case UnaryOp::Log: map1(x, y, n, [](T v) { return std::log(v); }); return;
        case UnaryOp::Sqrt: map1(x, y, n, [](T v) { return std::sqrt(v); }); return;
        case UnaryOp::Square: map1(x, y, n, [](T v) { return v * v; }); return;
        case UnaryOp::Pow: map1(x, y, n, [a](T v) { return std::pow(v, a); }); return;
        case UnaryOp::Abs: map1(x, y, n, [](T v) { return std::fabs(v); }); return;
        case UnaryOp::Sigmoid:
            // Two branches so exp never overflows: for v < 0 use e^v / (1 + e^v).
            map1(x, y, n, [](T v) {
                if (v >= T(0)) return T(1) / (T(1) + std::exp(-v));
                const T e = std::exp(v);
                return e / (T(1) + e);
            });
            return;
        case UnaryOp::Tanh: map1(x, y, n, [](T v) { return std::tanh(v); }); return;
        case UnaryOp::Clamp:
            map1(x, y, n, [a, b](T v) { return v < a ? a : (v > b ? b : v); });
            return;
        case UnaryOp::AddScalar: map1(x, y, n, [a](T v) { return v + a; }); return;
        case UnaryOp::MulScalar: map1(x, y, n, [a](T v) { return v * a; }); return;
    }
    G2L_ASSERT(false);
}

template <class T>
void unary_bwd_cpu(UnaryOp op, const T* x, const T* y, const T* dy, T* dx, int64_t n, double p0,
                   double p1) {
    const T a = T(p0), b = T(p1);
    G2L_ASSERT(!unary_bwd_needs_x(op) || x != nullptr);
    G2L_ASSERT(!unary_bwd_needs_y(op) || y != nullptr);
    switch (op) {
        case UnaryOp::Neg: map1(dy, dx, n, [](T g) { return -g; }); return;
        case UnaryOp::AddScalar: map1(dy, dx, n, [](T g) { return g; }); return;
        case UnaryOp::MulScalar: map1(dy, dx, n, [a](T g) { return g * a; }); return;
        case UnaryOp::Exp: map2(dy, y, dx, n, [](T g, T v) { return g * v; }); return;
        case UnaryOp::Log: map2(dy, x, dx, n, [](T g, T v) { return g / v; }); return;
        case UnaryOp::Sqrt: map2(dy, y, dx, n, [](T g, T v) { return g / (T(2) * v); }); return;
        case UnaryOp::Square: map2(dy, x, dx, n, [](T g, T v) { return T(2) * v * g; }); return;
        case UnaryOp::Pow:
            map2(dy, x, dx, n,
                 // x^0 is constant: its gradient is 0, not 0 * pow(0, -1) = NaN at x = 0.
                 [a](T g, T v) { return a == T(0) ? T(0) : g * a * std::pow(v, a - T(1)); });
            return;
        case UnaryOp::Abs:
            // The subgradient at 0 is taken as 0 (sign(0) = 0), as PyTorch does.
            map2(dy, x, dx, n, [](T g, T v) { return v > T(0) ? g : (v < T(0) ? -g : T(0)); });
            return;
        case UnaryOp::Sigmoid:
            map2(dy, y, dx, n, [](T g, T v) { return g * v * (T(1) - v); });
            return;
        case UnaryOp::Tanh: map2(dy, y, dx, n, [](T g, T v) { return g * (T(1) - v * v); }); return;
        case UnaryOp::Clamp:
            // The bounds themselves pass the gradient (inclusive), matching PyTorch's clamp.
            map2(dy, x, dx, n, [a, b](T g, T v) { return (v >= a && v <= b) ? g : T(0); });
            return;
    }
    G2L_ASSERT(false);
}

BroadcastPlan make_broadcast_plan(const std::vector<int64_t>& out_shape,
                                  const std::vector<int64_t>& a_shape,
                                  const std::vector<int64_t>& b_shape) {
    const size_t r = out_shape.size();
    G2L_ASSERT(a_shape.size() <= r && b_shape.size() <= r);
    // Element strides of each input in the output's (right-aligned) dimensions; 0 = broadcast.
    auto strides = [&](const std::vector<int64_t>& s) {
        std::vector<int64_t> st(r, 0);
        int64_t acc = 1;
        for (size_t k = r; k-- > 0;) {
            const size_t lead = r - s.size();
            const int64_t n = k >= lead ? s[k - lead] : 1;
            // NumPy broadcasting: each input dim is 1 or the output's (broadcast_shape checked it).
            G2L_ASSERT(n == 1 || n == out_shape[k]);
            st[k] = n == 1 ? 0 : acc;
            acc *= n;
        }
        return st;
    };
    const std::vector<int64_t> sa = strides(a_shape), sb = strides(b_shape);
    BroadcastPlan p;
    for (size_t k = 0; k < r; ++k) {
        const int64_t n = out_shape[k];
        p.numel *= n;
        if (n == 1) continue;
        // Merge into the previous dimension when both inputs step through it contiguously.
        if (!p.shape.empty() && p.a_stride.back() == sa[k] * n && p.b_stride.back() == sb[k] * n) {
            p.shape.back() *= n;
            p.a_stride.back() = sa[k];
            p.b_stride.back() = sb[k];
        } else {
            p.shape.push_back(n);
            p.a_stride.push_back(sa[k]);
            p.b_stride.push_back(sb[k]);
        }
    }
    if (p.shape.empty()) {  // every dimension is 1: a single element, both inputs at offset 0
        p.shape = {1};
        p.a_stride = {1};
        p.b_stride = {1};
    }
    return p;
}

template <class T>
void binary_cpu(BinaryOp op, const T* a, const T* b, T* y, const BroadcastPlan& p) {
    if (p.numel == 0) return;
    switch (op) {
        case BinaryOp::Add: binary_dispatch(a, b, y, p, [](T u, T v) { return u + v; }); return;
        case BinaryOp::Sub: binary_dispatch(a, b, y, p, [](T u, T v) { return u - v; }); return;
        case BinaryOp::Mul: binary_dispatch(a, b, y, p, [](T u, T v) { return u * v; }); return;
        case BinaryOp::Div: binary_dispatch(a, b, y, p, [](T u, T v) { return u / v; }); return;
    }
    G2L_ASSERT(false);
}

template void unary_fwd_cpu<float>(UnaryOp, const float*, float*, int64_t, double, double);
template void unary_fwd_cpu<double>(UnaryOp, const double*, double*, int64_t, double, double);
template void unary_bwd_cpu<float>(UnaryOp, const float*, const float*, const float*, float*,
                                   int64_t, double, double);
template void unary_bwd_cpu<double>(UnaryOp, const double*, const double*, const double*, double*,
                                    int64_t, double, double);
template void binary_cpu<float>(BinaryOp, const float*, const float*, float*, const BroadcastPlan&);
template void binary_cpu<double>(BinaryOp, const double*, const double*, double*,
                                 const BroadcastPlan&);

}  // namespace g2l::kernels
