// SPDX-License-Identifier: MIT
// The 2D detector of G2L-Net's global localization (spec §1-§2), CenterNet-style: a small
// fully-convolutional network that maps an RGB image to one heat-map per object class (the
// class-probability map whose peak is lifted to the sphere centre) plus a box size and a
// sub-cell offset at every output cell, at stride 4 of its input.
//
//   x [B, 3, H, W] (H, W multiples of 16; normalised: (rgb / 255 - 0.5) / 0.25)
//   stem  conv3x3 s2                    -> c    @ H/2
//   d4    conv3x3 s2, conv3x3           -> 2c   @ H/4   (f4)
//   d8    conv3x3 s2, conv3x3           -> 4c   @ H/8   (f8)
//   d16   conv3x3 s2, conv3x3           -> 4c   @ H/16
//   up8   up2(d16) + 1x1(f8), conv3x3   -> 2c   @ H/8
//   up4   up2(up8) + 1x1(f4), conv3x3   -> 2c   @ H/4
//   head  conv3x3 -> 2c, then 1x1 to heat [K] (logits), size [2], offset [2]
// Every conv3x3 is followed by BatchNorm and ReLU. State dict names: "stem.conv.weight",
// "d4a.bn.running_mean", "heat.weight", ...
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "nn/module.h"
#include "nn/modules/layers.h"

namespace g2l::nn {

struct DetectorConfig {
    int num_classes = 8;   ///< K heat-maps
    int width = 16;        ///< c, the stem width (>= 4)
    uint64_t seed = 1;     ///< initialisation
};

/// Throws g2l::Error naming the field for num_classes outside [1, 4096] or width outside
/// [4, 256].
void validate(const DetectorConfig& cfg);

/// Network outputs at stride 4 of the input: [B, K, H/4, W/4], [B, 2, ...], [B, 2, ...].
struct DetOut {
    Tensor heat;    ///< logits; sigmoid(heat) is the class-probability map
    Tensor size;    ///< log(box width / 4), log(box height / 4) in input pixels
    Tensor offset;  ///< box centre / 4 minus the cell index, x then y (in [0, 1) for the peak)
};

/// conv3x3 (stride s, padding 1) + BatchNorm + ReLU.
class ConvBnRelu : public Module {
public:
    ConvBnRelu(int64_t in, int64_t out, int64_t stride, Rng& rng);
    Tensor forward(const Tensor& x);
    std::shared_ptr<Conv2d> conv;
    std::shared_ptr<BatchNorm> bn;
};

class Detector : public Module {
public:
    explicit Detector(const DetectorConfig& cfg);
    /// x [B, 3, H, W] with H, W > 0 multiples of 16; throws naming the shape otherwise.
    DetOut forward(const Tensor& x);
    const DetectorConfig& config() const { return cfg_; }
    static constexpr int kStride = 4;  ///< output cell size in input pixels

private:
    DetectorConfig cfg_;
    std::shared_ptr<ConvBnRelu> stem_, d4a_, d4b_, d8a_, d8b_, d16a_, d16b_, up8_, up4_, head_;
    std::shared_ptr<Conv2d> lat8_, lat4_, heat_, size_, offset_;
};

/// One detected object: a peak of class `cls`'s heat-map and the box decoded there, in the
/// pixels of the detector's input image.
struct Detection {
    int cls = 0;           ///< class index (heat-map channel)
    float score = 0;       ///< sigmoid of the heat at the peak
    float peak_x = 0, peak_y = 0;  ///< peak cell centre refined by the offset (input pixels)
    float x = 0, y = 0, w = 0, h = 0;  ///< box: top-left corner and size (input pixels)
};

/// Decodes the outputs of one image (host float buffers, channel-major as DetOut for batch
/// index 0): a cell is a peak of its class when its probability is >= min_score and no larger
/// than none of its 8 neighbours' (ties: the first cell in row-major order wins, so a plateau
/// gives one peak). Returns at most max_per_class peaks per class, best first overall.
/// prob: [K, h, w] probabilities, size / offset: [2, h, w] (w columns, h rows). Throws for
/// non-positive sizes.
std::vector<Detection> decode_detections(const float* prob, const float* size,
                                         const float* offset, int K, int w, int h,
                                         float min_score, int max_per_class, int stride = 4);

/// The RGB image (H x W x 3, uint8) as the detector's input: average-pooled by `downscale`
/// (1, 2 or 4), zero-padded on the right/bottom to multiples of 16, normalised. Writes the
/// network input size to *in_w / *in_h. Throws for an empty image or a bad downscale.
Tensor detector_input(const uint8_t* rgb, int width, int height, int downscale, int* in_w,
                      int* in_h);

/// A trained detector and what it needs at inference: the classes' object ids and the input
/// downscale. Read from a detector export (g2l_train writes <run_dir>/detector.g2l).
struct LoadedDetector {
    std::unique_ptr<Detector> net;
    std::vector<int> object_ids;
    int downscale = 2;
};
LoadedDetector load_detector(const std::string& path);
/// True when the file is a g2l checkpoint whose metadata says it is a detector export (false
/// for any other checkpoint, e.g. a pose model). Throws naming the file when it cannot be read.
bool is_detector_export(const std::string& path);
/// Writes the export (weights + {format "g2l-detector", num_classes, width, object_ids,
/// downscale}) atomically.
void save_detector(const std::string& path, const Detector& net,
                   const std::vector<int>& object_ids, int downscale);

/// Runs the detector on one RGB image (H x W x 3): detections in the image's own pixels,
/// best score first (ties in a stable order). With `mirror` the network also sees the image
/// mirrored left-right and the class-probability maps of both passes are averaged (test-time
/// augmentation: two network passes; box sizes and offsets are the plain pass's).
std::vector<Detection> detect(Detector& net, int downscale, const uint8_t* rgb, int width,
                                  int height, float min_score = 0.05f, int max_per_class = 5,
                                  bool mirror = false);

}  // namespace g2l::nn
