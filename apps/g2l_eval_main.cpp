// SPDX-License-Identifier: MIT
// g2l_eval: the pose stage of G2L-Net with ground-truth 2D boxes over a BOP split.
#include <CLI/CLI.hpp>
#include <cctype>
#include <sstream>
#include <optional>

#include "pipeline_cli.h"
#include "core/cli.h"
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "data/bop.h"
#include "data/dataset.h"
#include "data/detections.h"
#include "data/draw.h"
#include "geometry/metrics.h"
#include "train/config.h"
#include "train/detector_train.h"
#include "eval/evaluate.h"
#include "infer/frame_pipeline.h"
#include "train/model_io.h"

namespace {

using json = nlohmann::json;

// A pose as --instances and --hypotheses write it: R row-major, t in mm.
json pose_json(const g2l::geom::Pose& p) {
    json R = json::array();
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) R.push_back(p.R(a, b));
    return json{{"R", R}, {"t", {p.t[0], p.t[1], p.t[2]}}};
}

// One --instances line: ids, status, box, estimate, ground truth, errors.
json instance_json(const g2l::eval::InstanceResult& r, const std::string& set_name) {
    json j = {{"set", set_name}, {"scene", r.scene}, {"image_id", r.image_id},
              {"inst", r.inst_index}, {"obj_id", r.obj_id}, {"status", r.status},
              {"found", r.found}, {"score", r.score},
              {"box", {r.box.x, r.box.y, r.box.w, r.box.h}}, {"ms", r.ms}};
    if (!r.false_positive) j["gt"] = pose_json(r.gt);
    if (r.reported) {  // the hypotheses road
        j["right"] = r.right;
        j["false_positive"] = r.false_positive;
        j["det_score"] = r.det_score;
        if (r.verify_score >= 0)
            j["check"] = {{"explained", r.explained}, {"violation", r.violation},
                          {"seg_agree", r.seg_agree}};
    }
    if (r.found) j["est"] = pose_json(r.est);
    if (r.found && !r.false_positive) {
        j["add_mm"] = r.add_mm;
        j["adds_mm"] = r.adds_mm;
        j["addsym_mm"] = r.addsym_mm;
        if (r.refine_hyp >= 0) {
            j["refine_hypothesis"] = r.refine_hyp;
            j["refine_cluster"] = r.refine_cluster;
            j["alt_fit_mm"] = r.alt_fit_mm;
            j["fit_mm"] = r.fit_mm;
            j["gt_fit_mm"] = r.gt_fit_mm;
        }
        j["rot_err_deg"] = r.rot_deg;
        j["rot_err_sym_deg"] = r.rot_sym_deg;
        j["trans_err_mm"] = r.trans_mm;
    }
    if (r.seg_iou >= 0) j["seg_iou"] = r.seg_iou;
    if (r.det_iou >= 0) j["det_iou"] = r.det_iou;
    if (r.det_iou_detector >= 0) j["det_iou_detector"] = r.det_iou_detector;
    if (!r.detector_box.empty()) {
        const g2l::geom::Box2i& b = r.detector_box;
        j["detector_box"] = {b.x, b.y, b.w, b.h};
    }
    return j;
}

