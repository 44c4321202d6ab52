// SPDX-License-Identifier: MIT
// Detector configs: the strict JSON reader, validation, defaults and --set overrides.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/json.h"
#include "core/json_reader.h"
#include "train/config.h"
#include "train/detector_train.h"

namespace g2l::train {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {


// ---------------------------------------------------------------- config
json to_json(const DetectorTrainConfig& c) {
    return json{{"task", "detector"},
                {"name", c.name},
                {"seed", c.seed},
                {"threads", c.threads},
                {"device", c.device},
                {"run_dir", c.run_dir},
                {"data",
                 {{"models_root", c.models_root},
                  {"object_ids", c.object_ids},
                  {"downscale", c.downscale},
                  {"input", nn::to_string(c.input)},
                  {"min_visib_fract", c.min_visib_fract},
                  {"distractors_root", c.distractors_root},
                  {"distractor_ids", c.distractor_ids},
                  {"distractor_colors", c.distractor_colors},
                  {"scene", json::parse(data::scene_config_to_json(c.scene))}}},
                {"augment",
                 {{"color_jitter", c.color_jitter},
                  {"noise_std", c.noise_std},
                  {"blur_prob", c.blur_prob},
                  {"gray_prob", c.gray_prob},
                  {"clutter_prob", c.clutter_prob},
                  {"occluder_prob", c.occluder_prob},
                  {"backgrounds", c.backgrounds},
                  {"photo_prob", c.photo_prob},
                  {"object_tone_prob", c.object_tone_prob}}},
                {"model", {{"width", c.width}, {"init", c.init}}},
                {"loss", {{"heat", c.w_heat}, {"size", c.w_size}, {"offset", c.w_offset}}},
                {"optim", {{"lr", c.lr}}},
                {"train",
                 {{"steps", c.steps},
                  {"batch", c.batch},
                  {"checkpoint_every", c.checkpoint_every},
                  {"log_every", c.log_every},
                  {"time_limit_min", c.time_limit_min},
                  {"time_schedule", c.time_schedule}}},
                {"val",
                 {{"root", c.val_root},
                  {"split", c.val_split},
                  {"every", c.val_every},
                  {"max_frames", c.val_max_frames}}}};
}

void validate(const DetectorTrainConfig& c, const std::string& where) {
    G2L_CHECK(!c.models_root.empty(), where, ": 'data.models_root' is required");
    G2L_CHECK(!c.object_ids.empty(), where, ": 'data.object_ids' must list at least one object");
    std::set<int> ids(c.object_ids.begin(), c.object_ids.end());
    G2L_CHECK(ids.size() == c.object_ids.size(), where, ": 'data.object_ids' repeats an id");
    G2L_CHECK(c.downscale == 1 || c.downscale == 2 || c.downscale == 4, where,
              ": 'data.downscale' must be 1, 2 or 4, got ", c.downscale);
    G2L_CHECK(c.min_visib_fract >= 0 && c.min_visib_fract <= 1, where,
              ": 'data.min_visib_fract' must be in [0, 1], got ", c.min_visib_fract);
    auto frac = [&](const char* k, double v) {
        G2L_CHECK(std::isfinite(v) && v >= 0 && v <= 1, where, ": '", k, "' must be in [0, 1], got ", v);
    };
    frac("augment.color_jitter", c.color_jitter);
    frac("augment.blur_prob", c.blur_prob);
    frac("augment.gray_prob", c.gray_prob);
    frac("augment.clutter_prob", c.clutter_prob);
    frac("augment.occluder_prob", c.occluder_prob);
    frac("augment.photo_prob", c.photo_prob);
    frac("augment.object_tone_prob", c.object_tone_prob);
    G2L_CHECK(c.photo_prob == 0 || !c.backgrounds.empty(), where,
              ": 'augment.photo_prob' is ", c.photo_prob, " but 'augment.backgrounds' lists no "
              "directory of photographs");
    G2L_CHECK(c.distractor_colors >= 1 && c.distractor_colors <= 16, where,
              ": 'data.distractor_colors' must be in [1, 16], got ", c.distractor_colors);
    G2L_CHECK(c.distractor_ids.empty() || !c.distractors_root.empty(), where,
              ": 'data.distractor_ids' is set but 'data.distractors_root' is empty");
    G2L_CHECK(std::isfinite(c.noise_std) && c.noise_std >= 0 && c.noise_std <= 128, where,
              ": 'augment.noise_std' must be in [0, 128], got ", c.noise_std);
    G2L_CHECK(c.width >= 4 && c.width <= 256, where, ": 'model.width' must be in [4, 256], got ",
              c.width);
    for (auto [k, v] : {std::pair<const char*, double>{"loss.heat", c.w_heat},
                        {"loss.size", c.w_size}, {"loss.offset", c.w_offset}})
        G2L_CHECK(std::isfinite(v) && v >= 0, where, ": '", k, "' must be >= 0, got ", v);
    G2L_CHECK(std::isfinite(c.lr) && c.lr > 0, where, ": 'optim.lr' must be > 0, got ", c.lr);
    G2L_CHECK(c.steps > 0, where, ": 'train.steps' must be > 0, got ", c.steps);
    G2L_CHECK(c.batch > 0 && c.batch <= 1024, where, ": 'train.batch' must be in [1, 1024], got ",
              c.batch);
    G2L_CHECK(c.checkpoint_every > 0, where, ": 'train.checkpoint_every' must be > 0, got ",
              c.checkpoint_every);
    G2L_CHECK(c.log_every > 0, where, ": 'train.log_every' must be > 0, got ", c.log_every);
    G2L_CHECK(std::isfinite(c.time_limit_min) && c.time_limit_min >= 0, where,
              ": 'train.time_limit_min' must be >= 0, got ", c.time_limit_min);
    G2L_CHECK(c.val_every >= 0 && c.val_max_frames >= 0, where,
              ": 'val.every' and 'val.max_frames' must be >= 0");
    G2L_CHECK(parse_device(c.device).is_cpu(), where, ": device '", c.device,
              "': the detector trains on the CPU in this version");
    G2L_CHECK(c.threads >= 0, where, ": 'threads' must be >= 0, got ", c.threads);
}

}  // namespace

DetectorTrainConfig parse_detector_config(const std::string& json_text, const std::string& source,
                                          const std::string& base_dir) {
    const json root = parse_json_strict(json_text, source);
    DetectorTrainConfig c;
    JsonReader k(root, source);
    std::string task;
    k.require("task");
    k.text("task", task);
    G2L_CHECK(task == "detector", source, ": 'task' must be \"detector\" for a detector config, "
                                          "got \"", task, "\"");
    k.text("name", c.name);
    k.integer("seed", c.seed);
    k.integer("threads", c.threads);
    k.text("device", c.device);
    k.text("run_dir", c.run_dir);
    // Each section: an object whose keys are read by fill(), unknown keys refused.
    k.object("data", [&](JsonReader& kd) {
        kd.text("models_root", c.models_root);
        kd.ints("object_ids", c.object_ids);
        kd.integer("downscale", c.downscale);
        std::string input = nn::to_string(c.input);
        kd.text("input", input);
        c.input = nn::parse_detector_input(input, source + ": data.input");
        kd.num("min_visib_fract", c.min_visib_fract);
        kd.text("distractors_root", c.distractors_root);
        kd.ints("distractor_ids", c.distractor_ids);
        kd.integer("distractor_colors", c.distractor_colors);
        std::string scene;
        kd.raw_object("scene", scene);
        if (!scene.empty()) c.scene = data::parse_scene_config(scene, source, "data.scene");
    });
    k.object("augment", [&](JsonReader& ka) {
        ka.num("color_jitter", c.color_jitter);
        ka.num("noise_std", c.noise_std);
        ka.num("blur_prob", c.blur_prob);
        ka.num("gray_prob", c.gray_prob);
        ka.num("clutter_prob", c.clutter_prob);
        ka.num("occluder_prob", c.occluder_prob);
        ka.texts("backgrounds", c.backgrounds);
        ka.num("photo_prob", c.photo_prob);
        ka.num("object_tone_prob", c.object_tone_prob);
    });
    k.object("model", [&](JsonReader& km) {
        km.integer("width", c.width);
        km.text("init", c.init);
    });
    k.object("loss", [&](JsonReader& kl) {
        kl.num("heat", c.w_heat);
        kl.num("size", c.w_size);
        kl.num("offset", c.w_offset);
    });
    k.object("optim", [&](JsonReader& ko) { ko.num("lr", c.lr); });
    k.object("train", [&](JsonReader& kt) {
        kt.integer("steps", c.steps);
        kt.integer("batch", c.batch);
        kt.integer("checkpoint_every", c.checkpoint_every);
        kt.integer("log_every", c.log_every);
        kt.num("time_limit_min", c.time_limit_min);
        kt.boolean("time_schedule", c.time_schedule);
    });
    k.object("val", [&](JsonReader& kv) {
        kv.text("root", c.val_root);
        kv.text("split", c.val_split);
        kv.integer("every", c.val_every);
        kv.integer("max_frames", c.val_max_frames);
    });
    k.finish();
    if (!c.models_root.empty()) c.models_root = resolve_config_path(c.models_root, base_dir);
    if (!c.val_root.empty()) c.val_root = resolve_config_path(c.val_root, base_dir);
    if (!c.init.empty()) c.init = resolve_config_path(c.init, base_dir);
    if (!c.distractors_root.empty())
        c.distractors_root = resolve_config_path(c.distractors_root, base_dir);
    for (std::string& b : c.backgrounds) b = resolve_config_path(b, base_dir);
    if (c.run_dir.empty()) c.run_dir = "runs/" + c.name;  // as the pose trainer: cwd-relative
    validate(c, source);
    return c;
}

std::string detector_config_to_json(const DetectorTrainConfig& cfg) {
    return to_json(cfg).dump(2) + "\n";
}

bool is_detector_config(const std::string& path) {
    const json j = parse_json_file(path);
    return j.is_object() && j.contains("task") && j["task"] == "detector";
}

DetectorTrainConfig load_detector_config(const std::string& path,
                                         const std::vector<std::string>& sets) {
    std::ifstream f(path, std::ios::binary);
    G2L_CHECK(f.good(), "load_detector_config: cannot open config file '", path, "'");
    std::ostringstream text;
    text << f.rdbuf();
    const std::string dir = fs::absolute(path).parent_path().lexically_normal().string();
    // As the pose trainer: overrides apply to the full config (defaults included), so any key
    // of docs/config.md can be set even when the file leaves it out.
    DetectorTrainConfig c = parse_detector_config(text.str(), path, dir);
    if (sets.empty()) return c;
    return parse_detector_config(apply_sets_to_json(detector_config_to_json(c), sets, path), path,
                                 dir);
}

}  // namespace g2l::train
