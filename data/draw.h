// SPDX-License-Identifier: MIT
// Drawing on RGB images for visualisations (g2l_infer, g2l_eval --vis): lines, projected 3D
// boxes as in the paper's Fig. 7, and simple curve plots.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "data/dataset.h"
#include "geometry/types.h"

namespace g2l::data {

using Rgb = std::array<uint8_t, 3>;

/// Draws a line segment (clipped to the image; `thickness` pixels) on a 3-channel image.
/// Non-finite end points draw nothing. Throws g2l::Error unless image is 3-channel and
/// w x h x 3 bytes.
void draw_line(Image* image, double u0, double v0, double u1, double v1, const Rgb& color,
               int thickness = 1);

/// Draws the 12 edges of the axis-aligned box [lo, hi] (model frame, mm) of an object at
/// `pose`, projected with K. Edges with a corner at z <= 0 are skipped.
void draw_box3d(Image* image, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                const geom::Pose& pose, const geom::Intrinsics& K, const Rgb& color,
                int thickness = 2);

/// Draws the outline of the pixel box [x, y, x + w) x [y, y + h) (clipped to the image).
void draw_rect(Image* image, double x, double y, double w, double h, const Rgb& color,
               int thickness = 1);

/// Writes `text` (ASCII; OpenCV's Hershey simplex font, `scale` 0.4 is ~9 px tall) with its
/// baseline's left end at (x, y), on a dark backing so it reads on any image; clipped to the
/// image. Throws g2l::Error unless image is 3-channel and w x h x 3 bytes.
void draw_text(Image* image, int x, int y, const std::string& text, const Rgb& color,
               double scale = 0.4);

/// A 3-channel image of a depth map (mm): near = bright, no depth = black.
Image depth_to_rgb(const std::vector<float>& depth_mm, int w, int h);

/// A plot (w x h pixels, white background, axes) of y(x) curves with x in [0, x_max] and y in
/// [0, 100] (e.g. accuracy in % against a threshold), one colour per curve.
Image plot_curves(const std::vector<std::vector<std::pair<double, double>>>& curves,
                  const std::vector<Rgb>& colors, double x_max, int w = 480, int h = 360);

}  // namespace g2l::data