// --vis: one image per frame: ground truth green, estimate blue (the paper's Fig. 7). With the
// hypotheses road, each reported pose carries its score and the rejected hypotheses are drawn
// in red with theirs and the reason.
void draw_frames(const g2l::data::Dataset& ds, const std::vector<g2l::eval::InstanceResult>& inst,
                 const std::vector<g2l::eval::HypothesisRecord>& hyps, const std::string& vis_dir) {
    namespace fs = std::filesystem;
    std::map<std::pair<std::string, int>, std::vector<const g2l::eval::InstanceResult*>> by_frame;
    for (const auto& r : inst) by_frame[{r.scene, r.image_id}].push_back(&r);
    std::map<std::pair<std::string, int>, std::vector<const g2l::eval::HypothesisRecord*>> hyp_frame;
    for (const auto& h : hyps) hyp_frame[{h.scene, h.image_id}].push_back(&h);
    char label[128];
    for (const auto& f : ds.frames()) {
        const auto it = by_frame.find({f.scene, f.image_id});
        if (it == by_frame.end()) continue;
        g2l::data::Image im;
        if (!f.rgb_path.empty()) {
            im = ds.load_rgb(f);
        } else {
            int w = 0, h = 0;
            im = g2l::data::depth_to_rgb(ds.load_depth_mm(f, &w, &h), w, h);
        }
        const auto hit = hyp_frame.find({f.scene, f.image_id});
        if (hit != hyp_frame.end())  // rejected hypotheses first, under the reported poses
            for (const auto* h : hit->second) {
                if (h->verdict == "accepted" || !h->posed) continue;
                const g2l::geom::ModelInfo& mi = ds.model(h->obj_id).info;
                g2l::data::draw_box3d(&im, mi.min, mi.min + mi.size, h->est, f.K, {230, 40, 40}, 1);
                std::snprintf(label, sizeof label, "%d %s %.2f", h->obj_id, h->verdict.c_str(),
                              h->score);
                g2l::data::draw_text(&im, h->box.x, h->box.y + h->box.h - 2, label, {255, 120, 120});
            }
        for (const auto* r : it->second) {
            const g2l::geom::ModelInfo& mi = ds.model(r->obj_id).info;
            const Eigen::Vector3d lo = mi.min, hi = mi.min + mi.size;
            if (!r->false_positive) g2l::data::draw_box3d(&im, lo, hi, r->gt, f.K, {40, 220, 40});
            if (r->found) g2l::data::draw_box3d(&im, lo, hi, r->est, f.K, {40, 90, 255});
            if (r->det_iou >= 0 && !r->box.empty())  // the detector's 2D box (yellow)
                g2l::data::draw_rect(&im, r->box.x, r->box.y, r->box.w, r->box.h, {250, 210, 0});
            if (r->reported) {
                std::snprintf(label, sizeof label, "%d %s %.2f", r->obj_id,
                              ds.model(r->obj_id).name.c_str(), r->score);
                g2l::data::draw_text(&im, r->box.x, std::max(10, r->box.y - 3), label,
                                     r->false_positive ? g2l::data::Rgb{255, 160, 60}
                                                       : g2l::data::Rgb{120, 170, 255});
            }
        }
        g2l::data::save_png((fs::path(vis_dir) / (f.scene + "_" + std::to_string(f.image_id) + ".png")).string(), im);
    }
}

// --vis: accuracy against the threshold (fraction of the diameter, 0-20%) per object: ADD-S
// (red), ADD modulo the geometric symmetries (blue), ADD (grey).
void draw_accuracy_curves(const g2l::data::Dataset& ds,
                          const std::vector<g2l::eval::InstanceResult>& inst,
                          const std::string& vis_dir) {
    namespace fs = std::filesystem;
    std::map<int, std::vector<const g2l::eval::InstanceResult*>> by_obj;
    for (const auto& r : inst)
        if (!r.false_positive) by_obj[r.obj_id].push_back(&r);
    for (const auto& [id, rs] : by_obj) {
        const double d = ds.model(id).info.diameter;
        std::vector<std::vector<std::pair<double, double>>> curves(3);
        for (int k = 0; k <= 40; ++k) {
            const double frac = 0.2 * k / 40.0;
            double n[3] = {0, 0, 0};
            for (const auto* r : rs) {
                if (!r->found || r->det_miss()) continue;
                n[0] += r->adds_mm < frac * d;
                n[1] += r->addsym_mm < frac * d;
                n[2] += r->add_mm < frac * d;
            }
            for (int c = 0; c < 3; ++c) curves[size_t(c)].push_back({frac, 100.0 * n[c] / double(rs.size())});
        }
        g2l::data::save_png((fs::path(vis_dir) / ("accuracy_obj_" + std::to_string(id) + ".png")).string(),
                            g2l::data::plot_curves(curves, {{{220, 40, 40}}, {{40, 90, 255}}, {{150, 150, 150}}}, 0.2));
    }
}

