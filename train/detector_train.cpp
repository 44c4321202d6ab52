// SPDX-License-Identifier: MIT
#include "train/detector_train.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <deque>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "core/autograd.h"
#include "core/checkpoint.h"
#include "core/error.h"
#include "core/json.h"
#include "core/rng.h"
#include "core/threads.h"
#include "data/bop.h"
#include "geometry/crop.h"
#include "data/draw.h"
#include "data/render.h"
#include "nn/ops/elementwise.h"
#include "nn/ops/reduce.h"
#include "nn/optim.h"
#include "train/config.h"
#include "train/trainer.h"

namespace g2l::train {

namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

constexpr const char* kCheckpointFormat = "g2l-detector-train";

// ---------------------------------------------------------------- config
struct Keys {
    const json& obj;
    std::string where;
    std::set<std::string> seen;
    Keys(const json& o, std::string w) : obj(o), where(std::move(w)) {
        G2L_CHECK(o.is_object(), where, ": expected a JSON object, got ", o.type_name());
    }
    const json* get(const std::string& k) {
        seen.insert(k);
        auto it = obj.find(k);
        return it == obj.end() ? nullptr : &*it;
    }
    template <class T> void num(const std::string& k, T& v) {
        if (const json* j = get(k)) {
            G2L_CHECK(j->is_number(), where, ": '", k, "' must be a number, got ", j->dump());
            if constexpr (std::is_integral_v<T>) {
                G2L_CHECK(j->is_number_integer() || (j->is_number_float() &&
                                                     std::floor(j->get<double>()) == j->get<double>()),
                          where, ": '", k, "' must be an integer, got ", j->dump());
                v = T(j->get<double>());
            } else {
                v = j->get<T>();
            }
        }
    }
    void text(const std::string& k, std::string& v) {
        if (const json* j = get(k)) {
            G2L_CHECK(j->is_string(), where, ": '", k, "' must be a string, got ", j->dump());
            v = j->get<std::string>();
        }
    }
    void ints(const std::string& k, std::vector<int>& v) {
        if (const json* j = get(k)) {
            G2L_CHECK(j->is_array(), where, ": '", k, "' must be a list of integers, got ",
                      j->dump());
            v.clear();
            for (const json& e : *j) {
                G2L_CHECK(e.is_number_integer(), where, ": '", k,
                          "' must be a list of integers, got ", j->dump());
                v.push_back(e.get<int>());
            }
        }
    }
    void texts(const std::string& k, std::vector<std::string>& v) {
        if (const json* j = get(k)) {
            G2L_CHECK(j->is_array(), where, ": '", k, "' must be a list of strings, got ", j->dump());
            v.clear();
            for (const json& e : *j) {
                G2L_CHECK(e.is_string(), where, ": '", k, "' must be a list of strings, got ",
                          j->dump());
                v.push_back(e.get<std::string>());
            }
        }
    }
    void done() {
        for (auto it = obj.begin(); it != obj.end(); ++it)
            if (!seen.count(it.key())) {
                std::string known;
                for (const auto& s : seen) known += (known.empty() ? "" : ", ") + s;
                G2L_CHECK(false, where, ": unknown key '", it.key(), "' (known: ", known, ")");
            }
    }
};

json to_json(const DetectorTrainConfig& c) {
    return json{{"task", "detector"},
                {"name", c.name},
                {"seed", c.seed},
                {"threads", c.threads},
                {"device", c.device},
                {"run_dir", c.run_dir},
                {"data",
                 {{"models_root", c.models_root},
                  {"object_ids", c.object_ids},
                  {"downscale", c.downscale},
                  {"input", nn::to_string(c.input)},
                  {"min_visib_fract", c.min_visib_fract},
                  {"distractors_root", c.distractors_root},
                  {"distractor_ids", c.distractor_ids},
                  {"distractor_colors", c.distractor_colors},
                  {"scene", json::parse(data::scene_config_to_json(c.scene))}}},
                {"augment",
                 {{"color_jitter", c.color_jitter},
                  {"noise_std", c.noise_std},
                  {"blur_prob", c.blur_prob},
                  {"gray_prob", c.gray_prob},
                  {"clutter_prob", c.clutter_prob},
                  {"occluder_prob", c.occluder_prob},
                  {"backgrounds", c.backgrounds},
                  {"photo_prob", c.photo_prob},
                  {"object_tone_prob", c.object_tone_prob}}},
                {"model", {{"width", c.width}, {"init", c.init}}},
                {"loss", {{"heat", c.w_heat}, {"size", c.w_size}, {"offset", c.w_offset}}},
                {"optim", {{"lr", c.lr}}},
                {"train",
                 {{"steps", c.steps},
                  {"batch", c.batch},
                  {"checkpoint_every", c.checkpoint_every},
                  {"log_every", c.log_every},
                  {"time_limit_min", c.time_limit_min}}},
                {"val",
                 {{"root", c.val_root},
                  {"split", c.val_split},
                  {"every", c.val_every},
                  {"max_frames", c.val_max_frames}}}};
}

void validate(const DetectorTrainConfig& c, const std::string& where) {
    G2L_CHECK(!c.models_root.empty(), where, ": 'data.models_root' is required");
    G2L_CHECK(!c.object_ids.empty(), where, ": 'data.object_ids' must list at least one object");
    std::set<int> ids(c.object_ids.begin(), c.object_ids.end());
    G2L_CHECK(ids.size() == c.object_ids.size(), where, ": 'data.object_ids' repeats an id");
    G2L_CHECK(c.downscale == 1 || c.downscale == 2 || c.downscale == 4, where,
              ": 'data.downscale' must be 1, 2 or 4, got ", c.downscale);
    G2L_CHECK(c.min_visib_fract >= 0 && c.min_visib_fract <= 1, where,
              ": 'data.min_visib_fract' must be in [0, 1], got ", c.min_visib_fract);
    auto frac = [&](const char* k, double v) {
        G2L_CHECK(std::isfinite(v) && v >= 0 && v <= 1, where, ": '", k, "' must be in [0, 1], got ", v);
    };
    frac("augment.color_jitter", c.color_jitter);
    frac("augment.blur_prob", c.blur_prob);
    frac("augment.gray_prob", c.gray_prob);
    frac("augment.clutter_prob", c.clutter_prob);
    frac("augment.occluder_prob", c.occluder_prob);
    frac("augment.photo_prob", c.photo_prob);
    frac("augment.object_tone_prob", c.object_tone_prob);
    G2L_CHECK(c.photo_prob == 0 || !c.backgrounds.empty(), where,
              ": 'augment.photo_prob' is ", c.photo_prob, " but 'augment.backgrounds' lists no "
              "directory of photographs");
    G2L_CHECK(c.distractor_colors >= 1 && c.distractor_colors <= 16, where,
              ": 'data.distractor_colors' must be in [1, 16], got ", c.distractor_colors);
    G2L_CHECK(c.distractor_ids.empty() || !c.distractors_root.empty(), where,
              ": 'data.distractor_ids' is set but 'data.distractors_root' is empty");
    G2L_CHECK(std::isfinite(c.noise_std) && c.noise_std >= 0 && c.noise_std <= 128, where,
              ": 'augment.noise_std' must be in [0, 128], got ", c.noise_std);
    G2L_CHECK(c.width >= 4 && c.width <= 256, where, ": 'model.width' must be in [4, 256], got ",
              c.width);
    for (auto [k, v] : {std::pair<const char*, double>{"loss.heat", c.w_heat},
                        {"loss.size", c.w_size}, {"loss.offset", c.w_offset}})
        G2L_CHECK(std::isfinite(v) && v >= 0, where, ": '", k, "' must be >= 0, got ", v);
    G2L_CHECK(std::isfinite(c.lr) && c.lr > 0, where, ": 'optim.lr' must be > 0, got ", c.lr);
    G2L_CHECK(c.steps > 0, where, ": 'train.steps' must be > 0, got ", c.steps);
    G2L_CHECK(c.batch > 0 && c.batch <= 1024, where, ": 'train.batch' must be in [1, 1024], got ",
              c.batch);
    G2L_CHECK(c.checkpoint_every > 0, where, ": 'train.checkpoint_every' must be > 0, got ",
              c.checkpoint_every);
    G2L_CHECK(c.log_every > 0, where, ": 'train.log_every' must be > 0, got ", c.log_every);
    G2L_CHECK(std::isfinite(c.time_limit_min) && c.time_limit_min >= 0, where,
              ": 'train.time_limit_min' must be >= 0, got ", c.time_limit_min);
    G2L_CHECK(c.val_every >= 0 && c.val_max_frames >= 0, where,
              ": 'val.every' and 'val.max_frames' must be >= 0");
    G2L_CHECK(parse_device(c.device).is_cpu(), where, ": device '", c.device,
              "': the detector trains on the CPU in this version");
    G2L_CHECK(c.threads >= 0, where, ": 'threads' must be >= 0, got ", c.threads);
}

}  // namespace

