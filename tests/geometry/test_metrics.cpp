// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>

#include "core/error.h"
#include "geom_test_util.h"
#include "geometry/metrics.h"

using namespace g2l::geom;
using Catch::Contains;

namespace {

const double kInf = std::numeric_limits<double>::infinity();

/// Points on a cylinder of radius 30 and height 80 around z (symmetric under z rotations by
/// multiples of 10 degrees: 36 points per ring).
Points cylinder() {
    Points p(36 * 9, 3);
    const double pi = std::acos(-1.0);
    int r = 0;
    for (int h = 0; h < 9; ++h) {
        for (int k = 0; k < 36; ++k) {
            const double a = 2 * pi * k / 36;
            p.row(r++) << float(30 * std::cos(a)), float(30 * std::sin(a)), float(-40 + 10 * h);
        }
    }
    return p;
}

/// Brute-force ADD-S: for each GT-posed point, min distance to the estimated-posed points.
double brute_adds(const Pose& e, const Pose& g, const Points& pts) {
    double sum = 0;
    for (int i = 0; i < pts.rows(); ++i) {
        const Eigen::Vector3d pg = g.R * pts.row(i).cast<double>().transpose() + g.t;
        double best = kInf;
        for (int j = 0; j < pts.rows(); ++j) {
            const Eigen::Vector3d pe = e.R * pts.row(j).cast<double>().transpose() + e.t;
            best = std::min(best, (pg - pe).norm());
        }
        sum += best;
    }
    return sum / pts.rows();
}

}  // namespace

TEST_CASE("ADD and ADD-S are zero for identical poses and |offset| for a translation",
          "[geometry]") {
    std::mt19937 rng(9);
    const Points pts = test::random_points(500, 60.0, rng);
    Pose gt;
    gt.R = test::random_rotation(rng);
    gt.t = Eigen::Vector3d(10, 20, 900);
    CHECK(add(gt, gt, pts) == Approx(0.0).margin(1e-12));
    CHECK(adds(gt, gt, pts) == Approx(0.0).margin(1e-9));
    Pose est = gt;
    est.t += Eigen::Vector3d(3, -4, 12);  // |offset| = 13
    CHECK(add(est, gt, pts) == Approx(13.0).epsilon(1e-12));
    CHECK(adds(est, gt, pts) <= 13.0 + 1e-9);
    CHECK(translation_error(est.t, gt.t) == Approx(13.0));
    CHECK(rotation_error_deg(est.R, gt.R) == Approx(0.0).margin(1e-5));
}

