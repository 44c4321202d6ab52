// SPDX-License-Identifier: MIT
// Point-cloud crops around an estimated object centre (spec §1.3). All lengths in mm; each
// function returns the indices (ascending) of the rows of `pts` it keeps.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace g2l::geom {

/// The crop around the sphere centre (spec §2): one value from the training config through the
/// checkpoint to inference.
enum class CropKind {
    sphere,   ///< |p - centre| < radius (the paper)
    frustum,  ///< every valid depth point of the 2D box (the Frustum-PointNets baseline)
    slab,     ///< |z - centre_z| < radius (the released code's depth slab)
};
/// "sphere" / "frustum" / "slab"; anything else throws g2l::Error naming `what` and the value.
CropKind parse_crop(const std::string& text, const std::string& what);
const char* to_string(CropKind c);

/// The one crop step of training samples and inference: indices (ascending) of the rows of
/// `pts` kept by `crop` around `centre` — "sphere": |p - centre| < radius, "slab":
/// |z - centre_z| < radius (the released code's depth slab), "frustum": every row.
/// Serial (several sample-making threads call it at once). Throws g2l::Error for (sphere/slab) a radius that is not finite and > 0 or a centre that is not finite.
std::vector<int> crop_indices(CropKind crop, const Points& pts,
                              const Eigen::Vector3d& centre, double radius);

/// The rows of `pts` that crop_indices keeps, in order, as a new point set (what the networks
/// get: training samples, g2l_eval and the inference library crop through this pair).
Points crop_points(CropKind crop, const Points& pts, const Eigen::Vector3d& centre,
                   double radius);

/// `box` clipped to a width x height image (an empty box when nothing is left).
Box2i clip_box(const Box2i& box, int width, int height);

/// Intersection over union of two boxes given as top-left corner and size (pixels); 0 when
/// the union is empty.
double box_iou(double ax, double ay, double aw, double ah, double bx, double by, double bw,
               double bh);

/// The sphere centre from a 2D box and the depth alone, as a detector gives it: in the central
/// third of the box (the whole box when that third has no valid depth), the valid pixel whose
/// depth is nearest the median depth there (ties: nearest the box centre), back-projected with
/// K. Pixels with z <= 0 or a non-finite z are invalid. Returns false when the box (clipped to
/// the image) is empty or has no valid depth. Throws g2l::Error for a null depth, a non-positive
/// image size or intrinsics with a focal length that is not finite and > 0.
bool box_centre(const float* depth_mm, int width, int height, const Intrinsics& K,
                const Box2i& box, Eigen::Vector3d* centre);

/// The sphere centre from a detector's heat-map peak (spec §2): the peak pixel (u, v) lifted
/// with the depth of the nearest valid pixel inside `box` (the peak's own when valid; else
/// searched in square rings of growing size, the smallest Euclidean distance first, ties in
/// row-major order: deterministic). Returns false when the box (clipped) is empty, the peak is
/// not finite, or the box has no valid depth. Throws as box_centre.
bool peak_centre(const float* depth_mm, int width, int height, const Intrinsics& K,
                 const Box2i& box, double u, double v, Eigen::Vector3d* centre);

}  // namespace g2l::geom