DetectorTrainConfig parse_detector_config(const std::string& json_text, const std::string& source,
                                          const std::string& base_dir) {
    const json root = parse_json_strict(json_text, source);
    DetectorTrainConfig c;
    Keys k(root, source);
    std::string task;
    k.text("task", task);
    G2L_CHECK(task == "detector", source, ": 'task' must be \"detector\" for a detector config, "
                                          "got \"", task, "\"");
    k.text("name", c.name);
    k.num("seed", c.seed);
    k.num("threads", c.threads);
    k.text("device", c.device);
    k.text("run_dir", c.run_dir);
    // Each section: an object whose keys are read by fill(), unknown keys refused.
    auto section = [&](const char* name, const std::function<void(Keys&)>& fill) {
        if (const json* j = k.get(name)) {
            Keys ks(*j, source + ": " + name);
            fill(ks);
            ks.done();
        }
    };
    section("data", [&](Keys& kd) {
        kd.text("models_root", c.models_root);
        kd.ints("object_ids", c.object_ids);
        kd.num("downscale", c.downscale);
        std::string input = nn::to_string(c.input);
        kd.text("input", input);
        c.input = nn::parse_detector_input(input, source + ": data.input");
        kd.num("min_visib_fract", c.min_visib_fract);
        kd.text("distractors_root", c.distractors_root);
        kd.ints("distractor_ids", c.distractor_ids);
        kd.num("distractor_colors", c.distractor_colors);
        if (const json* s = kd.get("scene"))
            c.scene = data::parse_scene_config(s->dump(), source + ": data.scene");
    });
    section("augment", [&](Keys& ka) {
        ka.num("color_jitter", c.color_jitter);
        ka.num("noise_std", c.noise_std);
        ka.num("blur_prob", c.blur_prob);
        ka.num("gray_prob", c.gray_prob);
        ka.num("clutter_prob", c.clutter_prob);
        ka.num("occluder_prob", c.occluder_prob);
        ka.texts("backgrounds", c.backgrounds);
        ka.num("photo_prob", c.photo_prob);
        ka.num("object_tone_prob", c.object_tone_prob);
    });
    section("model", [&](Keys& km) {
        km.num("width", c.width);
        km.text("init", c.init);
    });
    section("loss", [&](Keys& kl) {
        kl.num("heat", c.w_heat);
        kl.num("size", c.w_size);
        kl.num("offset", c.w_offset);
    });
    section("optim", [&](Keys& ko) { ko.num("lr", c.lr); });
    section("train", [&](Keys& kt) {
        kt.num("steps", c.steps);
        kt.num("batch", c.batch);
        kt.num("checkpoint_every", c.checkpoint_every);
        kt.num("log_every", c.log_every);
        kt.num("time_limit_min", c.time_limit_min);
    });
    section("val", [&](Keys& kv) {
        kv.text("root", c.val_root);
        kv.text("split", c.val_split);
        kv.num("every", c.val_every);
        kv.num("max_frames", c.val_max_frames);
    });
    k.done();
    if (!c.models_root.empty()) c.models_root = resolve_config_path(c.models_root, base_dir);
    if (!c.val_root.empty()) c.val_root = resolve_config_path(c.val_root, base_dir);
    if (!c.init.empty()) c.init = resolve_config_path(c.init, base_dir);
    if (!c.distractors_root.empty())
        c.distractors_root = resolve_config_path(c.distractors_root, base_dir);
    for (std::string& b : c.backgrounds) b = resolve_config_path(b, base_dir);
    if (c.run_dir.empty()) c.run_dir = "runs/" + c.name;  // as the pose trainer: cwd-relative
    validate(c, source);
    return c;
}

std::string detector_config_to_json(const DetectorTrainConfig& cfg) {
    return to_json(cfg).dump(2) + "\n";
}

bool is_detector_config(const std::string& path) {
    const json j = parse_json_file(path);
    return j.is_object() && j.contains("task") && j["task"] == "detector";
}

