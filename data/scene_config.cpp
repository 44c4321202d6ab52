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
#include "core/json_writer.h"

namespace g2l::data {
namespace {

using json = nlohmann::ordered_json;
/// Two numbers [min, max] and an [r, g, b] colour: the scene's only composite values.
void rgb(OrderedJsonReader& r, const char* k, std::array<uint8_t, 3>& v) {
    std::vector<int> c;
    const bool had = r.has(k);
    r.ints(k, c);
    if (!had) return;
    G2L_CHECK(c.size() == 3 && std::all_of(c.begin(), c.end(),
                                           [](int x) { return x >= 0 && x <= 255; }),
              r.source(), ": '", r.at(k), "' must be [r, g, b] with integers in [0, 255]");
    for (int i = 0; i < 3; ++i) v[i] = static_cast<uint8_t>(c[i]);
}
void rgb(JsonWriter& w, const char* k, const std::array<uint8_t, 3>& v) {
    w.ints(k, {v[0], v[1], v[2]});
}

/// Every key of a scene config, once. IO is OrderedJsonReader (parse) or JsonWriter (print).
template <class IO>
void visit_scene(IO& io, SceneConfig& c) {
    SensorNoiseConfig& n = c.noise;
    geom::Intrinsics& K = c.camera;
    io.object("camera", [&](IO& rc) {
        rc.num("fx", K.fx);
        rc.num("fy", K.fy);
        rc.num("cx", K.cx);
        rc.num("cy", K.cy);
        rc.integer("width", K.width);
        rc.integer("height", K.height);
    });
    io.object("noise", [&](IO& rn) {
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
    io.num("depth_scale", c.depth_scale);
    io.ints("target_obj_ids", c.target_obj_ids);
    io.integer("targets_min", c.targets_min);
    io.integer("targets_max", c.targets_max);
    io.boolean("unique_targets", c.unique_targets);
    io.integer("kinds_min", c.kinds_min);
    io.integer("kinds_max", c.kinds_max);
    io.ints("distractor_obj_ids", c.distractor_obj_ids);
    io.integer("distractors_min", c.distractors_min);
    io.integer("distractors_max", c.distractors_max);
    io.num("z_min", c.z_min);
    io.num("z_max", c.z_max);
    io.num("xy_frac", c.xy_frac);
    io.boolean("full_rotation", c.full_rotation);
    io.num3("euler_min", c.euler_min);
    io.num3("euler_max", c.euler_max);
    io.num("separation", c.separation);
    io.num("support_plane_prob", c.support_plane_prob);
    io.num("plane_tilt_max", c.plane_tilt_max);
    io.boolean("random_background", c.random_background);
    io.boolean("random_light", c.random_light);
    rgb(io, "object_color", c.object_color);
    io.text("pose_mode", c.pose_mode);
    io.template nums<2>("camera_distance", c.camera_distance);
    io.template nums<2>("camera_elevation", c.camera_elevation);
    io.num("camera_roll_max", c.camera_roll_max);
    io.num("upright_prob", c.upright_prob);
    io.num("tall_prob", c.tall_prob);
    io.integer("blocks_min", c.blocks_min);
    io.integer("blocks_max", c.blocks_max);
    io.template nums<2>("block_size_mm", c.block_size_mm);
    io.num("block_lookalike_tol", c.block_lookalike_tol);
    io.num("on_block_prob", c.on_block_prob);
    io.num("on_object_prob", c.on_object_prob);
    io.num("lean_prob", c.lean_prob);
    io.num("lean_max_deg", c.lean_max_deg);
    io.num("table_spread_mm", c.table_spread_mm);
    io.num("look_at_jitter_mm", c.look_at_jitter_mm);
    io.num("table_size_mm", c.table_size_mm);
    io.integer("seed", c.seed);
}

}  // namespace

SceneConfig parse_scene_config(const std::string& json_text, const std::string& source,
                               const std::string& key_path) {
    const json j = parse_json_strict_ordered(json_text, source);
    SceneConfig c;
    OrderedJsonReader r(j, source, key_path);
    visit_scene(r, c);
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

std::string scene_config_to_json(const SceneConfig& cfg) {
    SceneConfig c = cfg;
    json j = json::object();
    JsonWriter w(j);
    visit_scene(w, c);
    return j.dump(2);
}

}  // namespace g2l::data