// --bop-csv, --instances and --vis for the instances of one evaluated set.
void write_outputs(const g2l::data::Dataset& ds, const std::vector<g2l::eval::InstanceResult>& inst,
                   const std::vector<g2l::eval::HypothesisRecord>& hyps,
                   std::ofstream* csv, std::ofstream* jsonl, const std::string& vis_dir,
                   const std::string& set_name) {
    // BOP: `time` is the wall time of the whole image, the same on all of its rows.
    std::map<std::pair<std::string, int>, double> image_ms;
    for (const auto& r : inst) image_ms[{r.scene, r.image_id}] += r.ms;
    char buf[1024];
    for (const auto& r : inst) {
        if (csv && r.found) {
            const auto& R = r.est.R;
            const auto& t = r.est.t;
            std::snprintf(buf, sizeof buf,
                          "%d,%d,%d,%.6f,%.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g,%.6f %.6f %.6f,%.6f\n",
                          std::atoi(r.scene.c_str()), r.image_id, r.obj_id, r.score, R(0, 0), R(0, 1),
                          R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2), t[0], t[1],
                          t[2], image_ms[{r.scene, r.image_id}] / 1000.0);
            *csv << buf;
        }
        if (jsonl) {
            *jsonl << instance_json(r, set_name).dump() << "\n";
        }
    }
    if (vis_dir.empty()) return;
    draw_frames(ds, inst, hyps, vis_dir);
    draw_accuracy_curves(ds, inst, vis_dir);
}

/// Everything the command line asks for.
struct Job {
    std::string checkpoint, config, root, split = "test", boxes = "gt", json_out;
    std::vector<std::string> sets;
    int64_t max_instances = 0;
    double min_visib = 0.0;
    bool min_visib_given = false;
    std::string detector_path;
    bool det_mirror = false;
    std::string detections_path, bop_csv, instances_path, vis_dir, symmetric, poses_path;
    bool centre_from_mask = false;
    std::string oracle = "none";
    g2l::PipelineOptions pipeline;  // the library's own options, as g2l_infer's
    std::string pr_png, hyps_path, fit_score;
    bool verbose = false;
};