DetectorTrainConfig load_detector_config(const std::string& path,
                                         const std::vector<std::string>& sets) {
    std::ifstream f(path, std::ios::binary);
    G2L_CHECK(f.good(), "load_detector_config: cannot open config file '", path, "'");
    std::ostringstream text;
    text << f.rdbuf();
    const std::string dir = fs::absolute(path).parent_path().lexically_normal().string();
    // As the pose trainer: overrides apply to the full config (defaults included), so any key
    // of docs/config.md can be set even when the file leaves it out.
    DetectorTrainConfig c = parse_detector_config(text.str(), path, dir);
    if (sets.empty()) return c;
    return parse_detector_config(apply_sets_to_json(detector_config_to_json(c), sets, path), path,
                                 dir);
}

// ---------------------------------------------------------------- targets and loss
DetTargets make_detector_targets(const std::vector<DetBox>& boxes, int K, int w, int h,
                                 int stride) {
    G2L_CHECK(K > 0 && w > 0 && h > 0 && stride > 0, "make_detector_targets: bad sizes K ", K,
              ", ", w, " x ", h, ", stride ", stride);
    DetTargets t;
    const size_t plane = size_t(w) * size_t(h);
    t.heat.assign(size_t(K) * plane, 0.f);
    t.size.assign(2 * plane, 0.f);
    t.offset.assign(2 * plane, 0.f);
    t.mask.assign(plane, 0.f);
    for (const DetBox& b : boxes) {
        G2L_CHECK(b.cls >= 0 && b.cls < K, "make_detector_targets: class ", b.cls,
                  " outside [0, ", K, ")");
        if (!(b.w > 0 && b.h > 0) || !std::isfinite(b.x) || !std::isfinite(b.y)) continue;
        const float cx = (b.x + 0.5f * b.w) / float(stride), cy = (b.y + 0.5f * b.h) / float(stride);
        const int ix = int(std::floor(cx)), iy = int(std::floor(cy));
        if (ix < 0 || iy < 0 || ix >= w || iy >= h) continue;
        const float bw = b.w / float(stride), bh = b.h / float(stride);
        const float sigma = std::max(0.7f, 0.1f * std::sqrt(bw * bh));
        const int r = int(std::ceil(3 * sigma));
        float* heat = t.heat.data() + size_t(b.cls) * plane;
        for (int y = std::max(0, iy - r); y <= std::min(h - 1, iy + r); ++y)
            for (int x = std::max(0, ix - r); x <= std::min(w - 1, ix + r); ++x) {
                const float d2 = float((x - ix) * (x - ix) + (y - iy) * (y - iy));
                const float g = x == ix && y == iy ? 1.f : std::exp(-d2 / (2 * sigma * sigma));
                float& v = heat[size_t(y) * size_t(w) + size_t(x)];
                v = std::max(v, g);
            }
        const size_t i = size_t(iy) * size_t(w) + size_t(ix);
        t.mask[i] = 1.f;
        t.size[i] = std::log(bw);
        t.size[plane + i] = std::log(bh);
        t.offset[i] = cx - float(ix);
        t.offset[plane + i] = cy - float(iy);
    }
    return t;
}

Tensor detector_loss(const nn::DetOut& out, const std::vector<DetTargets>& targets,
                     double w_heat, double w_size, double w_offset, double* heat_loss,
                     double* size_loss, double* offset_loss) {
    G2L_CHECK(out.heat.defined() && out.heat.dim() == 4, "detector_loss: bad heat output");
    const int64_t B = out.heat.size(0), K = out.heat.size(1), H = out.heat.size(2),
                  W = out.heat.size(3);
    G2L_CHECK(int64_t(targets.size()) == B, "detector_loss: ", targets.size(),
              " targets for a batch of ", B);
    const size_t plane = size_t(H) * size_t(W);
    Tensor gt = Tensor::empty({B, K, H, W}), pos = Tensor::empty({B, K, H, W});
    Tensor negw = Tensor::empty({B, K, H, W});
    Tensor st = Tensor::empty({B, 2, H, W}), ot = Tensor::empty({B, 2, H, W});
    Tensor m = Tensor::empty({B, 1, H, W});
    double npos = 0;
    for (int64_t b = 0; b < B; ++b) {
        const DetTargets& t = targets[size_t(b)];
        G2L_CHECK(t.heat.size() == size_t(K) * plane && t.mask.size() == plane &&
                      t.size.size() == 2 * plane && t.offset.size() == 2 * plane,
                  "detector_loss: targets of sample ", b, " do not match the ", K, " x ", H,
                  " x ", W, " output");
        for (size_t i = 0; i < size_t(K) * plane; ++i) {
            const float g = t.heat[i];
            const size_t o = size_t(b) * size_t(K) * plane + i;
            gt.data<float>()[o] = g;
            const bool p = g >= 1.f;
            pos.data<float>()[o] = p ? 1.f : 0.f;
            const float q = 1.f - g;
            negw.data<float>()[o] = p ? 0.f : q * q * q * q;
            npos += p;
        }
        std::copy(t.size.begin(), t.size.end(), st.data<float>() + size_t(b) * 2 * plane);
        std::copy(t.offset.begin(), t.offset.end(), ot.data<float>() + size_t(b) * 2 * plane);
        std::copy(t.mask.begin(), t.mask.end(), m.data<float>() + size_t(b) * plane);
    }
    const double norm = 1.0 / std::max(1.0, npos);
    // Penalty-reduced focal loss (CenterNet): -(1-p)^2 log p at centres,
    // -(1-g)^4 p^2 log(1-p) elsewhere; p clamped away from 0 and 1.
    const Tensor p = nn::clamp(nn::sigmoid(out.heat), 1e-4, 1 - 1e-4);
    const Tensor one_minus = 1.0 - p;
    const Tensor lpos = pos * nn::log(p) * nn::square(one_minus);
    const Tensor lneg = negw * nn::log(one_minus) * nn::square(p);
    const Tensor Lh = nn::sum(lpos + lneg) * (-norm);
    const Tensor Ls = nn::sum(m * nn::abs(out.size - st)) * norm;
    const Tensor Lo = nn::sum(m * nn::abs(out.offset - ot)) * norm;
    if (heat_loss) *heat_loss = Lh.item<double>();
    if (size_loss) *size_loss = Ls.item<double>();
    if (offset_loss) *offset_loss = Lo.item<double>();
    return Lh * w_heat + Ls * w_size + Lo * w_offset;
}

