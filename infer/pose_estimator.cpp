// SPDX-License-Identifier: MIT
// g2l::PoseEstimator: the frame pipeline (infer/frame_pipeline.h: crop → networks → refinement,
// the code g2l_eval runs too) and the detector, behind a header of plain types.
#include "g2l/pose_estimator.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>

#include "core/error.h"
#include "core/threads.h"
#include "geometry/mesh_io.h"
#include "geometry/model_info.h"
#include "infer/frame_pipeline.h"
#include "infer/tracker.h"
#include "nn/models/detector.h"
#include "nn/models/g2l_io.h"

#ifndef G2L_VERSION_STRING
#define G2L_VERSION_STRING "0.0.0"
#endif

namespace g2l {

const char* version() { return G2L_VERSION_STRING; }

const char* to_string(PoseStatus s) {
    switch (s) {
        case PoseStatus::ok: return "ok";
        case PoseStatus::unknown_object: return "unknown object";
        case PoseStatus::box_outside_image: return "box outside image";
        case PoseStatus::no_depth: return "no depth";
        case PoseStatus::too_few_points: return "too few points";
        case PoseStatus::too_few_object_points: return "too few object points";
        case PoseStatus::rejected_low_score: return "low score";
        case PoseStatus::rejected_duplicate: return "duplicate";
        case PoseStatus::rejected_overlap: return "overlap";
        case PoseStatus::rejected_implausible_distance: return "implausible distance";
    }
    return "unknown status";
}

struct PoseEstimator::Impl {
    std::string path;
    nn::LoadedModel model;
    EstimatorOptions options;
    std::unique_ptr<infer::FramePipeline> pipeline;  // crop → networks → refinement
    std::unique_ptr<nn::LoadedDetector> detector;    // EstimatorOptions::detector
    std::mutex mutex;
    // Per-frame buffers, reused between frames.
    std::vector<float> depth_mm;  // the frame's depth in mm
    std::vector<infer::PoseRequest> requests;
    std::vector<infer::PoseOutcome> outcomes;
    std::vector<infer::Hypothesis> hyps;
    // Under the mutex: the threads, the frame's depth in mm and its intrinsics.
    const float* begin_frame(const FrameView& f, geom::Intrinsics* K);
    // detect() under the mutex.
    std::vector<ObjectBox> detect(const FrameView& f);
    // A frame's detections as the hypotheses road's candidates.
    std::vector<infer::Candidate> detections(const std::vector<ObjectBox>& boxes);
    // The road's hypotheses as the public poses (keep_rejected: the rejected ones too).
    std::vector<ObjectPose> to_public(const std::vector<infer::Hypothesis>& hs) const;
};

PoseEstimator::PoseEstimator(const std::string& model_path, const EstimatorOptions& options)
    : impl_(std::make_unique<Impl>()) {
    Impl& m = *impl_;
    m.path = model_path;
    m.options = options;
    try {
        options.check();
    } catch (const std::exception& e) {
        throw Error(std::string("PoseEstimator: ") + e.what());
    }
    if (options.refine == Refinement::automatic)  // turns with meshes, none without
        m.options.refine = options.meshes.empty() ? Refinement::none : Refinement::turns;
    G2L_CHECK(m.options.refine == Refinement::none || !options.meshes.empty(),
              "PoseEstimator: refine = ", to_string(m.options.refine),
              " needs EstimatorOptions::meshes (the folder of the objects' obj_NNNNNN.ply meshes)");
    m.model = nn::load_model(model_path);
    if (!options.detector.empty())
        m.detector = std::make_unique<nn::LoadedDetector>(nn::load_detector(options.detector));
    std::map<int, geom::ModelInfo> infos;  // EstimatorOptions::models_info
    if (!options.models_info.empty()) {
        infos = geom::load_models_info_json(options.models_info);
        for (const auto& [id, cls] : m.model.class_of) {
            (void)cls;
            if (!m.model.objects.count(id) && infos.count(id))
                m.model.objects[id] = {infos.at(id).diameter, infos.at(id).symmetric};
        }
    }
    for (const auto& [id, cls] : m.model.class_of) {
        (void)cls;
        G2L_CHECK(m.model.objects.count(id), "PoseEstimator: '", model_path,
                  "' does not store the diameter of object ", id,
                  " (a file written before 2026-12-02): give the dataset's BOP models_info.json "
                  "(g2l_infer --models-info; in the library EstimatorOptions::models_info), or "
                  "re-export it with g2l_train --export");
    }
    m.pipeline = std::make_unique<infer::FramePipeline>(infer::PipelineModel::of(m.model), m.options);
    if (!options.meshes.empty()) {
        // The meshes of the model's objects found in the folder: the refinement and the
        // verification use them (an object without one keeps the networks' pose unverified:
        // ObjectPose::refined and verified tell). Their box and diameter: the models_info.json
        // entry when one is given, else measured on the mesh.
        std::error_code ec;
        G2L_CHECK(std::filesystem::is_directory(options.meshes, ec),
                  "PoseEstimator: EstimatorOptions::meshes '", options.meshes, "' is not a folder");
        int found = 0;
        for (const auto& [id, cls] : m.model.class_of) {
            (void)cls;
            char name[32];
            std::snprintf(name, sizeof name, "/obj_%06d.ply", id);
            const std::string file = options.meshes + name;
            if (!std::filesystem::exists(file, ec)) continue;
            const geom::Mesh mesh = geom::load_mesh(file);
            const geom::ModelInfo* declared = infos.count(id) ? &infos.at(id) : nullptr;
            const geom::ModelInfo measured =
                geom::check_mesh_units(mesh, declared, "'" + options.models_info + "'");
            // The model's stored diameter (its crops' radius) must describe this mesh too.
            const double stored = m.model.objects.at(id).diameter;
            G2L_CHECK(std::abs(stored / measured.diameter - 1) <= 0.05, "PoseEstimator: mesh '",
                      file, "' measures ", measured.diameter, " mm across but the model '",
                      model_path, "' was trained on object ", id, " with diameter ", stored,
                      " mm: the meshes folder holds another object, or a mesh in other units");
            m.pipeline->add_mesh(id, mesh, declared ? *declared : measured);
            ++found;
        }
        G2L_CHECK(found > 0, "PoseEstimator: EstimatorOptions::meshes '", options.meshes,
                  "' has no obj_NNNNNN.ply mesh of the model's objects");
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
    const int64_t n = int64_t(buf.size());
    float* out = buf.data();
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < n; ++i) out[i] = float(double(f.depth_u16[i]) * f.depth_scale);
    return buf.data();
}

}  // namespace

