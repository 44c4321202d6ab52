// SPDX-License-Identifier: MIT
// g2l_train's JSON config (train/config.h): defaults, a full round trip, --set overrides, path
// rules, every error class (the message must name the file and key path), every shipped config.
#include <array>
#include <catch2/catch.hpp>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <fstream>
#include <nlohmann/json.hpp>
#include <map>
#include <optional>
#include <set>

#include "core/error.h"
#include "testing.h"
#include "train/config.h"
#include "train/detector_train.h"

using namespace g2l;
using namespace g2l::train;
using Catch::Contains;
namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

namespace {

std::string mini_root() { return (fs::path(testing::fixture_dir()) / "ycbv_mini").string(); }

/// The smallest valid config: one BOP source with an absolute root.
json minimal() {
    json j;
    j["data"]["train"] = json::array({{{"type", "bop"}, {"root", mini_root()}}});
    return j;
}

/// A config where every key differs from its default (two train sources, one val source).
json everything() {
    return json::parse(R"({
      "name": "full", "seed": 18446744073709551615, "threads": 3, "device": "cuda:1",
      "run_dir": "out/runs/full",
      "data": {
        "object_ids": [8, 14, 21],
        "train": [
          {"type": "bop", "root": "ROOT", "split": "test", "scenes": ["000000", "000002"],
           "objects": [8, 14], "models_eval": true, "min_visib_fract": 0.25, "max_frames": 7},
          {"type": "synthetic", "models_root": "ROOT", "objects": [14], "frames": 33,
           "scene": {"targets_min": 1, "targets_max": 1, "z_min": 400, "z_max": 800,
                     "noise": {"enabled": false}, "seed": 5}}
        ],
        "val": [{"type": "bop", "root": "ROOT", "split": "train_real", "scenes": [],
                 "objects": [], "models_eval": false, "min_visib_fract": 0, "max_frames": 0}]
      },
      "sampling": {"crop": "slab", "points": 900, "seg_points": 600, "radius_scale": 1.5,
                   "center_jitter_mm": 4, "box_jitter_frac": 0.1, "label_threshold_mm": 6,
                   "surface_spacing_mm": 3, "min_points": 20, "min_visib_fract": 0.3},
      "augment": {"enabled": false, "shift_mm": [1, 2, 3], "rot_deg": 15, "point_noise_mm": 1.5},
      "model": {"num_classes": 21, "keypoints": "fps12", "evf": false, "rre": false,
                "width": 0.5, "dropout": 0.1, "out_scale_mm": 100, "rot_unit": "mm", "class_heads": true,
                "init": "/models/start.g2l"},
      "loss": {"seg": 1, "t": 2, "vec": 3, "kp": 4, "res": 5, "t_loss": "smooth_l1",
               "symmetric_targets": true, "rot_centre": "pred", "rot_centre_noise_mm": 7,
               "rot_gt_points_epochs": 2, "rot_only_epochs": 3},
      "optim": {"lr": 0.005, "beta1": 0.8, "beta2": 0.95, "eps": 1e-6, "weight_decay": 0.0001,
                "lr_mult": {"seg": 2, "tnet": 3, "evf": 4, "rot": 5, "rre": 6}},
      "schedule": {"kind": "official", "step_epochs": 7, "gamma": 0.25},
      "train": {"epochs": 12, "batch": 4, "samples_per_epoch": 100, "checkpoint_every": 2,
                "val_every": 3, "max_val_samples": 50, "time_limit_min": 1.5, "time_schedule": true, "log_every": 5,
                "prefetch": false}
    })");
}

json with_root(json j) {
    for (const char* which : {"train", "val"})
        for (auto& s : j["data"][which]) {
            if (s.contains("root")) s["root"] = mini_root();
            if (s.contains("models_root")) s["models_root"] = mini_root();
        }
    return j;
}

TrainConfig parse(const json& j, const std::vector<std::string>& sets = {}) {
    return parse_config_text(j.dump(), "x.json", sets);
}

std::string write_file(const std::string& dir, const std::string& name, const std::string& text) {
    const std::string p = (fs::path(dir) / name).string();
    std::ofstream(p) << text;
    return p;
}

/// Sets or clears an environment variable for one scope.
struct EnvGuard {
    std::string name;
    std::optional<std::string> old;
    EnvGuard(std::string n, const char* value) : name(std::move(n)) {
        if (const char* v = std::getenv(name.c_str())) old = v;
        if (value) setenv(name.c_str(), value, 1); else unsetenv(name.c_str());
    }
    ~EnvGuard() {
        if (old) setenv(name.c_str(), old->c_str(), 1); else unsetenv(name.c_str());
    }
};

}  // namespace

