// SPDX-License-Identifier: MIT
// g2l_train: trains G2L-Net from a JSON config (docs/config.md).
#include <CLI/CLI.hpp>
#include "core/error.h"
#include <nlohmann/json.hpp>
#include <atomic>
#include <csignal>
#include <filesystem>

#include "core/cli.h"
#include <cstdio>

#include "train/config.h"
#include "train/detector_train.h"
#include "train/distributed.h"
#include "train/model_io.h"
#include "train/own_objects.h"
#include "train/trainer.h"

namespace {
// SIGINT / SIGTERM: the trainer finishes its step, writes last.g2l and returns.
std::atomic<bool> g_stop{false};
volatile std::sig_atomic_t g_signal = 0;
extern "C" void on_signal(int sig) {
    g_signal = sig;
    g_stop.store(true);
}
// MPI (train/distributed.h) from the first line of main to its return; a no-op without mpirun.
struct DistSession {
    DistSession(int* argc, char*** argv) { g2l::train::dist::init(argc, argv); }
    ~DistSession() { g2l::train::dist::finalize(); }
};
}  // namespace

namespace {

/// --resume: a change of what the checkpoint's weights mean (which objects the classes are and
/// in which order, the keypoints, the widths, the heads), by --set or by a --config other than
/// the run's own, would load them into a network that reads them otherwise; refused, naming the
/// key and both values. The run's config.json says what the weights were trained with. The
/// schedule, the epochs, the learning rate and the like may change.
void refuse_meaning_changes(const std::string& run, const std::string& cfg_path,
                            const std::vector<std::string>& sets, bool detector) {
    using json = nlohmann::json;
    const std::string saved_path = run + "/config.json";
    if (!std::filesystem::exists(saved_path)) return;  // the trainer names what the run lacks
    const auto as_json = [&](const std::string& path, const std::vector<std::string>& s) {
        return json::parse(detector ? g2l::train::detector_config_to_json(
                                          g2l::train::load_detector_config(path, s))
                                    : g2l::train::config_to_json(g2l::train::load_config(path, s)));
    };
    const json saved = as_json(saved_path, {}), now = as_json(cfg_path, sets);
    const json file = sets.empty() ? now : as_json(cfg_path, {});
    const std::vector<std::string> keys =
        detector ? std::vector<std::string>{"/data/object_ids", "/data/input", "/data/downscale",
                                            "/model/width"}
                 : std::vector<std::string>{"/data/object_ids", "/model/num_classes",
                                            "/model/keypoints", "/model/evf", "/model/rre",
                                            "/model/width", "/model/out_scale_mm",
                                            "/model/rot_unit", "/model/class_heads"};
    for (const std::string& k : keys) {
        const json::json_pointer p(k);
        if (!saved.contains(p) || !now.contains(p) || saved.at(p) == now.at(p)) continue;
        std::string key = k.substr(1);
        for (char& c : key) c = c == '/' ? '.' : c;
        const bool by_set = !file.contains(p) || file.at(p) != now.at(p);
        const std::string how = by_set ? g2l::cat(" --set ", key, "=", now.at(p).dump())
                                       : g2l::cat(" with --config ", cfg_path, " (", key, " = ",
                                                  now.at(p).dump(), ")");
        G2L_CHECK(false, "--resume '", run, "'", how, ": the run's weights were trained with ",
                  key, " = ", saved.at(p).dump(),
                  " and would mean something else; start a new run (--config with a new "
                  "run_dir), or resume with the run's own config.json (--resume alone)");
    }
}

/// --export CHECKPOINT OUT and --average OUT CHECKPOINT...: an inference export, then exit.
int run_export(const std::vector<std::string>& export_args,
               const std::vector<std::string>& average_args, bool verbose) {
    try {
        if (!export_args.empty()) {
            const int64_t bytes = g2l::train::export_model(export_args[0], export_args[1]);
            std::printf("g2l_train: exported %s -> %s (%.1f MB)\n", export_args[0].c_str(),
                        export_args[1].c_str(), double(bytes) / 1e6);
            return 0;
        }
        const std::vector<std::string> src(average_args.begin() + 1, average_args.end());
        const int64_t bytes = g2l::nn::is_detector_export(src.front())
                                  ? g2l::train::export_detector_average(src, average_args[0])
                                  : g2l::train::export_average(src, average_args[0]);
        std::printf("g2l_train: the mean of %zu checkpoints -> %s (%.1f MB)\n", src.size(),
                    average_args[0].c_str(), double(bytes) / 1e6);
        return 0;
    } catch (const std::exception& e) {
        return g2l::cli::report("g2l_train", e, verbose);
    }
}


/// Everything the command line asks for.
struct Job {
    std::string config, resume;
    std::string objects, out, camera;  // --objects: your own meshes to RUN
    double minutes = 30;
    std::vector<std::string> sets, export_args, average_args;
    int64_t max_steps = 0;
    bool quiet = false, force = false, verbose = false;
};

void add_options(CLI::App& app, Job& j) {
    app.add_option("--config", j.config, "JSON config (see configs/ and docs/config.md)");
    app.add_option("--set", j.sets, "override a key, e.g. --set optim.lr=5e-4 --set "
                                    "data.train.0.frames=100 (repeatable)")
        ->check(g2l::cli::key_value());
    app.add_option("--resume", j.resume, "continue the run in this directory exactly where it "
                                          "stopped (uses its config.json unless --config is given)");
    app.add_option("--max-steps", j.max_steps, "stop with a checkpoint after this many optimizer "
                                               "steps in total (0 = train to the end)")
        ->check(g2l::cli::at_least(0));
    app.add_flag("--quiet", j.quiet, "no progress output (errors still go to stderr)");
    app.add_flag("--force", j.force, "start over in a run directory that already holds a run "
                                     "(without it such a directory is refused; see --resume)");
    app.add_option("--export", j.export_args,
                   "CHECKPOINT OUT: write an inference export of a training checkpoint (weights, "
                   "model config, object ids, keypoints; no optimizer state) and exit")
        ->expected(2);
    app.add_option("--average", j.average_args,
                   "OUT CHECKPOINT CHECKPOINT...: write an inference export whose weights are the "
                   "mean of two or more checkpoints of one run (e.g. its last epoch_N.g2l files) "
                   "and exit; with detector exports (detector.g2l), a detector export whose "
                   "weights and BatchNorm statistics are their mean")
        ->expected(3, 1000);
    app.add_option("--objects", j.objects,
                   "DIR: your own objects, one command: the meshes of DIR (.ply / .obj, any "
                   "names, mm or metres) become RUN/models (BOP, with diameters, symmetries and "
                   "obj_names.json), then a depth detector and a pose model train on renders of "
                   "them within --minutes and export RUN/detector.g2l and RUN/pose.g2l "
                   "(docs/own_objects.md)");
    app.add_option("--out", j.out, "RUN: the folder --objects writes");
    app.add_option("--minutes", j.minutes, "--objects: the whole budget, both trainings "
                                           "(default 30)")
        ->check(CLI::Range(0.1, 100000.0));
    app.add_option("--camera", j.camera,
                   "--objects: your camera (a BOP camera.json with width and height), which the "
                   "detector's renders use (default: YCB-Video's, 640 x 480, f 1067 px)");
    app.add_flag("--verbose", j.verbose,
                 "error messages with their source location (also G2L_VERBOSE=1)");
}

/// A run stopped by SIGINT / SIGTERM: it wrote its checkpoint; say how to continue. In a
/// data-parallel job every rank stops after the same step (the stop flags travel with the
/// gradients); rank 0, which wrote the checkpoint, says so.
int interrupted(int64_t steps, const std::string& run_dir) {
    const int sig = g_signal != 0 ? int(g_signal) : SIGTERM;
    if (g2l::train::dist::is_root())
        std::fprintf(stderr, "g2l_train: %s after step %lld: checkpoint written, continue "
                             "with --resume %s\n",
                     g_signal == 0      ? "stopped (another rank of the job got a signal)"
                     : sig == SIGINT    ? "interrupted (SIGINT)"
                                        : "terminated (SIGTERM)",
                     (long long)steps, run_dir.c_str());
    return 128 + sig;
}

/// --objects: the meshes to a detector and a pose model (train/own_objects.h).
int train_own_objects(const Job& j) {
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    g2l::train::OwnObjectsOptions o;
    o.objects_dir = j.objects;
    o.out_dir = j.out;
    o.minutes = j.minutes;
    o.camera = j.camera;
    o.max_steps = j.max_steps;
    o.force = j.force;
    o.progress = !j.quiet;
    o.stop_flag = &g_stop;
    const g2l::train::OwnObjectsSummary s = g2l::train::run_own_objects(o);
    if (s.interrupted) return interrupted(s.interrupted_steps, s.interrupted_run);
    if (!j.quiet)
        std::printf("g2l_train: %zu objects in %.1f min: %s, %s (meshes %s); poses with\n"
                    "  g2l_infer --model %s --detector %s --meshes %s --depth D.png --camera C.json\n",
                    s.objects.size(), s.minutes, s.detector.c_str(), s.pose.c_str(),
                    s.models.c_str(), s.pose.c_str(), s.detector.c_str(), s.models.c_str());
    return 0;
}

/// The training the config asks for (a pose model, or with "task": "detector" the detector),
/// its closing line; the exit code.
int train(const Job& j) {
    namespace dist = g2l::train::dist;
    const std::string cfg_path = j.config.empty() ? j.resume + "/config.json" : j.config;
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    g2l::train::TrainOptions opt;
    opt.resume_dir = j.resume;
    opt.max_steps = j.max_steps;
    opt.progress = !j.quiet;
    opt.force = j.force;
    opt.stop_flag = &g_stop;
    const bool detector = g2l::train::is_detector_config(cfg_path);  // "task": "detector"
    if (!j.resume.empty()) refuse_meaning_changes(j.resume, cfg_path, j.sets, detector);
    if (detector) {
        const auto dcfg = g2l::train::load_detector_config(cfg_path, j.sets);
        const auto s = g2l::train::run_detector_training(dcfg, opt);
        if (s.interrupted) return interrupted(s.steps, s.run_dir);
        if (!j.quiet && dist::is_root())
            std::printf("g2l_train: detector %s after %lld steps, %.1f images/s; export %s/"
                        "detector.g2l%s\n",
                        s.stopped_early ? "stopped" : "finished", (long long)s.steps,
                        s.images_per_s, s.run_dir.c_str(),
                        s.evaluated ? g2l::cat("; validation mean recall@0.5 ",
                                               100 * s.val.mean_recall, "%").c_str()
                                    : "");
        return 0;
    }
    g2l::train::TrainConfig cfg = g2l::train::load_config(cfg_path, j.sets);
    const auto s = g2l::train::run_training(cfg, opt);
    if (s.interrupted) return interrupted(s.steps, s.run_dir);
    if (!j.quiet && dist::is_root())
        std::printf("g2l_train: %s after %lld steps (%d epochs), %.2f samples/s; best val "
                    "ADD-sym acc@0.1d %s; run dir %s\n",
                    s.stopped_early ? "stopped" : "finished", (long long)s.steps, s.epochs_done,
                    s.samples_per_s, s.best_val >= 0 ? std::to_string(s.best_val).c_str() : "n/a",
                    s.run_dir.c_str());
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    const DistSession dist_session(&argc, &argv);
    CLI::App app{"g2l_train: trains G2L-Net (segmentation, translation and rotation networks) "
                 "from a JSON config. Writes the run directory: config.json, steps.jsonl, "
                 "epochs.jsonl, last.g2l, best.g2l, epoch_<k>.g2l. A config with \"task\": "
                 "\"detector\" trains the 2D detector instead (run directory: config.json, "
                 "steps.jsonl, last.g2l, detector.g2l)."};
    Job j;
    add_options(app, j);
    if (const int rc = g2l::cli::parse(app, argc, argv, "g2l_train"); rc >= 0) return rc;
    if (!j.export_args.empty() || !j.average_args.empty())
        return run_export(j.export_args, j.average_args, j.verbose);
    if (!j.objects.empty() || !j.out.empty()) {
        if (j.objects.empty() || j.out.empty() || !j.config.empty() || !j.resume.empty()) {
            std::fprintf(stderr, "g2l_train: --objects DIR needs --out RUN, and takes no --config "
                                 "or --resume (see g2l_train --help)\n");
            return 2;
        }
        try {
            return train_own_objects(j);
        } catch (const std::exception& e) {
            return g2l::cli::report("g2l_train", e, j.verbose);
        }
    }
    if (!j.camera.empty()) {
        std::fprintf(stderr, "g2l_train: --camera is an option of --objects\n");
        return 2;
    }
    if (j.config.empty() && j.resume.empty()) {
        std::fprintf(stderr, "g2l_train: give --config FILE (or --resume RUN_DIR)\n%s",
                     app.help().c_str());
        return 2;
    }
    try {
        return train(j);
    } catch (const std::exception& e) {
        // Under mpirun a failing rank would leave the others waiting in a collective: it ends
        // the whole job (MPI_Abort) after naming what failed. Checkpoints are written
        // atomically, so the last one stays intact.
        const int rc = g2l::cli::report("g2l_train", e, j.verbose);
        return g2l::train::dist::abort_job(std::string("failed: ") + e.what(), rc);
    }
}
