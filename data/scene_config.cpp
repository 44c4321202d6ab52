// SPDX-License-Identifier: MIT
// SceneConfig <-> JSON (strict: unknown keys and wrong types are errors naming the key path).
#include <algorithm>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/error.h"
#include "data/scene.h"
#include "core/json.h"
#include "core/json_reader.h"

namespace g2l::data {
namespace {

using json = nlohmann::json;
/// Two numbers [min, max] and an [r, g, b] colour: the scene's only composite values.
void read_range(JsonReader& r, const char* k, std::array<double, 2>& v) { r.nums<2>(k, v); }
void read_rgb(JsonReader& r, const char* k, std::array<uint8_t, 3>& v) {
    std::vector<int> c;
    const bool had = r.has(k);
    r.ints(k, c);
    if (!had) return;
    G2L_CHECK(c.size() == 3 && std::all_of(c.begin(), c.end(),
                                           [](int x) { return x >= 0 && x <= 255; }),
              r.source(), ": '", r.at(k), "' must be [r, g, b] with integers in [0, 255]");
    for (int i = 0; i < 3; ++i) v[i] = static_cast<uint8_t>(c[i]);
}

}  // namespace

SceneConfig parse_scene_config(const std::string& json_text, const std::string& source,
                               const std::string& key_path) {
    const json j = parse_json_strict(json_text, source);
    SceneConfig c;
    SensorNoiseConfig& n = c.noise;
    geom::Intrinsics& K = c.camera;
    JsonReader r(j, source, key_path);
    r.object("camera", [&](JsonReader& rc) {
        rc.num("fx", K.fx);
        rc.num("fy", K.fy);
        rc.num("cx", K.cx);
        rc.num("cy", K.cy);
        rc.integer("width", K.width);
        rc.integer("height", K.height);
    });
    r.object("noise", [&](JsonReader& rn) {
        rn.boolean("enabled", n.enabled);
        rn.num("sigma_a_mm", n.sigma_a_mm);
        rn.num("sigma_b_mm_per_m2", n.sigma_b_mm_per_m2);
        rn.num("quant_step_mm", n.quant_step_mm);
        rn.num("grazing_cos_min", n.grazing_cos_min);
        rn.num("edge_jump_mm", n.edge_jump_mm);
        rn.integer("edge_width_px", n.edge_width_px);
        rn.num("edge_dropout_prob", n.edge_dropout_prob);
        rn.integer("holes_min", n.holes_min);
        rn.integer("holes_max", n.holes_max);
        rn.num("hole_radius_min_px", n.hole_radius_min_px);
        rn.num("hole_radius_max_px", n.hole_radius_max_px);
        rn.num("lateral_sigma_px", n.lateral_sigma_px);
    });
    r.num("depth_scale", c.depth_scale);
    r.ints("target_obj_ids", c.target_obj_ids);
    r.integer("targets_min", c.targets_min);
    r.integer("targets_max", c.targets_max);
    r.boolean("unique_targets", c.unique_targets);
    r.integer("kinds_min", c.kinds_min);
    r.integer("kinds_max", c.kinds_max);
    r.ints("distractor_obj_ids", c.distractor_obj_ids);
    r.integer("distractors_min", c.distractors_min);
    r.integer("distractors_max", c.distractors_max);
    r.num("z_min", c.z_min);
    r.num("z_max", c.z_max);
    r.num("xy_frac", c.xy_frac);
    r.boolean("full_rotation", c.full_rotation);
    r.num3("euler_min", c.euler_min);
    r.num3("euler_max", c.euler_max);
    r.num("separation", c.separation);
    r.num("support_plane_prob", c.support_plane_prob);
    r.num("plane_tilt_max", c.plane_tilt_max);
    r.boolean("random_background", c.random_background);
    r.boolean("random_light", c.random_light);
    read_rgb(r, "object_color", c.object_color);
    r.text("pose_mode", c.pose_mode);
    read_range(r, "camera_distance", c.camera_distance);
    read_range(r, "camera_elevation", c.camera_elevation);
    r.num("camera_roll_max", c.camera_roll_max);
    r.num("upright_prob", c.upright_prob);
    r.num("tall_prob", c.tall_prob);
    r.integer("blocks_min", c.blocks_min);
    r.integer("blocks_max", c.blocks_max);
    read_range(r, "block_size_mm", c.block_size_mm);
    r.num("on_block_prob", c.on_block_prob);
    r.num("on_object_prob", c.on_object_prob);
    r.num("lean_prob", c.lean_prob);
    r.num("lean_max_deg", c.lean_max_deg);
    r.num("table_spread_mm", c.table_spread_mm);
    r.num("look_at_jitter_mm", c.look_at_jitter_mm);
    r.num("table_size_mm", c.table_size_mm);
    r.integer("seed", c.seed);
    r.finish();
    validate(c, key_path.empty() ? source : source + ": " + key_path);
    return c;
}

SceneConfig load_scene_config(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    G2L_CHECK(f.good(), "load_scene_config: cannot open '", path, "'");
    std::ostringstream s;
    s << f.rdbuf();
    return parse_scene_config(s.str(), path);
}

std::string scene_config_to_json(const SceneConfig& c) {
    const SensorNoiseConfig& n = c.noise;
    json j;
    j["camera"] = {{"fx", c.camera.fx},         {"fy", c.camera.fy},
                   {"cx", c.camera.cx},         {"cy", c.camera.cy},
                   {"width", c.camera.width},   {"height", c.camera.height}};
    j["noise"] = {{"enabled", n.enabled},
                  {"sigma_a_mm", n.sigma_a_mm},
                  {"sigma_b_mm_per_m2", n.sigma_b_mm_per_m2},
                  {"quant_step_mm", n.quant_step_mm},
                  {"grazing_cos_min", n.grazing_cos_min},
                  {"edge_jump_mm", n.edge_jump_mm},
                  {"edge_width_px", n.edge_width_px},
                  {"edge_dropout_prob", n.edge_dropout_prob},
                  {"holes_min", n.holes_min},
                  {"holes_max", n.holes_max},
                  {"hole_radius_min_px", n.hole_radius_min_px},
                  {"hole_radius_max_px", n.hole_radius_max_px},
                  {"lateral_sigma_px", n.lateral_sigma_px}};
    j["depth_scale"] = c.depth_scale;
    j["target_obj_ids"] = c.target_obj_ids;
    j["targets_min"] = c.targets_min;
    j["targets_max"] = c.targets_max;
    j["unique_targets"] = c.unique_targets;
    j["kinds_min"] = c.kinds_min;
    j["kinds_max"] = c.kinds_max;
    j["distractor_obj_ids"] = c.distractor_obj_ids;
    j["distractors_min"] = c.distractors_min;
    j["distractors_max"] = c.distractors_max;
    j["z_min"] = c.z_min;
    j["z_max"] = c.z_max;
    j["xy_frac"] = c.xy_frac;
    j["full_rotation"] = c.full_rotation;
    j["euler_min"] = c.euler_min;
    j["euler_max"] = c.euler_max;
    j["separation"] = c.separation;
    j["support_plane_prob"] = c.support_plane_prob;
    j["plane_tilt_max"] = c.plane_tilt_max;
    j["random_background"] = c.random_background;
    j["random_light"] = c.random_light;
    j["object_color"] = {c.object_color[0], c.object_color[1], c.object_color[2]};
    j["pose_mode"] = c.pose_mode;
    j["camera_distance"] = c.camera_distance;
    j["camera_elevation"] = c.camera_elevation;
    j["camera_roll_max"] = c.camera_roll_max;
    j["upright_prob"] = c.upright_prob;
    j["tall_prob"] = c.tall_prob;
    j["blocks_min"] = c.blocks_min;
    j["blocks_max"] = c.blocks_max;
    j["block_size_mm"] = c.block_size_mm;
    j["on_block_prob"] = c.on_block_prob;
    j["on_object_prob"] = c.on_object_prob;
    j["lean_prob"] = c.lean_prob;
    j["lean_max_deg"] = c.lean_max_deg;
    j["table_spread_mm"] = c.table_spread_mm;
    j["look_at_jitter_mm"] = c.look_at_jitter_mm;
    j["table_size_mm"] = c.table_size_mm;
    j["seed"] = c.seed;
    return j.dump(2);
}

}  // namespace g2l::data
