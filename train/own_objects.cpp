// SPDX-License-Identifier: MIT
#include "train/own_objects.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "data/bop.h"
#include "data/bop_writer.h"
#include "geometry/labels.h"
#include "geometry/mesh_io.h"
#include "geometry/model_info.h"
#include "geometry/symmetry.h"
#include "train/config.h"
#include "train/detector_train.h"
#include "train/model_io.h"
#include "train/trainer.h"

namespace g2l::train {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

// BOP's symmetries_discrete: each non-identity symmetry as a row-major 4x4 transform (mm).
std::string symmetries_json(const std::vector<geom::SymmetryTransform>& syms) {
    json list = json::array();
    for (size_t k = 1; k < syms.size(); ++k) {  // [0] is the identity
        const auto& s = syms[k];
        json m = json::array();
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) m.push_back(double(s.R(r, c)));
            m.push_back(double(s.t[r]));
        }
        for (double v : {0.0, 0.0, 0.0, 1.0}) m.push_back(v);
        list.push_back(m);
    }
    return list.empty() ? std::string() : json{{"symmetries_discrete", list}}.dump();
}

// The renders both trainings see: the objects resting on a table among unannotated blocks,
// some standing, leaning or on a block (configs/scenes/ycbv_table_blocks.json), seen from
// 0.5-1.3 m; `camera`: the user's.
data::SceneConfig recipe_scene(const geom::Intrinsics& camera, int objects, uint64_t seed) {
    data::SceneConfig s;
    s.camera = camera;
    s.pose_mode = "resting";
    s.targets_min = 1;
    s.targets_max = std::max(1, std::min(objects, 6));
    s.unique_targets = true;
    s.distractors_min = s.distractors_max = 0;
    s.separation = 0.6;
    s.random_background = s.random_light = true;
    s.noise.enabled = true;
    s.noise.sigma_a_mm = 0.5;
    s.noise.sigma_b_mm_per_m2 = 2.0;
    s.noise.holes_max = 3;
    s.camera_distance = {{500, 1300}};
    s.camera_elevation = {{15, 80}};
    s.camera_roll_max = 10;
    s.table_spread_mm = 200;
    s.look_at_jitter_mm = 60;
    s.table_size_mm = 3000;
    s.upright_prob = 0.3;
    s.tall_prob = 0.15;
    s.blocks_min = 0;
    s.blocks_max = 2;
    s.block_size_mm = {{40, 220}};
    s.on_block_prob = 0.15;
    s.lean_prob = 0.15;
    s.lean_max_deg = 35;
    s.seed = seed;
    return s;
}

// The depth detector of configs/ycbv_detector.json on these objects, for `minutes`.
DetectorTrainConfig detector_recipe(const std::string& root, const std::vector<int>& ids,
                                    const geom::Intrinsics& camera, double minutes) {
    DetectorTrainConfig c;
    c.name = "detector";
    c.run_dir = (fs::path(root) / "detector_run").string();
    c.models_root = root;
    c.object_ids = ids;
    c.input = nn::DetectorInput::depth;
    c.downscale = 2;
    c.scene = recipe_scene(camera, int(ids.size()), 4243);
    c.color_jitter = c.noise_std = c.blur_prob = c.gray_prob = c.clutter_prob = 0;
    c.occluder_prob = 0.15;
    c.width = 16;
    c.lr = 2e-3;
    c.steps = 1000000;  // the time limit ends it; the schedule follows the time
    c.batch = 8;
    c.checkpoint_every = 100;
    c.log_every = 10;
    c.time_limit_min = minutes;
    c.time_schedule = true;
    return c;
}