TEST_CASE("config: defaults are the paper's values", "[config]") {
    const TrainConfig c = parse_config_text(minimal().dump(), "configs/mini.json");
    CHECK(c.name == "mini");
    CHECK(c.run_dir == "runs/mini");
    CHECK(c.seed == 1);
    CHECK(c.threads == 0);
    CHECK(c.device == "cpu");
    REQUIRE(c.data.object_ids == std::vector<int>{1});
    REQUIRE(c.data.train.size() == 1);
    CHECK(c.data.val.empty());
    const SourceConfig& s = c.data.train[0];
    CHECK(s.type == train::SourceType::bop);
    CHECK(s.root == mini_root());
    CHECK(s.split == "train_real");
    CHECK(s.scenes.empty());
    CHECK(s.objects.empty());
    CHECK_FALSE(s.models_eval);
    CHECK(s.min_visib_fract == 0.1);
    CHECK(s.max_frames == 0);
    CHECK(c.sampling.crop == geom::CropKind::sphere);
    CHECK(c.sampling.points == 1500);
    CHECK(c.sampling.seg_points == 1000);
    CHECK(c.sampling.radius_scale == 1.0);
    CHECK(c.sampling.center_jitter_mm == 10);
    CHECK(c.sampling.box_jitter_frac == 0.05);
    CHECK(c.sampling.label_threshold_mm == 8);
    CHECK(c.sampling.surface_spacing_mm == 2.0);
    CHECK(c.sampling.min_points == 50);
    CHECK(c.sampling.min_visib_fract == 0.1);
    CHECK(c.augment.enabled);
    CHECK(c.augment.shift_mm == std::array<double, 3>{{5, 5, 25}});
    CHECK(c.augment.rot_deg == 10);
    CHECK(c.augment.point_noise_mm == 0);
    CHECK(c.model.num_classes == 16);
    CHECK(c.model.keypoints == "bbx8");
    CHECK(c.model.evf);
    CHECK(c.model.rre);
    CHECK(c.model.width == 1.0);
    CHECK(c.model.dropout == 0.2);
    CHECK(c.model.out_scale_mm == 1.0);
    CHECK(c.model.rot_unit == "kp_rms");
    CHECK(c.model.init.empty());
    CHECK(c.loss.rot_centre == "gt");
    CHECK(c.loss.rot_centre_noise_mm == 0);
    CHECK(c.loss.rot_gt_points_epochs == 0);
    CHECK(c.loss.rot_only_epochs == 0);
    CHECK_FALSE(c.loss.symmetric_targets);
    CHECK(c.loss.seg == 10);
    CHECK(c.loss.t == 0.1);
    CHECK(c.loss.vec == 10);
    CHECK(c.loss.kp == 0.01);
    CHECK(c.loss.res == 0.01);
    CHECK(c.loss.t_loss == "mse");
    CHECK(c.optim.lr == 1e-3);
    CHECK(c.optim.beta1 == 0.9);
    CHECK(c.optim.beta2 == 0.99);
    CHECK(c.optim.eps == 1e-8);
    CHECK(c.optim.weight_decay == 0);
    CHECK(c.optim.lr_mult.seg == 1);
    CHECK(c.optim.lr_mult.tnet == 10);
    CHECK(c.optim.lr_mult.evf == 1);
    CHECK(c.optim.lr_mult.rot == 30);
    CHECK(c.optim.lr_mult.rre == 20);
    CHECK(c.schedule.kind == "step");
    CHECK(c.schedule.step_epochs == 50);
    CHECK(c.schedule.gamma == 0.5);
    CHECK(c.train.epochs == 200);
    CHECK(c.train.batch == 8);
    CHECK(c.train.samples_per_epoch == 0);
    CHECK(c.train.checkpoint_every == 10);
    CHECK(c.train.val_every == 1);
    CHECK(c.train.max_val_samples == 200);
    CHECK(c.train.time_limit_min == 0);
    CHECK(!c.train.time_schedule);
    CHECK(c.train.log_every == 10);
    // The struct defaults agree with the loaded ones (a default-constructed config only lacks
    // the train source, the name and the run dir).
    const TrainConfig d;
    CHECK(d.sampling.points == c.sampling.points);
    CHECK(d.optim.lr_mult.rot == c.optim.lr_mult.rot);
    CHECK(d.data.train.empty());
}

