// SPDX-License-Identifier: MIT
#include "infer/frame_pipeline.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <cmath>

#include "core/error.h"
#include "core/job_pool.h"
#include "geometry/camera.h"
#include "geometry/crop.h"
#include "geometry/verify.h"

namespace g2l::infer {

namespace {
using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
}  // namespace

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
        p.syms = geom::geometric_symmetries(*p.tree, info);
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
    : model_(std::move(model)) {
    G2L_CHECK(model_.net, "FramePipeline: the model has no network");
    G2L_CHECK(std::isfinite(model_.radius_scale) && model_.radius_scale > 0,
              "FramePipeline: radius_scale must be > 0, got ", model_.radius_scale);
    opt_ = resolved(opt);
    for (const auto& [id, cls] : model_.class_of)
        G2L_CHECK(cls >= 0 && size_t(cls) < model_.keypoints.size(), "FramePipeline: object ", id,
                  " has class index ", cls, " but the model has ", model_.keypoints.size(),
                  " keypoint sets");
    engine_ = std::make_unique<nn::PoseEngine>(*model_.net);
}

PipelineOptions FramePipeline::resolved(const PipelineOptions& opt) const {
    opt.check();
    PipelineOptions r = opt;
    if (r.crop_points < 0) r.crop_points = model_.points;
    if (r.object_points < 0) r.object_points = model_.seg_points;
    // Objects without a mesh keep the networks' pose whatever the setting, so `automatic`
    // (refine what can be refined) is `turns` here.
    if (r.refine == Refinement::automatic) r.refine = Refinement::turns;
    return r;
}

void FramePipeline::set_options(const PipelineOptions& opt) {
    PipelineOptions r = resolved(opt);
    G2L_CHECK(r.refine == opt_.refine, "FramePipeline::set_options: the refinement cannot "
              "change from ", to_string(opt_.refine), " to ", to_string(r.refine),
              " (the meshes were prepared for it): make a new pipeline");
    opt_ = r;
}

FramePipeline::~FramePipeline() = default;
FramePipeline::FramePipeline(FramePipeline&&) noexcept = default;

void FramePipeline::add_mesh(int obj_id, const geom::Mesh& mesh, const geom::ModelInfo& info) {
    meshes_[obj_id] = PreparedMesh::from_mesh(mesh, info, opt_.refine != Refinement::none);
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
    out->resize(requests.size());
    // The boxes are cropped side by side (OpenMP over the boxes; each writes only its own
    // outcome), errors rethrown after, the first box's first.
    const int64_t n = int64_t(requests.size());
    PieceErrors errors(requests.size());
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t i = 0; i < n; ++i)
        errors.run(size_t(i), [&] { crop_one(depth, K, requests[size_t(i)], &(*out)[size_t(i)]); });
    errors.rethrow_first();
}

void FramePipeline::crop_one(const float* depth, const geom::Intrinsics& K, const PoseRequest& r,
                             PoseOutcome* out) const {
    const int W = K.width, H = K.height;
    const auto t0 = Clock::now();
    PoseOutcome& p = *out;
    p = PoseOutcome{};
    p.obj_id = r.obj_id;
    if (!model_.class_of.count(r.obj_id)) {
        p.status = PoseStatus::unknown_object;
        return;
    }
    p.box = geom::clip_box(r.box, W, H);
    if (p.box.empty()) {
        p.status = PoseStatus::box_outside_image;
        return;
    }
    if (model_.crop == geom::CropKind::frustum) {
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
            return;
        }
        const auto d = model_.diameter.find(r.obj_id);
        G2L_CHECK(d != model_.diameter.end() && d->second > 0, "FramePipeline: no diameter "
                  "for object ", r.obj_id, " (the sphere crop needs it)");
        p.crop = geom::crop_points(model_.crop, geom::depth_to_points(depth, W, H, K, p.box), c,
                                   model_.radius_scale * d->second);
    }
    p.num_crop_points = int(p.crop.rows());
    p.ms_crop = ms_since(t0);
}

