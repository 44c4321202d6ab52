// SPDX-License-Identifier: MIT
// Model keypoints in the model frame (mm): the 8 bounding-box corners of G2L-Net (spec §5) or
// farthest-point-sampled vertices (the paper's FPS-4/8/12 ablation).
#pragma once

#include <string>

#include "geometry/types.h"

namespace g2l::geom {

/// The 8 corners of the model's axis-aligned box from models_info (max = min + size), 8 x 3, in
/// the fixed G2L-Net order (spec §5):
/// 0 (minx,miny,maxz) 1 (minx,maxy,maxz) 2 (minx,maxy,minz) 3 (minx,miny,minz)
/// 4 (maxx,miny,minz) 5 (maxx,miny,maxz) 6 (maxx,maxy,minz) 7 (maxx,maxy,maxz).
/// Throws g2l::Error if a size is negative or a value is not finite.
Points bbox_corners(const ModelInfo& info);

/// Farthest point sampling: picks k rows of `pts` (N x 3), each the point farthest from those
/// already picked (ties -> lowest index). start = -1 begins with the point farthest from the
/// centroid, otherwise with row `start`. Deterministic. Returns k x 3.
/// Throws g2l::Error if k < 1, k > N, or start is outside [-1, N).
Points farthest_point_sampling(const Points& pts, int k, int start = -1);

/// Keypoints of a model by kind: "bbx8" -> bbox_corners(info); "fps4", "fps8", "fps12" ->
/// farthest_point_sampling(model_pts, 4 / 8 / 12). Returns K x 3 (mm, model frame).
/// Throws g2l::Error naming `kind` if it is none of these.
Points keypoints(const Points& model_pts, const ModelInfo& info, const std::string& kind);

/// How many keypoints `kind` gives (bbx8 and fps8: 8, fps4: 4, fps12: 12), without a model.
/// Throws g2l::Error naming `kind` if it is none of these.
int keypoint_count(const std::string& kind);

/// keypoints() on the vertices of `mesh`.
Points keypoints(const Mesh& mesh, const ModelInfo& info, const std::string& kind);

}  // namespace g2l::geom
