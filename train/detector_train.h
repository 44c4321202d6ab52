// SPDX-License-Identifier: MIT
// Training the 2D detector (nn/models/detector.h) of G2L-Net's global
// localization: RGB renders of coloured meshes (data/scene.h) with colour, noise, blur and
// grey-scale augmentation, CenterNet targets (a Gaussian peak per object centre, log box size and
// sub-cell offset at the centre cell), the penalty-reduced focal loss, Adam; the run directory,
// checkpoints and --resume of the pose trainer. A detector config is a JSON file with
// "task": "detector" (docs/config.md, configs/lmo_detector.json).
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "core/tensor.h"
#include "data/dataset.h"
#include "data/detections.h"
#include "data/scene.h"
#include "nn/models/detector.h"
#include "eval/detector_eval.h"
#include "train/trainer.h"

namespace g2l::train {

struct DetectorTrainConfig {
    std::string name = "detector";
    uint64_t seed = 1;
    int threads = 0;
    std::string device = "cpu";
    std::string run_dir;
    // data
    std::string models_root;        ///< BOP root whose models/ (with vertex colours) are rendered
    std::vector<int> object_ids;    ///< classes, in heat-map order
    int downscale = 2;              ///< the detector sees the image at 1/downscale
    /// What the detector sees (nn::DetectorInput): "rgb" (colour renders: the meshes need
    /// vertex colours), "depth" (the depth encoding of the renders with the scene's sensor
    /// noise: untextured meshes are fine), "rgbd" (both; coloured meshes).
    nn::DetectorInput input = nn::DetectorInput::rgb;
    double min_visib_fract = 0.1;   ///< less visible instances get no target
    data::SceneConfig scene;        ///< at full resolution (the camera of the real images)
    /// Other scenes mixed in (data.mix): each training image comes from mix[i].scene with
    /// probability mix[i].prob, else from `scene` (probabilities summing to at most 1; the
    /// same camera as `scene`). A stage that learns new scenes while it keeps the old ones.
    struct SceneMix {
        double prob = 0;
        data::SceneConfig scene;
    };
    std::vector<SceneMix> mix;
    /// Unannotated distractor objects (scene.distractors_min/max per frame): the models of this
    /// BOP root ("" = none), each in `distractor_colors` random colourings (meshes without
    /// colours get them; coloured meshes keep theirs and give one variant).
    std::string distractors_root;
    std::vector<int> distractor_ids;  ///< empty = every model of distractors_root
    int distractor_colors = 2;
    // augmentation (training only)
    double color_jitter = 0.3;      ///< per-channel gain and brightness, +- this fraction
    double noise_std = 6.0;         ///< Gaussian pixel noise (0..255 units), std up to this
    double blur_prob = 0.3;         ///< probability of a 3x3 box blur
    double gray_prob = 0.05;        ///< probability of a grey-scale image
    /// Probability that every pixel without an annotated object is replaced by a random
    /// "dead leaves" clutter texture (rectangles and discs of random colours and sizes).
    double clutter_prob = 0.8;
    /// Per object, the probability of a random-coloured disc or rectangle (20-60% of its box)
    /// pasted over it; the target box is that of the pixels left visible. In the depth it is a
    /// flat plate 30-150 mm in front of the object's nearest point.
    double occluder_prob = 0.0;
    /// Directories of real photographs (any scene without the target objects, e.g. YCB-Video
    /// frames for LINEMOD objects); with probability photo_prob a random crop of one (random
    /// scale, flip) replaces every pixel without an object, instead of the clutter texture.
    std::vector<std::string> backgrounds;
    double photo_prob = 0.0;
    /// Per rendered object (each target; the distractors as one group), the probability of a
    /// random tone: contrast towards its mean colour (x 0.4-1), brightness (x 0.5-1.2), a tint
    /// (x 0.85-1.15 per channel) and saturation (x 0.5-1.3). The LINEMOD vertex colours were
    /// captured under other light than the test photos (bright objects are ~0.55-0.75 as bright
    /// there, dark ones unchanged); the image-wide colour_jitter cannot say "this object only".
    double object_tone_prob = 0.0;
    // model
    int width = 16;
    std::string init;               ///< a detector export to start from (fine-tuning); "" = fresh
    // loss
    double w_heat = 1.0, w_size = 0.1, w_offset = 1.0;
    /// The weight of the heat loss's negative part on cells whose centre pixel shows an
    /// unannotated block (data.scene blocks_*): 1 = background like the table; 0 = not taught
    /// either way (a block looks like some objects: a wood block is a plain cuboid).
    double w_block_negatives = 1.0;
    // optimisation
    double lr = 2e-3;
    int64_t steps = 4000;
    int batch = 8;
    int checkpoint_every = 250;
    int log_every = 25;
    double time_limit_min = 0;      ///< 0 = none; stop with a checkpoint after this much time
    /// With time_limit_min: the step decay at 70 % / 90 % follows the share of the time limit
    /// spent when it is ahead of the share of the steps (train/config.h LoopConfig).
    bool time_schedule = false;
    // validation on real images (optional: val_root empty = none)
    std::string val_root, val_split = "test";
    int val_every = 0;              ///< steps between validations (0 = only at the end)
    int val_max_frames = 0;         ///< 0 = every frame
};

/// True when the JSON file at `path` has "task": "detector". Throws naming the file when it
/// cannot be read or is not JSON.
bool is_detector_config(const std::string& path);

/// Reads a detector config (strict: unknown keys, wrong types and bad values throw naming the
/// key), applies `--set key=value` overrides, resolves ${G2L_SHARED} paths.
DetectorTrainConfig load_detector_config(const std::string& path,
                                         const std::vector<std::string>& sets = {});
DetectorTrainConfig parse_detector_config(const std::string& json_text, const std::string& source,
                                          const std::string& base_dir);
/// Every key, defaults included; parse_detector_config of it gives the same config.
std::string detector_config_to_json(const DetectorTrainConfig& cfg);

/// The object_tone augmentation on an image (w x h x 3): `groups` holds a group per pixel (0 =
/// background, left alone); each group, with probability `prob`, gets its own random tone (see
/// DetectorTrainConfig::object_tone_prob). Throws on sizes that do not match.
void object_tone(std::vector<uint8_t>& rgb, const std::vector<uint16_t>& groups, int w, int h,
                 double prob, Rng& rng);

/// Writes to `out_path` a detector export whose weights and BatchNorm statistics are the
/// element-wise mean of two or more detector exports of the same objects, width and downscale
/// (a "model soup" of fine-tuning runs from one start). Returns the bytes written; throws
/// naming the file that is not a detector export or does not match the first.
int64_t export_detector_average(const std::vector<std::string>& exports, const std::string& out_path);

/// A box of class `cls` in the detector's input pixels (top-left corner and size).
struct DetBox {
    int cls = 0;
    float x = 0, y = 0, w = 0, h = 0;
};

/// CenterNet targets of one image for an output grid of w x h cells (stride `stride`):
/// heat [K, h, w] (1 at each centre cell, a Gaussian of sigma 0.1 sqrt(box cells) (>= 0.7)
/// around it, max over objects), size [2, h, w] (log(box w / stride), log(box h / stride)),
/// offset [2, h, w] (centre / stride - cell), mask [h, w] (1 at the centre cells). Boxes whose
/// centre falls outside the grid or whose size is not positive are skipped. neg_weight [h, w]
/// (empty: 1 everywhere) scales the heat loss's negative part per cell, for every class.
struct DetTargets {
    std::vector<float> heat, size, offset, mask, neg_weight;
};
DetTargets make_detector_targets(const std::vector<DetBox>& boxes, int K, int w, int h,
                                 int stride = nn::Detector::kStride);
/// DetTargets::neg_weight of an image whose blocks show where `blocks` (W x H, 255) is: `weight`
/// on the (W / stride) x (H / stride) cells whose centre pixel shows a block, 1 elsewhere.
std::vector<float> block_cell_weights(const std::vector<uint8_t>& blocks, int W, int H,
                                      int stride, float weight);

/// The loss of a batch: heat logits against stacked targets (focal loss, normalised by the
/// number of centres), L1 on size and offset at the centre cells. Returns the total and writes
/// the three parts (unweighted) when the pointers are given. `centres` >= 0: normalise by this
/// number of centres instead of the batch's own (data-parallel training: the global batch's,
/// so the processes' losses add up to the one-process loss); < 0: count this batch's.
Tensor detector_loss(const nn::DetOut& out, const std::vector<DetTargets>& targets,
                     double w_heat, double w_size, double w_offset, double* heat_loss = nullptr,
                     double* size_loss = nullptr, double* offset_loss = nullptr,
                     double centres = -1);
/// The number of centres (heat cells equal to 1) of `targets`, as detector_loss counts them.
double detector_centres(const std::vector<DetTargets>& targets);

struct DetectorTrainSummary {
    std::string run_dir;
    int64_t steps = 0;
    bool interrupted = false, stopped_early = false;
    double images_per_s = 0;
    double final_loss = 0;
    bool evaluated = false;
    eval::DetectorEvalResult val;
};
/// Trains with the options of the pose trainer (resume_dir, max_steps, progress, force,
/// stop_flag: train/trainer.h).
DetectorTrainSummary run_detector_training(const DetectorTrainConfig& cfg, const TrainOptions& opt);

}  // namespace g2l::train