void FramePipeline::estimate(const float* depth, const geom::Intrinsics& K,
                             std::vector<PoseOutcome>* io, const std::vector<Oracle>* oracles,
                             const geom::VerifyOptions* verify_opt) {
    std::vector<PoseOutcome>& outs = *io;
    G2L_CHECK(!oracles || oracles->size() == outs.size(), "FramePipeline::estimate: ",
              oracles ? oracles->size() : 0, " oracles for ", outs.size(), " outcomes");
    // One box at a time, one engine call each: a box's pose then never depends on which other
    // boxes the frame has (a batched call packs them into the same GEMMs, whose tiling follows
    // the total point count and changes the last bits, and the refinement's choice among its
    // starts can amplify those). Batching saved ~10% of a 4-object frame; reproducible poses
    // are worth more.
    auto networks = [&](size_t i) {
        PoseOutcome& p = outs[i];
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
            return;
        }
        p.pose = e.pose;
    };
    // The verification against the depth (when asked, and the object has a mesh).
    auto verify_into = [&](PoseOutcome& p) {
        if (verify_opt && meshes_.count(p.obj_id)) p.check = verify(depth, K, p, *verify_opt);
    };
    // Depth refinement against the mesh (geometry/refine.h), then the verification.
    auto refine = [&](size_t i) {
        PoseOutcome& p = outs[i];
        const auto me = meshes_.find(p.obj_id);
        geom::Points obs(int64_t(p.object_rows.size()), 3);
        for (size_t k = 0; k < p.object_rows.size(); ++k)
            obs.row(int64_t(k)) = p.crop.row(p.object_rows[k]);
        if (obs.rows() >= 3 && me != meshes_.end()) {
            const PreparedMesh& m = me->second;
            geom::RefineOptions ro;
            ro.hypotheses = opt_.refine == Refinement::turns;
            const geom::DepthImage di{depth, K};
            const geom::RefineResult rr =
                geom::refine_pose(*m.tree, m.info, obs, p.pose, ro, &di, &m.normals, &m.grid, &m.syms);
            p.pose = rr.pose;
            p.fit_mm = rr.fit_mm;
            p.alt_fit_mm = rr.alt_fit_mm;
            p.refine_hypothesis = rr.hypothesis;
            p.refine_cluster = rr.cluster;
            p.refined = true;
        }
        verify_into(p);
    };
    const bool refining = opt_.refine != Refinement::none;
    // The first box's networks on every thread (nothing else is ready to run yet); then each
    // box's refinement is a job of a JobPool the region's threads share: while one thread runs
    // the next box's networks (a nested, hence one-thread, team: results never depend on the
    // thread count), the others refine the boxes before it, and refine_pose's starts, finalists
    // and cluster searches are jobs of the same pool, so one box's serial parts (support plane,
    // clusters) and last pieces overlap the others' work, and a thread waiting for one box's
    // pieces works on another box's meanwhile. Each box's refinement depends only on that box:
    // the poses are those of one box at a time.
    size_t next = 0;
    for (; next < outs.size(); ++next)
        if (outs[next].status == PoseStatus::ok) {
            networks(next++);
            break;
        }
    if (!refining) {  // the networks' poses, verified as they are when asked
        for (; next < outs.size(); ++next)
            if (outs[next].status == PoseStatus::ok) networks(next);
        if (verify_opt)
            for (PoseOutcome& p : outs)
                if (p.status == PoseStatus::ok) {
                    const auto tv = Clock::now();
                    verify_into(p);
                    p.ms_refine += ms_since(tv);  // verification is part of the depth stage
                }
        return;
    }
    PieceErrors errors(outs.size());
    auto guarded = [&](size_t i, auto&& step) { errors.run(i, [&] { step(i); }); };
    // The stage's wall time less the networks run inside it, shared among the refined boxes.
    const auto t0 = Clock::now();
    double ms_networks = 0;
    std::vector<size_t> refined;
    JobPool pool;
    JobPool::Group boxes;
#pragma omp parallel
    {
        JobPoolScope scope(pool);
#pragma omp master
        {
            for (size_t i = 0; i < outs.size(); ++i) {
                if (i >= next && outs[i].status == PoseStatus::ok) {
                    const auto tn = Clock::now();
                    guarded(i, networks);
                    ms_networks += ms_since(tn);
                }
                if (errors.failed(i) || outs[i].status != PoseStatus::ok) continue;
                refined.push_back(i);
                pool.submit(boxes, [&guarded, &refine, i] { guarded(i, refine); });
            }
            pool.close(boxes);
        }
        pool.wait(boxes);
    }
    errors.rethrow_first();
    const double share = std::max(0.0, ms_since(t0) - ms_networks) / double(std::max<size_t>(1, refined.size()));
    for (const size_t i : refined) outs[i].ms_refine = share;
}

