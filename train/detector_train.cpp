// SPDX-License-Identifier: MIT
// The detector's training loop (renders → augmentation → CenterNet loss → Adam, checkpoints,
// validation) and export averaging. Config: detector_config.cpp; targets and loss:
// detector_loss.cpp; augmentation: detector_augment.cpp; evaluation: eval/detector_eval.cpp.
#include "train/detector_train.h"
#include "train/loop.h"
#include "train/run_dir.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>

#include "core/autograd.h"
#include "core/checkpoint.h"
#include "core/error.h"
#include "core/json.h"
#include "core/json_reader.h"
#include "core/rng.h"
#include "core/threads.h"
#include "data/bop.h"
#include "data/draw.h"
#include "data/render.h"
#include "eval/detector_eval.h"
#include "nn/optim.h"
#include "train/config.h"
#include "nn/data_parallel.h"
#include "train/detector_augment.h"
#include "train/distributed.h"
#include "train/trainer.h"

namespace g2l::train {

namespace fs = std::filesystem;
using json = nlohmann::json;

int64_t export_detector_average(const std::vector<std::string>& exports,
                                const std::string& out_path) {
    G2L_CHECK(exports.size() >= 2, "average: give at least two detector exports, got ",
              exports.size());
    const std::string& first = exports.front();
    nn::LoadedDetector base = nn::load_detector(first);
    std::map<std::string, Tensor> sum = base.net->state_dict();
    for (auto& [name, t] : sum) t = t.clone();
    for (size_t i = 1; i < exports.size(); ++i) {
        const nn::LoadedDetector d = nn::load_detector(exports[i]);
        G2L_CHECK(d.object_ids == base.object_ids && d.downscale == base.downscale &&
                      d.net->config().width == base.net->config().width,
                  "average: '", exports[i], "' has other objects, width or downscale than '",
                  first, "' (average exports of one detector's fine-tuning runs)");
        for (const auto& [name, t] : d.net->state_dict()) {
            Tensor& s = sum.at(name);  // same config: same tensor names and shapes
            if (t.dtype() != DType::F32) continue;  // integer buffers: the first export's
            float* a = s.data<float>();
            const float* b = t.data<float>();
            for (int64_t k = 0; k < t.numel(); ++k) a[k] += b[k];
        }
    }
    const double n = double(exports.size());
    for (auto& [name, t] : sum)
        if (t.dtype() == DType::F32) {
            float* a = t.data<float>();
            for (int64_t k = 0; k < t.numel(); ++k) a[k] = float(double(a[k]) / n);
        }
    base.net->load_state_dict(sum, true);
    nn::save_detector(out_path, *base.net, base.object_ids, base.downscale);
    return int64_t(fs::file_size(out_path));
}

namespace {

constexpr const char* kCheckpointFormat = "g2l-detector-train";
constexpr int kDistractorId = 1000000;  // the largest obj_id a models_info.json may hold

struct DetSample {
    std::vector<uint8_t> rgb;  // H x W x 3 at the detector's input resolution
    std::vector<float> depth;  // H x W (mm), for a depth or rgbd detector
    std::vector<DetBox> boxes;
    // DetTargets::neg_weight of the image's blocks (empty: loss.block_negatives 1); an occluder
    // pasted over a block leaves its cells weighted as the block's.
    std::vector<float> neg_weight;
};

// A scene of the config (`full`: data.scene or one of data.mix) at the detector's input
// resolution: the camera scaled by 1/downscale.
data::SceneConfig input_scene(const DetectorTrainConfig& c, const data::SceneConfig& full) {
    data::SceneConfig s = full;
    const double k = 1.0 / c.downscale;
    s.camera.fx *= k, s.camera.fy *= k;
    s.camera.cx = (s.camera.cx + 0.5) * k - 0.5;
    s.camera.cy = (s.camera.cy + 0.5) * k - 0.5;
    s.camera.width /= c.downscale;
    s.camera.height /= c.downscale;
    s.target_obj_ids = c.object_ids;
    if (!nn::uses_depth(c.input)) {
        s.noise.enabled = false;  // the detector sees colour only
    } else {
        // Inference averages downscale x downscale sensor pixels into one input pixel
        // (nn::detector_input), which divides the independent axial noise by downscale; the
        // render at input resolution gets that noise directly. Hole sizes are in pixels.
        s.noise.sigma_a_mm /= c.downscale;
        s.noise.sigma_b_mm_per_m2 /= c.downscale;
        s.noise.hole_radius_min_px /= c.downscale;
        s.noise.hole_radius_max_px /= c.downscale;
    }
    return s;
}


// What the detector trains on: the targets' meshes (models_root), the distractors' (coloured
// copies where a mesh has no colour) and the scenes at the detector's input resolution
// (data.scene, then data.mix's). Built in place: the scene models point into its meshes.
struct TrainingScene {
    data::Dataset models;
    std::deque<geom::Mesh> distractor_meshes;
    std::vector<data::SceneModel> sm;
    data::SceneConfig scene;
    std::vector<data::SceneConfig> mix;