// The pose model of configs/ycbv_sim2real.json on these objects, for `minutes`: 60 % of the
// run trains the rotation blocks alone (on ground-truth points, ~2x the samples per minute),
// one epoch's share with ground-truth points, then everything jointly; the learning rate
// halves at 40 % and 80 % — shares of the time, whatever the machine's speed.
TrainConfig pose_recipe(const std::string& root, const std::vector<int>& ids,
                        const geom::Intrinsics& camera, double minutes) {
    TrainConfig c;
    c.name = "pose";
    c.run_dir = (fs::path(root) / "pose_run").string();
    c.data.object_ids = ids;
    SourceConfig src;
    src.type = SourceType::synthetic;
    src.models_root = root;
    src.frames = 1000;
    data::SceneConfig scene = recipe_scene(camera, int(ids.size()), 2024);
    scene.blocks_max = 1;
    src.scene = data::scene_config_to_json(scene);
    c.data.train = {src};
    c.sampling.points = 1024;
    c.sampling.seg_points = 512;
    c.model.num_classes = int(ids.size());
    c.model.width = 0.25;
    c.model.dropout = 0;
    c.model.class_heads = true;
    c.loss.symmetric_targets = true;
    c.loss.rot_centre_noise_mm = 8;
    c.train.epochs = 30;
    c.loss.rot_only_epochs = 18;
    c.loss.rot_gt_points_epochs = 1;
    c.optim.lr_mult.rot = c.optim.lr_mult.rre = 1;
    c.schedule.step_epochs = 12;
    c.train.batch = 16;
    c.train.samples_per_epoch = 2000;
    c.train.checkpoint_every = 0;
    c.train.val_every = 0;
    c.train.time_limit_min = minutes;
    c.train.time_schedule = true;
    c.train.log_every = 25;
    return c;
}

double minutes_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / 60.0;
}

}  // namespace

std::vector<OwnObject> prepare_own_models(const std::string& dir, const std::string& root,
                                          std::vector<std::string>* notes) {
    std::error_code ec;
    G2L_CHECK(fs::is_directory(dir, ec), "--objects: '", dir, "' is not a folder");
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
        std::string ext = e.path().extension().string();
        std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
        if (e.is_regular_file() && (ext == ".ply" || ext == ".obj")) files.push_back(e.path());
    }
    std::sort(files.begin(), files.end());
    G2L_CHECK(!files.empty(), "--objects: folder '", dir, "' holds no .ply or .obj mesh");
    std::vector<std::string> names;
    for (const fs::path& f : files) names.push_back(f.string());
    std::map<int, fs::path> by_id;
    const std::vector<int> ids = data::mesh_file_ids(names);  // throws for two files of one id
    for (size_t i = 0; i < files.size(); ++i) by_id[ids[i]] = files[i];
    std::vector<OwnObject> out;
    std::vector<std::unique_ptr<geom::Mesh>> meshes;
    std::vector<data::SceneModel> models;
    for (const auto& [id, f] : by_id) {
        auto mesh = std::make_unique<geom::Mesh>(geom::load_mesh(f.string()));
        OwnObject o;
        o.obj_id = id;
        o.source = f.string();
        o.name = f.stem().string();
        G2L_CHECK(mesh->vertices.rows() > 0 && mesh->faces.rows() > 0, "--objects: mesh '",
                  o.source, "' has no faces");
        geom::ModelInfo mi = geom::compute_model_info(mesh->vertices);
        if (mi.diameter < geom::kMetreMeshBelow) {
            mesh->vertices *= 1000.f;
            o.converted_from_m = true;
            if (notes)
                notes->push_back(cat("'", o.source, "' is ", mi.diameter, " units across: taken "
                                     "as metres, scaled by 1000 to ", 1000 * mi.diameter, " mm"));
        }
        mesh->path = o.source;
        mi = geom::check_mesh_units(*mesh, nullptr);  // still under it in mm: refused, naming it
        o.diameter_mm = mi.diameter;
        const geom::ModelKdTree tree = geom::ModelKdTree::from_mesh(*mesh);
        const auto syms = geom::geometric_symmetries(tree, mi);
        o.symmetries = int(syms.size());
        models.push_back({id, mesh.get(), symmetries_json(syms)});
        meshes.push_back(std::move(mesh));
        out.push_back(o);
    }
    data::write_bop_models((fs::path(root) / "models").string(), models);
    std::map<int, std::string> obj_names;
    for (const OwnObject& o : out) obj_names[o.obj_id] = o.name;
    data::write_obj_names(root, obj_names);
    return out;
}