void FramePipeline::run(const float* depth, const geom::Intrinsics& K,
                        const std::vector<PoseRequest>& requests, std::vector<PoseOutcome>* out,
                        const geom::VerifyOptions* verify_opt) {
    crop(depth, K, requests, out);
    estimate(depth, K, out, nullptr, verify_opt);
}

ScoreModel::Features ScoreModel::features(const geom::Verification& v, double det_score,
                                          bool borrowed) {
    return {{1.0, v.explained, v.violation, v.occlusion, v.seg_agree, v.score,
             std::log(std::clamp(det_score, 1e-3, 1.0)), borrowed ? 1.0 : 0.0}};
}

double ScoreModel::dot(const Features& w, const Features& x) {
    double z = 0;
    for (int k = 0; k < kFeatures; ++k) z += w[size_t(k)] * x[size_t(k)];
    return z;
}

double ScoreModel::sigmoid(double z) { return 1.0 / (1.0 + std::exp(-std::clamp(z, -40.0, 40.0))); }

double ScoreModel::probability(const geom::Verification& v, double det_score,
                               bool borrowed) const {
    return sigmoid(dot(w, features(v, det_score, borrowed)));
}

double ArbiterModel::ln_cells(size_t cells) { return std::log(double(std::max<size_t>(cells, 1))); }

double ArbiterModel::prefer(const ScoreModel::Features& a, const ScoreModel::Features& b,
                            double ln_cells_a, double ln_cells_b) const {
    ScoreModel::Features d;
    for (int k = 0; k < ScoreModel::kFeatures; ++k) d[size_t(k)] = a[size_t(k)] - b[size_t(k)];
    return ScoreModel::sigmoid(ScoreModel::dot(w, d) + footprint * (ln_cells_a - ln_cells_b));
}

const char* to_string(Verdict v) {
    switch (v) {
        case Verdict::accepted: return "accepted";
        case Verdict::no_pose: return "no pose";
        case Verdict::low_score: return "low score";
        case Verdict::duplicate: return "duplicate";
        case Verdict::overlap: return "overlap";
        case Verdict::covered: return "covered";
        case Verdict::implausible: return "implausible distance";
    }
    return "unknown verdict";
}

std::string implausible_distance(const geom::Pose& pose, const geom::Box2i& box,
                                 const geom::Intrinsics& K, double diameter) {
    const double z = pose.t.z();
    if (!(z >= 50 && z <= 20000))
        return cat("the pose lies at z = ", z, " mm, outside any RGB-D sensor's 50 mm - 20 m");
    const double f = 0.5 * (K.fx + K.fy);
    const double largest = f * diameter / std::max(1.0, z - 0.5 * diameter);  // px
    const double nominal = f * diameter / z;
    const int side = std::max(box.w, box.h);
    if (side > 2 * largest)
        return cat("its ", side, " px box is more than twice the ", int(std::lround(largest)),
                   " px the object can cover at z = ", int(std::lround(z)), " mm: the depth reads "
                   "too far (check the depth scale and the camera)");
    const bool at_border = box.x <= 0 || box.y <= 0 || box.x + box.w >= K.width ||
                           box.y + box.h >= K.height;
    if (!at_border && side < nominal / 8)
        return cat("its ", side, " px box is under 1/8 of the ", int(std::lround(nominal)),
                   " px the object covers at z = ", int(std::lround(z)), " mm: the depth reads "
                   "too near (check the depth scale and the camera)");
    return "";
}

namespace {

// Sorted box sides of a mesh (the shape a depth-only detector sees, up to its orientation).
Eigen::Vector3d sorted_sides(const geom::ModelInfo& info) {
    Eigen::Vector3d s = info.size;
    std::sort(s.data(), s.data() + 3);
    return s;
}

}  // namespace