// ---------------------------------------------------------------- evaluation
namespace {

// True when the frame has the images the detector's input needs (RGB and / or depth).
bool has_inputs(const nn::LoadedDetector& det, const data::Frame& fr) {
    return (!nn::uses_rgb(det.input()) || !fr.rgb_path.empty()) &&
           (!nn::uses_depth(det.input()) || !fr.depth_path.empty());
}

// The detector on one dataset frame, fed what its input kind needs (the RGB image, the depth
// in mm and the frame's intrinsics); *w / *h get the frame size, *ms the detector time.
std::vector<nn::Detection> detect_frame(const nn::LoadedDetector& det, const data::Dataset& ds,
                                        const data::Frame& fr, float min_score, int max_per_class,
                                        bool mirror, int* w, int* h, double* ms) {
    const nn::DetectorInput input = det.input();
    data::Image img;
    std::vector<float> depth;
    nn::DetectorFrame f;
    if (nn::uses_rgb(input)) {
        G2L_CHECK(!fr.rgb_path.empty(), "the ", nn::to_string(input), " detector needs an RGB "
                  "image and frame ", fr.scene, "/", fr.image_id, " of '", ds.root(), "' has none");
        img = ds.load_rgb(fr);
        G2L_CHECK(img.channels == 3, "'", fr.rgb_path, "' is not an RGB image");
        f.rgb = img.data.data(), f.width = img.w, f.height = img.h;
    }
    if (nn::uses_depth(input)) {
        G2L_CHECK(!fr.depth_path.empty(), "the ", nn::to_string(input), " detector needs a depth "
                  "image and frame ", fr.scene, "/", fr.image_id, " of '", ds.root(), "' has none");
        int dw = 0, dh = 0;
        depth = ds.load_depth_mm(fr, &dw, &dh);
        G2L_CHECK(!f.rgb || (dw == f.width && dh == f.height), "'", fr.depth_path, "' is ", dw,
                  " x ", dh, " pixels but its RGB image '", fr.rgb_path, "' is ", f.width, " x ",
                  f.height);
        f.depth_mm = depth.data(), f.width = dw, f.height = dh;
        f.fx = fr.K.fx, f.fy = fr.K.fy, f.cx = fr.K.cx, f.cy = fr.K.cy;
    }
    *w = f.width, *h = f.height;
    const auto t0 = Clock::now();
    std::vector<nn::Detection> dets =
        nn::detect(*det.net, det.downscale, f, min_score, max_per_class, mirror);
    *ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    return dets;
}


}  // namespace

DetectorEvalResult evaluate_detector(const nn::LoadedDetector& det, const data::Dataset& ds,
                                     double min_visib, float score_threshold, int max_frames,
                                     bool progress, bool mirror) {
    G2L_CHECK(det.net, "evaluate_detector: no network");
    std::map<int, int> cls;
    for (size_t i = 0; i < det.object_ids.size(); ++i) cls[det.object_ids[i]] = int(i);
    DetectorEvalResult r;
    r.rows.resize(det.object_ids.size());
    for (size_t i = 0; i < det.object_ids.size(); ++i) r.rows[i].obj_id = det.object_ids[i];
    std::vector<size_t> frames;
    const bool need_rgb = nn::uses_rgb(det.input()), need_depth = nn::uses_depth(det.input());
    for (size_t f = 0; f < ds.frames().size(); ++f)
        if (has_inputs(det, ds.frames()[f])) frames.push_back(f);
    G2L_CHECK(!frames.empty(), "evaluate_detector: the dataset '", ds.root(),
              "' has no frame with the ", need_rgb ? "RGB" : "", need_rgb && need_depth ? " and " : "",
              need_depth ? "depth" : "", " image the ", nn::to_string(det.input()),
              " detector needs");
    if (max_frames > 0 && int(frames.size()) > max_frames) {
        std::vector<size_t> keep;
        for (int i = 0; i < max_frames; ++i)
            keep.push_back(frames[size_t(i) * frames.size() / size_t(max_frames)]);
        frames = keep;
    }
    double ms = 0;
    std::unique_ptr<data::Renderer> renderer;
    data::RenderOutput ro;
    for (size_t fi = 0; fi < frames.size(); ++fi) {
        const data::Frame& fr = ds.frames()[frames[fi]];
        int img_w = 0, img_h = 0;  // the frame's size
        double frame_ms = 0;
        const std::vector<nn::Detection> dets =
            detect_frame(det, ds, fr, 0.01f, 10, mirror, &img_w, &img_h, &frame_ms);
        ms += frame_ms;
        // Visible masks: from the dataset, else rendered from the GT poses of the frame.
        bool rendered = false;
        auto ensure_render = [&]() {
            if (rendered) return;
            rendered = true;
            geom::Intrinsics K = fr.K;
            K.width = img_w;
            K.height = img_h;
            if (!renderer || renderer->intrinsics().width != K.width ||
                renderer->intrinsics().height != K.height || renderer->intrinsics().fx != K.fx ||
                renderer->intrinsics().fy != K.fy || renderer->intrinsics().cx != K.cx ||
                renderer->intrinsics().cy != K.cy)
                renderer = std::make_unique<data::Renderer>(K);
            std::vector<data::RenderObject> objs;
            for (size_t k = 0; k < fr.instances.size(); ++k) {
                const data::Instance& in = fr.instances[k];
                if (!ds.models().count(in.obj_id)) continue;
                data::RenderObject o;
                o.mesh = &ds.load_model_mesh(in.obj_id);
                o.pose = in.pose;
                o.instance_id = int32_t(k) + 1;
                objs.push_back(o);
            }
            data::RenderOptions opt;
            opt.shade = false;
            renderer->render(objs, opt, ro);
        };
        // Greedy one-to-one matching for precision, per class, by score.
        std::vector<bool> gt_used(fr.instances.size(), false);
        for (const nn::Detection& d : dets) {
            if (d.score < score_threshold) continue;
            DetectorEvalRow& row = r.rows[size_t(d.cls)];
            ++row.detections;
            int best = -1;
            double best_iou = 0.5;
            for (size_t k = 0; k < fr.instances.size(); ++k) {
                const data::Instance& in = fr.instances[k];
                auto it = cls.find(in.obj_id);
                if (gt_used[k] || it == cls.end() || it->second != d.cls) continue;
                const geom::Box2i& b = in.box();
                const double v = geom::box_iou(d.x, d.y, d.w, d.h, float(b.x), float(b.y), float(b.w),
                                     float(b.h));
                if (v >= best_iou) best_iou = v, best = int(k);
            }
            if (best >= 0) {
                gt_used[size_t(best)] = true;
                ++row.true_detections;
            }
        }
        // Each class's detections, best first (nn::detect returns them in that order).
        std::vector<std::vector<const nn::Detection*>> by_class(r.rows.size());
        for (const nn::Detection& d : dets) by_class[size_t(d.cls)].push_back(&d);
        for (size_t k = 0; k < fr.instances.size(); ++k) {
            const data::Instance& in = fr.instances[k];
            auto it = cls.find(in.obj_id);
            if (it == cls.end()) continue;
            if (!in.visible_enough(min_visib)) continue;
            const geom::Box2i& b = in.box();
            if (b.empty()) continue;
            DetectorEvalRow& row = r.rows[size_t(it->second)];
            ++row.instances;
            const std::vector<const nn::Detection*>& mine = by_class[size_t(it->second)];
            if (mine.empty()) continue;
            const nn::Detection* best = mine.front();  // the class's best: what the pipeline uses
            if (geom::box_iou(best->x, best->y, best->w, best->h, float(b.x), float(b.y), float(b.w),
                    float(b.h)) >= 0.5)
                ++row.found;
            for (size_t q = 0; q < std::min<size_t>(3, mine.size()); ++q)
                if (geom::box_iou(mine[q]->x, mine[q]->y, mine[q]->w, mine[q]->h, float(b.x), float(b.y),
                        float(b.w), float(b.h)) >= 0.5) {
                    ++row.found_top3;
                    break;
                }
            const int u = int(std::floor(best->peak_x)), v = int(std::floor(best->peak_y));
            if (u < 0 || v < 0 || u >= img_w || v >= img_h) continue;
            bool on = false;
            if (!in.mask_visib_path.empty()) {
                const data::Image m = ds.load_mask(fr, in);
                on = m.w == img_w && m.h == img_h && m.data[size_t(v) * size_t(m.w) + size_t(u)] != 0;
            } else {
                ensure_render();
                on = ro.instance[size_t(v) * size_t(img_w) + size_t(u)] == int32_t(k) + 1;
            }
            row.peak_on_mask += on;
        }
        ++r.frames;
        if (progress && (fi + 1) % 20 == 0)
            std::fprintf(stderr, "  detector eval: %zu / %zu frames\n", fi + 1, frames.size());
    }
    int n = 0;
    for (const DetectorEvalRow& row : r.rows) {
        r.total.instances += row.instances;
        r.total.found += row.found;
        r.total.found_top3 += row.found_top3;
        r.total.peak_on_mask += row.peak_on_mask;
        r.total.detections += row.detections;
        r.total.true_detections += row.true_detections;
        if (row.instances == 0) continue;
        ++n;
        r.mean_recall += row.recall();
        r.mean_recall_top3 += row.recall_top3();
        r.mean_precision += row.precision();
        r.mean_peak_rate += row.peak_rate();
    }
    if (n) r.mean_recall /= n, r.mean_precision /= n, r.mean_peak_rate /= n, r.mean_recall_top3 /= n;
    r.ms_per_frame = r.frames ? ms / r.frames : 0;
    return r;
}