    explicit TrainingScene(const DetectorTrainConfig& cfg)
        : models(data::open_bop_models(cfg.models_root, [&] {
              data::BopOptions bo;
              bo.obj_ids = cfg.object_ids;
              return bo;
          }())),
          scene(input_scene(cfg, cfg.scene)) {
        add_models(cfg);
        for (const DetectorTrainConfig::SceneMix& m : cfg.mix) {
            mix.push_back(input_scene(cfg, m.scene));
            mix.back().distractor_obj_ids = scene.distractor_obj_ids;
        }
    }
    TrainingScene(const TrainingScene&) = delete;
    TrainingScene& operator=(const TrainingScene&) = delete;

private:
    // The targets, then the distractors (into scene.distractor_obj_ids).
    void add_models(const DetectorTrainConfig& cfg) {
        for (const int id : cfg.object_ids) {
            G2L_CHECK(models.models().count(id), "data.object_ids: no model ", id, " in ",
                      cfg.models_root);
            const geom::Mesh& mesh = models.load_model_mesh(id);
            G2L_CHECK(mesh.colors.rows() > 0 || !nn::uses_rgb(cfg.input), "data.object_ids: "
                      "model ", id, " of ", cfg.models_root, " has no vertex colours; an ",
                      nn::to_string(cfg.input), " detector learns from colour renders (data.input "
                      "\"depth\" needs none)");
            sm.push_back({id, &mesh});
        }
        if (cfg.distractors_root.empty()) return;
        // Distractors: ids above kDistractorId (the largest id a model may have), numbered in
        // order, so no id collides with a target's or another distractor's.
        data::BopOptions dopt;
        dopt.obj_ids = cfg.distractor_ids;
        const data::Dataset dm = data::open_bop_models(cfg.distractors_root, dopt);
        Rng paint(mix_seed(cfg.seed, 0xD157));
        int next_id = kDistractorId + 1;
        for (const auto& [id, info] : dm.models()) {
            const geom::Mesh& mesh = dm.load_model_mesh(id);
            const int variants = mesh.colors.rows() > 0 ? 1 : cfg.distractor_colors;
            for (int v = 0; v < variants; ++v) {
                distractor_meshes.push_back(mesh);
                if (mesh.colors.rows() == 0) paint_distractor(distractor_meshes.back(), paint);
                const int did = next_id++;
                sm.push_back({did, &distractor_meshes.back()});
                scene.distractor_obj_ids.push_back(did);
            }
        }
        G2L_CHECK(!scene.distractor_obj_ids.empty(), "data.distractors_root '",
                  cfg.distractors_root, "': no model to use as a distractor");
    }
};

// Occluders: random-coloured discs and rectangles pasted over the objects; the visible masks
// `vis` (and so the target boxes and visible fractions) lose those pixels. In the depth the
// occluder is a plate 30-150 mm in front of the object's nearest point.
void paste_occluders(DetSample& d, std::vector<uint16_t>& vis, const data::RenderedFrame& fr,
                     int W, double prob, Rng& rng) {
    for (const data::RenderedInstance& in : fr.instances) {
        if (in.bbox_visib.empty() || rng.uniform() >= prob) continue;
        const geom::Box2i& bb = in.bbox_visib;
        const double rw = rng.uniform(0.2, 0.6) * bb.w, rh = rng.uniform(0.2, 0.6) * bb.h;
        const double cx = bb.x + rng.uniform(0, 1) * bb.w, cy = bb.y + rng.uniform(0, 1) * bb.h;
        const bool disc = rng.uniform() < 0.5;
        uint8_t col[3];
        for (uint8_t& c : col) c = uint8_t(rng.below(256));
        float plate = 0;
        if (!d.depth.empty()) {
            float near = 1e30f;
            for (int y = bb.y; y < bb.y + bb.h; ++y)
                for (int x = bb.x; x < bb.x + bb.w; ++x) {
                    const size_t i = size_t(y) * size_t(W) + size_t(x);
                    if (i < d.depth.size() && d.depth[i] > 0) near = std::min(near, d.depth[i]);
                }
            plate = near < 1e29f ? std::max(50.f, near - float(rng.uniform(30, 150))) : 0.f;
        }
        const int H = int(vis.size() / size_t(W));
        for_each_shape_pixel(W, H, cx, cy, rw, rh, disc, [&](size_t i) {
            for (int k = 0; k < 3; ++k) d.rgb[i * 3 + size_t(k)] = col[k];
            if (plate > 0) d.depth[i] = plate;
            vis[i] = 0;
        });
    }
}

// Every target instance's box of the pixels `vis` leaves visible (one pass over the mask);
// instances less visible than min_visib_fract get none.
std::vector<DetBox> visible_boxes(const data::RenderedFrame& fr, const std::vector<uint16_t>& vis,
                                  int W, int H, const std::map<int, int>& cls,
                                  double min_visib_fract) {
    struct Acc {
        int x0, y0, x1, y1;
        int64_t n;
    };
    std::vector<Acc> acc(fr.instances.size(), Acc{W, H, -1, -1, 0});
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const uint16_t id = vis[size_t(y) * size_t(W) + size_t(x)];
            if (id == 0 || id > acc.size()) continue;
            Acc& a = acc[id - 1u];
            ++a.n;
            a.x0 = std::min(a.x0, x), a.x1 = std::max(a.x1, x);
            a.y0 = std::min(a.y0, y), a.y1 = std::max(a.y1, y);
        }
    std::vector<DetBox> boxes;
    for (size_t k = 0; k < fr.instances.size(); ++k) {
        const data::RenderedInstance& in = fr.instances[k];
        auto it = cls.find(in.obj_id);
        const Acc& a = acc[k];
        if (it == cls.end() || in.px_count_all <= 0) continue;
        if (a.n == 0 || double(a.n) / double(in.px_count_all) < min_visib_fract) continue;
        boxes.push_back({it->second, float(a.x0), float(a.y0), float(a.x1 - a.x0 + 1),
                         float(a.y1 - a.y0 + 1)});
    }
    return boxes;
}

// The detector's training task on the loop (train/loop.h): rendered scenes → augmentation →
// CenterNet targets → the focal + size + offset loss; validation on real frames; checkpoints
// (and the detector export next to them).
class DetectorTask final : public TrainTask {
public:
    DetectorTask(const DetectorTrainConfig& cfg, const TrainOptions& opt,
                 std::vector<data::Image> photos, const RunDir& run, int64_t img_lo, int64_t img_hi)
        : cfg_(cfg), opt_(opt), photos_(std::move(photos)), run_(run), lo_(img_lo), hi_(img_hi),
          progress_(opt.progress && dist::is_root()), ts_(cfg), W_(ts_.scene.camera.width), H_(ts_.scene.camera.height),
          dc_(detector_config(cfg)), net_(dc_),
          adam_({nn::ParamGroup{"detector", net_.named_parameters()}}, adam_options(cfg)),
          gen_(ts_.scene, ts_.sm) {
        for (const data::SceneConfig& m : ts_.mix)
            mix_gens_.push_back(std::make_unique<data::SceneGenerator>(m, ts_.sm));
        G2L_CHECK(W_ % 16 == 0 && H_ % 16 == 0, "data.scene.camera: the detector input ", W_,
                  " x ", H_, " (camera / downscale) must be a multiple of 16 in both sizes");
        for (size_t i = 0; i < cfg.object_ids.size(); ++i) cls_[cfg.object_ids[i]] = int(i);
        if (!cfg.val_root.empty()) {
            data::BopOptions vo;
            vo.obj_ids = cfg.object_ids;
            val_ = std::make_unique<data::BopDataset>(data::open_bop(cfg.val_root, cfg.val_split, vo));
        }
    }

