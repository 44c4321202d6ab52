// SPDX-License-Identifier: MIT
// Plain geometry value types shared by geometry/, data/ and the layers above.
// Units: millimetres for every length; poses map model points into the camera frame:
// x_cam = R * x_model + t.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace g2l::geom {

/// N x 3 float points (mm), one point per row.
using Points = Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// N x 3 uint8 RGB colours, one per row.
using Colors = Eigen::Matrix<uint8_t, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// F x 3 vertex indices of triangles.
using Faces = Eigen::Matrix<int32_t, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// Pinhole intrinsics of a width x height image (pixels). Never hard-coded: read from the
/// dataset (scene_camera.json cam_K) or the config.
struct Intrinsics {
    double fx = 0, fy = 0, cx = 0, cy = 0;
    int width = 0, height = 0;
};

/// Rigid pose: x_cam = R * x_model + t (t in mm).
struct Pose {
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    Eigen::Vector3d t = Eigen::Vector3d::Zero();
};

/// A triangle mesh in model coordinates (mm). normals and colors are empty when the file has
/// none; faces are empty for a point-only model.
struct Mesh {
    Points vertices;
    Points normals;
    Colors colors;
    Faces faces;
    std::string path;  ///< file it was loaded from (for error messages)
};

/// BOP models_info entry: diameter and axis-aligned extent of the model (mm).
struct ModelInfo {
    double diameter = 0;
    Eigen::Vector3d min = Eigen::Vector3d::Zero();   ///< (min_x, min_y, min_z)
    Eigen::Vector3d size = Eigen::Vector3d::Zero();  ///< (size_x, size_y, size_z)
    bool symmetric = false;  ///< evaluated with ADD-S (dataset's symmetric list or config)
};

/// A 2D pixel box [x, y, x + w) x [y, y + h) as BOP stores it (bbox_visib / bbox_obj).
struct Box2i {
    int x = 0, y = 0, w = 0, h = 0;
    bool empty() const { return w <= 0 || h <= 0; }
};

}  // namespace g2l::geom