void add_options(CLI::App& app, Job& j) {
    app.add_option("--checkpoint", j.checkpoint, "a .g2l checkpoint written by g2l_train (required "
                                               "unless --detector is evaluated alone)");
    app.add_option("--detector", j.detector_path,
                   "a detector export (g2l_train with a \"task\": \"detector\" config writes "
                   "<run_dir>/detector.g2l). Alone (no --checkpoint): evaluates the 2D detector on "
                   "--root/--split (recall and precision at IoU 0.5, heat-map peak on the object); "
                   "with --checkpoint and --boxes det: the full pipeline, detector included");
    app.add_flag("--det-mirror", j.det_mirror,
                 "the detector also sees each image mirrored left-right and averages the two "
                 "class-probability maps (two network passes per frame)");
    app.add_option("--config", j.config, "evaluate on this config's data.val BOP sources");
    app.add_option("--set", j.sets, "config overrides (as g2l_train)")->check(g2l::cli::key_value());
    app.add_option("--root", j.root, "BOP dataset root (instead of --config)");
    app.add_option("--split", j.split, "BOP split with --root");
    app.add_option("--boxes", j.boxes, "2D boxes: gt (ground truth: one pose per annotated "
                                     "instance), file (a BOP detection file given with "
                                     "--detections) or det (the --detector's peaks, each lifted "
                                     "with depth as the sphere centre). file and det take the "
                                     "library's hypotheses road (each detection posed, refined, "
                                     "verified against the depth, duplicates and overlaps "
                                     "rejected) and match the reported poses to the instances as "
                                     "BOP does (pose_precision, det_precision_50, false "
                                     "positives)")
        ->check(CLI::IsMember({"gt", "file", "det"}));
    app.add_option("--symmetric", j.symmetric,
                   "the objects scored with ADD-S in acc_add_s_10 and marked (sym): a published "
                   "convention (ycbv: 13,16,19,20,21; lm / lmo: 10,11), object ids (13,16), or "
                   "none; default: those whose models_info.json declares symmetries (never "
                   "guessed from the folder's name)");
    app.add_option("--poses", j.poses_path,
                   "score the poses of a BOP results CSV (g2l_infer --bop-csv, e.g. of a tracked "
                   "video) instead of running the pipeline: matched to the instances as with "
                   "--boxes det (the same figures); --checkpoint says which objects count");
    app.add_option("--detections", j.detections_path,
                   "BOP detection file (JSON array of {scene_id, image_id, category_id, bbox, score, "
                   "time}) for --boxes file");
    app.add_option("--bop-csv", j.bop_csv, "write the estimates as a BOP Challenge results CSV "
                                         "(scene_id,im_id,obj_id,score,R,t,time)");
    app.add_option("--instances", j.instances_path, "write one JSON line per evaluated instance "
                                                  "(ids, status, box, estimate, ground truth, errors)");
    app.add_option("--vis", j.vis_dir, "write images with the projected 3D boxes (ground truth green, "
                                      "estimate blue, the detector's 2D box yellow) and an "
                                      "accuracy-threshold curve per object "
                                      "into this folder");
    app.add_option("--json", j.json_out, "also write the figures as JSON to this file");
    app.add_option("--max-instances", j.max_instances, "evaluate at most this many instances")
        ->check(g2l::cli::at_least(0));
    app.add_option("--min-visib", j.min_visib, "skip instances less visible than this fraction "
                                             "(default: 0 with --root, 0.1 with --root and "
                                             "--boxes det, the source's min_visib_fract with "
                                             "--config)")
        ->check(CLI::Range(0.0, 1.0));
    app.add_flag("--centre-from-mask", j.centre_from_mask,
                 "take the sphere centre from the GT visible mask (the earlier protocol; default: "
                 "from the box and the depth only, as a detector would give it)");
    app.add_option("--oracle", j.oracle,
                   "ground-truth inputs in place of a stage's output, to tell which stage an "
                   "error comes from: seg (the crop points within 8 mm of the posed model replace "
                   "the segmentation), t (the GT translation replaces the T-net's and centres the "
                   "rotation input), seg+t (both: the errors are the rotation's alone); default none")
        ->check(CLI::IsMember({"none", "seg", "t", "seg+t"}));
    g2l::cli::add_pipeline_options(app, j.pipeline, "--max-per-object");
    app.add_option("--min-det-score", j.pipeline.min_detection_score,
                   "--boxes det / file: detections scoring below this are not tried (default 0.1)")
        ->check(CLI::Range(0.0, 1.0));
    app.add_option("--fit-score", j.fit_score,
                   "--boxes det / file: fit the score model (the probability that a verified "
                   "pose is right, ADD-S < 0.1 d) and the arbiter (which of two poses claiming "
                   "the same depth is the right one) to this run's hypotheses and write their "
                   "weights as JSON here (fit on renders only; the shipped weights are infer/"
                   "frame_pipeline.h's defaults, docs/results.md). The run selects in score "
                   "order (no arbiter), so its conflicts and figures do not depend on the "
                   "shipped arbiter");
    app.add_option("--pr-curve", j.pr_png,
                   "--boxes det / file: write the precision-recall curve of the reported poses "
                   "over their verified score as a PNG (x: recall %, y: precision %) and print "
                   "its points");
    app.add_option("--hypotheses", j.hyps_path,
                   "--boxes det / file: write every hypothesis (score, verdict, rival, right, the "
                   "score model's features and the verification's counts when verified, box and, "
                   "when posed, the pose `est`) as JSON lines");
    app.add_flag("--verbose", j.verbose, "error messages with their source location (also G2L_VERBOSE=1)");
}

/// The usage rules, in the order a user meets them; "" when the command line holds together.
std::string usage_error(const Job& j) {
    if ((!j.pr_png.empty() || !j.hyps_path.empty() || !j.fit_score.empty()) && j.boxes == "gt")
        return "--pr-curve, --hypotheses and --fit-score need --boxes det or file (GT boxes have "
               "no hypotheses)";
    if (j.checkpoint.empty() && j.detector_path.empty())
        return "give --checkpoint FILE (and/or --detector FILE; see g2l_eval --help)";
    if (!j.poses_path.empty() && (j.boxes != "gt" || !j.detector_path.empty()))
        return "--poses scores given poses: it takes no --boxes det / file and no --detector";
    if ((j.boxes == "det") != !j.detector_path.empty() && !j.checkpoint.empty())
        return "--boxes det needs --detector FILE, and --detector with --checkpoint needs --boxes det";
    if (j.det_mirror && j.detector_path.empty()) return "--det-mirror needs --detector FILE";
    if (j.checkpoint.empty()) {  // the detector alone
        if (j.oracle != "none")
            return "--oracle " + j.oracle + " needs --checkpoint (it replaces a pose stage's output)";
        if (j.root.empty()) return "--detector alone needs --root (and --split)";
        return "";
    }
    if ((j.boxes == "file") != !j.detections_path.empty())
        return "--boxes file needs --detections FILE, and --detections needs --boxes file";
    if (j.config.empty() == j.root.empty())
        return "give exactly one of --config or --root (see g2l_eval --help)";
    // --set changes the config's evaluation sources (data.val.*); nothing else of a training
    // config affects evaluation (the crop and point counts come from the checkpoint).
    if (!j.sets.empty() && j.config.empty())
        return "--set needs --config (it overrides the config's data.val sources; with --root "
               "there is no config)";
    for (const auto& s : j.sets)
        if (s.rfind("data.val", 0) != 0)
            return "--set '" + s + "' has no effect on evaluation: only data.val.* keys apply (the "
                   "crop and point counts are the checkpoint's; see --crop-points / --object-points)";
    return g2l::cli::pipeline_usage_error(j.pipeline);
}

