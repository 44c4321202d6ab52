// SPDX-License-Identifier: MIT
#include "train/trainer.h"
#include "train/run_dir.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <memory>
#include <nlohmann/json.hpp>

#include "core/autograd.h"
#include "core/checkpoint.h"
#include "core/threads.h"
#include "data/bop.h"
#include "geometry/keypoints.h"
#include "geometry/symmetry.h"
#include "nn/models/g2l_net.h"
#include "nn/ops/elementwise.h"
#include "nn/optim.h"
#include "nn/schedule.h"
#include "eval/evaluate.h"
#include "nn/data_parallel.h"
#include "train/distributed.h"
#include "train/model_io.h"
#include "train/pipeline.h"
#include "train/sources.h"

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace g2l::train {

using eval::EvalOptions;
using eval::EvalReport;
using eval::evaluate_gt_boxes;
using eval::report_json;

namespace {

using Clock = std::chrono::steady_clock;

uint64_t mix(uint64_t a, uint64_t b) { return mix_seed(a, b); }

// Everything the run reads: datasets, meshes, the sample maker, keypoints.
struct RunData {
    std::vector<std::unique_ptr<data::BopDataset>> datasets;  // owns meshes of BOP sources
    std::map<int, train::SampleModel> models;                 // obj_id -> mesh + info
    std::map<int, int> class_of;                              // obj_id -> class index
    KeypointTable keypoints;                                  // class index -> K keypoints
    SymmetricKeypoints sym_keypoints;  // class index -> symmetric keypoint sets (if enabled)
    std::unique_ptr<SampleMaker> maker;
    struct Src {
        const SourceConfig* cfg;
        data::BopDataset* bop = nullptr;  // type bop
        std::vector<data::SceneModel> scene_models;  // type synthetic
        data::SceneConfig scene;
    };
    std::vector<Src> train, val;
};

// `extra_ids`: models loaded besides the source's objects (a synthetic scene's distractors,
// which need no class).
data::BopDataset* open_source_dataset(RunData& rd, const TrainConfig& cfg, const SourceConfig& s,
                                     bool models_only, const std::vector<int>& extra_ids = {}) {
    data::BopOptions o;
    o.scenes = s.scenes;
    o.obj_ids = source_objects(cfg, s);
    for (const int id : extra_ids)
        if (std::find(o.obj_ids.begin(), o.obj_ids.end(), id) == o.obj_ids.end())
            o.obj_ids.push_back(id);
    o.models_eval = s.models_eval;
    const std::string root = s.type == "bop" ? s.root : s.models_root;
    const std::string split = models_only ? "" : s.split;
    rd.datasets.push_back(std::make_unique<data::BopDataset>(
        models_only ? data::BopDataset(data::open_bop_models(root, o), "", {})
                    : data::open_bop(root, split, o)));
    return rd.datasets.back().get();
}

void add_models(RunData& rd, const data::Dataset& ds) {
    for (const auto& [id, om] : ds.models()) {
        if (!rd.class_of.count(id) || rd.models.count(id)) continue;
        rd.models[id] = SampleModel{&ds.load_model_mesh(id), om.info};
    }
}

// Every image a run will read, checked before the first step: the depth PNGs of the
// validation sets are decoded in full (a corrupt, truncated or 8-bit file is found now, not
// after the first epoch); the training sets' images, which may be many, by their headers
// (size against the intrinsics). Throws g2l::Error naming the file.
void preflight_images(const RunData& rd, bool verbose) {
    size_t decoded = 0, probed = 0;
    for (const auto* list : {&rd.val, &rd.train}) {
        const bool full = list == &rd.val;
        for (const auto& src : *list) {
            if (!src.bop) continue;
            for (const auto& f : src.bop->frames()) {
                if (f.depth_path.empty()) continue;
                int w = 0, h = 0;
                if (full) {
                    (void)data::load_depth_png(f.depth_path, &w, &h);
                    ++decoded;
                } else {
                    data::image_size(f.depth_path, &w, &h);
                    ++probed;
                }
                G2L_CHECK(w == f.K.width && h == f.K.height, "depth image '", f.depth_path, "' is ",
                          w, " x ", h, " but its camera is ", f.K.width, " x ", f.K.height);
            }
        }
    }
    if (verbose && decoded + probed > 0)
        std::printf("checked %zu validation depth images (decoded) and %zu training depth images "
                    "(headers)\n", decoded, probed);
}

RunData prepare_data(const TrainConfig& cfg, bool verbose) {
    RunData rd;
    for (size_t i = 0; i < cfg.data.object_ids.size(); ++i)
        rd.class_of[cfg.data.object_ids[i]] = int(i);
    auto add = [&](const SourceConfig& s, std::vector<RunData::Src>& list) {
        RunData::Src src;
        src.cfg = &s;
        if (s.type == "bop") {
            src.bop = open_source_dataset(rd, cfg, s, false);
            add_models(rd, *src.bop);
        } else {
            // The scene's distractors are rendered but never annotated: their meshes load
            // with the source's objects, and the targets stay the source's objects.
            src.scene = source_scene(s, "data.train/val synthetic source");
            if (src.scene.target_obj_ids.empty())
                src.scene.target_obj_ids = source_objects(cfg, s);
            data::BopDataset* ds =
                open_source_dataset(rd, cfg, s, true, src.scene.distractor_obj_ids);
            add_models(rd, *ds);
            for (const auto& [id, om] : ds->models())
                src.scene_models.push_back({id, &ds->load_model_mesh(id)});
        }
        list.push_back(std::move(src));
    };
    for (const auto& s : cfg.data.train) add(s, rd.train);
    for (const auto& s : cfg.data.val) add(s, rd.val);
    for (const auto& [id, cls] : rd.class_of)
        G2L_CHECK(rd.models.count(id), "data.object_ids: object ", id,
                  " has no model in any configured source");
    rd.keypoints.resize(rd.class_of.size());
    for (const auto& [id, cls] : rd.class_of) {
        const geom::Points kp = geom::keypoints(*rd.models[id].mesh, rd.models[id].info,
                                                cfg.model.keypoints);
        for (int64_t k = 0; k < kp.rows(); ++k) rd.keypoints[size_t(cls)].push_back(kp.row(k).transpose());
    }
    SampleConfig sc;
    sc.crop = cfg.sampling.crop;
    sc.points = cfg.sampling.points;
    sc.radius_scale = cfg.sampling.radius_scale;
    sc.center_jitter_mm = cfg.sampling.center_jitter_mm;
    sc.box_jitter_frac = cfg.sampling.box_jitter_frac;
    sc.label_threshold_mm = cfg.sampling.label_threshold_mm;
    sc.min_points = cfg.sampling.min_points;
    sc.shift_mm = cfg.augment.shift_mm;
    sc.rot_deg = cfg.augment.rot_deg;
    sc.point_noise_mm = cfg.augment.point_noise_mm;
    sc.augment = cfg.augment.enabled;
    rd.maker = std::make_unique<SampleMaker>(sc, rd.models, rd.class_of,
                                             cfg.sampling.surface_spacing_mm);
    if (cfg.loss.symmetric_targets) {
        rd.sym_keypoints.resize(rd.class_of.size());
        for (const auto& [id, cls] : rd.class_of) {
            // The sample maker's labelling tree: the same mesh surface, built once.
            const auto syms = geom::geometric_symmetries(rd.maker->tree(id), rd.maker->info(id));
            for (const auto& s : syms) {
                std::vector<Eigen::Vector3f> set;
                for (const auto& p : rd.keypoints[size_t(cls)]) set.push_back(s.R * p + s.t);
                rd.sym_keypoints[size_t(cls)].push_back(std::move(set));
            }
            if (verbose)
                std::printf("object %d: %zu geometric symmetr%s (rotation targets take the nearest)\n",
                            id, syms.size(), syms.size() == 1 ? "y" : "ies");
        }
        std::fflush(stdout);
    }
    return rd;
}

// One epoch's visiting order: (source, index) blocks. BOP instances are shuffled one by one;
// the instances of one synthetic frame stay together (the frame renders once).
struct Item {
    int source;
    int64_t index;
};

struct Sources {
    std::vector<std::unique_ptr<SampleSource>> list;
};

Sources make_train_sources(const RunData& rd, const TrainConfig& cfg, int epoch) {
    Sources s;
    for (const auto& src : rd.train) {
        if (src.bop) {
            // The stricter of the source's and the sampling section's visibility floors.
            s.list.push_back(std::make_unique<BopSource>(
                *src.bop, *rd.maker,
                std::max(src.cfg->min_visib_fract, cfg.sampling.min_visib_fract),
                src.cfg->max_frames));
        } else {
            data::SceneConfig scene = src.scene;
            scene.seed = mix(mix(cfg.seed, uint64_t(epoch)), scene.seed);  // fresh renders
            s.list.push_back(std::make_unique<SyntheticSource>(scene, src.scene_models, *rd.maker,
                                                               src.cfg->frames, 1,
                                                               cfg.sampling.min_visib_fract));
        }
    }
    return s;
}

std::vector<Item> epoch_order(const Sources& s, const RunData& rd, const TrainConfig& cfg, int epoch) {
    std::vector<std::vector<Item>> blocks;
    for (size_t i = 0; i < s.list.size(); ++i) {
        const int64_t n = s.list[i]->size();
        const int64_t per = rd.train[i].bop ? 1 : std::max(1, rd.train[i].scene.targets_max);
        for (int64_t b = 0; b < n; b += per) {
            std::vector<Item> blk;
            for (int64_t k = b; k < std::min(n, b + per); ++k) blk.push_back({int(i), k});
            blocks.push_back(std::move(blk));
        }
    }
    Rng rng(mix(cfg.seed, 1000003ull + uint64_t(epoch)));
    for (size_t i = blocks.size(); i > 1; --i) std::swap(blocks[i - 1], blocks[rng.below(i)]);
    std::vector<Item> order;
    for (auto& b : blocks) order.insert(order.end(), b.begin(), b.end());
    if (cfg.train.samples_per_epoch > 0 && !order.empty()) {
        std::vector<Item> cut;
        for (int64_t i = 0; int64_t(cut.size()) < cfg.train.samples_per_epoch * 2 &&
                            i < int64_t(order.size()) * 4; ++i)
            cut.push_back(order[size_t(i) % order.size()]);
        order.swap(cut);  // twice the target: unusable crops are skipped (see run loop)
    }
    return order;
}

std::string fmt_time(double s) {
    char b[32];
    const int t = int(s + 0.5);
    std::snprintf(b, sizeof b, "%d:%02d:%02d", t / 3600, (t / 60) % 60, t % 60);
    return b;
}

}  // namespace

TrainSummary run_training(const TrainConfig& cfg, const TrainOptions& opt) {
    if (cfg.threads > 0) set_num_threads(cfg.threads);
    G2L_CHECK(parse_device(cfg.device).is_cpu(), "device '", cfg.device,
              "': training runs on the CPU in this version (the CUDA backend is not complete)");
    // ---- the run directory first: a bad one is found before any data is read ----
    const std::string run_dir = opt.resume_dir.empty() ? cfg.run_dir : opt.resume_dir;
    // Data-parallel (train/distributed.h): this process trains on samples [lo, hi) of every
    // global batch; rank 0 alone writes the run directory, logs and prints.
    const bool root = dist::is_root();
    const bool progress = opt.progress && root;
    const std::pair<int64_t, int64_t> shard = dist::shard(cfg.train.batch);
    const int64_t lo = shard.first, hi = shard.second;
    const RunDir run(run_dir, !opt.resume_dir.empty(), opt.force, {"steps.jsonl", "epochs.jsonl"},
                     root);
    RunData rd = prepare_data(cfg, progress);
    preflight_images(rd, progress);
    G2L_CHECK(!rd.train.empty(), "data.train: no training source configured");

    nn::G2LConfig mc = model_config(cfg, rd.keypoints.empty() ? 8 : int(rd.keypoints[0].size()));
    nn::G2LNet net(mc);
    nn::G2LLrMults mults{cfg.optim.lr_mult.seg, cfg.optim.lr_mult.tnet, cfg.optim.lr_mult.evf,
                         cfg.optim.lr_mult.rot, cfg.optim.lr_mult.rre};
    nn::AdamOptions ao;
    ao.lr = cfg.optim.lr;
    ao.beta1 = cfg.optim.beta1;
    ao.beta2 = cfg.optim.beta2;
    ao.eps = cfg.optim.eps;
    nn::Adam adam(net.param_groups(mults, cfg.optim.weight_decay), ao);
    const auto schedule = nn::make_schedule(cfg.schedule.kind, cfg.optim.lr,
                                            cfg.schedule.step_epochs, cfg.schedule.gamma,
                                            cfg.train.epochs);
    LossWeights lw;
    lw.seg = cfg.loss.seg; lw.t = cfg.loss.t; lw.vec = cfg.loss.vec; lw.kp = cfg.loss.kp;
    lw.res = cfg.loss.res; lw.t_smooth_l1 = cfg.loss.t_loss == "smooth_l1";
    StepOptions so;
    for (const auto& kp : rd.keypoints) so.rot_scale.push_back(float(nn::rotation_scale(mc.rot_unit, kp)));
    so.centre_noise_mm = cfg.loss.rot_centre_noise_mm;
    so.centre_with_prediction = cfg.loss.rot_centre == "pred";

    // ---- resume state ----
    int epoch = 0;
    int64_t pos = 0, global_step = 0, epoch_batches = 0;
    double epoch_loss = 0, best_val = -1;
    double seconds_before = 0;  // training time of earlier sessions of this run
    if (!opt.resume_dir.empty()) {
        const ResumeState st = load_training_checkpoint(run.path("last.g2l"), net, adam);
        epoch = st.epoch; pos = st.pos; global_step = st.global_step;
        epoch_batches = st.epoch_batches; epoch_loss = st.epoch_loss; best_val = st.best_val;
        seconds_before = st.seconds;
        G2L_CHECK(epoch < cfg.train.epochs, "--resume '", run_dir, "': the run already finished its ",
                  cfg.train.epochs, " epochs (", global_step, " steps); to train on, resume with "
                  "--set train.epochs=N (N > ", cfg.train.epochs, ")");
        run.trim_log("steps.jsonl", "step", global_step);
        run.trim_log("epochs.jsonl", "epoch", epoch - 1);
    }
    run.begin(config_to_json(cfg) + "\n");
    if (progress && dist::size() > 1) {
        int64_t params = 0;
        for (const nn::ParamGroup& g : adam.groups())
            for (const auto& p : g.params) params += p.second.numel();
        std::printf("data-parallel: %d processes, %lld of the %d samples of each batch here; one "
                    "all-reduce of %lld parameters (%.2f MB) per step\n", dist::size(),
                    (long long)(hi - lo), cfg.train.batch, (long long)params, params * 4e-6);
    }
    const bool tty = progress && isatty(fileno(stdout));

    TrainSummary sum;
    sum.run_dir = run_dir;
    const auto t_start = Clock::now();
    int64_t samples_done = 0;
    std::map<int, nn::ModelObjectInfo> objects;  // stored so exports know each crop's radius
    for (const auto& [id, cls] : rd.class_of) {
        (void)cls;
        const geom::ModelInfo& mi = rd.maker->info(id);
        objects[id] = {mi.diameter, mi.symmetric};
    }
    auto save = [&](const std::string& name) {
        if (!root) return;  // the checkpoint holds the global state: one writer
        const double now = std::chrono::duration<double>(Clock::now() - t_start).count();
        ResumeState st{epoch, pos, global_step, epoch_batches, epoch_loss, best_val,
                       seconds_before + now};
        save_training_checkpoint(run.path(name), net, adam, cfg, rd.class_of,
                                 rd.keypoints, st, objects);
    };
    bool stop = false;
    std::string stop_reason;  // "signal", "max_steps" or "time_limit"
    while (epoch < cfg.train.epochs && !stop) {
        adam.set_lr(schedule->lr_at(epoch));
        Sources sources = make_train_sources(rd, cfg, epoch);
        const std::vector<Item> order = epoch_order(sources, rd, cfg, epoch);
        const int64_t target = cfg.train.samples_per_epoch > 0 ? cfg.train.samples_per_epoch
                                                               : int64_t(order.size());
        const int64_t batches_per_epoch = std::max<int64_t>(1, target / cfg.train.batch);
        net.train();
        const auto t_epoch = Clock::now();
        int64_t tried = 0, failed = 0;
        G2L_CHECK(!order.empty(), "training data: epoch ", epoch, " has no sample to visit");
        // Slot i of global batch b is order position b * batch + i; an unusable crop there is
        // replaced by positions drawn from (seed, slot, attempt). A slot's sample thus depends
        // only on (epoch, b, i), never on which process makes it or on the other slots: this
        // process makes slots [lo, hi), and the global batch is the same for any number of
        // processes (without unusable crops it is the consecutive walk through `order`).
        // Only `fetch` reads `sources`, and at most one call is in flight, so the prefetch
        // thread and the serial path make the same batches.
        struct Fetched {
            std::vector<PoseSample> batch;
            int64_t tried = 0, failed = 0;
        };
        auto fetch = [&](int64_t b) {
            Fetched f;
            const uint64_t n = order.size();
            for (int64_t i = lo; i < hi; ++i) {
                const uint64_t slot = uint64_t(b * cfg.train.batch + i);
                for (int a = 0;; ++a) {
                    G2L_CHECK(a < 64, "training data: 64 crops in a row were unusable (too few "
                              "points) at epoch ", epoch, " batch ", b, " slot ", i, " — check the "
                              "sources, sampling.min_points and the depth data");
                    const uint64_t p = a == 0 ? slot % n : mix(mix(cfg.seed ^ 0x510Full, slot),
                                                               uint64_t(a)) % n;
                    const Item it = order[size_t(p)];
                    Rng srng(mix(mix(cfg.seed, uint64_t(epoch) * 7919 + uint64_t(it.source)),
                                 uint64_t(it.index)));
                    PoseSample s;
                    ++f.tried;
                    if (sources.list[size_t(it.source)]->get(it.index, srng, &s)) {
                        f.batch.push_back(std::move(s));
                        break;
                    }
                    ++f.failed;
                }
            }
            return f;
        };
        std::future<Fetched> ahead;
        const bool prefetch = cfg.train.prefetch;
        if (prefetch && epoch_batches < batches_per_epoch)
            ahead = std::async(std::launch::async, fetch, epoch_batches);
        while (epoch_batches < batches_per_epoch) {
            Fetched got = prefetch ? ahead.get() : fetch(epoch_batches);
            tried += got.tried;
            failed += got.failed;
            std::vector<PoseSample> batch = std::move(got.batch);
            if (prefetch && epoch_batches + 1 < batches_per_epoch)
                ahead = std::async(std::launch::async, fetch, epoch_batches + 1);
            G2L_CHECK(tried < 50 || failed * 10 < tried * 9, "training data: ", failed, " of ",
                      tried, " crops were unusable (too few points) — check the sources, "
                      "sampling.min_points and the depth data");
            // The step's random draws per sample, seeded by the sample's slot in the global
            // batch (the same for any number of processes).
            const uint64_t step_seed = mix(cfg.seed, 0xABCDEFull + uint64_t(global_step));
            Rng step_rng(step_seed);
            std::vector<Rng> sample_rngs;
            for (int64_t i = lo; i < hi; ++i) sample_rngs.emplace_back(mix(step_seed, uint64_t(i)));
            so.sample_rngs = &sample_rngs;
            const auto t0 = Clock::now();
            adam.zero_grad();
            so.rot_gt_points = epoch < cfg.loss.rot_only_epochs + cfg.loss.rot_gt_points_epochs;
            so.rot_only = epoch < cfg.loss.rot_only_epochs;
            // BatchNorm and dropout see the global batch through this hook (forward and
            // backward); each process's loss is weighted by its share of the batch, so the
            // summed gradients are those of the global batch's mean loss.
            const nn::DataParallel hook = dist::step_hook(cfg.train.batch, lo);
            const nn::DataParallelGuard hook_on(&hook);
            const double share = double(hi - lo) / double(cfg.train.batch);
            StepLosses L = g2l_step(net, batch, rd.keypoints, mc.num_classes,
                                    cfg.sampling.seg_points, lw, step_rng,
                                    rd.sym_keypoints.empty() ? nullptr : &rd.sym_keypoints, so);
            double loss = L.total.item<double>();
            if (!std::isfinite(loss)) {
                std::string objs;
                for (const auto& s : batch) objs += " " + std::to_string(s.obj_id);
                G2L_CHECK(false, "non-finite loss ", loss, " at step ", global_step, " (epoch ",
                          epoch, "; objects", objs, "; seg ", L.seg, " t ", L.t, " vec ", L.vec,
                          " kp ", L.kp, " res ", L.res, ")");
            }
            (dist::size() > 1 ? nn::mul_scalar(L.total, share) : L.total).backward();
            // One all-reduce: every gradient, the weighted log terms and the stop flags (a
            // signal or the time limit seen by any process stops all after this step).
            const double run_s = seconds_before +
                                 std::chrono::duration<double>(Clock::now() - t_start).count();
            std::vector<float> extra = {
                float(share * loss), float(share * L.seg), float(share * L.t),
                float(share * L.vec), float(share * L.kp), float(share * L.res),
                float(share * L.seg_accuracy), float(share * L.t_error_mm),
                float(share * L.kp_error_mm), float(share * L.sym_fraction),
                opt.stop_flag && opt.stop_flag->load() ? 1.f : 0.f,
                cfg.train.time_limit_min > 0 && run_s > cfg.train.time_limit_min * 60 ? 1.f : 0.f};
            const double allreduce_s = dist::allreduce_gradients(adam, extra);
            if (dist::size() > 1) {
                loss = extra[0], L.seg = extra[1], L.t = extra[2], L.vec = extra[3];
                L.kp = extra[4], L.res = extra[5], L.seg_accuracy = extra[6];
                L.t_error_mm = extra[7], L.kp_error_mm = extra[8], L.sym_fraction = extra[9];
            }
            const bool any_signal = extra[10] > 0, any_time_limit = extra[11] > 0;
            adam.step();
            const double dt = std::chrono::duration<double>(Clock::now() - t0).count();
            ++global_step;
            ++epoch_batches;
            epoch_loss += loss;
            samples_done += cfg.train.batch;  // the global batch (every process)
            pos = epoch_batches * cfg.train.batch;  // the checkpoint's order position
            sum.last_loss = epoch_loss / double(epoch_batches);
            if (global_step % std::max(1, cfg.train.log_every) == 0 || epoch_batches == 1) {
                json j = {{"step", global_step}, {"epoch", epoch}, {"lr", adam.lr()},
                          {"loss", loss}, {"seg", L.seg}, {"t", L.t}, {"vec", L.vec},
                          {"kp", L.kp}, {"res", L.res}, {"seg_acc", L.seg_accuracy},
                          {"t_err_mm", L.t_error_mm}, {"kp_err_mm", L.kp_error_mm},
                          {"sym_frac", L.sym_fraction},
                          {"step_s", dt}};
                if (dist::size() > 1) j["allreduce_s"] = allreduce_s;
                run.append("steps.jsonl", j);
            }
            const double elapsed = std::chrono::duration<double>(Clock::now() - t_start).count();
            const double sps = samples_done / std::max(1e-9, elapsed);
            const double remaining_batches = double(batches_per_epoch - epoch_batches) +
                                             double(cfg.train.epochs - epoch - 1) * batches_per_epoch;
            double eta = remaining_batches * cfg.train.batch / std::max(1e-9, sps);
            const double run_seconds = seconds_before + elapsed;  // across resumes
            if (cfg.train.time_limit_min > 0)  // the run stops at the time limit
                eta = std::min(eta, std::max(0.0, cfg.train.time_limit_min * 60 - run_seconds));
            if (tty) {
                const int width = 24;
                const int fill = int(width * epoch_batches / batches_per_epoch);
                std::printf("\repoch %d/%d [%s%s] %lld/%lld loss %.4f (seg %.3f t %.1f kp %.1f) "
                            "%.2f samples/s ETA %s   ",
                            epoch + 1, cfg.train.epochs, std::string(size_t(fill), '#').c_str(),
                            std::string(size_t(width - fill), '.').c_str(),
                            (long long)epoch_batches, (long long)batches_per_epoch, loss, L.seg,
                            L.t, L.kp, sps, fmt_time(eta).c_str());
                std::fflush(stdout);
            } else if (progress && (global_step % std::max(1, cfg.train.log_every) == 0)) {
                std::printf("epoch %d/%d step %lld (%lld/%lld) loss %.4f seg %.4f t %.2f vec %.4f "
                            "kp %.2f res %.2f | %.2f samples/s ETA %s\n",
                            epoch + 1, cfg.train.epochs, (long long)global_step,
                            (long long)epoch_batches, (long long)batches_per_epoch, loss, L.seg,
                            L.t, L.vec, L.kp, L.res, sps, fmt_time(eta).c_str());
                std::fflush(stdout);
            }
            if (opt.max_steps > 0 && global_step >= opt.max_steps) stop_reason = "max_steps";
            if (any_time_limit) stop_reason = "time_limit";
            if (any_signal) {
                stop_reason = "signal";
                sum.interrupted = true;
            }
            stop = !stop_reason.empty();
            if (stop) break;
        }
        if (tty) std::printf("\n");
        if (stop && epoch_batches < batches_per_epoch) {
            save("last.g2l");
            sum.stopped_early = true;
            break;
        }
        // ---- end of epoch: validation, logs, checkpoints ----
        json ej = {{"epoch", epoch}, {"loss", epoch_batches ? epoch_loss / epoch_batches : 0.0},
                   {"batches", epoch_batches}, {"lr", adam.lr()},
                   {"seconds", std::chrono::duration<double>(Clock::now() - t_epoch).count()}};
        const bool val_epoch = !sum.interrupted && !rd.val.empty() && cfg.train.val_every > 0 &&
                            ((epoch + 1) % cfg.train.val_every == 0 || epoch + 1 == cfg.train.epochs);
        const bool do_val = root && val_epoch;  // rank 0 validates alone
        double val_auc = -1;
        if (do_val) {
            double s = 0;
            int n = 0;
            for (const auto& v : rd.val) {
                if (!v.bop) continue;
                EvalOptions eo;
                eo.crop = infer::parse_crop(cfg.sampling.crop, "sampling.crop");
                eo.radius_scale = cfg.sampling.radius_scale;
                eo.crop_points = cfg.sampling.points;
                eo.max_object_points = cfg.sampling.seg_points;
                eo.max_instances = cfg.train.max_val_samples;
                eo.min_visib_fract = v.cfg->min_visib_fract;
                const EvalReport r = evaluate_gt_boxes(net, *v.bop, rd.class_of, rd.keypoints, eo);
                ej["val"].push_back(json::parse(report_json(r)));
                // Model selection by what users see: the ADD accuracy modulo the geometric
                // symmetries (the YCB AUC's 10 cm threshold rewards random rotations).
                s += r.average.acc_addsym_10;
                ++n;
            }
            if (n) {
                val_auc = s / n;
                ej["val_acc_addsym_10"] = val_auc;
            }
        }
        if (val_epoch) dist::barrier();  // the other processes sleep while rank 0 validates
        run.append("epochs.jsonl", ej);
        if (progress)
            std::printf("epoch %d/%d done: loss %.4f%s\n", epoch + 1, cfg.train.epochs,
                    epoch_batches ? epoch_loss / epoch_batches : 0.0,
                    val_auc >= 0 ? (" val ADD-sym acc@0.1d " + std::to_string(val_auc)).c_str() : "");
        std::fflush(stdout);
        ++epoch;
        pos = 0;
        epoch_batches = 0;
        epoch_loss = 0;
        sum.epochs_done = epoch;
        if (val_auc > best_val) {
            best_val = val_auc;
            save("best.g2l");
        }
        if (cfg.train.checkpoint_every > 0 && epoch % cfg.train.checkpoint_every == 0)
            save("epoch_" + std::to_string(epoch) + ".g2l");
        save("last.g2l");
        if (stop) {
            sum.stopped_early = epoch < cfg.train.epochs;
            break;
        }
    }
    // A stopped run's log ends at the step its last.g2l holds (the loss records come every
    // log_every steps): what --resume continues from is in the log, with why it stopped.
    if (sum.stopped_early)
        run.append("steps.jsonl", {{"step", global_step}, {"epoch", epoch},
                                   {"event", "stopped"}, {"reason", stop_reason},
                                   {"checkpoint", "last.g2l"}});
    const double elapsed = std::chrono::duration<double>(Clock::now() - t_start).count();
    sum.steps = global_step;
    sum.epochs_done = epoch;
    sum.best_val = best_val;
    sum.samples_per_s = samples_done / std::max(1e-9, elapsed);
    return sum;
}

}  // namespace g2l::train
