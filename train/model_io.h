// SPDX-License-Identifier: MIT
// Training checkpoints (.g2l, see docs/checkpoint.md): the model's state dict ("model.*"), the
// optimizer state ("adam.*") and JSON metadata that makes the file self-describing (network
// hyper-parameters, object ids, keypoints, crop settings, the effective config, resume state).
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "nn/models/g2l_net.h"
#include "nn/optim.h"
#include "train/config.h"
#include "train/pipeline.h"

namespace g2l::train {

/// Where a run stands: enough to continue it bit for bit.
struct ResumeState {
    int epoch = 0;              ///< current epoch (0-based)
    int64_t pos = 0;            ///< position in the epoch's visiting order
    int64_t global_step = 0;    ///< optimizer steps done
    int64_t epoch_batches = 0;  ///< batches done in the current epoch
    double epoch_loss = 0;      ///< sum of their losses
    double best_val = -1;       ///< best validation ADD-S AUC so far
    double seconds = 0;         ///< wall-clock seconds of training so far (all sessions)
};

/// The network hyper-parameters of a config (K = number of keypoints per object).
nn::G2LConfig model_config(const TrainConfig& cfg, int num_keypoints);

/// Writes the checkpoint atomically (core/checkpoint.h).
void save_training_checkpoint(const std::string& path, const nn::G2LNet& net,
                              const nn::Adam& adam, const TrainConfig& cfg,
                              const std::map<int, int>& class_of, const KeypointTable& keypoints,
                              const ResumeState& state);

/// Restores model + optimizer from a checkpoint written by save_training_checkpoint and
/// returns the resume state. Throws g2l::Error naming the file when it is not a training
/// checkpoint or does not match the network (listing the mismatched tensors).
ResumeState load_training_checkpoint(const std::string& path, nn::G2LNet& net, nn::Adam& adam);

/// A trained model ready for inference, rebuilt from the checkpoint alone.
struct LoadedModel {
    std::unique_ptr<nn::G2LNet> net;
    std::map<int, int> class_of;   ///< obj_id -> class index
    KeypointTable keypoints;       ///< class index -> model keypoints (mm)
    std::string crop = "sphere";   ///< crop the network was trained with
    double radius_scale = 1.0;
    int points = 0;                ///< seg-net input points per crop (0 = the whole crop)
    int seg_points = 2000;         ///< object points fed to the T-net and the rotation blocks
    std::string config_json;       ///< the training config (effective)
};
/// Accepts training checkpoints ("g2l-train") and inference exports ("g2l-model").
LoadedModel load_model(const std::string& path);

/// Writes an inference export of a training checkpoint (atomically): the model's tensors,
/// network hyper-parameters, object ids, keypoints, crop and point-sampling settings, the
/// training config and where it came from (epoch, step, seconds) — no optimizer state, so it is
/// about a third of the checkpoint. Returns the number of bytes written. Throws g2l::Error naming
/// the file for anything load_model would refuse.
int64_t export_model(const std::string& checkpoint_path, const std::string& out_path);

/// Keeps only the lines of a JSONL log whose numeric `key` is <= max_value (after a resume the
/// log continues from the checkpoint). A missing file is fine.
void truncate_jsonl(const std::string& path, const std::string& key, int64_t max_value);

}  // namespace g2l::train
