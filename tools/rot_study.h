// SPDX-License-Identifier: MIT
// Learning curves of the rotation blocks alone (A, B and optionally C) on ground-truth-segmented
// points: the tool behind docs/experiments.md and the "rotation learns" test. Every factor that
// can hold blocks A/B on the "predict zero" plateau is a field of RotStudyConfig, so one factor
// can be changed at a time.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "train/pipeline.h"
#include "train/sample.h"

namespace g2l::tools {

struct RotStudyConfig {
    int steps = 300;           ///< optimiser steps
    int batch = 16;            ///< samples per step
    int points = 256;          ///< object points fed to the rotation blocks (M)
    int eval_every = 50;       ///< steps between validations (and the last step)
    double lr = 1e-3;          ///< Adam base lr (betas 0.9 / 0.99 as the official code)
    /// Step decay: the lr is multiplied by lr_decay_factor every lr_decay_every steps
    /// (0 = constant lr).
    int lr_decay_every = 0;
    double lr_decay_factor = 0.5;
    double mult_evf = 1, mult_rot = 1, mult_rre = 1;  ///< lr multipliers of blocks A, B, C
    double width = 0.25;       ///< network width multiplier
    double dropout = 0.2;      ///< dropout before the last layer of A and B
    double bn_momentum = 0.1;  ///< BatchNorm running-statistics momentum (PyTorch 0.1)
    std::string rot_unit = "kp_rms";  ///< "mm" (official) or "kp_rms" (nn::G2LConfig)
    double out_scale_mm = 1.0;        ///< nn::G2LConfig::out_scale_mm (rot_unit "mm" only)
    bool evf = true;           ///< block A on (its vectors feed block B)
    bool rre = false;          ///< block C on
    train::LossWeights weights;       ///< vec, kp, res used (seg and t are not)
    double centre_noise_mm = 0;  ///< Gaussian centring error per axis (StepOptions)
    bool symmetric = false;    ///< min-over-symmetries targets (needs `symmetric` tables)
    uint64_t seed = 1;         ///< initialisation, point picks, batch order
    /// Initialisation: false = PyTorch's default U(+-1/sqrt(fan_in)) everywhere; true = the
    /// last layers of blocks A, B (and C) start at zero (the prediction starts at "zero").
    bool zero_last_layers = false;
    bool class_heads = false;  ///< nn::G2LConfig::class_heads
};

/// One point of a learning curve.
struct RotStudyPoint {
    int step = 0;
    int64_t samples = 0;          ///< training samples seen so far
    double seconds = 0;           ///< wall time since the start of training
    double train_kp_err_mm = 0;   ///< mean keypoint error of the last eval_every steps (train mode)
    double val_kp_err_mm = 0;     ///< mean keypoint error on the validation samples (eval mode)
    double val_kp_err_frac = 0;   ///< val_kp_err_mm / object diameter (mean over samples)
    double val_rot_err_deg_median = 0;  ///< median rotation error (modulo symmetries if given)
    double val_rot_err_deg_mean = 0;
    double val_acc_10deg = 0;     ///< fraction of validation samples under 10 degrees
    std::vector<double> val_kp_err_frac_each;  ///< per validation sample, in `val` order
    std::vector<double> val_rot_err_deg_each;  ///< per validation sample, in `val` order
};

/// Source of training samples: fills *out for draw number i (i = 0, 1, ...) and returns true,
/// or returns false when draw i is unusable (it is skipped).
using SampleDraw = std::function<bool(int64_t i, train::PoseSample* out)>;

/// Trains a fresh G2LNet's rotation blocks on the ground-truth object points of the drawn
/// samples (centred on the GT translation plus centre_noise_mm), evaluating on `val` every
/// eval_every steps. `diameters[class]` (mm) scales val_kp_err_frac. `on_point` (optional) is
/// called with each curve point as it is measured. Throws g2l::Error for an empty validation
/// set, bad sizes, or a draw function that fails 1000 times in a row.
std::vector<RotStudyPoint> rot_study(const RotStudyConfig& cfg, int num_classes,
                                     const train::KeypointTable& keypoints,
                                     const std::vector<double>& diameters,
                                     const train::SymmetricKeypoints* symmetric, const SampleDraw& draw,
                                     const std::vector<train::PoseSample>& val,
                                     const std::function<void(const RotStudyPoint&)>& on_point = {});

}  // namespace g2l::tools
