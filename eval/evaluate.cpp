// SPDX-License-Identifier: MIT
#include "eval/evaluate.h"

#include <algorithm>
#include <chrono>
#include <optional>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <tuple>
#include <Eigen/Cholesky>
#include <nlohmann/json.hpp>

#include "core/autograd.h"
#include "geometry/camera.h"
#include "geometry/crop.h"
#include "geometry/labels.h"
#include "geometry/metrics.h"
#include "geometry/refine.h"
#include "geometry/symmetry.h"
#include "infer/frame_pipeline.h"
#include "nn/models/g2l_pose.h"

namespace g2l::eval {

namespace {

using Clock = std::chrono::steady_clock;

// The sphere centre with the GT visible mask (the earlier protocol, kept for comparison): the
// mask pixel nearest to the mask centroid that has depth, back-projected.
bool sphere_centre(const data::Dataset& ds, const data::Frame& f, const data::Instance& inst,
                   const std::vector<float>& depth, int w, int h, const geom::Box2i& box,
                   Eigen::Vector3d* centre) {
    std::vector<uint8_t> mask;
    if (!inst.mask_visib_path.empty()) {
        const data::Image m = ds.load_mask(f, inst);
        mask.assign(m.data.begin(), m.data.end());
    }
    double cu = 0, cv = 0, n = 0;
    for (int v = box.y; v < box.y + box.h; ++v)
        for (int u = box.x; u < box.x + box.w; ++u) {
            if (!mask.empty() && !mask[size_t(v) * w + u]) continue;
            cu += u; cv += v; n += 1;
        }
    if (n == 0) { cu = box.x + box.w / 2.0; cv = box.y + box.h / 2.0; }
    else { cu /= n; cv /= n; }
    double best = std::numeric_limits<double>::infinity();
    int bu = -1, bv = -1;
    for (int v = box.y; v < box.y + box.h; ++v)
        for (int u = box.x; u < box.x + box.w; ++u) {
            const float z = depth[size_t(v) * w + u];
            if (!(z > 0) || (!mask.empty() && !mask[size_t(v) * w + u])) continue;
            const double d = (u - cu) * (u - cu) + (v - cv) * (v - cv);
            if (d < best) { best = d; bu = u; bv = v; }
        }
    (void)h;
    if (bu < 0) return false;
    const double z = depth[size_t(bv) * w + bu];
    *centre = {(bu - f.K.cx) * z / f.K.fx, (bv - f.K.cy) * z / f.K.fy, z};
    return true;
}


struct Acc {
    std::vector<double> adds_m, add_m;
    int count = 0, misses = 0, correct = 0, found = 0, correct_adds = 0, correct_sym = 0;
    double rot = 0, trans = 0;
    std::vector<double> rot_sym, trans_all;
    double seg_iou = 0;
    int seg_n = 0;
    int det_n = 0, det_hits = 0;  // instances with a det_iou, of those IoU >= 0.5
    int det_raw_hits = 0;         // of those, the detection's own box at IoU >= 0.5
    int reported = 0, reported_right = 0, box_hits = 0, false_pos = 0;  // the hypotheses road
};


// Model points and geometric symmetries of one object (computed once per evaluation).
struct ObjGeom {
    geom::Points pts;  // model vertices for ADD / ADD-S (stride subsample)
    std::vector<geom::SymmetryTransform> syms;
};

// IoU of `taken` with the flagged rows of `gt`, both restricted to the rows in `seen` (each
// counted once); -1 when neither has a point there.
double rows_iou(const std::vector<int>& seen, const std::vector<int>& taken,
                const std::vector<uint8_t>& gt) {
    std::vector<uint8_t> in_seen(gt.size(), 0), in_taken(gt.size(), 0);
    for (int r : seen) in_seen[size_t(r)] = 1;
    for (int r : taken) in_taken[size_t(r)] = 1;
    int64_t inter = 0, uni = 0;
    for (size_t r = 0; r < gt.size(); ++r) {
        if (!in_seen[r]) continue;
        inter += in_taken[r] && gt[r];
        uni += in_taken[r] || gt[r];
    }
    return uni ? double(inter) / double(uni) : -1.0;
}

// The errors of an estimate against its instance's ground truth.
void set_errors(const geom::Pose& est, const geom::Pose& gt, const ObjGeom& og,
                InstanceResult* r) {
    r->add_mm = geom::add(est, gt, og.pts);
    r->adds_mm = geom::adds(est, gt, og.pts);
    // Modulo the geometric symmetries S: the GT pose composed with S is as right.
    r->addsym_mm = geom::add_sym(est, gt, og.pts, og.syms);
    r->rot_sym_deg = geom::rotation_error_sym_deg(est.R, gt.R, og.syms);
    r->rot_deg = geom::rotation_error_deg(est.R, gt.R);
    r->trans_mm = geom::translation_error(est.t, gt.t);
}

// What a reported pose (an accepted hypothesis) tells of itself, matched or not.
void set_reported(const infer::Hypothesis& hy, InstanceResult* r) {
    r->score = hy.score;
    r->est = hy.outcome.pose;
    r->found = true;
    r->reported = true;
    r->det_score = hy.cand.det_score;
    if (hy.verified) {
        r->verify_score = hy.check.score;
        r->explained = hy.check.explained;
        r->violation = hy.check.violation;
        r->seg_agree = hy.check.seg_agree;
    }
}

}  // namespace

namespace {

// A frame's given poses (EvalOptions::poses) as accepted hypotheses, best score first; each
// box the projection of its posed model box, clipped to the image.
void given_poses(const std::vector<const data::PoseRow*>& rows, const data::Dataset& ds,
                 const geom::Intrinsics& K, std::vector<infer::Hypothesis>* out) {
    out->clear();
    for (const data::PoseRow* r : rows) {
        infer::Hypothesis h;
        h.cand.obj_id = h.cand.det_obj_id = r->obj_id;
        h.cand.det_score = h.score = r->score;
        h.verdict = infer::Verdict::accepted;
        infer::PoseOutcome& o = h.outcome;
        o.obj_id = r->obj_id;
        o.status = infer::PoseStatus::ok;
        for (int a = 0; a < 3; ++a) {
            for (int b = 0; b < 3; ++b) o.pose.R(a, b) = r->R[size_t(a * 3 + b)];
            o.pose.t[a] = r->t[size_t(a)];
        }
        const geom::ModelInfo& mi = ds.model(r->obj_id).info;
        double u0 = 1e30, v0 = 1e30, u1 = -1e30, v1 = -1e30;
        for (int k = 0; k < 8; ++k) {
            const Eigen::Vector3d c = mi.min + Eigen::Vector3d(k & 1 ? mi.size.x() : 0,
                                                               k & 2 ? mi.size.y() : 0,
                                                               k & 4 ? mi.size.z() : 0);
            const Eigen::Vector3d p = o.pose.R * c + o.pose.t;
            if (p.z() <= 1.0) continue;
            const double u = K.fx * p.x() / p.z() + K.cx, v = K.fy * p.y() / p.z() + K.cy;
            u0 = std::min(u0, u), u1 = std::max(u1, u), v0 = std::min(v0, v), v1 = std::max(v1, v);
        }
        if (u1 >= u0 && v1 >= v0 && u0 > -1e6 && v0 > -1e6 && u1 < 1e6 && v1 < 1e6)
            o.box = geom::clip_box({int(std::floor(u0)), int(std::floor(v0)),
                                    int(std::ceil(u1 - std::floor(u0))),
                                    int(std::ceil(v1 - std::floor(v0)))},
                                   K.width, K.height);
        out->push_back(std::move(h));
    }
    std::stable_sort(out->begin(), out->end(), [](const infer::Hypothesis& a,
                                                  const infer::Hypothesis& b) {
        return a.score > b.score;
    });
}

}  // namespace

EvalReport evaluate_gt_boxes(const infer::PipelineModel& model, const data::Dataset& ds,
                             const EvalOptions& opt) {
    return evaluate_instances(model, ds, opt, nullptr);
}

namespace {

// One evaluation's state: the frame pipeline the inference library runs
// (infer/frame_pipeline.h: the same crop, networks and refinement; evaluation adds only the
// ground truth and the oracle inputs), each object's metric geometry, the results so far and
// the stage times. Two roads: gt_frame (a pose per ground-truth box) and matched_frame (the
// library's hypotheses, or given poses, matched to the ground truth as BOP does).
class Evaluation {
public:
    Evaluation(const infer::PipelineModel& model, const data::Dataset& ds, const EvalOptions& opt,
               std::vector<HypothesisRecord>* hyps_out)
        : ds_(ds), class_of_(model.class_of), opt_(opt), hyps_out_(hyps_out),
          pipe_(with_dataset_diameters(model, ds), opt.pipeline) {
        infer::HypothesisTuning tune = pipe_.tuning();
        tune.arbitrate = opt.arbitrate;
        pipe_.set_tuning(tune);
        if (opt.detections) {
            for (size_t i = 0; i < opt.detections->size(); ++i) {
                const data::Detection& d = (*opt.detections)[i];
                G2L_CHECK(d.scene_id >= 0 && d.image_id >= 0, "evaluate: detection ", i,
                          " (object ", d.obj_id, ") has no scene_id / image_id: evaluation needs both");
                infer::Candidate c;
                c.obj_id = c.det_obj_id = d.obj_id;
                c.box = {int(std::lround(d.x)), int(std::lround(d.y)), int(std::lround(d.w)),
                         int(std::lround(d.h))};
                c.peak_x = d.peak_x, c.peak_y = d.peak_y;
                c.det_score = d.score;
                frame_dets_[{d.scene_id, d.image_id}].push_back(c);
            }
        }
        if (opt.poses)
            for (const data::PoseRow& r : *opt.poses)
                if (class_of_.count(r.obj_id)) frame_poses_[{r.scene_id, r.image_id}].push_back(&r);
        if (hyps_out_) hyps_out_->clear();
        // The hypotheses road may pose any object of the model the dataset has a mesh of (a
        // peak is also tried as the objects of a like shape).
        if (matched_road())
            for (const auto& [id, om] : ds.models())
                if (class_of_.count(id)) prepare(id), (void)om;
    }

