// SPDX-License-Identifier: MIT
// linear / conv1x1 / matmul: the dispatch points (kernels/dispatch.h) over the CPU GEMM and bias
// kernels (gemm_cpu.cpp, bias_cpu.cpp).
#include "kernels/linear.h"

#include <type_traits>

#include "kernels/bias.h"
#include "kernels/dispatch.h"
#include "kernels/gemm.h"

namespace g2l::kernels {

namespace {
bool wanted(const Tensor* t) { return t && t->defined(); }
}  // namespace

void linear_fwd(const Tensor& x, const Tensor& w, const Tensor& b, Tensor& y) {
    const int64_t M = x.size(0), Cin = x.size(1), Cout = w.size(0);
    dispatch("linear", {&x, &w, &b, &y}, [&](auto tag) {
        using T = decltype(tag);
        // w is stored [Cout, Cin] (PyTorch's layout, so imported weights load as they are); trans_b
        // reads it as [Cin, Cout] without a transposed copy.
        gemm_cpu<T>(false, true, M, Cout, Cin, T(1), x.data<T>(), Cin, w.data<T>(), Cin, T(0),
                    y.data<T>(), Cout);
        // A [M, Cout] row is a [1, Cout, 1] bias pattern; M rows = "B" in the [B, C, N] kernel.
        if (b.defined()) add_bias_bcn_cpu<T>(y.data<T>(), b.data<T>(), M, Cout, 1);
    });
}

void linear_bwd(const Tensor& x, const Tensor& w, const Tensor& dy, Tensor* dx, Tensor* dw,
                Tensor* db) {
    const int64_t M = x.size(0), Cin = x.size(1), Cout = w.size(0);
    dispatch("linear backward", {&dy, &x, &w, dx, dw, db}, [&](auto tag) {
        using T = decltype(tag);
        if (wanted(dx))  // dx = dy w : [M, Cout] x [Cout, Cin]
            gemm_cpu<T>(false, false, M, Cin, Cout, T(1), dy.data<T>(), Cout, w.data<T>(), Cin,
                        T(0), dx->data<T>(), Cin);
        if (wanted(dw))  // dw = dy^T x : [Cout, M] x [M, Cin]
            gemm_cpu<T>(true, false, Cout, Cin, M, T(1), dy.data<T>(), Cout, x.data<T>(), Cin,
                        T(0), dw->data<T>(), Cin);
        if (wanted(db)) bias_grad_bcn_cpu<T>(dy.data<T>(), db->data<T>(), M, Cout, 1, false);
    });
}

void conv1x1_fwd(const Tensor& x, const Tensor& w, const Tensor& b, Tensor& y) {
    const int64_t B = x.size(0), Cin = x.size(1), N = x.size(2), Cout = w.size(0);
    dispatch("conv1x1", {&x, &w, &b, &y}, [&](auto tag) {
        using T = decltype(tag);
        // y[b] = w x[b] + bias: [Cout, Cin] x [Cin, N], w packed once for the batch; the float
        // GEMM adds the bias to each tile while it is in cache
        GemmEpilogue ep;
        // Only the float GEMM has the epilogue; for double the bias is a separate pass below.
        const bool fused = std::is_same_v<T, float> && b.defined();
        if constexpr (std::is_same_v<T, float>) ep.bias = fused ? b.data<float>() : nullptr;
        gemm_batched_cpu<T>(false, false, Cout, N, Cin, T(1), w.data<T>(), Cin, x.data<T>(),
                            N, Cin * N, T(0), y.data<T>(), N, Cout * N, B, fused ? &ep : nullptr);
        if (b.defined() && !fused) add_bias_bcn_cpu<T>(y.data<T>(), b.data<T>(), B, Cout, N);
    });
}

void conv1x1_bwd(const Tensor& x, const Tensor& w, const Tensor& dy, Tensor* dx, Tensor* dw,
                 Tensor* db) {
    const int64_t B = x.size(0), Cin = x.size(1), N = x.size(2), Cout = w.size(0);
    dispatch("conv1x1 backward", {&dy, &x, &w, dx, dw, db}, [&](auto tag) {
        using T = decltype(tag);
        if (wanted(dx))  // dx[b] = w^T dy[b] : [Cin, Cout] x [Cout, N]
            gemm_batched_cpu<T>(true, false, Cin, N, Cout, T(1), w.data<T>(), Cin, dy.data<T>(),
                                N, Cout * N, T(0), dx->data<T>(), N, Cin * N, B);
        if (wanted(dw))  // dw = sum_b dy[b] x[b]^T : [Cout, N] x [N, Cin], fixed b order
            // The first sample overwrites dw, later ones add, in sample order: a fixed sum order.
            for (int64_t bi = 0; bi < B; ++bi)
                gemm_cpu<T>(false, true, Cout, Cin, N, T(1), dy.data<T>() + bi * Cout * N, N,
                            x.data<T>() + bi * Cin * N, N, bi ? T(1) : T(0), dw->data<T>(), Cin);
        if (wanted(db)) bias_grad_bcn_cpu<T>(dy.data<T>(), db->data<T>(), B, Cout, N, false);
    });
}

void matmul_fwd(const Tensor& a, const Tensor& b, Tensor& y) {
    const int64_t M = a.size(0), K = a.size(1), N = b.size(1);
    dispatch("matmul", {&a, &b, &y}, [&](auto tag) {
        using T = decltype(tag);
        gemm_cpu<T>(false, false, M, N, K, T(1), a.data<T>(), K, b.data<T>(), N, T(0),
                    y.data<T>(), N);
    });
}

void matmul_bwd(const Tensor& a, const Tensor& b, const Tensor& dy, Tensor* da, Tensor* db) {
    const int64_t M = a.size(0), K = a.size(1), N = b.size(1);
    dispatch("matmul backward", {&dy, &a, &b, da, db}, [&](auto tag) {
        using T = decltype(tag);
        if (wanted(da))  // da = dy b^T
            gemm_cpu<T>(false, true, M, K, N, T(1), dy.data<T>(), N, b.data<T>(), N, T(0),
                        da->data<T>(), K);
        if (wanted(db))  // db = a^T dy
            gemm_cpu<T>(true, false, K, N, M, T(1), a.data<T>(), K, dy.data<T>(), N, T(0),
                        db->data<T>(), N);
    });
}

}  // namespace g2l::kernels
