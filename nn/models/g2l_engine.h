// SPDX-License-Identifier: MIT
// The fast inference path of G2L-Net: the eval-mode networks of a G2LNet compiled into plain
// weight matrices and run on preallocated buffers, for batch-1 (and several-objects) pose
// estimation. Same results as estimate_pose (nn/models/g2l_pose.h) up to float rounding.
//
// What makes it fast (all exact algebra on the eval-mode graph):
//  * BatchNorm folded into the preceding conv / linear weights and biases.
//  * The global feature g and the one-hot enter a head's first layer as a per-object bias
//    (W_g g + W_c onehot), computed once per object instead of per point.
//  * conv5 of the backbone has no ReLU, so pf = W5 x2 + b5 is linear in x2: a head's pf columns
//    fold into its x2 columns at load time (W_pf W5 is [Cout, 128] instead of [Cout, 1024]), and
//    pf itself is only computed for its max over the points. This removes ~55% of the
//    multiply-adds of the segmentation and block-A heads and ~45% of block B's first layer.
//  * No autograd graph, no per-call allocation once the buffers have grown (buffers keep the
//    largest size seen), the objects of a frame run as one batch (their points side by side).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <vector>

#include "geometry/types.h"
#include "nn/models/g2l_net.h"
#include "nn/models/g2l_pose.h"

namespace g2l::nn {

/// One object of PoseEngine::estimate.
struct PoseQuery {
    const geom::Points* crop = nullptr;  ///< camera-frame crop points (mm)
    int class_index = 0;
    const std::vector<Eigen::Vector3f>* keypoints = nullptr;  ///< the class's model keypoints
    /// Optional, one flag per crop row: the object points are given (e.g. by an instance mask,
    /// or the ground truth in an oracle evaluation). The flagged rows among the points the seg
    /// net would see (`crop_points`) replace its decision; the rest of the pipeline is unchanged.
    const std::vector<uint8_t>* object_mask = nullptr;
    /// Optional: the object's translation (mm) is given; it replaces the T-net's and centres
    /// the rotation input.
    const Eigen::Vector3f* translation = nullptr;
    /// Optional output: the crop rows taken as object (by the seg net or `object_mask`) among
    /// the points the seg net sees, before the `max_points` subsample (a row may repeat when
    /// the crop has fewer than `crop_points` points).
    std::vector<int>* object_rows = nullptr;
};

class PoseEngine {
public:
    /// Compiles the eval-mode networks of `net` (its current weights and BatchNorm running
    /// statistics; the net is not modified and may be destroyed afterwards). Throws g2l::Error
    /// if a BatchNorm has an eps other than 1e-5 or a weight is missing.
    explicit PoseEngine(const G2LNet& net);
    ~PoseEngine();
    PoseEngine(PoseEngine&&) noexcept;
    PoseEngine& operator=(PoseEngine&&) noexcept;

    /// estimate_pose for several objects at once (one PoseEstimate per query, same order):
    /// `crop_points` > 0 crop points go to the segmentation (even_sample; 0 = the whole crop),
    /// at most `max_points` object points (even_sample; 0 = all) to the T-net and the rotation
    /// blocks. Stage times (ms_seg, ms_t, ms_rot) are the batch's, divided by its size. Throws
    /// g2l::Error for a null crop/keypoints pointer, a class index outside the network, or a
    /// keypoint count that does not match. Not thread-safe (one engine per thread).
    void estimate(const std::vector<PoseQuery>& queries, int max_points, int crop_points,
                  std::vector<PoseEstimate>* out);

    /// One object.
    PoseEstimate estimate(const geom::Points& crop, int class_index,
                          const std::vector<Eigen::Vector3f>& keypoints, int max_points,
                          int crop_points);

    const G2LConfig& config() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace g2l::nn
