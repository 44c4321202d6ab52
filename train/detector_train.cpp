// SPDX-License-Identifier: MIT
// The detector's training loop (renders → augmentation → CenterNet loss → Adam, checkpoints,
// validation) and export averaging. Config: detector_config.cpp; targets and loss:
// detector_loss.cpp; augmentation: detector_augment.cpp; evaluation: eval/detector_eval.cpp.
#include "train/detector_train.h"
#include "train/run_dir.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <map>
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
using Clock = std::chrono::steady_clock;

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
};

// The scene at the detector's input resolution: the camera scaled by 1/downscale.
data::SceneConfig input_scene(const DetectorTrainConfig& c) {
    data::SceneConfig s = c.scene;
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

}  // namespace

DetectorTrainSummary run_detector_training(const DetectorTrainConfig& cfg, const TrainOptions& opt) {
    if (cfg.threads > 0) set_num_threads(cfg.threads);
    const std::string run_dir = opt.resume_dir.empty() ? cfg.run_dir : opt.resume_dir;
    const std::vector<data::Image> photos = load_photos(cfg.backgrounds);  // before the run dir
    // Data-parallel (train/distributed.h): this process renders and trains on images
    // [img_lo, img_hi) of every global batch; rank 0 alone writes the run directory and prints.
    const bool root = dist::is_root();
    const bool progress = opt.progress && root;
    const std::pair<int64_t, int64_t> shard = dist::shard(cfg.batch);
    const int64_t img_lo = shard.first, img_hi = shard.second, local = img_hi - img_lo;
    const RunDir run(run_dir, !opt.resume_dir.empty(), opt.force, {"steps.jsonl"}, root);

    // ---- models and the scene ----
    data::BopOptions bo;
    bo.obj_ids = cfg.object_ids;
    const data::Dataset models = data::open_bop_models(cfg.models_root, bo);
    std::vector<data::SceneModel> sm;
    for (const int id : cfg.object_ids) {
        G2L_CHECK(models.models().count(id), "data.object_ids: no model ", id, " in ",
                  cfg.models_root);
        const geom::Mesh& mesh = models.load_model_mesh(id);
        G2L_CHECK(mesh.colors.rows() > 0 || !nn::uses_rgb(cfg.input), "data.object_ids: model ",
                  id, " of ", cfg.models_root, " has no vertex colours; an ", nn::to_string(cfg.input),
                  " detector learns from colour renders (data.input \"depth\" needs none)");
        sm.push_back({id, &mesh});
    }
    // Distractors: ids above kDistractorId (the largest id a model may have), numbered in
    // order, so no id collides with a target's or another distractor's.
    data::SceneConfig scene = input_scene(cfg);
    std::deque<geom::Mesh> distractor_meshes;
    if (!cfg.distractors_root.empty()) {
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

    const int W = scene.camera.width, H = scene.camera.height;
    G2L_CHECK(W % 16 == 0 && H % 16 == 0, "data.scene.camera: the detector input ", W, " x ", H,
              " (camera / downscale) must be a multiple of 16 in both sizes");
    std::map<int, int> cls;
    for (size_t i = 0; i < cfg.object_ids.size(); ++i) cls[cfg.object_ids[i]] = int(i);
    const int K = int(cfg.object_ids.size());
    std::unique_ptr<data::BopDataset> val;
    if (!cfg.val_root.empty()) {
        data::BopOptions vo;
        vo.obj_ids = cfg.object_ids;
        val = std::make_unique<data::BopDataset>(data::open_bop(cfg.val_root, cfg.val_split, vo));
    }

    nn::DetectorConfig dc;
    dc.num_classes = K;
    dc.width = cfg.width;
    dc.seed = cfg.seed;
    dc.input = cfg.input;
    nn::Detector net(dc);
    nn::AdamOptions ao;
    ao.lr = cfg.lr;
    ao.beta1 = 0.9;
    ao.beta2 = 0.999;
    nn::ParamGroup group;
    group.name = "detector";
    group.params = net.named_parameters();
    nn::Adam adam({group}, ao);

    int64_t step = 0;
    double seconds_before = 0;
    if (!opt.resume_dir.empty()) {
        const std::string path = run.path("last.g2l");
        const Checkpoint ck = load_checkpoint(path);
        const json meta = parse_json_strict(ck.meta_json, path + " (metadata)");
        G2L_CHECK(meta.is_object() && meta.value("format", "") == kCheckpointFormat, "'", path,
                  "' is not a detector training checkpoint");
        JsonReader r(meta, "checkpoint '" + path + "' (metadata)");
        r.ignore("format");
        r.require("step");
        r.integer("step", step);
        r.num("seconds", seconds_before);
        r.ignore("config");
        r.finish();
        G2L_CHECK(step >= 0 && seconds_before >= 0, r.source(), ": negative 'step' or 'seconds'");
        net.load_state_dict(model_state_of(ck.tensors), true);
        adam.load_state(ck.tensors, step);
        G2L_CHECK(step < cfg.steps, "--resume '", run_dir, "': the run already finished its ",
                  cfg.steps, " steps");
        run.trim_log("steps.jsonl", "step", step);  // a killed run logged past its checkpoint
    } else {
        if (!cfg.init.empty()) {  // fine-tuning: the weights of an export, a fresh optimiser
            const nn::LoadedDetector from = nn::load_detector(cfg.init);
            G2L_CHECK(from.object_ids == cfg.object_ids && from.net->config().width == cfg.width &&
                          from.input() == cfg.input,
                      "model.init '", cfg.init, "': its objects / width / input differ from the "
                      "config's (data.object_ids, model.width, data.input)");
            net.load_state_dict(from.net->state_dict(), true);
        }
    }
    run.begin(detector_config_to_json(cfg));
    const auto save = [&](const std::string& name, double seconds_total) {
        if (!root) return;  // the checkpoint holds the global state: one writer
        const json meta{{"format", kCheckpointFormat}, {"step", step},
                        {"seconds", seconds_total}, {"config", json::parse(detector_config_to_json(cfg))}};
        save_checkpoint(run.path(name), checkpoint_tensors(net.state_dict(), adam), meta.dump());
        nn::save_detector(run.path("detector.g2l"), net, cfg.object_ids, cfg.downscale);
    };

    // One generator per batch producer; frame index = step * batch + b (resumable exactly),
    // image b's draws seeded by (step, b): the global batch is the same for any number of
    // processes, this one making images [img_lo, img_hi).
    data::SceneGenerator gen(scene, sm);
    const int hw = W / nn::Detector::kStride, hh = H / nn::Detector::kStride;
    auto make_batch = [&](int64_t s) {
        std::vector<DetSample> batch(static_cast<size_t>(local));
        data::RenderedFrame fr;
        for (int64_t b = img_lo; b < img_hi; ++b) {
            gen.render_frame(s * cfg.batch + b, fr, 1);
            DetSample& d = batch[size_t(b - img_lo)];
            d.rgb = fr.rgb;
            if (nn::uses_depth(cfg.input)) d.depth = fr.depth;
            Rng rng(mix_seed(mix_seed(cfg.seed, uint64_t(s)), uint64_t(b) + 17));
            if (cfg.object_tone_prob > 0) {  // each target its own group, the distractors one
                const uint16_t dgroup = uint16_t(fr.instances.size() + 1);
                std::vector<uint16_t> groups(fr.mask);
                for (size_t i = 0; i < groups.size(); ++i)
                    if (groups[i] == 0 && !fr.distractor_mask.empty() && fr.distractor_mask[i])
                        groups[i] = dgroup;
                Rng trng(mix_seed(mix_seed(cfg.seed, uint64_t(s)), uint64_t(b) + 0x70E));
                object_tone(d.rgb, groups, W, H, cfg.object_tone_prob, trng);
            }
            // The pixels a new background must leave alone: targets' and distractors'.
            auto keep = [&fr] {
                std::vector<uint8_t> k(fr.mask.size());
                for (size_t i = 0; i < k.size(); ++i)
                    k[i] = fr.mask[i] != 0 || (!fr.distractor_mask.empty() && fr.distractor_mask[i]);
                return k;
            };
            if (cfg.photo_prob > 0 && rng.uniform() < cfg.photo_prob)
                photo_background(d.rgb, keep(), W, H, photos, rng);
            else if (rng.uniform() < cfg.clutter_prob)
                clutter_background(d.rgb, keep(), W, H, rng);
            // Occluders: random-coloured discs and rectangles pasted over the objects; the
            // visible masks (and so the target boxes and visible fractions) lose those pixels.
            std::vector<uint16_t> vis = fr.mask;
            if (cfg.occluder_prob > 0)
                for (const data::RenderedInstance& in : fr.instances) {
                    if (in.bbox_visib.empty() || rng.uniform() >= cfg.occluder_prob) continue;
                    const geom::Box2i& bb = in.bbox_visib;
                    const double rw = rng.uniform(0.2, 0.6) * bb.w, rh = rng.uniform(0.2, 0.6) * bb.h;
                    const double cx = bb.x + rng.uniform(0, 1) * bb.w, cy = bb.y + rng.uniform(0, 1) * bb.h;
                    const bool disc = rng.uniform() < 0.5;
                    uint8_t col[3];
                    for (uint8_t& c : col) c = uint8_t(rng.below(256));
                    float plate = 0;  // depth: a plate in front of the object's nearest point
                    if (!d.depth.empty()) {
                        float near = 1e30f;
                        for (int y = bb.y; y < bb.y + bb.h; ++y)
                            for (int x = bb.x; x < bb.x + bb.w; ++x) {
                                const size_t i = size_t(y) * size_t(W) + size_t(x);
                                if (i < d.depth.size() && d.depth[i] > 0) near = std::min(near, d.depth[i]);
                            }
                        plate = near < 1e29f ? std::max(50.f, near - float(rng.uniform(30, 150))) : 0.f;
                    }
                    for_each_shape_pixel(W, H, cx, cy, rw, rh, disc, [&](size_t i) {
                        for (int k = 0; k < 3; ++k) d.rgb[i * 3 + size_t(k)] = col[k];
                        if (plate > 0) d.depth[i] = plate;
                        vis[i] = 0;
                    });
                }
            augment(d.rgb, W, H, cfg, rng);
            // Every instance's box of the pixels left visible, in one pass over the mask.
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
            for (size_t k = 0; k < fr.instances.size(); ++k) {
                const data::RenderedInstance& in = fr.instances[k];
                auto it = cls.find(in.obj_id);
                const Acc& a = acc[k];
                if (it == cls.end() || in.px_count_all <= 0) continue;
                if (a.n == 0 || double(a.n) / double(in.px_count_all) < cfg.min_visib_fract) continue;
                d.boxes.push_back({it->second, float(a.x0), float(a.y0), float(a.x1 - a.x0 + 1),
                                   float(a.y1 - a.y0 + 1)});
            }
        }
        return batch;
    };

    DetectorTrainSummary sum;
    sum.run_dir = run_dir;
    const auto t0 = Clock::now();
    const int64_t start_step = step;
    double loss_acc = 0, lh_acc = 0, ls_acc = 0, lo_acc = 0;
    int acc_n = 0;
    std::future<std::vector<DetSample>> next =
        std::async(std::launch::async, make_batch, step);
    auto elapsed_min = [&]() {
        return (seconds_before + std::chrono::duration<double>(Clock::now() - t0).count()) / 60;
    };
    auto run_val = [&]() {
        if (!val) return;
        if (!root) {  // rank 0 validates alone; the others sleep until it is done
            dist::barrier();
            return;
        }
        nn::LoadedDetector ld;
        ld.downscale = cfg.downscale;
        ld.object_ids = cfg.object_ids;  // the input kind travels in dc
        // Evaluate a copy in eval mode (the training net keeps its mode and state).
        ld.net = std::make_unique<nn::Detector>(dc);
        ld.net->load_state_dict(net.state_dict(), true);
        ld.net->eval();
        sum.val = eval::evaluate_detector(ld, *val, 0.1, 0.3f, cfg.val_max_frames, false);
        sum.evaluated = true;
        if (progress)
            std::printf("validation at step %lld on %s/%s:\n%s", (long long)step,
                        cfg.val_root.c_str(), cfg.val_split.c_str(),
                        eval::detector_eval_table(sum.val).c_str());
        run.append("steps.jsonl", {{"step", step}, {"val_mean_recall", sum.val.mean_recall},
                                   {"val_mean_precision", sum.val.mean_precision},
                                   {"val_mean_peak_rate", sum.val.mean_peak_rate}});
        dist::barrier();
    };
    bool previewed = !opt.resume_dir.empty() || !root;
    while (step < cfg.steps) {
        std::vector<DetSample> batch = next.get();
        if (!previewed) {  // what the detector trains on, with its target boxes
            previewed = true;
            for (int b = 0; b < int(std::min<int64_t>(local, 4)); ++b) {
                data::Image im;
                im.w = W, im.h = H, im.channels = 3;
                im.data = batch[size_t(b)].rgb;
                if (!nn::uses_rgb(cfg.input)) {  // what a depth detector sees: the normals
                    std::vector<float> f(size_t(nn::kDepthChannels) * size_t(W) * size_t(H));
                    nn::depth_features(batch[size_t(b)].depth.data(), W, H, scene.camera.fx,
                                       scene.camera.fy, scene.camera.cx, scene.camera.cy, f.data(),
                                       W, int64_t(W) * H);
                    const size_t plane = size_t(W) * size_t(H);
                    for (size_t i = 0; i < plane; ++i)
                        for (int k = 0; k < 3; ++k)
                            im.data[i * 3 + size_t(k)] =
                                uint8_t(std::clamp(127.5f * (f[(3 + size_t(k)) * plane + i] + 1.f), 0.f, 255.f));
                }
                for (const DetBox& d : batch[size_t(b)].boxes) {
                    const data::Rgb c{0, 255, 0};
                    data::draw_line(&im, d.x, d.y, d.x + d.w, d.y, c, 1);
                    data::draw_line(&im, d.x + d.w, d.y, d.x + d.w, d.y + d.h, c, 1);
                    data::draw_line(&im, d.x + d.w, d.y + d.h, d.x, d.y + d.h, c, 1);
                    data::draw_line(&im, d.x, d.y + d.h, d.x, d.y, c, 1);
                }
                data::save_png(run.path(cat("preview_", b, ".png")), im);
            }
        }
        if (step + 1 < cfg.steps) next = std::async(std::launch::async, make_batch, step + 1);
        const int C = nn::detector_input_channels(cfg.input);
        Tensor x = Tensor::empty({local, C, H, W});
        std::vector<DetTargets> targets;
        for (int b = 0; b < int(local); ++b) {
            const std::vector<uint8_t>& rgb = batch[size_t(b)].rgb;
            float* px = x.data<float>() + size_t(b) * size_t(C) * size_t(H) * size_t(W);
            if (nn::uses_rgb(cfg.input))
                for (int k = 0; k < 3; ++k)
                    for (size_t i = 0; i < size_t(H) * size_t(W); ++i)
                        px[size_t(k) * size_t(H) * size_t(W) + i] =
                            (float(rgb[i * 3 + size_t(k)]) / 255.f - 0.5f) / 0.25f;
            if (nn::uses_depth(cfg.input))  // the encoding inference computes (nn::detector_input)
                nn::depth_features(batch[size_t(b)].depth.data(), W, H, scene.camera.fx,
                                   scene.camera.fy, scene.camera.cx, scene.camera.cy,
                                   px + (nn::uses_rgb(cfg.input) ? 3 : 0) * size_t(H) * size_t(W),
                                   W, int64_t(H) * W);
            targets.push_back(make_detector_targets(batch[size_t(b)].boxes, K, hw, hh));
        }
        // Step decay: x0.1 at 70% and 90% of the steps.
        adam.set_lr(cfg.lr * (step >= cfg.steps * 9 / 10 ? 0.01 : step >= cfg.steps * 7 / 10 ? 0.1 : 1.0));
        net.train();
        adam.zero_grad();
        double lh = 0, ls = 0, lo = 0;
        // The loss is normalised by the global batch's centres (one small all-reduce), so
        // the processes' losses and gradients add up to the one-process ones; BatchNorm sees
        // the global batch through the hook.
        double centres = detector_centres(targets);
        if (dist::size() > 1) dist::allreduce_sum(&centres, 1);
        const nn::DataParallel hook = dist::step_hook(cfg.batch, img_lo);
        const nn::DataParallelGuard hook_on(&hook);
        const nn::DetOut out = net.forward(x);
        Tensor loss = detector_loss(out, targets, cfg.w_heat, cfg.w_size, cfg.w_offset, &lh, &ls,
                                    &lo, centres);
        double lv = loss.item<double>();
        G2L_CHECK(std::isfinite(lv), "detector training: non-finite loss at step ", step + 1);
        loss.backward();
        // One all-reduce: every gradient, the loss terms and the stop flags (a signal or the
        // time limit seen by any process stops all after this step).
        std::vector<float> extra = {float(lv), float(lh), float(ls), float(lo),
                                    opt.stop_flag && opt.stop_flag->load() ? 1.f : 0.f,
                                    cfg.time_limit_min > 0 && elapsed_min() >= cfg.time_limit_min
                                        ? 1.f : 0.f};
        const double allreduce_s = dist::allreduce_gradients(adam, extra);
        if (dist::size() > 1) lv = extra[0], lh = extra[1], ls = extra[2], lo = extra[3];
        adam.step();
        ++step;
        loss_acc += lv, lh_acc += lh, ls_acc += ls, lo_acc += lo, ++acc_n;
        sum.final_loss = lv;
        const double secs = std::chrono::duration<double>(Clock::now() - t0).count();
        if (step % cfg.log_every == 0 || step == cfg.steps) {
            json rec{{"step", step},
                           {"loss", loss_acc / acc_n},
                           {"heat", lh_acc / acc_n},
                           {"size", ls_acc / acc_n},
                           {"offset", lo_acc / acc_n},
                           {"images_per_s", double((step - start_step) * cfg.batch) / std::max(1e-9, secs)},
                           {"minutes", elapsed_min()}};
            if (dist::size() > 1) rec["allreduce_s"] = allreduce_s;
            run.append("steps.jsonl", rec);
            if (progress)
                std::printf("step %lld/%lld  loss %.4f (heat %.4f size %.4f offset %.4f)  %.1f img/s  %.1f min\n",
                            (long long)step, (long long)cfg.steps, loss_acc / acc_n, lh_acc / acc_n,
                            ls_acc / acc_n, lo_acc / acc_n,
                            double((step - start_step) * cfg.batch) / std::max(1e-9, secs),
                            elapsed_min());
            std::fflush(stdout);
            loss_acc = lh_acc = ls_acc = lo_acc = 0;
            acc_n = 0;
        }
        const bool stop_flag = extra[4] > 0;
        const bool max_hit = opt.max_steps > 0 && step >= opt.max_steps;
        const bool time_hit = extra[5] > 0;
        if (step % cfg.checkpoint_every == 0 || step == cfg.steps || stop_flag || max_hit ||
            time_hit) {
            save("last.g2l",
                 seconds_before + std::chrono::duration<double>(Clock::now() - t0).count());
        }
        if (cfg.val_every > 0 && step % cfg.val_every == 0 && step < cfg.steps) run_val();
        if (stop_flag || ((max_hit || time_hit) && step < cfg.steps)) {
            // the log ends at the step last.g2l holds, with why the run stopped
            run.append("steps.jsonl", {{"step", step}, {"event", "stopped"},
                                       {"reason", stop_flag ? "signal"
                                                  : max_hit ? "max_steps" : "time_limit"},
                                       {"checkpoint", "last.g2l"}});
        }
        if (stop_flag) {
            sum.interrupted = true;
            break;
        }
        if (max_hit || time_hit) {
            sum.stopped_early = true;
            break;
        }
    }
    if (next.valid()) next.wait();
    const double secs = std::chrono::duration<double>(Clock::now() - t0).count();
    sum.steps = step;
    sum.images_per_s = double((step - start_step) * cfg.batch) / std::max(1e-9, secs);
    if (step >= cfg.steps) run_val();
    return sum;
}

}  // namespace g2l::train