std::vector<data::Detection> run_detector_on(const nn::LoadedDetector& det, const data::Dataset& ds,
                                             float min_score, bool mirror) {
    G2L_CHECK(det.net, "run_detector_on: no network");
    std::vector<data::Detection> out;
    for (const data::Frame& fr : ds.frames()) {
        if (!has_inputs(det, fr)) continue;
        int scene_id = -1;
        try {
            scene_id = std::stoi(fr.scene);
        } catch (const std::exception&) {
            G2L_CHECK(false, "run_detector_on: scene '", fr.scene, "' is not a number (BOP scene "
                             "ids are), so detections cannot be matched to it");
        }
        int w = 0, h = 0;
        double ms = 0;
        const auto dets = detect_frame(det, ds, fr, min_score, 3, mirror, &w, &h, &ms);
        const double secs = ms / 1000;
        for (const nn::Detection& d : dets) {
            data::Detection o;
            o.scene_id = scene_id;
            o.image_id = fr.image_id;
            o.obj_id = det.object_ids[size_t(d.cls)];
            o.x = d.x, o.y = d.y, o.w = d.w, o.h = d.h;
            o.score = d.score;
            o.time = secs;
            o.peak_x = d.peak_x, o.peak_y = d.peak_y;
            out.push_back(o);
        }
    }
    return out;
}

std::string detector_eval_table(const DetectorEvalResult& r) {
    std::ostringstream o;
    char line[256];
    std::snprintf(line, sizeof line, "%8s %9s %10s %12s %13s %11s %10s\n", "obj_id", "instances",
                  "recall@.5", "recall_top3", "precision@.5", "peak_on_obj", "dets>=thr");
    o << line;
    for (const DetectorEvalRow& row : r.rows) {
        std::snprintf(line, sizeof line, "%8d %9d %10.1f %12.1f %13.1f %11.1f %10d\n", row.obj_id,
                      row.instances, 100 * row.recall(), 100 * row.recall_top3(),
                      100 * row.precision(), 100 * row.peak_rate(), row.detections);
        o << line;
    }
    std::snprintf(line, sizeof line, "%8s %9d %10.1f %12.1f %13.1f %11.1f %10d\n", "mean",
                  r.total.instances, 100 * r.mean_recall, 100 * r.mean_recall_top3,
                  100 * r.mean_precision, 100 * r.mean_peak_rate, r.total.detections);
    o << line;
    std::snprintf(line, sizeof line, "%d frames, %.1f ms per frame (detector)\n", r.frames,
                  r.ms_per_frame);
    o << line;
    return o.str();
}

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

