// SPDX-License-Identifier: MIT
// g2l_eval's grouping and averaging on a hand-made set of per-instance results: every figure of
// the report is checked against values computed by hand.
#include <catch2/catch.hpp>
#include <limits>

#include "geometry/metrics.h"
#include "eval/evaluate.h"
#include "data/bop.h"
#include "nn/models/g2l_io.h"
#include "testing.h"

using namespace g2l;
using namespace g2l::eval;

TEST_CASE("aggregate: per-object and average figures of a hand-made case", "[train][eval]") {
    const std::map<int, ObjectMeta> meta = {{1, {"box", 100.0, false, 2}},
                                            {2, {"can", 200.0, true, 24}}};
    auto found = [](int id, double add, double adds, double addsym, double rot, double rot_sym,
                    double trans) {
        InstanceResult r;
        r.obj_id = id;
        r.found = true;
        r.add_mm = add, r.adds_mm = adds, r.addsym_mm = addsym;
        r.rot_deg = rot, r.rot_sym_deg = rot_sym, r.trans_mm = trans;
        return r;
    };
    InstanceResult miss;
    miss.obj_id = 1;
    const std::vector<InstanceResult> res = {
        found(1, 5, 3, 5, 2, 2, 4),        // right by every measure (10 mm threshold)
        found(1, 50, 8, 9, 180, 3, 6),     // off by a symmetry: wrong for ADD, right modulo it
        miss,                              // no pose
        found(2, 30, 15, 30, 90, 90, 10),  // ADD-S right (20 mm threshold), ADD-sym wrong
    };
    const EvalReport r = aggregate(res, meta);
    REQUIRE(r.objects.size() == 2);
    REQUIRE(r.instances == 4);
    const ObjectScores& a = r.objects[0];
    const ObjectScores& b = r.objects[1];
    CHECK(a.obj_id == 1);
    CHECK(a.name == "box");
    CHECK(a.count == 3);
    CHECK(a.misses == 1);
    CHECK(a.acc_add_s_10 == Approx(100.0 / 3));   // not symmetric: ADD, 1 of 3
    CHECK(a.acc_adds_all_10 == Approx(200.0 / 3));
    CHECK(a.acc_addsym_10 == Approx(200.0 / 3));
    CHECK(a.rot_err_sym_deg_median == Approx(3.0));  // median of 2, 3 and 180 (the miss)
    CHECK(a.median_trans_err_mm == Approx(5.0));
    CHECK(a.mean_rot_err_deg == Approx(91.0));       // found poses only
    CHECK(a.mean_trans_err_mm == Approx(5.0));
    CHECK(a.num_symmetries == 2);
    const double inf = std::numeric_limits<double>::infinity();
    CHECK(a.auc_adds == Approx(geom::vocap_auc({0.003, 0.008, inf})));
    CHECK(a.auc_add == Approx(geom::vocap_auc({0.005, 0.050, inf})));
    CHECK(b.obj_id == 2);
    CHECK(b.symmetric);
    CHECK(b.acc_add_s_10 == Approx(100.0));  // symmetric: ADD-S
    CHECK(b.acc_adds_all_10 == Approx(100.0));
    CHECK(b.acc_addsym_10 == Approx(0.0));
    CHECK(b.rot_err_sym_deg_median == Approx(90.0));
    const ObjectScores& avg = r.average;
    CHECK(avg.count == 4);
    CHECK(avg.misses == 1);
    CHECK(avg.acc_add_s_10 == Approx((100.0 / 3 + 100.0) / 2));  // mean over objects
    CHECK(avg.acc_adds_all_10 == Approx((200.0 / 3 + 100.0) / 2));
    CHECK(avg.acc_addsym_10 == Approx((200.0 / 3 + 0.0) / 2));
    CHECK(avg.rot_err_sym_deg_median == Approx((3.0 + 90.0) / 2));
    CHECK(avg.auc_adds == Approx((a.auc_adds + b.auc_adds) / 2));
    CHECK(avg.mean_rot_err_deg == Approx((2.0 + 180.0 + 90.0) / 3));  // mean over found instances
    CHECK(avg.mean_trans_err_mm == Approx((4.0 + 6.0 + 10.0) / 3));

    // The table names the refinement (here none), and an object whose every instance was
    // missed shows no mean errors ("-"), never a 0.00 that reads as perfect.
    InstanceResult miss2;
    miss2.obj_id = 2;
    const EvalReport rm = aggregate({res[0], miss2, miss2}, meta);
    const std::string md = report_markdown(rm);
    CHECK_THAT(md, Catch::Contains("Depth refinement (none): none, the networks' poses"));
    CHECK_THAT(md, Catch::Contains("| 2 | 0.0 | 0.0 | 0.0 | 180.0 | 0.0 | 0.0 | - | - | - |"));
    CHECK_THAT(md, Catch::Contains("| 1 | 0 | 100.0 |"));  // object 1: one instance, found
    // The columns say how a miss counts.
    CHECK_THAT(md, Catch::Contains("rot err sym median (deg; miss = 180)") &&
                       Catch::Contains("rot err (deg; found)") &&
                       Catch::Contains("counts as a wrong pose in the accuracies"));
}

