// SPDX-License-Identifier: MIT
#include "nn/ops/linear.h"

#include "core/autograd.h"
#include "core/dispatch.h"
#include "kernels/bias.h"
#include "kernels/gemm.h"

namespace g2l::nn {

namespace {

void check_weight(const char* op, const Tensor& x, int64_t cin, const Tensor& w, const Tensor& b) {
    require_rank(op, "w", w, 2, "[Cout, Cin]");
    require_same(op, {&x, &w, &b});
    require_cpu(op, {&x, &w, &b});
    G2L_CHECK(w.size(1) == cin, op, ": w ", w.desc(), " expects Cin = ", w.size(1),
              " input channels, x ", x.desc(), " has ", cin);
    if (b.defined())
        G2L_CHECK(b.dim() == 1 && b.size(0) == w.size(0), op, ": bias ", b.desc(),
                  " must be [Cout] = [", w.size(0), "]");
}

}  // namespace

Tensor linear(const Tensor& x, const Tensor& w, const Tensor& b) {
    require_rank("linear", "x", x, 2, "[M, Cin]");
    check_weight("linear", x, x.size(1), w, b);
    const int64_t M = x.size(0), Cin = x.size(1), Cout = w.size(0);
    Tensor y = Tensor::empty({M, Cout}, x.dtype());
    dispatch_float(x.dtype(), "linear", [&](auto tag) {
        using T = decltype(tag);
        kernels::gemm_cpu<T>(false, true, M, Cout, Cin, T(1), x.data<T>(), Cin, w.data<T>(), Cin,
                             T(0), y.data<T>(), Cout);
        // A [M, Cout] row is a [1, Cout, 1] bias pattern; M rows = "B" in the [B, C, N] kernel.
        if (b.defined()) kernels::add_bias_bcn_cpu<T>(y.data<T>(), b.data<T>(), M, Cout, 1);
    });
    return autograd::record("linear", y, {x, w, b}, [x, w](const Tensor& dy, autograd::Grads& g) {
        const int64_t M = x.size(0), Cin = x.size(1), Cout = w.size(0);
        dispatch_float(dy.dtype(), "linear backward", [&](auto tag) {
            using T = decltype(tag);
            if (g.needs(0)) {  // dx = dy w : [M, Cout] x [Cout, Cin]
                Tensor dx = Tensor::empty({M, Cin}, dy.dtype());
                kernels::gemm_cpu<T>(false, false, M, Cin, Cout, T(1), dy.data<T>(), Cout,
                                     w.data<T>(), Cin, T(0), dx.data<T>(), Cin);
                g.add(0, dx);
            }
            if (g.needs(1)) {  // dw = dy^T x : [Cout, M] x [M, Cin]
                Tensor dw = Tensor::empty({Cout, Cin}, dy.dtype());
                kernels::gemm_cpu<T>(true, false, Cout, Cin, M, T(1), dy.data<T>(), Cout,
                                     x.data<T>(), Cin, T(0), dw.data<T>(), Cin);
                g.add(1, dw);
            }
            if (g.needs(2)) {
                Tensor db = Tensor::empty({Cout}, dy.dtype());
                kernels::bias_grad_bcn_cpu<T>(dy.data<T>(), db.data<T>(), M, Cout, 1, false);
                g.add(2, db);
            }
        });
    });
}

Tensor conv1x1(const Tensor& x, const Tensor& w, const Tensor& b) {
    require_rank("conv1x1", "x", x, 3, "[B, Cin, N]");
    check_weight("conv1x1", x, x.size(1), w, b);
    const int64_t B = x.size(0), Cin = x.size(1), N = x.size(2), Cout = w.size(0);
    Tensor y = Tensor::empty({B, Cout, N}, x.dtype());
    dispatch_float(x.dtype(), "conv1x1", [&](auto tag) {
        using T = decltype(tag);
        for (int64_t bi = 0; bi < B; ++bi)  // y[b] = w x[b]: [Cout, Cin] x [Cin, N]
            kernels::gemm_cpu<T>(false, false, Cout, N, Cin, T(1), w.data<T>(), Cin,
                                 x.data<T>() + bi * Cin * N, N, T(0),
                                 y.data<T>() + bi * Cout * N, N);
        if (b.defined()) kernels::add_bias_bcn_cpu<T>(y.data<T>(), b.data<T>(), B, Cout, N);
    });
    return autograd::record("conv1x1", y, {x, w, b}, [x, w](const Tensor& dy,
                                                            autograd::Grads& g) {
        const int64_t B = x.size(0), Cin = x.size(1), N = x.size(2), Cout = w.size(0);
        dispatch_float(dy.dtype(), "conv1x1 backward", [&](auto tag) {
            using T = decltype(tag);
            if (g.needs(0)) {  // dx[b] = w^T dy[b] : [Cin, Cout] x [Cout, N]
                Tensor dx = Tensor::empty({B, Cin, N}, dy.dtype());
                for (int64_t bi = 0; bi < B; ++bi)
                    kernels::gemm_cpu<T>(true, false, Cin, N, Cout, T(1), w.data<T>(), Cin,
                                         dy.data<T>() + bi * Cout * N, N, T(0),
                                         dx.data<T>() + bi * Cin * N, N);
                g.add(0, dx);
            }
            if (g.needs(1)) {  // dw = sum_b dy[b] x[b]^T : [Cout, N] x [N, Cin], fixed b order
                Tensor dw = Tensor::empty({Cout, Cin}, dy.dtype());
                for (int64_t bi = 0; bi < B; ++bi)
                    kernels::gemm_cpu<T>(false, true, Cout, Cin, N, T(1),
                                         dy.data<T>() + bi * Cout * N, N,
                                         x.data<T>() + bi * Cin * N, N, bi ? T(1) : T(0),
                                         dw.data<T>(), Cin);
                g.add(1, dw);
            }
            if (g.needs(2)) {
                Tensor db = Tensor::empty({Cout}, dy.dtype());
                kernels::bias_grad_bcn_cpu<T>(dy.data<T>(), db.data<T>(), B, Cout, N, false);
                g.add(2, db);
            }
        });
    });
}

Tensor matmul(const Tensor& a, const Tensor& b) {
    require_rank("matmul", "a", a, 2, "[M, K]");
    require_rank("matmul", "b", b, 2, "[K, N]");
    require_same("matmul", {&a, &b});
    require_cpu("matmul", {&a, &b});
    G2L_CHECK(a.size(1) == b.size(0), "matmul: inner sizes differ: a ", a.desc(), " b ",
              b.desc());
    const int64_t M = a.size(0), K = a.size(1), N = b.size(1);
    Tensor y = Tensor::empty({M, N}, a.dtype());
    dispatch_float(a.dtype(), "matmul", [&](auto tag) {
        using T = decltype(tag);
        kernels::gemm_cpu<T>(false, false, M, N, K, T(1), a.data<T>(), K, b.data<T>(), N, T(0),
                             y.data<T>(), N);
    });
    return autograd::record("matmul", y, {a, b}, [a, b](const Tensor& dy, autograd::Grads& g) {
        const int64_t M = a.size(0), K = a.size(1), N = b.size(1);
        dispatch_float(dy.dtype(), "matmul backward", [&](auto tag) {
            using T = decltype(tag);
            if (g.needs(0)) {  // da = dy b^T
                Tensor da = Tensor::empty({M, K}, dy.dtype());
                kernels::gemm_cpu<T>(false, true, M, K, N, T(1), dy.data<T>(), N, b.data<T>(), N,
                                     T(0), da.data<T>(), K);
                g.add(0, da);
            }
            if (g.needs(1)) {  // db = a^T dy
                Tensor db = Tensor::empty({K, N}, dy.dtype());
                kernels::gemm_cpu<T>(true, false, K, N, M, T(1), a.data<T>(), K, dy.data<T>(), N,
                                     T(0), db.data<T>(), N);
                g.add(1, db);
            }
        });
    });
}

}  // namespace g2l::nn