    /// A resumed run: the model and Adam from `path`, and the step it holds.
    LoopState resume(const std::string& path) {
        const Checkpoint ck = load_checkpoint(path);
        const json meta = parse_json_strict(ck.meta_json, path + " (metadata)");
        G2L_CHECK(meta.is_object() && meta.value("format", "") == kCheckpointFormat, "'", path,
                  "' is not a detector training checkpoint");
        JsonReader r(meta, "checkpoint '" + path + "' (metadata)");
        LoopState s;
        r.ignore("format");
        r.require("step");
        r.integer("step", s.step);
        r.num("seconds", s.seconds);
        r.ignore("config");
        r.finish();
        G2L_CHECK(s.step >= 0 && s.seconds >= 0, r.source(), ": negative 'step' or 'seconds'");
        net_.load_state_dict(model_state_of(ck.tensors), true);
        adam_.load_state(ck.tensors, s.step);
        s.epoch_step = s.step;  // one "epoch" of cfg.steps steps
        return s;
    }
    /// Fine-tuning: the weights of an export, a fresh optimiser. An export of a narrower
    /// width (model.width a whole multiple of it) is widened keeping its function
    /// (nn::widen_detector): more capacity from where the narrow one stopped.
    void init_from(const std::string& path) {
        const nn::LoadedDetector from = nn::load_detector(path);
        const int w0 = from.net->config().width;
        G2L_CHECK(from.object_ids == cfg_.object_ids && from.input() == cfg_.input,
                  "model.init '", path, "': its objects / input differ from the config's "
                  "(data.object_ids, data.input)");
        G2L_CHECK(cfg_.width == w0 || (cfg_.width > w0 && cfg_.width % w0 == 0), "model.init '",
                  path, "': its width ", w0, " is neither model.width ", cfg_.width,
                  " nor a whole divisor of it (a narrower export is widened)");
        if (cfg_.width == w0)
            net_.load_state_dict(from.net->state_dict(), true);
        else
            nn::widen_detector(*from.net, net_, cfg_.seed ^ 0x5769646eull);
    }
    const DetectorTrainSummary& validation() const { return val_sum_; }

