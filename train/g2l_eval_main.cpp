// SPDX-License-Identifier: MIT
// g2l_eval: the pose stage of G2L-Net with ground-truth 2D boxes over a BOP split.
#include <CLI/CLI.hpp>

#include "core/cli.h"
#include <cstdio>
#include <fstream>

#include "data/bop.h"
#include "train/config.h"
#include "train/evaluate.h"
#include "train/model_io.h"

int main(int argc, char** argv) {
    CLI::App app{"g2l_eval: evaluates a trained G2L-Net checkpoint with ground-truth 2D boxes "
                 "(the paper's Fig. 5a protocol) on a BOP split; prints a Markdown table per "
                 "object: ADD(-S) accuracy at 10% of the diameter, ADD-S / ADD AUC (10 cm), "
                 "rotation / translation errors, and per-stage timings."};
    std::string checkpoint, config, root, split = "test", boxes = "gt", json_out;
    std::vector<std::string> sets;
    int64_t max_instances = 0;
    double min_visib = 0.0;
    int crop_points = -1, object_points = -1;
    app.add_option("--checkpoint", checkpoint, "a .g2l checkpoint written by g2l_train")->required();
    app.add_option("--config", config, "evaluate on this config's data.val BOP sources");
    app.add_option("--set", sets, "config overrides (as g2l_train)");
    app.add_option("--root", root, "BOP dataset root (instead of --config)");
    app.add_option("--split", split, "BOP split with --root");
    app.add_option("--boxes", boxes, "2D boxes: gt (ground truth; detector boxes come later)")
        ->check(CLI::IsMember({"gt"}));
    app.add_option("--json", json_out, "also write the figures as JSON to this file");
    app.add_option("--max-instances", max_instances, "evaluate at most this many instances")
        ->check(g2l::cli::at_least(0));
    app.add_option("--min-visib", min_visib, "skip instances less visible than this fraction "
                                             "(default: 0 with --root, the source's "
                                             "min_visib_fract with --config)")
        ->check(CLI::Range(0.0, 1.0));
    app.add_option("--crop-points", crop_points,
                   "seg-net input points per crop (default: the checkpoint's sampling.points, as "
                   "in training; 0 = the whole crop)")
        ->check(g2l::cli::at_least(0));
    app.add_option("--object-points", object_points,
                   "object points fed to the T-net and rotation blocks (default: the checkpoint's "
                   "sampling.seg_points)")
        ->check(g2l::cli::at_least(1));
    bool centre_from_mask = false;
    app.add_flag("--centre-from-mask", centre_from_mask,
                 "take the sphere centre from the GT visible mask (the earlier protocol; default: "
                 "from the box and the depth only, as a detector would give it)");
    bool verbose = false;
    app.add_flag("--verbose", verbose, "error messages with their source location (also G2L_VERBOSE=1)");
    if (const int rc = g2l::cli::parse(app, argc, argv, "g2l_eval"); rc >= 0) return rc;
    if (config.empty() == root.empty()) {
        std::fprintf(stderr, "g2l_eval: give exactly one of --config or --root (see g2l_eval --help)\n");
        return g2l::cli::kUsageError;
    }
    // --set changes the config's evaluation sources (data.val.*); nothing else of a training
    // config affects evaluation (the crop and point counts come from the checkpoint).
    if (!sets.empty() && config.empty()) {
        std::fprintf(stderr, "g2l_eval: --set needs --config (it overrides the config's data.val "
                             "sources; with --root there is no config)\n");
        return g2l::cli::kUsageError;
    }
    for (const auto& s : sets) {
        if (s.rfind("data.val", 0) != 0) {
            std::fprintf(stderr, "g2l_eval: --set '%s' has no effect on evaluation: only data.val.* "
                                 "keys apply (the crop and point counts are the checkpoint's; see "
                                 "--crop-points / --object-points)\n", s.c_str());
            return g2l::cli::kUsageError;
        }
    }
    try {
        g2l::train::LoadedModel m = g2l::train::load_model(checkpoint);
        std::vector<std::pair<std::string, g2l::data::BopDataset>> sets_to_eval;
        std::vector<double> set_min_visib;  // per set: --min-visib, else the source's
        std::vector<int> ids;
        for (const auto& p : m.class_of) ids.push_back(p.first);
        if (!root.empty()) {
            // The checkpoint's objects that the dataset has models of (a model for 21 objects
            // evaluates on a dataset that ships 2 of them).
            const g2l::data::Dataset all = g2l::data::open_bop_models(root, {});
            std::vector<int> present;
            for (int id : ids)
                if (all.models().count(id)) present.push_back(id);
            if (present.empty()) {
                std::fprintf(stderr, "g2l_eval: none of the checkpoint's %zu objects has a model in "
                                     "%s/models\n", ids.size(), root.c_str());
                return g2l::cli::kRunError;
            }
            g2l::data::BopOptions o;
            o.obj_ids = present;
            sets_to_eval.emplace_back(root + "/" + split, g2l::data::open_bop(root, split, o));
            set_min_visib.push_back(min_visib);
        } else {
            const auto cfg = g2l::train::load_config(config, sets);
            for (const auto& s : cfg.data.val) {
                if (s.type != "bop") continue;
                g2l::data::BopOptions o;
                o.scenes = s.scenes;
                o.obj_ids = s.objects.empty() ? ids : s.objects;
                sets_to_eval.emplace_back(s.root + "/" + s.split, g2l::data::open_bop(s.root, s.split, o));
                set_min_visib.push_back(app.count("--min-visib") ? min_visib : s.min_visib_fract);
            }
            if (sets_to_eval.empty()) {
                std::fprintf(stderr, "g2l_eval: %s has no BOP source in data.val\n", config.c_str());
                return g2l::cli::kRunError;
            }
        }
        std::string json_all = "[";
        for (size_t i = 0; i < sets_to_eval.size(); ++i) {
            g2l::train::EvalOptions eo;
            eo.crop = m.crop;
            eo.radius_scale = m.radius_scale;
            eo.crop_points = crop_points >= 0 ? crop_points : m.points;
            eo.max_object_points = object_points > 0 ? object_points : m.seg_points;
            eo.max_instances = max_instances;
            eo.min_visib_fract = set_min_visib[i];
            eo.centre_from_mask = centre_from_mask;
            if (eo.min_visib_fract > 0) {
                bool annotated = false;
                for (const auto& f : sets_to_eval[i].second.frames())
                    for (const auto& inst : f.instances) annotated |= inst.visib_fract >= 0;
                if (!annotated)
                    std::fprintf(stderr, "g2l_eval: note: min visible fraction %g has no effect on "
                                         "%s: it has no visib_fract annotations (every instance is "
                                         "evaluated)\n", eo.min_visib_fract,
                                 sets_to_eval[i].first.c_str());
            }
            const auto r = g2l::train::evaluate_gt_boxes(*m.net, sets_to_eval[i].second, m.class_of,
                                                         m.keypoints, eo);
            std::printf("## %s (GT boxes, %s crop)\n\n%s\n", sets_to_eval[i].first.c_str(),
                        m.crop.c_str(), g2l::train::report_markdown(r).c_str());
            json_all += (i ? "," : "") + g2l::train::report_json(r);
        }
        json_all += "]";
        if (!json_out.empty()) {
            std::ofstream f(json_out);
            if (!f) throw std::runtime_error("cannot write '" + json_out + "'");
            f << json_all << "\n";
        }
        return 0;
    } catch (const std::exception& e) {
        return g2l::cli::report("g2l_eval", e, verbose);
    }
}