TEST_CASE("aggregate: instances of unknown objects or bad diameters throw", "[train][eval]") {
    InstanceResult r;
    r.obj_id = 7;
    CHECK_THROWS_WITH(aggregate({r}, {{1, {"x", 10.0, false, 1}}}), Catch::Contains("obj_id 7"));
    CHECK_THROWS_WITH(aggregate({r}, {{7, {"x", 0.0, false, 1}}}), Catch::Contains("diameter"));
    const EvalReport empty = aggregate({}, {});
    CHECK(empty.objects.empty());
    CHECK(empty.instances == 0);
}

TEST_CASE("evaluate_instances: detector boxes take the hypotheses road and are matched as BOP "
          "does, undetected instances are misses", "[train][eval]") {
    const std::string root = testing::fixture_dir() + "/ycbv_mini";
    const data::Dataset ds = data::open_bop(root, "train_real", {});
    nn::LoadedModel m = nn::load_model(std::string(G2L_SOURCE_DIR) + "/models/ycbv_sim2real.g2l");
    EvalOptions eo;  // the pipeline's defaults: the model's point counts, turns
    const g2l::infer::PipelineModel pm = g2l::infer::PipelineModel::of(m);
    std::vector<InstanceResult> gt, det, some;
    const EvalReport rg = evaluate_instances(pm, ds, eo, &gt);
    REQUIRE(gt.size() == 4);
    CHECK(rg.average.pose_precision == -1);  // GT boxes report no precision
    std::vector<data::Detection> dets;
    for (const auto& f : ds.frames())
        for (const auto& inst : f.instances)
            dets.push_back({std::stoi(f.scene), f.image_id, inst.obj_id, double(inst.bbox_visib.x),
                            double(inst.bbox_visib.y), double(inst.bbox_visib.w),
                            double(inst.bbox_visib.h), 0.5, 0.01});
    // A worse-scoring box beside each one: posed and verified too, it must not displace the
    // right pose (ranked below it, or rejected, or reported as a false positive).
    const size_t n = dets.size();
    for (size_t i = 0; i < n; ++i) {
        data::Detection d = dets[i];
        d.x += 100;
        d.score = 0.2;
        dets.push_back(d);
    }
    eo.detections = &dets;
    std::vector<HypothesisRecord> hyps;
    const EvalReport rd = evaluate_instances(pm, ds, eo, &det, &hyps);
    std::vector<const InstanceResult*> matched, fps;
    for (const auto& r : det) (r.false_positive ? fps : matched).push_back(&r);
    REQUIRE(matched.size() == gt.size());
    for (size_t i = 0; i < gt.size(); ++i) {
        INFO("instance " << i << " object " << gt[i].obj_id);
        const InstanceResult& r = *matched[i];
        CHECK(r.obj_id == gt[i].obj_id);
        CHECK(r.found == gt[i].found);
        CHECK(r.status == "ok");
        CHECK(r.reported);
        CHECK(r.det_score == 0.5);
        // The same box gives the same crop, networks and refinement: the same pose.
        CHECK(r.add_mm == gt[i].add_mm);
        CHECK(r.est.t == gt[i].est.t);
        CHECK(r.right);
        CHECK(r.box_hit);
        CHECK(r.verify_score >= 0.0);
        CHECK(r.score >= 0.0);
        CHECK(r.score > 0.5);
        // The detection was the GT box; the pose is reported with the box of its surface the
        // depth explains (the inliers' pixels: inside the mask's box, short of its edges where
        // the sensor has no depth).
        CHECK(r.det_iou_detector == Approx(1.0));
        CHECK(r.detector_box.w > 0);
        CHECK(r.det_iou > 0.75);
        CHECK(r.det_iou < 1.0);
    }
    for (const InstanceResult* r : fps) {
        CHECK(r->reported);
        CHECK(r->inst_index == -1);
        CHECK_FALSE(r->right);
        for (const InstanceResult* t : matched)  // every right pose outranks a false positive
            if (t->scene == r->scene && t->image_id == r->image_id) CHECK(t->score > r->score);
    }
    CHECK(rd.instances == 4);
    CHECK(rd.average.count == 4);
    CHECK(rd.average.reported == int(det.size()));
    CHECK(rd.average.false_positives == int(fps.size()));
    CHECK(rd.average.pose_precision == Approx(100.0 * 4 / double(det.size())));
    CHECK(rd.average.det_recall_50 == Approx(100.0));
    CHECK(rd.average.detector_recall_50 == Approx(100.0));
    CHECK(rd.average.auc_adds == rg.average.auc_adds);
    CHECK(hyps.size() == dets.size());  // every candidate is a hypothesis with a verdict
    int accepted = 0;
    for (const auto& h : hyps) accepted += h.verdict == "accepted";
    CHECK(accepted == int(det.size()));
    // Thresholding the score at the curve's points gives its precision and recall.
    const auto curve = pr_curve(det);
    REQUIRE(!curve.empty());
    CHECK(curve.back().precision == Approx(rd.average.pose_precision));
    CHECK(curve.back().recall == Approx(100.0));
    CHECK(curve.front().precision == Approx(100.0));
    // Only image 1's detections: image 11's instances are misses.
    std::vector<data::Detection> one;
    for (const auto& d : dets)
        if (d.image_id == 1) one.push_back(d);
    eo.detections = &one;
    const EvalReport rs = evaluate_instances(pm, ds, eo, &some);
    int misses = 0, counted = 0;
    for (const auto& r : some) {
        counted += !r.false_positive;
        misses += r.status == "no detection" && !r.found;
    }
    CHECK(counted == 4);
    CHECK(misses == 2);
    CHECK(rs.average.misses == 2);
    // Detections must say which image they belong to.
    std::vector<data::Detection> anon = {dets[0]};
    anon[0].scene_id = -1;
    eo.detections = &anon;
    REQUIRE_THROWS_WITH(evaluate_instances(pm, ds, eo, nullptr),
                        Catch::Contains("no scene_id / image_id"));
}

