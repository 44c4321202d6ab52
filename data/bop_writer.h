// SPDX-License-Identifier: MIT
// Writes rendered frames as a BOP scene folder (https://bop.felk.cvut.cz format):
//   <scene_dir>/rgb/%06d.png, depth/%06d.png (uint16 = round(z / depth_scale)),
//   mask/%06d_%06d.png (full silhouettes), mask_visib/%06d_%06d.png (visible parts),
//   scene_gt.json, scene_camera.json, scene_gt_info.json
// and model folders (models/obj_%06d.ply + models_info.json). Every file is written to a
// temporary name and renamed into place, so a crash never leaves a truncated file.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "data/scene.h"
#include "geometry/types.h"

namespace g2l::data {

/// The file a scene folder holds while it is being written (an interrupted render keeps it).
constexpr const char* kIncompleteMarker = "render_incomplete.json";

/// Accumulates the JSON records of one BOP scene while its images are written.
class BopSceneWriter {
public:
    /// Creates scene_dir and its rgb/, depth/, mask/, mask_visib/ sub-folders, and the marker
    /// kIncompleteMarker that says the scene is being written (open_bop refuses a scene that
    /// holds it, naming how many frames its JSON lists); finish() removes it. `planned`: the
    /// frames the writer will write (for the marker; 0 = unknown). Throws g2l::Error naming
    /// the folder when it cannot be created.
    explicit BopSceneWriter(std::string scene_dir, int64_t planned = 0);

    /// Writes the images of `frame` under image id `image_id` (>= 0) and records its
    /// scene_gt / scene_camera / scene_gt_info entries. Depth values beyond the uint16 range
    /// (z / depth_scale > 65535) are written as 0 (no measurement). Throws g2l::Error for a
    /// negative or repeated image id, buffers whose size differs from frame.K, or a write error.
    void write(int image_id, const RenderedFrame& frame);

    /// Writes scene_gt.json, scene_camera.json and scene_gt_info.json for every frame written so
    /// far (may be called repeatedly; each call rewrites them) and the marker's count. Throws
    /// g2l::Error on write errors.
    void flush() const;
    /// flush(), then removes the marker: the scene is complete.
    void finish() const;

    /// Reopens the scene an interrupted writer left in scene_dir (it holds kIncompleteMarker):
    /// its scene_gt / scene_camera / scene_gt_info records are read back, and the images of
    /// frames they do not list (written after the last flush) are deleted, so writing the
    /// frames from next_image_id() on and finish() give the scene an uninterrupted writer
    /// would have written. planned(): the marker's frame count. Throws g2l::Error naming the
    /// folder when it holds no marker (a complete scene, or none) or a record is unreadable.
    static BopSceneWriter resume(const std::string& scene_dir);
    /// One past the largest image id written or read back (0 for none).
    int next_image_id() const { return gt_.empty() ? 0 : gt_.rbegin()->first + 1; }
    int64_t planned() const { return planned_; }
    /// The bytes of the files image `image_id` was written as (its rgb, depth and masks).
    uint64_t image_bytes(int image_id) const;

    const std::string& dir() const { return dir_; }

private:
    BopSceneWriter() = default;
    std::string dir_;
    int64_t planned_ = 0;
    std::map<int, std::string> gt_, camera_, info_;  ///< image id -> serialised JSON value
};

/// The symmetries_discrete / symmetries_continuous entries of object `obj_id` in a BOP
/// models_info.json, as a JSON object's text ("" when the file or the entry is absent or
/// declares none). Throws g2l::Error naming the file for invalid JSON or a non-array entry.
std::string read_symmetries(const std::string& models_info_path, int obj_id);

/// The object id a BOP file name gives (obj_000005.ply, obj_12.obj -> 5, 12: "obj_" and digits
/// only before the extension), or -1 for any other name.
int bop_mesh_id(const std::string& file);

/// The object ids of mesh files handed in (g2l_render --models, g2l_train --objects): a file
/// named obj_NNNNNN.ply / .obj keeps NNNNNN (a BOP folder stays comparable with its dataset);
/// the others get the smallest ids no file claims, in the order given. Throws g2l::Error
/// naming both files when two claim one id.
std::vector<int> mesh_file_ids(const std::vector<std::string>& files);

/// Writes <root>/obj_names.json ({"<id>": "<name>"}, BOP's optional names file: g2l_eval's
/// tables and g2l_infer --vis show them). Throws g2l::Error on a write error.
void write_obj_names(const std::string& root, const std::map<int, std::string>& names);

/// Writes each mesh as <models_dir>/obj_%06d.ply (geometry/mesh_io.h save_ply) and
/// models_info.json (diameter, min_*, size_* from compute_model_info, and the model's declared
/// symmetries, SceneModel::symmetries; none declared: none written, BOP readers treat absent
/// symmetries as none). Throws g2l::Error for a null mesh or a write error.
void write_bop_models(const std::string& models_dir, const std::vector<SceneModel>& models);

}  // namespace g2l::data
