// SPDX-License-Identifier: MIT
// G2L-Net (Chen et al., CVPR 2020): segmentation, translation residual and rotation networks
// (spec §4) in one Module, with the entry points the trainer and the pose estimator call.
//
// State dict names: "seg.backbone.conv1.weight", "seg.head.conv1.weight", "seg.out.weight",
// "tnet.mlp.conv1.weight", "tnet.fc.fc1.weight", "evf.backbone...", "rot.mlp.conv1.weight",
// "rot.fc.fc1.weight", "rot.out.weight", "rre.mlp.conv1.weight", "rre.out.weight", plus BN
// buffers and the Dropout "rng_state" buffers. See g2l_blocks.h for the head column order.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <memory>
#include <vector>

#include "nn/models/g2l_blocks.h"
#include "nn/optim.h"

namespace g2l::nn {

/// Hyper-parameters of the networks.
struct G2LConfig {
    int num_classes = 16;    ///< one-hot width (16 in the official LINEMOD code)
    int num_keypoints = 8;   ///< K (8 for bbx8; 4/8/12 for fps); block A/B/C output 3K
    bool evf = true;         ///< build block A (else the frustum baseline: B sees features only)
    bool rre = true;         ///< build block C (the rotation residual)
    double width = 1.0;      ///< multiplier of every hidden width (rounded, min 8); 1 = paper
    double dropout = 0.2;    ///< Dropout before the last layer of seg, tnet, evf, rot
    uint64_t seed = 1;       ///< initialisation and dropout streams
    double rre_dropout = 0.3;  ///< Dropout on block C's input (official 0.3)
    /// Unit of the millimetre-valued outputs (T-net residual, block B keypoints, block C
    /// residual): the last layer predicts value / out_scale_mm. The official code uses 1, which
    /// makes Adam need thousands of steps just to reach the ~100 mm output range.
    double out_scale_mm = 1.0;
    /// Unit of the rotation branch (inputs and outputs): "mm" (official) or "kp_rms" (the RMS
    /// norm of the object's model keypoints, so keypoint targets have unit size for every
    /// object). The network itself only sees the `scale` tensor; callers compute it with
    /// rotation_scale(). out_scale_mm does not apply to the rotation branch under "kp_rms".
    std::string rot_unit = "mm";
    /// One output block per class in the last layers of blocks A, B and C (each sample reads
    /// its class's block; the one-hot still enters the heads as in the paper). Without it the
    /// classes share the output layer and one model of many objects learns each object's
    /// keypoints far more slowly (docs/experiments.md).
    bool class_heads = false;
};

/// The same network: every field that shapes the parameters or what they compute (classes,
/// keypoints, evf, rre, width, out_scale_mm, rot_unit, class_heads); dropout rates and the
/// seed only change training, so two configs differing in them load each other's weights.
bool same_architecture(const G2LConfig& a, const G2LConfig& b);

/// Scale (mm per unit) of the rotation branch for an object with these model keypoints under
/// `rot_unit`: 1 for "mm", sqrt(mean_k |kp_k|^2) for "kp_rms". Throws for another unit or
/// degenerate keypoints.
double rotation_scale(const std::string& rot_unit, const std::vector<Eigen::Vector3f>& keypoints);

/// The outputs of the rotation branch.
struct RotOut {
    Tensor vectors;    ///< [B, 3K, M] block A's per-point keypoint vectors (undefined if evf off)
    Tensor keypoints;  ///< [B, K, 3] block B's keypoints in the canonical frame (mm)
    Tensor residual;   ///< [B, K, 3] block C's per-keypoint residual (undefined if rre off)
};

/// Learning-rate multipliers per sub-network (official: seg 1, tnet 10, evf 1, rre 20, rot 30).
struct G2LLrMults {
    double seg = 1, tnet = 10, evf = 1, rot = 30, rre = 20;
};

/// All G2L-Net sub-networks. Children (state dict prefixes): "seg", "tnet", "evf" (if evf),
/// "rot", "rre" (if rre). Graphs are recorded unless the caller holds an
/// autograd::NoGradGuard (do so for evaluation); eval() switches BN and dropout to inference.
class G2LNet : public Module {
public:
    /// Throws g2l::Error naming the field if num_classes < 1, num_keypoints < 3, width is not
    /// finite and > 0, or a dropout is outside [0, 1).
    explicit G2LNet(const G2LConfig& cfg);

    const G2LConfig& config() const { return cfg_; }

    /// Segmentation. x: [B, 3, N] (mm, channel-first), onehot: [B, num_classes] ->
    /// log-probabilities [B, 2, N] (channel 1 = object). Throws naming the shape if x is not
    /// [B, 3, N] (e.g. [B, N, 3]) or onehot does not fit.
    Tensor seg_forward(const Tensor& x, const Tensor& onehot);
    /// Translation residual. x: [B, 3, M] object points minus their mean -> [B, 3] (mm).
    Tensor t_forward(const Tensor& x, const Tensor& onehot);
    /// Rotation branch on canonical points x: [B, 3, M] (object points minus the translation):
    /// A (if evf) -> B on [A's vectors, A's detached features] -> C (if rre) on the same
    /// detached features. Without evf, B's own backbone provides the features (trained by B's
    /// loss) and C gets them detached.
    ///
    /// `scale` (optional, [B, 1, 1], mm): the rotation branch works in units of `scale` per
    /// sample: x is divided by it before block A, and the keypoints and residual (predicted in
    /// those units) are multiplied by it, so the outputs are always in mm. With the object's
    /// keypoint RMS radius as the scale every object's keypoints have unit size (see
    /// G2LConfig::rot_unit), which keeps blocks B/C off the "predict zero" plateau.
    RotOut rot_forward(const Tensor& x, const Tensor& onehot, const Tensor& scale = Tensor());

    /// One ParamGroup per built sub-network, named "seg", "tnet", "evf", "rot", "rre", with
    /// full dotted parameter names ("seg.backbone.conv1.weight") and the given multipliers.
    std::vector<ParamGroup> param_groups(const G2LLrMults& mults = {},
                                         double weight_decay = 0.0) const;

    /// The sub-networks (evf / rre are null when not built).
    const std::shared_ptr<SegNet>& seg() const { return seg_; }
    const std::shared_ptr<TNet>& tnet() const { return tnet_; }
    const std::shared_ptr<EvfNet>& evf() const { return evf_; }
    const std::shared_ptr<RotNet>& rot() const { return rot_; }
    const std::shared_ptr<RreNet>& rre() const { return rre_; }

private:
    Tensor scaled(const Tensor& t) const;  ///< t * out_scale_mm (identity at 1)
    G2LConfig cfg_;
    std::shared_ptr<SegNet> seg_;
    std::shared_ptr<TNet> tnet_;
    std::shared_ptr<EvfNet> evf_;
    std::shared_ptr<RotNet> rot_;
    std::shared_ptr<RreNet> rre_;
};

}  // namespace g2l::nn
