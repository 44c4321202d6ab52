// SPDX-License-Identifier: MIT
// Pose-error metrics with the BOP toolkit / YCB-Video toolbox definitions (spec §11). Lengths
// in whatever unit the inputs use (g2l: mm), except vocap_auc which follows the toolbox in metres.
#pragma once

#include <vector>

#include "geometry/types.h"

namespace g2l::geom {

/// ADD: mean over model points x of |(R_e x + t_e) - (R_g x + t_g)|. model_pts: N x 3 (mm).
/// Throws g2l::Error if N == 0 or a pose or point is not finite.
double add(const Pose& est, const Pose& gt, const Points& model_pts);

/// Median of the values (the mean of the two middle ones for an even count); 0 when empty.
double median(std::vector<double> v);

/// ADD-S (BOP `adi`): a KD-tree is built on the ESTIMATED-posed points; for every GT-posed point
/// its nearest-neighbour distance is taken; returns the mean. Throws like add().
double adds(const Pose& est, const Pose& gt, const Points& model_pts);

/// Rotation error in degrees: acos(clamp((trace(R_e R_g^T) - 1) / 2, -1, 1)).
/// Throws g2l::Error if a rotation is not finite.
double rotation_error_deg(const Eigen::Matrix3d& R_est, const Eigen::Matrix3d& R_gt);

/// Translation error |t_g - t_e| (same unit as t). Throws g2l::Error if not finite.
double translation_error(const Eigen::Vector3d& t_est, const Eigen::Vector3d& t_gt);

/// LINEMOD accuracy test: err < frac * diameter (strict). A miss should be passed as
/// err = +inf (counts as incorrect). Throws g2l::Error if err is NaN, diameter <= 0 or
/// frac <= 0.
bool correct_at(double err, double diameter, double frac = 0.1);

/// YCB-Video toolbox VOCap AUC (spec §11.3), in percent [0, 100]. distances_m: one ADD or ADD-S
/// per GT instance in METRES, +inf for a missed detection. Entries > max_threshold_m become inf;
/// they and the misses stay in n (the accuracy denominator). Accuracy vs threshold is integrated
/// with the toolbox's right-endpoint step rule on [0, max_threshold_m] and divided by
/// max_threshold_m. All entries inf -> 0. Throws g2l::Error for an empty list, a NaN or negative
/// entry (naming its index) or max_threshold_m <= 0.
double vocap_auc(std::vector<double> distances_m, double max_threshold_m = 0.1);

}  // namespace g2l::geom
