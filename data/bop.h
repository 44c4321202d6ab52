// SPDX-License-Identifier: MIT
// Reader for datasets in the BOP format (https://bop.felk.cvut.cz): YCB-Video, LINEMOD,
// LINEMOD-Occluded, the renderer's output, ... See docs/datasets.md for the layout.
#pragma once

#include <array>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <vector>

#include "data/dataset.h"

namespace g2l::data {

/// What open_bop reads. Every field has a working default.
struct BopOptions {
    /// Scene folder names under <root>/<split> (e.g. "000000"); empty = every all-digit folder.
    std::vector<std::string> scenes;
    /// Keep only these object ids (models and instances); empty = all objects of models_info.
    /// With a filter, frames left without any instance are dropped.
    std::vector<int> obj_ids;
    /// Objects evaluated with ADD-S. nullopt = those whose models_info.json entry declares
    /// symmetries_discrete / symmetries_continuous (whatever the folder is called); when set
    /// (also to {}), exactly these ids (data::symmetric_convention gives the published lists).
    std::optional<std::vector<int>> symmetric_ids;
    /// Dataset name; "" = the root folder's name (e.g. "ycbv", "lmo").
    std::string dataset_name;
    /// Read <root>/models_eval (BOP's resampled evaluation models) instead of <root>/models.
    bool models_eval = false;
};

/// A BOP dataset split: Dataset plus the split and the scenes read.
class BopDataset : public Dataset {
public:
    BopDataset() = default;
    BopDataset(Dataset base, std::string split, std::vector<std::string> scenes)
        : Dataset(std::move(base)), split_(std::move(split)), scenes_(std::move(scenes)) {}
    const std::string& split() const { return split_; }
    /// Scene folder names read, in order.
    const std::vector<std::string>& scenes() const { return scenes_; }

private:
    std::string split_;
    std::vector<std::string> scenes_;
};

/// Opens <root>/<split> of a BOP dataset.
/// Reads <root>/models (or models_eval)/models_info.json and obj_%06d.ply paths,
/// <root>/obj_names.json (optional: names), <root>/camera.json (optional: image size), and per
/// scene scene_gt.json, scene_camera.json (cam_K, depth_scale per image), scene_gt_info.json
/// (optional: bbox_obj, bbox_visib, visib_fract), rgb/%06d.{png,jpg,jpeg,tif,tiff},
/// depth/%06d.png and mask_visib/%06d_%06d.png. Frames are those of scene_gt.json, sorted by
/// scene then image id. A missing rgb/, depth/ or mask_visib/ folder gives "" paths; a folder that
/// exists but lacks a frame's file is an error.
/// Throws g2l::Error naming the file and the key path (e.g. `scene_gt.json: key "3"[1].cam_t_m2c`)
/// for: missing root/split/scene/models folders or files, malformed JSON, missing keys, wrong
/// array lengths or types, a non-rotation cam_R_m2c, an image id of scene_gt.json missing from
/// scene_camera.json, scene_gt_info.json lists of another length than scene_gt.json's, an
/// instance whose object has no model, a requested scene or object that does not exist.
BopDataset open_bop(const std::string& root, const std::string& split,
                    const BopOptions& options = {});

/// Only the object models of a BOP root (<root>/models or models_eval + models_info.json,
/// obj_names.json): a Dataset without frames, for training from renders of the meshes. Same
/// option semantics and model errors as open_bop (scenes are ignored).
Dataset open_bop_models(const std::string& root, const BopOptions& options = {});

/// A camera: intrinsics (pixels), depth scale (mm per unit of the depth PNG) and, when the file
/// gives it, the image size (0 when not).
struct CameraFile {
    double fx = 0, fy = 0, cx = 0, cy = 0;
    double depth_scale = 0;
    int width = 0, height = 0;
    std::array<double, 9> cam_K() const { return {fx, 0, cx, 0, fy, cy, 0, 0, 1}; }
};

/// The one camera reader: a BOP camera.json ({fx, fy, cx, cy, depth_scale, width, height}), one
/// scene_camera.json entry ({cam_K, depth_scale, ...}), or a whole scene_camera.json (then
/// image_id picks the entry; -1 = none given). depth_scale is required (a guess would put the
/// object 10 times too far or too near); focal lengths and depth_scale must be > 0, cam_K
/// without skew. Errors name the file and the key ("camera 'c.json': '11.cam_K' must be an
/// array of 9 numbers, got [1,2]").
CameraFile load_camera_file(const std::string& path, int image_id = -1);
/// The same from text; `source` names it in errors.
CameraFile parse_camera_file(const std::string& text, const std::string& source,
                             int image_id = -1);
/// One entry already parsed (scene_camera.json's per-image objects); `path` is its key.
CameraFile parse_camera_entry(const nlohmann::json& entry, const std::string& source,
                              const std::string& path);

}  // namespace g2l::data