TEST_CASE("config: every key round-trips through config_to_json", "[config]") {
    const TrainConfig c = parse(with_root(everything()));
    CHECK(c.name == "full");
    CHECK(c.seed == 18446744073709551615ull);
    CHECK(c.threads == 3);
    CHECK(c.device == "cuda:1");
    CHECK(c.run_dir == "out/runs/full");
    CHECK(c.data.object_ids == std::vector<int>{8, 14, 21});
    REQUIRE(c.data.train.size() == 2);
    REQUIRE(c.data.val.size() == 1);
    const SourceConfig& b = c.data.train[0];
    CHECK(b.split == "test");
    CHECK(b.scenes == std::vector<std::string>{"000000", "000002"});
    CHECK(b.objects == std::vector<int>{8, 14});
    CHECK(b.models_eval);
    CHECK(b.min_visib_fract == 0.25);
    CHECK(b.max_frames == 7);
    const SourceConfig& s = c.data.train[1];
    CHECK(s.type == train::SourceType::synthetic);
    CHECK(s.models_root == mini_root());
    CHECK(s.objects == std::vector<int>{14});
    CHECK(s.frames == 33);
    const data::SceneConfig sc = source_scene(s, "scene");
    CHECK(sc.z_min == 400);
    CHECK(sc.z_max == 800);
    CHECK(sc.targets_max == 1);
    CHECK_FALSE(sc.noise.enabled);
    CHECK(sc.seed == 5);
    CHECK(c.data.val[0].min_visib_fract == 0);
    CHECK(c.sampling.crop == geom::CropKind::slab);
    CHECK(c.sampling.points == 900);
    CHECK(c.sampling.seg_points == 600);
    CHECK(c.sampling.radius_scale == 1.5);
    CHECK(c.sampling.center_jitter_mm == 4);
    CHECK(c.sampling.box_jitter_frac == 0.1);
    CHECK(c.sampling.label_threshold_mm == 6);
    CHECK(c.sampling.surface_spacing_mm == 3);
    CHECK(c.sampling.min_points == 20);
    CHECK(c.sampling.min_visib_fract == 0.3);
    CHECK_FALSE(c.augment.enabled);
    CHECK(c.augment.shift_mm == std::array<double, 3>{{1, 2, 3}});
    CHECK(c.augment.rot_deg == 15);
    CHECK(c.augment.point_noise_mm == 1.5);
    CHECK(c.model.num_classes == 21);
    CHECK(c.model.keypoints == "fps12");
    CHECK_FALSE(c.model.evf);
    CHECK_FALSE(c.model.rre);
    CHECK(c.model.width == 0.5);
    CHECK(c.model.dropout == 0.1);
    CHECK(c.model.out_scale_mm == 100);
    CHECK(c.model.class_heads);
    CHECK(c.loss.symmetric_targets);
    CHECK(c.loss.seg == 1);
    CHECK(c.loss.t == 2);
    CHECK(c.loss.vec == 3);
    CHECK(c.loss.kp == 4);
    CHECK(c.loss.res == 5);
    CHECK(c.loss.t_loss == "smooth_l1");
    CHECK(c.optim.lr == 0.005);
    CHECK(c.optim.beta1 == 0.8);
    CHECK(c.optim.beta2 == 0.95);
    CHECK(c.optim.eps == 1e-6);
    CHECK(c.optim.weight_decay == 0.0001);
    CHECK(c.optim.lr_mult.seg == 2);
    CHECK(c.optim.lr_mult.tnet == 3);
    CHECK(c.optim.lr_mult.evf == 4);
    CHECK(c.optim.lr_mult.rot == 5);
    CHECK(c.optim.lr_mult.rre == 6);
    CHECK(c.schedule.kind == "official");
    CHECK(c.schedule.step_epochs == 7);
    CHECK(c.schedule.gamma == 0.25);
    CHECK(c.train.epochs == 12);
    CHECK(c.train.batch == 4);
    CHECK(c.train.samples_per_epoch == 100);
    CHECK(c.train.checkpoint_every == 2);
    CHECK(c.train.val_every == 3);
    CHECK(c.train.max_val_samples == 50);
    CHECK(c.train.time_limit_min == 1.5);
    CHECK(c.train.time_schedule);
    CHECK(c.train.log_every == 5);
    CHECK(c.model.init == "/models/start.g2l");

    // Print -> parse -> print is a fixed point, and the printed JSON has every input key with
    // the same value (the scene object is kept verbatim).
    const std::string text = config_to_json(c);
    const TrainConfig c2 = parse_config_text(text, "elsewhere/other.json", {}, "/nonexistent");
    CHECK(config_to_json(c2) == text);
    CHECK(c2.data.train[1].scene == c.data.train[1].scene);
    CHECK(c2.seed == c.seed);
    CHECK(json::parse(text) == with_root(everything()));

    // The defaults round-trip too (name and run_dir filled in once).
    const TrainConfig d = parse(minimal());
    const std::string dt = config_to_json(d);
    CHECK(config_to_json(parse_config_text(dt, "y.json")) == dt);
    CHECK(json::parse(dt)["run_dir"] == "runs/x");
}

TEST_CASE("config: unknown keys are errors naming the key path", "[config]") {
    json j = minimal();
    j["optim"]["lr_mult"]["segg"] = 1;  // depth 3
    REQUIRE_THROWS_WITH(parse(j), Contains("x.json: unknown key 'optim.lr_mult.segg'") &&
                                      Contains("known: seg, tnet, evf, rot, rre"));
    j = minimal();
    j["optim"]["lrr"] = 0.1;
    REQUIRE_THROWS_WITH(parse(j), Contains("unknown key 'optim.lrr'"));
    j = minimal();
    j["bogus"] = true;
    REQUIRE_THROWS_WITH(parse(j), Contains("unknown key 'bogus'"));
    // A key of the other source type.
    j = minimal();
    j["data"]["train"][0]["frames"] = 10;
    REQUIRE_THROWS_WITH(parse(j), Contains("unknown key 'data.train[0].frames'") &&
                                      Contains("models_eval"));
    // A source without its type.
    j = minimal();
    j["data"]["train"][0].erase("type");
    REQUIRE_THROWS_WITH(parse(j), Contains("'data.train[0].type' is required"));
    // Unknown keys inside a scene are reported by the scene parser under the scene's path.
    j = with_root(everything());
    j["data"]["train"][1]["scene"]["z_mn"] = 3;
    REQUIRE_THROWS_WITH(parse(j), Contains("x.json: unknown key 'data.train[1].scene.z_mn'"));
}

