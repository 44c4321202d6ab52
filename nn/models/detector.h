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

/// What the detector sees (config key data.input, stored in the export).
///  - rgb:   the colour image, 3 channels, (rgb / 255 - 0.5) / 0.25.
///  - depth: kDepthChannels channels computed from the depth image and the intrinsics
///           (depth_features): what transfers from untextured renders to a real sensor.
///  - rgbd:  the 3 colour channels, then the depth channels.
enum class DetectorInput { rgb, depth, rgbd };
/// "rgb", "depth", "rgbd".
const char* to_string(DetectorInput input);
/// Parses "rgb" / "depth" / "rgbd"; throws naming `where` and the value otherwise.
DetectorInput parse_detector_input(const std::string& text, const std::string& where);
/// Input channels of each kind: 3, kDepthChannels, 3 + kDepthChannels.
int detector_input_channels(DetectorInput input);
inline bool uses_depth(DetectorInput input) { return input != DetectorInput::rgb; }
inline bool uses_rgb(DetectorInput input) { return input != DetectorInput::depth; }

/// The depth encoding, per pixel of the detector's input (channel order):
///   0 valid       1 where the depth is measured, else 0 (every other channel is 0 there too)
///   1 depth       (z - 1000 mm) / 500 mm, clamped to [-2, 4]: the metric scale of what is seen
///   2 relief      z minus the mean measured z in the surrounding window of 2 * kReliefRadius + 1
///                 pixels, / 30 mm, clamped to [-3, 3]: what stands out of its surroundings
///   3-5 normal    the surface normal in the camera frame (unit, towards the camera), from the
///                 depth smoothed over the measured pixels within kNormalSmooth, back-projected
///                 at the neighbours kNormalStep pixels away (central differences; one-sided
///                 where a neighbour is unmeasured; 0 where both are)
constexpr int kDepthChannels = 6;
constexpr int kReliefRadius = 12;
constexpr int kNormalStep = 2;
constexpr int kNormalSmooth = 2;

struct DetectorConfig {
    int num_classes = 8;   ///< K heat-maps
    int width = 16;        ///< c, the stem width (>= 4)
    uint64_t seed = 1;     ///< initialisation
    DetectorInput input = DetectorInput::rgb;  ///< what the stem sees
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
    /// x [B, C, H, W] (C = detector_input_channels(config().input)) with H, W > 0 multiples of
    /// 16; throws naming the shape otherwise.
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

/// One frame as the detector takes it: borrowed row-major buffers of width x height pixels and
/// the camera intrinsics (pixels). A depth detector needs depth_mm and the intrinsics, an RGB
/// detector rgb; an rgbd detector both.
struct DetectorFrame {
    int width = 0, height = 0;
    const uint8_t* rgb = nullptr;     ///< H x W x 3
    const float* depth_mm = nullptr;  ///< H x W, mm; 0, NaN or inf = not measured
    double fx = 0, fy = 0, cx = 0, cy = 0;
};

/// The depth encoding (kDepthChannels, see above) of a depth image of w x h pixels (mm) seen
/// through the given intrinsics, written channel-major into out[c * out_stride_plane +
/// y * out_row + x] (the caller's zero-padded input planes). Throws for a bad size or
/// intrinsics.
void depth_features(const float* depth_mm, int w, int h, double fx, double fy, double cx,
                    double cy, float* out, int64_t out_row, int64_t out_stride_plane);

/// The frame as the detector's input [1, C, H, W]: average-pooled by `downscale` (1, 2 or 4;
/// depth: the mean of the measured pixels of each block, the intrinsics scaled to match),
/// zero-padded on the right/bottom to multiples of 16, encoded as `input` says. Writes the
/// network input size to *in_w / *in_h. Throws for an empty frame, a bad downscale, or a
/// buffer or intrinsics the input needs and the frame lacks (naming it).
Tensor detector_input(const DetectorFrame& frame, DetectorInput input, int downscale, int* in_w,
                      int* in_h);
/// The RGB-only form: detector_input of a frame with just `rgb`, input rgb.
Tensor detector_input(const uint8_t* rgb, int width, int height, int downscale, int* in_w,
                      int* in_h);

/// Function-preserving widening (Net2Net, Chen et al. 2016): writes into `wide` (width a
/// whole multiple k of from's, the same classes and input) weights that compute the same
/// outputs as `from`'s, in training and in eval mode. Every channel j of a widened layer
/// becomes k copies (j, j + n, ...), BatchNorm statistics and biases copied; the weights that
/// read a widened layer are split among the copies with random shares that sum to one per
/// element (drawn from `seed`, within 1/k +- spread/k), so the copies learn apart from the
/// first step. Throws naming the widths for any other pair.
void widen_detector(const Detector& from, Detector& wide, uint64_t seed, double spread = 0.5);

/// A trained detector and what it needs at inference: the classes' object ids and the input
/// downscale (its input kind is net->config().input). Read from a detector export (g2l_train
/// writes <run_dir>/detector.g2l).
struct LoadedDetector {
    std::unique_ptr<Detector> net;
    std::vector<int> object_ids;
    int downscale = 2;
    DetectorInput input() const { return net->config().input; }
};
LoadedDetector load_detector(const std::string& path);
/// True when the file is a g2l checkpoint whose metadata says it is a detector export (false
/// for any other checkpoint, e.g. a pose model). Throws naming the file when it cannot be read.
bool is_detector_export(const std::string& path);
/// Writes the export (weights + {format "g2l-detector", num_classes, width, object_ids,
/// downscale, input}) atomically. An export without "input" (written before it existed) is an
/// RGB detector.
void save_detector(const std::string& path, const Detector& net,
                   const std::vector<int>& object_ids, int downscale);

/// Runs the detector on one frame, fed as its input kind asks (net.config().input):
/// detections in the frame's own pixels, best score first (ties in a stable order). With
/// `mirror` the network also sees the frame mirrored left-right (depth and principal point
/// too) and the class-probability maps of both passes are averaged (test-time augmentation:
/// two network passes; box sizes and offsets are the plain pass's).
std::vector<Detection> detect(Detector& net, int downscale, const DetectorFrame& frame,
                              float min_score = 0.05f, int max_per_class = 5,
                              bool mirror = false);
/// The RGB-only form, for an RGB detector.
std::vector<Detection> detect(Detector& net, int downscale, const uint8_t* rgb, int width,
                                  int height, float min_score = 0.05f, int max_per_class = 5,
                                  bool mirror = false);

}  // namespace g2l::nn