    nn::Adam& optimizer() override { return adam_; }
    // Step decay: x0.1 at 70 % and 90 % of the steps.
    double lr(const LoopState& s) const override {
        const int64_t n = cfg_.steps;
        int64_t at = s.step;
        if (cfg_.time_schedule)  // the step the clock says the run is at (time limit first)
            at = std::max(at, int64_t(time_fitted_progress(s, double(at) / double(n),
                                                           cfg_.time_limit_min) * double(n)));
        return cfg_.lr * (at >= n * 9 / 10 ? 0.01 : at >= n * 7 / 10 ? 0.1 : 1.0);
    }
    int64_t begin_epoch(const LoopState& s) override {
        previewed_ = s.step > 0 || !dist::is_root();  // a resumed run has its preview
        next_ = std::async(std::launch::async, [this, b = s.step] { return make_batch(b); });
        return cfg_.steps;
    }

    StepValues step(const LoopState& s) override {
        std::vector<DetSample> batch = next_.get();
        if (!previewed_) {
            previewed_ = true;
            preview(batch);
        }
        if (s.step + 1 < cfg_.steps)
            next_ = std::async(std::launch::async, [this, b = s.step + 1] { return make_batch(b); });
        const int C = nn::detector_input_channels(cfg_.input);
        const size_t plane = size_t(H_) * size_t(W_);
        const int64_t local = hi_ - lo_;
        Tensor x = Tensor::empty({local, C, H_, W_});
        std::vector<DetTargets> targets;
        const geom::Intrinsics& cam = ts_.scene.camera;
        for (int64_t b = 0; b < local; ++b) {
            const DetSample& d = batch[size_t(b)];
            float* px = x.data<float>() + size_t(b) * size_t(C) * plane;
            if (nn::uses_rgb(cfg_.input))
                for (int k = 0; k < 3; ++k)
                    for (size_t i = 0; i < plane; ++i)
                        px[size_t(k) * plane + i] = (float(d.rgb[i * 3 + size_t(k)]) / 255.f - 0.5f) / 0.25f;
            if (nn::uses_depth(cfg_.input))  // the encoding inference computes (nn::detector_input)
                nn::depth_features(d.depth.data(), W_, H_, cam.fx, cam.fy, cam.cx, cam.cy,
                                   px + (nn::uses_rgb(cfg_.input) ? 3 : 0) * plane, W_,
                                   int64_t(H_) * W_);
            targets.push_back(make_detector_targets(d.boxes, int(cls_.size()),
                                                    W_ / nn::Detector::kStride,
                                                    H_ / nn::Detector::kStride));
            targets.back().neg_weight = d.neg_weight;
        }
        net_.train();
        adam_.zero_grad();
        // The loss is normalised by the global batch's centres (one small all-reduce), so the
        // processes' losses and gradients add up to the one-process ones; BatchNorm sees the
        // global batch through the hook.
        double centres = detector_centres(targets);
        if (dist::size() > 1) dist::allreduce_sum(&centres, 1);
        const nn::DataParallel hook = dist::step_hook(cfg_.batch, lo_);
        const nn::DataParallelGuard hook_on(&hook);
        const nn::DetOut out = net_.forward(x);
        double lh = 0, ls = 0, lo = 0;
        Tensor loss = detector_loss(out, targets, cfg_.w_heat, cfg_.w_size, cfg_.w_offset, &lh,
                                    &ls, &lo, centres);
        const double lv = loss.item<double>();
        G2L_CHECK(std::isfinite(lv), "detector training: non-finite loss at step ", s.step + 1);
        loss.backward();
        return {{"loss", lv}, {"heat", lh}, {"size", ls}, {"offset", lo}};
    }

