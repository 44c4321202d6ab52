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

TEST_CASE("evaluate_instances: detector boxes equal to the GT boxes give the GT-box results, "
          "undetected instances are misses", "[train][eval]") {
    const std::string root = testing::fixture_dir() + "/ycbv_mini";
    const data::Dataset ds = data::open_bop(root, "train_real", {});
    nn::LoadedModel m = nn::load_model(std::string(G2L_SOURCE_DIR) + "/models/ycbv_sim2real.g2l");
    EvalOptions eo;
    eo.crop = g2l::infer::parse_crop(m.crop, "crop");
    eo.radius_scale = m.radius_scale;
    eo.crop_points = m.points;
    eo.max_object_points = m.seg_points;
    std::vector<InstanceResult> gt, det, some;
    const EvalReport rg = evaluate_instances(*m.net, ds, m.class_of, m.keypoints, eo, &gt);
    REQUIRE(gt.size() == 4);
    std::vector<data::Detection> dets;
    for (const auto& f : ds.frames())
        for (const auto& inst : f.instances)
            dets.push_back({std::stoi(f.scene), f.image_id, inst.obj_id, double(inst.bbox_visib.x),
                            double(inst.bbox_visib.y), double(inst.bbox_visib.w),
                            double(inst.bbox_visib.h), 0.5, 0.01});
    // A worse-scoring wrong box for each: the best-scoring detection is the one used.
    const size_t n = dets.size();
    for (size_t i = 0; i < n; ++i) {
        data::Detection d = dets[i];
        d.x += 100;
        d.score = 0.1;
        dets.push_back(d);
    }
    eo.detections = &dets;
    const EvalReport rd = evaluate_instances(*m.net, ds, m.class_of, m.keypoints, eo, &det);
    REQUIRE(det.size() == gt.size());
    for (size_t i = 0; i < gt.size(); ++i) {
        CHECK(det[i].found == gt[i].found);
        CHECK(det[i].add_mm == gt[i].add_mm);
        CHECK(det[i].score == 0.5);
        CHECK(gt[i].score == 1.0);
        CHECK(det[i].status == "ok");
        CHECK(det[i].est.t == gt[i].est.t);
    }
    CHECK(rd.average.auc_adds == rg.average.auc_adds);
    // Only image 1's detections: image 11's instances are misses.
    std::vector<data::Detection> one;
    for (const auto& d : dets)
        if (d.image_id == 1) one.push_back(d);
    eo.detections = &one;
    const EvalReport rs = evaluate_instances(*m.net, ds, m.class_of, m.keypoints, eo, &some);
    REQUIRE(some.size() == 4);
    int misses = 0;
    for (const auto& r : some) misses += r.status == "no detection" && !r.found;
    CHECK(misses == 2);
    CHECK(rs.average.misses == 2);
    // Detections must say which image they belong to.
    std::vector<data::Detection> anon = {dets[0]};
    anon[0].scene_id = -1;
    eo.detections = &anon;
    REQUIRE_THROWS_WITH(evaluate_instances(*m.net, ds, m.class_of, m.keypoints, eo, nullptr),
                        Catch::Contains("no scene_id / image_id"));
}