// ---------------------------------------------------------------- training
void object_tone(std::vector<uint8_t>& rgb, const std::vector<uint16_t>& groups, int w, int h,
                 double prob, Rng& rng) {
    G2L_CHECK(w > 0 && h > 0, "object_tone: bad image size ", w, " x ", h);
    const size_t n = size_t(w) * size_t(h);
    G2L_CHECK(rgb.size() == n * 3 && groups.size() == n, "object_tone: ", rgb.size(),
              " colour values and ", groups.size(), " group ids for a ", w, " x ", h, " image");
    G2L_CHECK(std::isfinite(prob) && prob >= 0 && prob <= 1, "object_tone: prob must be in [0, 1], got ",
              prob);
    if (prob == 0) return;
    // Mean colour of every group present, in one pass.
    std::map<uint16_t, std::array<double, 4>> mean;
    for (size_t i = 0; i < n; ++i) {
        if (groups[i] == 0) continue;
        auto& m = mean[groups[i]];
        for (int k = 0; k < 3; ++k) m[size_t(k)] += rgb[i * 3 + size_t(k)];
        m[3] += 1;
    }
    struct Tone {
        float mean[3], contrast, gain[3], sat;
    };
    std::map<uint16_t, Tone> tone;  // the groups drawn to change, in id order (reproducible)
    for (auto& [g, m] : mean) {
        if (rng.uniform() >= prob) continue;
        Tone t;
        for (int k = 0; k < 3; ++k) t.mean[k] = float(m[size_t(k)] / m[3]);
        t.contrast = float(rng.uniform(0.4, 1.0));
        const double bright = rng.uniform(0.5, 1.2);
        for (float& gk : t.gain) gk = float(bright * rng.uniform(0.85, 1.15));
        t.sat = float(rng.uniform(0.5, 1.3));
        tone[g] = t;
    }
    if (tone.empty()) return;
    for (size_t i = 0; i < n; ++i) {
        if (groups[i] == 0) continue;
        const auto it = tone.find(groups[i]);
        if (it == tone.end()) continue;
        const Tone& t = it->second;
        float v[3];
        for (int k = 0; k < 3; ++k)
            v[k] = (t.mean[k] + t.contrast * (float(rgb[i * 3 + size_t(k)]) - t.mean[k])) * t.gain[k];
        const float lum = (v[0] + v[1] + v[2]) / 3;
        for (int k = 0; k < 3; ++k)
            rgb[i * 3 + size_t(k)] = uint8_t(std::clamp(lum + t.sat * (v[k] - lum) + 0.5f, 0.f, 255.f));
    }
}

namespace {

struct DetSample {
    std::vector<uint8_t> rgb;  // H x W x 3 at the detector's input resolution
    std::vector<float> depth;  // H x W (mm), for a depth or rgbd detector
    std::vector<DetBox> boxes;
};

// Colour gain / brightness, grey, Gaussian noise, 3x3 box blur: in place.
void augment(std::vector<uint8_t>& rgb, int w, int h, const DetectorTrainConfig& c, Rng& rng) {
    float gain[3], bias = float(rng.uniform(-c.color_jitter, c.color_jitter) * 255 * 0.5);
    const float g0 = float(rng.uniform(1 - c.color_jitter, 1 + c.color_jitter));
    for (float& g : gain) g = g0 * float(rng.uniform(1 - 0.5 * c.color_jitter, 1 + 0.5 * c.color_jitter));
    const bool gray = rng.uniform() < c.gray_prob;
    const float noise = float(rng.uniform(0, c.noise_std));
    const size_t n = size_t(w) * size_t(h);
    for (size_t i = 0; i < n; ++i) {
        float v[3];
        for (int k = 0; k < 3; ++k) v[k] = float(rgb[i * 3 + size_t(k)]) * gain[k] + bias;
        if (gray) v[0] = v[1] = v[2] = (v[0] + v[1] + v[2]) / 3;
        for (int k = 0; k < 3; ++k) {
            const float x = v[k] + (noise > 0 ? noise * float(rng.normal()) : 0.f);
            rgb[i * 3 + size_t(k)] = uint8_t(std::clamp(x, 0.f, 255.f));
        }
    }
    if (rng.uniform() < c.blur_prob) {
        std::vector<uint8_t> src = rgb;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                for (int k = 0; k < 3; ++k) {
                    int s = 0, m = 0;
                    for (int dy = -1; dy <= 1; ++dy)
                        for (int dx = -1; dx <= 1; ++dx) {
                            const int yy = y + dy, xx = x + dx;
                            if (yy < 0 || yy >= h || xx < 0 || xx >= w) continue;
                            s += src[(size_t(yy) * size_t(w) + size_t(xx)) * 3 + size_t(k)];
                            ++m;
                        }
                    rgb[(size_t(y) * size_t(w) + size_t(x)) * 3 + size_t(k)] = uint8_t(s / m);
                }
    }
}

// Calls f(pixel index) for every pixel of a w x h image inside the axis-aligned ellipse (disc)
// or rectangle of centre (cx, cy) and half-sizes (rw, rh), clipped to the image.
template <class F>
void for_each_shape_pixel(int w, int h, double cx, double cy, double rw, double rh, bool disc,
                          F&& f) {
    const int x0 = std::max(0, int(cx - rw)), x1 = std::min(w - 1, int(cx + rw));
    const int y0 = std::max(0, int(cy - rh)), y1 = std::min(h - 1, int(cy + rh));
    for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) {
            if (disc) {
                const double dx = (x - cx) / rw, dy = (y - cy) / rh;
                if (dx * dx + dy * dy > 1) continue;
            }
            f(size_t(y) * size_t(w) + size_t(x));
        }
}

// A "dead leaves" clutter texture (random rectangles and discs of random colours, sizes spread
// over a log scale, painted back to front) replaces every pixel that shows no object (keep == 0):
// real frames show cluttered desks, the renders a plain table.
void clutter_background(std::vector<uint8_t>& rgb, const std::vector<uint8_t>& keep, int w,
                        int h, Rng& rng) {
    std::vector<uint8_t> bg(size_t(w) * size_t(h) * 3);
    for (size_t i = 0; i < bg.size(); i += 3) {
        bg[i] = uint8_t(rng.below(256));
        bg[i + 1] = bg[i];
        bg[i + 2] = bg[i];
    }
    const int shapes = int(rng.randint(40, 160));
    for (int s = 0; s < shapes; ++s) {
        const double size = std::exp(rng.uniform(std::log(3.0), std::log(0.6 * std::max(w, h))));
        const double cx = rng.uniform(-0.1 * w, 1.1 * w), cy = rng.uniform(-0.1 * h, 1.1 * h);
        const double aspect = std::exp(rng.uniform(-1.2, 1.2));
        const double rw = size * aspect * 0.5, rh = size / aspect * 0.5;
        const bool disc = rng.uniform() < 0.5;
        uint8_t col[3];
        const double sat = rng.uniform();
        const double base = rng.uniform(0, 255);
        for (uint8_t& c : col) c = uint8_t(std::clamp(base + sat * rng.uniform(-128, 128), 0.0, 255.0));
        for_each_shape_pixel(w, h, cx, cy, rw, rh, disc, [&](size_t i) {
            uint8_t* p = &bg[i * 3];
            p[0] = col[0], p[1] = col[1], p[2] = col[2];
        });
    }
    for (size_t i = 0; i < size_t(w) * size_t(h); ++i)
        if (keep[i] == 0)
            for (int k = 0; k < 3; ++k) rgb[i * 3 + size_t(k)] = bg[i * 3 + size_t(k)];
}