    void after_step(const LoopState& s) override {
        if (cfg_.val_every > 0 && s.step % cfg_.val_every == 0 && s.step < cfg_.steps) validate(s);
    }
    double end_epoch(const LoopState& s, json&) override {
        validate(s);  // the end of the run
        return -1;    // no best.g2l: the last detector is the one to use
    }

    void save(const std::string& path, const LoopState& s) override {
        const json meta{{"format", kCheckpointFormat}, {"step", s.step}, {"seconds", s.seconds},
                        {"config", json::parse(detector_config_to_json(cfg_))}};
        save_checkpoint(path, checkpoint_tensors(net_.state_dict(), adam_), meta.dump());
        nn::save_detector(run_.path("detector.g2l"), net_, cfg_.object_ids, cfg_.downscale);
    }

private:
    static nn::DetectorConfig detector_config(const DetectorTrainConfig& cfg) {
        nn::DetectorConfig dc;
        dc.num_classes = int(cfg.object_ids.size());
        dc.width = cfg.width;
        dc.seed = cfg.seed;
        dc.input = cfg.input;
        return dc;
    }
    static nn::AdamOptions adam_options(const DetectorTrainConfig& cfg) {
        nn::AdamOptions ao;
        ao.lr = cfg.lr;
        ao.beta1 = 0.9;
        ao.beta2 = 0.999;
        return ao;
    }

