// SPDX-License-Identifier: MIT
// g2l_train's JSON configuration (docs/config.md lists every key): plain structs with the
// paper's defaults (spec §4-§6), a strict loader (unknown keys, wrong types and bad values throw
// g2l::Error naming the file and the key path), `--set a.b.c=value` overrides, and the effective
// config as JSON, which loads back to the same config.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "data/scene.h"
#include "geometry/crop.h"
#include "train/source_types.h"

namespace g2l::train {

/// One source of training or validation samples: a BOP dataset split ("bop"), synthetic
/// renders of a BOP dataset's models ("synthetic") or a Linemod_preprocessed folder
/// ("linemod_preprocessed"); the kinds and their readers: train/source_types.h. Only the
/// fields of `type` are read/written.
struct SourceConfig {
    SourceType type = SourceType::bop;
    std::vector<int> objects;           ///< object ids used; empty = every id of data.object_ids
    // --- annotated frames: bop, linemod_preprocessed ---
    std::string root;                   ///< BOP dataset root (resolved, see resolve_config_path)
    std::string split = "train_real";   ///< split folder under root
    std::vector<std::string> scenes;    ///< scene folders ("000000"); empty = all
    bool models_eval = false;           ///< read <root>/models_eval instead of <root>/models
    double min_visib_fract = 0.1;       ///< instances less visible than this are skipped
    int64_t max_frames = 0;             ///< > 0: that many frames evenly spaced; 0 = all
    // --- type "synthetic" ---
    std::string models_root;            ///< BOP root whose models/ + models_info.json are used
    int64_t frames = 2000;              ///< frames rendered per epoch
    /// data/scene.h SceneConfig as JSON object text, kept verbatim; parsed by validate().
    std::string scene = "{}";
};

/// What the network is trained on.
struct DataConfig {
    /// Class index of each object = its position here; one-hot width = model.num_classes.
    std::vector<int> object_ids{1};
    std::vector<SourceConfig> train;  ///< at least one source
    std::vector<SourceConfig> val;    ///< may be empty (no validation)
};

/// How a sample is cut out of a depth frame (spec §6 and train/sample.h). Lengths in mm.
struct SamplingConfig {
    geom::CropKind crop = geom::CropKind::sphere;  ///< "sphere" | "frustum" | "slab" in JSON
    int points = 1500;                ///< points per crop (seg-net input)
    int seg_points = 1000;            ///< points resampled from the segmented object
    double radius_scale = 1.0;        ///< sphere radius (slab half-depth) = scale x diameter
    double center_jitter_mm = 10;     ///< std-dev of the crop-centre jitter per axis
    double box_jitter_frac = 0.05;    ///< 2D box edge jitter, fraction of the box size
    double label_threshold_mm = 8;    ///< a point is object when this close to the posed model
    double surface_spacing_mm = 2.0;  ///< spacing of model surface samples for labelling
    int min_points = 50;              ///< fewer cropped points -> the sample is skipped
    double min_visib_fract = 0.1;     ///< instances less visible than this give no sample
};

/// Per-sample augmentation of the seg-net input (spec §6 data_augment).
struct AugmentConfig {
    bool enabled = true;                         ///< false: no shift, rotation or noise
    std::array<double, 3> shift_mm{{5, 5, 25}};  ///< shift s_i ~ U[-shift_i, shift_i) (mm)
    double rot_deg = 10;                         ///< Euler angles ~ U(-rot_deg, rot_deg)
    double point_noise_mm = 0;                   ///< Gaussian noise std-dev per coordinate
};

/// G2L-Net options (spec §4).
struct ModelConfig {
    int num_classes = 16;            ///< one-hot width (>= data.object_ids size)
    std::string keypoints = "bbx8";  ///< "bbx8" | "fps4" | "fps8" | "fps12"
    bool evf = true;                 ///< block A (embedding-vector features)
    bool rre = true;                 ///< block C (rotation residual estimator)
    double width = 1.0;              ///< channel multiplier (> 0)
    double dropout = 0.2;            ///< dropout before the last layer of each head
    double out_scale_mm = 1.0;       ///< unit of the mm-valued outputs (nn::G2LConfig)
    std::string rot_unit = "kp_rms"; ///< rotation branch unit: "kp_rms" or "mm" (official)
    bool class_heads = false;        ///< one output block per class in blocks A/B/C
    /// Fine-tuning: start from this model file's weights (an export or a checkpoint of the same
    /// network and objects), with a fresh optimiser and schedule. "" = random initialisation.
    /// Relative paths are relative to the config file.
    std::string init;
};

/// Loss weights (spec §6: 10 L_seg + L_T/10 + 10 L_vec + L_kp/100 + L_res/100).
struct LossConfig {
    double seg = 10, t = 0.1, vec = 10, kp = 0.01, res = 0.01;
    std::string t_loss = "mse";  ///< "mse" | "smooth_l1"
    /// Rotation targets: the geometric symmetry of the model nearest the prediction (min over
    /// symmetries, geometry/symmetry.h) instead of the single GT pose. Off = paper.
    bool symmetric_targets = false;
    /// Centre of the rotation input in training: "gt" (GT translation + rot_centre_noise_mm
    /// Gaussian noise per axis) or "pred" (the T-net's prediction, as at test time).
    std::string rot_centre = "gt";
    double rot_centre_noise_mm = 0;
    /// For this many first epochs the rotation blocks see the ground-truth object points
    /// instead of the seg net's (they learn on clean input while segmentation is poor).
    int rot_gt_points_epochs = 0;
    /// For this many first epochs only the rotation blocks train (no seg / T-net pass; GT object
    /// points centred on the GT translation + rot_centre_noise_mm): a fast warm-up, ~4x the
    /// samples per second of the joint step.
    int rot_only_epochs = 0;
};

/// Per-sub-network learning-rate multipliers (official code: seg 1, tnet 10, evf 1, rot 30,
/// rre 20; the paper's setting is all 1).
struct LrMultConfig {
    double seg = 1, tnet = 10, evf = 1, rot = 30, rre = 20;
};

/// Adam.
struct OptimConfig {
    double lr = 1e-3;
    double beta1 = 0.9, beta2 = 0.99, eps = 1e-8;
    double weight_decay = 0;
    LrMultConfig lr_mult;
};

/// Learning-rate schedule: "step" (paper: x gamma every step_epochs), "official" (lr / 4 every
/// epochs / 4 epochs; step_epochs and gamma unused), "constant".
struct ScheduleConfig {
    std::string kind = "step";
    int step_epochs = 50;
    double gamma = 0.5;
};

/// The training loop (JSON section "train").
struct LoopConfig {
    int epochs = 200;
    int batch = 8;
    int64_t samples_per_epoch = 0;  ///< 0 = the total size of the training sources
    int checkpoint_every = 10;      ///< epochs between epoch_<k> checkpoints; 0 = none
    int val_every = 1;              ///< epochs between validations; 0 = never
    int64_t max_val_samples = 200;  ///< 0 = every validation sample
    double time_limit_min = 0;      ///< > 0: stop with a checkpoint after this many minutes
    /// With time_limit_min: the learning-rate schedule follows the share of the time limit spent
    /// when it is ahead of the share of the epochs done, so a run the time limit ends early has
    /// decayed as one that ran to the end (the epochs a step is in then depend on the machine's
    /// speed: not bitwise reproducible across machines).
    bool time_schedule = false;
    int log_every = 10;             ///< steps between log lines
    /// Make the next batch (render, crop, label) on a second thread while this one trains.
    /// Never changes a result: a batch depends only on its position in the epoch's order.
    bool prefetch = true;
};

/// Everything g2l_train reads from its config file.
struct TrainConfig {
    std::string name;           ///< run name; "" -> the config file's stem at load
    uint64_t seed = 1;
    int threads = 0;            ///< CPU threads, 0 = all
    std::string device = "cpu"; ///< "cpu" | "cuda" | "cuda:N" (core/dtype.h parse_device)
    std::string run_dir;        ///< "" -> "runs/<name>" at load; relative to the current dir
    DataConfig data;
    SamplingConfig sampling;
    AugmentConfig augment;
    ModelConfig model;
    LossConfig loss;
    OptimConfig optim;
    ScheduleConfig schedule;
    LoopConfig train;
};

/// Reads, parses, overrides and validates a config file. `sets` are "a.b.c=value" overrides
/// applied in order before validation (value parsed as JSON, else taken as a string; list
/// elements by index: "data.train.0.frames=10"; inside a synthetic source's "scene" new keys may
/// be added, they are checked by the scene parser). Relative dataset paths resolve against the
/// file's directory (see resolve_config_path). Throws g2l::Error naming the file and the key
/// path for a missing file, malformed JSON (the parser's line/column), an unknown key, a wrong
/// type, a bad enum value (listing the allowed ones), a bad --set and any invalid value.
TrainConfig load_config(const std::string& path, const std::vector<std::string>& sets = {});

/// load_config on text: `source_name` prefixes errors and gives the default name (its stem);
/// relative paths resolve against `base_dir` ("" = the current directory).
TrainConfig parse_config_text(const std::string& json_text, const std::string& source_name,
                              const std::vector<std::string>& sets = {},
                              const std::string& base_dir = "");

/// The effective config as pretty JSON (every key, defaults included); parse_config_text of it
/// gives the same config.
std::string config_to_json(const TrainConfig& cfg);

/// The objects a source serves: its own `objects`, else the run's `data.object_ids`.
inline const std::vector<int>& source_objects(const TrainConfig& cfg, const SourceConfig& s) {
    return s.objects.empty() ? cfg.data.object_ids : s.objects;
}

/// Throws g2l::Error prefixed by `where` and naming the key path and value for any invalid
/// setting (bad device, points < seg_points, lr <= 0, an object of a source that is not in
/// data.object_ids, an invalid scene, ...). Does not check that dataset paths exist.
void validate(const TrainConfig& cfg, const std::string& where = "TrainConfig");

/// The SceneConfig of a synthetic source (parse_scene_config of src.scene; errors prefixed by
/// `where`, e.g. "x.json: data.train[1].scene").
data::SceneConfig source_scene(const SourceConfig& src, const std::string& where,
                               const std::string& key_path = "");

/// Resolves a dataset path written in a config: "${G2L_SHARED}" as a prefix expands to
/// shared_data_root(base_dir); an absolute path is kept; a relative path that exists relative
/// to the current directory is taken from there; any other relative path is joined to base_dir
/// ("" = current directory). The result is absolute and lexically normal. Throws g2l::Error
/// for an empty path or another "${...}" variable.
std::string resolve_config_path(const std::string& value, const std::string& base_dir);

/// Applies `--set key.path=value` overrides (the rules of load_config: the path must exist,
/// except inside a data...scene object) to a JSON config text; returns the new text. Throws
/// g2l::Error naming source_name and the override.
std::string apply_sets_to_json(const std::string& json_text, const std::vector<std::string>& sets,
                               const std::string& source_name);

/// $G2L_SHARED_DATA when set and non-empty; else the first existing <A>/shared/data for A an
/// ancestor of base_dir (for a config in <repo>/configs: <repo>/../shared/data), then of the
/// current directory; else base_dir/../../shared/data. Absolute.
std::string shared_data_root(const std::string& base_dir);

}  // namespace g2l::train
