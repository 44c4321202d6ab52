// SPDX-License-Identifier: MIT
#include "nn/ops/concat_conv.h"

#include "core/autograd.h"
#include "core/dispatch.h"
#include "kernels/concat_conv.h"

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
        cp += xs[i].size(1);
    }
    for (size_t j = 0; j < gs.size(); ++j) {
        G2L_CHECK(gs[j].defined(), kOp, ": global_feats[", j, "] is undefined");
        G2L_CHECK(gs[j].dim() == 2 && gs[j].size(0) == x0.size(0), kOp,
                  ": expected global_feats[", j, "] as [B, Cj] with B = ", x0.size(0), ", got ",
                  gs[j].desc());
        require_same(kOp, {&x0, &gs[j]});
        cg += gs[j].size(1);
    }
    require_rank(kOp, "w", w, 2, "[Cout, sum Ci + sum Cj]");
    require_same(kOp, {&x0, &w, &b});
    G2L_CHECK(w.size(1) == cp + cg, kOp, ": w ", w.desc(), " has ", w.size(1),
              " input columns, the features have ", cp, " per-point + ", cg, " global = ",
              cp + cg, " channels");
    if (b.defined())
        G2L_CHECK(b.dim() == 1 && b.size(0) == w.size(0), kOp, ": bias ", b.desc(),
                  " must be [Cout] = [", w.size(0), "]");
}

}  // namespace

Tensor concat_conv1x1(const std::vector<Tensor>& point_feats,
                      const std::vector<Tensor>& global_feats, const Tensor& w, const Tensor& b) {
    int64_t cp = 0, cg = 0;
    check_inputs(point_feats, global_feats, w, b, cp, cg);
    const Tensor& x0 = point_feats[0];
    Tensor y = Tensor::empty({x0.size(0), w.size(0), x0.size(2)}, x0.dtype(), x0.device());
    kernels::concat_conv1x1_fwd(point_feats, global_feats, w, b, y);
    std::vector<Tensor> inputs;
    inputs.reserve(point_feats.size() + global_feats.size() + 2);
    inputs.insert(inputs.end(), point_feats.begin(), point_feats.end());
    inputs.insert(inputs.end(), global_feats.begin(), global_feats.end());
    inputs.push_back(w);
    // b is pushed even when undefined so that its slot is always P + G + 1.
    inputs.push_back(b);
    // At inference skip building the closure, which copies both feature lists.
    if (!autograd::needs_grad(inputs)) return y;
    return autograd::record(kOp, y, inputs, [xs = point_feats, gs = global_feats, w](
                                                 const Tensor& dy, autograd::Grads& g) {
        // Slots of g: point feats [0, P), global feats [P, P + G), w, b.
        const size_t P = xs.size(), G = gs.size();
        std::vector<Tensor> dxs(P), dgs(G);
        for (size_t i = 0; i < P; ++i)
            if (g.needs(i)) dxs[i] = Tensor::empty(xs[i].shape(), dy.dtype(), dy.device());
        for (size_t j = 0; j < G; ++j)
            if (g.needs(P + j)) dgs[j] = Tensor::empty(gs[j].shape(), dy.dtype(), dy.device());
        Tensor dw, db;
        if (g.needs(P + G)) dw = Tensor::empty(w.shape(), dy.dtype(), dy.device());
        if (g.needs(P + G + 1)) db = Tensor::empty({w.size(0)}, dy.dtype(), dy.device());
        kernels::concat_conv1x1_bwd(xs, gs, w, dy, dxs, dgs, &dw, &db);
        for (size_t i = 0; i < P; ++i)
            if (dxs[i].defined()) g.add(i, dxs[i]);
        for (size_t j = 0; j < G; ++j)
            if (dgs[j].defined()) g.add(P + j, dgs[j]);
        if (dw.defined()) g.add(P + G, dw);
        if (db.defined()) g.add(P + G + 1, db);
    });
}

}  // namespace g2l::nn
