// SPDX-License-Identifier: MIT
// g2l_bench: prints the engine's speed on G2L-Net's shapes; --json prints one JSON object.
#include <CLI/CLI.hpp>
#include <tuple>

#include "core/cli.h"
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <limits>

#include "core/error.h"
#include "core/threads.h"
#include "data/bop.h"
#include "g2l/pose_estimator.h"
#include "tools/bench.h"
#include "train/config.h"

namespace {

// The real video the frame figures run on: ../shared/data/ycbv/train_real/000001 (4 objects)
// when that is there, else the fixture's scene (tests/data/ycbv_mini, 2 objects).
std::pair<std::string, std::string> bench_scene() {
    namespace fs = std::filesystem;
    const std::string root = g2l::train::shared_data_root("") + "/ycbv";
    if (fs::is_directory(root + "/train_real/000001")) return {root, "000001"};
    return {std::string(G2L_SOURCE_DIR) + "/tests/data/ycbv_mini", "000000"};
}

// frame_ms: the whole pipeline of the library (g2l::PoseEstimator, the code g2l_infer and an
// embedding program run) on one real 640 x 480 frame: the detector, then the poses of its
// `objects` best boxes, each refined against its mesh. The frame: the first one of
// ../shared/data/ycbv/train_real/000001 (4 objects) when that is there, else the fixture's
// first frame (tests/data/ycbv_mini); the what-string says which.
std::vector<g2l::tools::BenchFigure> bench_frame(int reps, const std::string& model,
                                                 const std::string& detector, int objects) {
    const auto [root, scene] = bench_scene();
    const g2l::data::BopDataset ds = g2l::data::open_bop(root, "train_real", {});
    const g2l::data::Frame* fr = nullptr;
    for (const auto& f : ds.frames())
        if (f.scene == scene) {
            fr = &f;
            break;
        }
    G2L_CHECK(fr, "bench_frame: no frame in ", root, "/train_real/", scene);
    int w = 0, h = 0;
    const std::vector<uint16_t> depth = g2l::data::load_depth_png(fr->depth_path, &w, &h);
    const g2l::data::Image rgb = ds.load_rgb(*fr);
    g2l::EstimatorOptions opt;
    opt.detector = detector;
    opt.meshes = root + "/models";
    opt.min_detection_score = 0.0;  // always `objects` boxes, whatever the scores
    const auto t_load = std::chrono::steady_clock::now();
    g2l::PoseEstimator est(model, opt);
    const double load_ms = std::chrono::duration<double, std::milli>(
                               std::chrono::steady_clock::now() - t_load).count();
    g2l::FrameView v;
    v.width = w, v.height = h;
    v.depth_u16 = depth.data();
    v.depth_scale = fr->depth_scale;
    v.rgb = rgb.data.data();
    v.K = {fr->K.fx, fr->K.fy, fr->K.cx, fr->K.cy};
    std::vector<double> ms;
    int boxes = 0;
    for (int r = 0; r < reps + 1; ++r) {
        const auto t0 = std::chrono::steady_clock::now();
        std::vector<g2l::ObjectBox> b = est.detect(v);
        if (int(b.size()) > objects) b.resize(size_t(objects));
        const auto poses = est.estimate(v, b);
        const double dt = std::chrono::duration<double, std::milli>(
                              std::chrono::steady_clock::now() - t0).count();
        boxes = int(poses.size());
        if (r >= 1) ms.push_back(dt);
    }
    std::sort(ms.begin(), ms.end());
    const double p90 = ms[std::min(ms.size() - 1, size_t(0.9 * double(ms.size())))];
    const std::string where = root + "/train_real/" + scene + "/" + std::to_string(fr->image_id) +
                              " (" + std::to_string(w) + " x " + std::to_string(h) + "), " +
                              std::to_string(reps) + " runs";
    const std::string what = "g2l::PoseEstimator: detector + " + std::to_string(boxes) +
                             " poses + refinement + verification on " + where;
    // The road estimate(frame) takes with the default options: every detection (and like-shaped
    // object) a hypothesis, each posed, refined and verified, duplicates and overlaps rejected.
    g2l::EstimatorOptions hopt;
    hopt.detector = detector;
    hopt.meshes = opt.meshes;
    hopt.keep_rejected = true;
    g2l::PoseEstimator hest(model, hopt);
    std::vector<double> hms;
    int hyps = 0, reported = 0;
    for (int r = 0; r < reps + 1; ++r) {
        const auto t0 = std::chrono::steady_clock::now();
        const auto poses = hest.estimate(v);
        const double dt = std::chrono::duration<double, std::milli>(
                              std::chrono::steady_clock::now() - t0).count();
        hyps = 0, reported = 0;
        for (const auto& p : poses) hyps += 1, reported += p.ok();
        if (r >= 1) hms.push_back(dt);
    }
    std::sort(hms.begin(), hms.end());
    const std::string hwhat = "g2l::PoseEstimator::estimate(frame), default options: detector + " +
                              std::to_string(hyps) + " hypotheses posed, refined and verified, " +
                              std::to_string(reported) + " reported, on " + where;
    return {{"estimator_load_ms", load_ms, "ms",
             "g2l::PoseEstimator's construction: the pose model, the detector and every mesh of " +
                 opt.meshes + " the model knows, each with its k-d tree, normals and closest-point "
                 "grid (once per program)"},
            {"frame_ms", ms[ms.size() / 2], "ms", what},
            {"frame_ms_p90", p90, "ms", what},
            {"frame_hypotheses_ms", hms[hms.size() / 2], "ms", hwhat}};
}

// track_frame_ms: g2l::PoseTracker over a real video (the 20 consecutive frames of
// ../shared/data/ycbv/train_real/000001, 4 objects; else the fixture's two frames, alternated),
// `passes` times over it: each frame's track() call (its depth already in memory). The median is
// a followed frame's time; the mean includes the frames the detector runs on (the first, a lost
// pose, a weak pose every 3 frames, every 10 frames).
std::vector<g2l::tools::BenchFigure> bench_track(int passes, const std::string& model,
                                                 const std::string& detector) {
    const auto [root, scene] = bench_scene();
    const g2l::data::BopDataset ds = g2l::data::open_bop(root, "train_real", {});
    struct Frame {
        std::vector<uint16_t> depth;
        g2l::FrameView v;
    };
    std::vector<const g2l::data::Frame*> scene_frames;  // in the order of the video
    for (const auto& f : ds.frames())
        if (f.scene == scene) scene_frames.push_back(&f);
    std::sort(scene_frames.begin(), scene_frames.end(),
              [](const auto* a, const auto* b) { return a->image_id < b->image_id; });
    std::vector<Frame> frames;
    for (const g2l::data::Frame* fp : scene_frames) {
        const g2l::data::Frame& f = *fp;
        Frame fr;
        int w = 0, h = 0;
        fr.depth = g2l::data::load_depth_png(f.depth_path, &w, &h);
        fr.v.width = w, fr.v.height = h;
        fr.v.depth_scale = f.depth_scale;
        fr.v.K = {f.K.fx, f.K.fy, f.K.cx, f.K.cy};
        frames.push_back(std::move(fr));
    }
    G2L_CHECK(!frames.empty(), "bench_track: no frame in ", root, "/train_real/", scene);
    if (frames.size() < 10) {  // the fixture: its frames back and forth, 20 in all
        std::vector<Frame> seq;
        for (size_t i = 0; i < 20; ++i) seq.push_back(frames[(i / 2) % frames.size()]);
        frames = std::move(seq);
    }
    for (Frame& f : frames) f.v.depth_u16 = f.depth.data();
    g2l::EstimatorOptions opt;
    opt.detector = detector;
    opt.meshes = root + "/models";
    g2l::PoseEstimator est(model, opt);
    std::vector<double> ms;
    int detected = 0, poses = 0;
    for (int pass = 0; pass < passes + 1; ++pass) {
        g2l::PoseTracker tracker(est);
        for (const Frame& f : frames) {
            const auto t0 = std::chrono::steady_clock::now();
            const auto out = tracker.track(f.v);
            const double dt = std::chrono::duration<double, std::milli>(
                                  std::chrono::steady_clock::now() - t0).count();
            if (pass == 0) continue;  // warm-up
            ms.push_back(dt);
            detected += tracker.detected();
            for (const auto& p : out) poses += p.ok();
        }
    }
    double mean = 0;
    for (const double m : ms) mean += m / double(ms.size());
    std::sort(ms.begin(), ms.end());
    const std::string what = g2l::cat(
        "g2l::PoseTracker on ", root, "/train_real/", scene, ": ", frames.size(), " frames x ",
        passes, ", ", double(poses) / double(ms.size()), " poses per frame, the detector on ",
        detected, " of ", ms.size(), " frames");
    return {{"track_frame_ms", ms[ms.size() / 2], "ms", what + " (median)"},
            {"track_frame_mean_ms", mean, "ms", what + " (mean)"}};
}

// soak_rss_growth_pct: `frames` frames through one g2l::PoseEstimator (the bench scene's frames in
// turn, meshes given): each frame one box posed, refined and verified, the box alternating
// between the objects; every 25th frame also a box outside the image and a frame whose depth is
// all NaN (the error roads); every 100th the whole estimate(frame) road. The resident memory at
// frame 1000 against the end: flat means nothing grows per frame.
std::vector<g2l::tools::BenchFigure> bench_soak(int frames, const std::string& model,
                                                const std::string& detector) {
    const auto [root, scene] = bench_scene();
    const g2l::data::BopDataset ds = g2l::data::open_bop(root, "train_real", {});
    std::vector<std::vector<uint16_t>> depths;
    std::vector<g2l::FrameView> views;
    for (const auto& f : ds.frames()) {
        if (f.scene != scene || depths.size() >= 8) continue;
        int w = 0, h = 0;
        depths.push_back(g2l::data::load_depth_png(f.depth_path, &w, &h));
        g2l::FrameView v;
        v.width = w, v.height = h;
        v.depth_scale = f.depth_scale;
        v.K = {f.K.fx, f.K.fy, f.K.cx, f.K.cy};
        views.push_back(v);
    }
    for (size_t i = 0; i < views.size(); ++i) views[i].depth_u16 = depths[i].data();
    std::vector<float> nan_depth(size_t(views[0].width) * size_t(views[0].height),
                                 std::numeric_limits<float>::quiet_NaN());
    g2l::FrameView nan_view = views[0];
    nan_view.depth_u16 = nullptr;
    nan_view.depth_mm = nan_depth.data();
    g2l::EstimatorOptions opt;
    opt.detector = detector;
    opt.meshes = root + "/models";
    g2l::PoseEstimator est(model, opt);
    std::vector<std::vector<g2l::ObjectBox>> boxes;  // each frame's detections, found once
    for (const auto& v : views) boxes.push_back(est.detect(v));
    double rss_1000 = -1;
    const int mark = std::min(1000, std::max(1, frames / 10));
    int poses = 0;
    const auto t0 = std::chrono::steady_clock::now();
    for (int n = 0; n < frames; ++n) {
        const size_t k = size_t(n) % views.size();
        if (!boxes[k].empty()) {
            const g2l::ObjectBox b = boxes[k][size_t(n / int(views.size())) % boxes[k].size()];
            for (const auto& p : est.estimate(views[k], {b})) poses += p.ok();
        }
        if (n % 25 == 0) {
            est.estimate(views[k], {{boxes[k].empty() ? 1 : boxes[k][0].obj_id, 5000, 5000, 10, 10}});
            est.estimate(nan_view, boxes[0]);
        }
        if (n % 100 == 0) poses += int(est.estimate(views[k]).size());
        if (n + 1 == mark) rss_1000 = g2l::tools::current_rss_mb();
    }
    const double rss_end = g2l::tools::current_rss_mb();
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const std::string what = g2l::cat(frames, " frames through one PoseEstimator on ", root,
                                      "/train_real/", scene, " (", poses, " poses, ", secs,
                                      " s): resident ", rss_1000, " MB at frame ", mark, ", ",
                                      rss_end, " MB at the end");
    return {{"soak_rss_growth_pct", 100.0 * (rss_end - rss_1000) / rss_1000, "%", what},
            {"soak_rss_mb", rss_end, "MB", what}};
}

/// Everything the command line asks for.
struct Job {
    bool json = false, quick = false, pose_only = false, verbose = false;
    int reps = 7, threads = 0, train_reps = 5, pose_reps = 21, det_reps = 30, refine_reps = 9;
    int frame_reps = 9, frame_objects = 4, soak_frames = 0;
    double width = 1.0;
    std::string frame_model = std::string(G2L_SOURCE_DIR) + "/models/ycbv_sim2real.g2l";
    std::string frame_detector = std::string(G2L_SOURCE_DIR) + "/models/ycbv_detector.g2l";
};

void add_options(CLI::App& app, Job& j) {
    app.add_flag("--json", j.json, "print one JSON object instead of a table");
    app.add_flag("--quick", j.quick, "fewer and smaller measurements (for smoke tests)");
    app.add_option("--reps", j.reps, "timed repetitions per figure (median reported)")
        ->check(CLI::Range(1, 1000));
    app.add_option("--threads", j.threads, "OpenMP threads (0 = OMP_NUM_THREADS / all cores)")
        ->check(CLI::Range(0, 1024));
    app.add_option("--train-reps", j.train_reps, "timed G2L-Net training steps (0 = skip)")
        ->check(CLI::Range(0, 1000));
    app.add_option("--width", j.width, "G2L-Net width multiplier for the training figure")
        ->check(CLI::Range(0.01, 4.0));
    app.add_option("--pose-reps", j.pose_reps, "timed batch-1 pose estimations per setting (0 = skip)")
        ->check(g2l::cli::at_least(0));
    app.add_option("--detector-reps", j.det_reps, "timed 2D-detector runs on a 640 x 480 frame "
                                                  "(0 = skip)")
        ->check(CLI::Range(0, 100000));
    app.add_option("--refine-reps", j.refine_reps, "timed depth refinements (--refine turns) of "
                                                    "one object (0 = skip)")
        ->check(CLI::Range(0, 100000));
    app.add_flag("--pose-only", j.pose_only, "only the batch-1 pose figures (and peak RSS)");
    app.add_option("--frame-reps", j.frame_reps, "timed runs of the whole pipeline on one real "
                                                 "frame: detector, poses, refinement (0 = skip)")
        ->check(CLI::Range(0, 100000));
    app.add_option("--frame-objects", j.frame_objects, "boxes posed per frame (the detector's best)")
        ->check(CLI::Range(1, 64));
    app.add_option("--frame-model", j.frame_model, "pose model of the frame figure")
        ->capture_default_str();
    app.add_option("--frame-detector", j.frame_detector, "detector of the frame figure")
        ->capture_default_str();
    app.add_option("--soak-frames", j.soak_frames,
                   "frames through one PoseEstimator for soak_rss_growth_pct (resident memory at "
                   "frame 1000 against the end; 10000 takes ~5 min; 0 = skip)")
        ->check(CLI::Range(0, 10000000));
    app.add_flag("--verbose", j.verbose,
                 "error messages with their source location (also G2L_VERBOSE=1)");
}

/// Every figure the job asks for, in the order printed.
std::vector<g2l::tools::BenchFigure> measure(const Job& j) {
    using Figures = std::vector<g2l::tools::BenchFigure>;
    Figures figs = j.pose_only ? Figures{} : g2l::tools::bench_engine(j.reps, j.quick);
    auto add = [&](const Figures& f) { figs.insert(figs.end(), f.begin(), f.end()); };
    if (j.pose_reps > 0) {
        // The settings: paper widths, 1500 -> 1000 points ("paper") and
        // 1024 -> 512 ("fast"), batch 1.
        const int pr = j.quick ? 2 : j.pose_reps;
        for (const auto& [name, cp, op] : {std::tuple<const char*, int, int>{"pose_ms_paper", 1500, 1000},
                                           {"pose_ms_fast", 1024, 512}}) {
            add(g2l::tools::bench_pose(name, pr, 1.0, cp, op, true));
            add(g2l::tools::bench_pose(std::string("graph_") + name, pr, 1.0, cp, op, false));
        }
    }
    if (j.det_reps > 0)
        for (bool mirror : {false, true})
            add(g2l::tools::bench_detector(j.quick ? 2 : j.det_reps, 16, 2, mirror));
    if (j.refine_reps > 0) add(g2l::tools::bench_refine(j.quick ? 2 : j.refine_reps));
    if (j.frame_reps > 0 && !j.pose_only) {
        add(bench_frame(j.quick ? 2 : j.frame_reps, j.frame_model, j.frame_detector,
                        j.frame_objects));
        add(bench_track(j.quick ? 1 : 3, j.frame_model, j.frame_detector));
    }
    if (j.soak_frames > 0) add(bench_soak(j.soak_frames, j.frame_model, j.frame_detector));
    if (j.train_reps > 0 && !j.pose_only) {
        // The setting: paper architecture, batch 8, 1500 -> 1000 points.
        add(j.quick ? g2l::tools::bench_training(1, j.width, 2, 300, 200)
                    : g2l::tools::bench_training(j.train_reps, j.width, 8, 1500, 1000));
    }
    figs.push_back({"peak_rss_mb", g2l::tools::peak_rss_mb(), "MB", "peak resident set size of this run"});
    return figs;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"g2l_bench: times the g2l engine on G2L-Net layer shapes (medians of repeated "
                 "runs). Figures are machine-dependent; see docs/results.md for recorded ones."};
    Job j;
    add_options(app, j);
    if (const int rc = g2l::cli::parse(app, argc, argv, "g2l_bench"); rc >= 0) return rc;
    try {
        if (j.threads > 0) g2l::set_num_threads(j.threads);
        const auto figs = measure(j);
        if (j.json) {
            nlohmann::json out;
            out["threads"] = g2l::num_threads();
            for (const auto& f : figs) out[f.name] = f.value;
            std::cout << out.dump(2) << "\n";
        } else {
            std::printf("g2l_bench (%d threads, median of %d)\n", g2l::num_threads(), j.reps);
            for (const auto& f : figs)
                std::printf("  %-28s %10.2f %-9s  %s\n", f.name.c_str(), f.value, f.unit.c_str(),
                            f.detail.c_str());
        }
        return 0;
    } catch (const std::exception& e) {
        return g2l::cli::report("g2l_bench", e, j.verbose);
    }
}
