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

}  // namespace

EvalReport evaluate_gt_boxes(nn::G2LNet& net, const data::Dataset& ds,
                             const std::map<int, int>& class_of,
                             const std::vector<std::vector<Eigen::Vector3f>>& keypoints,
                             const EvalOptions& opt) {
    return evaluate_instances(net, ds, class_of, keypoints, opt, nullptr);
}

EvalReport evaluate_instances(nn::G2LNet& net, const data::Dataset& ds,
                              const std::map<int, int>& class_of,
                              const std::vector<std::vector<Eigen::Vector3f>>& keypoints,
                              const EvalOptions& opt, std::vector<InstanceResult>* instances_out) {
    // Detector boxes: the best-scoring detection per (scene, image, object).
    std::map<std::tuple<int, int, int>, const data::Detection*> best_det;
    if (opt.detections) {
        for (size_t i = 0; i < opt.detections->size(); ++i) {
            const data::Detection& d = (*opt.detections)[i];
            G2L_CHECK(d.scene_id >= 0 && d.image_id >= 0, "evaluate: detection ", i,
                      " (object ", d.obj_id, ") has no scene_id / image_id: evaluation needs both");
            const auto k = std::make_tuple(d.scene_id, d.image_id, d.obj_id);
            auto it = best_det.find(k);
            if (it == best_det.end() || d.score > it->second->score) best_det[k] = &d;
        }
    }
    // The frame pipeline the inference library runs (infer/frame_pipeline.h): the same crop,
    // networks and refinement; evaluation adds only the ground truth and the oracle inputs.
    infer::PipelineModel pm;
    pm.net = &net;
    pm.class_of = class_of;
    pm.keypoints = keypoints;
    pm.crop = infer::to_string(opt.crop);
    pm.radius_scale = opt.radius_scale;
    for (const auto& [id, om] : ds.models())
        if (class_of.count(id)) pm.diameter[id] = om.info.diameter;
    infer::PipelineOptions po;
    po.crop_points = std::max(0, opt.crop_points);
    po.object_points = opt.max_object_points;
    po.refine = opt.refine;
    const bool was_training = net.is_training();
    net.eval();
    autograd::NoGradGuard no_grad;
    infer::FramePipeline pipe(std::move(pm), po);
    std::vector<InstanceResult> results;
    std::map<int, ObjectMeta> meta;
    std::map<int, ObjGeom> model_geom;
    EvalReport rep;
    double t_crop = 0, t_seg = 0, t_t = 0, t_rot = 0, t_refine = 0;
    std::vector<const data::Instance*> insts;  // this frame's evaluated instances
    std::vector<InstanceResult> res;           // their results
    std::vector<infer::PoseRequest> reqs;      // the boxes the pipeline poses
    std::vector<size_t> req_of;                // index in insts of each request
    std::vector<infer::PoseOutcome> outs;
    std::vector<std::vector<uint8_t>> gt_obj;  // per request: GT object flags of its crop rows
    std::vector<Eigen::Vector3f> gt_t;
    std::vector<infer::Oracle> oracles;
    for (const data::Frame& f : ds.frames()) {
        if (opt.max_instances > 0 && rep.instances >= opt.max_instances) break;
        insts.clear();
        for (const data::Instance& inst : f.instances) {
            if (!class_of.count(inst.obj_id) || !inst.visible_enough(opt.min_visib_fract)) continue;
            if (opt.max_instances > 0 && rep.instances >= opt.max_instances) break;
            insts.push_back(&inst);
            rep.instances++;
        }
        if (insts.empty()) continue;
        int w = 0, h = 0;
        const std::vector<float> depth = ds.load_depth_mm(f, &w, &h);
        geom::Intrinsics K = f.K;
        K.width = w;
        K.height = h;
        res.assign(insts.size(), InstanceResult{});
        reqs.clear();
        req_of.clear();
        for (size_t k = 0; k < insts.size(); ++k) {
            const data::Instance& inst = *insts[k];
            const data::ObjectModel& om = ds.model(inst.obj_id);
            if (!model_geom.count(inst.obj_id)) {  // once per object
                const geom::Mesh& mesh = ds.load_model_mesh(inst.obj_id);
                pipe.add_mesh(inst.obj_id, mesh, om.info);
                const int64_t nv = mesh.vertices.rows();
                const int64_t keep = opt.max_model_points > 0 ? std::min<int64_t>(nv, opt.max_model_points) : nv;
                ObjGeom g;
                g.pts.resize(keep, 3);
                for (int64_t i = 0; i < keep; ++i) g.pts.row(i) = mesh.vertices.row(i * nv / keep);
                g.syms = geom::geometric_symmetries(*pipe.mesh(inst.obj_id)->tree, om.info);
                meta[inst.obj_id] = {om.name, om.info.diameter, om.info.symmetric,
                                     int(std::max<size_t>(1, g.syms.size()))};
                model_geom[inst.obj_id] = std::move(g);
            }
            InstanceResult& r = res[k];
            r.obj_id = inst.obj_id;
            r.scene = f.scene;
            r.image_id = f.image_id;
            r.inst_index = int(&inst - f.instances.data());
            r.gt = inst.pose;
            infer::PoseRequest q;
            q.obj_id = inst.obj_id;
            q.box = inst.box();
            if (opt.detections) {
                int scene_id = -1;
                try {
                    scene_id = std::stoi(f.scene);
                } catch (const std::exception&) {
                    G2L_CHECK(false, "evaluate: scene '", f.scene, "' is not a number (BOP scene ids "
                              "are), so detections cannot be matched to it");
                }
                const auto it = best_det.find(std::make_tuple(scene_id, f.image_id, inst.obj_id));
                r.det_iou = 0;
                if (it == best_det.end()) {
                    r.status = "no detection";
                    r.box = geom::clip_box(q.box, w, h);
                    continue;
                }
                const data::Detection& d = *it->second;
                q.box = {int(std::lround(d.x)), int(std::lround(d.y)), int(std::lround(d.w)),
                         int(std::lround(d.h))};
                r.score = d.score;
                const geom::Box2i gt = inst.box();
                r.det_iou = geom::box_iou(d.x, d.y, d.w, d.h, gt.x, gt.y, gt.w, gt.h);
                if (d.peak_x >= 0 && d.peak_y >= 0) q.peak_x = d.peak_x, q.peak_y = d.peak_y;
            }
            if (opt.centre_from_mask && opt.crop != infer::CropKind::frustum) {
                Eigen::Vector3d c;
                const geom::Box2i box = geom::clip_box(q.box, w, h);
                r.box = box;
                if (box.empty()) {
                    r.status = "box outside image";
                    continue;
                }
                if (!sphere_centre(ds, f, inst, depth, w, h, box, &c)) {
                    r.status = "no depth";
                    continue;
                }
                q.centre = c;
            }
            reqs.push_back(q);
            req_of.push_back(k);
        }
        pipe.crop(depth.data(), K, reqs, &outs);
        // The ground-truth object points of each crop (training's label rule; outside the
        // timed stages): the seg IoU, and the oracle inputs when asked for.
        gt_obj.assign(reqs.size(), {});
        gt_t.resize(reqs.size());
        oracles.assign(reqs.size(), infer::Oracle{});
        for (size_t i = 0; i < reqs.size(); ++i) {
            if (!outs[i].ok()) continue;
            const data::Instance& inst = *insts[req_of[i]];
            gt_obj[i] = pipe.mesh(inst.obj_id)->tree->label_points(outs[i].crop, inst.pose,
                                                                   float(opt.label_threshold_mm));
            gt_t[i] = inst.pose.t.cast<float>();
            if (opt.oracle_seg) oracles[i].object_mask = &gt_obj[i];
            if (opt.oracle_t) oracles[i].translation = &gt_t[i];
        }
        pipe.estimate(depth.data(), K, &outs, &oracles);
        for (size_t i = 0; i < reqs.size(); ++i) {
            const infer::PoseOutcome& o = outs[i];
            const data::Instance& inst = *insts[req_of[i]];
            InstanceResult& r = res[req_of[i]];
            r.box = o.box;
            r.status = infer::to_string(o.status);
            r.ms = o.ms_crop + o.ms_seg + o.ms_t + o.ms_rot + o.ms_refine;
            t_crop += o.ms_crop;
            t_seg += o.ms_seg;
            t_t += o.ms_t;
            t_rot += o.ms_rot;
            t_refine += o.ms_refine;
            if (o.num_crop_points > 0 && !gt_obj[i].empty()) {
                const int n_seen = opt.crop_points > 0 ? opt.crop_points : int(o.crop.rows());
                r.seg_iou = rows_iou(nn::even_sample(int(o.crop.rows()), n_seen), o.object_rows,
                                     gt_obj[i]);
            }
            if (!o.ok()) continue;
            const ObjGeom& og = model_geom[inst.obj_id];
            if (o.refined) {
                geom::Points obs(int64_t(o.object_rows.size()), 3);
                for (size_t j = 0; j < o.object_rows.size(); ++j)
                    obs.row(int64_t(j)) = o.crop.row(o.object_rows[j]);
                r.refine_hyp = o.refine_hypothesis;
                r.refine_cluster = o.refine_cluster;
                r.fit_mm = o.fit_mm;
                r.gt_fit_mm = geom::fit_error(*pipe.mesh(inst.obj_id)->tree, obs, inst.pose,
                                              0.1 * meta.at(inst.obj_id).diameter);
            }
            r.est = o.pose;
            r.found = true;
            r.add_mm = geom::add(o.pose, inst.pose, og.pts);
            r.adds_mm = geom::adds(o.pose, inst.pose, og.pts);
            // Modulo the geometric symmetries S: the GT pose composed with S is as right.
            r.addsym_mm = geom::add_sym(o.pose, inst.pose, og.pts, og.syms);
            r.rot_sym_deg = geom::rotation_error_sym_deg(o.pose.R, inst.pose.R, og.syms);
            r.rot_deg = geom::rotation_error_deg(o.pose.R, inst.pose.R);
            r.trans_mm = geom::translation_error(o.pose.t, inst.pose.t);
        }
        results.insert(results.end(), res.begin(), res.end());
    }
    const double n_inst = rep.instances;
    rep = aggregate(results, meta);
    rep.refine = opt.refine;
    rep.oracle = opt.oracle_seg ? (opt.oracle_t ? "seg+t" : "seg") : opt.oracle_t ? "t" : "none";
    if (instances_out) *instances_out = results;
    if (n_inst > 0) {
        rep.ms_crop = t_crop / n_inst; rep.ms_seg = t_seg / n_inst;
        rep.ms_t = t_t / n_inst; rep.ms_rot = t_rot / n_inst;
        rep.ms_refine = t_refine / n_inst;
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
        a.count++;
        if (r.seg_iou >= 0) {
            a.seg_iou += r.seg_iou;
            a.seg_n++;
        }
        if (r.det_iou >= 0) {
            a.det_n++;
            a.det_hits += !r.det_miss();
        }
        if (!r.found || r.det_miss()) {  // no pose, or a pose from no true detection
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
    rep.instances = int(results.size());
    Acc all;
    for (auto& [id, a] : acc) {
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
        rep.objects.push_back(s);
        all.adds_m.insert(all.adds_m.end(), a.adds_m.begin(), a.adds_m.end());
        all.add_m.insert(all.add_m.end(), a.add_m.begin(), a.add_m.end());
        all.count += a.count; all.misses += a.misses; all.found += a.found;
        all.rot += a.rot; all.trans += a.trans;
        all.det_n += a.det_n; all.det_hits += a.det_hits;
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
    s += std::string("Depth refinement (") + infer::to_string(r.refine) + "): " +
         (r.refine == infer::Refine::none ? std::string("none, the networks' poses as they are")
          : r.refine == infer::Refine::icp
              ? std::string("ICP of the object points onto the mesh")
              : std::string("ICP onto the mesh from the pose and its near-symmetric turns, the "
                            "best depth fit wins")) +
         ".\n\n";
    s += "| object | n | miss | ADD(-S) acc 0.1d (%) | ADD-S acc 0.1d (%) | ADD-sym acc 0.1d (%) | "
                    "rot err sym median (deg) | ADD-S AUC | ADD AUC | rot err (deg) | trans err (mm) | trans err median (mm) | seg IoU |\n"
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
    if (r.average.det_recall_50 >= 0) {  // detector boxes: what the detector found
        s += "\nDetection recall (the class's best box at IoU >= 0.5 with the visible GT box; an "
             "instance without one counts as a miss above):";
        for (const auto& o : r.objects) {
            std::snprintf(line, sizeof line, " %d: %.1f%%", o.obj_id, o.det_recall_50);
            s += line;
        }
        std::snprintf(line, sizeof line, "; all %d instances: **%.1f%%**\n", r.average.count,
                      r.average.det_recall_50);
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
                                                    : nlohmann::json(nullptr)}};
    };
    for (const auto& o : r.objects) j["objects"].push_back(obj(o));
    j["average"] = obj(r.average);
    j["timing_ms"] = {{"crop", r.ms_crop}, {"seg", r.ms_seg}, {"t", r.ms_t}, {"rot", r.ms_rot},
                      {"refine", r.ms_refine}};
    j["refine"] = infer::to_string(r.refine);
    j["instances"] = r.instances;
    j["oracle"] = r.oracle;
    return j.dump(2);
}

}  // namespace g2l::eval
