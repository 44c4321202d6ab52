// SPDX-License-Identifier: MIT
// g2l_rotstudy: learning curves of G2L-Net's rotation blocks alone (keypoint error on renders
// against samples seen), one factor at a time. docs/experiments.md lists the runs.
#include <CLI/CLI.hpp>

#include "core/cli.h"
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
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

namespace {

// Everything the command line sets.
struct Job {
    std::string models_root, scene_json = "{}", out_json, keypoints_kind = "bbx8";
    std::vector<int> objects{5};
    tools::RotStudyConfig c;
    int pool = 0, val_n = 100, threads = 0, crop_points = 1024;
    bool noise = false, val_on_pool = false, verbose = false;
    double min_visib = 0, val_min_visib = 0;
};

void add_options(CLI::App& app, Job& j) {
    tools::RotStudyConfig& c = j.c;
    app.add_option("--models", j.models_root, "BOP root whose models/ are rendered")->required();
    app.add_option("--objects", j.objects, "object ids (default 5)")->delimiter(',');
    app.add_option("--scene", j.scene_json, "scene config JSON (data/scene.h keys) for the renders");
    app.add_flag("--noise", j.noise, "sensor noise on (default: noise-free renders)");
    app.add_option("--pool", j.pool, "render this many training samples once and draw from them "
                                     "(0 = a fresh render for every sample)");
    app.add_option("--val", j.val_n, "held-out validation samples");
    app.add_option("--min-visib", j.min_visib, "training instances less visible than this "
                                               "fraction give no sample (sampling.min_visib_fract)")
        ->check(CLI::Range(0.0, 1.0));
    app.add_option("--val-min-visib", j.val_min_visib, "the same floor for the validation renders "
                                                       "(their errors are also reported per "
                                                       "visibility bucket)")
        ->check(CLI::Range(0.0, 1.0));
    app.add_flag("--val-on-pool", j.val_on_pool, "validate on the training pool (how well it fits)");
    app.add_option("--steps", c.steps, "optimiser steps");
    app.add_option("--batch", c.batch, "samples per step");
    app.add_option("--points", c.points, "object points per sample (rotation input)");
    app.add_option("--crop-points", j.crop_points, "points per crop before the object points are taken");
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
    app.add_option("--keypoints", j.keypoints_kind, "bbx8 | fps4 | fps8 | fps12");
    app.add_option("--seed", c.seed, "seed");
    app.add_option("--class-heads", c.class_heads, "one output block per class in blocks A/B/C (1/0)");
    app.add_option("--zero-last", c.zero_last_layers, "zero-initialise the last layers of A/B/C (1/0)");
    app.add_option("--threads", j.threads, "CPU threads (0 = all)");
    app.add_option("--json", j.out_json, "write the curve as JSON here");
    app.add_flag("--verbose", j.verbose, "error messages with their source location (also G2L_VERBOSE=1)");
}

// The objects: meshes, keypoints, diameters, the sample maker and the symmetric keypoint sets.
struct Objects {
    data::Dataset ds;
    std::map<int, train::SampleModel> models;
    std::map<int, int> cls;
    std::vector<data::SceneModel> scene_models;
    train::KeypointTable kps;
    std::vector<double> diam;
    std::unique_ptr<train::SampleMaker> maker;
    train::SymmetricKeypoints sym;

    explicit Objects(const Job& j) : ds(data::open_bop_models(j.models_root, [&] {
                                         data::BopOptions bo;
                                         bo.obj_ids = j.objects;
                                         return bo;
                                     }())) {
        for (size_t i = 0; i < j.objects.size(); ++i) {
            const int id = j.objects[i];
            G2L_CHECK(ds.models().count(id), "--objects: no model ", id, " in ", j.models_root);
            const geom::Mesh& mesh = ds.load_model_mesh(id);
            models[id] = {&mesh, ds.models().at(id).info};
            cls[id] = int(i);
            scene_models.push_back({id, &mesh});
            const geom::Points kp = geom::keypoints(mesh, ds.models().at(id).info, j.keypoints_kind);
            std::vector<Eigen::Vector3f> v;
            for (int64_t k = 0; k < kp.rows(); ++k) v.push_back(kp.row(k).transpose());
            kps.push_back(v);
            diam.push_back(ds.models().at(id).info.diameter);
        }
        train::SampleConfig sc;
        sc.points = j.crop_points;
        sc.augment = false;
        sc.center_jitter_mm = 0;
        sc.box_jitter_frac = 0;
        maker = std::make_unique<train::SampleMaker>(sc, models, cls);
        sym.resize(j.objects.size());
        for (size_t i = 0; i < j.objects.size(); ++i) {
            const auto syms = geom::geometric_symmetries(maker->tree(j.objects[i]), maker->info(j.objects[i]));
            for (const auto& s : syms) {
                std::vector<Eigen::Vector3f> set;
                for (const auto& p : kps[i]) set.push_back(s.R * p + s.t);
                sym[i].push_back(std::move(set));
            }
            std::printf("object %d: diameter %.1f mm, %zu geometric symmetries, unit %.1f mm\n",
                        j.objects[i], diam[i], syms.size(), nn::rotation_scale(j.c.rot_unit, kps[i]));
        }
    }
};

// Visibility buckets of the validation samples: [0, 0.3), [0.3, 0.7), [0.7, 1].
constexpr double kEdges[4] = {0, 0.3, 0.7, 1.0001};

// The training renders (fresh or a pool) and the held-out validation samples.
struct Samples {
    data::SceneConfig scene;
    std::unique_ptr<train::SyntheticSource> src;
    std::vector<train::PoseSample> val, pooled;
    std::vector<double> val_visib;  // rendered visible fraction of each validation sample

