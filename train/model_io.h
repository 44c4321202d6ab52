// SPDX-License-Identifier: MIT
// Training checkpoints (.g2l, see docs/checkpoint.md): the model's state dict ("model.*"), the
// optimizer state ("adam.*") and JSON metadata that makes the file self-describing (network
// hyper-parameters, object ids, keypoints, crop settings, the effective config, resume state).
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "nn/models/g2l_io.h"
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
                              const ResumeState& state,
                              const std::map<int, nn::ModelObjectInfo>& objects = {});

/// Restores model + optimizer from a checkpoint written by save_training_checkpoint and
/// returns the resume state. Throws g2l::Error naming the file when it is not a training
/// checkpoint or does not match the network (listing the mismatched tensors).
ResumeState load_training_checkpoint(const std::string& path, nn::G2LNet& net, nn::Adam& adam);

/// Model loading lives in nn/models/g2l_io.h (infer/ reads the same files).
using nn::LoadedModel;
using nn::load_model;

/// Writes an inference export of a training checkpoint (atomically): the model's tensors,
/// network hyper-parameters, object ids, keypoints, object diameters (stored in the checkpoint,
/// or read from the models_info.json of its config's data sources for older checkpoints), crop and point-sampling settings, the
/// training config and where it came from (epoch, step, seconds) — no optimizer state, so it is
/// about a third of the checkpoint. Returns the number of bytes written. Throws g2l::Error naming
/// the file for anything load_model would refuse.
int64_t export_model(const std::string& checkpoint_path, const std::string& out_path);

/// An inference export whose weights and BatchNorm statistics are the element-wise mean of
/// several checkpoints of one run (checkpoint averaging: it smooths the epoch-to-epoch swing of
/// the last weights); the metadata is the last checkpoint's, plus the list of sources under
/// "trained.averaged". Integer tensors are taken from the last checkpoint. Throws g2l::Error
/// naming the file for fewer than two checkpoints, one load_model would refuse, or one whose
/// network, classes, keypoints, sampling or tensors differ from the first's.
int64_t export_average(const std::vector<std::string>& checkpoints, const std::string& out_path);

}  // namespace g2l::train
