// SPDX-License-Identifier: MIT
// Random synthetic scenes: target objects (and distractors) at random poses in front of an
// optional tilted support plane, random light and background, rendered with data/render.h and
// degraded with data/sensor_noise.h. A frame depends only on (config.seed, frame index), so
// frames can be generated in any order or in parallel with identical results.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "data/render.h"
#include "data/sensor_noise.h"
#include "core/rng.h"
#include "geometry/stable_poses.h"
#include "geometry/types.h"

namespace g2l::data {

/// Everything that defines a synthetic scene distribution. Lengths in mm, angles in degrees.
/// JSON keys are the field names (noise.* for SensorNoiseConfig, camera.* for the intrinsics).
struct SceneConfig {
    /// Camera (default: YCB-Video Asus Xtion, 640 x 480).
    geom::Intrinsics camera{1066.778, 1067.487, 312.9869, 241.3109, 640, 480};
    double depth_scale = 0.1;              ///< mm per depth PNG unit
    std::vector<int> target_obj_ids;       ///< annotated objects; empty = every model given
    int targets_min = 1, targets_max = 3;  ///< annotated instances per frame
    bool unique_targets = true;            ///< each target id at most once per frame
    /// Bin scenes: when kinds_max > 0, each frame first draws between kinds_min and kinds_max
    /// distinct target objects (without replacement), and its targets are copies of those
    /// (unique_targets must be false): several identical parts per frame, as in a bin. 0 = off
    /// (the draws of older configs are unchanged).
    int kinds_min = 0, kinds_max = 0;
    std::vector<int> distractor_obj_ids;   ///< empty = every given model that is not a target
    int distractors_min = 0, distractors_max = 2;  ///< unannotated clutter objects per frame
    double z_min = 500, z_max = 1500;      ///< object centre depth range (mm)
    /// Object centres project uniformly into the central xy_frac part of the image (0..1].
    double xy_frac = 0.8;
    /// Full uniform random rotation; when false, R = Rz(c) Ry(b) Rx(a) with (a, b, c) uniform
    /// in [euler_min, euler_max] (degrees).
    bool full_rotation = true;
    std::array<double, 3> euler_min{{-180, -180, -180}};
    std::array<double, 3> euler_max{{180, 180, 180}};
    /// Centres are re-drawn (up to 100 times) while two bounding spheres overlap by more than
    /// (1 - separation) of the sum of their radii; 0 = allow any interpenetration.
    double separation = 0.9;
    double support_plane_prob = 0.8;      ///< probability of a plane behind/under the objects
    double plane_tilt_max = 60;           ///< plane normal tilt from the optical axis (degrees)
    bool random_background = true;        ///< random colour gradient + noise where no surface
    bool random_light = true;             ///< random light direction / ambient / diffuse
    std::array<uint8_t, 3> object_color{{170, 170, 170}};  ///< for meshes without colours
    SensorNoiseConfig noise;
    uint64_t seed = 0;