TEST_CASE("ADD-S matches brute force and is ~0 under a symmetry while ADD is large",
          "[geometry]") {
    const Points cyl = cylinder();
    Pose gt;
    gt.R = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    gt.t = Eigen::Vector3d(0, 0, 1000);
    Pose est = gt;
    const double pi = std::acos(-1.0);
    est.R = gt.R * Eigen::AngleAxisd(pi / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    CHECK(adds(est, gt, cyl) < 1e-4);
    // Rotating a radius-30 ring by 90 degrees moves each point by 30 * sqrt(2).
    CHECK(add(est, gt, cyl) == Approx(30.0 * std::sqrt(2.0)).epsilon(1e-6));
    CHECK(rotation_error_deg(est.R, gt.R) == Approx(90.0).epsilon(1e-9));

    std::mt19937 rng(12);
    const Points pts = test::random_points(300, 40.0, rng);
    for (int trial = 0; trial < 3; ++trial) {
        Pose e, g;
        e.R = test::random_rotation(rng);
        g.R = test::random_rotation(rng);
        e.t = Eigen::Vector3d(trial, 5, 800);
        g.t = Eigen::Vector3d(0, 0, 810);
        CHECK(adds(e, g, pts) == Approx(brute_adds(e, g, pts)).epsilon(1e-6));
        CHECK(adds(e, g, pts) <= add(e, g, pts));
    }
}

TEST_CASE("rotation_error_deg, translation_error and correct_at", "[geometry]") {
    const Eigen::Matrix3d R30 =
        Eigen::AngleAxisd(30.0 * std::acos(-1.0) / 180, Eigen::Vector3d(0, 1, 1).normalized())
            .toRotationMatrix();
    CHECK(rotation_error_deg(R30, Eigen::Matrix3d::Identity()) == Approx(30.0).epsilon(1e-9));
    CHECK(rotation_error_deg(-Eigen::Matrix3d::Identity() * R30 * -1, R30) ==
          Approx(0.0).margin(1e-5));
    CHECK(translation_error(Eigen::Vector3d(1, 2, 2), Eigen::Vector3d(0, 0, 0)) == Approx(3.0));
    CHECK(correct_at(10.0, 102.0));
    CHECK_FALSE(correct_at(10.3, 102.0));
    CHECK_FALSE(correct_at(10.0, 40.0, 0.25));  // strict: 10 == 0.25 * 40 exactly
    CHECK(correct_at(9.999, 40.0, 0.25));
    CHECK(correct_at(19.0, 102.0, 0.2));
    CHECK_FALSE(correct_at(kInf, 102.0));  // a miss counts as a failure
    REQUIRE_THROWS_WITH(correct_at(std::nan(""), 102.0), Contains("NaN"));
    REQUIRE_THROWS_WITH(correct_at(1.0, 0.0), Contains("diameter") && Contains("got 0"));
    Pose p;
    REQUIRE_THROWS_WITH(add(p, p, Points(0, 3)), Contains("no model points"));
    p.t.x() = std::nan("");
    REQUIRE_THROWS_WITH(adds(p, Pose(), Points::Zero(3, 3)), Contains("estimated pose"));
}

TEST_CASE("vocap_auc reproduces the YCB-Video toolbox on hand-computed lists", "[geometry]") {
    // {0.01, 0.02, inf}: n = 3, acc 1/3, 2/3; AP = .01/3 + .01*2/3 + .08*2/3 = 0.19/3 -> x10 x100.
    CHECK(vocap_auc({0.01, 0.02, kInf}) == Approx(100 * 10 * 0.19 / 3).epsilon(1e-12));
    CHECK(vocap_auc({kInf, kInf}) == 0.0);
    CHECK(vocap_auc({0.0, 0.0, 0.0, 0.0}) == Approx(100.0).epsilon(1e-12));
    // Order does not matter; > 0.1 behaves like a miss (still counted in n).
    CHECK(vocap_auc({0.2, 0.02, 0.01}) == Approx(vocap_auc({0.01, 0.02, kInf})));
    // Right-endpoint rule: a single d = 0.05 gives accuracy 1 over [0, 0.05] too (mrec
    // [0 .05 .1], mpre [0 1 1]) -> 100; {0.05, inf}: mpre [0 .5 .5] -> 50.
    CHECK(vocap_auc({0.05}) == Approx(100.0).epsilon(1e-12));
    CHECK(vocap_auc({0.05, kInf}) == Approx(50.0).epsilon(1e-12));
    // Exactly 0.1 is kept (only D > 0.1 is cut): mrec [0 .1 .1] -> 0.1 * 1 -> 100.
    CHECK(vocap_auc({0.1}) == Approx(100.0).epsilon(1e-12));
    CHECK(vocap_auc({0.1000001}) == 0.0);
    // Duplicates follow the MATLAB index rule: {0.01, 0.01}: mrec [0 .01 .01 .1],
    // mpre [0 .5 1 1] -> changes at i = 2 and 4 -> .01*.5 + .09*1 = .095 -> 95.
    CHECK(vocap_auc({0.01, 0.01}) == Approx(95.0).epsilon(1e-12));
    // A custom max threshold: {0.01, 0.03, inf} with max 0.02 -> 0.03 is cut;
    // mrec [0 .01 .02], mpre [0 1/3 1/3] -> 0.02 / 3 / 0.02 -> 33.33.
    CHECK(vocap_auc({0.01, 0.03, kInf}, 0.02) == Approx(100.0 / 3).epsilon(1e-12));
    // A uniform spread approaches the mean-distance formula 1 - E[d]/0.1 for large n.
    std::vector<double> many;
    for (int i = 0; i < 1000; ++i) many.push_back(0.1 * (i + 0.5) / 1000);
    CHECK(vocap_auc(many) == Approx(50.0).margin(0.1));

    REQUIRE_THROWS_WITH(vocap_auc({}), Contains("empty"));
    REQUIRE_THROWS_WITH(vocap_auc({0.01, std::nan("")}), Contains("distance 1"));
    REQUIRE_THROWS_WITH(vocap_auc({0.01, -0.5}), Contains("got -0.5"));
    REQUIRE_THROWS_WITH(vocap_auc({0.01}, 0.0), Contains("max_threshold_m"));
}