// A random crop of a random photograph (35-100% of its width, the input's aspect ratio,
// mirrored half the time), resampled bilinearly, replaces every pixel with keep == 0.
void photo_background(std::vector<uint8_t>& rgb, const std::vector<uint8_t>& keep, int w, int h,
                      const std::vector<data::Image>& photos, Rng& rng) {
    const data::Image& p = photos[size_t(rng.below(photos.size()))];
    const double aspect = double(h) / double(w);
    double cw = rng.uniform(0.35, 1.0) * p.w;
    if (cw * aspect > p.h) cw = p.h / aspect;
    const double ch = cw * aspect;
    const double x0 = rng.uniform(0, std::max(0.0, p.w - cw)), y0 = rng.uniform(0, std::max(0.0, p.h - ch));
    const bool flip = rng.uniform() < 0.5;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const size_t i = size_t(y) * size_t(w) + size_t(x);
            if (keep[i]) continue;
            const double fx = (flip ? (w - 1 - x) : x) + 0.5, fy = y + 0.5;
            const double sx = std::clamp(x0 + fx * cw / w - 0.5, 0.0, double(p.w - 1));
            const double sy = std::clamp(y0 + fy * ch / h - 0.5, 0.0, double(p.h - 1));
            const int ix = std::min(int(sx), p.w - 2);  // photos are >= 16 px (load_photos)
            const int iy = std::min(int(sy), p.h - 2);
            const double ax = std::clamp(sx - ix, 0.0, 1.0), ay = std::clamp(sy - iy, 0.0, 1.0);
            const int ix1 = std::min(ix + 1, p.w - 1), iy1 = std::min(iy + 1, p.h - 1);
            for (int k = 0; k < 3; ++k) {
                auto at = [&](int xx, int yy) {
                    return double(p.data[(size_t(yy) * size_t(p.w) + size_t(xx)) * 3 + size_t(k)]);
                };
                const double v = (1 - ay) * ((1 - ax) * at(ix, iy) + ax * at(ix1, iy)) +
                                 ay * ((1 - ax) * at(ix, iy1) + ax * at(ix1, iy1));
                rgb[i * 3 + size_t(k)] = uint8_t(std::clamp(v + 0.5, 0.0, 255.0));
            }
        }
}