namespace {

// One pipeline outcome as the public type (score and check are set by the caller).
ObjectPose to_public(const infer::PoseOutcome& o) {
    ObjectPose p;
    p.obj_id = o.obj_id;
    switch (o.status) {
        case infer::PoseStatus::ok: p.status = PoseStatus::ok; break;
        case infer::PoseStatus::unknown_object: p.status = PoseStatus::unknown_object; break;
        case infer::PoseStatus::box_outside_image: p.status = PoseStatus::box_outside_image; break;
        case infer::PoseStatus::no_depth: p.status = PoseStatus::no_depth; break;
        case infer::PoseStatus::too_few_points: p.status = PoseStatus::too_few_points; break;
        case infer::PoseStatus::too_few_object_points:
            p.status = PoseStatus::too_few_object_points;
            break;
    }
    p.num_crop_points = o.num_crop_points;
    p.num_object_points = o.num_object_points;
    p.bbox = {{o.box.x, o.box.y, o.box.w, o.box.h}};
    p.timings.crop_ms = o.ms_crop;
    p.timings.segmentation_ms = o.ms_seg;
    p.timings.translation_ms = o.ms_t;
    p.timings.rotation_ms = o.ms_rot;
    p.timings.refine_ms = o.ms_refine;
    p.timings.total_ms = o.ms_crop + o.ms_seg + o.ms_t + o.ms_rot + o.ms_refine;
    p.refined = o.refined;
    p.fit_mm = o.fit_mm;
    p.alt_fit_mm = o.alt_fit_mm;
    if (o.ok()) {
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) p.R[size_t(r * 3 + c)] = o.pose.R(r, c);
            p.t[size_t(r)] = o.pose.t[r];
        }
    }
    return p;
}

