// SPDX-License-Identifier: MIT
// g2l_rotstudy: learning curves of G2L-Net's rotation blocks alone (keypoint error on renders
// against samples seen), one factor at a time. docs/experiments.md lists the runs.
#include <CLI/CLI.hpp>

#include "core/cli.h"
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/threads.h"
#include "data/bop.h"
#include "data/scene.h"
#include "geometry/keypoints.h"
#include "geometry/metrics.h"
#include "geometry/symmetry.h"
#include "tools/rot_study.h"
#include "train/sources.h"

using namespace g2l;
using json = nlohmann::json;

int main(int argc, char** argv) {
    CLI::App app{"g2l_rotstudy: train G2L-Net's rotation blocks alone on ground-truth-segmented "
                 "points of synthetic renders and print the learning curve (keypoint and "
                 "rotation error on held-out renders against samples seen)"};
    std::string models_root, scene_json = "{}", out_json, keypoints_kind = "bbx8";
    std::vector<int> objects{5};
    tools::RotStudyConfig c;
    int pool = 0, val_n = 100, threads = 0, crop_points = 1024;
    bool noise = false, val_on_pool = false;
    double min_visib = 0, val_min_visib = 0;
    app.add_option("--models", models_root, "BOP root whose models/ are rendered")->required();
    app.add_option("--objects", objects, "object ids (default 5)")->delimiter(',');
    app.add_option("--scene", scene_json, "scene config JSON (data/scene.h keys) for the renders");
    app.add_flag("--noise", noise, "sensor noise on (default: noise-free renders)");
    app.add_option("--pool", pool, "render this many training samples once and draw from them "
                                   "(0 = a fresh render for every sample)");
    app.add_option("--val", val_n, "held-out validation samples");
    app.add_option("--min-visib", min_visib, "training instances less visible than this fraction "
                                             "give no sample (sampling.min_visib_fract)")
        ->check(CLI::Range(0.0, 1.0));
    app.add_option("--val-min-visib", val_min_visib, "the same floor for the validation renders "
                                                     "(their errors are also reported per "
                                                     "visibility bucket)")
        ->check(CLI::Range(0.0, 1.0));
    app.add_flag("--val-on-pool", val_on_pool, "validate on the training pool (how well it fits)");
    app.add_option("--steps", c.steps, "optimiser steps");
    app.add_option("--batch", c.batch, "samples per step");
    app.add_option("--points", c.points, "object points per sample (rotation input)");
    app.add_option("--crop-points", crop_points, "points per crop before the object points are taken");
    app.add_option("--eval-every", c.eval_every, "steps between validations");
    app.add_option("--lr", c.lr, "Adam base learning rate");
    app.add_option("--lr-decay-every", c.lr_decay_every,
                   "multiply the lr by --lr-decay-factor every this many steps (0 = constant)");
    app.add_option("--lr-decay-factor", c.lr_decay_factor, "step-decay factor of the lr")
        ->check(CLI::Range(1e-6, 1.0));
    app.add_option("--mult-evf", c.mult_evf, "lr multiplier of block A");
    app.add_option("--mult-rot", c.mult_rot, "lr multiplier of block B");
    app.add_option("--mult-rre", c.mult_rre, "lr multiplier of block C");
    app.add_option("--width", c.width, "network width multiplier");
    app.add_option("--dropout", c.dropout, "dropout before the last layer of A and B");
    app.add_option("--bn-momentum", c.bn_momentum, "BatchNorm momentum");
    app.add_option("--unit", c.rot_unit, "rotation unit: mm | kp_rms");
    app.add_option("--out-scale", c.out_scale_mm, "out_scale_mm (unit mm only)");
    app.add_option("--evf", c.evf, "block A on (1) or off (0)");
    app.add_option("--rre", c.rre, "block C on (1) or off (0)");
    app.add_option("--w-vec", c.weights.vec, "loss weight of block A");
    app.add_option("--w-kp", c.weights.kp, "loss weight of block B");
    app.add_option("--w-res", c.weights.res, "loss weight of block C");
    app.add_option("--centre-noise", c.centre_noise_mm, "centring error std-dev per axis (mm)");
    app.add_option("--symmetric", c.symmetric, "min-over-symmetries targets (1/0)");
    app.add_option("--keypoints", keypoints_kind, "bbx8 | fps4 | fps8 | fps12");
    app.add_option("--seed", c.seed, "seed");
    app.add_option("--class-heads", c.class_heads, "one output block per class in blocks A/B/C (1/0)");
    app.add_option("--zero-last", c.zero_last_layers, "zero-initialise the last layers of A/B/C (1/0)");
    app.add_option("--threads", threads, "CPU threads (0 = all)");
    app.add_option("--json", out_json, "write the curve as JSON here");
    bool verbose = false;
    app.add_flag("--verbose", verbose, "error messages with their source location (also G2L_VERBOSE=1)");
    if (const int rc = g2l::cli::parse(app, argc, argv, "g2l_rotstudy"); rc >= 0) return rc;
    try {
        if (threads > 0) set_num_threads(threads);
        data::BopOptions bo;
        bo.obj_ids = objects;
        const data::Dataset ds = data::open_bop_models(models_root, bo);
        std::map<int, train::SampleModel> models;
        std::map<int, int> cls;
        std::vector<data::SceneModel> scene_models;
        train::KeypointTable kps;
        std::vector<double> diam;
        for (size_t i = 0; i < objects.size(); ++i) {
            const int id = objects[i];
            G2L_CHECK(ds.models().count(id), "--objects: no model ", id, " in ", models_root);
            const geom::Mesh& mesh = ds.load_model_mesh(id);
            models[id] = {&mesh, ds.models().at(id).info};
            cls[id] = int(i);
            scene_models.push_back({id, &mesh});
            const geom::Points kp = geom::keypoints(mesh, ds.models().at(id).info, keypoints_kind);
            std::vector<Eigen::Vector3f> v;
            for (int64_t k = 0; k < kp.rows(); ++k) v.push_back(kp.row(k).transpose());
            kps.push_back(v);
            diam.push_back(ds.models().at(id).info.diameter);
        }
        train::SampleConfig sc;
        sc.points = crop_points;
        sc.augment = false;
        sc.center_jitter_mm = 0;
        sc.box_jitter_frac = 0;
        const train::SampleMaker maker(sc, models, cls);
        train::SymmetricKeypoints sym(objects.size());
        for (size_t i = 0; i < objects.size(); ++i) {
            const auto syms = geom::geometric_symmetries(maker.tree(objects[i]), maker.info(objects[i]));
            for (const auto& s : syms) {
                std::vector<Eigen::Vector3f> set;
                for (const auto& p : kps[i]) set.push_back(s.R * p + s.t);
                sym[i].push_back(std::move(set));
            }
            std::printf("object %d: diameter %.1f mm, %zu geometric symmetries, unit %.1f mm\n",
                        objects[i], diam[i], syms.size(), nn::rotation_scale(c.rot_unit, kps[i]));
        }
        data::SceneConfig scene = data::parse_scene_config(scene_json, "--scene");
        if (!noise) scene.noise.enabled = false;
        scene.targets_min = scene.targets_max = std::max(1, scene.targets_min);
        data::SceneConfig vscene = scene;
        vscene.seed = scene.seed + 7777;
        auto src = std::make_unique<train::SyntheticSource>(scene, scene_models, maker,
                                                            int64_t(1) << 40, 0, min_visib);
        train::SyntheticSource vsrc(vscene, scene_models, maker, int64_t(1) << 40, 0,
                                    val_min_visib);
        std::vector<train::PoseSample> val;
        std::vector<double> val_visib;  // rendered visible fraction of each validation sample
        for (int64_t i = 0; int(val.size()) < val_n && i < int64_t(val_n) * 20; ++i) {
            Rng r(uint64_t(i) + 99);
            train::PoseSample s;
            if (vsrc.get(i * scene.targets_max, r, &s)) {
                val.push_back(std::move(s));
                const int64_t idx = i * scene.targets_max;
                val_visib.push_back(vsrc.frame(vsrc.frame_of(idx))
                                        .instances[size_t(vsrc.instance_of(idx))]
                                        .visib_fract);
            }
        }
        // Visibility buckets of the validation samples: [0, 0.3), [0.3, 0.7), [0.7, 1].
        const double edges[4] = {0, 0.3, 0.7, 1.0001};
        int bucket_n[3] = {0, 0, 0};
        for (double v : val_visib)
            for (int b = 0; b < 3; ++b) bucket_n[b] += v >= edges[b] && v < edges[b + 1];
        std::printf("validation visibility buckets <0.3 / 0.3-0.7 / >=0.7: %d / %d / %d samples\n",
                    bucket_n[0], bucket_n[1], bucket_n[2]);
        std::vector<train::PoseSample> pooled;
        for (int64_t i = 0; int(pooled.size()) < pool && i < int64_t(pool) * 20; ++i) {
            Rng r(uint64_t(i) + 7);
            train::PoseSample s;
            if (src->get(i * scene.targets_max, r, &s)) pooled.push_back(std::move(s));
        }
        if (val_on_pool) {
            G2L_CHECK(!pooled.empty(), "--val-on-pool needs --pool > 0");
            val = pooled;
        }
        std::printf("%zu validation samples, %s\n", val.size(),
                    pool > 0 ? ("pool of " + std::to_string(pooled.size()) + " training samples").c_str()
                             : "fresh training renders");
        std::fflush(stdout);
        Rng pick(c.seed * 31 + 5);
        const tools::SampleDraw draw = [&](int64_t i, train::PoseSample* out) {
            if (pool > 0) {
                *out = pooled[pick.below(pooled.size())];
                return true;
            }
            Rng r(uint64_t(i) * 2654435761ull + c.seed);
            return src->get(i * scene.targets_max, r, out);
        };
        std::printf("%6s %8s %7s %12s %10s %9s %11s %10s %8s\n", "step", "samples", "sec",
                    "train_kp_mm", "val_kp_mm", "val_kp/d", "rot_med_deg", "rot_mean", "acc10");
        json curve = json::array();
        tools::rot_study(c, int(objects.size()), kps, diam, &sym, draw, val,
                         [&](const tools::RotStudyPoint& p) {
                             std::printf("%6d %8lld %7.1f %12.2f %10.2f %9.3f %11.1f %10.1f %8.3f\n",
                                         p.step, (long long)p.samples, p.seconds, p.train_kp_err_mm,
                                         p.val_kp_err_mm, p.val_kp_err_frac,
                                         p.val_rot_err_deg_median, p.val_rot_err_deg_mean,
                                         p.val_acc_10deg);
                             json buckets = json::array();
                             if (!val_on_pool && p.val_kp_err_frac_each.size() == val_visib.size()) {
                                 std::printf("        by visibility <0.3 / 0.3-0.7 / >=0.7: kp/d");
                                 std::string rot_line;
                                 for (int b = 0; b < 3; ++b) {
                                     std::vector<double> kp, rot;
                                     for (size_t k = 0; k < val_visib.size(); ++k)
                                         if (val_visib[k] >= edges[b] && val_visib[k] < edges[b + 1]) {
                                             kp.push_back(p.val_kp_err_frac_each[k]);
                                             rot.push_back(p.val_rot_err_deg_each[k]);
                                         }
                                     double mkp = 0;
                                     for (double e : kp) mkp += e;
                                     mkp = kp.empty() ? 0 : mkp / double(kp.size());
                                     const double mrot = rot.empty() ? 0 : geom::median(rot);
                                     std::printf(" %.3f", mkp);
                                     rot_line += " " + std::to_string(int(std::lround(mrot)));
                                     buckets.push_back({{"visib_min", edges[b]},
                                                        {"visib_max", std::min(1.0, edges[b + 1])},
                                                        {"n", kp.size()},
                                                        {"val_kp_err_frac", mkp},
                                                        {"val_rot_err_deg_median", mrot}});
                                 }
                                 std::printf(", rot median deg%s\n", rot_line.c_str());
                             }
                             // Per object (several objects only): mean kp/d and median rotation.
                             json by_object = json::array();
                             if (objects.size() > 1 && p.val_kp_err_frac_each.size() == val.size()) {
                                 std::printf("        by object (id kp/d rot_med):");
                                 for (size_t o = 0; o < objects.size(); ++o) {
                                     std::vector<double> rot;
                                     double mkp = 0;
                                     for (size_t k = 0; k < val.size(); ++k)
                                         if (val[k].class_index == int(o)) {
                                             mkp += p.val_kp_err_frac_each[k];
                                             rot.push_back(p.val_rot_err_deg_each[k]);
                                         }
                                     mkp = rot.empty() ? 0 : mkp / double(rot.size());
                                     const double mrot = rot.empty() ? 0 : geom::median(rot);
                                     std::printf("  %d %.3f %.0f", objects[o], mkp, mrot);
                                     by_object.push_back({{"obj_id", objects[o]}, {"n", rot.size()},
                                                          {"val_kp_err_frac", mkp},
                                                          {"val_rot_err_deg_median", mrot}});
                                 }
                                 std::printf("\n");
                             }
                             std::fflush(stdout);
                             curve.push_back({{"step", p.step}, {"samples", p.samples},
                                              {"by_visibility", buckets}, {"by_object", by_object},
                                              {"seconds", p.seconds},
                                              {"train_kp_err_mm", p.train_kp_err_mm},
                                              {"val_kp_err_mm", p.val_kp_err_mm},
                                              {"val_kp_err_frac", p.val_kp_err_frac},
                                              {"val_rot_err_deg_median", p.val_rot_err_deg_median},
                                              {"val_rot_err_deg_mean", p.val_rot_err_deg_mean},
                                              {"val_acc_10deg", p.val_acc_10deg}});
                             if (p.step == c.steps) {  // the last point: every sample's errors
                                 json each = json::array();
                                 for (size_t k = 0; k < p.val_rot_err_deg_each.size() && k < val.size(); ++k)
                                     each.push_back({objects[size_t(val[k].class_index)],
                                                     p.val_kp_err_frac_each[k],
                                                     p.val_rot_err_deg_each[k]});
                                 curve.back()["val_each_obj_kpfrac_rotdeg"] = each;
                             }
                         });
        if (!out_json.empty()) std::ofstream(out_json) << curve.dump(1) << "\n";
        return 0;
    } catch (const std::exception& e) {
        return g2l::cli::report("g2l_rotstudy", e, verbose);
    }
}
