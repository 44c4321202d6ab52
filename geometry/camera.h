// SPDX-License-Identifier: MIT
// Pinhole camera helpers: depth image -> camera-frame points, points -> pixels, BOP cam_K.
// Units: millimetres for depth and points, pixels for image coordinates. A pixel (u, v) is the
// integer column/row index (no half-pixel offset), as in the official G2L-Net depth_2_mesh_bbx.
#pragma once

#include <cstdint>
#include <vector>

#include <string>

#include "geometry/types.h"

namespace g2l::geom {

/// N x 2 float pixel coordinates (u = column, v = row), one point per row.
using Pixels = Eigen::Matrix<float, Eigen::Dynamic, 2, Eigen::RowMajor>;

/// Back-projects the pixels of a 16-bit depth image inside `box` to camera-frame points (mm).
/// depth: [height, width] row-major raw sensor values; z = depth * depth_scale (mm). Pixel (u, v)
/// gives X = (u - cx) z / fx, Y = (v - cy) z / fy, Z = z. Pixels with raw depth 0 are skipped.
/// `box` is clipped to the image (an empty clipped box gives 0 points). Points come in row-major
/// pixel order (v, then u). If `pixel_index` is non-null it receives v * width + u for each point.
/// Throws g2l::Error for a null depth pointer, non-positive width/height, depth_scale <= 0 or
/// non-finite, fx/fy <= 0 or non-finite intrinsics, or K.width/K.height (when non-zero) that
/// differ from width/height.
Points depth_to_points(const uint16_t* depth, int width, int height, double depth_scale,
                       const Intrinsics& K, const Box2i& box,
                       std::vector<int>* pixel_index = nullptr);

/// Same as above for a float depth image already in millimetres. Pixels whose depth is NaN,
/// +-inf or <= 0 are skipped. Throws like the uint16 overload.
Points depth_to_points(const float* depth_mm, int width, int height, const Intrinsics& K,
                       const Box2i& box, std::vector<int>* pixel_index = nullptr);

/// Projects camera-frame points (mm, N x 3) to pixels: u = fx X / Z + cx, v = fy Y / Z + cy.
/// Returns N x 2. Throws g2l::Error naming the row if a point has Z <= 0 or a non-finite
/// coordinate, or if fx/fy are not positive.
Pixels project(const Points& pts, const Intrinsics& K);

/// Builds Intrinsics from a BOP scene_camera.json `cam_K` (row-major 3 x 3:
/// [fx 0 cx; 0 fy cy; 0 0 1]) and the image size. Throws g2l::Error naming the offending entry
/// if fx/fy <= 0, an entry is non-finite, the matrix has skew or a last row other than
/// (0, 0, 1), or width/height <= 0.
Intrinsics intrinsics_from_cam_K(const double K[9], int width, int height);

/// "" when the intrinsics are plausible for a width x height image, else why: a horizontal
/// field of view outside 20-140 degrees (fx outside 0.18-2.8 x width), fx and fy more than 10 %
/// apart, or the principal point outside the middle 60 % of the image. The intrinsics of
/// another resolution (a 1280 x 960 calibration on 640 x 480 frames) fail the last; poses
/// through them would be off without an error anywhere, so tools warn.
std::string implausible_camera(const Intrinsics& K, int width, int height);

}  // namespace g2l::geom