void set_check(const geom::Verification& v, double score, ObjectPose* p) {
    p->verified = true;
    p->score = score;
    p->check.explained = v.explained;
    p->check.violation = v.violation;
    p->check.occlusion = v.occlusion;
    p->check.seg_agree = v.seg_agree;
    if (!v.box.empty()) p->check.bbox = {{v.box.x, v.box.y, v.box.w, v.box.h}};
}

}  // namespace

const float* PoseEstimator::Impl::begin_frame(const FrameView& f, geom::Intrinsics* K) {
    if (options.threads > 0) set_num_threads(options.threads);
    K->fx = f.K.fx, K->fy = f.K.fy, K->cx = f.K.cx, K->cy = f.K.cy;
    K->width = f.width, K->height = f.height;
    return depth_in_mm(f, depth_mm);
}

std::vector<ObjectPose> PoseEstimator::estimate(const FrameView& f,
                                                const std::vector<ObjectBox>& boxes) {
    check_frame(f, "PoseEstimator::estimate");
    Impl& m = *impl_;
    std::lock_guard<std::mutex> lock(m.mutex);
    geom::Intrinsics K;
    const float* depth = m.begin_frame(f, &K);
    m.requests.resize(boxes.size());
    for (size_t i = 0; i < boxes.size(); ++i) {
        const ObjectBox& b = boxes[i];
        infer::PoseRequest& r = m.requests[i];
        r = infer::PoseRequest{};
        r.obj_id = b.obj_id;
        r.box = {b.x, b.y, b.w, b.h};
        r.peak_x = b.peak_x, r.peak_y = b.peak_y;
    }
    // Each refined pose is verified against the depth inside the pipeline, its box's
    // refinement and verification running alongside the other boxes'.
    const infer::HypothesisTuning& tune = m.pipeline->tuning();
    m.pipeline->run(depth, K, m.requests, &m.outcomes, &tune.verify);
    std::vector<ObjectPose> out(boxes.size());
    for (size_t i = 0; i < boxes.size(); ++i) {
        const infer::PoseOutcome& o = m.outcomes[i];
        ObjectPose& p = out[i];
        p = to_public(o);
        p.obj_id = boxes[i].obj_id;
        p.score = p.detection_score = boxes[i].score;
        if (o.ok() && !infer::implausible_distance(o.pose, o.box, K, m.model.objects.at(o.obj_id).diameter)
                           .empty()) {
            p.status = PoseStatus::rejected_implausible_distance;
            continue;
        }
        if (!o.ok() || !o.check) continue;
        set_check(*o.check, tune.score_model.probability(*o.check, boxes[i].score, false), &p);
        if (p.score < m.options.min_pose_score) p.status = PoseStatus::rejected_low_score;
    }
    return out;
}

std::vector<ObjectBox> PoseEstimator::detect(const FrameView& f) {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    return impl_->detect(f);
}