/// --checkpoint absent: the detector alone, its recall and precision per object.
int run_detector_alone(const Job& j) {
    const g2l::nn::LoadedDetector det = g2l::nn::load_detector(j.detector_path);
    g2l::data::BopOptions o;
    o.obj_ids = det.object_ids;
    const g2l::data::BopDataset ds = g2l::data::open_bop(j.root, j.split, o);
    const auto r = g2l::eval::evaluate_detector(det, ds, j.min_visib > 0 ? j.min_visib : 0.1,
                                                 0.3f, 0, true, j.det_mirror);
    std::printf("detector %s on %s/%s (instances with visib_fract >= %.2f):\n%s",
                j.detector_path.c_str(), j.root.c_str(), j.split.c_str(),
                j.min_visib > 0 ? j.min_visib : 0.1,
                g2l::eval::detector_eval_table(r).c_str());
    if (!j.json_out.empty()) {
        nlohmann::json js;
        js["detector"] = j.detector_path;
        js["mirror"] = j.det_mirror;
        js["dataset"] = j.root + "/" + j.split;
        js["frames"] = r.frames;
        js["ms_per_frame"] = r.ms_per_frame;
        js["mean_recall"] = r.mean_recall;
        js["mean_precision"] = r.mean_precision;
        js["mean_peak_on_object"] = r.mean_peak_rate;
        js["mean_recall_top3"] = r.mean_recall_top3;
        for (const auto& row : r.rows)
            js["objects"][std::to_string(row.obj_id)] = {
                {"instances", row.instances}, {"recall", row.recall()},
                {"recall_top3", row.recall_top3()},
                {"precision", row.precision()}, {"peak_on_object", row.peak_rate()},
                {"detections", row.detections}};
        std::ofstream f(j.json_out);
        f << js.dump(2) << "\n";
        f.flush();
        G2L_CHECK(f.good(), "--json '", j.json_out, "': cannot write the file: ",
                  std::strerror(errno));
    }
    return 0;
}

/// --symmetric: a convention's name (ycbv, lm), object ids (13,16), none; nullopt when not given
/// (the models_info.json's symmetries then decide).
std::optional<std::vector<int>> symmetric_ids(const Job& j) {
    std::optional<std::vector<int>> sym_ids;
    if (j.symmetric == "none") {
        sym_ids = std::vector<int>{};
    } else if (!j.symmetric.empty() && std::isdigit(static_cast<unsigned char>(j.symmetric[0]))) {
        std::vector<int> ids;
        std::stringstream ss(j.symmetric);
        std::string tok;
        while (std::getline(ss, tok, ',')) {
            char* end = nullptr;
            const long v = std::strtol(tok.c_str(), &end, 10);
            G2L_CHECK(!tok.empty() && *end == '\0' && v >= 1 && v < 1000000, "--symmetric '",
                      j.symmetric, "': '", tok, "' is not an object id");
            ids.push_back(int(v));
        }
        sym_ids = ids;
    } else if (!j.symmetric.empty()) {
        sym_ids = g2l::data::symmetric_convention(j.symmetric);
    }
    return sym_ids;
}

/// One evaluated set: a dataset split and its minimum visible fraction.
struct EvalSet {
    std::string name;
    std::unique_ptr<g2l::data::Dataset> ds;
    double min_visib = 0;
};