    // Global batch s: frame index s * batch + b, image b's draws seeded by (s, b) — the same
    // batch for any number of processes (this one makes images [lo, hi)) and after a resume.
    std::vector<DetSample> make_batch(int64_t s) {
        std::vector<DetSample> batch(static_cast<size_t>(hi_ - lo_));
        data::RenderedFrame fr;
        for (int64_t b = lo_; b < hi_; ++b) {
            if (interrupt_now(opt_)) throw StepInterrupted();
            const int64_t image = s * cfg_.batch + b;
            scene_of(image).render_frame(image, fr, 1);
            DetSample& d = batch[size_t(b - lo_)];
            d.rgb = fr.rgb;
            if (nn::uses_depth(cfg_.input)) d.depth = fr.depth;
            Rng rng(mix_seed(mix_seed(cfg_.seed, uint64_t(s)), uint64_t(b) + 17));
            if (cfg_.object_tone_prob > 0) {  // each target its own group, the distractors one
                const uint16_t dgroup = uint16_t(fr.instances.size() + 1);
                std::vector<uint16_t> groups(fr.mask);
                for (size_t i = 0; i < groups.size(); ++i)
                    if (groups[i] == 0 && !fr.distractor_mask.empty() && fr.distractor_mask[i])
                        groups[i] = dgroup;
                Rng trng(mix_seed(mix_seed(cfg_.seed, uint64_t(s)), uint64_t(b) + 0x70E));
                object_tone(d.rgb, groups, W_, H_, cfg_.object_tone_prob, trng);
            }
            // The pixels a new background must leave alone: targets' and distractors'.
            auto keep = [&fr] {
                std::vector<uint8_t> k(fr.mask.size());
                for (size_t i = 0; i < k.size(); ++i)
                    k[i] = fr.mask[i] != 0 || (!fr.distractor_mask.empty() && fr.distractor_mask[i]);
                return k;
            };
            if (cfg_.photo_prob > 0 && rng.uniform() < cfg_.photo_prob)
                photo_background(d.rgb, keep(), W_, H_, photos_, rng);
            else if (rng.uniform() < cfg_.clutter_prob)
                clutter_background(d.rgb, keep(), W_, H_, rng);
            std::vector<uint16_t> vis = fr.mask;
            if (cfg_.occluder_prob > 0) paste_occluders(d, vis, fr, W_, cfg_.occluder_prob, rng);
            augment(d.rgb, W_, H_, cfg_, rng);
            d.boxes = visible_boxes(fr, vis, W_, H_, cls_, cfg_.min_visib_fract);
            if (cfg_.w_block_negatives != 1.0)
                d.neg_weight = block_cell_weights(fr.block_mask, W_, H_, nn::Detector::kStride,
                                                  float(cfg_.w_block_negatives));
        }
        return batch;
    }

    // The scene image `image` is drawn from: data.mix[i] with its probability, else data.scene;
    // a function of (seed, image) alone.
    data::SceneGenerator& scene_of(int64_t image) {
        if (mix_gens_.empty()) return gen_;
        Rng pick(mix_seed(mix_seed(cfg_.seed, 0x313C), uint64_t(image)));
        const double u = pick.uniform();
        double below = 0;  // the probabilities of the mixed scenes before i, and i's
        for (size_t i = 0; i < mix_gens_.size(); ++i)
            if (u < (below += cfg_.mix[i].prob)) return *mix_gens_[i];
        return gen_;
    }

    // preview_<b>.png: what the detector trains on (a depth detector: its normals as colour),
    // with the target boxes.
    void preview(const std::vector<DetSample>& batch) const {
        const geom::Intrinsics& cam = ts_.scene.camera;
        const size_t plane = size_t(W_) * size_t(H_);
        for (size_t b = 0; b < std::min<size_t>(batch.size(), 4); ++b) {
            data::Image im;
            im.w = W_, im.h = H_, im.channels = 3;
            im.data = batch[b].rgb;
            if (!nn::uses_rgb(cfg_.input)) {
                std::vector<float> f(size_t(nn::kDepthChannels) * plane);
                nn::depth_features(batch[b].depth.data(), W_, H_, cam.fx, cam.fy, cam.cx, cam.cy,
                                   f.data(), W_, int64_t(W_) * H_);
                for (size_t i = 0; i < plane; ++i)
                    for (int k = 0; k < 3; ++k)
                        im.data[i * 3 + size_t(k)] = uint8_t(
                            std::clamp(127.5f * (f[(3 + size_t(k)) * plane + i] + 1.f), 0.f, 255.f));
            }
            for (const DetBox& d : batch[b].boxes) {
                const data::Rgb c{0, 255, 0};
                data::draw_line(&im, d.x, d.y, d.x + d.w, d.y, c, 1);
                data::draw_line(&im, d.x + d.w, d.y, d.x + d.w, d.y + d.h, c, 1);
                data::draw_line(&im, d.x + d.w, d.y + d.h, d.x, d.y + d.h, c, 1);
                data::draw_line(&im, d.x, d.y + d.h, d.x, d.y, c, 1);
            }
            data::save_png(run_.path(cat("preview_", b, ".png")), im);
        }
    }