    bool matched_road() const { return opt_.detections || opt_.poses; }
    bool full() const { return opt_.max_instances > 0 && instances_ >= opt_.max_instances; }

    void gt_frame(const data::Frame& f);
    void matched_frame(const data::Frame& f);

    EvalReport report(std::vector<InstanceResult>* instances_out) const {
        EvalReport rep = aggregate(results_, meta_);
        rep.refine = pipe_.refine();
        rep.oracle = opt_.oracle_seg ? (opt_.oracle_t ? "seg+t" : "seg") : opt_.oracle_t ? "t" : "none";
        if (instances_out) *instances_out = results_;
        if (instances_ > 0) {
            const double n = instances_;
            rep.ms_crop = t_crop_ / n, rep.ms_seg = t_seg_ / n, rep.ms_t = t_t_ / n;
            rep.ms_rot = t_rot_ / n, rep.ms_refine = t_refine_ / n;
        }
        return rep;
    }

private:
    // The dataset's diameters: the sphere radius and the metrics' 10 % both use them.
    static infer::PipelineModel with_dataset_diameters(infer::PipelineModel pm,
                                                       const data::Dataset& ds) {
        pm.diameter.clear();
        for (const auto& [id, om] : ds.models())
            if (pm.class_of.count(id)) pm.diameter[id] = om.info.diameter;
        return pm;
    }

