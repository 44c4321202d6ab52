// SPDX-License-Identifier: MIT
// Records every dataset reader yields (BOP, Linemod_preprocessed) and the Dataset container
// with its image and mesh loaders. OpenCV stays private to data/*.cpp: images come back as plain
// byte/uint16 buffers. Units: millimetres; poses map model points into the camera frame
// (x_cam = R * x_model + t).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace g2l::data {

/// One annotated object instance of a frame.
struct Instance {
    int obj_id = 0;               ///< dataset object id (key of Dataset::models())
    geom::Pose pose;              ///< model -> camera, t in mm
    geom::Box2i bbox_obj;         ///< full-object 2D box; empty (w = h = 0) when not annotated
    geom::Box2i bbox_visib;       ///< visible-part 2D box; empty when not annotated
    double visib_fract = -1;      ///< visible fraction in [0, 1]; -1 when not annotated
    std::string mask_visib_path;  ///< visible-part mask (non-zero = object); "" if none
    int index_in_frame = 0;       ///< position in the frame's annotation list (BOP's k)
    /// The box to detect / crop: the visible part's, else the full object's (both may be empty).
    const geom::Box2i& box() const { return bbox_visib.empty() ? bbox_obj : bbox_visib; }
    /// At least min_visib visible, or the visible fraction is not annotated (-1).
    bool visible_enough(double min_visib) const { return visib_fract < 0 || visib_fract >= min_visib; }
};

/// One RGB(-D) image with its camera and ground truth.
struct Frame {
    std::string scene;         ///< scene / sequence name ("000000", or "01" for Linemod)
    int image_id = 0;          ///< image id inside the scene
    std::string rgb_path;      ///< "" when the dataset has no colour image for this frame
    std::string depth_path;    ///< "" when absent (LM-O ships no depth)
    geom::Intrinsics K;        ///< fx, fy, cx, cy; width/height of the images
    double depth_scale = 1.0;  ///< depth PNG value * depth_scale = mm
    std::vector<Instance> instances;
};

/// One object model of the dataset.
struct ObjectModel {
    int obj_id = 0;
    std::string name;       ///< e.g. "009_gelatin_box" (obj_names.json), "ape", "obj_000008"
    std::string mesh_path;  ///< PLY file of the model (mm)
    geom::ModelInfo info;   ///< diameter, extent, symmetric flag
};

/// A decoded 8-bit image, row-major, interleaved channels: data[(v * w + u) * channels + c].
/// RGB images have channels == 3 in R, G, B order; masks have channels == 1.
struct Image {
    int w = 0, h = 0, channels = 0;
    std::vector<uint8_t> data;
    /// Value of channel c at pixel (u, v); no bounds check.
    uint8_t at(int u, int v, int c = 0) const {
        return data[(static_cast<size_t>(v) * w + u) * channels + c];
    }
};

/// Reads a 16-bit single-channel PNG (depth or label image) into *w x *h row-major values.
/// Throws g2l::Error naming the file when it is missing, cannot be decoded, or is not 16-bit
/// single-channel (the message gives the depth/channel count found).
std::vector<uint16_t> load_depth_png(const std::string& path, int* w, int* h);

/// Reads a colour image (PNG/JPEG/TIFF) as 8-bit RGB (channels == 3). Grey images are expanded
/// to three channels. Throws g2l::Error naming the file when missing or undecodable.
Image load_rgb_image(const std::string& path);

/// Reads a mask as an 8-bit single-channel image (colour masks are converted to grey; any
/// non-zero value is "object"). Throws g2l::Error naming the file when missing or undecodable.
Image load_mask_image(const std::string& path);

/// Writes an 8-bit image with 1, 3 (RGB order) or 4 (RGBA) channels as PNG. Throws g2l::Error
/// naming the file on a bad shape or a write failure.
void save_png(const std::string& path, const Image& image);

/// Writes w x h 16-bit values (row-major) as a single-channel 16-bit PNG. Throws g2l::Error
/// naming the file on a bad shape or a write failure.
void save_depth_png(const std::string& path, const uint16_t* depth, int w, int h);

/// Width and height of an image file without decoding the pixels when it is a PNG (reads the
/// IHDR chunk); other formats are decoded. Throws g2l::Error naming the file.
void image_size(const std::string& path, int* w, int* h);

/// A loaded dataset: frames (sorted by scene, then image id), object models, and loaders.
/// Copies share the mesh cache. load_model_mesh is safe to call from several threads.
class Dataset {
public:
    Dataset() = default;
    /// name: dataset name ("ycbv", "lmo", ...); root: its folder (for messages).
    Dataset(std::string name, std::string root, std::vector<Frame> frames,
            std::map<int, ObjectModel> models);
    virtual ~Dataset() = default;

    const std::string& name() const { return name_; }
    const std::string& root() const { return root_; }
    const std::vector<Frame>& frames() const { return frames_; }
    const std::map<int, ObjectModel>& models() const { return models_; }

    /// The model with this id; throws g2l::Error listing the known ids when absent.
    const ObjectModel& model(int obj_id) const;

    /// The model's mesh (geometry/mesh_io.h load_mesh), loaded on first use and cached. The
    /// reference stays valid as long as any copy of this Dataset lives. Throws g2l::Error for an
    /// unknown id or an unreadable mesh file.
    const geom::Mesh& load_model_mesh(int obj_id) const;

    /// Raw 16-bit depth of the frame (value * frame.depth_scale = mm), *w x *h row-major.
    /// Throws g2l::Error when the frame has no depth, the file is missing/unreadable/not 16-bit,
    /// or its size differs from frame.K.width x height.
    std::vector<uint16_t> load_depth(const Frame& frame, int* w, int* h) const;

    /// Depth in mm as float (0 = no measurement), *w x *h. Same errors as load_depth.
    std::vector<float> load_depth_mm(const Frame& frame, int* w, int* h) const;

    /// RGB image of the frame (channels == 3). Throws g2l::Error when the frame has no colour
    /// image, the file cannot be read, or its size differs from frame.K.
    Image load_rgb(const Frame& frame) const;

    /// Visible mask of an instance of `frame` (channels == 1, non-zero = object). Throws
    /// g2l::Error when the instance has no mask or the file is unreadable / of the wrong size.
    Image load_mask(const Frame& frame, const Instance& instance) const;

protected:
    std::string name_, root_;
    std::vector<Frame> frames_;
    std::map<int, ObjectModel> models_;

private:
    struct MeshCache;
    std::shared_ptr<MeshCache> cache_;
};

/// The published symmetric-object conventions, for a dataset whose models_info.json does not
/// declare its symmetries (the YCB-Video convention of PoseCNN and the paper's tables): "ycbv" ->
/// {13, 16, 19, 20, 21}, "lm" / "lmo" / "linemod" -> {10, 11}, case-insensitive. Asked for by
/// name (g2l_eval --symmetric ycbv), never taken from a folder's name. Throws g2l::Error naming
/// the known conventions for any other name.
std::vector<int> symmetric_convention(const std::string& convention);

/// Conventional object names of a known dataset (LINEMOD: 1 "ape" ... 15 "phone"); "" when
/// unknown. Used when the dataset ships no obj_names.json.
std::string default_object_name(const std::string& dataset_name, int obj_id);

}  // namespace g2l::data
