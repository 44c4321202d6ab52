// SPDX-License-Identifier: MIT
// Geometric (shape-only) symmetries of an object model. G2L-Net sees only depth points, so a box,
// a can or a brick looks the same under some rotations even when its texture does not: regressing
// keypoints with a plain MSE then averages the equivalent answers (e.g. the 8 corners of a box
// under its 180-degree flips average to the centre) and the rotation never learns. Training with
// a min over these symmetries ("loss.symmetric_targets") picks the equivalent target nearest the
// prediction instead. Lengths in millimetres.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "geometry/labels.h"
#include "geometry/types.h"

namespace g2l::geom {

/// A rigid motion of model space onto itself: p -> R p + t.
struct SymmetryTransform {
    Eigen::Matrix3f R = Eigen::Matrix3f::Identity();
    Eigen::Vector3f t = Eigen::Vector3f::Zero();
};

struct SymmetryOptions {
    /// A candidate is a symmetry when the mean distance from the moved model points to the model
    /// surface is at most tolerance_frac * diameter AND either at most displacement_frac times
    /// the mean distance the points moved (small rotations move points little, so the first test
    /// alone would accept a 15-degree turn of almost anything) or below noise_frac * diameter
    /// (scan noise: a thin cylinder's 15-degree turn moves its points little but fits exactly).
    /// Chosen on the 21 YCB-Video models (docs/results.md): boxes get their 180-degree flips,
    /// cans and bowls their axis turns, the mug, drill, clamps and banana nothing.
    double tolerance_frac = 0.015;
    double displacement_frac = 0.1;
    double noise_frac = 0.005;
    /// Rotations about each bounding-box axis at multiples of 360 / axis_steps degrees are tried
    /// (continuous symmetries of cans and bowls become this many discrete ones).
    int axis_steps = 24;
    /// At most this many model points (evenly strided) are moved and measured per candidate.
    int max_points = 2000;
};

/// The object's own box: a mesh need not be modelled with its faces along the model axes (the
/// YCB-Video pudding box and wood block are turned ~20-30 degrees about z in their model frames,
/// so the axis-aligned box of `info` is not theirs and its flips are not their symmetries).
struct ModelFrame {
    Eigen::Matrix3f axes = Eigen::Matrix3f::Identity();  ///< box axes (columns), model coordinates
    Eigen::Vector3f centre = Eigen::Vector3f::Zero();    ///< box centre, model coordinates
    Eigen::Vector3f size = Eigen::Vector3f::Zero();      ///< box extent along each axis (mm)
    bool aligned = true;                                 ///< axes are the model axes
};

/// The smallest-volume box among the axis-aligned one and, for each principal axis of `pts`
/// (PCA), the box along that axis whose cross-section has the least area (a search over the
/// turn about the axis in 0.5-degree steps). The axis-aligned box is kept unless the other is
/// smaller by more than `min_gain` of its volume (a modelled-aligned object stays as modelled).
/// Throws g2l::Error if pts has fewer than 4 rows or a non-finite coordinate.
ModelFrame model_frame(const Points& pts, double min_gain = 0.03);

/// The symmetries of the model whose surface `tree` holds (ModelKdTree::from_mesh), about the
/// centre of its box (model_frame of the tree's points; the axis-aligned box of `info` when the
/// model is modelled along its axes): the identity first, then every accepted candidate among
/// the 24 axis-permuting rotations of the box and the rotations about each box axis (duplicates
/// removed). Throws g2l::Error if info.diameter is not > 0 or an option is out of range.
std::vector<SymmetryTransform> geometric_symmetries(const ModelKdTree& tree, const ModelInfo& info,
                                                    const SymmetryOptions& opt = {});

/// How well a candidate maps the model onto itself, over at most max_points strided points of
/// `tree`: error_mm = mean distance from the moved points to the model surface, displacement_mm =
/// mean distance the points moved. The measures geometric_symmetries thresholds.
struct SymmetryScore {
    double error_mm = 0;
    double displacement_mm = 0;
};
SymmetryScore symmetry_score(const ModelKdTree& tree, const SymmetryTransform& s,
                             int max_points = 2000);

/// The GT pose composed with a symmetry S (p -> R_gt (R_s p + t_s) + t_gt): as right as gt.
Pose compose(const Pose& gt, const SymmetryTransform& s);

/// ADD modulo the symmetries (BOP's MSSD idea with the mean instead of the max): the minimum
/// over S in `syms` of ADD(est, compose(gt, S)); an empty list is plain ADD. Throws like add().
double add_sym(const Pose& est, const Pose& gt, const Points& model_pts,
               const std::vector<SymmetryTransform>& syms);

/// Rotation error (degrees) modulo the symmetries: min over S of the angle between R_est and
/// R_gt R_s; an empty list is the plain error.
double rotation_error_sym_deg(const Eigen::Matrix3d& R_est, const Eigen::Matrix3d& R_gt,
                              const std::vector<SymmetryTransform>& syms);

}  // namespace g2l::geom
