// SPDX-License-Identifier: MIT
#include "infer/frame_pipeline.h"

#include <chrono>
#include <cmath>

#include "core/error.h"
#include "geometry/camera.h"
#include "geometry/crop.h"

namespace g2l::infer {

namespace {
using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
}  // namespace

Refine parse_refine(const std::string& text, const std::string& what) {
    if (text == "none") return Refine::none;
    if (text == "icp") return Refine::icp;
    if (text == "turns") return Refine::turns;
    G2L_CHECK(false, what, " must be none, icp or turns, got '", text, "'");
    return Refine::none;
}

const char* to_string(Refine r) {
    switch (r) {
        case Refine::none: return "none";
        case Refine::icp: return "icp";
        case Refine::turns: return "turns";
    }
    return "unknown refinement";
}

CropKind parse_crop(const std::string& text, const std::string& what) {
    if (text == "sphere") return CropKind::sphere;
    if (text == "frustum") return CropKind::frustum;
    if (text == "slab") return CropKind::slab;
    G2L_CHECK(false, what, " must be sphere, frustum or slab, got '", text, "'");
    return CropKind::sphere;
}

const char* to_string(CropKind c) {
    switch (c) {
        case CropKind::sphere: return "sphere";
        case CropKind::frustum: return "frustum";
        case CropKind::slab: return "slab";
    }
    return "unknown crop";
}

const char* to_string(PoseStatus s) {
    switch (s) {
        case PoseStatus::ok: return "ok";
        case PoseStatus::unknown_object: return "unknown object";
        case PoseStatus::box_outside_image: return "box outside image";
        case PoseStatus::no_depth: return "no depth";
        case PoseStatus::too_few_points: return "too few crop points";
        case PoseStatus::too_few_object_points: return "too few object points";
    }
    return "unknown status";
}

PreparedMesh PreparedMesh::from_mesh(const geom::Mesh& mesh, const geom::ModelInfo& info,
                                     bool for_refine) {
    G2L_CHECK(mesh.vertices.rows() > 0, "PreparedMesh: mesh '", mesh.path, "' has no vertices");
    G2L_CHECK(std::isfinite(info.diameter) && info.diameter > 0, "PreparedMesh: mesh '", mesh.path,
              "': diameter must be > 0, got ", info.diameter);
    PreparedMesh p;
    p.tree = std::make_unique<geom::ModelKdTree>(geom::ModelKdTree::from_mesh(mesh));
    p.info = info;
    if (for_refine) {
        p.normals = p.tree->normals();
        p.grid = geom::ClosestPointGrid::for_refine(*p.tree, info);
    }
    return p;
}

PipelineModel PipelineModel::of(const nn::LoadedModel& m) {
    PipelineModel p;
    p.net = m.net.get();
    p.class_of = m.class_of;
    p.keypoints = m.keypoints;
    for (const auto& [id, o] : m.objects) p.diameter[id] = o.diameter;
    p.crop = m.crop;
    p.radius_scale = m.radius_scale;
    p.points = m.points;
    p.seg_points = m.seg_points;
    return p;
}

FramePipeline::FramePipeline(PipelineModel model, const PipelineOptions& opt)
    : model_(std::move(model)), opt_(opt) {
    G2L_CHECK(model_.net, "FramePipeline: the model has no network");
    G2L_CHECK(opt.crop_points >= -1, "FramePipeline: crop_points must be >= -1, got ",
              opt.crop_points);
    G2L_CHECK(opt.object_points == -1 || opt.object_points >= 1,
              "FramePipeline: object_points must be -1 or >= 1, got ", opt.object_points);
    G2L_CHECK(std::isfinite(model_.radius_scale) && model_.radius_scale > 0,
              "FramePipeline: radius_scale must be > 0, got ", model_.radius_scale);
    crop_kind_ = parse_crop(model_.crop, "FramePipeline: the model's crop");
    if (opt_.crop_points < 0) opt_.crop_points = model_.points;
    if (opt_.object_points < 0) opt_.object_points = model_.seg_points;
    for (const auto& [id, cls] : model_.class_of)
        G2L_CHECK(cls >= 0 && size_t(cls) < model_.keypoints.size(), "FramePipeline: object ", id,
                  " has class index ", cls, " but the model has ", model_.keypoints.size(),
                  " keypoint sets");
    engine_ = std::make_unique<nn::PoseEngine>(*model_.net);
}

FramePipeline::~FramePipeline() = default;
FramePipeline::FramePipeline(FramePipeline&&) noexcept = default;

void FramePipeline::add_mesh(int obj_id, const geom::Mesh& mesh, const geom::ModelInfo& info) {
    meshes_[obj_id] = PreparedMesh::from_mesh(mesh, info, opt_.refine != Refine::none);
}

const PreparedMesh* FramePipeline::mesh(int obj_id) const {
    const auto it = meshes_.find(obj_id);
    return it == meshes_.end() ? nullptr : &it->second;
}

void FramePipeline::crop(const float* depth, const geom::Intrinsics& K,
                         const std::vector<PoseRequest>& requests, std::vector<PoseOutcome>* out) {
    G2L_CHECK(depth != nullptr && K.width > 0 && K.height > 0,
              "FramePipeline::crop: need a depth image and its size, got ", K.width, " x ",
              K.height);
    const int W = K.width, H = K.height;
    out->resize(requests.size());
    for (size_t i = 0; i < requests.size(); ++i) {
        const PoseRequest& r = requests[i];
        const auto t0 = Clock::now();
        PoseOutcome& p = (*out)[i];
        p = PoseOutcome{};
        p.obj_id = r.obj_id;
        if (!model_.class_of.count(r.obj_id)) {
            p.status = PoseStatus::unknown_object;
            continue;
        }
        p.box = geom::clip_box(r.box, W, H);
        if (p.box.empty()) {
            p.status = PoseStatus::box_outside_image;
            continue;
        }
        if (crop_kind_ == CropKind::frustum) {
            // every point of the box: no centre needed
            p.crop = geom::depth_to_points(depth, W, H, K, p.box);
        } else {  // the centre first: a box without depth there is not back-projected at all
            Eigen::Vector3d c;
            const bool have = r.centre ? (c = *r.centre, true)
                              : r.peak_x >= 0 && r.peak_y >= 0
                                  ? geom::peak_centre(depth, W, H, K, p.box, r.peak_x, r.peak_y, &c)
                                  : geom::box_centre(depth, W, H, K, p.box, &c);
            if (!have) {
                p.status = PoseStatus::no_depth;
                p.ms_crop = ms_since(t0);
                continue;
            }
            const auto d = model_.diameter.find(r.obj_id);
            G2L_CHECK(d != model_.diameter.end() && d->second > 0, "FramePipeline: no diameter "
                      "for object ", r.obj_id, " (the sphere crop needs it)");
            p.crop = geom::crop_points(to_string(crop_kind_),
                                       geom::depth_to_points(depth, W, H, K, p.box), c,
                                       model_.radius_scale * d->second);
        }
        p.num_crop_points = int(p.crop.rows());
        p.ms_crop = ms_since(t0);
    }
}

void FramePipeline::estimate(const float* depth, const geom::Intrinsics& K,
                             std::vector<PoseOutcome>* io, const std::vector<Oracle>* oracles) {
    std::vector<PoseOutcome>& outs = *io;
    G2L_CHECK(!oracles || oracles->size() == outs.size(), "FramePipeline::estimate: ",
              oracles ? oracles->size() : 0, " oracles for ", outs.size(), " outcomes");
    // One box at a time, one engine call each: a box's pose then never depends on which other
    // boxes the frame has (a batched call packs them into the same GEMMs, whose tiling follows
    // the total point count and changes the last bits, and the refinement's choice among its
    // starts can amplify those). Batching saved ~10% of a 4-object frame; reproducible poses
    // are worth more.
    for (size_t i = 0; i < outs.size(); ++i) {
        PoseOutcome& p = outs[i];
        if (p.status != PoseStatus::ok) continue;
        // 1. The networks.
        nn::PoseQuery q;
        q.crop = &p.crop;
        q.class_index = model_.class_of.at(p.obj_id);
        q.keypoints = &model_.keypoints[size_t(q.class_index)];
        q.object_rows = &p.object_rows;
        if (oracles) {
            q.object_mask = (*oracles)[i].object_mask;
            q.translation = (*oracles)[i].translation;
        }
        single_.assign(1, q);
        engine_->estimate(single_, opt_.object_points, opt_.crop_points, &single_out_);
        const nn::PoseEstimate& e = single_out_[0];
        p.ms_seg = e.ms_seg;
        p.ms_t = e.ms_t;
        p.ms_rot = e.ms_rot;
        p.num_object_points = e.num_object_points;
        if (!e.ok) {
            p.status = e.status == "too few crop points" ? PoseStatus::too_few_points
                                                         : PoseStatus::too_few_object_points;
            continue;
        }
        p.pose = e.pose;
        // 2. Depth refinement against the mesh (geometry/refine.h).
        if (opt_.refine == Refine::none) continue;
        const auto t0 = Clock::now();
        const auto me = meshes_.find(p.obj_id);
        geom::Points obs(int64_t(p.object_rows.size()), 3);
        for (size_t i = 0; i < p.object_rows.size(); ++i)
            obs.row(int64_t(i)) = p.crop.row(p.object_rows[i]);
        if (obs.rows() >= 3 && me != meshes_.end()) {
            const PreparedMesh& m = me->second;
            geom::RefineOptions ro;
            ro.hypotheses = opt_.refine == Refine::turns;
            const geom::DepthImage di{depth, K};
            const geom::RefineResult rr =
                geom::refine_pose(*m.tree, m.info, obs, p.pose, ro, &di, &m.normals, &m.grid);
            p.pose = rr.pose;
            p.fit_mm = rr.fit_mm;
            p.refine_hypothesis = rr.hypothesis;
            p.refine_cluster = rr.cluster;
            p.refined = true;
        }
        p.ms_refine = ms_since(t0);
    }
}

void FramePipeline::run(const float* depth, const geom::Intrinsics& K,
                        const std::vector<PoseRequest>& requests, std::vector<PoseOutcome>* out) {
    crop(depth, K, requests, out);
    estimate(depth, K, out);
}

}  // namespace g2l::infer
