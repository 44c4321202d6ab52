// SPDX-License-Identifier: MIT
// g2l_eval's grouping and averaging on a hand-made set of per-instance results: every figure of
// the report is checked against values computed by hand.
#include <catch2/catch.hpp>
#include <limits>

#include "geometry/metrics.h"
#include "train/evaluate.h"

using namespace g2l;
using namespace g2l::train;

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
