// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <random>

#include "core/error.h"
#include "geom_test_util.h"
#include "geometry/crop.h"
#include "core/rng.h"
#include <cmath>

using namespace g2l::geom;
using Catch::Contains;

TEST_CASE("crop_indices keeps exactly the points inside the sphere / slab", "[geometry]") {
    Points p(6, 3);
    p << 0, 0, 1000,   // at the centre
        99, 0, 1000,   // inside sphere r=100
        100, 0, 1000,  // on the sphere: excluded (strict)
        0, 300, 1050,  // outside sphere, inside slab |dz| < 100
        0, 0, 1100,    // on the slab boundary: excluded
        0, 0, 901;     // inside both
    const Eigen::Vector3d c0(0, 0, 1000);
    CHECK(crop_indices(CropKind::sphere, p, c0, 100) == std::vector<int>{0, 1, 5});
    CHECK(crop_indices(CropKind::slab, p, c0, 100) == std::vector<int>{0, 1, 2, 3, 5});

    // Brute force on a large random cloud.
    std::mt19937 rng(4);
    Points r = test::random_points(50000, 500.0, rng);
    r.col(2).array() += 1000.f;
    const Eigen::Vector3d c(10, -20, 1100);
    std::vector<int> sphere, slab;
    for (int i = 0; i < r.rows(); ++i) {
        if ((r.row(i).cast<double>() - c.transpose()).norm() < 150) sphere.push_back(i);
        if (std::abs(double(r(i, 2)) - 1100) < 150) slab.push_back(i);
    }
    CHECK(crop_indices(CropKind::sphere, r, c, 150) == sphere);
    CHECK(crop_indices(CropKind::slab, r, c, 150) == slab);
    CHECK(!sphere.empty());
    CHECK(sphere.size() < slab.size());
    const Points kept = crop_points(CropKind::sphere, r, c, 150);
    REQUIRE(kept.rows() == int64_t(sphere.size()));
    CHECK(kept.row(0) == r.row(sphere.front()));
    CHECK(kept.row(kept.rows() - 1) == r.row(sphere.back()));

    const auto all = crop_indices(CropKind::frustum, p, c, 0);  // no radius needed
    REQUIRE(all.size() == 6);
    CHECK(all.back() == 5);
    REQUIRE_THROWS_WITH(parse_crop("cube", "sampling.crop"), Contains("'cube'") && Contains("sampling.crop"));
    CHECK(parse_crop(to_string(CropKind::slab), "x") == CropKind::slab);
    REQUIRE_THROWS_WITH(crop_indices(CropKind::sphere, p, c, 0), Contains("radius"));
    REQUIRE_THROWS_WITH(crop_indices(CropKind::slab, p, c, -1), Contains("radius") && Contains("-1"));
    REQUIRE_THROWS_WITH(crop_indices(CropKind::sphere, p, Eigen::Vector3d(NAN, 0, 0), 5), Contains("not finite"));
}

