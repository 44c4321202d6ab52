// SPDX-License-Identifier: MIT
#include "nn/ops/concat_conv.h"

#include "core/autograd.h"
#include "core/dispatch.h"
#include "kernels/bias.h"
#include "kernels/gemm.h"

namespace g2l::nn {

namespace {

constexpr const char* kOp = "concat_conv1x1";

// Validates every input; returns the total channel count of the point and global parts.
void check_inputs(const std::vector<Tensor>& xs, const std::vector<Tensor>& gs, const Tensor& w,
                  const Tensor& b, int64_t& cp, int64_t& cg) {
    G2L_CHECK(!xs.empty(), kOp, ": needs at least one per-point feature [B, Ci, N]");
    const Tensor& x0 = xs[0];
    G2L_CHECK(x0.defined() && x0.dim() == 3 && x0.size(0) > 0, kOp,
              ": expected point_feats[0] as [B, Ci, N] with B > 0, got ",
              x0.defined() ? x0.desc() : std::string("undefined"));
    cp = cg = 0;
    for (size_t i = 0; i < xs.size(); ++i) {
        G2L_CHECK(xs[i].defined(), kOp, ": point_feats[", i, "] is undefined");
        G2L_CHECK(xs[i].dim() == 3, kOp, ": expected point_feats[", i, "] as [B, Ci, N], got ",
                  xs[i].desc());
        G2L_CHECK(xs[i].size(0) == x0.size(0) && xs[i].size(2) == x0.size(2), kOp,
                  ": point_feats[", i, "] ", xs[i].desc(),
                  " disagrees on B or N with point_feats[0] ", x0.desc());
        require_same(kOp, {&x0, &xs[i]});
        require_cpu(kOp, {&xs[i]});
        cp += xs[i].size(1);
    }
    for (size_t j = 0; j < gs.size(); ++j) {
        G2L_CHECK(gs[j].defined(), kOp, ": global_feats[", j, "] is undefined");
        G2L_CHECK(gs[j].dim() == 2 && gs[j].size(0) == x0.size(0), kOp,
                  ": expected global_feats[", j, "] as [B, Cj] with B = ", x0.size(0), ", got ",
                  gs[j].desc());
        require_same(kOp, {&x0, &gs[j]});
        require_cpu(kOp, {&gs[j]});
        cg += gs[j].size(1);
    }
    require_rank(kOp, "w", w, 2, "[Cout, sum Ci + sum Cj]");
    require_same(kOp, {&x0, &w, &b});
    require_cpu(kOp, {&w, &b});
    G2L_CHECK(w.size(1) == cp + cg, kOp, ": w ", w.desc(), " has ", w.size(1),
              " input columns, the features have ", cp, " per-point + ", cg, " global = ",
              cp + cg, " channels");
    if (b.defined())
        G2L_CHECK(b.dim() == 1 && b.size(0) == w.size(0), kOp, ": bias ", b.desc(),
                  " must be [Cout] = [", w.size(0), "]");
}

// Forward: per-point GEMMs accumulate into y, the global part becomes a per-(b, channel) bias.
template <class T>
void forward(const std::vector<Tensor>& xs, const std::vector<Tensor>& gs, const Tensor& w,
             const Tensor& b, Tensor& y) {
    const int64_t B = y.size(0), Cout = y.size(1), N = y.size(2), Ctot = w.size(1);
    const T* pw = w.data<T>();
    T* py = y.data<T>();
    for (int64_t bi = 0; bi < B; ++bi) {
        int64_t off = 0;
        for (size_t i = 0; i < xs.size(); ++i) {  // y[b] (+)= W_i x_i[b]: [Cout, Ci] x [Ci, N]
            const int64_t Ci = xs[i].size(1);
            kernels::gemm_cpu<T>(false, false, Cout, N, Ci, T(1), pw + off, Ctot,
                                 xs[i].data<T>() + bi * Ci * N, N, i ? T(1) : T(0),
                                 py + bi * Cout * N, N);
            off += Ci;
        }
    }
    if (gs.empty() && !b.defined()) return;
    // v[b, o] = bias[o] + sum_j (g_j W_j^T)[b, o]: [B, Cj] x [Cj, Cout] per global block.
    Tensor v = Tensor::zeros({B, Cout}, y.dtype());
    T* pv = v.data<T>();
    if (b.defined()) kernels::add_bias_bcn_cpu<T>(pv, b.data<T>(), B, Cout, 1);
    int64_t off = Ctot;
    for (const Tensor& g : gs) off -= g.size(1);
    for (const Tensor& g : gs) {
        const int64_t Cj = g.size(1);
        kernels::gemm_cpu<T>(false, true, B, Cout, Cj, T(1), g.data<T>(), Cj, pw + off, Ctot,
                             T(1), pv, Cout);
        off += Cj;
    }
    for (int64_t bi = 0; bi < B; ++bi)  // broadcast v[b] over the N points of batch b
        kernels::add_bias_bcn_cpu<T>(py + bi * Cout * N, pv + bi * Cout, 1, Cout, N);
}

// Backward; slot layout of g: point feats [0, P), global feats [P, P + G), w, b.
template <class T>
void backward(const std::vector<Tensor>& xs, const std::vector<Tensor>& gs, const Tensor& w,
              const Tensor& dy, autograd::Grads& g) {
    const size_t P = xs.size(), G = gs.size(), iw = P + G, ib = P + G + 1;
    const int64_t B = dy.size(0), Cout = dy.size(1), N = dy.size(2), Ctot = w.size(1);
    const T* pw = w.data<T>();
    const T* pdy = dy.data<T>();
    bool need_g = g.needs(ib) || (G > 0 && g.needs(iw));
    for (size_t j = 0; j < G; ++j) need_g = need_g || g.needs(P + j);
    // s[b, o] = sum_n dy[b, o, n]: the gradient of the broadcast (global + bias) term.
    Tensor s;
    if (need_g) {
        s = Tensor::empty({B, Cout}, dy.dtype());
        for (int64_t bi = 0; bi < B; ++bi)
            kernels::bias_grad_bcn_cpu<T>(pdy + bi * Cout * N, s.data<T>() + bi * Cout, 1, Cout,
                                          N, false);
    }
    Tensor dw;
    if (g.needs(iw)) dw = Tensor::empty({Cout, Ctot}, dy.dtype());
    int64_t off = 0;
    for (size_t i = 0; i < P; ++i) {
        const int64_t Ci = xs[i].size(1);
        const T* px = xs[i].data<T>();
        if (g.needs(i)) {  // dx_i[b] = W_i^T dy[b]: [Ci, Cout] x [Cout, N]
            Tensor dx = Tensor::empty({B, Ci, N}, dy.dtype());
            for (int64_t bi = 0; bi < B; ++bi)
                kernels::gemm_cpu<T>(true, false, Ci, N, Cout, T(1), pw + off, Ctot,
                                     pdy + bi * Cout * N, N, T(0), dx.data<T>() + bi * Ci * N, N);
            g.add(i, dx);
        }
        if (dw.defined())  // dW_i = sum_b dy[b] x_i[b]^T, batches summed in a fixed order
            for (int64_t bi = 0; bi < B; ++bi)
                kernels::gemm_cpu<T>(false, true, Cout, Ci, N, T(1), pdy + bi * Cout * N, N,
                                     px + bi * Ci * N, N, bi ? T(1) : T(0), dw.data<T>() + off,
                                     Ctot);
        off += Ci;
    }
    for (size_t j = 0; j < G; ++j) {
        const int64_t Cj = gs[j].size(1);
        if (g.needs(P + j)) {  // dg_j = s W_j: [B, Cout] x [Cout, Cj]
            Tensor dg = Tensor::empty({B, Cj}, dy.dtype());
            kernels::gemm_cpu<T>(false, false, B, Cj, Cout, T(1), s.data<T>(), Cout, pw + off,
                                 Ctot, T(0), dg.data<T>(), Cj);
            g.add(P + j, dg);
        }
        if (dw.defined())  // dW_j = s^T g_j: [Cout, B] x [B, Cj]
            kernels::gemm_cpu<T>(true, false, Cout, Cj, B, T(1), s.data<T>(), Cout,
                                 gs[j].data<T>(), Cj, T(0), dw.data<T>() + off, Ctot);
        off += Cj;
    }
    if (dw.defined()) g.add(iw, dw);
    if (g.needs(ib)) {
        Tensor db = Tensor::empty({Cout}, dy.dtype());
        kernels::bias_grad_bcn_cpu<T>(s.data<T>(), db.data<T>(), B, Cout, 1, false);
        g.add(ib, db);
    }
}

}  // namespace

Tensor concat_conv1x1(const std::vector<Tensor>& point_feats,
                      const std::vector<Tensor>& global_feats, const Tensor& w, const Tensor& b) {
    int64_t cp = 0, cg = 0;
    check_inputs(point_feats, global_feats, w, b, cp, cg);
    const Tensor& x0 = point_feats[0];
    Tensor y = Tensor::empty({x0.size(0), w.size(0), x0.size(2)}, x0.dtype());
    dispatch_float(x0.dtype(), kOp, [&](auto tag) {
        forward<decltype(tag)>(point_feats, global_feats, w, b, y);
    });
    std::vector<Tensor> inputs;
    inputs.reserve(point_feats.size() + global_feats.size() + 2);
    inputs.insert(inputs.end(), point_feats.begin(), point_feats.end());
    inputs.insert(inputs.end(), global_feats.begin(), global_feats.end());
    inputs.push_back(w);
    inputs.push_back(b);
    if (!autograd::needs_grad(inputs)) return y;
    return autograd::record(kOp, y, inputs, [xs = point_feats, gs = global_feats, w](
                                                 const Tensor& dy, autograd::Grads& g) {
        dispatch_float(dy.dtype(), "concat_conv1x1 backward",
                       [&](auto tag) { backward<decltype(tag)>(xs, gs, w, dy, g); });
    });
}

}  // namespace g2l::nn
