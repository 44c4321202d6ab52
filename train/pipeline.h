// SPDX-License-Identifier: MIT
// One G2L-Net training step on a batch of samples (spec §5-§6, with the official code's bugs
// fixed): segmentation on the crop, translation residual on the points the seg net predicts as
// object, rotation blocks A/B/C in the canonical frame (points minus the GT translation), and
// block C's target computed online with a batched Kabsch.
#pragma once

#include <Eigen/Core>
#include <cstdint>
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

/// Options of a training step beyond the loss weights.
struct StepOptions {
    /// Per class index: mm per unit of the rotation branch (nn::rotation_scale of the class's
    /// keypoints). Empty = 1 for every class (rot_unit "mm").
    std::vector<float> rot_scale;
    /// Rotation input points: "pred" (the points the seg net predicts as object, as at test
    /// time; fewer than 10 -> the GT object points) or "gt" (the ground-truth object points: the
    /// rotation blocks learn on clean input while the seg net is still poor).
    bool rot_gt_points = false;
    /// Rotation input centre: the GT translation plus Gaussian noise of this std-dev per axis
    /// (mm), so the rotation nets see the centring error that the T-net's estimate has at test
    /// time. Targets stay geometrically consistent: keypoints relative to the noisy centre.
    double centre_noise_mm = 0;
    /// true: centre the rotation input with the T-net's prediction of this step (detached)
    /// instead of the GT translation (+ noise) — exactly the test-time input.
    bool centre_with_prediction = false;
    /// true: train the rotation blocks alone — no segmentation or T-net forward pass; they get
    /// the ground-truth object points centred on the GT translation (+ centre_noise_mm). The
    /// seg/T losses are reported as 0. A cheap warm-up phase (loss.rot_only_epochs).
    bool rot_only = false;
    /// Per-sample random streams (size B) used instead of g2l_step's `rng`: sample b draws its
    /// resampling and centre noise from (*sample_rngs)[b] alone, so its draws do not depend on
    /// which other samples share its batch — data-parallel training (train/distributed.h)
    /// seeds them by the sample's place in the global batch. Borrowed; null = `rng`.
    std::vector<Rng>* sample_rngs = nullptr;
};

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
                    const LossWeights& w, Rng& rng, const SymmetricKeypoints* symmetric = nullptr,
                    const StepOptions& opt = StepOptions());

/// The rotation input made of the ground-truth object points of each sample: M of them, drawn
/// with replacement from `rng`, or an even stride when `rng` is null (evaluation); centred on the
/// GT translation plus N(0, noise_mm) per axis (noise only with `rng`). Every point is flagged
/// object. Throws g2l::Error naming the sample that has no object point.
struct RotationInput {
    Tensor x;                              ///< [B, 3, M] points minus centres (mm)
    std::vector<uint8_t> object;           ///< B * M ones
    std::vector<Eigen::Vector3f> centres;  ///< per sample
};
/// `sample_rngs` (optional, size B): sample b draws from (*sample_rngs)[b] instead of `rng`.
RotationInput gt_rotation_input(const std::vector<PoseSample>& samples, int64_t M,
                                double noise_mm, Rng* rng,
                                std::vector<Rng>* sample_rngs = nullptr);

/// The rotation blocks alone (A, B, C) on canonical points, as in g2l_step's part 4.
/// xr: [B, 3, M] points minus `centres` (mm); object[b * M + m] != 0 for points of the object
/// (the others get zero vector targets, as in the official code); centres[b]: the point the
/// input was centred on, in the sample's frame (targets are R kp + t - centre). Losses are
/// taken in the rotation unit (opt.rot_scale). Fills vec, kp, res, kp_error_mm, sym_fraction
/// and returns the weighted sum of the rotation losses.
Tensor rotation_losses(nn::G2LNet& net, const std::vector<PoseSample>& samples, const Tensor& xr,
                       const std::vector<uint8_t>& object,
                       const std::vector<Eigen::Vector3f>& centres, const Tensor& onehot,
                       const KeypointTable& keypoints, const LossWeights& w,
                       const SymmetricKeypoints* symmetric, const StepOptions& opt,
                       StepLosses* out);

}  // namespace g2l::train