    // Once per object: its mesh in the pipeline, its metric points and symmetries.
    void prepare(int obj_id) {
        if (model_geom_.count(obj_id)) return;
        const data::ObjectModel& om = ds_.model(obj_id);
        const geom::Mesh& mesh = ds_.load_model_mesh(obj_id);
        pipe_.add_mesh(obj_id, mesh, om.info);
        const int64_t nv = mesh.vertices.rows();
        const int64_t keep =
            opt_.max_model_points > 0 ? std::min<int64_t>(nv, opt_.max_model_points) : nv;
        ObjGeom g;
        g.pts.resize(keep, 3);
        for (int64_t i = 0; i < keep; ++i) g.pts.row(i) = mesh.vertices.row(i * nv / keep);
        const infer::PreparedMesh& pm = *pipe_.mesh(obj_id);  // its symmetries when refining
        g.syms = pm.syms.empty() ? geom::geometric_symmetries(*pm.tree, om.info) : pm.syms;
        meta_[obj_id] = {om.name, om.info.diameter, om.info.symmetric,
                         int(std::max<size_t>(1, g.syms.size()))};
        model_geom_[obj_id] = std::move(g);
    }
    void add_times(const infer::PoseOutcome& o) {
        t_crop_ += o.ms_crop, t_seg_ += o.ms_seg, t_t_ += o.ms_t, t_rot_ += o.ms_rot;
        t_refine_ += o.ms_refine;
    }
    // The frame's depth (mm) and its camera with the image size.
    std::vector<float> frame_depth(const data::Frame& f, geom::Intrinsics* K) const {
        int w = 0, h = 0;
        std::vector<float> depth = ds_.load_depth_mm(f, &w, &h);
        *K = f.K;
        K->width = w, K->height = h;
        return depth;
    }

    // The matched road's matching of one frame (hypotheses best first, accepted ones first).
    struct Matching {
        std::vector<int> est_of;      // GT -> hypothesis index (-1: none)
        std::vector<int> gt_of;       // hypothesis -> GT index (-1: none)
        std::vector<uint8_t> right;   // hypothesis right at ADD-S < 0.1 d
        std::vector<uint8_t> box_hit; // 1: its box found a counted GT box, 2: an uncounted one
    };
    Matching match(const std::vector<const data::Instance*>& gts,
                   const std::vector<uint8_t>& counted) const;
    double adds_of(const infer::Hypothesis& hy, const data::Instance& gt) const {
        return geom::adds(hy.outcome.pose, gt.pose, model_geom_.at(gt.obj_id).pts);
    }
    void record_hypotheses(const data::Frame& f, const std::vector<const data::Instance*>& gts,
                           const std::vector<uint8_t>& counted, const Matching& m);