/// The sets to evaluate: --root/--split (the checkpoint's objects it has models of), or the
/// config's BOP validation sources. Throws naming the problem (no object, no source, no frame).
std::vector<EvalSet> open_sets(const Job& j, const g2l::train::LoadedModel& m) {
    const std::optional<std::vector<int>> sym_ids = symmetric_ids(j);
    std::vector<EvalSet> sets_to_eval;
    std::vector<int> ids;
    for (const auto& p : m.class_of) ids.push_back(p.first);
    if (!j.root.empty()) {
        // The checkpoint's objects that the dataset has models of (a model for 21 objects
        // evaluates on a dataset that ships 2 of them).
        const g2l::data::Dataset all = g2l::data::open_bop_models(j.root, {});
        std::vector<int> present;
        for (int id : ids)
            if (all.models().count(id)) present.push_back(id);
        G2L_CHECK(!present.empty(), "none of the checkpoint's ", ids.size(),
                  " objects has a model in ", j.root, "/models");
        g2l::data::BopOptions o;
        o.obj_ids = present;
        o.symmetric_ids = sym_ids;
        // The detector's figures count every instance at least 10% visible (the detector
        // evaluation's rule); GT boxes keep every instance unless told.
        sets_to_eval.push_back({j.root + "/" + j.split,
                                std::make_unique<g2l::data::BopDataset>(g2l::data::open_bop(j.root, j.split, o)),
                                j.min_visib_given || (j.boxes != "det" && j.poses_path.empty())
                                    ? j.min_visib : 0.1});
    } else {
        const auto cfg = g2l::train::load_config(j.config, j.sets);
        for (const auto& s : cfg.data.val) {
            const g2l::train::SourceKind& kind = g2l::train::source_kind(s.type);
            if (!kind.frames) continue;  // renders have no frames to score
            g2l::train::SourceOpen what;
            what.symmetric_ids = sym_ids;
            what.obj_ids = s.objects.empty() ? ids : s.objects;
            sets_to_eval.push_back({s.root + "/" + s.split, kind.open(s, what),
                                    j.min_visib_given ? j.min_visib : s.min_visib_fract});
        }
        G2L_CHECK(!sets_to_eval.empty(), j.config, " has no source of annotated frames in data.val");
    }
    // A split without a frame would print a table of 0.0 % and exit 0: a wrong root or
    // split name must be an error.
    for (const EvalSet& s : sets_to_eval)
        G2L_CHECK(!s.ds->frames().empty(), "'", s.name, "' has no frame (its scene_gt.json files list no image): check "
                  "--root and --split");
    return sets_to_eval;
}

/// The evaluation options of one set: the pipeline's as the command line gives them (the
/// checkpoint brings its crop and point counts), and what evaluation adds.
g2l::eval::EvalOptions eval_options(const Job& j, const EvalSet& s) {
    g2l::eval::EvalOptions eo;
    eo.pipeline = j.pipeline;
    eo.max_instances = j.max_instances;
    eo.min_visib_fract = s.min_visib;
    eo.centre_from_mask = j.centre_from_mask;
    eo.arbitrate = j.fit_score.empty();  // a fit sees the score order's conflicts
    eo.oracle_seg = j.oracle == "seg" || j.oracle == "seg+t";
    eo.oracle_t = j.oracle == "t" || j.oracle == "seg+t";
    if (eo.min_visib_fract > 0) {
        bool annotated = false;
        for (const auto& f : s.ds->frames())
            for (const auto& inst : f.instances) annotated |= inst.visib_fract >= 0;
        if (!annotated)
            std::fprintf(stderr, "g2l_eval: note: min visible fraction %g has no effect on "
                                 "%s: it has no visib_fract annotations (every instance is "
                                 "evaluated)\n", eo.min_visib_fract,
                         s.name.c_str());
    }
    return eo;
}

/// --fit-score: the score model and the arbiter fitted on the set's hypotheses.
void write_score_fit(const Job& j, const std::vector<g2l::eval::HypothesisRecord>& hyps,
                     const std::string& name) {
    if (!j.fit_score.empty()) {
        const g2l::infer::ScoreModel sm = g2l::eval::fit_score_model(hyps);
        const g2l::infer::ArbiterModel am = g2l::eval::fit_arbiter(hyps);
        std::ofstream f(j.fit_score);
        f << json{{"features", {"bias", "explained", "violation", "occlusion", "seg_agree",
                                "support_x_seg_agree", "ln_det_score", "borrowed"}},
                  {"w", sm.w}, {"arbiter_w", am.w}, {"arbiter_footprint", am.footprint}}
                 .dump(2)
          << "\n";
        G2L_CHECK(f.good(), "--fit-score '", j.fit_score, "': cannot write the file");
        auto print = [](const char* what, const auto& w) {
            std::printf("%s = {", what);
            for (size_t k = 0; k < w.size(); ++k) std::printf("%s%.4f", k ? ", " : "", w[k]);
            std::printf("}");
        };
        std::printf("fitted on %s: ", name.c_str());
        print("score model w", sm.w);
        std::printf(", ");
        print("arbiter w", am.w);
        std::printf(", arbiter footprint = %.4f (%s)\n\n", am.footprint, j.fit_score.c_str());
    }
}

