// SPDX-License-Identifier: MIT
#include "nn/models/g2l_blocks.h"

#include <algorithm>
#include <cmath>

#include "nn/ops/relu.h"
#include "nn/ops/concat_conv.h"
#include "nn/ops/elementwise.h"
#include "nn/ops/pool_points.h"
#include "nn/ops/reduce.h"
#include "nn/ops/shape.h"
#include "nn/ops/softmax.h"

namespace g2l::nn {

int64_t scaled_width(int64_t base, double width) {
    G2L_CHECK(std::isfinite(width) && width > 0,
              "G2L-Net: width multiplier must be finite and > 0, got ", width);
    return std::max<int64_t>(8, std::llround(double(base) * width));
}

std::vector<int64_t> official_head_columns(int64_t prefix, int64_t c1, int64_t c2, int64_t c5,
                                           int64_t num_classes) {
    // Official blocks: [prefix | x1 | x2 | g | pf | onehot];
    // ours:            [prefix | x1 | x2 | pf | g | onehot].
    std::vector<int64_t> cols;
    auto block = [&cols](int64_t start, int64_t n) {
        for (int64_t i = 0; i < n; ++i) cols.push_back(start + i);
    };
    const int64_t g_off = prefix + c1 + c2, pf_off = g_off + c5;
    block(0, prefix + c1 + c2);
    block(pf_off, c5);
    block(g_off, c5);
    block(pf_off + c5, num_classes);
    return cols;
}

Tensor select_class_block(const Tensor& x, const Tensor& onehot) {
    G2L_CHECK(x.defined() && onehot.defined() && onehot.dim() == 2 && (x.dim() == 2 || x.dim() == 3) &&
                  x.size(0) == onehot.size(0) && onehot.size(1) >= 1 &&
                  x.size(1) % onehot.size(1) == 0,
              "select_class_block: expected x [B, C*F] or [B, C*F, N] and onehot [B, C], got x ",
              x.defined() ? x.desc() : std::string("undefined"), " and onehot ",
              onehot.defined() ? onehot.desc() : std::string("undefined"));
    const int64_t B = x.size(0), C = onehot.size(1), F = x.size(1) / C;
    const int64_t N = x.dim() == 3 ? x.size(2) : 1;
    if (C == 1) return x;
    const Tensor blocks = x.reshape({B, C, F * N});
    const Tensor picked = sum(mul(blocks, onehot.reshape({B, C, 1})), 1);  // [B, F*N]
    return x.dim() == 3 ? picked.reshape({B, F, N}) : picked.reshape({B, F});
}

PointFeatures PointFeatures::detached() const {
    return {x1.detach(), x2.detach(), pf.detach(), g.detach(), onehot.detach()};
}

void check_points_input(const char* who, const Tensor& x, const Tensor& onehot,
                        int64_t num_classes) {
    G2L_CHECK(x.defined() && onehot.defined(), who, ": x or onehot is undefined");
    G2L_CHECK(x.dim() == 3 && x.size(1) == 3 && x.size(0) > 0 && x.size(2) > 0, who,
              ": expected x as [B, 3, N] (points channel-first, B and N > 0), got ", x.desc());
    G2L_CHECK(x.dtype() == DType::F32 || x.dtype() == DType::F64, who,
              ": x must be f32 or f64, got ", x.desc());
    G2L_CHECK(onehot.dim() == 2 && onehot.size(0) == x.size(0) && onehot.size(1) == num_classes,
              who, ": expected onehot as [B, num_classes] = [", x.size(0), ", ", num_classes,
              "], got ", onehot.desc());
    G2L_CHECK(onehot.dtype() == x.dtype(), who, ": onehot ", onehot.desc(),
              " must have the dtype of x ", x.desc());
}

// ---- PointBackbone ----

namespace {
std::vector<int64_t> backbone_widths(double w) {
    return {3,
            scaled_width(64, w),
            scaled_width(64, w),
            scaled_width(64, w),
            scaled_width(128, w),
            scaled_width(1024, w)};
}
}  // namespace

PointBackbone::PointBackbone(double width, Rng& rng)
    : SharedMlp(backbone_widths(width), rng, /*batch_norm=*/true, /*relu_last=*/false),
      c1(scaled_width(64, width)),
      c2(scaled_width(128, width)),
      c5(scaled_width(1024, width)) {}

PointFeatures PointBackbone::forward_features(const Tensor& x, const Tensor& onehot) {
    std::vector<Tensor> taps;
    taps.reserve(5);
    SharedMlp::forward(x, &taps);
    PointFeatures f;
    f.x1 = taps[1];
    f.x2 = taps[3];
    f.pf = taps[4];
    f.g = max_pool_points(f.pf);
    f.onehot = onehot;
    return f;
}

// ---- ConcatMlp ----

ConcatMlp::ConcatMlp(int64_t in_point, int64_t in_global, const std::vector<int64_t>& hidden,
                     Rng& rng, bool relu_last)
    : hidden_(hidden), relu_last_(relu_last) {
    G2L_CHECK(!hidden.empty() && in_point > 0 && in_global >= 0, "ConcatMlp: bad widths (in_point ",
              in_point, ", in_global ", in_global, ", ", hidden.size(), " layers)");
    int64_t in = in_point + in_global;
    for (size_t i = 0; i < hidden.size(); ++i) {
        const std::string k = std::to_string(i + 1);
        convs_.push_back(
            register_module("conv" + k, std::make_shared<Conv1x1>(in, hidden[i], rng)));
        bns_.push_back(register_module("bn" + k, std::make_shared<BatchNorm>(hidden[i])));
        in = hidden[i];
    }
}

Tensor ConcatMlp::forward(const std::vector<Tensor>& point, const std::vector<Tensor>& global) {
    Tensor h = concat_conv1x1(point, global, convs_[0]->weight, convs_[0]->bias);
    for (size_t i = 0; i < convs_.size(); ++i) {
        if (i > 0) h = convs_[i]->forward(h);
        h = bns_[i]->forward(h);
        if (i + 1 < convs_.size() || relu_last_) h = relu(h);
    }
    return h;
}

// ---- SegNet ----

namespace {
// The SegNet / EvfNet head widths 512 -> 256 -> 128 -> 128.
std::vector<int64_t> seg_head(double w) {
    return {scaled_width(512, w), scaled_width(256, w), scaled_width(128, w), scaled_width(128, w)};
}
}  // namespace

SegNet::SegNet(double width, int64_t num_classes, double dropout, Rng& rng, uint64_t seed)
    : num_classes_(num_classes) {
    backbone_ = register_module("backbone", std::make_shared<PointBackbone>(width, rng));
    const int64_t cp = backbone_->c1 + backbone_->c2 + backbone_->c5;
    head_ = register_module("head", std::make_shared<ConcatMlp>(cp, backbone_->c5 + num_classes,
                                                                seg_head(width), rng, true));
    drop_ = register_module("drop", std::make_shared<Dropout>(dropout, seed));
    out_ = register_module("out", std::make_shared<Conv1x1>(head_->out_channels(), 2, rng));
}

Tensor SegNet::forward(const Tensor& x, const Tensor& onehot) {
    check_points_input("SegNet", x, onehot, num_classes_);
    const PointFeatures f = backbone_->forward_features(x, onehot);
    const Tensor h = drop_->forward(head_->forward(f.point(), f.global()));
    return log_softmax(out_->forward(h), 1);
}

// ---- TNet ----

TNet::TNet(double width, int64_t num_classes, double dropout, Rng& rng, uint64_t seed)
    : num_classes_(num_classes) {
    const int64_t c3 = scaled_width(512, width);
    mlp_ = register_module("mlp", std::make_shared<SharedMlp>(
                                      std::vector<int64_t>{3, scaled_width(128, width),
                                                           scaled_width(256, width), c3},
                                      rng, true, /*relu_last=*/false));
    fc_ = register_module("fc", std::make_shared<Mlp>(
                                    std::vector<int64_t>{c3 + num_classes, scaled_width(256, width),
                                                         scaled_width(128, width)},
                                    rng, true, /*relu_last=*/false));
    drop_ = register_module("drop", std::make_shared<Dropout>(dropout, seed));
    out_ = register_module("out", std::make_shared<Linear>(scaled_width(128, width), 3, rng));
}

Tensor TNet::forward(const Tensor& x, const Tensor& onehot) {
    check_points_input("TNet", x, onehot, num_classes_);
    const Tensor g = max_pool_points(mlp_->forward(x));  // [B, 512]
    return out_->forward(drop_->forward(fc_->forward(concat({g, onehot}, 1))));
}

// ---- EvfNet ----

EvfNet::EvfNet(double width, int64_t num_classes, int64_t num_keypoints, double dropout, Rng& rng,
               uint64_t seed, bool class_heads)
    : num_classes_(num_classes), num_keypoints_(num_keypoints), class_heads_(class_heads) {
    backbone_ = register_module("backbone", std::make_shared<PointBackbone>(width, rng));
    const int64_t cp = backbone_->c1 + backbone_->c2 + backbone_->c5;
    head_ = register_module("head", std::make_shared<ConcatMlp>(cp, backbone_->c5 + num_classes,
                                                                seg_head(width), rng, true));
    drop_ = register_module("drop", std::make_shared<Dropout>(dropout, seed));
    out_ = register_module(
        "out", std::make_shared<Conv1x1>(head_->out_channels(),
                                         (class_heads ? num_classes : 1) * 3 * num_keypoints, rng));
}

EvfOut EvfNet::forward(const Tensor& x, const Tensor& onehot) {
    check_points_input("EvfNet", x, onehot, num_classes_);
    const PointFeatures f = backbone_->forward_features(x, onehot);
    const Tensor h = drop_->forward(head_->forward(f.point(), f.global()));
    Tensor v = out_->forward(h);
    if (class_heads_) v = select_class_block(v, onehot);
    return {v, f.detached()};
}

// ---- RotNet ----

RotNet::RotNet(double width, int64_t num_classes, int64_t num_keypoints, bool use_vectors,
               double dropout, Rng& rng, uint64_t seed, bool class_heads)
    : num_classes_(num_classes),
      num_keypoints_(num_keypoints),
      use_vectors_(use_vectors),
      class_heads_(class_heads) {
    if (!use_vectors)
        backbone_ = register_module("backbone", std::make_shared<PointBackbone>(width, rng));
    const int64_t c1 = scaled_width(64, width), c2 = scaled_width(128, width),
                  c5 = scaled_width(1024, width);
    const int64_t cp = (use_vectors ? 3 * num_keypoints : 0) + c1 + c2 + c5;
    mlp_ = register_module("mlp", std::make_shared<ConcatMlp>(
                                      cp, c5 + num_classes,
                                      std::vector<int64_t>{scaled_width(1024, width),
                                                           scaled_width(512, width),
                                                           scaled_width(256, width)},
                                      rng, true));
    fc_ = register_module("fc", std::make_shared<Mlp>(
                                    std::vector<int64_t>{scaled_width(256, width),
                                                         scaled_width(256, width),
                                                         scaled_width(128, width),
                                                         scaled_width(128, width)},
                                    rng, true, true));
    drop_ = register_module("drop", std::make_shared<Dropout>(dropout, seed));
    out_ = register_module("out", std::make_shared<Linear>(
                                      scaled_width(128, width),
                                      (class_heads ? num_classes : 1) * 3 * num_keypoints, rng));
}

PointFeatures RotNet::features(const Tensor& x, const Tensor& onehot) {
    G2L_CHECK(!use_vectors_, "RotNet::features: this RotNet consumes block A's features and has "
                             "no backbone of its own");
    check_points_input("RotNet", x, onehot, num_classes_);
    return backbone_->forward_features(x, onehot);
}

Tensor RotNet::forward(const Tensor& vectors, const PointFeatures& feat) {
    std::vector<Tensor> point = feat.point();
    if (use_vectors_) {
        G2L_CHECK(vectors.defined() && vectors.dim() == 3 && vectors.size(1) == 3 * num_keypoints_,
                  "RotNet: expected vectors as [B, 3K, N] = [B, ", 3 * num_keypoints_,
                  ", N], got ", vectors.defined() ? vectors.desc() : std::string("undefined"));
        point.insert(point.begin(), vectors);
    } else {
        G2L_CHECK(!vectors.defined(), "RotNet: built without block A (evf off) but got vectors ",
                  vectors.desc());
    }
    const Tensor g = max_pool_points(mlp_->forward(point, feat.global()));  // [B, 256]
    Tensor kp = out_->forward(drop_->forward(fc_->forward(g)));  // [B, 3K] or [B, C*3K]
    if (class_heads_) kp = select_class_block(kp, feat.onehot);
    return kp.reshape({kp.size(0), num_keypoints_, 3});
}

// ---- RreNet ----

RreNet::RreNet(double width, int64_t num_classes, int64_t num_keypoints, double dropout_in,
               Rng& rng, uint64_t seed, bool class_heads)
    : num_classes_(num_classes), num_keypoints_(num_keypoints), class_heads_(class_heads) {
    drop_ = register_module("drop", std::make_shared<Dropout>(dropout_in, seed));
    const int64_t c1 = scaled_width(64, width), c2 = scaled_width(128, width),
                  c5 = scaled_width(1024, width);
    mlp_ = register_module("mlp", std::make_shared<ConcatMlp>(
                                      c1 + c2 + c5, c5 + num_classes,
                                      std::vector<int64_t>{scaled_width(256, width),
                                                           scaled_width(128, width)},
                                      rng, /*relu_last=*/false));
    out_ = register_module("out", std::make_shared<Linear>(
                                      scaled_width(128, width),
                                      (class_heads ? num_classes : 1) * 3 * num_keypoints, rng));
}

Tensor RreNet::forward(const PointFeatures& feat) {
    G2L_CHECK(feat.onehot.defined() && feat.onehot.dim() == 2 &&
                  feat.onehot.size(1) == num_classes_,
              "RreNet: expected feat.onehot as [B, ", num_classes_, "], got ",
              feat.onehot.defined() ? feat.onehot.desc() : std::string("undefined"));
    std::vector<Tensor> point, global;
    for (const Tensor& t : feat.point()) point.push_back(drop_->forward(t));
    for (const Tensor& t : feat.global()) global.push_back(drop_->forward(t));
    const Tensor g = max_pool_points(mlp_->forward(point, global));  // [B, 128]
    Tensor r = out_->forward(g);  // [B, 3K] or [B, C*3K]
    if (class_heads_) r = select_class_block(r, feat.onehot);
    return r.reshape({r.size(0), num_keypoints_, 3});
}

}  // namespace g2l::nn