    /// "random": the poses above (centres in the view frustum, random or Euler rotations,
    /// optional tilted plane). "resting": the real-world prior (spec §14) — every object lies
    /// in one of its stable poses (geometry/stable_poses.h, drawn with their probabilities) with
    /// a random yaw on a table, and the camera sits on the upper hemisphere around them:
    /// distance camera_distance, elevation camera_elevation above the table, any azimuth, roll
    /// within +-camera_roll_max; the table (a table_size_mm square, always rendered, with sensor
    /// noise) fills the view around the objects. z_min/z_max, xy_frac, full_rotation, euler_*,
    /// support_plane_prob and plane_tilt_max do not apply in this mode.
    std::string pose_mode = "random";
    std::array<double, 2> camera_distance{{500, 1200}};  ///< camera to look-at point (mm)
    std::array<double, 2> camera_elevation{{15, 80}};    ///< degrees above the table plane
    double camera_roll_max = 10;     ///< in-plane roll, degrees
    double table_spread_mm = 200;    ///< objects' centres within this radius on the table
    double look_at_jitter_mm = 50;   ///< look-at point: objects' mean + N(0, this) per axis
    double table_size_mm = 3000;     ///< side of the square table
    /// "resting" mode: per target, the probability that it stands as it was modelled — the
    /// stable pose whose down direction is nearest the model's -z (when one lies within 30
    /// degrees of it) — instead of a stable pose drawn with its drop probability. Scanned
    /// models (LINEMOD, YCB-Video) sit in their frame as they stood on the table, and people
    /// stand a bottle up where a drop would lay it down: the LINEMOD glue stands on its base in
    /// 3.5% of random drops and in every LM-O photograph. Distractors keep the drop prior.
    double upright_prob = 0;
    /// "resting" mode: per target, the probability that it stands in its tallest stable pose
    /// (greatest centre-of-mass height, drop probability ignored): a marker on its cap, a box on
    /// its smallest face — poses people choose and random drops almost never give. Applied after
    /// upright_prob (it wins when both fire). 0 draws nothing, so older configs give the same frames.
    double tall_prob = 0;
    /// "resting" mode: unannotated cuboid blocks on the table (edge lengths uniform in
    /// block_size_mm, random yaw and grey level), drawn before the objects: the wooden block of
    /// YCB-Video, boxes, books. They are unannotated distractors (in RenderedFrame::distractor_mask)
    /// and, as block_lookalike_tol says, marked in RenderedFrame::block_mask.
    int blocks_min = 0, blocks_max = 0;
    std::array<double, 2> block_size_mm{{40, 200}};
    /// Which blocks RenderedFrame::block_mask marks: 0 (default) every block; > 0 only the
    /// lookalikes — blocks whose sorted edge lengths each lie within this share of the sorted
    /// bounding-box extents of some target (a depth image cannot tell a 10 x 10 x 21 cm block
    /// from the YCB-Video wood block). The other blocks are plain distractors (instance id -1,
    /// in distractor_mask only). The frames are the same either way. In [0, 1].
    double block_lookalike_tol = 0;
    /// Per object, the probability that it rests on top of a block (when the frame has one)
    /// instead of on the table.
    double on_block_prob = 0;
    /// Per object after the first, the probability that it rests on top of an object placed
    /// before it (a target or a distractor): on the highest vertex of that object under its
    /// footprint — a box on the wooden block, a can on a box.
    double on_object_prob = 0;
    /// Per object, the probability that it leans: its resting rotation tilted about a random
    /// horizontal axis by up to lean_max_deg, then lowered until its lowest vertex touches its
    /// support — an object propped against another, as real tables show.
    double lean_prob = 0;
    double lean_max_deg = 30;
};

/// Throws g2l::Error naming the field and value for any invalid setting (`where` prefixes the
/// message, e.g. the file name): inverted z range, z_min <= 0, targets_min > targets_max,
/// negative counts, xy_frac outside (0, 1], a bad camera, a probability outside [0, 1], ...
void validate(const SceneConfig& cfg, const std::string& where = "SceneConfig");

/// Parses a JSON object into a SceneConfig (defaults for absent keys). Unknown keys and wrong
/// types throw g2l::Error naming `source` and the key path; the result is validated.
/// `key_path` is where the object sits in a larger file ("data.train[1].scene"): errors then
/// read "<source>: 'data.train[1].scene.z_min' must be a number, got \"near\"".
SceneConfig parse_scene_config(const std::string& json_text, const std::string& source,
                               const std::string& key_path = "");

/// Reads and parses a JSON scene config file. Throws g2l::Error naming the file.
SceneConfig load_scene_config(const std::string& path);

/// The config as pretty-printed JSON (parse_scene_config(scene_config_to_json(c)) == c).
std::string scene_config_to_json(const SceneConfig& cfg);

/// A mesh the scene may place, borrowed (must outlive the generator).
struct SceneModel {
    int obj_id = 0;
    const geom::Mesh* mesh = nullptr;
    /// The object's symmetries as BOP declares them: a JSON object holding its input
    /// models_info.json's "symmetries_discrete" / "symmetries_continuous" entries (read_symmetries),
    /// copied into the models_info.json written beside the renders; "" = none declared.
    std::string symmetries;
    SceneModel() = default;
    SceneModel(int id, const geom::Mesh* m, std::string sym = "")
        : obj_id(id), mesh(m), symmetries(std::move(sym)) {}
};

/// Ground truth of one annotated instance, with BOP scene_gt / scene_gt_info semantics.
struct RenderedInstance {
    int obj_id = 0;
    geom::Pose pose;               ///< model -> camera (mm)
    geom::Box2i bbox_obj;          ///< box of the full silhouette (object rendered alone)
    geom::Box2i bbox_visib;        ///< box of the visible pixels; empty if none
    int64_t px_count_all = 0;      ///< pixels of the full silhouette
    int64_t px_count_valid = 0;    ///< silhouette pixels with depth > 0 in the final depth
    int64_t px_count_visib = 0;    ///< visible pixels (instance image == k + 1)
    double visib_fract = 0;        ///< px_count_visib / px_count_all (0 when all is 0)
};

/// One rendered frame; buffers are H x W row-major and reused across render_frame calls.
struct RenderedFrame {
    geom::Intrinsics K;
    double depth_scale = 0.1;
    std::vector<float> depth;       ///< mm, sensor noise applied (if enabled); 0 = no depth
    std::vector<uint8_t> rgb;       ///< H x W x 3
    std::vector<uint16_t> mask;     ///< k + 1 where instance k is visible, 0 elsewhere
    std::vector<uint8_t> distractor_mask;  ///< 255 where a distractor or a block is visible
    std::vector<uint8_t> block_mask;  ///< 255 where a block (SceneConfig blocks_*) is visible
    std::vector<std::vector<uint8_t>> full_masks;  ///< per instance: 255 on the full silhouette
    std::vector<RenderedInstance> instances;
};

/// Samples and renders scenes. Holds a Renderer and scratch buffers: one generator per thread.
class SceneGenerator {
public:
    /// Throws g2l::Error for an invalid config, an empty model list, a null or faceless mesh
    /// (naming obj_id), a duplicated obj_id, or a target/distractor id that is not among the
    /// models (listing the known ids).
    SceneGenerator(const SceneConfig& cfg, std::vector<SceneModel> models);

