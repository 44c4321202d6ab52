// SPDX-License-Identifier: MIT
// Verification of a pose against the depth it came from (spec §16): does the measured depth
// explain the model's visible surface at this pose? The classical CAD-only pipelines (Vidal et
// al. 2018, Aldoma et al. 2012) keep the hypotheses the depth explains; BOP's VSD is the same
// idea as a metric. An analytic score needs no wrong poses to train on.
//
// The posed model's surface points are projected; a coarse z-buffer keeps those the camera
// would see (nearest in their cell). Each visible point is compared with the depth measured at
// its pixel:
//   |D - z| <= tol   an inlier: the depth explains it,
//   D > z + tol      a free-space violation: the sensor saw *through* where the model would be,
//   D < z - tol      occluded: something stands in front (neutral: clutter hides objects),
//   no measurement   not counted.
// The segmentation's object points are compared with the posed surface too (how much of what
// the network took as object the pose explains). Lengths in mm.
#pragma once

#include <cstdint>
#include <vector>

#include "geometry/labels.h"
#include "geometry/refine.h"
#include "geometry/types.h"

namespace g2l::geom {

struct VerifyOptions {
    /// Half-width of the inlier band: max(tol_min_mm, tol_frac * diameter). Real depth sensors
    /// are off by a few mm at 1 m, and a pose right at 10% of the diameter may be off by more.
    double tol_frac = 0.04;
    double tol_min_mm = 6.0;
    int model_points = 4000;   ///< surface points projected (evenly strided from the tree)
    int object_points = 600;   ///< segmented points checked against the posed surface
    /// The support: inliers / (inliers + violation_weight * violations + occluded_weight *
    /// occluded). A violation is strong evidence against a pose (the sensor saw through the
    /// model); occlusion is weak (clutter hides right poses too, but a pose buried behind a
    /// surface with nothing of it seen is no pose).
    double violation_weight = 2.0;
    double occluded_weight = 0.25;
    /// Fewer measured visible points than this: nothing to verify, score 0.
    int min_visible = 25;
    /// Cell of the footprint (pixels) two poses are compared on for overlap.
    int footprint_cell_px = 4;
};

struct Verification {
    int visible = 0;       ///< visible model points with a depth measurement at their pixel
    int inliers = 0, violations = 0, occluded = 0;
    int unmeasured = 0;    ///< visible model points without a depth measurement
    double tol_mm = 0;     ///< the inlier band used
    double explained = 0;  ///< inliers / visible: the share of the seen surface the depth explains
    double violation = 0;  ///< violations / visible
    double occlusion = 0;  ///< occluded / visible
    double seg_agree = 0;  ///< share of the object points within tol of the posed surface
    double support = 0;    ///< see VerifyOptions::violation_weight
    /// support x seg_agree, in [0, 1]: near 1 when the depth explains the pose (docs/results.md
    /// has its precision-recall curve on renders and real frames); 0 with fewer than
    /// min_visible measured visible points.
    double score = 0;
    /// The image cells (footprint_cell_px squares, row-major over the image) holding the
    /// inlier points, sorted: the depth this pose claims. Two objects cannot claim the same.
    std::vector<int32_t> footprint;
    /// The bounding box of the inlier points' pixels: the part of the image the depth confirms
    /// the posed model covers (what a detector's box should have been). Empty with fewer than
    /// VerifyOptions::min_visible inliers.
    Box2i box;
};

/// Verifies `pose` of the model `tree` (its surface points, model frame) with box and diameter
/// `info` against `depth` and the segmented object points `object_points` (camera frame; may be
/// empty: seg_agree is then 0). Throws g2l::Error for a null depth image, a size <= 0, a
/// diameter <= 0, a non-finite pose or options out of range. With `grid` (a ClosestPointGrid
/// over the same tree) the object points' nearest model points come from its buckets: the same
/// distances as the tree's, for a fraction of the time.
Verification verify_pose(const ModelKdTree& tree, const ModelInfo& info, const Pose& pose,
                         const DepthImage& depth, const Points& object_points,
                         const VerifyOptions& opt = {}, const ClosestPointGrid* grid = nullptr);

/// |a ∩ b| / |b| of two sorted footprints (0 when either is empty): the share of b's claim that
/// a claims too. Asymmetric on purpose: a small wrong pose lying on a large object's surface
/// claims a sliver of the large one's footprint (both may stay), while the large one claims
/// all of the small one's (the small one goes when it scored lower).
double footprint_overlap(const std::vector<int32_t>& a, const std::vector<int32_t>& b);

}  // namespace g2l::geom