/// --pr-curve: precision against recall over the verified score, printed and drawn.
void write_pr_curve(const Job& j, const std::vector<g2l::eval::InstanceResult>& inst,
                    const std::string& name) {
    if (!j.pr_png.empty()) {
        const auto curve = g2l::eval::pr_curve(inst);
        std::vector<std::pair<double, double>> pts;
        std::printf("Precision-recall over the verified score (%s):\n\n"
                    "| score >= | precision (%%) | recall (%%) |\n|---|---|---|\n",
                    name.c_str());
        size_t step = std::max<size_t>(1, curve.size() / 12);
        for (size_t k = 0; k < curve.size(); ++k) {
            pts.push_back({curve[k].recall, curve[k].precision});
            if (k % step == 0 || k + 1 == curve.size())
                std::printf("| %.3f | %.1f | %.1f |\n", curve[k].threshold,
                            curve[k].precision, curve[k].recall);
        }
        g2l::data::Image plot = g2l::data::plot_curves({pts}, {{{40, 90, 255}}}, 100.0);
        g2l::data::draw_text(&plot, 40, 20, "precision (%) vs recall (%), ADD-S < 0.1 d",
                             {255, 255, 255});
        g2l::data::save_png(j.pr_png, plot);
        std::printf("\nwrote %s\n\n", j.pr_png.c_str());
    }
}

/// The files a run writes besides the table, opened before the (long) evaluation.
struct Outputs {
    std::ofstream csv, inst, hyp;
    explicit Outputs(const Job& j) {
        if (!j.bop_csv.empty()) {
            csv.open(j.bop_csv);
            G2L_CHECK(csv.good(), "--bop-csv '", j.bop_csv, "': cannot write the file");
            csv << "scene_id,im_id,obj_id,score,R,t,time\n";
        }
        if (!j.hyps_path.empty()) {
            hyp.open(j.hyps_path);
            G2L_CHECK(hyp.good(), "--hypotheses '", j.hyps_path, "': cannot write the file");
        }
        if (!j.instances_path.empty()) {
            inst.open(j.instances_path);
            G2L_CHECK(inst.good(), "--instances '", j.instances_path, "': cannot write the file");
        }
        if (!j.vis_dir.empty()) {
            std::error_code ec;
            std::filesystem::create_directories(j.vis_dir, ec);
            G2L_CHECK(!ec && std::filesystem::is_directory(j.vis_dir), "--vis '", j.vis_dir,
                      "': cannot create the folder: ", ec.message());
        }
    }
    void hypotheses(const std::vector<g2l::eval::HypothesisRecord>& hyps, const std::string& set) {
        if (!hyp.is_open()) return;
        for (const auto& h : hyps) {
            json r = {{"set", set}, {"scene", h.scene}, {"image_id", h.image_id},
                      {"obj_id", h.obj_id}, {"score", h.score}, {"det_score", h.det_score},
                      {"verdict", h.verdict}, {"rival", h.rival}, {"right", h.right},
                      {"pose_right", h.pose_right}, {"features", h.features},
                      {"box", {h.box.x, h.box.y, h.box.w, h.box.h}}};
            if (h.posed) r["est"] = pose_json(h.est);
            if (h.verified)
                r["counts"] = {{"visible", h.visible}, {"inliers", h.inliers},
                               {"footprint_cells", h.footprint_cells}};
            hyp << r.dump() << "\n";
        }
    }
    void close(const Job& j) {
        if (csv.is_open()) {
            csv.close();
            G2L_CHECK(csv.good(), "--bop-csv '", j.bop_csv, "': write error");
        }
        if (inst.is_open()) {
            inst.close();
            G2L_CHECK(inst.good(), "--instances '", j.instances_path, "': write error");
        }
    }
};