TEST_CASE("config: wrong types name the key and the value", "[config]") {
    json j = minimal();
    j["optim"]["lr"] = "abc";
    REQUIRE_THROWS_WITH(parse(j), Contains("x.json: 'optim.lr' must be a number, got \"abc\""));
    j = minimal();
    j["train"]["epochs"] = 1.5;
    REQUIRE_THROWS_WITH(parse(j), Contains("'train.epochs' must be an integer") &&
                                      Contains("got 1.5"));
    j = minimal();
    j["seed"] = -1;
    REQUIRE_THROWS_WITH(parse(j), Contains("'seed' must be a non-negative integer"));
    j = minimal();
    j["train"]["batch"] = 5000000000LL;
    REQUIRE_THROWS_WITH(parse(j), Contains("'train.batch' must be an integer in the range of 32"));
    j = minimal();
    j["model"]["evf"] = 1;
    REQUIRE_THROWS_WITH(parse(j), Contains("'model.evf' must be true or false, got 1"));
    j = minimal();
    j["loss"]["symmetric_targets"] = "yes";
    REQUIRE_THROWS_WITH(parse(j), Contains("'loss.symmetric_targets' must be true or false"));
    j = minimal();
    j["augment"]["shift_mm"] = json::array({1, 2});
    REQUIRE_THROWS_WITH(parse(j), Contains("'augment.shift_mm' must be an array of 3 numbers"));
    j = minimal();
    j["data"]["object_ids"] = json::array({1, "two"});
    REQUIRE_THROWS_WITH(parse(j), Contains("'data.object_ids[1]' must be an integer") &&
                                      Contains("\"two\""));
    j = minimal();
    j["data"]["train"][0]["scenes"] = json::array({0});
    REQUIRE_THROWS_WITH(parse(j), Contains("'data.train[0].scenes[0]' must be a string, got 0"));
    j = minimal();
    j["optim"] = 3;
    REQUIRE_THROWS_WITH(parse(j), Contains("'optim' must be a JSON object, got 3"));
    j = minimal();
    j["data"]["train"] = json::object();
    REQUIRE_THROWS_WITH(parse(j), Contains("'data.train' must be an array of objects"));
    j = with_root(everything());
    j["data"]["train"][1]["scene"]["z_min"] = "near";
    REQUIRE_THROWS_WITH(parse(j), Contains("'data.train[1].scene.z_min' must be a number, got \"near\""));
    REQUIRE_THROWS_WITH(parse_config_text("[1, 2]", "arr.json"),
                        Contains("arr.json: the config must be a JSON object, got array"));
}

TEST_CASE("config: bad enum values list the allowed ones", "[config]") {
    json j = minimal();
    j["sampling"]["crop"] = "cube";
    REQUIRE_THROWS_WITH(parse(j), Contains("'sampling.crop' must be one of \"sphere\", "
                                           "\"frustum\", \"slab\", got \"cube\""));
    j = minimal();
    j["model"]["keypoints"] = "fps16";
    REQUIRE_THROWS_WITH(parse(j), Contains("\"bbx8\", \"fps4\", \"fps8\", \"fps12\", got "
                                           "\"fps16\""));
    j = minimal();
    j["schedule"]["kind"] = "cosine";
    REQUIRE_THROWS_WITH(parse(j), Contains("'schedule.kind' must be one of \"step\", "
                                           "\"official\", \"constant\""));
    j = minimal();
    j["model"]["rot_unit"] = "cm";
    REQUIRE_THROWS_WITH(parse(j), Contains("'model.rot_unit' must be one of \"kp_rms\", \"mm\", "
                                           "got \"cm\""));
    j = minimal();
    j["loss"]["rot_centre"] = "mean";
    REQUIRE_THROWS_WITH(parse(j), Contains("'loss.rot_centre' must be one of \"gt\", \"pred\""));
    j = minimal();
    j["loss"]["t_loss"] = "l1";
    REQUIRE_THROWS_WITH(parse(j), Contains("'loss.t_loss' must be one of"));
    j = minimal();
    j["data"]["train"][0]["type"] = "lmdb";
    REQUIRE_THROWS_WITH(parse(j), Contains("'data.train[0].type' must be one of \"bop\", "
                                           "\"synthetic\", \"linemod_preprocessed\", got \"lmdb\""));
    j = minimal();
    j["device"] = "gpu";
    REQUIRE_THROWS_WITH(parse(j), Contains("'device' must be \"cpu\", \"cuda\" or \"cuda:N\", "
                                           "got \"gpu\""));
}