TEST_CASE("pr_curve and aggregate: false positives lower the precision only, fit_score_model "
          "learns a separating score", "[train][eval]") {
    std::map<int, ObjectMeta> meta{{1, {"a", 100.0, false, 1}}};
    std::vector<InstanceResult> rs;
    auto inst = [](double score, bool right, bool fp, bool found) {
        InstanceResult r;
        r.obj_id = 1;
        r.found = found;
        r.reported = found;
        r.false_positive = fp;
        r.right = right;
        r.box_hit = right;
        r.score = score;
        r.det_iou = fp ? -1 : (found ? 0.9 : 0.0);
        // The detector's own box is loose around the right poses' instances.
        r.det_iou_detector = fp ? -1 : (found && !right ? 0.6 : 0.3);
        r.adds_mm = r.add_mm = r.addsym_mm = right ? 1.0 : 50.0;
        return r;
    };
    rs.push_back(inst(0.9, true, false, true));
    rs.push_back(inst(0.8, false, true, true));   // a false positive
    rs.push_back(inst(0.7, true, false, true));
    rs.push_back(inst(0.6, false, false, true));  // a wrong pose of an instance
    rs.push_back(inst(0.0, false, false, false)); // a miss
    const EvalReport r = aggregate(rs, meta);
    CHECK(r.instances == 4);
    CHECK(r.average.count == 4);
    CHECK(r.average.misses == 1);
    CHECK(r.average.reported == 4);
    CHECK(r.average.false_positives == 1);
    CHECK(r.average.pose_precision == Approx(50.0));
    CHECK(r.average.det_precision_50 == Approx(50.0));
    CHECK(r.average.det_recall_50 == Approx(75.0));       // 3 reported boxes of 4 instances
    CHECK(r.average.detector_recall_50 == Approx(25.0));  // the wrong pose's detection only
    CHECK(r.average.acc_adds_all_10 == Approx(50.0));  // 2 right of 4 instances
    const auto c = pr_curve(rs);
    REQUIRE(c.size() == 4);
    CHECK(c[0].threshold == 0.9);
    CHECK(c[0].precision == Approx(100.0));
    CHECK(c[0].recall == Approx(25.0));
    CHECK(c[1].precision == Approx(50.0));
    CHECK(c[2].precision == Approx(200.0 / 3.0));
    CHECK(c[2].recall == Approx(50.0));
    CHECK(c[3].precision == Approx(50.0));
    CHECK(pr_curve({}).empty());

    // Right poses have a high explained share, wrong ones a low one, with overlap: the fitted
    // model ranks them by it (a positive weight) and predicts well above / below one half.
    std::vector<HypothesisRecord> hs;
    for (int i = 0; i < 60; ++i) {
        HypothesisRecord h;
        h.posed = h.verified = true;
        h.pose_right = i % 2 == 0;
        const double e = h.pose_right ? 0.6 + 0.006 * i : 0.1 + 0.008 * i;
        h.features = {{1.0, e, 0.1, 0.1, 0.5, 0.5 * e, std::log(0.5), 0.0}};
        hs.push_back(h);
    }
    const g2l::infer::ScoreModel sm = fit_score_model(hs);
    CHECK(sm.w[1] + 0.5 * sm.w[5] > 0);
    geom::Verification hi, lo;
    hi.explained = 0.95, hi.score = 0.5 * 0.95, hi.seg_agree = 0.5, hi.violation = hi.occlusion = 0.1;
    lo.explained = 0.15, lo.score = 0.5 * 0.15, lo.seg_agree = 0.5, lo.violation = lo.occlusion = 0.1;
    CHECK(sm.probability(hi, 0.5, false) > 0.8);
    CHECK(sm.probability(lo, 0.5, false) < 0.2);
    // Too few, or one label only: a clear error.
    std::vector<HypothesisRecord> few(hs.begin(), hs.begin() + 10);
    CHECK_THROWS_WITH(fit_score_model(few), Catch::Contains("at least 20 verified"));
    std::vector<HypothesisRecord> same = hs;
    for (auto& h : same) h.pose_right = true;
    CHECK_THROWS_WITH(fit_score_model(same), Catch::Contains("right and wrong"));
}