std::vector<Candidate> FramePipeline::candidates(const std::vector<Candidate>& detections) const {
    const PipelineOptions& opt = opt_;
    std::vector<Candidate> all;
    for (const Candidate& d : detections) {
        // Objects the model does not know, or whose size it was not given (evaluation on a
        // dataset with a part of the model's objects), are not posed.
        if (!model_.class_of.count(d.obj_id) || !model_.diameter.count(d.obj_id) ||
            !(d.det_score >= opt.min_detection_score))
            continue;
        Candidate c = d;
        c.det_obj_id = d.obj_id;
        all.push_back(c);
        // The same peak as each object of a like shape (both need their mesh's box).
        const PreparedMesh* me = mesh(d.obj_id);
        if (opt.alike_frac <= 0 || !me) continue;
        const Eigen::Vector3d a = sorted_sides(me->info);
        for (const auto& [id, other] : meshes_) {
            if (id == d.obj_id || !model_.class_of.count(id) || !model_.diameter.count(id))
                continue;
            const Eigen::Vector3d b = sorted_sides(other.info);
            bool like = true;
            for (int k = 0; k < 3; ++k)
                like = like && std::abs(a[k] - b[k]) <= opt.alike_frac * std::max(a[k], b[k]);
            if (!like) continue;
            Candidate alt = c;
            alt.obj_id = id;
            alt.det_score = c.det_score * tuning_.alike_discount;
            if (alt.det_score >= opt.min_detection_score) all.push_back(alt);
        }
    }
    // The order the budget (max_hypotheses) is spent in: each object's best own peak first
    // (a weak peak of a partly hidden object is worth more than a second look at a found
    // one), then the other own peaks, then the borrowed ones; by score within each.
    std::map<int, double> best_own;
    for (const Candidate& c : all)
        if (c.obj_id == c.det_obj_id)
            best_own[c.obj_id] = std::max(best_own[c.obj_id], c.det_score);
    auto rank = [&](const Candidate& c) {
        if (c.obj_id != c.det_obj_id) return 2;
        return c.det_score == best_own[c.obj_id] ? 0 : 1;
    };
    std::stable_sort(all.begin(), all.end(), [&](const Candidate& x, const Candidate& y) {
        const int rx = rank(x), ry = rank(y);
        if (rx != ry) return rx < ry;
        return x.det_score > y.det_score;
    });
    std::vector<Candidate> out;
    std::map<int, int> per_object;
    for (const Candidate& c : all) {
        if (int(out.size()) >= opt.max_hypotheses) break;
        // A borrowed peak already tried as that object (the same box) adds nothing.
        bool seen = false;
        for (const Candidate& o : out)
            seen = seen || (o.obj_id == c.obj_id && o.box.x == c.box.x && o.box.y == c.box.y &&
                            o.box.w == c.box.w && o.box.h == c.box.h);
        if (seen || per_object[c.obj_id] >= opt.max_instances) continue;
        per_object[c.obj_id]++;
        out.push_back(c);
    }
    return out;
}

geom::Verification FramePipeline::verify(const float* depth, const geom::Intrinsics& K,
                                         const PoseOutcome& o,
                                         const geom::VerifyOptions& opt) const {
    const PreparedMesh* m = mesh(o.obj_id);
    G2L_CHECK(m && o.ok(), "FramePipeline::verify: object ", o.obj_id,
              m ? " has no pose" : " has no mesh");
    geom::Points obs(int64_t(o.object_rows.size()), 3);
    for (size_t i = 0; i < o.object_rows.size(); ++i)
        obs.row(int64_t(i)) = o.crop.row(o.object_rows[i]);
    const geom::DepthImage di{depth, K};
    return geom::verify_pose(*m->tree, m->info, o.pose, di, obs, opt,
                             m->grid.empty() ? nullptr : &m->grid);
}

bool same_instance(const Hypothesis& a, const Hypothesis& b, const HypothesisTuning& tune,
                   double diameter, double shared) {
    if (a.cand.obj_id != b.cand.obj_id ||
        (a.outcome.pose.t - b.outcome.pose.t).norm() >= tune.duplicate_frac * diameter)
        return false;
    return !(a.verified && b.verified) || shared > tune.duplicate_overlap;
}

bool same_instance(const Hypothesis& a, const Hypothesis& b, const HypothesisTuning& tune,
                   double diameter) {
    const double shared = a.verified && b.verified
                              ? geom::footprint_overlap(a.check.footprint, b.check.footprint)
                              : 0;
    return same_instance(a, b, tune, diameter, shared);
}