TEST_CASE("config: value checks name the key and the value", "[config]") {
    const std::vector<std::pair<std::function<void(json&)>, std::string>> cases = {
        {[](json& j) { j["optim"]["lr"] = 0; }, "'optim.lr' must be > 0, got 0"},
        {[](json& j) { j["optim"]["lr"] = -1e-3; }, "'optim.lr' must be > 0, got -0.001"},
        {[](json& j) { j["optim"]["beta2"] = 1.0; }, "'optim.beta2' must be in [0, 1)"},
        {[](json& j) { j["optim"]["lr_mult"]["rot"] = -2; }, "'optim.lr_mult.rot' must be >= 0"},
        {[](json& j) { j["train"]["epochs"] = 0; }, "'train.epochs' must be > 0, got 0"},
        {[](json& j) { j["train"]["batch"] = -3; }, "'train.batch' must be > 0, got -3"},
        {[](json& j) { j["train"]["time_limit_min"] = -1; }, "'train.time_limit_min' must be >= 0"},
        {[](json& j) { j["sampling"]["seg_points"] = 2000; },
         "'sampling.points' = 1500 must be >= 'sampling.seg_points' = 2000"},
        {[](json& j) { j["sampling"]["seg_points"] = 0; }, "'sampling.seg_points' must be > 0"},
        {[](json& j) { j["sampling"]["box_jitter_frac"] = 0.7; },
         "'sampling.box_jitter_frac' must be in [0, 0.5], got 0.7"},
        {[](json& j) { j["augment"]["rot_deg"] = 200; }, "'augment.rot_deg' must be in [0, 180]"},
        {[](json& j) { j["model"]["width"] = 0; }, "'model.width' must be > 0, got 0"},
        {[](json& j) { j["model"]["dropout"] = 1; }, "'model.dropout' must be in [0, 1)"},
        {[](json& j) { j["model"]["out_scale_mm"] = -2; },
         "'model.out_scale_mm' must be finite and > 0, got -2"},
        {[](json& j) { j["schedule"]["gamma"] = 0; }, "'schedule.gamma' must be in (0, 1]"},
        {[](json& j) { j["loss"]["rot_centre_noise_mm"] = -3; },
         "'loss.rot_centre_noise_mm' must be >= 0, got -3"},
        {[](json& j) { j["loss"]["rot_only_epochs"] = 200; },
         "'loss.rot_only_epochs' must be in [0, train.epochs), got 200"},
        {[](json& j) { j["loss"]["rot_gt_points_epochs"] = -1; },
         "'loss.rot_gt_points_epochs' must be >= 0, got -1"},
        {[](json& j) { j["threads"] = -1; }, "'threads' must be >= 0"},
        {[](json& j) { j["loss"] = {{"seg", 0}, {"t", 0}, {"vec", 0}, {"kp", 0}, {"res", 0}}; },
         "every loss weight is 0"},
        {[](json& j) { j["data"]["object_ids"] = json::array(); },
         "'data.object_ids' must list at least one object"},
        {[](json& j) { j["data"]["object_ids"] = {3, 3}; },
         "'data.object_ids' lists object 3 twice"},
        {[](json& j) { j["data"]["object_ids"] = {0}; }, "'data.object_ids[0]' must be > 0"},
        {[](json& j) { j["data"]["train"] = json::array(); },
         "'data.train' must list at least one source"},
        {[](json& j) { j["data"]["train"][0]["objects"] = {1, 5}; },
         "'data.train[0].objects[1]' = 5 is not in data.object_ids"},
        {[](json& j) { j["data"]["train"][0]["min_visib_fract"] = 1.5; },
         "'data.train[0].min_visib_fract' must be in [0, 1], got 1.5"},
        {[](json& j) { j["data"]["train"][0]["root"] = ""; },
         "'data.train[0].root' must be set for a \"bop\" source"},
        {[](json& j) { j["data"]["train"][0].erase("root"); }, "'data.train[0].root' must be set"},
        {[](json& j) {
             j["data"]["object_ids"] = json::array();
             for (int i = 1; i <= 17; ++i) j["data"]["object_ids"].push_back(i);
         },
         "'model.num_classes' = 16 is smaller than the 17 objects"},
    };
    for (const auto& [edit, message] : cases) {
        json j = minimal();
        edit(j);
        INFO(j.dump());
        REQUIRE_THROWS_WITH(parse(j), Contains("x.json: " + message));
    }
    // Synthetic sources: frames, scene validity (under the scene's key path), scene targets.
    json j = with_root(everything());
    j["data"]["train"][1]["frames"] = 0;
    REQUIRE_THROWS_WITH(parse(j), Contains("x.json: 'data.train[1].frames' must be > 0, got 0"));
    j = with_root(everything());
    j["data"]["train"][1]["scene"]["z_min"] = 900;  // > z_max 800
    REQUIRE_THROWS_WITH(parse(j), Contains("x.json: data.train[1].scene"));
    j = with_root(everything());
    j["data"]["train"][1]["scene"]["target_obj_ids"] = {8};
    REQUIRE_THROWS_WITH(parse(j), Contains("'data.train[1].scene.target_obj_ids[0]' = 8 is not "
                                           "among the source's objects"));
}

