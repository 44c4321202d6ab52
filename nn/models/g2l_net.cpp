// SPDX-License-Identifier: MIT
#include "nn/models/g2l_net.h"

#include <cmath>

#include "nn/ops/elementwise.h"

namespace g2l::nn {

namespace {

const G2LConfig& checked(const G2LConfig& c) {
    G2L_CHECK(c.rot_unit == "mm" || c.rot_unit == "kp_rms",
              "G2LConfig: rot_unit must be \"mm\" or \"kp_rms\", got \"", c.rot_unit, "\"");
    // Upper bounds keep a corrupt or hostile model file from allocating gigabytes.
    G2L_CHECK(c.num_classes >= 1 && c.num_classes <= 4096,
              "G2LConfig: num_classes must be in [1, 4096], got ", c.num_classes);
    G2L_CHECK(c.num_keypoints >= 3 && c.num_keypoints <= 256,
              "G2LConfig: num_keypoints must be in [3, 256] (Kabsch needs 3), got ", c.num_keypoints);
    G2L_CHECK(std::isfinite(c.width) && c.width > 0 && c.width <= 16,
              "G2LConfig: width must be finite, > 0 and <= 16, got ", c.width);
    G2L_CHECK(c.dropout >= 0 && c.dropout < 1, "G2LConfig: dropout must be in [0, 1), got ",
              c.dropout);
    G2L_CHECK(c.rre_dropout >= 0 && c.rre_dropout < 1,
              "G2LConfig: rre_dropout must be in [0, 1), got ", c.rre_dropout);
    G2L_CHECK(std::isfinite(c.out_scale_mm) && c.out_scale_mm > 0,
              "G2LConfig: out_scale_mm must be finite and > 0, got ", c.out_scale_mm);
    return c;
}

// Parameters of `m` renamed "<prefix>.<name>".
ParamGroup group(const std::string& name, const Module& m, double lr_mult, double wd) {
    ParamGroup g;
    g.name = name;
    g.lr_mult = lr_mult;
    g.weight_decay = wd;
    for (auto& [n, t] : m.named_parameters()) g.params.emplace_back(name + "." + n, t);
    return g;
}

}  // namespace

G2LNet::G2LNet(const G2LConfig& config) : cfg_(checked(config)) {
    // One initialisation stream, consumed in a fixed order; independent dropout streams.
    Rng rng(cfg_.seed);
    Rng seeds(cfg_.seed ^ 0xD1B54A32D192ED03ull);
    const double w = cfg_.width, p = cfg_.dropout;
    const int64_t C = cfg_.num_classes, K = cfg_.num_keypoints;
    seg_ = register_module("seg", std::make_shared<SegNet>(w, C, p, rng, seeds.next_u64()));
    tnet_ = register_module("tnet", std::make_shared<TNet>(w, C, p, rng, seeds.next_u64()));
    if (cfg_.evf)
        evf_ = register_module("evf", std::make_shared<EvfNet>(w, C, K, p, rng, seeds.next_u64(),
                                                                cfg_.class_heads));
    rot_ = register_module("rot",
                           std::make_shared<RotNet>(w, C, K, cfg_.evf, p, rng, seeds.next_u64(),
                                                    cfg_.class_heads));
    if (cfg_.rre)
        rre_ = register_module(
            "rre", std::make_shared<RreNet>(w, C, K, cfg_.rre_dropout, rng, seeds.next_u64(),
                                             cfg_.class_heads));
}

Tensor G2LNet::scaled(const Tensor& t) const {
    return cfg_.out_scale_mm == 1.0 ? t : mul_scalar(t, cfg_.out_scale_mm);
}

Tensor G2LNet::seg_forward(const Tensor& x, const Tensor& onehot) {
    return seg_->forward(x, onehot);
}

Tensor G2LNet::t_forward(const Tensor& x, const Tensor& onehot) {
    return scaled(tnet_->forward(x, onehot));
}

bool same_architecture(const G2LConfig& a, const G2LConfig& b) {
    return a.num_classes == b.num_classes && a.num_keypoints == b.num_keypoints &&
           a.evf == b.evf && a.rre == b.rre && a.width == b.width &&
           a.out_scale_mm == b.out_scale_mm && a.rot_unit == b.rot_unit &&
           a.class_heads == b.class_heads;
}

double rotation_scale(const std::string& unit, const std::vector<Eigen::Vector3f>& kp) {
    if (unit == "mm") return 1.0;
    G2L_CHECK(unit == "kp_rms", "rotation unit must be \"mm\" or \"kp_rms\", got \"", unit, "\"");
    G2L_CHECK(!kp.empty(), "rotation_scale: no keypoints");
    double s = 0;
    for (const auto& p : kp) s += double(p.squaredNorm());
    s = std::sqrt(s / double(kp.size()));
    G2L_CHECK(std::isfinite(s) && s > 1e-3, "rotation_scale: keypoints of RMS norm ", s,
              " mm cannot set the rotation unit");
    return s;
}

RotOut G2LNet::rot_forward(const Tensor& x, const Tensor& onehot, const Tensor& scale) {
    const bool unit = scale.defined();
    if (unit)
        G2L_CHECK(scale.dim() == 3 && x.dim() == 3 && scale.size(0) == x.size(0) &&
                      scale.size(1) == 1 && scale.size(2) == 1,
                  "G2LNet::rot_forward: scale must be [B, 1, 1] for x ", x.desc(), ", got ",
                  scale.desc());
    // Outputs in mm: multiplied by the per-sample scale (kp_rms) or by out_scale_mm.
    auto to_mm = [&](const Tensor& t) { return unit ? mul(t, scale) : scaled(t); };
    const Tensor xin = unit ? div(x, scale) : x;
    RotOut out;
    PointFeatures feat;
    if (evf_) {
        EvfOut a = evf_->forward(xin, onehot);
        out.vectors = a.vectors;
        feat = a.feat;  // already detached
        out.keypoints = to_mm(rot_->forward(out.vectors, feat));
    } else {
        const PointFeatures live = rot_->features(xin, onehot);
        out.keypoints = to_mm(rot_->forward(Tensor(), live));
        feat = live.detached();
    }
    if (rre_) out.residual = to_mm(rre_->forward(feat));
    return out;
}

std::vector<ParamGroup> G2LNet::param_groups(const G2LLrMults& m, double wd) const {
    std::vector<ParamGroup> groups;
    groups.push_back(group("seg", *seg_, m.seg, wd));
    groups.push_back(group("tnet", *tnet_, m.tnet, wd));
    if (evf_) groups.push_back(group("evf", *evf_, m.evf, wd));
    groups.push_back(group("rot", *rot_, m.rot, wd));
    if (rre_) groups.push_back(group("rre", *rre_, m.rre, wd));
    return groups;
}

}  // namespace g2l::nn