std::vector<ObjectBox> PoseEstimator::Impl::detect(const FrameView& f) {
    Impl& m = *this;
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
    if (m.options.threads > 0) set_num_threads(m.options.threads);
    const auto dets = nn::detect(*m.detector->net, m.detector->downscale, df,
                                 float(m.options.min_detection_score), m.options.max_instances,
                                 m.options.detector_mirror);
    std::vector<ObjectBox> out;  // best first, at most max_instances per class
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

std::vector<infer::Candidate> PoseEstimator::Impl::detections(const std::vector<ObjectBox>& boxes) {
    std::vector<infer::Candidate> dets;
    for (const ObjectBox& b : boxes) {
        infer::Candidate c;
        c.obj_id = c.det_obj_id = b.obj_id;
        c.box = {b.x, b.y, b.w, b.h};
        c.peak_x = b.peak_x, c.peak_y = b.peak_y;
        c.det_score = b.score;
        dets.push_back(c);
    }
    return pipeline->candidates(dets);
}

std::vector<ObjectPose> PoseEstimator::Impl::to_public(const std::vector<infer::Hypothesis>& hs) const {
    std::vector<ObjectPose> out;
    for (const infer::Hypothesis& h : hs) {
        if (!h.accepted() && !options.keep_rejected) continue;
        if (h.verdict == infer::Verdict::covered) continue;  // never posed: no pose to return
        ObjectPose p = g2l::to_public(h.outcome);
        p.score = p.detection_score = h.cand.det_score;
        if (h.verified) set_check(h.check, h.score, &p);
        p.rival = h.rival;
        p.tracked = h.tracked;
        p.track_id = h.track_id;
        switch (h.verdict) {
            case infer::Verdict::low_score: p.status = PoseStatus::rejected_low_score; break;
            case infer::Verdict::duplicate: p.status = PoseStatus::rejected_duplicate; break;
            case infer::Verdict::overlap: p.status = PoseStatus::rejected_overlap; break;
            case infer::Verdict::implausible:
                p.status = PoseStatus::rejected_implausible_distance;
                break;
            case infer::Verdict::accepted:
            case infer::Verdict::no_pose:
            case infer::Verdict::covered: break;
        }
        out.push_back(p);
    }
    return out;
}

std::vector<ObjectPose> PoseEstimator::estimate(const FrameView& f) {
    Impl& m = *impl_;
    std::lock_guard<std::mutex> lock(m.mutex);
    const std::vector<ObjectBox> boxes = m.detect(f);  // checks the frame for the detector
    check_frame(f, "PoseEstimator::estimate");
    geom::Intrinsics K;
    const float* depth = m.begin_frame(f, &K);
    m.pipeline->hypotheses(depth, K, m.detections(boxes), &m.hyps);
    return m.to_public(m.hyps);
}

struct PoseTracker::Impl {
    PoseEstimator* est = nullptr;
    std::unique_ptr<infer::Tracker> tracker;
};

PoseTracker::PoseTracker(PoseEstimator& est, const TrackerOptions& options)
    : impl_(std::make_unique<Impl>()) {
    PoseEstimator::Impl& m = *est.impl_;
    G2L_CHECK(m.detector, "PoseTracker: the estimator has no detector (EstimatorOptions::"
                          "detector): tracking finds the objects with it");
    G2L_CHECK(m.options.refine != Refinement::none,
              "PoseTracker: the estimator does not refine (EstimatorOptions::meshes and a "
              "refinement other than none): tracking follows the poses against the meshes");
    infer::TrackerOptions to;
    to.redetect_every = options.redetect_every;
    to.redetect_weak_every = options.redetect_weak_every;
    to.min_track_score = options.min_track_score;
    to.lost_score = options.lost_score;
    G2L_CHECK(std::isfinite(to.min_track_score), "PoseTracker: min_track_score must be in "
                                                  "[0, 1], got ", to.min_track_score);
    G2L_CHECK(std::isfinite(to.lost_score), "PoseTracker: lost_score must be in [0, "
                                             "min_track_score], got ", to.lost_score);
    impl_->est = &est;
    impl_->tracker = std::make_unique<infer::Tracker>(*m.pipeline, to);
}

PoseTracker::~PoseTracker() = default;
PoseTracker::PoseTracker(PoseTracker&&) noexcept = default;
PoseTracker& PoseTracker::operator=(PoseTracker&&) noexcept = default;

std::vector<ObjectPose> PoseTracker::track(const FrameView& f) {
    PoseEstimator& est = *impl_->est;
    check_frame(f, "PoseTracker::track");
    PoseEstimator::Impl& m = *est.impl_;
    std::lock_guard<std::mutex> lock(m.mutex);
    geom::Intrinsics K;
    const float* depth = m.begin_frame(f, &K);
    // The detector only when the tracker asks.
    auto detect = [&]() { return m.detections(m.detect(f)); };
    impl_->tracker->step(depth, K, detect, &m.hyps);
    return m.to_public(m.hyps);
}

void PoseTracker::reset() { impl_->tracker->reset(); }

bool PoseTracker::detected() const { return impl_->tracker->detected(); }

}  // namespace g2l