TEST_CASE("config: --set overrides apply before validation", "[config]") {
    const json base = with_root(everything());
    const TrainConfig c = parse(base, {"optim.lr=0.01", "data.train.1.frames=10",
                                       "sampling.crop=frustum", "augment.shift_mm=[0, 0, 7]",
                                       "data.object_ids=[8, 14, 21, 30]", "model.evf=true",
                                       "data.train.1.scene.z_min=300", "seed=42",
                                       "data.train.1.scene.noise.sigma_a_mm=2.5"});
    CHECK(c.optim.lr == 0.01);
    CHECK(c.data.train[1].frames == 10);
    CHECK(c.sampling.crop == geom::CropKind::frustum);  // not JSON -> the name
    CHECK(c.augment.shift_mm == std::array<double, 3>{{0, 0, 7}});
    CHECK(c.data.object_ids == std::vector<int>{8, 14, 21, 30});
    CHECK(c.model.evf);
    CHECK(c.seed == 42);
    const data::SceneConfig sc = source_scene(c.data.train[1], "s");
    CHECK(sc.z_min == 300);
    CHECK(sc.z_max == 800);  // untouched keys stay
    CHECK(sc.noise.sigma_a_mm == 2.5);
    CHECK_FALSE(sc.noise.enabled);

    // Later sets win; a set can repair a value that alone would fail validation.
    CHECK(parse(base, {"optim.lr=1", "optim.lr=2"}).optim.lr == 2);
    CHECK(parse(base, {"sampling.seg_points=5000", "sampling.points=6000"}).sampling.points ==
          6000);
    // name drives the default run_dir when run_dir is empty.
    json m = minimal();
    CHECK(parse(m, {"name=exp7"}).run_dir == "runs/exp7");
    CHECK(parse(m, {"name=exp7", "run_dir=/tmp/r"}).run_dir == "/tmp/r");

    REQUIRE_THROWS_WITH(parse(base, {"optim.lrr=1"}),
                        Contains("x.json: --set 'optim.lrr=1': unknown key 'optim.lrr'"));
    REQUIRE_THROWS_WITH(parse(base, {"optim.lr_mult.segg=1"}),
                        Contains("unknown key 'optim.lr_mult.segg'"));
    REQUIRE_THROWS_WITH(parse(base, {"optim.lr"}), Contains("--set 'optim.lr': expected "
                                                             "key.path=value"));
    REQUIRE_THROWS_WITH(parse(base, {"=3"}), Contains("expected key.path=value"));
    REQUIRE_THROWS_WITH(parse(base, {"optim..lr=3"}), Contains("empty component in key path "
                                                                "'optim..lr'"));
    REQUIRE_THROWS_WITH(parse(base, {"data.train.2.frames=1"}),
                        Contains("'data.train' is a list of 2 element(s), '2' is not a valid "
                                 "index"));
    REQUIRE_THROWS_WITH(parse(base, {"data.train.first.frames=1"}),
                        Contains("'first' is not a valid index"));
    REQUIRE_THROWS_WITH(parse(base, {"optim.lr.x=1"}),
                        Contains("'optim.lr' is a number, it has no key 'x'"));
    REQUIRE_THROWS_WITH(parse(base, {"data.train.0.frames=10"}),
                        Contains("unknown key 'data.train.0.frames'"));
    REQUIRE_THROWS_WITH(parse(base, {"optim.lr=abc"}),
                        Contains("x.json (--set 'optim.lr=abc'): 'optim.lr' must be a number, "
                                 "got \"abc\""));
    REQUIRE_THROWS_WITH(parse(base, {"optim.lr=-1"}), Contains("'optim.lr' must be > 0, got -1"));
    REQUIRE_THROWS_WITH(parse(base, {"data.train.1.scene.z_mn=3"}),
                        Contains("unknown key 'data.train[1].scene.z_mn'"));
}

