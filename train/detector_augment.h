// SPDX-License-Identifier: MIT
// What the detector trainer does to a rendered image before the network sees it: colour,
// noise and blur augmentation, clutter or photograph backgrounds, painted distractors
// (docs/config.md "augment"). Internal to train/.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/rng.h"
#include "data/dataset.h"
#include "geometry/types.h"
#include "train/detector_train.h"

namespace g2l::train {

// Calls f(pixel index) for every pixel of a w x h image inside the axis-aligned ellipse (disc)
// or rectangle of centre (cx, cy) and half-sizes (rw, rh), clipped to the image.
template <class F>
void for_each_shape_pixel(int w, int h, double cx, double cy, double rw, double rh, bool disc,
                          F&& f) {
    const int x0 = std::max(0, int(cx - rw)), x1 = std::min(w - 1, int(cx + rw));
    const int y0 = std::max(0, int(cy - rh)), y1 = std::min(h - 1, int(cy + rh));
    for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) {
            if (disc) {
                const double dx = (x - cx) / rw, dy = (y - cy) / rh;
                if (dx * dx + dy * dy > 1) continue;
            }
            f(size_t(y) * size_t(w) + size_t(x));
        }
}

/// Colour gain / brightness, grey, Gaussian noise, 3x3 box blur (the config's augment.*): in
/// place on a w x h x 3 image.
void augment(std::vector<uint8_t>& rgb, int w, int h, const DetectorTrainConfig& c, Rng& rng);

/// A "dead leaves" clutter texture (random rectangles and discs of random colours, sizes spread
/// over a log scale, painted back to front) replaces every pixel with keep == 0.
void clutter_background(std::vector<uint8_t>& rgb, const std::vector<uint8_t>& keep, int w,
                        int h, Rng& rng);

/// A random crop of a random photograph (35-100% of its width, the input's aspect ratio,
/// mirrored half the time), resampled bilinearly, replaces every pixel with keep == 0.
void photo_background(std::vector<uint8_t>& rgb, const std::vector<uint8_t>& keep, int w, int h,
                      const std::vector<data::Image>& photos, Rng& rng);

/// Every .png / .jpg file directly in each directory, as RGB (sorted: the training is
/// reproducible). Throws naming the directory when one is missing or holds no image.
std::vector<data::Image> load_photos(const std::vector<std::string>& dirs);

/// Vertex colours for a distractor mesh without any: a base colour (half the time a grey or
/// white, else a saturated one) with a linear gradient along a random axis and per-vertex noise.
void paint_distractor(geom::Mesh& m, Rng& rng);

}  // namespace g2l::train
