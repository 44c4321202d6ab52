// SPDX-License-Identifier: MIT
#include "train/trainer.h"
#include "train/loop.h"
#include "train/run_dir.h"


#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <cstdlib>
#include <fstream>
#include <future>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>

#include "core/autograd.h"
#include "core/checkpoint.h"
#include "core/threads.h"
#include "data/bop.h"
#include "geometry/keypoints.h"
#include "geometry/symmetry.h"
#include "nn/models/g2l_io.h"
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


uint64_t mix(uint64_t a, uint64_t b) { return mix_seed(a, b); }

// Everything the run reads: datasets, meshes, the sample maker, keypoints.
struct RunData {
    std::vector<std::unique_ptr<data::Dataset>> datasets;  // owns the sources' meshes
    std::map<int, train::SampleModel> models;                 // obj_id -> mesh + info
    std::map<int, int> class_of;                              // obj_id -> class index
    KeypointTable keypoints;                                  // class index -> K keypoints
    SymmetricKeypoints sym_keypoints;  // class index -> symmetric keypoint sets (if enabled)
    std::unique_ptr<SampleMaker> maker;
    struct Src {
        const SourceConfig* cfg;
        data::Dataset* frames = nullptr;  // a source of annotated frames (source_kind().frames)
        std::vector<data::SceneModel> scene_models;  // type synthetic
        data::SceneConfig scene;
    };
    std::vector<Src> train, val;
};