TEST_CASE("config: files, malformed JSON and path resolution", "[config]") {
    const std::string dir = testing::temp_dir("config");
    REQUIRE_THROWS_WITH(load_config(dir + "/no_such.json", {}),
                        Contains("config file '" + dir + "/no_such.json' does not exist"));
    REQUIRE_THROWS_WITH(load_config(dir, {}), Contains("' does not exist or is not a file"));

    const std::string bad = write_file(dir, "bad.json", "{\n  \"seed\": 1,\n  \"threads\" 2\n}\n");
    REQUIRE_THROWS_WITH(load_config(bad, {}), Contains(bad + ": invalid JSON") &&
                                                  Contains("line 3, column"));
    const std::string trunc = write_file(dir, "trunc.json", "{\"seed\": 1, \"data\": {");
    REQUIRE_THROWS_WITH(load_config(trunc, {}), Contains("trunc.json: invalid JSON") &&
                                                    Contains("line 1, column"));
    const std::string empty = write_file(dir, "empty.json", "");
    REQUIRE_THROWS_WITH(load_config(empty, {}), Contains("empty.json: invalid JSON"));

    // Relative paths: the config's directory unless they exist relative to the current one.
    fs::create_directories(fs::path(dir) / "mydata");
    json j = minimal();
    j["data"]["train"][0]["root"] = "mydata";
    j["data"]["val"] = json::array({{{"type", "bop"}, {"root", "../elsewhere/x/"}}});
    const std::string file = write_file(dir, "rel.json", j.dump(1));
    const TrainConfig c = load_config(file, {});
    CHECK(c.name == "rel");
    CHECK(c.data.train[0].root == (fs::path(dir) / "mydata").lexically_normal().string());
    CHECK(c.data.val[0].root ==
          (fs::path(dir).parent_path() / "elsewhere" / "x").lexically_normal().string());
    const std::string cwd_rel = fs::relative(testing::fixture_dir()).string();
    CHECK(resolve_config_path(cwd_rel, dir) ==
          fs::absolute(testing::fixture_dir()).lexically_normal().string());
    CHECK(resolve_config_path("/a/b/../c/", dir) == "/a/c");
    CHECK(resolve_config_path("not/here", "/base") == "/base/not/here");
    REQUIRE_THROWS_WITH(resolve_config_path("${HOME}/x", dir),
                        Contains("'${HOME}/x': the only variable allowed"));
    REQUIRE_THROWS_WITH(resolve_config_path("${G2L_SHARED}x", dir),
                        Contains("must be followed by '/'"));
    REQUIRE_THROWS_WITH(resolve_config_path("", dir), Contains("empty path"));
    j["data"]["train"][0]["root"] = "${G2L_SHARED_X}/ycbv";
    REQUIRE_THROWS_WITH(parse(j), Contains("x.json: 'data.train[0].root': ") &&
                                      Contains("${G2L_SHARED_X}/ycbv"));

    // ${G2L_SHARED}: $G2L_SHARED_DATA wins; else <ancestor>/shared/data; else a guess.
    {
        EnvGuard env("G2L_SHARED_DATA", "/opt/shared_here");
        CHECK(resolve_config_path("${G2L_SHARED}/ycbv", dir) == "/opt/shared_here/ycbv");
        CHECK(resolve_config_path("${G2L_SHARED}", dir) == "/opt/shared_here");
        j["data"]["train"][0]["root"] = "${G2L_SHARED}/lmo";
        CHECK(parse(j).data.train[0].root == "/opt/shared_here/lmo");
    }
    {
        EnvGuard env("G2L_SHARED_DATA", nullptr);
        const std::string repo = testing::temp_dir("config_repo");
        fs::create_directories(fs::path(repo) / "shared" / "data");
        fs::create_directories(fs::path(repo) / "main" / "configs");
        CHECK(shared_data_root((fs::path(repo) / "main" / "configs").string()) ==
              (fs::path(repo) / "shared" / "data").string());
    }
}