TEST_CASE("clip_box and box_centre: boxes partly or wholly outside, depth holes", "[geometry]") {
    CHECK(clip_box({-5, -5, 20, 20}, 10, 10).x == 0);
    CHECK(clip_box({-5, -5, 20, 20}, 10, 10).w == 10);
    CHECK(clip_box({8, 8, 20, 20}, 10, 10).w == 2);
    CHECK(clip_box({10, 0, 5, 5}, 10, 10).empty());
    CHECK(clip_box({0, 0, -3, 5}, 10, 10).empty());
    CHECK(clip_box({2147483000, 0, 2000, 5}, 10, 10).empty());  // no overflow
    Intrinsics K;
    K.fx = K.fy = 100;
    K.cx = K.cy = 5;
    // A 10 x 10 depth: a near object (500 mm) in the centre, the background at 900 mm.
    std::vector<float> d(100, 900.f);
    for (int v = 3; v < 7; ++v)
        for (int u = 3; u < 7; ++u) d[size_t(v * 10 + u)] = 500.f;
    Eigen::Vector3d c;
    REQUIRE(box_centre(d.data(), 10, 10, K, {0, 0, 10, 10}, &c));
    CHECK(c.z() == 500.0);  // the central third is the object
    // The median of the central third is lifted: the centre pixel nearest the box centre.
    CHECK(std::abs(c.x()) <= 0.5 * 500 / 100 * 2);
    // Holes (NaN, inf, 0, negative) are skipped; a box with none valid gives false.
    std::vector<float> holes(100, NAN);
    holes[0] = INFINITY, holes[1] = 0, holes[2] = -5;
    CHECK_FALSE(box_centre(holes.data(), 10, 10, K, {0, 0, 10, 10}, &c));
    holes[99] = 700;  // outside the central third, found by the whole-box pass
    REQUIRE(box_centre(holes.data(), 10, 10, K, {0, 0, 10, 10}, &c));
    CHECK(c.z() == 700.0);
    CHECK(c.x() == Approx((9 - 5) * 700.0 / 100));
    CHECK_FALSE(box_centre(d.data(), 10, 10, K, {20, 20, 5, 5}, &c));  // outside the image
    K.fx = 0;
    REQUIRE_THROWS_WITH(box_centre(d.data(), 10, 10, K, {0, 0, 10, 10}, &c), Contains("fx 0"));
    K.fx = 100;
    REQUIRE_THROWS_WITH(box_centre(nullptr, 10, 10, K, {0, 0, 10, 10}, &c), Contains("no depth"));
}

TEST_CASE("peak_centre: the peak lifted with the nearest valid depth in the box", "[geometry]") {
    const int w = 10, h = 8;
    std::vector<float> depth(size_t(w * h), 0.f);
    const Intrinsics K{100, 100, 5, 4, w, h};
    const Box2i box{2, 2, 6, 5};
    Eigen::Vector3d c;
    REQUIRE_FALSE(peak_centre(depth.data(), w, h, K, box, 4.5, 4.5, &c));  // no valid depth
    depth[size_t(4 * w + 4)] = 800.f;  // the peak pixel itself
    REQUIRE(peak_centre(depth.data(), w, h, K, box, 4.5, 4.5, &c));
    REQUIRE(c.z() == Approx(800));
    REQUIRE(c.x() == Approx((4.5 - 5) * 800 / 100));
    REQUIRE(c.y() == Approx((4.5 - 4) * 800 / 100));
    // A hole at the peak: the nearest valid pixel's depth (distance 1 beats the diagonal).
    depth[size_t(4 * w + 4)] = 0.f;
    depth[size_t(5 * w + 5)] = 700.f;  // diagonal, distance sqrt 2
    depth[size_t(4 * w + 5)] = 900.f;  // right, distance 1
    REQUIRE(peak_centre(depth.data(), w, h, K, box, 4.2, 4.7, &c));
    REQUIRE(c.z() == Approx(900));
    REQUIRE(c.x() == Approx((4.2 - 5) * 900 / 100));
    // Valid depth outside the box is never used; NaN depth is invalid.
    std::vector<float> out(size_t(w * h), 0.f);
    out[0] = 500.f;
    out[size_t(3 * w + 3)] = std::nanf("");
    REQUIRE_FALSE(peak_centre(out.data(), w, h, K, box, 4.0, 4.0, &c));
    REQUIRE_FALSE(peak_centre(depth.data(), w, h, K, Box2i{20, 20, 5, 5}, 4.0, 4.0, &c));
    REQUIRE_FALSE(peak_centre(depth.data(), w, h, K, box, std::nan(""), 4.0, &c));
    REQUIRE_THROWS_WITH(peak_centre(nullptr, w, h, K, box, 4, 4, &c), Catch::Contains("no depth image"));
    REQUIRE_THROWS_WITH(peak_centre(depth.data(), w, h, Intrinsics{0, 100, 5, 4, w, h}, box, 4, 4, &c),
                        Catch::Contains("focal lengths"));
}