    const SceneConfig& config() const { return cfg_; }

    /// Renders frame `index` into `out`; the result depends only on (config().seed, index).
    /// threads: OpenMP threads for the rasterizer (0 = default); never changes the result.
    void render_frame(int64_t index, RenderedFrame& out, int threads = 0);

private:
    struct ModelGeom {
        int obj_id;
        const geom::Mesh* mesh;
        Eigen::Vector3d center;  ///< bounding-box centre, model frame
        double radius;           ///< max distance of a vertex from center
        Eigen::Vector3d com;     ///< centre of mass (resting mode)
        std::vector<geom::StablePose> stable;  ///< stable poses (resting mode)
        int upright = -1;  ///< the stable pose nearest "model -z down" (within 30 deg), or -1
        geom::StablePose tall;  ///< the stable pose with the highest centre of mass (tall_prob > 0)
        Eigen::Vector3d extent_sorted = Eigen::Vector3d::Zero();  ///< bounding box, ascending
    };
    /// Whether a block of edge lengths `size` looks like a target (block_lookalike_tol).
    bool block_is_lookalike(const Eigen::Vector3d& size) const;
    /// Places objects_ (and the table) for a "resting" frame; returns each object's centre
    /// and radius in camera coordinates.
    std::vector<std::pair<Eigen::Vector3d, double>> place_resting(
        const std::vector<int>& chosen, int n_targets, Rng& rng);
    // The stages of render_frame, in its order of random draws (a frame depends only on the
    // seed and its index): the objects (targets first), their random poses, the support plane,
    // the background, each target's ground truth.
    std::vector<int> choose_objects(Rng& rng, int* n_targets) const;
    std::vector<std::pair<Eigen::Vector3d, double>> place_random(const std::vector<int>& chosen,
                                                                 int n_targets, Rng& rng);
    void add_support_plane(const std::vector<std::pair<Eigen::Vector3d, double>>& placed, Rng& rng);
    void paint_background(RenderedFrame& out, Rng& rng) const;
    void instance_truth(RenderedFrame& out, const std::vector<int>& chosen, int n_targets,
                        const RenderOptions& opt);
    const ModelGeom& model(int obj_id) const;

    SceneConfig cfg_;
    std::vector<ModelGeom> models_;
    std::vector<int> targets_, distractors_;
    Renderer renderer_;
    RenderOutput full_, solo_;
    geom::Mesh plane_;
    geom::Points plane_unit_;  ///< plane vertices for a unit-size quad
    std::vector<geom::Mesh> blocks_;  ///< this frame's blocks (objects_ points into it)
    std::vector<RenderObject> objects_;
    std::vector<float> noise_scratch_;
};

}  // namespace g2l::data