// Every .png / .jpg file directly in each directory, as RGB (sorted: the training is
// reproducible). Throws naming the directory when one is missing or holds no image.
std::vector<data::Image> load_photos(const std::vector<std::string>& dirs) {
    std::vector<data::Image> out;
    for (const std::string& d : dirs) {
        G2L_CHECK(fs::is_directory(d), "augment.backgrounds: '", d, "' is not a directory");
        std::vector<std::string> files;
        for (const auto& e : fs::directory_iterator(d)) {
            std::string ext = e.path().extension().string();
            for (char& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
            if (e.is_regular_file() && (ext == ".png" || ext == ".jpg" || ext == ".jpeg"))
                files.push_back(e.path().string());
        }
        G2L_CHECK(!files.empty(), "augment.backgrounds: '", d, "' holds no .png or .jpg image");
        std::sort(files.begin(), files.end());
        for (const std::string& f : files) {
            out.push_back(data::load_rgb_image(f));
            G2L_CHECK(out.back().w >= 16 && out.back().h >= 16, "augment.backgrounds: '", f,
                      "' is too small (", out.back().w, " x ", out.back().h, ")");
        }
    }
    return out;
}

// Vertex colours for a distractor mesh without any: a base colour (half the time a grey or
// white, else a saturated one) with a linear gradient along a random axis and per-vertex noise,
// so a distractor looks like a painted or printed object, not a flat silhouette.
void paint_distractor(geom::Mesh& m, Rng& rng) {
    double base[3];
    if (rng.uniform() < 0.5) {
        const double g = rng.uniform(90, 250);
        for (double& b : base) b = g + rng.uniform(-10, 10);
    } else {
        for (double& b : base) b = rng.uniform(0, 255);
    }
    Eigen::Vector3d axis(rng.normal(), rng.normal(), rng.normal());
    axis.normalize();
    double lo = 1e30, hi = -1e30;
    for (int i = 0; i < m.vertices.rows(); ++i) {
        const double t = m.vertices.row(i).cast<double>().dot(axis.transpose());
        lo = std::min(lo, t), hi = std::max(hi, t);
    }
    const double amp = rng.uniform(0, 60);
    m.colors.resize(m.vertices.rows(), 3);
    for (int i = 0; i < m.vertices.rows(); ++i) {
        const double t = (m.vertices.row(i).cast<double>().dot(axis.transpose()) - lo) /
                         std::max(1e-9, hi - lo);
        for (int k = 0; k < 3; ++k)
            m.colors(i, k) = uint8_t(std::clamp(base[k] + amp * (t - 0.5) + rng.uniform(-8, 8), 0.0, 255.0));
    }
}

constexpr int kDistractorId = 1000000;  // the largest obj_id a models_info.json may hold

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
    prepare_run_dir(run_dir, !opt.resume_dir.empty(), opt.force);

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
        const std::string path = (fs::path(run_dir) / "last.g2l").string();
        const Checkpoint ck = load_checkpoint(path);
        const json meta = parse_json_strict(ck.meta_json, path + " (metadata)");
        G2L_CHECK(meta.value("format", "") == kCheckpointFormat, "'", path,
                  "' is not a detector training checkpoint");
        step = meta.at("step").get<int64_t>();
        seconds_before = meta.value("seconds", 0.0);
        std::map<std::string, Tensor> sd;
        for (const auto& [name, t] : ck.tensors)
            if (name.rfind("model.", 0) == 0) sd[name.substr(6)] = t;
        net.load_state_dict(sd, true);
        adam.load_state(ck.tensors, step);
        G2L_CHECK(step < cfg.steps, "--resume '", run_dir, "': the run already finished its ",
                  cfg.steps, " steps");
    } else {
        if (!cfg.init.empty()) {  // fine-tuning: the weights of an export, a fresh optimiser
            const nn::LoadedDetector from = nn::load_detector(cfg.init);
            G2L_CHECK(from.object_ids == cfg.object_ids && from.net->config().width == cfg.width &&
                          from.input() == cfg.input,
                      "model.init '", cfg.init, "': its objects / width / input differ from the "
                      "config's (data.object_ids, model.width, data.input)");
            net.load_state_dict(from.net->state_dict(), true);
        }
        std::ofstream c(fs::path(run_dir) / "config.json");
        c << detector_config_to_json(cfg);
        G2L_CHECK(c.good(), "cannot write '", (fs::path(run_dir) / "config.json").string(), "'");
        std::ofstream t(fs::path(run_dir) / "steps.jsonl", std::ios::trunc);
        G2L_CHECK(t.good(), "cannot write the steps log in '", run_dir, "'");
    }
    std::ofstream log(fs::path(run_dir) / "steps.jsonl", std::ios::app);
    const auto save = [&](const std::string& name, double seconds_total) {
        std::vector<std::pair<std::string, Tensor>> ts;
        for (const auto& [n, t] : net.state_dict()) ts.emplace_back("model." + n, t);
        for (auto& p : adam.state_tensors()) ts.push_back(p);
        const json meta{{"format", kCheckpointFormat}, {"step", step},
                        {"seconds", seconds_total}, {"config", json::parse(detector_config_to_json(cfg))}};
        save_checkpoint((fs::path(run_dir) / name).string(), ts, meta.dump());
        nn::save_detector((fs::path(run_dir) / "detector.g2l").string(), net, cfg.object_ids,
                      cfg.downscale);
    };

    // One generator per batch producer; frame index = step * batch + b (resumable exactly).
    data::SceneGenerator gen(scene, sm);
    const int hw = W / nn::Detector::kStride, hh = H / nn::Detector::kStride;
    auto make_batch = [&](int64_t s) {
        std::vector<DetSample> batch(size_t(cfg.batch));
        data::RenderedFrame fr;
        for (int b = 0; b < cfg.batch; ++b) {
            gen.render_frame(s * cfg.batch + b, fr, 1);
            DetSample& d = batch[size_t(b)];
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
        nn::LoadedDetector ld;
        ld.downscale = cfg.downscale;
        ld.object_ids = cfg.object_ids;  // the input kind travels in dc
        // Evaluate a copy in eval mode (the training net keeps its mode and state).
        ld.net = std::make_unique<nn::Detector>(dc);
        ld.net->load_state_dict(net.state_dict(), true);
        ld.net->eval();
        sum.val = evaluate_detector(ld, *val, 0.1, 0.3f, cfg.val_max_frames, false);
        sum.evaluated = true;
        if (opt.progress)
            std::printf("validation at step %lld on %s/%s:\n%s", (long long)step,
                        cfg.val_root.c_str(), cfg.val_split.c_str(),
                        detector_eval_table(sum.val).c_str());
        log << json{{"step", step}, {"val_mean_recall", sum.val.mean_recall},
                    {"val_mean_precision", sum.val.mean_precision},
                    {"val_mean_peak_rate", sum.val.mean_peak_rate}}
                   .dump()
            << "\n";
        log.flush();
    };
    bool previewed = !opt.resume_dir.empty();
    while (step < cfg.steps) {
        std::vector<DetSample> batch = next.get();
        if (!previewed) {  // what the detector trains on, with its target boxes
            previewed = true;
            for (int b = 0; b < std::min(cfg.batch, 4); ++b) {
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
                data::save_png((fs::path(run_dir) / cat("preview_", b, ".png")).string(), im);
            }
        }
        if (step + 1 < cfg.steps) next = std::async(std::launch::async, make_batch, step + 1);
        const int C = nn::detector_input_channels(cfg.input);
        Tensor x = Tensor::empty({cfg.batch, C, H, W});
        std::vector<DetTargets> targets;
        for (int b = 0; b < cfg.batch; ++b) {
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
        const nn::DetOut out = net.forward(x);
        Tensor loss = detector_loss(out, targets, cfg.w_heat, cfg.w_size, cfg.w_offset, &lh, &ls, &lo);
        const double lv = loss.item<double>();
        G2L_CHECK(std::isfinite(lv), "detector training: non-finite loss at step ", step + 1);
        loss.backward();
        adam.step();
        ++step;
        loss_acc += lv, lh_acc += lh, ls_acc += ls, lo_acc += lo, ++acc_n;
        sum.final_loss = lv;
        const double secs = std::chrono::duration<double>(Clock::now() - t0).count();
        if (step % cfg.log_every == 0 || step == cfg.steps) {
            const json rec{{"step", step},
                           {"loss", loss_acc / acc_n},
                           {"heat", lh_acc / acc_n},
                           {"size", ls_acc / acc_n},
                           {"offset", lo_acc / acc_n},
                           {"images_per_s", double((step - start_step) * cfg.batch) / std::max(1e-9, secs)},
                           {"minutes", elapsed_min()}};
            log << rec.dump() << "\n";
            log.flush();
            G2L_CHECK(log.good(), "cannot write '", run_dir, "/steps.jsonl' (disk full?)");
            if (opt.progress)
                std::printf("step %lld/%lld  loss %.4f (heat %.4f size %.4f offset %.4f)  %.1f img/s  %.1f min\n",
                            (long long)step, (long long)cfg.steps, loss_acc / acc_n, lh_acc / acc_n,
                            ls_acc / acc_n, lo_acc / acc_n,
                            double((step - start_step) * cfg.batch) / std::max(1e-9, secs),
                            elapsed_min());
            std::fflush(stdout);
            loss_acc = lh_acc = ls_acc = lo_acc = 0;
            acc_n = 0;
        }
        const bool stop_flag = opt.stop_flag && opt.stop_flag->load();
        const bool max_hit = opt.max_steps > 0 && step >= opt.max_steps;
        const bool time_hit = cfg.time_limit_min > 0 && elapsed_min() >= cfg.time_limit_min;
        if (step % cfg.checkpoint_every == 0 || step == cfg.steps || stop_flag || max_hit ||
            time_hit) {
            save("last.g2l",
                 seconds_before + std::chrono::duration<double>(Clock::now() - t0).count());
        }
        if (cfg.val_every > 0 && step % cfg.val_every == 0 && step < cfg.steps) run_val();
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
