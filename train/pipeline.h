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

/// For each class index, the keypoints moved by each geometric symmetry of the model
/// (geom::geometric_symmetries): [num_classes][S][K] x 3, the identity (= KeypointTable) first.
using SymmetricKeypoints = std::vector<KeypointTable>;

/// Scalar values of one step (for logs) and the differentiable total.
struct StepLosses {
    Tensor total;
    double seg = 0, t = 0, vec = 0, kp = 0, res = 0;
    double seg_accuracy = 0;    ///< fraction of crop points classified correctly
    double t_error_mm = 0;      ///< mean |T_pred - T_gt| over the batch
    double kp_error_mm = 0;     ///< mean keypoint distance of block B (or C when on)
    double sym_fraction = 0;    ///< fraction of samples whose nearest target is not the identity
};

/// Forward + losses for `samples` (all with the same number of points). `seg_points` points are
/// resampled (with replacement, from `rng`) among those the seg net predicts as object; a sample
/// whose prediction has fewer than 10 object points uses its ground-truth object points instead
/// (the official code kept all-zero inputs there). Does not call backward.
/// `symmetric` (optional): per sample, the rotation targets (keypoints of block B and C, vectors
/// of block A) use the symmetric keypoint set nearest block B's prediction instead of the
/// identity one (a min-over-symmetries loss; see geometry/symmetry.h).
StepLosses g2l_step(nn::G2LNet& net, const std::vector<PoseSample>& samples,
                    const KeypointTable& keypoints, int num_classes, int seg_points,
                    const LossWeights& w, Rng& rng, const SymmetricKeypoints* symmetric = nullptr);

}  // namespace g2l::train