std::vector<Hypothesis> select_hypotheses(std::vector<Hypothesis> hs,
                                          const HypothesisTuning& tune,
                                          const std::map<int, double>& diameter,
                                          const geom::Intrinsics& K, double min_pose_score) {
    // 3. Greedy selection, best score first: a hypothesis is kept unless a kept one is the same
    //    instance (same object, centres closer than duplicate_frac x diameter, some depth
    //    shared) or claims the same depth (footprints overlapping by more than overlap_frac)
    //    — and the arbiter does not prefer it to every kept one it conflicts with; those it
    //    beats are dropped then.
    for (const Hypothesis& h : hs)
        G2L_CHECK(!h.outcome.ok() || diameter.count(h.cand.obj_id), "select_hypotheses: object ",
                  h.cand.obj_id, " is posed but has no diameter");
    std::vector<size_t> order(hs.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
        const bool oa = hs[a].outcome.ok() && hs[a].verdict != Verdict::covered;
        const bool ob = hs[b].outcome.ok() && hs[b].verdict != Verdict::covered;
        if (oa != ob) return oa;
        if (hs[a].fill_in != hs[b].fill_in) return hs[b].fill_in;
        return hs[a].score > hs[b].score;
    });
    std::vector<size_t> kept;
    std::vector<ScoreModel::Features> features(hs.size());  // the arbiter's inputs, once a pose
    std::vector<double> ln_cells(hs.size(), 0.0);
    for (size_t i = 0; i < hs.size(); ++i)
        if (hs[i].verified) {
            features[i] = ScoreModel::features(hs[i].check, hs[i].cand.det_score,
                                               hs[i].cand.det_obj_id != hs[i].cand.obj_id);
            ln_cells[i] = ArbiterModel::ln_cells(hs[i].check.footprint.size());
        }
    // Keeps hypothesis i unless a kept pose is the same instance or claims the same depth and
    // the arbiter does not prefer i to it; the kept poses i beats are dropped. Whether kept.
    auto keep = [&](size_t i) {
        Hypothesis& h = hs[i];
        // What a kept pose w is to h: the same instance, the same depth, or neither.
        auto conflict = [&](const Hypothesis& w) {
            // Both verified: the share of depth they both claim, computed once for both tests.
            const bool both_verified = h.verified && w.verified;
            const double shared =
                both_verified ? geom::footprint_overlap(w.check.footprint, h.check.footprint) : 0;
            if (same_instance(h, w, tune, diameter.at(h.cand.obj_id), shared))
                return Verdict::duplicate;
            if (both_verified && shared > tune.overlap_frac) return Verdict::overlap;
            return Verdict::accepted;
        };
        std::vector<std::pair<size_t, Verdict>> beaten;  // kept poses h replaces
        for (const size_t k : kept) {
            const Hypothesis& w = hs[k];
            const Verdict c = conflict(w);
            if (c == Verdict::accepted) continue;
            if (tune.arbitrate && h.verified && w.verified && !h.fill_in && !w.fill_in &&
                tune.arbiter.prefer(features[i], features[k], ln_cells[i], ln_cells[k]) > 0.5) {
                beaten.emplace_back(k, c);
                continue;
            }
            h.verdict = c;
            h.rival = int(k);
            return false;
        }
        h.verdict = Verdict::accepted;
        h.rival = -1;
        for (const auto& [k, c] : beaten) {
            hs[k].verdict = c;
            hs[k].rival = int(i);
            kept.erase(std::find(kept.begin(), kept.end(), k));
        }
        kept.push_back(i);
        return true;
    };
    for (const size_t i : order) {
        Hypothesis& h = hs[i];
        if (h.verdict == Verdict::covered) continue;
        if (!h.outcome.ok()) {
            h.verdict = Verdict::no_pose;
            continue;
        }
        if (!implausible_distance(h.outcome.pose, h.outcome.box, K,
                                  diameter.at(h.cand.obj_id)).empty()) {
            h.verdict = Verdict::implausible;
            continue;
        }
        if (h.score < min_pose_score) {
            h.verdict = Verdict::low_score;
            continue;
        }
        keep(i);
    }
    // A pose that lost to one the arbiter dropped later is tried again, so that every rival
    // named is a kept pose. Each pose kept this way outranks (by the arbiter's order, w .
    // features + footprint x ln cells) every pose it drops, so the passes end; they run only
    // after a replacement.
    for (bool changed = true; changed;) {
        changed = false;
        for (const size_t i : order) {
            const Hypothesis& h = hs[i];
            if ((h.verdict == Verdict::duplicate || h.verdict == Verdict::overlap) &&
                h.rival >= 0 && !hs[size_t(h.rival)].accepted())
                changed = keep(i) || changed;
        }
    }
    // 4. Accepted first, then the rejected, each by score; rivals renumbered.
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
        const bool ka = hs[a].accepted(), kb = hs[b].accepted();
        if (ka != kb) return ka;
        if (ka && hs[a].fill_in != hs[b].fill_in) return hs[a].score > hs[b].score;
        return false;  // keep the score order of step 3
    });
    std::vector<int> new_index(hs.size());
    for (size_t j = 0; j < order.size(); ++j) new_index[order[j]] = int(j);
    std::vector<Hypothesis> out;
    out.reserve(hs.size());
    for (const size_t i : order) {
        out.push_back(std::move(hs[i]));
        if (out.back().rival >= 0) out.back().rival = new_index[size_t(out.back().rival)];
    }
    return out;
}

