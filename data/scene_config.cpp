// SPDX-License-Identifier: MIT
// SceneConfig <-> JSON (strict: unknown keys and wrong types are errors naming the key path).
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/error.h"
#include "data/scene.h"
#include "core/json.h"

namespace g2l::data {
namespace {

using json = nlohmann::json;
using Reader = std::function<void(const json&, const std::string&)>;

void read_object(const json& j, const std::string& path, const std::map<std::string, Reader>& keys) {
    G2L_CHECK(j.is_object(), path, ": expected a JSON object, got ", j.type_name());
    for (auto it = j.begin(); it != j.end(); ++it) {
        const auto f = keys.find(it.key());
        if (f == keys.end()) {
            std::string known;
            for (const auto& [k, r] : keys) known += (known.empty() ? "" : ", ") + k;
            G2L_CHECK(false, path, ": unknown key '", it.key(), "' (known: ", known, ")");
        }
        f->second(it.value(), path + "." + it.key());
    }
}

Reader as_double(double& dst) {
    return [&dst](const json& v, const std::string& p) {
        G2L_CHECK(v.is_number(), p, " must be a number, got ", v.dump());
        dst = v.get<double>();
    };
}
Reader as_int(int& dst) {
    return [&dst](const json& v, const std::string& p) {
        G2L_CHECK(v.is_number_integer(), p, " must be an integer, got ", v.dump());
        dst = v.get<int>();
    };
}
Reader as_bool(bool& dst) {
    return [&dst](const json& v, const std::string& p) {
        G2L_CHECK(v.is_boolean(), p, " must be true or false, got ", v.dump());
        dst = v.get<bool>();
    };
}
Reader as_ids(std::vector<int>& dst) {
    return [&dst](const json& v, const std::string& p) {
        G2L_CHECK(v.is_array(), p, " must be an array of integers, got ", v.dump());
        dst.clear();
        for (const json& e : v) {
            G2L_CHECK(e.is_number_integer(), p, " must hold integers, got ", e.dump());
            dst.push_back(e.get<int>());
        }
    };
}
Reader as_array3(std::array<double, 3>& dst) {
    return [&dst](const json& v, const std::string& p) {
        G2L_CHECK(v.is_array() && v.size() == 3, p, " must be an array of 3 numbers, got ",
                  v.dump());
        for (size_t k = 0; k < 3; ++k) {
            G2L_CHECK(v[k].is_number(), p, "[", k, "] must be a number, got ", v[k].dump());
            dst[k] = v[k].get<double>();
        }
    };
}
Reader as_array2(std::array<double, 2>& dst) {
    return [&dst](const json& v, const std::string& p) {
        G2L_CHECK(v.is_array() && v.size() == 2, p, " must be an array of 2 numbers [min, max], got ",
                  v.dump());
        for (size_t k = 0; k < 2; ++k) {
            G2L_CHECK(v[k].is_number(), p, "[", k, "] must be a number, got ", v[k].dump());
            dst[k] = v[k].get<double>();
        }
    };
}
Reader as_string(std::string& dst) {
    return [&dst](const json& v, const std::string& p) {
        G2L_CHECK(v.is_string(), p, " must be a string, got ", v.dump());
        dst = v.get<std::string>();
    };
}
Reader as_rgb(std::array<uint8_t, 3>& dst) {
    return [&dst](const json& v, const std::string& p) {
        G2L_CHECK(v.is_array() && v.size() == 3, p, " must be [r, g, b], got ", v.dump());
        for (size_t k = 0; k < 3; ++k) {
            G2L_CHECK(v[k].is_number_integer() && v[k].get<int>() >= 0 && v[k].get<int>() <= 255,
                      p, "[", k, "] must be an integer in [0, 255], got ", v[k].dump());
            dst[k] = uint8_t(v[k].get<int>());
        }
    };
}

}  // namespace

SceneConfig parse_scene_config(const std::string& json_text, const std::string& source) {
    const json j = parse_json_strict(json_text, source);
    SceneConfig c;
    SensorNoiseConfig& n = c.noise;
    geom::Intrinsics& K = c.camera;
    const std::map<std::string, Reader> noise_keys = {
        {"enabled", as_bool(n.enabled)},
        {"sigma_a_mm", as_double(n.sigma_a_mm)},
        {"sigma_b_mm_per_m2", as_double(n.sigma_b_mm_per_m2)},
        {"quant_step_mm", as_double(n.quant_step_mm)},
        {"grazing_cos_min", as_double(n.grazing_cos_min)},
        {"edge_jump_mm", as_double(n.edge_jump_mm)},
        {"edge_width_px", as_int(n.edge_width_px)},
        {"edge_dropout_prob", as_double(n.edge_dropout_prob)},
        {"holes_min", as_int(n.holes_min)},
        {"holes_max", as_int(n.holes_max)},
        {"hole_radius_min_px", as_double(n.hole_radius_min_px)},
        {"hole_radius_max_px", as_double(n.hole_radius_max_px)},
        {"lateral_sigma_px", as_double(n.lateral_sigma_px)},
    };
    const std::map<std::string, Reader> camera_keys = {
        {"fx", as_double(K.fx)},       {"fy", as_double(K.fy)},       {"cx", as_double(K.cx)},
        {"cy", as_double(K.cy)},       {"width", as_int(K.width)},    {"height", as_int(K.height)},
    };
    const std::map<std::string, Reader> keys = {
        {"camera", [&](const json& v, const std::string& p) { read_object(v, p, camera_keys); }},
        {"noise", [&](const json& v, const std::string& p) { read_object(v, p, noise_keys); }},
        {"depth_scale", as_double(c.depth_scale)},
        {"target_obj_ids", as_ids(c.target_obj_ids)},
        {"targets_min", as_int(c.targets_min)},
        {"targets_max", as_int(c.targets_max)},
        {"unique_targets", as_bool(c.unique_targets)},
        {"distractor_obj_ids", as_ids(c.distractor_obj_ids)},
        {"distractors_min", as_int(c.distractors_min)},
        {"distractors_max", as_int(c.distractors_max)},
        {"z_min", as_double(c.z_min)},
        {"z_max", as_double(c.z_max)},
        {"xy_frac", as_double(c.xy_frac)},
        {"full_rotation", as_bool(c.full_rotation)},
        {"euler_min", as_array3(c.euler_min)},
        {"euler_max", as_array3(c.euler_max)},
        {"separation", as_double(c.separation)},
        {"support_plane_prob", as_double(c.support_plane_prob)},
        {"plane_tilt_max", as_double(c.plane_tilt_max)},
        {"random_background", as_bool(c.random_background)},
        {"random_light", as_bool(c.random_light)},
        {"object_color", as_rgb(c.object_color)},
        {"pose_mode", as_string(c.pose_mode)},
        {"camera_distance", as_array2(c.camera_distance)},
        {"camera_elevation", as_array2(c.camera_elevation)},
        {"camera_roll_max", as_double(c.camera_roll_max)},
        {"upright_prob", as_double(c.upright_prob)},
        {"tall_prob", as_double(c.tall_prob)},
        {"blocks_min", as_int(c.blocks_min)},
        {"blocks_max", as_int(c.blocks_max)},
        {"block_size_mm", as_array2(c.block_size_mm)},
        {"on_block_prob", as_double(c.on_block_prob)},
        {"on_object_prob", as_double(c.on_object_prob)},
        {"lean_prob", as_double(c.lean_prob)},
        {"lean_max_deg", as_double(c.lean_max_deg)},
        {"table_spread_mm", as_double(c.table_spread_mm)},
        {"look_at_jitter_mm", as_double(c.look_at_jitter_mm)},
        {"table_size_mm", as_double(c.table_size_mm)},
        {"seed",
         [&](const json& v, const std::string& p) {
             G2L_CHECK(v.is_number_unsigned() || (v.is_number_integer() && v.get<int64_t>() >= 0),
                       p, " must be a non-negative integer, got ", v.dump());
             c.seed = v.get<uint64_t>();
         }},
    };
    read_object(j, source, keys);
    validate(c, source);
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
