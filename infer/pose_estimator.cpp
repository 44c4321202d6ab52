// SPDX-License-Identifier: MIT
// g2l::PoseEstimator: the crop step (geometry/crop.h, shared with training samples and
// g2l_eval) in front of the compiled networks (nn::PoseEngine), behind a header of plain types.
#include "g2l/pose_estimator.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>

#include "core/error.h"
#include "core/threads.h"
#include "geometry/camera.h"
#include "geometry/crop.h"
#include "geometry/labels.h"
#include "geometry/mesh_io.h"
#include "geometry/model_info.h"
#include "geometry/refine.h"
#include "nn/models/detector.h"
#include "nn/models/g2l_io.h"
#include "nn/models/g2l_engine.h"
#include "nn/models/g2l_pose.h"

#ifndef G2L_VERSION_STRING
#define G2L_VERSION_STRING "0.0.0"
#endif

namespace g2l {

namespace {
using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
}  // namespace

const char* version() { return G2L_VERSION_STRING; }

const char* to_string(PoseStatus s) {
    switch (s) {
        case PoseStatus::ok: return "ok";
        case PoseStatus::unknown_object: return "unknown object";
        case PoseStatus::box_outside_image: return "box outside image";
        case PoseStatus::no_depth: return "no depth";
        case PoseStatus::too_few_points: return "too few points";
        case PoseStatus::too_few_object_points: return "too few object points";
    }
    return "unknown status";
}

const char* to_string(Refinement r) {
    switch (r) {
        case Refinement::none: return "none";
        case Refinement::icp: return "icp";
        case Refinement::turns: return "turns";
        case Refinement::automatic: return "automatic";
    }
    return "unknown refinement";
}

struct PoseEstimator::Impl {
    std::string path;
    nn::LoadedModel model;
    EstimatorOptions options;
    int crop_points = 0, object_points = 1;
    std::unique_ptr<nn::PoseEngine> engine;  // the compiled networks (fast path)
    std::unique_ptr<nn::LoadedDetector> detector;  // EstimatorOptions::detector
    std::mutex mutex;
    // Per-frame buffers, reused between frames.
    std::vector<float> depth_mm;  // the frame's depth in mm
    std::vector<geom::Points> crops;
    std::vector<nn::PoseQuery> queries;
    std::vector<size_t> query_box;  // box index of each query
    std::vector<nn::PoseEstimate> results;
    std::vector<std::vector<int>> object_rows;  // per query: the crop rows taken as object
    // EstimatorOptions::refine: each object's mesh surface (model frame) and box.
    struct Mesh {
        std::unique_ptr<geom::ModelKdTree> tree;
        geom::Points normals;  // of the tree points (point-to-plane ICP)
        geom::ClosestPointGrid grid;  // nearest tree point per cell (the ICP's fast lookups)
        geom::ModelInfo info;
    };
    std::map<int, Mesh> meshes;
};

PoseEstimator::PoseEstimator(const std::string& model_path, const EstimatorOptions& options)
    : impl_(std::make_unique<Impl>()) {
    Impl& m = *impl_;
    m.path = model_path;
    m.options = options;
    G2L_CHECK(options.threads >= 0, "PoseEstimator: threads must be >= 0, got ", options.threads);
    G2L_CHECK(options.crop_points >= -1, "PoseEstimator: crop_points must be >= -1, got ",
              options.crop_points);
    G2L_CHECK(options.object_points == -1 || options.object_points >= 1,
              "PoseEstimator: object_points must be -1 or >= 1, got ", options.object_points);
    G2L_CHECK(std::isfinite(options.min_detection_score) && options.min_detection_score >= 0 &&
                  options.min_detection_score <= 1,
              "PoseEstimator: min_detection_score must be in [0, 1], got ",
              options.min_detection_score);
    G2L_CHECK(options.refine == Refinement::none || options.refine == Refinement::icp ||
                  options.refine == Refinement::turns || options.refine == Refinement::automatic,
              "PoseEstimator: refine must be none, icp, turns or automatic, got ",
              int(options.refine));
    if (options.refine == Refinement::automatic)  // turns with meshes, none without
        m.options.refine = options.meshes.empty() ? Refinement::none : Refinement::turns;
    G2L_CHECK(m.options.refine == Refinement::none || !options.meshes.empty(),
              "PoseEstimator: refine = ", to_string(m.options.refine),
              " needs EstimatorOptions::meshes (the folder of the objects' obj_NNNNNN.ply meshes)");
    m.model = nn::load_model(model_path);
    if (!options.detector.empty())
        m.detector = std::make_unique<nn::LoadedDetector>(nn::load_detector(options.detector));
    m.engine = std::make_unique<nn::PoseEngine>(*m.model.net);
    m.crop_points = options.crop_points >= 0 ? options.crop_points : m.model.points;
    m.object_points = options.object_points >= 1 ? options.object_points : m.model.seg_points;
    if (!options.models_info.empty()) {
        const auto infos = geom::load_models_info_json(options.models_info);
        for (const auto& [id, cls] : m.model.class_of) {
            (void)cls;
            if (!m.model.objects.count(id) && infos.count(id))
                m.model.objects[id] = {infos.at(id).diameter, infos.at(id).symmetric};
        }
    }
    if (m.options.refine != Refinement::none) {
        // The meshes of the model's objects found in the folder (an object without one keeps
        // the networks' pose: ObjectPose::refined tells).
        std::error_code ec;
        G2L_CHECK(std::filesystem::is_directory(options.meshes, ec),
                  "PoseEstimator: EstimatorOptions::meshes '", options.meshes, "' is not a folder");
        for (const auto& [id, cls] : m.model.class_of) {
            (void)cls;
            char name[32];
            std::snprintf(name, sizeof name, "/obj_%06d.ply", id);
            const std::string file = options.meshes + name;
            if (!std::filesystem::exists(file, ec)) continue;
            const geom::Mesh mesh = geom::load_mesh(file);
            Impl::Mesh& me = m.meshes[id];
            me.tree = std::make_unique<geom::ModelKdTree>(geom::ModelKdTree::from_mesh(mesh));
            me.normals = me.tree->normals();
            me.info = geom::compute_model_info(mesh.vertices);
            me.grid = geom::ClosestPointGrid::for_refine(*me.tree, me.info);
        }
        G2L_CHECK(!m.meshes.empty(), "PoseEstimator: EstimatorOptions::meshes '", options.meshes,
                  "' has no obj_NNNNNN.ply mesh of the model's objects");
    }
    for (const auto& [id, cls] : m.model.class_of) {
        (void)cls;
        G2L_CHECK(m.model.objects.count(id), "PoseEstimator: '", model_path,
                  "' does not store the diameter of object ", id,
                  " (a file written before 2026-12-02): give a BOP models_info.json in "
                  "EstimatorOptions::models_info, or re-export it with g2l_train --export");
    }
}

PoseEstimator::~PoseEstimator() = default;
PoseEstimator::PoseEstimator(PoseEstimator&&) noexcept = default;
PoseEstimator& PoseEstimator::operator=(PoseEstimator&&) noexcept = default;

std::vector<int> PoseEstimator::object_ids() const {
    std::vector<int> ids;
    for (const auto& [id, cls] : impl_->model.class_of) ids.push_back(id), (void)cls;
    return ids;
}

double PoseEstimator::diameter(int obj_id) const {
    const auto it = impl_->model.objects.find(obj_id);
    G2L_CHECK(it != impl_->model.objects.end() && impl_->model.class_of.count(obj_id),
              "PoseEstimator::diameter: object ", obj_id, " is not in '", impl_->path, "'");
    return it->second.diameter;
}

std::vector<double> PoseEstimator::keypoints(int obj_id) const {
    const auto it = impl_->model.class_of.find(obj_id);
    G2L_CHECK(it != impl_->model.class_of.end(), "PoseEstimator::keypoints: object ", obj_id,
              " is not in '", impl_->path, "'");
    std::vector<double> out;
    for (const auto& p : impl_->model.keypoints[size_t(it->second)])
        out.insert(out.end(), {double(p.x()), double(p.y()), double(p.z())});
    return out;
}

namespace {

// The checks every frame with depth passes (throws naming `who` and the field).
void check_frame(const FrameView& f, const char* who) {
    G2L_CHECK(f.width > 0 && f.height > 0, who, ": frame size must be positive, got ", f.width,
              " x ", f.height);
    G2L_CHECK((f.depth_u16 != nullptr) != (f.depth_mm != nullptr), who,
              ": set exactly one of FrameView::depth_u16 and depth_mm (",
              f.depth_u16 ? "both" : "neither", " given)");
    G2L_CHECK(!f.depth_u16 || (std::isfinite(f.depth_scale) && f.depth_scale > 0), who,
              ": depth_scale must be finite and > 0, got ", f.depth_scale);
    G2L_CHECK(std::isfinite(f.K.fx) && std::isfinite(f.K.fy) && f.K.fx > 0 && f.K.fy > 0, who,
              ": focal lengths must be finite and > 0, got fx=", f.K.fx, " fy=", f.K.fy);
    G2L_CHECK(std::isfinite(f.K.cx) && std::isfinite(f.K.cy), who,
              ": principal point must be finite, got cx=", f.K.cx, " cy=", f.K.cy);
}

// The frame's depth in mm: depth_mm itself, or depth_u16 * depth_scale converted into `buf`.
const float* depth_in_mm(const FrameView& f, std::vector<float>& buf) {
    if (f.depth_mm) return f.depth_mm;
    buf.resize(size_t(f.width) * size_t(f.height));
    for (size_t i = 0; i < buf.size(); ++i) buf[i] = float(double(f.depth_u16[i]) * f.depth_scale);
    return buf.data();
}

}  // namespace

std::vector<ObjectPose> PoseEstimator::estimate(const FrameView& f,
                                                const std::vector<ObjectBox>& boxes) {
    check_frame(f, "PoseEstimator::estimate");
    Impl& m = *impl_;
    std::lock_guard<std::mutex> lock(m.mutex);
    if (m.options.threads > 0) set_num_threads(m.options.threads);
    const float* depth = depth_in_mm(f, m.depth_mm);
    geom::Intrinsics K;
    K.fx = f.K.fx, K.fy = f.K.fy, K.cx = f.K.cx, K.cy = f.K.cy;
    K.width = f.width, K.height = f.height;

    // 1. The crop of every box (geometry/crop.h, the step training samples use too).
    std::vector<ObjectPose> out(boxes.size());
    if (m.crops.size() < boxes.size()) m.crops.resize(boxes.size());
    m.queries.clear();
    m.query_box.clear();
    for (size_t i = 0; i < boxes.size(); ++i) {
        const ObjectBox& b = boxes[i];
        const auto t0 = Clock::now();
        ObjectPose& p = out[i];
        p.obj_id = b.obj_id;
        p.score = b.score;
        const auto cls = m.model.class_of.find(b.obj_id);
        if (cls == m.model.class_of.end()) {
            p.status = PoseStatus::unknown_object;
            continue;
        }
        const geom::Box2i box = geom::clip_box({b.x, b.y, b.w, b.h}, f.width, f.height);
        if (box.empty()) {
            p.status = PoseStatus::box_outside_image;
            continue;
        }
        Eigen::Vector3d centre;
        const bool have_centre =
            b.peak_x >= 0 && b.peak_y >= 0
                ? geom::peak_centre(depth, f.width, f.height, K, box, b.peak_x, b.peak_y, &centre)
                : geom::box_centre(depth, f.width, f.height, K, box, &centre);
        if (!have_centre) {
            p.status = PoseStatus::no_depth;
            p.timings.crop_ms = p.timings.total_ms = ms_since(t0);
            continue;
        }
        const geom::Points pts = geom::depth_to_points(depth, f.width, f.height, K, box);
        const double radius = m.model.radius_scale * m.model.objects.at(b.obj_id).diameter;
        geom::Points& crop = m.crops[i];
        crop = geom::crop_points(m.model.crop, pts, centre, radius);
        p.num_crop_points = int(crop.rows());
        p.timings.crop_ms = ms_since(t0);
        m.queries.push_back({&crop, cls->second, &m.model.keypoints[size_t(cls->second)]});
        m.query_box.push_back(i);
    }
    // 2. The networks for all boxes of the frame at once (nn::PoseEngine).
    const bool refine = m.options.refine != Refinement::none;
    if (refine) {
        m.object_rows.resize(m.queries.size());
        for (size_t q = 0; q < m.queries.size(); ++q) m.queries[q].object_rows = &m.object_rows[q];
    }
    if (!m.queries.empty()) m.engine->estimate(m.queries, m.object_points, m.crop_points, &m.results);
    for (size_t q = 0; q < m.queries.size(); ++q) {
        const nn::PoseEstimate& est = m.results[q];
        ObjectPose& p = out[m.query_box[q]];
        p.timings.segmentation_ms = est.ms_seg;
        p.timings.translation_ms = est.ms_t;
        p.timings.rotation_ms = est.ms_rot;
        p.num_object_points = est.num_object_points;
        if (!est.ok) {
            p.status = est.status == "too few crop points" ? PoseStatus::too_few_points
                                                           : PoseStatus::too_few_object_points;
        } else {
            nn::PoseEstimate& e = m.results[q];
            if (refine) {
                // 3. Depth refinement against the mesh (geometry/refine.h).
                const auto t0 = Clock::now();
                const std::vector<int>& rows = m.object_rows[q];
                const geom::Points& crop = *m.queries[q].crop;
                geom::Points obs(int64_t(rows.size()), 3);
                for (size_t i = 0; i < rows.size(); ++i) obs.row(int64_t(i)) = crop.row(rows[i]);
                const auto mesh_it = m.meshes.find(p.obj_id);
                if (obs.rows() >= 3 && mesh_it != m.meshes.end()) {
                    const Impl::Mesh& me = mesh_it->second;
                    geom::RefineOptions ro;
                    ro.hypotheses = m.options.refine == Refinement::turns;
                    const geom::DepthImage di{depth, K};
                    const geom::RefineResult rr =
                        geom::refine_pose(*me.tree, me.info, obs, e.pose, ro, &di, &me.normals,
                                          &me.grid);
                    e.pose = rr.pose;
                    p.fit_mm = rr.fit_mm;
                    p.refined = true;
                }
                p.timings.refine_ms = ms_since(t0);
            }
            for (int r = 0; r < 3; ++r) {
                for (int c = 0; c < 3; ++c) p.R[size_t(r * 3 + c)] = est.pose.R(r, c);
                p.t[size_t(r)] = est.pose.t[r];
            }
        }
        p.timings.total_ms =
            p.timings.crop_ms + est.ms_seg + est.ms_t + est.ms_rot + p.timings.refine_ms;
    }
    return out;
}

std::vector<ObjectBox> PoseEstimator::detect(const FrameView& f) {
    Impl& m = *impl_;
    G2L_CHECK(m.detector, "PoseEstimator::detect: no detector (set EstimatorOptions::detector to "
                          "a detector export)");
    const nn::DetectorInput input = m.detector->input();
    G2L_CHECK(f.width > 0 && f.height > 0, "PoseEstimator::detect: frame size must be positive, "
                                           "got ", f.width, " x ", f.height);
    G2L_CHECK(!nn::uses_rgb(input) || f.rgb != nullptr, "PoseEstimator::detect: the ",
              nn::to_string(input), " detector '", m.options.detector,
              "' needs the frame's RGB image (FrameView::rgb)");
    nn::DetectorFrame df;
    df.width = f.width, df.height = f.height, df.rgb = f.rgb;
    std::vector<float> depth;
    if (nn::uses_depth(input)) {
        G2L_CHECK(f.depth_u16 || f.depth_mm, "PoseEstimator::detect: the ", nn::to_string(input),
                  " detector '", m.options.detector, "' needs the frame's depth "
                  "(FrameView::depth_u16 or depth_mm)");
        check_frame(f, "PoseEstimator::detect");
        df.depth_mm = depth_in_mm(f, depth);
        df.fx = f.K.fx, df.fy = f.K.fy, df.cx = f.K.cx, df.cy = f.K.cy;
    }
    std::lock_guard<std::mutex> lock(m.mutex);
    if (m.options.threads > 0) set_num_threads(m.options.threads);
    const auto dets = nn::detect(*m.detector->net, m.detector->downscale, df,
                                 float(m.options.min_detection_score), 1,
                                 m.options.detector_mirror);
    std::vector<ObjectBox> out;  // detect() returns them best first, one per class
    for (const nn::Detection& d : dets) {
        ObjectBox b;
        b.obj_id = m.detector->object_ids[size_t(d.cls)];
        b.x = int(std::lround(d.x)), b.y = int(std::lround(d.y));
        b.w = int(std::lround(d.w)), b.h = int(std::lround(d.h));
        b.score = d.score;
        b.peak_x = d.peak_x, b.peak_y = d.peak_y;
        out.push_back(b);
    }
    return out;
}

std::string PoseEstimator::detector_input() const {
    return impl_->detector ? nn::to_string(impl_->detector->input()) : "";
}

std::vector<ObjectPose> PoseEstimator::estimate(const FrameView& frame) {
    return estimate(frame, detect(frame));
}

}  // namespace g2l