OwnObjectsSummary run_own_objects(const OwnObjectsOptions& opt) {
    const auto t0 = std::chrono::steady_clock::now();
    G2L_CHECK(std::isfinite(opt.minutes) && opt.minutes > 0, "--minutes must be > 0, got ",
              opt.minutes);
    G2L_CHECK(opt.detector_share > 0 && opt.detector_share < 1,
              "detector_share must be in (0, 1), got ", opt.detector_share);
    G2L_CHECK(!opt.out_dir.empty(), "--objects needs --out RUN (the folder to write)");
    std::error_code ec;
    if (fs::exists(opt.out_dir, ec)) {
        G2L_CHECK(fs::is_directory(opt.out_dir, ec), "--out '", opt.out_dir, "' is not a folder");
        G2L_CHECK(opt.force || fs::is_empty(opt.out_dir, ec), "--out '", opt.out_dir,
                  "' already holds files: give another folder, or --force to start over there "
                  "(each training's folder, RUN/detector_run and RUN/pose_run, continues with "
                  "g2l_train --resume)");
    }
    fs::create_directories(opt.out_dir, ec);
    G2L_CHECK(!ec, "cannot create '", opt.out_dir, "': ", ec.message());
    const std::string root = fs::absolute(opt.out_dir).lexically_normal().string();
    geom::Intrinsics camera = data::SceneConfig{}.camera;
    if (!opt.camera.empty()) {
        const data::CameraFile cf = data::load_camera_file(opt.camera);
        G2L_CHECK(cf.width > 0 && cf.height > 0, "--camera '", opt.camera,
                  "' gives no image size (width, height): the renders need it");
        camera = {cf.fx, cf.fy, cf.cx, cf.cy, cf.width, cf.height};
    }

    OwnObjectsSummary sum;
    std::vector<std::string> notes;
    sum.objects = prepare_own_models(opt.objects_dir, root, &notes);
    sum.models = (fs::path(root) / "models").string();
    if (opt.progress) {
        for (const std::string& n : notes) std::fprintf(stderr, "g2l_train: note: %s\n", n.c_str());
        for (const OwnObject& o : sum.objects)
            std::fprintf(stderr, "g2l_train: object %d = %s (%.1f mm across, %d symmetr%s)\n",
                         o.obj_id, o.name.c_str(), o.diameter_mm, o.symmetries,
                         o.symmetries == 1 ? "y: none but the identity" : "ies");
    }
    std::vector<int> ids;
    for (const OwnObject& o : sum.objects) ids.push_back(o.obj_id);

    // The budget: what is left after the models, less a margin for the exports and the
    // last checkpoints, split between the two trainings.
    const double left = std::max(0.05, opt.minutes * 0.97 - minutes_since(t0) - 0.1);
    DetectorTrainConfig dcfg = detector_recipe(root, ids, camera, left * opt.detector_share);
    TrainOptions to;
    to.max_steps = opt.max_steps;
    to.progress = opt.progress;
    to.force = true;  // RUN was checked above
    to.stop_flag = opt.stop_flag;
    write_file_atomic((fs::path(root) / "detector.json").string(),
                      detector_config_to_json(dcfg));
    if (opt.progress)
        std::fprintf(stderr, "g2l_train: 1/2 the detector, %.1f min (%s)\n", dcfg.time_limit_min,
                     dcfg.run_dir.c_str());
    const DetectorTrainSummary ds = run_detector_training(dcfg, to);
    if (ds.interrupted) {
        sum.interrupted = true, sum.interrupted_run = ds.run_dir, sum.interrupted_steps = ds.steps;
        return sum;
    }
    sum.detector = (fs::path(root) / "detector.g2l").string();
    fs::copy_file(fs::path(dcfg.run_dir) / "detector.g2l", sum.detector,
                  fs::copy_options::overwrite_existing, ec);
    G2L_CHECK(!ec, "cannot copy the detector export to '", sum.detector, "': ", ec.message());

    // The pose model gets whatever the detector left (it may have stopped early).
    const double pose_min = std::max(0.05, opt.minutes * 0.97 - minutes_since(t0) - 0.05);
    TrainConfig pcfg = pose_recipe(root, ids, camera, pose_min);
    validate(pcfg, "the pose recipe");
    write_file_atomic((fs::path(root) / "pose.json").string(), config_to_json(pcfg));
    if (opt.progress)
        std::fprintf(stderr, "g2l_train: 2/2 the pose model, %.1f min (%s)\n", pose_min,
                     pcfg.run_dir.c_str());
    const TrainSummary ps = run_training(pcfg, to);
    if (ps.interrupted) {
        sum.interrupted = true, sum.interrupted_run = ps.run_dir, sum.interrupted_steps = ps.steps;
        return sum;
    }
    sum.pose = (fs::path(root) / "pose.g2l").string();
    export_model((fs::path(pcfg.run_dir) / "last.g2l").string(), sum.pose);
    sum.minutes = minutes_since(t0);
    return sum;
}

}  // namespace g2l::train