    const data::Dataset& ds_;
    const std::map<int, int>& class_of_;
    const EvalOptions& opt_;
    std::vector<HypothesisRecord>* hyps_out_;
    infer::FramePipeline pipe_;
    std::map<std::pair<int, int>, std::vector<infer::Candidate>> frame_dets_;
    std::map<std::pair<int, int>, std::vector<const data::PoseRow*>> frame_poses_;
    std::vector<InstanceResult> results_;
    std::map<int, ObjectMeta> meta_;
    std::map<int, ObjGeom> model_geom_;
    int64_t instances_ = 0;  // counted GT instances
    double t_crop_ = 0, t_seg_ = 0, t_t_ = 0, t_rot_ = 0, t_refine_ = 0;
    std::vector<infer::Hypothesis> hyps_;
};

Evaluation::Matching Evaluation::match(const std::vector<const data::Instance*>& gts,
                                       const std::vector<uint8_t>& counted) const {
    const size_t ng = gts.size(), nh = hyps_.size();
    Matching m{std::vector<int>(ng, -1), std::vector<int>(nh, -1), std::vector<uint8_t>(nh, 0),
               std::vector<uint8_t>(nh, 0)};
    // BOP matching: accepted poses by score; each takes the GT instance of its object it is
    // right for (ADD-S < 0.1 d) with the smallest error.
    for (size_t hi = 0; hi < nh && hyps_[hi].accepted(); ++hi) {
        int best = -1;
        double best_err = 0;
        for (size_t g = 0; g < ng; ++g) {
            if (m.est_of[g] >= 0 || gts[g]->obj_id != hyps_[hi].cand.obj_id) continue;
            const double e = adds_of(hyps_[hi], *gts[g]);
            if (geom::correct_at(e, meta_.at(gts[g]->obj_id).diameter) && (best < 0 || e < best_err))
                best = int(g), best_err = e;
        }
        if (best >= 0) m.est_of[size_t(best)] = int(hi), m.gt_of[hi] = best, m.right[hi] = 1;
    }
    // Left-over instances take the nearest left-over pose of their object within a diameter
    // (a wrong pose, its errors reported).
    for (size_t hi = 0; hi < nh && hyps_[hi].accepted(); ++hi) {
        if (m.gt_of[hi] >= 0) continue;
        int best = -1;
        double best_d = 0;
        for (size_t g = 0; g < ng; ++g) {
            if (m.est_of[g] >= 0 || gts[g]->obj_id != hyps_[hi].cand.obj_id) continue;
            const double d = (hyps_[hi].outcome.pose.t - gts[g]->pose.t).norm();
            if (d < meta_.at(gts[g]->obj_id).diameter && (best < 0 || d < best_d))
                best = int(g), best_d = d;
        }
        if (best >= 0) m.est_of[size_t(best)] = int(hi), m.gt_of[hi] = best;
    }
    // Box hits (det_precision_50): each accepted pose's box against the visible GT boxes of
    // its object, one box each, by score.
    std::vector<uint8_t> box_taken(ng, 0);
    for (size_t hi = 0; hi < nh && hyps_[hi].accepted(); ++hi) {
        const geom::Box2i b = hyps_[hi].reported_box();
        int best = -1;
        double best_iou = 0.5;
        for (size_t g = 0; g < ng; ++g) {
            if (box_taken[g] || gts[g]->obj_id != hyps_[hi].cand.obj_id) continue;
            const geom::Box2i gb = gts[g]->box();
            const double iou = geom::box_iou(b.x, b.y, b.w, b.h, gb.x, gb.y, gb.w, gb.h);
            if (iou >= best_iou) best = int(g), best_iou = iou;
        }
        if (best >= 0) {
            box_taken[size_t(best)] = 1;
            // A box that only finds an uncounted instance is neither hit nor miss.
            m.box_hit[hi] = counted[size_t(best)] ? 1 : 2;
        }
    }
    return m;
}

void Evaluation::record_hypotheses(const data::Frame& f,
                                   const std::vector<const data::Instance*>& gts,
                                   const std::vector<uint8_t>& counted, const Matching& m) {
    for (size_t hi = 0; hi < hyps_.size(); ++hi) {
        const infer::Hypothesis& hy = hyps_[hi];
        if (hyps_out_) {
            HypothesisRecord rec;
            rec.scene = f.scene;
            rec.image_id = f.image_id;
            rec.obj_id = hy.cand.obj_id;
            rec.score = hy.score;
            rec.det_score = hy.cand.det_score;
            rec.verdict = infer::to_string(hy.verdict);
            rec.rival = hy.rival;
            rec.right = m.right[hi] && counted[size_t(m.gt_of[hi])];
            rec.box = hy.outcome.box;
            rec.posed = hy.outcome.ok();
            if (rec.posed) {
                rec.est = hy.outcome.pose;
                for (const data::Instance* g : gts)
                    rec.pose_right = rec.pose_right ||
                                     (g->obj_id == hy.cand.obj_id &&
                                      geom::correct_at(adds_of(hy, *g), meta_.at(hy.cand.obj_id).diameter));
            }
            rec.verified = hy.verified;
            if (hy.verified) {
                rec.features = infer::ScoreModel::features(hy.check, hy.cand.det_score,
                                                           hy.cand.det_obj_id != hy.cand.obj_id);
                rec.visible = hy.check.visible;
                rec.inliers = hy.check.inliers;
                rec.footprint_cells = int(hy.check.footprint.size());
            }
            hyps_out_->push_back(rec);
        }
        // An accepted pose matched to no instance is a false positive; one matched to an
        // uncounted instance (or whose box found only one) is left out.
        if (!hy.accepted() || m.gt_of[hi] >= 0 || m.box_hit[hi] == 2) continue;
        InstanceResult r;
        r.obj_id = hy.cand.obj_id;
        r.scene = f.scene;
        r.image_id = f.image_id;
        r.inst_index = -1;
        r.status = "false positive";
        set_reported(hy, &r);
        r.box = hy.reported_box();
        r.false_positive = true;
        r.box_hit = m.box_hit[hi] == 1;
        results_.push_back(r);
    }
}

void Evaluation::matched_frame(const data::Frame& f) {
    int scene_id = -1;
    try {
        scene_id = std::stoi(f.scene);
    } catch (const std::exception&) {
        G2L_CHECK(false, "evaluate: scene '", f.scene, "' is not a number (BOP scene ids are), so "
                  "detections cannot be matched to it");
    }
    // Every GT instance of a known object takes part in the matching; those below
    // min_visib_fract (or past max_instances) are not counted: an estimate matched to one is
    // neither right nor a false positive (BOP's rule).
    std::vector<const data::Instance*> gts;
    std::vector<uint8_t> counted;
    for (const data::Instance& inst : f.instances) {
        if (!class_of_.count(inst.obj_id)) continue;
        prepare(inst.obj_id);
        const bool c = inst.visible_enough(opt_.min_visib_fract) && !full();
        gts.push_back(&inst);
        counted.push_back(c);
        instances_ += c;
    }
    geom::Intrinsics K;
    const std::vector<float> depth = frame_depth(f, &K);
    const auto fd = frame_dets_.find({scene_id, f.image_id});
    const std::vector<infer::Candidate> cands =
        fd == frame_dets_.end() ? std::vector<infer::Candidate>{}
                                : pipe_.candidates(fd->second);
    if (opt_.poses)
        given_poses(frame_poses_[{scene_id, f.image_id}], ds_, K, &hyps_);
    else
        pipe_.hypotheses(depth.data(), K, cands, &hyps_);
    for (const infer::Hypothesis& hy : hyps_) add_times(hy.outcome);
    const Matching m = match(gts, counted);
    for (size_t g = 0; g < gts.size(); ++g) {
        if (!counted[g]) continue;
        const data::Instance& inst = *gts[g];
        InstanceResult r;
        r.obj_id = inst.obj_id;
        r.scene = f.scene;
        r.image_id = f.image_id;
        r.inst_index = int(&inst - f.instances.data());
        r.gt = inst.pose;
        r.det_iou = r.det_iou_detector = 0;
        r.box = geom::clip_box(inst.box(), K.width, K.height);
        if (m.est_of[g] < 0) {
            r.status = opt_.poses ? "no estimate" : cands.empty() ? "no detection" : "no pose";
            results_.push_back(r);
            continue;
        }
        const infer::Hypothesis& hy = hyps_[size_t(m.est_of[g])];
        const infer::PoseOutcome& o = hy.outcome;
        r.status = infer::to_string(o.status);
        r.box = hy.reported_box();
        const geom::Box2i gb = inst.box();
        r.det_iou = geom::box_iou(r.box.x, r.box.y, r.box.w, r.box.h, gb.x, gb.y, gb.w, gb.h);
        r.detector_box = o.box;
        r.det_iou_detector =
            geom::box_iou(o.box.x, o.box.y, o.box.w, o.box.h, gb.x, gb.y, gb.w, gb.h);
        set_reported(hy, &r);
        r.ms = o.ms_crop + o.ms_seg + o.ms_t + o.ms_rot + o.ms_refine;
        r.refine_hyp = o.refine_hypothesis;
        r.refine_cluster = o.refine_cluster;
        r.alt_fit_mm = o.alt_fit_mm;
        r.fit_mm = o.fit_mm;
        r.right = m.right[size_t(m.est_of[g])];
        r.box_hit = m.box_hit[size_t(m.est_of[g])] == 1;
        set_errors(o.pose, inst.pose, model_geom_.at(inst.obj_id), &r);
        results_.push_back(r);
    }
    record_hypotheses(f, gts, counted, m);
}

void Evaluation::gt_frame(const data::Frame& f) {
    std::vector<const data::Instance*> insts;  // this frame's evaluated instances
    for (const data::Instance& inst : f.instances) {
        if (!class_of_.count(inst.obj_id) || !inst.visible_enough(opt_.min_visib_fract)) continue;
        if (full()) break;
        insts.push_back(&inst);
        instances_++;
    }
    if (insts.empty()) return;
    geom::Intrinsics K;
    const std::vector<float> depth = frame_depth(f, &K);
    std::vector<InstanceResult> res(insts.size());
    std::vector<infer::PoseRequest> reqs;  // the boxes the pipeline poses
    std::vector<size_t> req_of;            // index in insts of each request
    for (size_t k = 0; k < insts.size(); ++k) {
        const data::Instance& inst = *insts[k];
        prepare(inst.obj_id);
        InstanceResult& r = res[k];
        r.obj_id = inst.obj_id;
        r.scene = f.scene;
        r.image_id = f.image_id;
        r.inst_index = int(&inst - f.instances.data());
        r.gt = inst.pose;
        infer::PoseRequest q;
        q.obj_id = inst.obj_id;
        q.box = inst.box();
        if (opt_.centre_from_mask && pipe_.model().crop != geom::CropKind::frustum) {
            Eigen::Vector3d c;
            const geom::Box2i box = geom::clip_box(q.box, K.width, K.height);
            r.box = box;
            if (box.empty()) {
                r.status = "box outside image";
                continue;
            }
            if (!sphere_centre(ds_, f, inst, depth, K.width, K.height, box, &c)) {
                r.status = "no depth";
                continue;
            }
            q.centre = c;
        }
        reqs.push_back(q);
        req_of.push_back(k);
    }
    std::vector<infer::PoseOutcome> outs;
    pipe_.crop(depth.data(), K, reqs, &outs);
    // The ground-truth object points of each crop (training's label rule; outside the timed
    // stages): the seg IoU, and the oracle inputs when asked for.
    std::vector<std::vector<uint8_t>> gt_obj(reqs.size());
    std::vector<Eigen::Vector3f> gt_t(reqs.size());
    std::vector<infer::Oracle> oracles(reqs.size());
    for (size_t i = 0; i < reqs.size(); ++i) {
        if (!outs[i].ok()) continue;
        const data::Instance& inst = *insts[req_of[i]];
        gt_obj[i] = pipe_.mesh(inst.obj_id)->tree->label_points(outs[i].crop, inst.pose,
                                                                float(opt_.label_threshold_mm));
        gt_t[i] = inst.pose.t.cast<float>();
        if (opt_.oracle_seg) oracles[i].object_mask = &gt_obj[i];
        if (opt_.oracle_t) oracles[i].translation = &gt_t[i];
    }
    pipe_.estimate(depth.data(), K, &outs, &oracles);
    for (size_t i = 0; i < reqs.size(); ++i) {
        const infer::PoseOutcome& o = outs[i];
        const data::Instance& inst = *insts[req_of[i]];
        InstanceResult& r = res[req_of[i]];
        r.box = o.box;
        r.status = infer::to_string(o.status);
        r.ms = o.ms_crop + o.ms_seg + o.ms_t + o.ms_rot + o.ms_refine;
        add_times(o);
        if (o.num_crop_points > 0 && !gt_obj[i].empty()) {
            const int n_seen = pipe_.options().crop_points > 0 ? pipe_.options().crop_points
                                                              : int(o.crop.rows());
            r.seg_iou = rows_iou(nn::even_sample(int(o.crop.rows()), n_seen), o.object_rows, gt_obj[i]);
        }
        if (!o.ok()) continue;
        if (o.refined) {
            geom::Points obs(int64_t(o.object_rows.size()), 3);
            for (size_t j = 0; j < o.object_rows.size(); ++j)
                obs.row(int64_t(j)) = o.crop.row(o.object_rows[j]);
            r.refine_hyp = o.refine_hypothesis;
            r.refine_cluster = o.refine_cluster;
            r.alt_fit_mm = o.alt_fit_mm;
            r.fit_mm = o.fit_mm;
            const geom::DepthImage di{depth.data(), K};
            r.gt_fit_mm = geom::pose_cost(*pipe_.mesh(inst.obj_id)->tree, pipe_.mesh(inst.obj_id)->info,
                                          obs, inst.pose, {}, &di);
        }
        r.est = o.pose;
        r.found = true;
        set_errors(o.pose, inst.pose, model_geom_[inst.obj_id], &r);
    }
    results_.insert(results_.end(), res.begin(), res.end());
}

}  // namespace

EvalReport evaluate_instances(const infer::PipelineModel& model, const data::Dataset& ds,
                              const EvalOptions& opt, std::vector<InstanceResult>* instances_out,
                              std::vector<HypothesisRecord>* hyps_out) {
    G2L_CHECK(model.net, "evaluate: the model has no network");
    nn::G2LNet& net = *model.net;
    const bool was_training = net.is_training();
    net.eval();
    autograd::NoGradGuard no_grad;
    EvalReport rep;
    {
        Evaluation ev(model, ds, opt, hyps_out);
        for (const data::Frame& f : ds.frames()) {
            if (ev.full()) break;
            if (ev.matched_road())
                ev.matched_frame(f);
            else
                ev.gt_frame(f);
        }
        rep = ev.report(instances_out);
    }
    net.train(was_training);
    return rep;
}

EvalReport aggregate(const std::vector<InstanceResult>& results,
                     const std::map<int, ObjectMeta>& meta) {
    std::map<int, Acc> acc;
    for (const InstanceResult& r : results) {
        const auto m = meta.find(r.obj_id);
        G2L_CHECK(m != meta.end(), "aggregate: no object meta for obj_id ", r.obj_id);
        G2L_CHECK(m->second.diameter > 0, "aggregate: object ", r.obj_id, " has diameter ",
                  m->second.diameter);
        Acc& a = acc[r.obj_id];
        if (r.reported) {
            a.reported++;
            a.reported_right += r.right;
            a.box_hits += r.box_hit;
        }
        if (r.false_positive) {  // no instance: only the precisions count it
            a.false_pos++;
            continue;
        }
        a.count++;
        if (r.seg_iou >= 0) {
            a.seg_iou += r.seg_iou;
            a.seg_n++;
        }
        if (r.det_iou >= 0) {
            a.det_n++;
            a.det_hits += !r.det_miss();
            a.det_raw_hits += r.det_iou_detector >= 0.5;
        }
        // No pose, or (a detection file or detector without the hypotheses road) a pose from
        // no true detection. A reported pose is judged by its pose: a loose box around a right
        // pose is the box's miss (det_recall_50), not the pose's.
        if (!r.found || (r.det_miss() && !r.reported)) {
            a.misses++;
            a.rot_sym.push_back(180.0);
            a.adds_m.push_back(std::numeric_limits<double>::infinity());
            a.add_m.push_back(std::numeric_limits<double>::infinity());
            continue;
        }
        const double d = m->second.diameter;
        a.correct_adds += geom::correct_at(r.adds_mm, d);
        a.correct_sym += geom::correct_at(r.addsym_mm, d);
        a.rot_sym.push_back(r.rot_sym_deg);
        a.trans_all.push_back(r.trans_mm);
        a.add_m.push_back(r.add_mm / 1000.0);
        a.adds_m.push_back(r.adds_mm / 1000.0);
        a.correct += geom::correct_at(m->second.symmetric ? r.adds_mm : r.add_mm, d);
        a.found++;
        a.rot += r.rot_deg;
        a.trans += r.trans_mm;
    }
    EvalReport rep;
    // The hypotheses road reports poses (precisions); GT boxes do not (-1).
    const bool any_reported =
        std::any_of(results.begin(), results.end(), [](const InstanceResult& r) {
            return r.false_positive || (r.reported || (r.det_iou >= 0 && !r.found));
        });
    rep.instances = int(std::count_if(results.begin(), results.end(),
                                      [](const InstanceResult& r) { return !r.false_positive; }));
    Acc all;
    for (auto& [id, a] : acc) {
        if (a.count == 0) {  // only false positives: no row (the average pools them)
            all.reported += a.reported;
            all.box_hits += a.box_hits;
            all.false_pos += a.false_pos;
            continue;
        }
        ObjectScores s;
        s.obj_id = id;
        s.name = meta.at(id).name;
        s.symmetric = meta.at(id).symmetric;
        s.count = a.count;
        s.misses = a.misses;
        s.acc_add_s_10 = a.count ? 100.0 * a.correct / a.count : 0;
        s.auc_adds = geom::vocap_auc(a.adds_m);
        s.auc_add = geom::vocap_auc(a.add_m);
        s.mean_rot_err_deg = a.found ? a.rot / a.found : 0;
        s.mean_trans_err_mm = a.found ? a.trans / a.found : 0;
        s.acc_adds_all_10 = a.count ? 100.0 * a.correct_adds / a.count : 0;
        s.acc_addsym_10 = a.count ? 100.0 * a.correct_sym / a.count : 0;
        s.rot_err_sym_deg_median = geom::median(a.rot_sym);
        s.median_trans_err_mm = geom::median(a.trans_all);
        s.num_symmetries = meta.at(id).num_symmetries;
        s.seg_iou = a.seg_n ? a.seg_iou / a.seg_n : -1;
        s.det_recall_50 = a.det_n ? 100.0 * a.det_hits / a.det_n : -1;
        s.detector_recall_50 = a.det_n ? 100.0 * a.det_raw_hits / a.det_n : -1;
        s.reported = a.reported;
        s.false_positives = a.false_pos;
        if (any_reported) {
            s.pose_precision = a.reported ? 100.0 * a.reported_right / a.reported : 0.0;
            s.det_precision_50 = a.reported ? 100.0 * a.box_hits / a.reported : 0.0;
        }
        rep.objects.push_back(s);
        all.adds_m.insert(all.adds_m.end(), a.adds_m.begin(), a.adds_m.end());
        all.add_m.insert(all.add_m.end(), a.add_m.begin(), a.add_m.end());
        all.count += a.count; all.misses += a.misses; all.found += a.found;
        all.rot += a.rot; all.trans += a.trans;
        all.det_n += a.det_n; all.det_hits += a.det_hits; all.det_raw_hits += a.det_raw_hits;
        all.reported += a.reported; all.reported_right += a.reported_right;
        all.box_hits += a.box_hits; all.false_pos += a.false_pos;
    }
    ObjectScores& avg = rep.average;
    avg.name = "average";
    avg.count = all.count;
    avg.misses = all.misses;
    int seg_objects = 0;  // objects with a seg IoU (-1: none measured)
    double seg_sum = 0;
    for (const auto& s : rep.objects) {
        if (s.seg_iou >= 0) {
            seg_sum += s.seg_iou;
            seg_objects++;
        }
        avg.acc_add_s_10 += s.acc_add_s_10 / double(rep.objects.size());
        avg.auc_adds += s.auc_adds / double(rep.objects.size());
        avg.auc_add += s.auc_add / double(rep.objects.size());
        avg.acc_adds_all_10 += s.acc_adds_all_10 / double(rep.objects.size());
        avg.acc_addsym_10 += s.acc_addsym_10 / double(rep.objects.size());
        avg.rot_err_sym_deg_median += s.rot_err_sym_deg_median / double(rep.objects.size());
        avg.median_trans_err_mm += s.median_trans_err_mm / double(rep.objects.size());
    }
    avg.seg_iou = seg_objects ? seg_sum / seg_objects : -1;
    avg.det_recall_50 = all.det_n ? 100.0 * all.det_hits / all.det_n : -1;
    avg.detector_recall_50 = all.det_n ? 100.0 * all.det_raw_hits / all.det_n : -1;
    avg.reported = all.reported;
    avg.false_positives = all.false_pos;
    if (any_reported) {  // pooled over every reported pose
        avg.pose_precision = all.reported ? 100.0 * all.reported_right / all.reported : 0.0;
        avg.det_precision_50 = all.reported ? 100.0 * all.box_hits / all.reported : 0.0;
    }
    avg.mean_rot_err_deg = all.found ? all.rot / all.found : 0;
    avg.mean_trans_err_mm = all.found ? all.trans / all.found : 0;
    return rep;
}

std::string report_markdown(const EvalReport& r) {
    std::string s;
    if (r.oracle != "none")
        s = "Oracle inputs (" + r.oracle + "): " +
            (r.oracle == "seg"  ? std::string("ground-truth object points")
             : r.oracle == "t" ? std::string("ground-truth translation")
                               : std::string("ground-truth object points and translation")) +
            " replace the network's.\n\n";
    // The table always says which stages its poses went through.
    s += std::string("Depth refinement (") + g2l::to_string(r.refine) + "): " +
         (r.refine == Refinement::none ? std::string("none, the networks' poses as they are")
          : r.refine == Refinement::icp
              ? std::string("ICP of the object points onto the mesh")
              : std::string("ICP onto the mesh from the pose and its near-symmetric turns, the "
                            "best depth fit wins")) +
         ".\n\n";
    // Each column says how a missed instance counts: as a wrong pose (the accuracies, the AUCs at
    // an infinite distance, the median at 180 deg) or not at all (the means over found poses).
    s += "| object | n | miss | ADD(-S) acc 0.1d (%) | ADD-S acc 0.1d (%) | ADD-sym acc 0.1d (%) | "
                    "rot err sym median (deg; miss = 180) | ADD-S AUC | ADD AUC | rot err (deg; found) | "
                    "trans err (mm; found) | trans err median (mm; found) | seg IoU |\n"
                    "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    char line[512];
    auto row = [&](const ObjectScores& o, const std::string& name) {
        std::snprintf(line, sizeof line, "| %s | %d | %d | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | ",
                      name.c_str(), o.count, o.misses, o.acc_add_s_10, o.acc_adds_all_10,
                      o.acc_addsym_10, o.rot_err_sym_deg_median, o.auc_adds, o.auc_add);
        s += line;
        // The mean errors are over found poses: an object whose every instance was missed
        // has none ("-", not a 0.00 that reads as perfect).
        if (o.count > o.misses) {
            std::snprintf(line, sizeof line, "%.2f | %.1f | %.1f | ", o.mean_rot_err_deg,
                          o.mean_trans_err_mm, o.median_trans_err_mm);
            s += line;
        } else {
            s += "- | - | - | ";
        }
        if (o.seg_iou >= 0) {
            std::snprintf(line, sizeof line, "%.3f |\n", o.seg_iou);
            s += line;
        } else {
            s += "- |\n";
        }
    };
    for (const auto& o : r.objects)
        row(o, std::to_string(o.obj_id) + " " + o.name + (o.symmetric ? " (sym)" : ""));
    row(r.average, "**average**");
    s += "\nA missed instance (no pose) counts as a wrong pose in the accuracies, at an infinite "
         "distance in the AUCs and at 180 deg in the median rotation error; the columns marked "
         "\"found\" are over the poses found.\n";
    if (r.average.det_recall_50 >= 0) {  // detector boxes: what the detector found
        s += "\nDetection recall (the box the pose matched to the instance is reported with — "
             "the box of its surface the depth explains, else the detector's — at IoU >= 0.5 "
             "with the visible GT box; the pose itself is judged above by its error):";
        for (const auto& o : r.objects) {
            std::snprintf(line, sizeof line, " %d: %.1f%%", o.obj_id, o.det_recall_50);
            s += line;
        }
        std::snprintf(line, sizeof line,
                      "; all %d instances: **%.1f%%** (the detector's own boxes: %.1f%%)\n",
                      r.average.count, r.average.det_recall_50, r.average.detector_recall_50);
        s += line;
    }
    if (r.average.pose_precision >= 0) {  // the hypotheses road: what was reported
        std::snprintf(line, sizeof line,
                      "\nReported poses (accepted hypotheses): %d, of which %d match no instance. "
                      "Pose precision (right at ADD-S < 0.1 d): **%.1f%%**; box precision (IoU >= "
                      "0.5 with a visible GT box): **%.1f%%**\n",
                      r.average.reported, r.average.false_positives, r.average.pose_precision,
                      r.average.det_precision_50);
        s += line;
    }
    const double total = r.ms_crop + r.ms_seg + r.ms_t + r.ms_rot + r.ms_refine;
    std::snprintf(line, sizeof line,
                  "\nTime per instance (ms, mean of %d; the paper's Table 5 stages):\n\n"
                  "| crop | segmentation | translation | rotation (blocks A, B, C + Kabsch) | refinement | total | fps |\n"
                  "|---|---|---|---|---|---|---|\n"
                  "| %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %.1f |\n",
                  r.instances, r.ms_crop, r.ms_seg, r.ms_t, r.ms_rot, r.ms_refine, total,
                  total > 0 ? 1000.0 / total : 0.0);
    s += line;
    return s;
}

std::string report_json(const EvalReport& r) {
    nlohmann::json j;
    auto obj = [](const ObjectScores& o) {
        return nlohmann::json{{"obj_id", o.obj_id}, {"name", o.name}, {"symmetric", o.symmetric},
                              {"count", o.count}, {"misses", o.misses},
                              {"acc_adds_10", o.acc_add_s_10}, {"auc_adds", o.auc_adds},
                              {"auc_add", o.auc_add}, {"rot_err_deg", o.mean_rot_err_deg},
                              {"trans_err_mm", o.mean_trans_err_mm},
                              {"acc_adds_all_10", o.acc_adds_all_10},
                              {"acc_addsym_10", o.acc_addsym_10},
                              {"rot_err_sym_deg_median", o.rot_err_sym_deg_median},
                              {"trans_err_mm_median", o.median_trans_err_mm},
                              {"num_symmetries", o.num_symmetries},
                              {"seg_iou", o.seg_iou >= 0 ? nlohmann::json(o.seg_iou)
                                                         : nlohmann::json(nullptr)},
                              {"det_recall_50", o.det_recall_50 >= 0
                                                    ? nlohmann::json(o.det_recall_50)
                                                    : nlohmann::json(nullptr)},
                              {"detector_recall_50", o.detector_recall_50 >= 0
                                                         ? nlohmann::json(o.detector_recall_50)
                                                         : nlohmann::json(nullptr)},
                              {"pose_precision", o.pose_precision >= 0
                                                     ? nlohmann::json(o.pose_precision)
                                                     : nlohmann::json(nullptr)},
                              {"det_precision_50", o.det_precision_50 >= 0
                                                       ? nlohmann::json(o.det_precision_50)
                                                       : nlohmann::json(nullptr)},
                              {"reported", o.reported},
                              {"false_positives", o.false_positives}};
    };
    for (const auto& o : r.objects) j["objects"].push_back(obj(o));
    j["average"] = obj(r.average);
    j["timing_ms"] = {{"crop", r.ms_crop}, {"seg", r.ms_seg}, {"t", r.ms_t}, {"rot", r.ms_rot},
                      {"refine", r.ms_refine}};
    j["refine"] = g2l::to_string(r.refine);
    j["instances"] = r.instances;
    j["oracle"] = r.oracle;
    return j.dump(2);
}

std::vector<PrPoint> pr_curve(const std::vector<InstanceResult>& results) {
    int instances = 0;
    std::vector<std::pair<double, bool>> reported;  // (score, right)
    for (const InstanceResult& r : results) {
        instances += !r.false_positive;
        if (r.reported) reported.emplace_back(r.score, r.right && !r.false_positive);
    }
    std::stable_sort(reported.begin(), reported.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    std::vector<PrPoint> curve;
    int n = 0, right = 0;
    for (size_t i = 0; i < reported.size(); ++i) {
        ++n;
        right += reported[i].second;
        if (i + 1 < reported.size() && reported[i + 1].first == reported[i].first) continue;
        PrPoint p;
        p.threshold = reported[i].first;
        p.precision = 100.0 * right / n;
        p.recall = instances ? 100.0 * right / instances : 0.0;
        curve.push_back(p);
    }
    return curve;
}

namespace {

using FeatureVec = Eigen::Matrix<double, infer::ScoreModel::kFeatures, 1>;

FeatureVec to_vec(const infer::ScoreModel::Features& f) {
    FeatureVec x;
    for (int k = 0; k < infer::ScoreModel::kFeatures; ++k) x[k] = f[size_t(k)];
    return x;
}

// L2-penalised logistic regression by Newton's method: the w minimising
// sum_i -log P(y_i | x_i) + l2 n / 2 sum_{k >= first_penalised} w_k^2, P(1 | x) =
// ScoreModel::sigmoid(w . x).
infer::ScoreModel::Features fit_logistic(const std::vector<FeatureVec>& x,
                                         const std::vector<double>& y, double l2,
                                         int first_penalised) {
    constexpr int F = infer::ScoreModel::kFeatures;
    const double n = double(x.size());
    FeatureVec w = FeatureVec::Zero();
    for (int it = 0; it < 100; ++it) {
        FeatureVec grad = FeatureVec::Zero();
        Eigen::Matrix<double, F, F> hess = Eigen::Matrix<double, F, F>::Zero();
        for (size_t i = 0; i < x.size(); ++i) {
            const double p = infer::ScoreModel::sigmoid(w.dot(x[i]));
            grad += (p - y[i]) * x[i];
            hess += std::max(p * (1 - p), 1e-9) * x[i] * x[i].transpose();
        }
        for (int k = first_penalised; k < F; ++k) {
            grad[k] += l2 * n * w[k];
            hess(k, k) += l2 * n;
        }
        hess.diagonal().array() += 1e-9;
        const FeatureVec step = hess.ldlt().solve(grad);
        w -= step;
        if (step.cwiseAbs().maxCoeff() < 1e-8) break;
    }
    infer::ScoreModel::Features out;
    for (int k = 0; k < F; ++k) out[size_t(k)] = w[k];
    return out;
}

}  // namespace

infer::ScoreModel fit_score_model(const std::vector<HypothesisRecord>& hyps, double l2) {
    std::vector<FeatureVec> x;
    std::vector<double> y;  // 1: the pose is right
    for (const HypothesisRecord& h : hyps)
        if (h.posed && h.verified) x.push_back(to_vec(h.features)), y.push_back(h.pose_right);
    const int n = int(x.size());
    const int pos = int(std::count(y.begin(), y.end(), 1.0));
    G2L_CHECK(n >= 20 && pos > 0 && pos < n, "fit_score_model: need at least 20 verified "
              "hypotheses with right and wrong poses among them, got ", n, " (", pos, " right)");
    infer::ScoreModel m;
    m.w = fit_logistic(x, y, l2, 1);  // the bias is not penalised
    return m;
}

infer::ArbiterModel fit_arbiter(const std::vector<HypothesisRecord>& hyps, double l2) {
    std::vector<FeatureVec> dx;  // loser - winner
    std::vector<double> y;       // 1: the loser was the right one
    for (size_t b = 0; b < hyps.size();) {  // one frame's records: [b, e)
        size_t e = b + 1;
        while (e < hyps.size() && hyps[e].scene == hyps[b].scene &&
               hyps[e].image_id == hyps[b].image_id)
            ++e;
        for (size_t i = b; i < e; ++i) {
            const HypothesisRecord& h = hyps[i];
            if (h.verdict != "duplicate" && h.verdict != "overlap") continue;
            G2L_CHECK(h.rival >= 0 && size_t(h.rival) < e - b, "fit_arbiter: hypothesis ", i - b,
                      " of scene ", h.scene, " image ", h.image_id, " names rival ", h.rival,
                      ", outside its frame's ", e - b, " hypotheses");
            const HypothesisRecord& w = hyps[b + size_t(h.rival)];
            if (!h.verified || !w.verified || h.pose_right == w.pose_right) continue;
            dx.push_back(to_vec(h.features) - to_vec(w.features));
            // The bias's difference is 0: its slot carries the footprints' ln-cells difference.
            dx.back()[0] = infer::ArbiterModel::ln_cells(size_t(h.footprint_cells)) -
                           infer::ArbiterModel::ln_cells(size_t(w.footprint_cells));
            y.push_back(h.pose_right ? 1.0 : 0.0);
        }
        b = e;
    }
    const int n = int(dx.size());
    G2L_CHECK(n >= 10, "fit_arbiter: need at least 10 duplicates or overlaps where exactly one "
              "of the two poses is right, got ", n);
    infer::ArbiterModel m;
    m.w = fit_logistic(dx, y, l2, 0);
    m.footprint = m.w[0];  // slot 0 held the ln-cells difference
    m.w[0] = 0;
    return m;
}

}  // namespace g2l::eval