/// The pose evaluation: every set through evaluate_instances, its table printed, the outputs
/// written.
int run_eval(const Job& j) {
    // Every input and output before the (long) evaluation.
    std::vector<g2l::data::Detection> detections;
    if (!j.detections_path.empty()) detections = g2l::data::load_bop_detections(j.detections_path);
    std::vector<g2l::data::PoseRow> given;
    if (!j.poses_path.empty()) given = g2l::data::load_bop_results_csv(j.poses_path);
    Outputs out(j);
    g2l::train::LoadedModel m = g2l::train::load_model(j.checkpoint);
    std::unique_ptr<g2l::nn::LoadedDetector> det;
    if (j.boxes == "det")
        det = std::make_unique<g2l::nn::LoadedDetector>(g2l::nn::load_detector(j.detector_path));
    const std::vector<EvalSet> sets = open_sets(j, m);
    std::string json_all = "[";
    for (size_t i = 0; i < sets.size(); ++i) {
        const EvalSet& s = sets[i];
        g2l::eval::EvalOptions eo = eval_options(j, s);
        if (j.boxes == "file") eo.detections = &detections;
        if (!j.poses_path.empty()) eo.poses = &given;
        std::vector<g2l::data::Detection> det_boxes;
        if (j.boxes == "det") {  // the detector on every frame (what its input needs), timed
            // Peaks per class: as many as the hypotheses road may try of one object.
            det_boxes = g2l::eval::run_detector_on(*det, *s.ds, 0.05f, j.det_mirror,
                                                   std::max(3, j.pipeline.max_instances));
            eo.detections = &det_boxes;
        }
        std::vector<g2l::eval::InstanceResult> inst;
        std::vector<g2l::eval::HypothesisRecord> hyps;
        const auto r = g2l::eval::evaluate_instances(g2l::infer::PipelineModel::of(m), *s.ds, eo,
                                                      &inst, &hyps);
        std::printf("## %s (%s boxes, %s crop)\n\n%s\n", s.name.c_str(),
                    !j.poses_path.empty() ? ("poses " + j.poses_path).c_str()
                    : j.boxes == "gt"    ? "GT"
                    : j.boxes == "det"   ? ("detector " + j.detector_path).c_str()
                                         : ("detection file " + j.detections_path).c_str(),
                    g2l::geom::to_string(m.crop), g2l::eval::report_markdown(r).c_str());
        write_outputs(*s.ds, inst, hyps, out.csv.is_open() ? &out.csv : nullptr,
                      out.inst.is_open() ? &out.inst : nullptr, j.vis_dir, s.name);
        out.hypotheses(hyps, s.name);
        if (i == 0) {  // the first set's fit and curve (a config may have more)
            write_score_fit(j, hyps, s.name);
            write_pr_curve(j, inst, s.name);
        }
        json_all += (i ? "," : "") + g2l::eval::report_json(r);
    }
    json_all += "]";
    if (!j.json_out.empty()) {
        std::ofstream f(j.json_out);
        G2L_CHECK(f.good(), "--json '", j.json_out, "': cannot open the file: ", std::strerror(errno));
        f << json_all << "\n";
        f.flush();
        G2L_CHECK(f.good(), "--json '", j.json_out, "': cannot write the file: ", std::strerror(errno));
    }
    out.close(j);
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"g2l_eval: evaluates a trained G2L-Net checkpoint with ground-truth 2D boxes "
                 "(the paper's Fig. 5a protocol) on a BOP split; prints a Markdown table per "
                 "object: ADD(-S) accuracy at 10% of the diameter, ADD-S / ADD AUC (10 cm), "
                 "rotation / translation errors, and per-stage timings. Each pose is refined "
                 "against the object's mesh by default (--refine turns); --refine none gives "
                 "the networks' poses alone, as G2L-Net publishes them."};
    Job j;
    add_options(app, j);
    if (const int rc = g2l::cli::parse(app, argc, argv, "g2l_eval"); rc >= 0) return rc;
    j.min_visib_given = app.count("--min-visib") > 0;
    if (const std::string err = usage_error(j); !err.empty()) {
        std::fprintf(stderr, "g2l_eval: %s\n", err.c_str());
        return g2l::cli::kUsageError;
    }
    try {
        return j.checkpoint.empty() ? run_detector_alone(j) : run_eval(j);
    } catch (const std::exception& e) {
        return g2l::cli::report("g2l_eval", e, j.verbose);
    }
}
