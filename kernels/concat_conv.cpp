// SPDX-License-Identifier: MIT
// concat_conv1x1: the dispatch point (kernels/dispatch.h) and its CPU implementation over the
// GEMM and bias kernels. The per-point blocks of w multiply their features directly; the global
// blocks become a per-(sample, channel) bias broadcast over the points.
#include "kernels/concat_conv.h"

#include "kernels/bias.h"
#include "kernels/dispatch.h"
#include "kernels/gemm.h"

namespace g2l::kernels {

namespace {

// Serves the G2L heads whose input is the 2256-channel point feature: x1 64, x2 128, pf 1024
// per point, plus g 1024 and the one-hot 16 tiled over the points (spec §4.1-4.2). The global
// blocks are equal for every point, so W_g g is one [B, Cout] product instead of N, and the
// 2256 x N input is never built.
template <class T>
void concat_conv1x1_fwd_cpu(const std::vector<Tensor>& xs, const std::vector<Tensor>& gs,
                            const Tensor& w, const Tensor& b, Tensor& y) {
    const int64_t B = y.size(0), Cout = y.size(1), N = y.size(2), Ctot = w.size(1);
    const T* pw = w.data<T>();
    T* py = y.data<T>();
    int64_t off = 0;
    // beta = 0 for the first block overwrites y (it starts uninitialised); later blocks add.
    for (size_t i = 0; i < xs.size(); ++i) {  // y[b] (+)= W_i x_i[b]: [Cout, Ci] x [Ci, N]
        const int64_t Ci = xs[i].size(1);
        gemm_batched_cpu<T>(false, false, Cout, N, Ci, T(1), pw + off, Ctot, xs[i].data<T>(), N,
                            Ci * N, i ? T(1) : T(0), py, N, Cout * N, B);
        off += Ci;
    }
    if (gs.empty() && !b.defined()) return;
    // v[b, o] = bias[o] + sum_j (g_j W_j^T)[b, o]: [B, Cj] x [Cj, Cout] per global block.
    Tensor v = Tensor::zeros({B, Cout}, y.dtype(), y.device());
    T* pv = v.data<T>();
    if (b.defined()) add_bias_bcn_cpu<T>(pv, b.data<T>(), B, Cout, 1);
    // w's columns hold the point blocks first, then the global ones: start at the first global.
    off = Ctot;
    for (const Tensor& g : gs) off -= g.size(1);
    for (const Tensor& g : gs) {
        const int64_t Cj = g.size(1);
        gemm_cpu<T>(false, true, B, Cout, Cj, T(1), g.data<T>(), Cj, pw + off, Ctot, T(1), pv,
                    Cout);
        off += Cj;
    }
    for (int64_t bi = 0; bi < B; ++bi)  // broadcast v[b] over the N points of batch b
        add_bias_bcn_cpu<T>(py + bi * Cout * N, pv + bi * Cout, 1, Cout, N);
}

template <class T>
void concat_conv1x1_bwd_cpu(const std::vector<Tensor>& xs, const std::vector<Tensor>& gs,
                            const Tensor& w, const Tensor& dy, std::vector<Tensor>& dxs,
                            std::vector<Tensor>& dgs, Tensor* dw, Tensor* db) {
    const size_t P = xs.size(), G = gs.size();
    const int64_t B = dy.size(0), Cout = dy.size(1), N = dy.size(2), Ctot = w.size(1);
    const T* pw = w.data<T>();
    const T* pdy = dy.data<T>();
    const bool want_w = dw && dw->defined(), want_b = db && db->defined();
    // s feeds db, the global blocks' dW and every dg; skip the reduction when none is wanted.
    bool need_s = want_b || (G > 0 && want_w);
    for (size_t j = 0; j < G; ++j) need_s = need_s || dgs[j].defined();
    // s[b, o] = sum_n dy[b, o, n]: the gradient of the broadcast (global + bias) term.
    Tensor s;
    if (need_s) {
        s = Tensor::empty({B, Cout}, dy.dtype(), dy.device());
        // Per sample: the broadcast term differs between samples, so s keeps its batch index.
        for (int64_t bi = 0; bi < B; ++bi)
            bias_grad_bcn_cpu<T>(pdy + bi * Cout * N, s.data<T>() + bi * Cout, 1, Cout, N, false);
    }
    int64_t off = 0;
    for (size_t i = 0; i < P; ++i) {
        const int64_t Ci = xs[i].size(1);
        const T* px = xs[i].data<T>();
        if (dxs[i].defined())  // dx_i[b] = W_i^T dy[b]: [Ci, Cout] x [Cout, N]
            gemm_batched_cpu<T>(true, false, Ci, N, Cout, T(1), pw + off, Ctot, pdy, N, Cout * N,
                                T(0), dxs[i].data<T>(), N, Ci * N, B);
        if (want_w)  // dW_i = sum_b dy[b] x_i[b]^T, batches summed in a fixed order
            for (int64_t bi = 0; bi < B; ++bi)
                gemm_cpu<T>(false, true, Cout, Ci, N, T(1), pdy + bi * Cout * N, N,
                            px + bi * Ci * N, N, bi ? T(1) : T(0), dw->data<T>() + off, Ctot);
        off += Ci;
    }
    for (size_t j = 0; j < G; ++j) {
        const int64_t Cj = gs[j].size(1);
        if (dgs[j].defined())  // dg_j = s W_j: [B, Cout] x [Cout, Cj]
            gemm_cpu<T>(false, false, B, Cj, Cout, T(1), s.data<T>(), Cout, pw + off, Ctot, T(0),
                        dgs[j].data<T>(), Cj);
        if (want_w)  // dW_j = s^T g_j: [Cout, B] x [B, Cj]
            gemm_cpu<T>(true, false, Cout, Cj, B, T(1), s.data<T>(), Cout, gs[j].data<T>(), Cj,
                        T(0), dw->data<T>() + off, Ctot);
        off += Cj;
    }
    if (want_b) bias_grad_bcn_cpu<T>(s.data<T>(), db->data<T>(), B, Cout, 1, false);
}

// Every tensor of the call, for the device check of the dispatch.
// dispatch() only sees the fixed arguments; the variable-length lists are checked here.
void check_one_device(const char* op, const std::vector<Tensor>& ts, const Tensor& key) {
    for (const Tensor& t : ts)
        if (t.defined())
            G2L_CHECK(t.device() == key.device(), op, ": tensors must be on one device, got ",
                      key.desc(), " and ", t.desc());
}

}  // namespace

void concat_conv1x1_fwd(const std::vector<Tensor>& xs, const std::vector<Tensor>& gs,
                        const Tensor& w, const Tensor& b, Tensor& y) {
    check_one_device("concat_conv1x1", xs, y);
    check_one_device("concat_conv1x1", gs, y);
    dispatch("concat_conv1x1", {&y, &w, &b},
             [&](auto tag) { concat_conv1x1_fwd_cpu<decltype(tag)>(xs, gs, w, b, y); });
}

void concat_conv1x1_bwd(const std::vector<Tensor>& xs, const std::vector<Tensor>& gs,
                        const Tensor& w, const Tensor& dy, std::vector<Tensor>& dxs,
                        std::vector<Tensor>& dgs, Tensor* dw, Tensor* db) {
    G2L_CHECK(dxs.size() == xs.size() && dgs.size() == gs.size(),
              "concat_conv1x1 backward: ", dxs.size(), " / ", dgs.size(), " gradient slots for ",
              xs.size(), " / ", gs.size(), " inputs");
    for (const std::vector<Tensor>* v : {&xs, &gs, static_cast<const std::vector<Tensor>*>(&dxs),
                                         static_cast<const std::vector<Tensor>*>(&dgs)})
        check_one_device("concat_conv1x1 backward", *v, dy);
    dispatch("concat_conv1x1 backward", {&dy, &w, dw, db}, [&](auto tag) {
        concat_conv1x1_bwd_cpu<decltype(tag)>(xs, gs, w, dy, dxs, dgs, dw, db);
    });
}

}  // namespace g2l::kernels
