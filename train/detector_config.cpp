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
#include "core/json_writer.h"
#include "train/config.h"
#include "train/detector_train.h"

namespace g2l::train {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {


// ---------------------------------------------------------------- config
/// Every key of a detector config, once (as train/config.cpp's visit_config). IO is
/// OrderedJsonReader (parse) or JsonWriter (print); the enum and the scene go through their
/// text forms both ways.
template <class IO>
void visit_detector(IO& io, DetectorTrainConfig& c, const std::string& source) {
    io.text("name", c.name);
    io.integer("seed", c.seed);
    io.integer("threads", c.threads);
    io.text("device", c.device);
    io.text("run_dir", c.run_dir);
    io.object("data", [&](IO& d) {
        d.text("models_root", c.models_root);
        d.ints("object_ids", c.object_ids);
        d.integer("downscale", c.downscale);
        std::string input = nn::to_string(c.input);
        d.text("input", input);
        c.input = nn::parse_detector_input(input, source + ": data.input");
        d.num("min_visib_fract", c.min_visib_fract);
        d.text("distractors_root", c.distractors_root);
        d.ints("distractor_ids", c.distractor_ids);
        d.integer("distractor_colors", c.distractor_colors);
        std::string scene = data::scene_config_to_json(c.scene);
        d.raw_object("scene", scene);
        c.scene = data::parse_scene_config(scene, source, "data.scene");
        d.list("mix", c.mix, [&](IO& m, DetectorTrainConfig::SceneMix& e) {
            m.require("prob");
            m.require("scene");
            m.num("prob", e.prob);
            std::string s = data::scene_config_to_json(e.scene);
            m.raw_object("scene", s);
            e.scene = data::parse_scene_config(s, source, "data.mix.scene");
        });
    });
    io.object("augment", [&](IO& a) {
        a.num("color_jitter", c.color_jitter);
        a.num("noise_std", c.noise_std);
        a.num("blur_prob", c.blur_prob);
        a.num("gray_prob", c.gray_prob);
        a.num("clutter_prob", c.clutter_prob);
        a.num("occluder_prob", c.occluder_prob);
        a.texts("backgrounds", c.backgrounds);
        a.num("photo_prob", c.photo_prob);
        a.num("object_tone_prob", c.object_tone_prob);
    });
    io.object("model", [&](IO& m) {
        m.integer("width", c.width);
        m.text("init", c.init);
    });
    io.object("loss", [&](IO& l) {
        l.num("heat", c.w_heat);
        l.num("size", c.w_size);
        l.num("offset", c.w_offset);
        l.num("block_negatives", c.w_block_negatives);
    });
    io.object("optim", [&](IO& o) { o.num("lr", c.lr); });
    io.object("train", [&](IO& t) {
        t.integer("steps", c.steps);
        t.integer("batch", c.batch);
        t.integer("checkpoint_every", c.checkpoint_every);
        t.integer("log_every", c.log_every);
        t.num("time_limit_min", c.time_limit_min);
        t.boolean("time_schedule", c.time_schedule);
    });
    io.object("val", [&](IO& v) {
        v.text("root", c.val_root);
        v.text("split", c.val_split);
        v.integer("every", c.val_every);
        v.integer("max_frames", c.val_max_frames);
    });
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
    double mixed = 0;
    for (size_t i = 0; i < c.mix.size(); ++i) {
        const DetectorTrainConfig::SceneMix& m = c.mix[i];
        G2L_CHECK(std::isfinite(m.prob) && m.prob > 0 && m.prob <= 1, where, ": 'data.mix[", i,
                  "].prob' must be in (0, 1], got ", m.prob);
        mixed += m.prob;
        const geom::Intrinsics &a = m.scene.camera, &b = c.scene.camera;
        G2L_CHECK(a.fx == b.fx && a.fy == b.fy && a.cx == b.cx && a.cy == b.cy &&
                      a.width == b.width && a.height == b.height,
                  where, ": 'data.mix[", i, "].scene.camera' (", a.width, " x ", a.height,
                  ", f ", a.fx, ") must be data.scene's camera (", b.width, " x ", b.height,
                  ", f ", b.fx, "): the detector sees one camera");
    }
    G2L_CHECK(mixed <= 1 + 1e-9, where, ": the 'data.mix' probabilities sum to ", mixed,
              ", more than 1");
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
    G2L_CHECK(std::isfinite(c.w_block_negatives) && c.w_block_negatives >= 0 &&
                  c.w_block_negatives <= 1,
              where, ": 'loss.block_negatives' must be in [0, 1], got ", c.w_block_negatives);
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

namespace {

/// The keys of a detector config with its paths resolved; run_dir stays as given (the default
/// follows the overrides: finish_detector_config).
DetectorTrainConfig read_detector_config(const std::string& json_text, const std::string& source,
                                         const std::string& base_dir) {
    const nlohmann::ordered_json root = parse_json_strict_ordered(json_text, source);
    DetectorTrainConfig c;
    OrderedJsonReader k(root, source);
    std::string task;
    k.require("task");
    k.text("task", task);
    G2L_CHECK(task == "detector", source, ": 'task' must be \"detector\" for a detector config, "
                                          "got \"", task, "\"");
    visit_detector(k, c, source);
    k.finish();
    if (!c.models_root.empty()) c.models_root = resolve_config_path(c.models_root, base_dir);
    if (!c.val_root.empty()) c.val_root = resolve_config_path(c.val_root, base_dir);
    if (!c.init.empty()) c.init = resolve_config_path(c.init, base_dir);
    if (!c.distractors_root.empty())
        c.distractors_root = resolve_config_path(c.distractors_root, base_dir);
    for (std::string& b : c.backgrounds) b = resolve_config_path(b, base_dir);
    return c;
}

/// The defaults that depend on other keys, then the checks.
void finish_detector_config(DetectorTrainConfig& c, const std::string& source) {
    if (c.run_dir.empty()) c.run_dir = "runs/" + c.name;  // as the pose trainer: cwd-relative
    validate(c, source);
}

}  // namespace

DetectorTrainConfig parse_detector_config(const std::string& json_text, const std::string& source,
                                          const std::string& base_dir) {
    DetectorTrainConfig c = read_detector_config(json_text, source, base_dir);
    finish_detector_config(c, source);
    return c;
}

std::string detector_config_to_json(const DetectorTrainConfig& cfg) {
    DetectorTrainConfig c = cfg;
    nlohmann::ordered_json j = {{"task", "detector"}};
    JsonWriter w(j);
    visit_detector(w, c, "detector_config_to_json");
    return j.dump(2) + "\n";
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
    // of docs/config.md can be set even when the file leaves it out; run_dir defaults to
    // runs/<name> after them (--set name=X moves the run to runs/X unless run_dir is given).
    DetectorTrainConfig c = read_detector_config(text.str(), path, dir);
    if (!sets.empty())
        c = read_detector_config(apply_sets_to_json(detector_config_to_json(c), sets, path), path,
                                 dir);
    finish_detector_config(c, path);
    return c;
}

}  // namespace g2l::train
