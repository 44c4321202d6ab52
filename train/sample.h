// SPDX-License-Identifier: MIT
// Training samples for G2L-Net (spec §1.3, §5, §6): crop a depth frame around one annotated
// instance, sample a fixed number of points, label them with the GT-posed model (8 mm rule) and
// augment. Unlike the official script (spec §6, [OBS]: rotation nets fed un-augmented points with
// augmented targets), the points, labels and GT pose of a PoseSample all live in ONE augmented
// frame. Units: millimetres, degrees in the config.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/rng.h"
#include "data/dataset.h"
#include "geometry/crop.h"
#include "geometry/labels.h"
#include "geometry/types.h"

namespace g2l::train {

/// How a training sample is cut out of a frame. Lengths in mm, angles in degrees.
struct SampleConfig {
    /// "sphere": |p - centre| < radius_scale * diameter (the paper);
    /// "frustum": every valid depth point of the (jittered) 2D box (Frustum-PointNets baseline);
    /// "slab": |z - centre_z| < radius_scale * diameter (the released code's chooselimt).
    geom::CropKind crop = geom::CropKind::sphere;
    int points = 1500;              ///< points per sample (N)
    double radius_scale = 1.0;      ///< crop radius / half-depth in units of the model diameter
    double center_jitter_mm = 10;   ///< std-dev of the Gaussian added to the crop centre, per axis
    double box_jitter_frac = 0.05;  ///< each box edge moves by U(-f, f) x the box width/height
    double label_threshold_mm = 8;  ///< a point is object when within this of the posed model
    int min_points = 50;            ///< fewer cropped points -> the sample is unusable
    std::array<double, 3> shift_mm{{5, 5, 25}};  ///< augmentation shift s_i ~ U[-shift_i, shift_i)
    double rot_deg = 10;            ///< augmentation Euler angles ~ U(-rot_deg, rot_deg)
    double point_noise_mm = 0;      ///< std-dev of Gaussian noise added to each coordinate
    bool augment = true;            ///< false: Rm = I, shift = 0, no point noise
};

/// Throws g2l::Error prefixed by `where` and naming the field and value for: an unknown crop
/// name, points <= 0, min_points <= 0, non-finite or non-positive radius_scale or
/// label_threshold_mm, negative or non-finite center_jitter_mm / point_noise_mm / shift_mm,
/// box_jitter_frac outside [0, 0.5], rot_deg outside [0, 180].
void validate(const SampleConfig& cfg, const std::string& where = "SampleConfig");

/// A depth image in millimetres (0, negative or non-finite = no measurement), borrowed.
struct DepthView {
    const float* depth_mm = nullptr;  ///< [height, width] row-major
    int width = 0, height = 0;
    geom::Intrinsics K;
};

/// One segmentation/pose training sample. Every vector quantity is in the augmented frame
/// p' = Rm (p - mean) + shift (+ noise), where p is the camera-frame point (mm).
struct PoseSample {
    int obj_id = 0;
    int class_index = 0;             ///< index of obj_id in the SampleMaker's class map
    std::vector<float> points;       ///< N x 3 row-major: the seg-net input, augmented
    std::vector<int32_t> labels;     ///< N: 1 = within label_threshold_mm of the GT-posed model
    Eigen::Matrix3f R = Eigen::Matrix3f::Identity();  ///< GT rotation, augmented: Rm R_gt
    Eigen::Vector3f t = Eigen::Vector3f::Zero();  ///< GT translation: Rm (t_gt - mean) + shift
    Eigen::Vector3f mean = Eigen::Vector3f::Zero();   ///< mean of the N camera points (mm)
    Eigen::Matrix3f Rm = Eigen::Matrix3f::Identity();  ///< augmentation rotation Rz Ry Rx
    Eigen::Vector3f shift = Eigen::Vector3f::Zero();  ///< augmentation shift (mm)
    int num_object_points = 0;       ///< number of labels equal to 1
    Eigen::Vector3f centre = Eigen::Vector3f::Zero();  ///< crop centre, camera frame (mm)
    geom::Box2i box;                 ///< jittered, image-clipped 2D box the points come from
    int num_candidates = 0;          ///< points left by the crop, before sampling to N
};

/// A model the SampleMaker can label against: the mesh (borrowed, must outlive the maker; only
/// read while constructing) and its models_info entry (the diameter sets the crop size).
struct SampleModel {
    const geom::Mesh* mesh = nullptr;
    geom::ModelInfo info;
};

/// Turns (depth frame, GT instance) pairs into PoseSamples. Builds one KD-tree per class object
/// at construction; make() is const and safe to call from several threads at once (each with
/// its own Rng and output).
class SampleMaker {
public:
    /// cfg: validated (throws as validate()). models: obj_id -> model. class_index: obj_id ->
    /// class index (>= 0) for every object samples are made of; each needs an entry in models
    /// with a non-null mesh that has vertices and a diameter > 0. surface_spacing_mm: the KD-tree
    /// holds the vertices plus geom::sample_surface(mesh, surface_spacing_mm).
    /// Throws g2l::Error naming the obj_id for any of these violations, or an empty class map.
    SampleMaker(SampleConfig cfg, const std::map<int, SampleModel>& models,
                std::map<int, int> class_index, double surface_spacing_mm = 2.0);

    /// Makes one sample of instance `inst` (its obj_id, pose and bbox_visib, or bbox_obj when
    /// bbox_visib is empty) seen in `view`. Steps: jitter the box, back-project its valid depth,
    /// centre = a random object-labelled box point + N(0, center_jitter_mm), crop, sample
    /// cfg.points points (without replacement when enough are available, else every point once
    /// plus random repeats), label, augment. Returns false (out unspecified) when the jittered box
    /// is empty, the box holds no object point, fewer than min_points points survive the crop,
    /// or fewer than 10 of the sampled points are object. Deterministic for a given rng state.
    /// Throws g2l::Error for a null out / depth pointer, a bad view (as geom::depth_to_points),
    /// an obj_id outside the class map, a non-finite pose, or an instance without any box.
    bool make(const DepthView& view, const data::Instance& inst, Rng& rng, PoseSample* out) const;

    const SampleConfig& config() const { return cfg_; }
    const std::map<int, int>& class_map() const { return class_index_; }
    /// True when obj_id has a class index.
    bool has_class(int obj_id) const { return class_index_.count(obj_id) != 0; }
    /// Class index of obj_id; throws g2l::Error listing the known ids when absent.
    int class_of(int obj_id) const;
    /// The labelling KD-tree of obj_id (model frame, mm); throws like class_of.
    const geom::ModelKdTree& tree(int obj_id) const;
    /// The model info of obj_id; throws like class_of.
    const geom::ModelInfo& info(int obj_id) const;

private:
    struct Object {
        geom::ModelInfo info;
        geom::ModelKdTree tree;
        Eigen::Vector3f lo, hi;  ///< bounding box of the tree points (model frame, mm)
    };
    const Object& object(int obj_id) const;

    SampleConfig cfg_;
    std::map<int, int> class_index_;
    std::map<int, Object> objects_;
};

}  // namespace g2l::train
