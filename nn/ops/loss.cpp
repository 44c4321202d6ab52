// SPDX-License-Identifier: MIT
#include "nn/ops/loss.h"

#include <cmath>
#include <string>

#include "core/autograd.h"
#include "core/dispatch.h"
#include "kernels/loss.h"
#include "nn/ops/dim_utils.h"
#include "nn/ops/elementwise.h"
#include "nn/ops/reduce.h"
#include "nn/ops/softmax.h"

namespace g2l::nn {

namespace {

struct NllLayout {
    int64_t B = 0, K = 0, N = 0;
};

NllLayout nll_layout(const Tensor& logp, const Tensor& target) {
    detail::check_float_input("nll_loss", "logp", logp);
    G2L_CHECK(target.defined(), "nll_loss: target is undefined");
    G2L_CHECK(target.dtype() == DType::I32, "nll_loss: target must be i32 class ids, got ",
              target.desc());
    NllLayout l;
    if (logp.dim() == 2) {
        l = {logp.size(0), logp.size(1), 1};
        G2L_CHECK(target.shape() == Shape{l.B}, "nll_loss: logp ", logp.desc(),
                  " ([M, K]) needs target [M] = [", l.B, "], got ", target.desc());
    } else {
        G2L_CHECK(logp.dim() == 3, "nll_loss: expected logp as [M, K] or [B, K, N], got ",
                  logp.desc());
        l = {logp.size(0), logp.size(1), logp.size(2)};
        G2L_CHECK(target.shape() == (Shape{l.B, l.N}), "nll_loss: logp ", logp.desc(),
                  " ([B, K, N]) needs target [B, N] = [", l.B, ", ", l.N, "], got ", target.desc());
    }
    G2L_CHECK(l.B * l.N > 0, "nll_loss: no elements to average (logp ", logp.desc(), ")");
    // The ids are checked on the host (a copy when the target lives on another device).
    // The kernels use the ids as indices into logp, so an out-of-range id would read and write out
    // of bounds; checking every id here turns that into a clear error.
    const Tensor th = target.device().is_cpu() ? target : target.to(Device::cpu());
    const int32_t* t = th.data<int32_t>();
    for (int64_t i = 0; i < l.B * l.N; ++i) {
        if (t[i] >= 0 && t[i] < l.K) continue;
        const std::string where =
            logp.dim() == 2 ? cat("target[", i, "]") : cat("target[", i / l.N, ", ", i % l.N, "]");
        G2L_CHECK(false, "nll_loss: ", where, " = ", t[i], " is out of range [0, ", l.K,
                  ") for logp ", logp.desc());
    }
    return l;
}

// Per-element Huber loss (before the mean); both inputs get gradients.
Tensor smooth_l1_elems(const Tensor& a, const Tensor& b, double beta) {
    Tensor y = Tensor::empty(a.shape(), a.dtype(), a.device());
    kernels::smooth_l1_fwd(a, b, y, beta);
    return autograd::record(
        "smooth_l1_loss", y, {a, b},
        [beta, ad = a.detach(), bd = b.detach()](const Tensor& dy, autograd::Grads& g) {
            Tensor da, db;
            if (g.needs(0)) da = Tensor::empty(dy.shape(), dy.dtype(), dy.device());
            if (g.needs(1)) db = Tensor::empty(dy.shape(), dy.dtype(), dy.device());
            kernels::smooth_l1_bwd(ad, bd, dy, &da, &db, beta);
            if (da.defined()) g.add(0, da);
            if (db.defined()) g.add(1, db);
        });
}

void check_pair(const char* op, const Tensor& a, const Tensor& b) {
    detail::check_float_input(op, "a", a);
    detail::check_float_input(op, "b", b);
    require_same(op, {&a, &b});
    G2L_CHECK(a.shape() == b.shape(), op, ": shapes must match exactly, got ", a.desc(), " and ",
              b.desc());
    G2L_CHECK(a.numel() > 0, op, ": inputs are empty (", a.desc(), ")");
}

}  // namespace

Tensor nll_loss(const Tensor& logp, const Tensor& target, const Tensor& weight) {
    const NllLayout l = nll_layout(logp, target);
    if (weight.defined()) {
        G2L_CHECK(weight.dtype() == logp.dtype() && weight.shape() == Shape{l.K},
                  "nll_loss: weight must be ", dtype_name(logp.dtype()), " [K] = [", l.K, "], got ",
                  weight.desc());
    }
    double num = 0, den = 0;
    kernels::nll_fwd(logp, target, weight, l.B, l.K, l.N, &num, &den);
    // den is 0 when every target's class has weight 0; the mean would then be 0/0.
    G2L_CHECK(den != 0 && std::isfinite(den), "nll_loss: total weight of the targets is ", den,
              " (the mean is undefined)");
    Tensor y = Tensor::scalar(num / den, logp.dtype()).to(logp.device());
    // target and weight are recorded too so that an in-place edit before backward is caught.
    auto backward = [l, den, target, weight, shape = logp.shape()](const Tensor& dy,
                                                                   autograd::Grads& g) {
        if (!g.needs(0)) return;  // weight gets no gradient; target is i32
        Tensor dlogp = Tensor::empty({l.B, l.K, l.N}, dy.dtype(), dy.device());
        // scale = dy / den: the gradient of the weighted mean.
        kernels::nll_bwd(target, weight, l.B, l.K, l.N, dy.item<double>() / den, dlogp);
        // [M, K] inputs were handled as [M, K, 1]: same memory, so a reshape view suffices.
        g.add(0, dlogp.reshape(shape));
    };
    return autograd::record("nll_loss", y, {logp, target, weight}, backward);
}

Tensor cross_entropy(const Tensor& logits, const Tensor& target, const Tensor& weight) {
    detail::check_float_input("cross_entropy", "logits", logits);
    G2L_CHECK(logits.dim() == 2 || logits.dim() == 3,
              "cross_entropy: expected logits as [M, K] or [B, K, N], got ", logits.desc());
    // log_softmax + NLL, as G2L's Seg_3D head and its loss (spec §4.2); log_softmax is the
    // stable form (no log of a rounded-to-zero probability).
    return nll_loss(log_softmax(logits, 1), target, weight);
}

Tensor mse_loss(const Tensor& a, const Tensor& b) {
    check_pair("mse_loss", a, b);
    // nn.MSELoss with mean reduction: the G2L losses for T, EVF vectors and keypoints (spec §6).
    return mean(square(sub(a, b)));
}

Tensor smooth_l1_loss(const Tensor& a, const Tensor& b, double beta) {
    check_pair("smooth_l1_loss", a, b);
    G2L_CHECK(std::isfinite(beta) && beta >= 0,
              "smooth_l1_loss: beta must be finite and >= 0, got ", beta);
    return mean(smooth_l1_elems(a, b, beta));
}

Tensor argmax(const Tensor& x, int64_t dim) {
    // Indices carry no gradient: no node is recorded for the max it comes from.
    autograd::NoGradGuard no_grad;
    return max(x, dim, false).indices;
}

}  // namespace g2l::nn
