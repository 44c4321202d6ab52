// SPDX-License-Identifier: MIT
// Reader for the classic "Linemod_preprocessed" layout (DenseFusion / G2L-Net release):
//   <root>/data/NN/{rgb,depth,mask}/NNNN.png, data/NN/gt.yml, data/NN/info.yml,
//   data/NN/train.txt, data/NN/test.txt, <root>/models/obj_NN.ply, models/models_info.yml
// where NN is the object id on two digits and NNNN the image index on four.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "data/dataset.h"

namespace g2l::data {

/// What open_linemod_preprocessed reads.
struct LinemodOptions {
    /// Object folders to read (data/NN); empty = every all-digit folder under <root>/data.
    std::vector<int> objects;
    /// "train" or "test" (the image indices listed in data/NN/<split>.txt) or "all" (every
    /// image of gt.yml).
    std::string split = "test";
    /// Keep only the instance of the folder's own object (the masks of data/NN/mask show only
    /// that object). When false, the other annotated objects (folder 02 lists all of LM-O's) are
    /// kept too, with mask_visib_path "".
    bool only_folder_object = true;
    /// Objects evaluated with ADD-S; nullopt = LINEMOD's {10 eggbox, 11 glue}.
    std::optional<std::vector<int>> symmetric_ids;
};

/// A Linemod_preprocessed dataset: Dataset plus the split read.
class LinemodDataset : public Dataset {
public:
    LinemodDataset() = default;
    LinemodDataset(Dataset base, std::string split)
        : Dataset(std::move(base)), split_(std::move(split)) {}
    const std::string& split() const { return split_; }

private:
    std::string split_;
};

/// Opens a Linemod_preprocessed folder. Frames: scene = "NN", image_id = the image index, rgb /
/// depth / mask paths data/NN/{rgb,depth,mask}/NNNN.png (depth_path "" if data/NN/depth is
/// absent), K and depth_scale from info.yml (cam_K, depth_scale), instances from gt.yml
/// (cam_R_m2c row-major, cam_t_m2c mm, obj_bb -> bbox_obj, obj_id). Models: every object of the
/// kept instances, mesh models/obj_NN.ply, info from models/models_info.yml, name "ape" ...
/// Throws g2l::Error naming the file and line (or key) for a missing folder or file, a YAML
/// construct outside the supported subset, a missing key or wrong list length, a non-rotation
/// cam_R_m2c, a split-list index missing from gt.yml or info.yml, an image file listed but absent,
/// an object without a model, an unknown split name, or a folder without its own object in gt.yml.
LinemodDataset open_linemod_preprocessed(const std::string& root,
                                         const LinemodOptions& options = {});

}  // namespace g2l::data
