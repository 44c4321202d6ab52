// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <limits>
#include <random>

#include "core/error.h"
#include "geom_test_util.h"
#include "geometry/keypoints.h"

using namespace g2l::geom;
using Catch::Contains;

TEST_CASE("bbox_corners follows the G2L-Net corner order", "[geometry]") {
    ModelInfo info;
    info.min = Eigen::Vector3d(-1, -2, -3);
    info.size = Eigen::Vector3d(10, 20, 30);  // max = (9, 18, 27)
    const Points c = bbox_corners(info);
    REQUIRE(c.rows() == 8);
    Points expected(8, 3);
    expected << -1, -2, 27,   // 0 (minx, miny, maxz)
        -1, 18, 27,           // 1 (minx, maxy, maxz)
        -1, 18, -3,           // 2 (minx, maxy, minz)
        -1, -2, -3,           // 3 (minx, miny, minz)
        9, -2, -3,            // 4 (maxx, miny, minz)
        9, -2, 27,            // 5 (maxx, miny, maxz)
        9, 18, -3,            // 6 (maxx, maxy, minz)
        9, 18, 27;            // 7 (maxx, maxy, maxz)
    CHECK(c == expected);
    info.size.y() = -1;
    REQUIRE_THROWS_WITH(bbox_corners(info), Contains("size must be >= 0"));
}

TEST_CASE("farthest_point_sampling picks the greedy farthest points deterministically",
          "[geometry]") {
    // Points on a line: 0, 1, 2, 10, -7. Centroid 1.2 -> farthest is 10 (8.8 vs 8.2 for -7),
    // then -7 (17 away), then the point farthest from both: 0 (10 from 10, 7 from -7), 1 (9, 8),
    // 2 (8, 9): min-distances 7, 8, 8 -> tie between 1 and 2 -> lowest index, 1.
    Points p(5, 3);
    p << 0, 0, 0, 1, 0, 0, 2, 0, 0, 10, 0, 0, -7, 0, 0;
    const Points s = farthest_point_sampling(p, 3);
    REQUIRE(s.rows() == 3);
    CHECK(s(0, 0) == 10.f);
    CHECK(s(1, 0) == -7.f);
    CHECK(s(2, 0) == 1.f);
    const Points s2 = farthest_point_sampling(p, 2, 1);
    CHECK(s2(0, 0) == 1.f);
    CHECK(s2(1, 0) == 10.f);
    // k = N returns every point once.
    const Points all = farthest_point_sampling(p, 5);
    CHECK(all.col(0).sum() == Approx(6.0));

    // Brute-force check of the greedy max-min property on a random cloud.
    std::mt19937 rng(3);
    const Points r = test::random_points(400, 30.0, rng);
    const Points f = farthest_point_sampling(r, 8);
    for (int k = 1; k < 8; ++k) {
        auto min_dist = [&](const Eigen::RowVector3f& q) {
            double m = std::numeric_limits<double>::infinity();
            for (int j = 0; j < k; ++j) m = std::min(m, double((q - f.row(j)).squaredNorm()));
            return m;
        };
        double best = 0;
        for (int i = 0; i < r.rows(); ++i) best = std::max(best, min_dist(r.row(i)));
        CHECK(min_dist(f.row(k)) == Approx(best));
    }

    REQUIRE_THROWS_WITH(farthest_point_sampling(p, 6), Contains("k must be in [1, 5], got 6"));
    REQUIRE_THROWS_WITH(farthest_point_sampling(p, 0), Contains("got 0"));
    REQUIRE_THROWS_WITH(farthest_point_sampling(p, 2, 5), Contains("start"));
}

TEST_CASE("keypoints dispatches on kind and rejects unknown kinds", "[geometry]") {
    std::mt19937 rng(5);
    Mesh mesh;
    mesh.vertices = test::random_points(200, 10.0, rng);
    ModelInfo info;
    info.min = Eigen::Vector3d(-10, -10, -10);
    info.size = Eigen::Vector3d(20, 20, 20);
    CHECK(keypoints(mesh, info, "bbx8") == bbox_corners(info));
    CHECK(keypoints(mesh, info, "fps4").rows() == 4);
    CHECK(keypoints(mesh, info, "fps8") == farthest_point_sampling(mesh.vertices, 8));
    CHECK(keypoints(mesh.vertices, info, "fps12").rows() == 12);
    REQUIRE_THROWS_WITH(keypoints(mesh, info, "fps9"), Contains("'fps9'"));
    // The count each kind gives, without a model (what a config's network is built with).
    for (const char* kind : {"bbx8", "fps4", "fps8", "fps12"})
        CHECK(keypoint_count(kind) == keypoints(mesh, info, kind).rows());
    REQUIRE_THROWS_WITH(keypoint_count("fps"), Contains("'fps'"));
    REQUIRE_THROWS_WITH(keypoint_count(""), Contains("unknown keypoint kind ''"));
}