void FramePipeline::hypotheses(const float* depth, const geom::Intrinsics& K,
                               const std::vector<Candidate>& cands, std::vector<Hypothesis>* out,
                               const std::vector<Hypothesis>* seeds) {
    const PipelineOptions& opt = opt_;
    const HypothesisTuning& tune = tuning_;
    // 1-2. Each candidate, in order, through the one road (crop, networks, refinement) and the
    //      verification against the depth, unless an earlier confident pose already explains
    //      the depth at its peak.
    const int fc = tune.verify.footprint_cell_px;
    const int fw = (K.width + fc - 1) / fc;
    const double cover = std::max(opt.cover_score, opt.min_pose_score);
    const size_t ns = seeds ? seeds->size() : 0;
    std::vector<Hypothesis> hs(ns + cands.size());
    for (size_t i = 0; i < ns; ++i) {  // posed already: only their verdicts are decided here
        hs[i] = (*seeds)[i];
        hs[i].verdict = Verdict::no_pose;
        hs[i].rival = -1;
    }
    std::vector<PoseRequest> req(1);
    std::vector<PoseOutcome> outs;
    for (size_t i = ns; i < hs.size(); ++i) {
        Hypothesis& h = hs[i];
        h.cand = cands[i - ns];
        h.score = h.cand.det_score;
        if (cover <= 1.0) {
            const double px = h.cand.peak_x >= 0 ? h.cand.peak_x : h.cand.box.x + 0.5 * h.cand.box.w;
            const double py = h.cand.peak_y >= 0 ? h.cand.peak_y : h.cand.box.y + 0.5 * h.cand.box.h;
            if (px >= 0 && py >= 0 && px < K.width && py < K.height) {
                // The footprint holds the cells of the explained model points, a sample of the
                // surface: the peak's cell or one of its 8 neighbours.
                const int cx = int(px) / fc, cy = int(py) / fc;
                auto claims = [&](const std::vector<int32_t>& fp) {
                    for (int dy = -1; dy <= 1; ++dy)
                        for (int dx = -1; dx <= 1; ++dx)
                            if (cx + dx >= 0 && cx + dx < fw && cy + dy >= 0 &&
                                std::binary_search(fp.begin(), fp.end(),
                                                   int32_t((cy + dy) * fw + cx + dx)))
                                return true;
                    return false;
                };
                for (size_t k = 0; k < i; ++k) {
                    const Hypothesis& w = hs[k];
                    if (w.verified && !w.fill_in && w.score >= cover && claims(w.check.footprint)) {
                        h.verdict = Verdict::covered;
                        h.rival = int(k);
                        break;
                    }
                }
            }
            if (h.verdict == Verdict::covered) {
                h.outcome.obj_id = h.cand.obj_id;
                h.outcome.status = PoseStatus::no_depth;  // never posed (see the verdict)
                h.score = 0;
                continue;
            }
        }
        req[0] = PoseRequest{};
        req[0].obj_id = h.cand.obj_id;
        req[0].box = h.cand.box;
        req[0].peak_x = h.cand.peak_x;
        req[0].peak_y = h.cand.peak_y;
        // The road verifies a refined pose itself (PoseOutcome::check, part of its depth
        // stage's time): the one place a pose is verified, whichever caller asks.
        run(depth, K, req, &outs, &tune.verify);
        h.outcome = std::move(outs[0]);
        if (!h.outcome.ok()) continue;
        if (h.outcome.check) {
            h.check = *h.outcome.check;
            h.verified = true;
            h.score = tune.score_model.probability(h.check, h.cand.det_score,
                                                  h.cand.det_obj_id != h.cand.obj_id);
        }
    }
    // 3-4. Which are kept, in the order the caller sees them.
    *out = select_hypotheses(std::move(hs), tune, model_.diameter, K, opt.min_pose_score);
}

