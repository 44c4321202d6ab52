// SPDX-License-Identifier: MIT
// Reading trained G2L-Net models: training checkpoints ("g2l-train", train/model_io.h writes
// them) and inference exports ("g2l-model", `g2l_train --export`). Here, below train/ and
// infer/, because both read them (docs/checkpoint.md has the metadata keys).
#pragma once

#include <Eigen/Core>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "geometry/crop.h"
#include "nn/models/g2l_net.h"

namespace g2l::nn {

/// The network hyper-parameters as stored in a checkpoint's "model" metadata.
nlohmann::json g2l_config_json(const G2LConfig& c);
/// The inverse of g2l_config_json, read strictly (core/json_reader.h): a missing, unknown or
/// mistyped key throws g2l::Error naming `source` and the key. Keys added after the first
/// checkpoints default to the behaviour those files were trained with.
G2LConfig g2l_config_from_json(const nlohmann::json& j,
                               const std::string& source = "model metadata");

/// j[k] of a model file's metadata; throws g2l::Error naming the file when it is missing.
const nlohmann::json& metadata_key(const nlohmann::json& j, const char* k, const std::string& path);

/// What the pose pipeline needs to know of one object beyond its keypoints.
struct ModelObjectInfo {
    double diameter = 0;     ///< mm (the sphere crop's radius is radius_scale x this)
    bool symmetric = false;  ///< BOP symmetry annotation (ADD-S instead of ADD)
};

/// A trained model ready for inference, rebuilt from the file alone.
struct LoadedModel {
    std::unique_ptr<G2LNet> net;    ///< in eval mode
    std::map<int, int> class_of;    ///< obj_id -> class index
    std::vector<std::vector<Eigen::Vector3f>> keypoints;  ///< class index -> model keypoints (mm)
    std::map<int, ModelObjectInfo> objects;  ///< obj_id -> diameter etc. (empty in files
                                             ///< written before 2026-12-02)
    geom::CropKind crop = geom::CropKind::sphere;  ///< crop the network was trained with
    double radius_scale = 1.0;
    int points = 0;                 ///< seg-net input points per crop (0 = the whole crop)
    int seg_points = 2000;          ///< object points fed to the T-net and the rotation blocks
    std::string format;             ///< "g2l-train" or "g2l-model"
    std::string config_json;        ///< the training config (effective)
};

/// Accepts training checkpoints ("g2l-train") and inference exports ("g2l-model"). Throws
/// g2l::Error naming the file for a missing/corrupt/truncated file, another format, malformed
/// metadata or tensors that do not fit the stored network config.
LoadedModel load_model(const std::string& path);

}  // namespace g2l::nn