    Samples(const Job& j, const Objects& o) : scene(data::parse_scene_config(j.scene_json, "--scene")) {
        if (!j.noise) scene.noise.enabled = false;
        scene.targets_min = scene.targets_max = std::max(1, scene.targets_min);
        data::SceneConfig vscene = scene;
        vscene.seed = scene.seed + 7777;
        src = std::make_unique<train::SyntheticSource>(scene, o.scene_models, *o.maker,
                                                       int64_t(1) << 40, 0, j.min_visib);
        train::SyntheticSource vsrc(vscene, o.scene_models, *o.maker, int64_t(1) << 40, 0,
                                    j.val_min_visib);
        for (int64_t i = 0; int(val.size()) < j.val_n && i < int64_t(j.val_n) * 20; ++i) {
            Rng r(uint64_t(i) + 99);
            train::PoseSample s;
            const int64_t idx = i * scene.targets_max;
            if (!vsrc.get(idx, r, &s)) continue;
            val.push_back(std::move(s));
            val_visib.push_back(vsrc.frame(vsrc.frame_of(idx)).instances[size_t(vsrc.instance_of(idx))]
                                    .visib_fract);
        }
        int bucket_n[3] = {0, 0, 0};
        for (double v : val_visib)
            for (int b = 0; b < 3; ++b) bucket_n[b] += v >= kEdges[b] && v < kEdges[b + 1];
        std::printf("validation visibility buckets <0.3 / 0.3-0.7 / >=0.7: %d / %d / %d samples\n",
                    bucket_n[0], bucket_n[1], bucket_n[2]);
        for (int64_t i = 0; int(pooled.size()) < j.pool && i < int64_t(j.pool) * 20; ++i) {
            Rng r(uint64_t(i) + 7);
            train::PoseSample s;
            if (src->get(i * scene.targets_max, r, &s)) pooled.push_back(std::move(s));
        }
        if (j.val_on_pool) {
            G2L_CHECK(!pooled.empty(), "--val-on-pool needs --pool > 0");
            val = pooled;
        }
        std::printf("%zu validation samples, %s\n", val.size(),
                    j.pool > 0 ? ("pool of " + std::to_string(pooled.size()) + " training samples").c_str()
                               : "fresh training renders");
        std::fflush(stdout);
    }
};

// Mean keypoint error / diameter and median rotation error of the validation samples `keep`
// selects, printed and returned as JSON.
json subset(const tools::RotStudyPoint& p, size_t n, const std::function<bool(size_t)>& keep) {
    std::vector<double> rot;
    double mkp = 0;
    for (size_t k = 0; k < n; ++k)
        if (keep(k)) {
            mkp += p.val_kp_err_frac_each[k];
            rot.push_back(p.val_rot_err_deg_each[k]);
        }
    mkp = rot.empty() ? 0 : mkp / double(rot.size());
    return {{"n", rot.size()}, {"val_kp_err_frac", mkp},
            {"val_rot_err_deg_median", rot.empty() ? 0 : geom::median(rot)}};
}

// One point of the curve: its table row, the errors per visibility bucket and per object, and
// its JSON record.
json report_point(const Job& j, const Samples& sm, const tools::RotStudyPoint& p) {
    std::printf("%6d %8lld %7.1f %12.2f %10.2f %9.3f %11.1f %10.1f %8.3f\n", p.step,
                (long long)p.samples, p.seconds, p.train_kp_err_mm, p.val_kp_err_mm,
                p.val_kp_err_frac, p.val_rot_err_deg_median, p.val_rot_err_deg_mean, p.val_acc_10deg);
    json buckets = json::array(), by_object = json::array();
    const std::vector<double>& vv = sm.val_visib;
    if (!j.val_on_pool && p.val_kp_err_frac_each.size() == vv.size()) {
        std::string kp_line, rot_line;
        for (int b = 0; b < 3; ++b) {
            json e = subset(p, vv.size(), [&](size_t k) { return vv[k] >= kEdges[b] && vv[k] < kEdges[b + 1]; });
            char text[32];
            std::snprintf(text, sizeof text, " %.3f", e["val_kp_err_frac"].get<double>());
            kp_line += text;
            rot_line += " " + std::to_string(std::lround(e["val_rot_err_deg_median"].get<double>()));
            e["visib_min"] = kEdges[b];
            e["visib_max"] = std::min(1.0, kEdges[b + 1]);
            buckets.push_back(e);
        }
        std::printf("        by visibility <0.3 / 0.3-0.7 / >=0.7: kp/d%s, rot median deg%s\n",
                    kp_line.c_str(), rot_line.c_str());
    }
    if (j.objects.size() > 1 && p.val_kp_err_frac_each.size() == sm.val.size()) {
        std::printf("        by object (id kp/d rot_med):");
        for (size_t o = 0; o < j.objects.size(); ++o) {
            json e = subset(p, sm.val.size(), [&](size_t k) { return sm.val[k].class_index == int(o); });
            std::printf("  %d %.3f %.0f", j.objects[o], e["val_kp_err_frac"].get<double>(),
                        e["val_rot_err_deg_median"].get<double>());
            e["obj_id"] = j.objects[o];
            by_object.push_back(e);
        }
        std::printf("\n");
    }
    std::fflush(stdout);
    json rec = {{"step", p.step}, {"samples", p.samples}, {"by_visibility", buckets},
                {"by_object", by_object}, {"seconds", p.seconds},
                {"train_kp_err_mm", p.train_kp_err_mm}, {"val_kp_err_mm", p.val_kp_err_mm},
                {"val_kp_err_frac", p.val_kp_err_frac},
                {"val_rot_err_deg_median", p.val_rot_err_deg_median},
                {"val_rot_err_deg_mean", p.val_rot_err_deg_mean}, {"val_acc_10deg", p.val_acc_10deg}};
    if (p.step == j.c.steps) {  // the last point: every sample's errors
        json each = json::array();
        for (size_t k = 0; k < p.val_rot_err_deg_each.size() && k < sm.val.size(); ++k)
            each.push_back({j.objects[size_t(sm.val[k].class_index)], p.val_kp_err_frac_each[k],
                            p.val_rot_err_deg_each[k]});
        rec["val_each_obj_kpfrac_rotdeg"] = each;
    }
    return rec;
}

int run(const Job& j) {
    if (j.threads > 0) set_num_threads(j.threads);
    Objects o(j);
    Samples sm(j, o);
    Rng pick(j.c.seed * 31 + 5);
    const tools::SampleDraw draw = [&](int64_t i, train::PoseSample* out) {
        if (j.pool > 0) {
            *out = sm.pooled[pick.below(sm.pooled.size())];
            return true;
        }
        Rng r(uint64_t(i) * 2654435761ull + j.c.seed);
        return sm.src->get(i * sm.scene.targets_max, r, out);
    };
    std::printf("%6s %8s %7s %12s %10s %9s %11s %10s %8s\n", "step", "samples", "sec",
                "train_kp_mm", "val_kp_mm", "val_kp/d", "rot_med_deg", "rot_mean", "acc10");
    json curve = json::array();
    tools::rot_study(j.c, int(j.objects.size()), o.kps, o.diam, &o.sym, draw, sm.val,
                     [&](const tools::RotStudyPoint& p) { curve.push_back(report_point(j, sm, p)); });
    if (!j.out_json.empty()) std::ofstream(j.out_json) << curve.dump(1) << "\n";
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"g2l_rotstudy: train G2L-Net's rotation blocks alone on ground-truth-segmented "
                 "points of synthetic renders and print the learning curve (keypoint and "
                 "rotation error on held-out renders against samples seen)"};
    Job j;
    add_options(app, j);
    if (const int rc = g2l::cli::parse(app, argc, argv, "g2l_rotstudy"); rc >= 0) return rc;
    try {
        return run(j);
    } catch (const std::exception& e) {
        return g2l::cli::report("g2l_rotstudy", e, j.verbose);
    }
}