    // Validation on the real frames of val_root (rank 0 alone; the others sleep until done).
    void validate(const LoopState& s) {
        if (!val_) return;
        if (dist::is_root()) {
            nn::LoadedDetector ld;
            ld.downscale = cfg_.downscale;
            ld.object_ids = cfg_.object_ids;  // the input kind travels in dc_
            // A copy in eval mode: the training net keeps its mode and state.
            ld.net = std::make_unique<nn::Detector>(dc_);
            ld.net->load_state_dict(net_.state_dict(), true);
            ld.net->eval();
            val_sum_.val = eval::evaluate_detector(ld, *val_, 0.1, 0.3f, cfg_.val_max_frames, false);
            val_sum_.evaluated = true;
            if (progress_)
                std::printf("validation at step %lld on %s/%s:\n%s", (long long)s.step,
                            cfg_.val_root.c_str(), cfg_.val_split.c_str(),
                            eval::detector_eval_table(val_sum_.val).c_str());
            run_.append("steps.jsonl", {{"step", s.step}, {"val_mean_recall", val_sum_.val.mean_recall},
                                        {"val_mean_precision", val_sum_.val.mean_precision},
                                        {"val_mean_peak_rate", val_sum_.val.mean_peak_rate}});
        }
        dist::barrier();
    }

    const DetectorTrainConfig& cfg_;
    const TrainOptions& opt_;
    const std::vector<data::Image> photos_;
    const RunDir& run_;
    const int64_t lo_, hi_;  // this process's images of each global batch
    const bool progress_;
    TrainingScene ts_;
    const int W_, H_;  // the detector's input size
    std::map<int, int> cls_;  // obj_id -> class
    std::unique_ptr<data::BopDataset> val_;
    nn::DetectorConfig dc_;
    nn::Detector net_;
    nn::Adam adam_;
    data::SceneGenerator gen_;
    std::vector<std::unique_ptr<data::SceneGenerator>> mix_gens_;  // data.mix's scenes
    DetectorTrainSummary val_sum_;
    bool previewed_ = false;
    std::future<std::vector<DetSample>> next_;  // last: joined before what make_batch reads
};

}  // namespace

DetectorTrainSummary run_detector_training(const DetectorTrainConfig& cfg, const TrainOptions& opt) {
    if (cfg.threads > 0) set_num_threads(cfg.threads);
    const std::string run_dir = opt.resume_dir.empty() ? cfg.run_dir : opt.resume_dir;
    std::vector<data::Image> photos = load_photos(cfg.backgrounds);  // before the run dir
    // Data-parallel (train/distributed.h): this process renders and trains on images [lo, hi)
    // of every global batch; rank 0 alone writes the run directory and prints.
    const std::pair<int64_t, int64_t> shard = dist::shard(cfg.batch);
    const RunDir run(run_dir, !opt.resume_dir.empty(), opt.force, {"steps.jsonl"}, dist::is_root());
    DetectorTask task(cfg, opt, std::move(photos), run, shard.first, shard.second);
    LoopState start;
    if (!opt.resume_dir.empty()) {
        start = task.resume(run.path("last.g2l"));
        G2L_CHECK(start.step < cfg.steps, "--resume '", run_dir, "': the run already finished "
                  "its ", cfg.steps, " steps");
        run.trim_log("steps.jsonl", "step", start.step);  // a killed run logged past it
    } else if (!cfg.init.empty()) {
        task.init_from(cfg.init);
    }
    run.begin(detector_config_to_json(cfg));

    LoopOptions lo;
    lo.epochs = 1;
    lo.global_batch = cfg.batch;
    lo.log_every = cfg.log_every;
    lo.checkpoint_every_steps = cfg.checkpoint_every;
    lo.time_limit_min = cfg.time_limit_min;
    lo.unit = "images";
    const LoopResult r = run_loop(task, run, lo, opt, start);

    DetectorTrainSummary sum = task.validation();
    sum.run_dir = run_dir;
    sum.steps = r.state.step;
    sum.interrupted = r.interrupted;
    sum.stopped_early = r.stopped_early;
    sum.images_per_s = r.samples_per_s;
    sum.final_loss = r.last_step_loss;
    return sum;
}

}  // namespace g2l::train
