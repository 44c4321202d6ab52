// SPDX-License-Identifier: MIT
// One G2L-Net training step on a batch of samples (spec §5-§6, with the official code's bugs
// fixed): segmentation on the crop, translation residual on the points the seg net predicts as
// object, rotation blocks A/B/C in the canonical frame (points minus the GT translation), and
// block C's target computed online with a batched Kabsch.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "core/rng.h"
#include "core/tensor.h"
#include "nn/models/g2l_net.h"
#include "train/sample.h"

namespace g2l::train {

struct LossWeights {
    double seg = 10, t = 0.1, vec = 10, kp = 0.01, res = 0.01;  ///< spec §6 (official code)
    bool t_smooth_l1 = false;  ///< smooth-L1 (Huber, beta 1 mm) instead of MSE for T
};

/// The model-frame keypoints of each class index: [num_classes][K] x 3 (mm).
using KeypointTable = std::vector<std::vector<Eigen::Vector3f>>;

/// Scalar values of one step (for logs) and the differentiable total.
struct StepLosses {
    Tensor total;
    double seg = 0, t = 0, vec = 0, kp = 0, res = 0;
    double seg_accuracy = 0;    ///< fraction of crop points classified correctly
    double t_error_mm = 0;      ///< mean |T_pred - T_gt| over the batch
    double kp_error_mm = 0;     ///< mean keypoint distance of block B (or C when on)
};

/// Forward + losses for `samples` (all with the same number of points). `seg_points` points are
/// resampled (with replacement, from `rng`) among those the seg net predicts as object; a sample
/// whose prediction has fewer than 10 object points uses its ground-truth object points instead
/// (the official code kept all-zero inputs there). Does not call backward.
StepLosses g2l_step(nn::G2LNet& net, const std::vector<PoseSample>& samples,
                    const KeypointTable& keypoints, int num_classes, int seg_points,
                    const LossWeights& w, Rng& rng);

}  // namespace g2l::train