namespace {

// FramePipeline::follow's object points: the depth pixels of `box` under the model's
// silhouette at `prev` (its surface points projected, each widened to cover the gaps between
// them) that lie within `gate` mm of the posed surface. The silhouette keeps the table around a
// standing object and the neighbours out, as the segmentation network does on a detection's crop.
std::vector<Eigen::Vector3f> points_near_pose(const float* depth, const geom::Intrinsics& K,
                                              const PreparedMesh* m, const geom::Pose& prev,
                                              const geom::Box2i& box, double gate) {
    const geom::Points& tree_pts = m->tree->points();
    const int bw = box.w, bh = box.h;
    std::vector<uint8_t> sil(size_t(bw) * size_t(bh), 0);
    const int64_t n_tree = tree_pts.rows();
    const int64_t stride = std::max<int64_t>(1, n_tree / 6000);
    // The tree samples the surface every ~2 mm (ModelKdTree::from_mesh); every stride-th one
    // lies ~2 sqrt(stride) mm from the next: each marks the pixels within that distance.
    const double spacing = 2.0 * std::sqrt(double(stride));
    for (int64_t i = 0; i < n_tree; i += stride) {
        const Eigen::Vector3d p = prev.R * tree_pts.row(i).transpose().cast<double>() + prev.t;
        if (p.z() <= 1.0) continue;
        const double u = K.fx * p.x() / p.z() + K.cx, v = K.fy * p.y() / p.z() + K.cy;
        const int rad = std::min(8, int(std::ceil(K.fx * spacing / p.z())));
        const int ui = int(std::floor(u)) - box.x, vi = int(std::floor(v)) - box.y;
        for (int y = std::max(0, vi - rad); y <= std::min(bh - 1, vi + rad); ++y)
            for (int x = std::max(0, ui - rad); x <= std::min(bw - 1, ui + rad); ++x)
                sil[size_t(y) * size_t(bw) + size_t(x)] = 1;
    }
    const Eigen::Matrix3f Rt = prev.R.transpose().cast<float>();
    const Eigen::Vector3f tf = prev.t.cast<float>();
    const float g2 = float(gate * gate);
    const bool use_grid = !m->grid.empty() && gate <= m->grid.margin_mm();
    // The ICP and the verification use a few hundred points: a pixel stride keeps ~4000 of the
    // silhouette's (a near object covers ~50000 pixels).
    int64_t n_sil = 0;
    for (const uint8_t v : sil) n_sil += v;
    const int step = std::max(1, int(std::sqrt(double(n_sil) / 4000.0)));
    std::vector<Eigen::Vector3f> keep;
    for (int y = 0; y < bh; y += step)
        for (int x = 0; x < bw; x += step) {
            if (!sil[size_t(y) * size_t(bw) + size_t(x)]) continue;
            const int px = box.x + x, py = box.y + y;
            const float z = depth[size_t(py) * size_t(K.width) + size_t(px)];
            if (!(z > 0.f) || !std::isfinite(z)) continue;
            const Eigen::Vector3f p(float((px - K.cx) * z / K.fx), float((py - K.cy) * z / K.fy), z);
            const Eigen::Vector3f xm = Rt * (p - tf);
            float dist2;
            if (use_grid) {
                const int row = m->grid.lookup(xm);
                if (row < 0) continue;
                dist2 = (xm - tree_pts.row(row).transpose()).squaredNorm();
            } else {
                const float dn = m->tree->nearest(xm);
                dist2 = dn * dn;
            }
            if (dist2 <= g2) keep.push_back(p);
        }
    return keep;
}

}  // namespace

