// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <random>

#include "core/error.h"
#include "geom_test_util.h"
#include "geometry/crop.h"

using namespace g2l::geom;
using Catch::Contains;

TEST_CASE("crop_sphere and crop_slab keep exactly the points inside", "[geometry]") {
    Points p(6, 3);
    p << 0, 0, 1000,   // at the centre
        99, 0, 1000,   // inside sphere r=100
        100, 0, 1000,  // on the sphere: excluded (strict)
        0, 300, 1050,  // outside sphere, inside slab |dz| < 100
        0, 0, 1100,    // on the slab boundary: excluded
        0, 0, 901;     // inside both
    CHECK(crop_sphere(p, Eigen::Vector3d(0, 0, 1000), 100) == std::vector<int>{0, 1, 5});
    CHECK(crop_slab(p, 1000, 100) == std::vector<int>{0, 1, 2, 3, 5});

    // Brute force on a large random cloud (exercises the parallel mask path).
    std::mt19937 rng(4);
    Points r = test::random_points(50000, 500.0, rng);
    r.col(2).array() += 1000.f;
    const Eigen::Vector3d c(10, -20, 1100);
    const std::vector<int> s = crop_sphere(r, c, 150);
    std::vector<int> expect;
    for (int i = 0; i < r.rows(); ++i) {
        if ((r.row(i).cast<double>() - c.transpose()).norm() < 150) expect.push_back(i);
    }
    CHECK(s == expect);
    CHECK(!s.empty());

    REQUIRE_THROWS_WITH(crop_sphere(p, c, -1), Contains("radius") && Contains("-1"));
    REQUIRE_THROWS_WITH(crop_slab(p, 1000, 0), Contains("half_depth") && Contains("got 0"));
}

TEST_CASE("crop_slab_adaptive widens the slab like chooselimt_test", "[geometry]") {
    // 1200 points at z = 1000 +- 50 (inside 1 x dia = 100), 10 points at z <= 20 (dropped).
    auto make = [](int near, int mid, int far) {
        Points p(near + mid + far + 10, 3);
        int r = 0;
        for (int i = 0; i < near; ++i) p.row(r++) = Eigen::RowVector3f(0, 0, 950.f + i % 100);
        for (int i = 0; i < mid; ++i) p.row(r++) = Eigen::RowVector3f(0, 0, 1150.f);   // dz 150
        for (int i = 0; i < far; ++i) p.row(r++) = Eigen::RowVector3f(0, 0, 1250.f);   // dz 250
        for (int i = 0; i < 10; ++i) p.row(r++) = Eigen::RowVector3f(0, 0, 15.f);
        return p;
    };
    int f = 0;
    CHECK(crop_slab_adaptive(make(1200, 5, 5), 1000, 100, {}, &f).size() == 1200);
    CHECK(f == 1);
    // 900 at 1 x dia -> 2 x dia: 900 + 50 = 950 >= 500 -> stays at 2.
    CHECK(crop_slab_adaptive(make(900, 50, 7), 1000, 100, {}, &f).size() == 950);
    CHECK(f == 2);
    // 300 + 100 = 400 < 500 at 2 x dia -> 3 x dia: 300 + 100 + 20.
    CHECK(crop_slab_adaptive(make(300, 100, 20), 1000, 100, {}, &f).size() == 420);
    CHECK(f == 3);
    // The z > min_z filter: a centre near 0 with a huge diameter still drops z <= 20.
    const auto low = crop_slab_adaptive(make(10, 0, 0), 10, 5000, {}, &f);
    CHECK(low.size() == 10);
    // Custom thresholds.
    AdaptiveSlabParams prm;
    prm.min_points_2dia = 5;
    CHECK(crop_slab_adaptive(make(10, 3, 3), 1000, 100, prm, &f).size() == 10);
    CHECK(f == 1);
    REQUIRE_THROWS_WITH(crop_slab_adaptive(make(1, 1, 1), 1000, 0), Contains("diameter"));
}
