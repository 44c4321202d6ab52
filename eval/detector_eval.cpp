// SPDX-License-Identifier: MIT
#include "eval/detector_eval.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>

#include "core/error.h"
#include "core/threads.h"
#include "data/render.h"
#include "geometry/crop.h"

namespace g2l::eval {

using Clock = std::chrono::steady_clock;

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
                                             float min_score, bool mirror, int max_per_class) {
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
        const auto dets = detect_frame(det, ds, fr, min_score, max_per_class, mirror, &w, &h, &ms);
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

}  // namespace g2l::eval
