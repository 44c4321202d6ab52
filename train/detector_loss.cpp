// SPDX-License-Identifier: MIT
// The detector's CenterNet targets and its loss.
#include <algorithm>
#include <cmath>

#include "core/autograd.h"
#include "core/error.h"
#include "nn/ops/elementwise.h"
#include "nn/ops/reduce.h"
#include "train/detector_train.h"

namespace g2l::train {

// ---------------------------------------------------------------- targets and loss
DetTargets make_detector_targets(const std::vector<DetBox>& boxes, int K, int w, int h,
                                 int stride) {
    G2L_CHECK(K > 0 && w > 0 && h > 0 && stride > 0, "make_detector_targets: bad sizes K ", K,
              ", ", w, " x ", h, ", stride ", stride);
    DetTargets t;
    const size_t plane = size_t(w) * size_t(h);
    t.heat.assign(size_t(K) * plane, 0.f);
    t.size.assign(2 * plane, 0.f);
    t.offset.assign(2 * plane, 0.f);
    t.mask.assign(plane, 0.f);
    for (const DetBox& b : boxes) {
        G2L_CHECK(b.cls >= 0 && b.cls < K, "make_detector_targets: class ", b.cls,
                  " outside [0, ", K, ")");
        if (!(b.w > 0 && b.h > 0) || !std::isfinite(b.x) || !std::isfinite(b.y)) continue;
        const float cx = (b.x + 0.5f * b.w) / float(stride), cy = (b.y + 0.5f * b.h) / float(stride);
        const int ix = int(std::floor(cx)), iy = int(std::floor(cy));
        if (ix < 0 || iy < 0 || ix >= w || iy >= h) continue;
        const float bw = b.w / float(stride), bh = b.h / float(stride);
        const float sigma = std::max(0.7f, 0.1f * std::sqrt(bw * bh));
        const int r = int(std::ceil(3 * sigma));
        float* heat = t.heat.data() + size_t(b.cls) * plane;
        for (int y = std::max(0, iy - r); y <= std::min(h - 1, iy + r); ++y)
            for (int x = std::max(0, ix - r); x <= std::min(w - 1, ix + r); ++x) {
                const float d2 = float((x - ix) * (x - ix) + (y - iy) * (y - iy));
                const float g = x == ix && y == iy ? 1.f : std::exp(-d2 / (2 * sigma * sigma));
                float& v = heat[size_t(y) * size_t(w) + size_t(x)];
                v = std::max(v, g);
            }
        const size_t i = size_t(iy) * size_t(w) + size_t(ix);
        t.mask[i] = 1.f;
        t.size[i] = std::log(bw);
        t.size[plane + i] = std::log(bh);
        t.offset[i] = cx - float(ix);
        t.offset[plane + i] = cy - float(iy);
    }
    return t;
}

std::vector<float> block_cell_weights(const std::vector<uint8_t>& blocks, int W, int H,
                                      int stride, float weight) {
    G2L_CHECK(W > 0 && H > 0 && stride > 0 && blocks.size() == size_t(W) * size_t(H),
              "block_cell_weights: a mask of ", blocks.size(), " pixels for ", W, " x ", H);
    G2L_CHECK(std::isfinite(weight) && weight >= 0, "block_cell_weights: weight ", weight);
    const int w = W / stride, h = H / stride;
    std::vector<float> nw(size_t(w) * size_t(h), 1.f);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            if (blocks[size_t(y * stride + stride / 2) * size_t(W) + size_t(x * stride + stride / 2)])
                nw[size_t(y) * size_t(w) + size_t(x)] = weight;
    return nw;
}

double detector_centres(const std::vector<DetTargets>& targets) {
    double n = 0;
    for (const DetTargets& t : targets)
        for (const float g : t.heat) n += g >= 1.f;
    return n;
}

Tensor detector_loss(const nn::DetOut& out, const std::vector<DetTargets>& targets,
                     double w_heat, double w_size, double w_offset, double* heat_loss,
                     double* size_loss, double* offset_loss, double centres) {
    G2L_CHECK(out.heat.defined() && out.heat.dim() == 4, "detector_loss: bad heat output");
    const int64_t B = out.heat.size(0), K = out.heat.size(1), H = out.heat.size(2),
                  W = out.heat.size(3);
    G2L_CHECK(int64_t(targets.size()) == B, "detector_loss: ", targets.size(),
              " targets for a batch of ", B);
    const size_t plane = size_t(H) * size_t(W);
    Tensor gt = Tensor::empty({B, K, H, W}), pos = Tensor::empty({B, K, H, W});
    Tensor negw = Tensor::empty({B, K, H, W});
    Tensor st = Tensor::empty({B, 2, H, W}), ot = Tensor::empty({B, 2, H, W});
    Tensor m = Tensor::empty({B, 1, H, W});
    double npos = 0;
    for (int64_t b = 0; b < B; ++b) {
        const DetTargets& t = targets[size_t(b)];
        G2L_CHECK(t.heat.size() == size_t(K) * plane && t.mask.size() == plane &&
                      t.size.size() == 2 * plane && t.offset.size() == 2 * plane &&
                      (t.neg_weight.empty() || t.neg_weight.size() == plane),
                  "detector_loss: targets of sample ", b, " do not match the ", K, " x ", H,
                  " x ", W, " output");
        for (size_t i = 0; i < size_t(K) * plane; ++i) {
            const float g = t.heat[i];
            const size_t o = size_t(b) * size_t(K) * plane + i;
            gt.data<float>()[o] = g;
            const bool p = g >= 1.f;
            pos.data<float>()[o] = p ? 1.f : 0.f;
            const float q = 1.f - g;
            const float nw = t.neg_weight.empty() ? 1.f : t.neg_weight[i % plane];
            negw.data<float>()[o] = p ? 0.f : nw * q * q * q * q;
            npos += p;
        }
        std::copy(t.size.begin(), t.size.end(), st.data<float>() + size_t(b) * 2 * plane);
        std::copy(t.offset.begin(), t.offset.end(), ot.data<float>() + size_t(b) * 2 * plane);
        std::copy(t.mask.begin(), t.mask.end(), m.data<float>() + size_t(b) * plane);
    }
    const double norm = 1.0 / std::max(1.0, centres >= 0 ? centres : npos);
    // Penalty-reduced focal loss (CenterNet): -(1-p)^2 log p at centres,
    // -(1-g)^4 p^2 log(1-p) elsewhere; p clamped away from 0 and 1.
    const Tensor p = nn::clamp(nn::sigmoid(out.heat), 1e-4, 1 - 1e-4);
    const Tensor one_minus = 1.0 - p;
    const Tensor lpos = pos * nn::log(p) * nn::square(one_minus);
    const Tensor lneg = negw * nn::log(one_minus) * nn::square(p);
    const Tensor Lh = nn::sum(lpos + lneg) * (-norm);
    const Tensor Ls = nn::sum(m * nn::abs(out.size - st)) * norm;
    const Tensor Lo = nn::sum(m * nn::abs(out.offset - ot)) * norm;
    if (heat_loss) *heat_loss = Lh.item<double>();
    if (size_loss) *size_loss = Ls.item<double>();
    if (offset_loss) *offset_loss = Lo.item<double>();
    return Lh * w_heat + Ls * w_size + Lo * w_offset;
}


}  // namespace g2l::train
