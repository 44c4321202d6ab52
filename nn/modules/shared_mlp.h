// SPDX-License-Identifier: MIT
// PointNet shared MLP: a stack of Conv1x1 [+ BatchNorm] [+ ReLU] layers over [B, C, N].
#pragma once

#include <memory>
#include <vector>

#include "nn/modules/layers.h"

namespace g2l::nn {

class SharedMlp : public Module {
public:
    /// widths = {in, h1, ..., out}: one layer per consecutive pair, named conv<i>/bn<i> from 1.
    /// batch_norm: BN after every conv; relu_last: whether the LAST layer gets a ReLU (the G2L
    /// backbone's conv5 and the T-net's third layer have none).
    SharedMlp(const std::vector<int64_t>& widths, Rng& rng, bool batch_norm = true,
              bool relu_last = true);
    /// x: [B, in, N] -> [B, out, N]. If taps is given, it receives every layer's output.
    Tensor forward(const Tensor& x, std::vector<Tensor>* taps = nullptr);
    int64_t out_channels() const { return widths_.back(); }

private:
    std::vector<int64_t> widths_;
    std::vector<std::shared_ptr<Conv1x1>> convs_;
    std::vector<std::shared_ptr<BatchNorm>> bns_;
    bool relu_last_;
};

/// A stack of Linear [+ BatchNorm] [+ ReLU] layers over [B, C] rows, named fc<i>/bn<i>.
class Mlp : public Module {
public:
    Mlp(const std::vector<int64_t>& widths, Rng& rng, bool batch_norm = true,
        bool relu_last = true);
    Tensor forward(const Tensor& x);

private:
    std::vector<int64_t> widths_;
    std::vector<std::shared_ptr<Linear>> fcs_;
    std::vector<std::shared_ptr<BatchNorm>> bns_;
    bool relu_last_;
};

}  // namespace g2l::nn
