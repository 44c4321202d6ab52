// SPDX-License-Identifier: MIT
#include "nn/modules/shared_mlp.h"

#include "nn/ops/relu.h"

namespace g2l::nn {

namespace {
void check_widths(const char* what, const std::vector<int64_t>& w) {
    G2L_CHECK(w.size() >= 2, what, ": needs at least {in, out} widths, got ", w.size());
    for (int64_t v : w) G2L_CHECK(v > 0, what, ": widths must be > 0, got ", v);
}
}  // namespace

// PointNet's shared MLP: 1x1 convolutions applied to every point with the same weights, e.g.
// G2L's backbone 3 -> 64 -> 64 -> 64 -> 128 -> 1024 (spec §4.1).
SharedMlp::SharedMlp(const std::vector<int64_t>& widths, Rng& rng, bool batch_norm,
                     bool relu_last)
    : widths_(widths), relu_last_(relu_last) {
    check_widths("SharedMlp", widths);
    for (size_t i = 0; i + 1 < widths.size(); ++i) {
        const std::string k = std::to_string(i + 1);
        convs_.push_back(register_module("conv" + k,
                                         std::make_shared<Conv1x1>(widths[i], widths[i + 1], rng)));
        if (batch_norm)
            bns_.push_back(register_module("bn" + k, std::make_shared<BatchNorm>(widths[i + 1])));
    }
}

Tensor SharedMlp::forward(const Tensor& x, std::vector<Tensor>* taps) {
    G2L_CHECK(x.dim() == 3 && x.size(1) == widths_.front(), "SharedMlp: expected x as [B, ",
              widths_.front(), ", N], got ", x.desc());
    Tensor h = x;
    for (size_t i = 0; i < convs_.size(); ++i) {
        h = convs_[i]->forward(h);
        if (!bns_.empty()) h = bns_[i]->forward(h);
        // Some G2L layers end without ReLU (backbone conv5, the T-net's 256 -> 512;
        // spec §4.1, §4.3), hence relu_last.
        if (i + 1 < convs_.size() || relu_last_) h = relu(h);
        // Intermediate outputs: the backbone concatenates x1 (conv2), x2 (conv4) and pf
        // (conv5) into the per-point feature (spec §4.1).
        if (taps) taps->push_back(h);
    }
    return h;
}

// The per-sample counterpart for the heads after the max over points (e.g. the T-net's
// 528 -> 256 -> 128, spec §4.3).
Mlp::Mlp(const std::vector<int64_t>& widths, Rng& rng, bool batch_norm, bool relu_last)
    : widths_(widths), relu_last_(relu_last) {
    check_widths("Mlp", widths);
    for (size_t i = 0; i + 1 < widths.size(); ++i) {
        const std::string k = std::to_string(i + 1);
        fcs_.push_back(register_module("fc" + k,
                                       std::make_shared<Linear>(widths[i], widths[i + 1], rng)));
        if (batch_norm)
            bns_.push_back(register_module("bn" + k, std::make_shared<BatchNorm>(widths[i + 1])));
    }
}

Tensor Mlp::forward(const Tensor& x) {
    G2L_CHECK(x.dim() == 2 && x.size(1) == widths_.front(), "Mlp: expected x as [B, ",
              widths_.front(), "], got ", x.desc());
    Tensor h = x;
    for (size_t i = 0; i < fcs_.size(); ++i) {
        h = fcs_[i]->forward(h);
        if (!bns_.empty()) h = bns_[i]->forward(h);
        if (i + 1 < fcs_.size() || relu_last_) h = relu(h);
    }
    return h;
}

}  // namespace g2l::nn