Hypothesis FramePipeline::follow(const float* depth, const geom::Intrinsics& K,
                                 const Hypothesis& last, const TrackOptions& topt) const {
    const int obj = last.cand.obj_id;
    const PreparedMesh* m = mesh(obj);
    G2L_CHECK(m && opt_.refine != Refinement::none, "FramePipeline::follow: object ", obj,
              m ? ": the pipeline does not refine (tracking needs the refinement)"
                : " has no mesh (tracking needs it)");
    G2L_CHECK(depth != nullptr && K.width > 0 && K.height > 0,
              "FramePipeline::follow: need a depth image and its size, got ", K.width, " x ",
              K.height);
    G2L_CHECK(topt.search_frac >= 0 && topt.gate_frac >= 0 && topt.gate_min_mm >= 0 &&
                  topt.iterations >= 1 && topt.max_points >= 3,
              "FramePipeline::follow: track options out of range");
    const auto t0 = Clock::now();
    Hypothesis h;
    h.cand = last.cand;
    h.tracked = true;
    h.track_id = last.track_id;
    h.score = 0;
    PoseOutcome& o = h.outcome;
    o.obj_id = obj;
    const geom::Pose& prev = last.outcome.pose;
    const double d = m->info.diameter;
    // 1. The sphere the object can have moved within, and its image box (the projection of
    //    the sphere's bounding cube; the whole image when the camera is inside it).
    const Eigen::Vector3d c = prev.R * (m->info.min + 0.5 * m->info.size) + prev.t;
    const double r = (0.5 + topt.search_frac) * d;  // the box's margin for the motion
    int x0 = 0, y0 = 0, x1 = K.width, y1 = K.height;
    if (c.z() - r > 1.0) {
        double u0 = 1e30, v0 = 1e30, u1 = -1e30, v1 = -1e30;
        for (int k = 0; k < 8; ++k) {
            const Eigen::Vector3d q = c + r * Eigen::Vector3d(k & 1 ? 1 : -1, k & 2 ? 1 : -1,
                                                              k & 4 ? 1 : -1);
            const double u = K.fx * q.x() / q.z() + K.cx, v = K.fy * q.y() / q.z() + K.cy;
            u0 = std::min(u0, u), u1 = std::max(u1, u), v0 = std::min(v0, v), v1 = std::max(v1, v);
        }
        x0 = int(std::floor(std::max(-1.0, u0))), x1 = int(std::ceil(std::min(1e6, u1)));
        y0 = int(std::floor(std::max(-1.0, v0))), y1 = int(std::ceil(std::min(1e6, v1)));
    }
    o.box = geom::clip_box({x0, y0, x1 - x0, y1 - y0}, K.width, K.height);
    if (o.box.empty()) {
        o.status = PoseStatus::box_outside_image;
        o.ms_crop = ms_since(t0);
        return h;
    }
    // 2. The object's points: under the last pose's silhouette, near its surface.
    const double gate = std::max(topt.gate_min_mm, topt.gate_frac * d);
    const std::vector<Eigen::Vector3f> keep = points_near_pose(depth, K, m, prev, o.box, gate);
    o.num_crop_points = int(keep.size());
    o.crop.resize(int64_t(keep.size()), 3);
    for (size_t i = 0; i < keep.size(); ++i) o.crop.row(int64_t(i)) = keep[i].transpose();
    o.object_rows.resize(keep.size());
    for (size_t i = 0; i < keep.size(); ++i) o.object_rows[i] = int(i);
    o.num_object_points = int(keep.size());
    o.ms_crop = ms_since(t0);
    if (keep.size() < 10) {
        o.status = PoseStatus::too_few_object_points;
        return h;
    }
    // 3. A short ICP from the last pose: no turned starts, no clusters (the last pose was
    //    verified; the turns exist to undo a network's flips).
    const auto t1 = Clock::now();
    geom::RefineOptions ro;
    ro.hypotheses = false;
    ro.cluster_frac = 0;
    ro.support_plane = false;
    ro.coarse_iterations = 0;  // one start: no ranking pass
    ro.iterations = topt.iterations;
    ro.max_points = topt.max_points;
    ro.polish_iterations = 0;  // the grid's pairs lie within a cell of the exact ones
    const geom::DepthImage di{depth, K};
    const geom::RefineResult rr = geom::refine_pose(*m->tree, m->info, o.crop, prev, ro, &di,
                                                    &m->normals, m->grid.empty() ? nullptr : &m->grid);
    o.status = PoseStatus::ok;
    o.pose = rr.pose;
    o.fit_mm = rr.fit_mm;
    o.refined = true;
    // 4. Verified and scored like a detection's pose.
    h.check = verify(depth, K, o, tuning_.verify);
    h.verified = true;
    h.score = tuning_.score_model.probability(h.check, h.cand.det_score,
                                          h.cand.det_obj_id != h.cand.obj_id);
    o.ms_refine = ms_since(t1);
    return h;
}

}  // namespace g2l::infer
