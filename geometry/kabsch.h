// SPDX-License-Identifier: MIT
// Kabsch / Umeyama rigid alignment without scale (spec §7). Poses use the g2l convention
// q = R p + t; R is always a proper rotation (det = +1).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "geometry/types.h"

namespace g2l::geom {

/// N x 3 double points, for Kabsch in full precision (tests, gradient checks).
using PointsD = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// Rotation R minimising sum_i |R p_i + t - q_i|^2 over rotations (t free). P and Q are N x 3
/// with row i of P matched to row i of Q; both are centred internally. With H = sum (p_i -
/// p_mean)(q_i - q_mean)^T = U S V^T, R = V diag(1, 1, d) U^T, d = sign(det(V U^T)), so a
/// reflected point set still gives det(R) = +1. Degenerate input (all points equal, collinear or
/// coplanar) gives a valid rotation, never NaN. Computed in double.
/// Throws g2l::Error if the row counts differ, N < 3, or a value is not finite (naming the row).
Eigen::Matrix3d kabsch(const Points& P, const Points& Q);

/// The rotation R minimising sum |R p_c - q_c|^2 from the 3 x 3 cross-covariance
/// H = sum (p - p_mean)(q - q_mean)^T (what every kabsch() here ends with): SVD with the
/// reflection fix. Allocation-free. H = 0 gives the identity.
Eigen::Matrix3d rotation_from_covariance(const Eigen::Matrix3d& H);

/// Weighted Kabsch: minimises sum_i w_i |R p_i + t - q_i|^2. weights: N values, finite, >= 0,
/// with a positive sum. Throws like kabsch() and for bad weights (naming the index and value).
Eigen::Matrix3d kabsch(const Points& P, const Points& Q, const std::vector<double>& weights);

/// Kabsch rotation plus t = q_mean - R p_mean, i.e. the rigid pose mapping P onto Q.
/// Throws like kabsch().
Pose kabsch_pose(const Points& P, const Points& Q);

/// Weighted kabsch_pose (weighted means). Throws like the weighted kabsch().
Pose kabsch_pose(const Points& P, const Points& Q, const std::vector<double>& weights);

/// Double-precision kabsch(). Throws like the float version.
Eigen::Matrix3d kabsch(const PointsD& P, const PointsD& Q);

/// Double-precision kabsch_pose(). Throws like the float version.
Pose kabsch_pose(const PointsD& P, const PointsD& Q);

/// Batched Kabsch on raw float buffers for the training loop (block C's online target).
/// P, Q: [B, K, 3] row-major; R_out: [B, 3, 3] row-major, R_out[b] maps P[b] onto Q[b] (centred).
/// Allocation-free (fixed-size Eigen in double), OpenMP over b; each b is independent, so results
/// do not depend on the thread count. Throws g2l::Error for null pointers, B < 0, K < 3, or a
/// non-finite input (naming b and k).
void kabsch_batched(const float* P, const float* Q, int B, int K, float* R_out);

}  // namespace g2l::geom
