// SPDX-License-Identifier: MIT
// G2L-Net pose recovery from a cropped point cloud (spec §1 steps 4-10): segmentation,
// translation = mean(object points) + residual, rotation from the keypoints of block B by Kabsch,
// corrected by block C's residual and a second Kabsch. Shared by training validation and the
// inference library.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "geometry/types.h"
#include "nn/models/g2l_net.h"

namespace g2l::nn {

struct PoseEstimate {
    bool ok = false;              ///< false: too few points / object points (see `status`)
    std::string status;           ///< "ok", "too few crop points", "too few object points"
    geom::Pose pose;              ///< model -> camera (mm)
    int num_object_points = 0;
    double ms_seg = 0, ms_t = 0, ms_rot = 0;  ///< wall time of each stage
};

/// Estimates the pose of the object of class `class_index` from camera-frame points (mm) of a
/// crop. `model_keypoints` are the K model-frame keypoints the network was trained with.
/// `max_points` caps the object points fed to the T/rotation nets (a deterministic stride
/// subsample; 0 = no cap). Runs the networks without recording a graph (the caller puts `net`
/// in eval mode). Throws g2l::Error for a bad class index or keypoint count.
/// `crop_points` > 0: the seg net sees exactly that many crop points, picked deterministically
/// as in training (an even stride when the crop has more, every point once plus evenly spread
/// repeats when it has fewer); 0 = the whole crop. `max_points` > 0 likewise fixes the number of
/// object points fed to the T-net and the rotation blocks (training: sampling.seg_points).
PoseEstimate estimate_pose(G2LNet& net, const geom::Points& crop_points, int class_index,
                           const std::vector<Eigen::Vector3f>& model_keypoints,
                           int max_points = 2000, int crop_points_n = 0);

/// n indices into [0, size): an even stride when size > n, else every index once and then
/// evenly spread repeats (the deterministic counterpart of training's sampling). Empty when
/// size == 0 or n <= 0.
std::vector<int> even_sample(int size, int n);
/// even_sample into *out (its capacity is reused: no allocation once it is large enough).
void even_sample_into(int size, int n, std::vector<int>* out);

}  // namespace g2l::nn