TEST_CASE("config: every shipped config parses", "[config]") {
    const fs::path configs = fs::path(G2L_SOURCE_DIR) / "configs";
    std::set<std::string> found;
    for (const auto& e : fs::directory_iterator(configs))
        if (e.path().extension() == ".json") found.insert(e.path().stem().string());
    for (const char* name : {"lm_paper", "lm_pose", "lm_ablation", "ycbv", "demo_cpu",
                             "ycbv_sim2real", "ablation_frustum", "ablation_sphere", "ablation_evf",
                             "ablation_fps4", "ablation_fps8", "ablation_fps12", "lmo_detector",
                             "lmo_detector_photo"})
        CHECK(found.count(name) == 1);

    const EnvGuard env("G2L_SHARED_DATA", "/g2l_shared_for_test");
    std::map<std::string, TrainConfig> cfg;
    for (const std::string& name : found) {
        INFO(name);
        const std::string path = (configs / (name + ".json")).string();
        if (is_detector_config(path)) {  // "task": "detector": its own parser, round trip too
            const DetectorTrainConfig d = load_detector_config(path);
            CHECK(d.name == name);
            // --set name= moves the run to runs/<name>, as the pose trainer's, unless run_dir
            // is given.
            CHECK(d.run_dir == "runs/" + name);
            CHECK(load_detector_config(path, {"name=exp7"}).run_dir == "runs/exp7");
            CHECK(load_detector_config(path, {"name=exp7", "run_dir=/tmp/r"}).run_dir == "/tmp/r");
            CHECK(load_detector_config(path, {"run_dir=/tmp/r", "name=exp7"}).run_dir == "/tmp/r");
            CHECK(detector_config_to_json(parse_detector_config(detector_config_to_json(d), path,
                                                                configs.string())) ==
                  detector_config_to_json(d));
            REQUIRE_THROWS_WITH(load_config(path), Catch::Contains("this is a detector config"));
            continue;
        }
        cfg[name] = load_config(path, {});
        CHECK(cfg[name].name == name);
        CHECK(config_to_json(parse_config_text(config_to_json(cfg[name]), path)) ==
              config_to_json(cfg[name]));
    }
    // The ablation rows (issue 26): each is its predecessor with exactly one change (plus name):
    // Table A frustum -> +SP (sphere) -> +EVF -> +RRE (lm_ablation); Table B lm_ablation (BBX-8)
    // -> FPS-4/8/12.
    const std::vector<std::array<std::string, 3>> chain = {
        {"ablation_frustum", "ablation_sphere", "/sampling/crop"},
        {"ablation_sphere", "ablation_evf", "/model/evf"},
        {"ablation_evf", "lm_ablation", "/model/rre"},
        {"lm_ablation", "ablation_fps4", "/model/keypoints"},
        {"lm_ablation", "ablation_fps8", "/model/keypoints"},
        {"lm_ablation", "ablation_fps12", "/model/keypoints"}};
    for (const auto& [from, to, pointer] : chain) {
        INFO(from << " -> " << to);
        const json diff = json::diff(json::parse(config_to_json(cfg.at(from))),
                                     json::parse(config_to_json(cfg.at(to))));
        std::set<std::string> paths;
        for (const auto& d : diff) paths.insert(d["path"].get<std::string>());
        CHECK(paths == std::set<std::string>{"/name", "/run_dir", pointer});
    }
    CHECK(cfg.at("ablation_frustum").sampling.crop == geom::CropKind::frustum);
    CHECK_FALSE(cfg.at("ablation_sphere").model.evf);
    CHECK_FALSE(cfg.at("ablation_sphere").model.rre);
    CHECK(cfg.at("ablation_fps12").model.keypoints == "fps12");
    // Everything the LINEMOD-like runs need is in ../shared: renders of the LM-O meshes, the
    // other LM-O objects as unannotated distractors.
    for (const char* name : {"lm_paper", "lm_pose", "lm_ablation"}) {
        INFO(name);
        const TrainConfig& c = cfg.at(name);
        REQUIRE(c.data.train.size() == 1);
        const SourceConfig& src = c.data.train[0];
        CHECK(src.type == train::SourceType::synthetic);
        CHECK(src.models_root == "/g2l_shared_for_test/lmo");
        CHECK(src.scene.find("distractor_obj_ids") != std::string::npos);
    }
    CHECK(cfg.at("lm_pose").data.object_ids == std::vector<int>{1, 5, 6, 8, 9, 10, 11, 12});
    CHECK(cfg.at("lm_ablation").data.object_ids == std::vector<int>{1, 8});
    const TrainConfig& p = cfg.at("lm_paper");
    CHECK(p.data.object_ids == std::vector<int>{1});
    CHECK(p.sampling.crop == geom::CropKind::sphere);
    CHECK(p.sampling.points == 1500);
    CHECK(p.model.width == 1.0);
    CHECK(p.schedule.kind == "step");
    CHECK(p.train.epochs == 200);

    const TrainConfig& s = cfg.at("ycbv_sim2real");
    CHECK(s.data.object_ids.size() == 21);
    CHECK(s.model.num_classes == 21);
    CHECK(s.model.width == 0.25);
    CHECK(s.model.class_heads);
    CHECK(s.train.batch == 16);
    CHECK(s.train.time_limit_min == 125);
    CHECK(s.model.rot_unit == "kp_rms");
    CHECK(s.loss.symmetric_targets);
    CHECK(s.data.train[0].scene.find("\"resting\"") != std::string::npos);
    REQUIRE(s.data.train.size() == 1);
    CHECK(s.data.train[0].type == train::SourceType::synthetic);
    CHECK(s.data.train[0].models_root == "/g2l_shared_for_test/ycbv");
    REQUIRE(s.data.val.size() == 1);
    CHECK(s.data.val[0].root == "/g2l_shared_for_test/ycbv");
    CHECK(s.data.val[0].split == "train_real");

    // The demo's data ship with the repository: its paths must exist.
    const TrainConfig& d = cfg.at("demo_cpu");
    CHECK(d.model.width == 0.25);
    CHECK(d.sampling.points == 300);
    CHECK(d.sampling.seg_points == 200);
    const std::string mini = fs::absolute(mini_root()).lexically_normal().string();
    REQUIRE(d.data.train.size() == 1);
    CHECK(d.data.train[0].models_root == mini);
    CHECK(fs::is_regular_file(fs::path(mini) / "models" / "models_info.json"));
    REQUIRE(d.data.val.size() == 1);
    CHECK(d.data.val[0].root == mini);
    CHECK(fs::is_directory(fs::path(mini) / d.data.val[0].split / "000000"));
}