// `extra_ids`: models loaded besides the source's objects (a synthetic scene's distractors,
// which need no class).
data::Dataset* open_source_dataset(RunData& rd, const TrainConfig& cfg, const SourceConfig& s,
                                   bool models_only, const std::vector<int>& extra_ids = {}) {
    SourceOpen what;
    what.obj_ids = source_objects(cfg, s);
    for (const int id : extra_ids)
        if (std::find(what.obj_ids.begin(), what.obj_ids.end(), id) == what.obj_ids.end())
            what.obj_ids.push_back(id);
    what.models_only = models_only;
    rd.datasets.push_back(source_kind(s.type).open(s, what));
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
            if (!src.frames) continue;
            for (const auto& f : src.frames->frames()) {
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

// obj_id -> class index: its position in data.object_ids.
std::map<int, int> class_index(const TrainConfig& cfg) {
    std::map<int, int> class_of;
    for (size_t i = 0; i < cfg.data.object_ids.size(); ++i)
        class_of[cfg.data.object_ids[i]] = int(i);
    return class_of;
}

RunData prepare_data(const TrainConfig& cfg, bool verbose) {
    RunData rd;
    rd.class_of = class_index(cfg);
    auto add = [&](const SourceConfig& s, std::vector<RunData::Src>& list) {
        RunData::Src src;
        src.cfg = &s;
        if (source_kind(s.type).frames) {
            src.frames = open_source_dataset(rd, cfg, s, false);
            add_models(rd, *src.frames);
        } else {
            // The scene's distractors are rendered but never annotated: their meshes load
            // with the source's objects, and the targets stay the source's objects.
            src.scene = source_scene(s, "data.train/val synthetic source");
            if (src.scene.target_obj_ids.empty())
                src.scene.target_obj_ids = source_objects(cfg, s);
            data::Dataset* ds =
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
        if (src.frames) {
            // The stricter of the source's and the sampling section's visibility floors.
            s.list.push_back(std::make_unique<BopSource>(
                *src.frames, *rd.maker,
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
        const int64_t per = rd.train[i].frames ? 1 : std::max(1, rd.train[i].scene.targets_max);
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

// The memory of one training step, measured (2026-12-05, configs/demo_cpu.json with batch 8
// and 32, the maximum RSS of /usr/bin/time): 7.6 MB per sample at 300 crop points and width
// 0.25, in proportion to both (600 points: 14.9 MB; width 0.5: 15.0 MB), i.e. ~101 kB per crop
// point per unit of width. A batch that cannot fit is refused before anything starts (it would
// otherwise run for minutes without output while the memory fills).
void check_step_memory(const TrainConfig& cfg, int64_t local_batch) {
    const double need = 1.01e5 * cfg.sampling.points * cfg.model.width * double(local_batch);
    double avail = 0;  // /proc/meminfo MemAvailable (bytes); 0 where unknown
    std::ifstream f("/proc/meminfo");
    for (std::string line; std::getline(f, line);)
        if (line.rfind("MemAvailable:", 0) == 0) avail = std::atof(line.c_str() + 13) * 1024;
    G2L_CHECK(avail <= 0 || need < avail, "train.batch ", cfg.train.batch, ": a training step "
              "needs about ", need / 1e9, " GB (~", need / double(local_batch) / 1e6,
              " MB per sample at sampling.points ", cfg.sampling.points, " and model.width ",
              cfg.model.width, ") but this machine has ", avail / 1e9, " GB available: lower "
              "train.batch (about ", int64_t(0.8 * avail / (need / double(local_batch))),
              " fits) or sampling.points");
}

// model.init: the model file, checked against the config before the run directory and the
// data are made (a wrong file is named at once, not after minutes of data preparation): the
// same network (classes, keypoints, blocks, width, units, heads) and the same data.object_ids
// in the same order.
nn::LoadedModel load_init_model(const TrainConfig& cfg) {
    const std::string& path = cfg.model.init;
    nn::LoadedModel from = nn::load_model(path);
    const nn::G2LConfig want = model_config(cfg, geom::keypoint_count(cfg.model.keypoints));
    const auto arch = [](const nn::G2LConfig& c) {  // what the error shows
        return cat("num_classes ", c.num_classes, ", keypoints ", c.num_keypoints, ", evf ",
                   c.evf, ", rre ", c.rre, ", width ", c.width, ", out_scale_mm ",
                   c.out_scale_mm, ", rot_unit ", c.rot_unit, ", class_heads ", c.class_heads);
    };
    G2L_CHECK(nn::same_architecture(from.net->config(), want), "model.init '", path,
              "': its network (", arch(from.net->config()), ") is not the config's model (",
              arch(want), ")");
    G2L_CHECK(from.class_of == class_index(cfg), "model.init '", path,
              "': its objects differ from data.object_ids (the same ids in the same order)");
    return from;
}

// The pose networks' training task on the loop (train/loop.h): a batch of point-cloud crops
// from the epoch's visiting order, the G2L-Net step (train/pipeline.h), validation on the
// configured BOP sets, checkpoints with the resume state.
class PoseTask final : public TrainTask {
public:
    PoseTask(const TrainConfig& cfg, const TrainOptions& opt, RunData& rd, int64_t lo, int64_t hi)
        : cfg_(cfg), opt_(opt), rd_(rd), lo_(lo), hi_(hi),
          mc_(model_config(cfg, rd.keypoints.empty() ? 8 : int(rd.keypoints[0].size()))),
          net_(mc_),
          adam_(net_.param_groups({cfg.optim.lr_mult.seg, cfg.optim.lr_mult.tnet,
                                   cfg.optim.lr_mult.evf, cfg.optim.lr_mult.rot,
                                   cfg.optim.lr_mult.rre},
                                  cfg.optim.weight_decay),
                adam_options(cfg)),
          schedule_(nn::make_schedule(cfg.schedule.kind, cfg.optim.lr, cfg.schedule.step_epochs,
                                      cfg.schedule.gamma, cfg.train.epochs)) {
        lw_.seg = cfg.loss.seg, lw_.t = cfg.loss.t, lw_.vec = cfg.loss.vec;
        lw_.kp = cfg.loss.kp, lw_.res = cfg.loss.res;
        lw_.t_smooth_l1 = cfg.loss.t_loss == "smooth_l1";
        for (const auto& kp : rd.keypoints)
            so_.rot_scale.push_back(float(nn::rotation_scale(mc_.rot_unit, kp)));
        so_.centre_noise_mm = cfg.loss.rot_centre_noise_mm;
        so_.centre_with_prediction = cfg.loss.rot_centre == "pred";
        for (const auto& [id, cls] : rd.class_of) {  // exports need each crop's radius
            (void)cls;
            const geom::ModelInfo& mi = rd.maker->info(id);
            objects_[id] = {mi.diameter, mi.symmetric};
        }
    }

    /// A resumed run: the model and Adam from `path`, and where the run stood.
    LoopState resume(const std::string& path) {
        const ResumeState st = load_training_checkpoint(path, net_, adam_);
        LoopState s;
        s.epoch = st.epoch, s.epoch_step = st.epoch_batches, s.step = st.global_step;
        s.epoch_loss = st.epoch_loss, s.best_val = st.best_val, s.seconds = st.seconds;
        return s;
    }
    /// Fine-tuning (model.init): the weights of a model file already checked by
    /// load_init_model, with this run's fresh optimiser and schedule.
    void init_from(const nn::LoadedModel& from) {
        net_.load_state_dict(from.net->state_dict(), true);
    }
    int64_t parameters() const {
        int64_t n = 0;
        for (const nn::ParamGroup& g : adam_.groups())
            for (const auto& p : g.params) n += p.second.numel();
        return n;
    }

    nn::Adam& optimizer() override { return adam_; }
    // The epoch the schedule and the warm-up phases follow: the loop's, or with
    // train.time_schedule the epoch the clock says the run is in when the time limit will end
    // it early — so a short run still decays its learning rate and leaves its warm-up phases
    // at the same share of the run (rot_only_epochs / epochs of the time).
    int schedule_epoch(const LoopState& s) const {
        if (!cfg_.train.time_schedule) return s.epoch;
        const int E = cfg_.train.epochs;
        const double p = time_fitted_progress(s, double(s.epoch) / E, cfg_.train.time_limit_min);
        return std::min(E - 1, std::max(s.epoch, int(p * E)));
    }
    double lr(const LoopState& s) const override { return schedule_->lr_at(schedule_epoch(s)); }

    int64_t begin_epoch(const LoopState& s) override {
        if (ahead_.valid()) ahead_.wait();  // a stopped epoch's prefetch reads the old sources
        sources_ = make_train_sources(rd_, cfg_, s.epoch);
        order_ = epoch_order(sources_, rd_, cfg_, s.epoch);
        G2L_CHECK(!order_.empty(), "training data: epoch ", s.epoch, " has no sample to visit");
        const int64_t target = cfg_.train.samples_per_epoch > 0 ? cfg_.train.samples_per_epoch
                                                                : int64_t(order_.size());
        batches_ = std::max<int64_t>(1, target / cfg_.train.batch);
        tried_ = failed_ = 0;
        epoch_ = s.epoch;
        net_.train();
        if (cfg_.train.prefetch && s.epoch_step < batches_)
            ahead_ = std::async(std::launch::async, [this, b = s.epoch_step] { return fetch(b); });
        return batches_;
    }

    StepValues step(const LoopState& s) override {
        Fetched got = cfg_.train.prefetch ? ahead_.get() : fetch(s.epoch_step);
        tried_ += got.tried;
        failed_ += got.failed;
        if (cfg_.train.prefetch && s.epoch_step + 1 < batches_)
            ahead_ = std::async(std::launch::async,
                                [this, b = s.epoch_step + 1] { return fetch(b); });
        G2L_CHECK(tried_ < 50 || failed_ * 10 < tried_ * 9, "training data: ", failed_, " of ",
                  tried_, " crops were unusable (too few points) — check the sources, "
                  "sampling.min_points and the depth data");
        // The step's random draws per sample, seeded by the sample's slot in the global batch
        // (the same for any number of processes).
        const uint64_t step_seed = mix(cfg_.seed, 0xABCDEFull + uint64_t(s.step));
        Rng step_rng(step_seed);
        std::vector<Rng> sample_rngs;
        for (int64_t i = lo_; i < hi_; ++i) sample_rngs.emplace_back(mix(step_seed, uint64_t(i)));
        so_.sample_rngs = &sample_rngs;
        adam_.zero_grad();
        // The warm-up phases (docs/config.md, loss.rot_only_epochs): the rotation networks
        // alone first, then on ground-truth object points, then on the segmentation's.
        const int e = schedule_epoch(s);
        so_.rot_gt_points = e < cfg_.loss.rot_only_epochs + cfg_.loss.rot_gt_points_epochs;
        so_.rot_only = e < cfg_.loss.rot_only_epochs;
        // BatchNorm and dropout see the global batch through this hook (forward and backward);
        // each process's loss is weighted by its share of the batch, so the summed gradients
        // are those of the global batch's mean loss.
        const nn::DataParallel hook = dist::step_hook(cfg_.train.batch, lo_);
        const nn::DataParallelGuard hook_on(&hook);
        const double share = double(hi_ - lo_) / double(cfg_.train.batch);
        StepLosses L = g2l_step(net_, got.batch, rd_.keypoints, mc_.num_classes,
                                cfg_.sampling.seg_points, lw_, step_rng,
                                rd_.sym_keypoints.empty() ? nullptr : &rd_.sym_keypoints, so_);
        const double loss = L.total.item<double>();
        if (!std::isfinite(loss)) {
            std::string objs;
            for (const auto& p : got.batch) objs += " " + std::to_string(p.obj_id);
            G2L_CHECK(false, "non-finite loss ", loss, " at step ", s.step, " (epoch ", s.epoch,
                      "; objects", objs, "; seg ", L.seg, " t ", L.t, " vec ", L.vec, " kp ",
                      L.kp, " res ", L.res, ")");
        }
        (dist::size() > 1 ? nn::mul_scalar(L.total, share) : L.total).backward();
        return {{"loss", share * loss}, {"seg", share * L.seg}, {"t", share * L.t},
                {"vec", share * L.vec}, {"kp", share * L.kp}, {"res", share * L.res},
                {"seg_acc", share * L.seg_accuracy}, {"t_err_mm", share * L.t_error_mm},
                {"kp_err_mm", share * L.kp_error_mm}, {"sym_frac", share * L.sym_fraction}};
    }

    double end_epoch(const LoopState& s, json& record) override {
        const bool val_epoch = !rd_.val.empty() && cfg_.train.val_every > 0 &&
                               ((s.epoch + 1) % cfg_.train.val_every == 0 ||
                                s.epoch + 1 == cfg_.train.epochs);
        double score = -1;
        if (val_epoch && dist::is_root()) {  // rank 0 validates alone
            double sum = 0;
            int n = 0;
            for (const auto& v : rd_.val) {
                if (!v.frames) continue;
                EvalOptions eo;  // the networks alone, as trained: no refinement
                eo.pipeline.refine = Refinement::none;
                eo.max_instances = cfg_.train.max_val_samples;
                eo.min_visib_fract = v.cfg->min_visib_fract;
                const EvalReport r = evaluate_gt_boxes(validation_model(), *v.frames, eo);
                record["val"].push_back(json::parse(report_json(r)));
                // Model selection by what users see: the ADD accuracy modulo the geometric
                // symmetries (the YCB AUC's 10 cm threshold rewards random rotations).
                sum += r.average.acc_addsym_10;
                ++n;
            }
            if (n) {
                score = sum / n;
                record["val_acc_addsym_10"] = score;
            }
        }
        if (val_epoch) dist::barrier();  // the other processes sleep while rank 0 validates
        return score;
    }

    void save(const std::string& path, const LoopState& s) override {
        // pos: the position in the epoch's visiting order the resumed run continues from.
        const ResumeState st{s.epoch, s.epoch_step * cfg_.train.batch, s.step, s.epoch_step,
                             s.epoch_loss, s.best_val, s.seconds};
        save_training_checkpoint(path, net_, adam_, cfg_, rd_.class_of, rd_.keypoints, st,
                                 objects_);
    }

private:
    // The network in training as the pipeline sees a trained model: the crop, its radius and
    // point counts of the config.
    infer::PipelineModel validation_model() {
        infer::PipelineModel pm;
        pm.net = &net_;
        pm.class_of = rd_.class_of;
        pm.keypoints = rd_.keypoints;
        pm.crop = cfg_.sampling.crop;
        pm.radius_scale = cfg_.sampling.radius_scale;
        pm.points = cfg_.sampling.points;
        pm.seg_points = cfg_.sampling.seg_points;
        return pm;
    }
    static nn::AdamOptions adam_options(const TrainConfig& cfg) {
        nn::AdamOptions ao;
        ao.lr = cfg.optim.lr;
        ao.beta1 = cfg.optim.beta1;
        ao.beta2 = cfg.optim.beta2;
        ao.eps = cfg.optim.eps;
        return ao;
    }

    struct Fetched {
        std::vector<PoseSample> batch;
        int64_t tried = 0, failed = 0;
    };
    // Slot i of global batch b is order position b * batch + i; an unusable crop there is
    // replaced by positions drawn from (seed, slot, attempt). A slot's sample thus depends only
    // on (epoch, b, i), never on which process makes it or on the other slots: this process
    // makes slots [lo, hi), and the global batch is the same for any number of processes
    // (without unusable crops it is the consecutive walk through the order). Only fetch reads
    // sources_, and at most one call is in flight, so the prefetch thread and the serial path
    // make the same batches.
    Fetched fetch(int64_t b) {
        Fetched f;
        const uint64_t n = order_.size();
        for (int64_t i = lo_; i < hi_; ++i) {
            const uint64_t slot = uint64_t(b * cfg_.train.batch + i);
            if (interrupt_now(opt_)) throw StepInterrupted();
            for (int a = 0;; ++a) {
                G2L_CHECK(a < 64, "training data: 64 crops in a row were unusable (too few "
                          "points) at epoch ", epoch_, " batch ", b, " slot ", i, " — check the "
                          "sources, sampling.min_points and the depth data");
                const uint64_t p = a == 0 ? slot % n
                                          : mix(mix(cfg_.seed ^ 0x510Full, slot), uint64_t(a)) % n;
                const Item it = order_[size_t(p)];
                Rng srng(mix(mix(cfg_.seed, uint64_t(epoch_) * 7919 + uint64_t(it.source)),
                             uint64_t(it.index)));
                PoseSample s;
                ++f.tried;
                if (sources_.list[size_t(it.source)]->get(it.index, srng, &s)) {
                    f.batch.push_back(std::move(s));
                    break;
                }
                ++f.failed;
            }
        }
        return f;
    }

    const TrainConfig& cfg_;
    const TrainOptions& opt_;
    RunData& rd_;
    const int64_t lo_, hi_;  // this process's samples of each global batch
    nn::G2LConfig mc_;
    nn::G2LNet net_;
    nn::Adam adam_;
    std::unique_ptr<nn::LrSchedule> schedule_;
    LossWeights lw_;
    StepOptions so_;
    std::map<int, nn::ModelObjectInfo> objects_;  // stored so exports know each crop's radius
    Sources sources_;
    std::vector<Item> order_;
    int64_t batches_ = 0, tried_ = 0, failed_ = 0;
    int epoch_ = 0;
    std::future<Fetched> ahead_;  // last: destroyed (joined) before what fetch reads
};

}  // namespace

TrainSummary run_training(const TrainConfig& cfg, const TrainOptions& opt) {
    if (cfg.threads > 0) set_num_threads(cfg.threads);
    G2L_CHECK(parse_device(cfg.device).is_cpu(), "device '", cfg.device,
              "': training runs on the CPU in this version (the CUDA backend is not complete)");
    // The run directory first: a bad one is found before any data is read. Data-parallel
    // (train/distributed.h): this process trains on samples [lo, hi) of every global batch;
    // rank 0 alone writes the run directory, logs and prints.
    const std::string run_dir = opt.resume_dir.empty() ? cfg.run_dir : opt.resume_dir;
    const bool progress = opt.progress && dist::is_root();
    const std::pair<int64_t, int64_t> shard = dist::shard(cfg.train.batch);
    check_step_memory(cfg, shard.second - shard.first);  // before anything is written or read
    std::optional<nn::LoadedModel> init;  // model.init, for a run that does not resume
    if (opt.resume_dir.empty() && !cfg.model.init.empty()) init.emplace(load_init_model(cfg));
    const RunDir run(run_dir, !opt.resume_dir.empty(), opt.force, {"steps.jsonl", "epochs.jsonl"},
                     dist::is_root());
    RunData rd = prepare_data(cfg, progress);
    preflight_images(rd, progress);
    G2L_CHECK(!rd.train.empty(), "data.train: no training source configured");
    PoseTask task(cfg, opt, rd, shard.first, shard.second);

    LoopState start;
    if (!opt.resume_dir.empty()) {
        start = task.resume(run.path("last.g2l"));
        G2L_CHECK(start.epoch < cfg.train.epochs, "--resume '", run_dir, "': the run already "
                  "finished its ", cfg.train.epochs, " epochs (", start.step, " steps); to train "
                  "on, resume with --set train.epochs=N (N > ", cfg.train.epochs, ")");
        run.trim_log("steps.jsonl", "step", start.step);  // a killed run logged past it
        run.trim_log("epochs.jsonl", "epoch", start.epoch - 1);
    } else if (init) {
        task.init_from(*init);
        if (progress) std::printf("model.init: the weights of %s\n", cfg.model.init.c_str());
    }
    run.begin(config_to_json(cfg) + "\n");
    if (progress && dist::size() > 1)
        std::printf("data-parallel: %d processes, %lld of the %d samples of each batch here; one "
                    "all-reduce of %lld parameters (%.2f MB) per step\n", dist::size(),
                    (long long)(shard.second - shard.first), cfg.train.batch,
                    (long long)task.parameters(), task.parameters() * 4e-6);

    LoopOptions lo;
    lo.epochs = cfg.train.epochs;
    lo.global_batch = cfg.train.batch;
    lo.log_every = cfg.train.log_every;
    lo.keep_every_epochs = cfg.train.checkpoint_every;
    lo.time_limit_min = cfg.train.time_limit_min;
    lo.epoch_log = "epochs.jsonl";
    lo.shown_values = 6;  // loss seg t vec kp res
    const LoopResult r = run_loop(task, run, lo, opt, start);

    TrainSummary sum;
    sum.run_dir = run_dir;
    sum.steps = r.state.step;
    sum.epochs_done = r.state.epoch;
    sum.last_loss = r.last_loss;
    sum.best_val = r.state.best_val;
    sum.samples_per_s = r.samples_per_s;
    sum.stopped_early = r.stopped_early;
    sum.interrupted = r.interrupted;
    return sum;
}

}  // namespace g2l::train
