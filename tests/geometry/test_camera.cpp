// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <vector>

#include "core/error.h"
#include "geometry/camera.h"

using namespace g2l::geom;
using Catch::Contains;

namespace {

Intrinsics test_K() {
    Intrinsics K;
    K.fx = 500;
    K.fy = 400;
    K.cx = 2;
    K.cy = 1.5;
    K.width = 4;
    K.height = 3;
    return K;
}

}  // namespace

TEST_CASE("depth_to_points back-projects every valid pixel with the pinhole model", "[geometry]") {
    // 4 x 3 image, values in raw units (scale 0.5 mm / unit); pixel (u=1, v=2) and (3, 0) are 0.
    const std::vector<uint16_t> depth = {1000, 1200, 1400, 0,
                                         1600, 1800, 2000, 2200,
                                         2400, 0,    2800, 3000};
    std::vector<int> idx;
    const Points p = depth_to_points(depth.data(), 4, 3, 0.5, test_K(), Box2i{0, 0, 4, 3}, &idx);
    REQUIRE(p.rows() == 10);
    REQUIRE(idx.size() == 10);
    REQUIRE(idx == std::vector<int>{0, 1, 2, 4, 5, 6, 7, 8, 10, 11});
    for (int r = 0; r < p.rows(); ++r) {
        const int u = idx[r] % 4, v = idx[r] / 4;
        const double z = depth[idx[r]] * 0.5;
        CHECK(p(r, 2) == Approx(z));
        CHECK(p(r, 0) == Approx((u - 2.0) * z / 500.0).margin(1e-5));
        CHECK(p(r, 1) == Approx((v - 1.5) * z / 400.0).margin(1e-5));
    }
    // Pixel (u=3, v=1): z = 1100 mm, X = 1 * 1100 / 500 = 2.2, Y = -0.5 * 1100 / 400 = -1.375.
    CHECK(p(6, 0) == Approx(2.2f));
    CHECK(p(6, 1) == Approx(-1.375f));
    CHECK(p(6, 2) == Approx(1100.f));
}

TEST_CASE("depth_to_points clips the box to the image and honours it", "[geometry]") {
    std::vector<uint16_t> depth(12, 1000);
    std::vector<int> idx;
    // Box [2, 10) x [-5, 2) -> columns 2..3, rows 0..1.
    const Points p = depth_to_points(depth.data(), 4, 3, 1.0, test_K(), Box2i{2, -5, 8, 7}, &idx);
    REQUIRE(idx == std::vector<int>{2, 3, 6, 7});
    REQUIRE(p.rows() == 4);
    // A box fully outside, and an empty one, give no points.
    CHECK(depth_to_points(depth.data(), 4, 3, 1.0, test_K(), Box2i{10, 10, 5, 5}).rows() == 0);
    CHECK(depth_to_points(depth.data(), 4, 3, 1.0, test_K(), Box2i{0, 0, 0, 3}).rows() == 0);
}

TEST_CASE("float depth_to_points skips NaN, inf and non-positive depth", "[geometry]") {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    const std::vector<float> depth = {500.f, nan, inf, -3.f, 0.f, 750.5f, -inf, 1e-3f,
                                      nan,   nan, nan, nan};
    std::vector<int> idx;
    const Points p = depth_to_points(depth.data(), 4, 3, test_K(), Box2i{0, 0, 4, 3}, &idx);
    REQUIRE(idx == std::vector<int>{0, 5, 7});
    CHECK(p(0, 0) == Approx(-2.0 * 500 / 500));
    CHECK(p(1, 2) == Approx(750.5f));
    CHECK(p(1, 0) == Approx((1 - 2.0) * 750.5 / 500));
    CHECK(p(1, 1) == Approx((1 - 1.5) * 750.5 / 400));
    CHECK(p(2, 2) == Approx(1e-3f));
}

TEST_CASE("project inverts depth_to_points", "[geometry]") {
    std::vector<uint16_t> depth(12);
    for (int i = 0; i < 12; ++i) depth[i] = static_cast<uint16_t>(700 + 37 * i);
    std::vector<int> idx;
    const Points p = depth_to_points(depth.data(), 4, 3, 0.1, test_K(), Box2i{0, 0, 4, 3}, &idx);
    const Pixels uv = project(p, test_K());
    REQUIRE(uv.rows() == 12);
    for (int r = 0; r < 12; ++r) {
        CHECK(uv(r, 0) == Approx(idx[r] % 4).margin(1e-4));
        CHECK(uv(r, 1) == Approx(idx[r] / 4).margin(1e-4));
    }
}

TEST_CASE("camera functions reject bad input with the offending values", "[geometry]") {
    std::vector<uint16_t> depth(12, 1);
    const Box2i box{0, 0, 4, 3};
    REQUIRE_THROWS_WITH(depth_to_points(depth.data(), 4, 3, 0.0, test_K(), box),
                        Contains("depth_scale") && Contains("got 0"));
    REQUIRE_THROWS_WITH(depth_to_points(static_cast<const uint16_t*>(nullptr), 4, 3, 1.0, test_K(),
                                        box),
                        Contains("null"));
    REQUIRE_THROWS_WITH(depth_to_points(depth.data(), 5, 3, 1.0, test_K(), box),
                        Contains("4 x 3") && Contains("5 x 3"));
    Intrinsics bad = test_K();
    bad.fx = std::nan("");
    REQUIRE_THROWS_WITH(depth_to_points(depth.data(), 4, 3, 1.0, bad, box), Contains("fx=nan"));
    Points behind(2, 3);
    behind << 0, 0, 100, 1, 2, -5;
    REQUIRE_THROWS_WITH(project(behind, test_K()), Contains("point 1") && Contains("Z = -5"));
}

TEST_CASE("intrinsics_from_cam_K reads a BOP cam_K and rejects bad matrices", "[geometry]") {
    const double K[9] = {1066.778, 0, 312.9869, 0, 1067.487, 241.3109, 0, 0, 1};
    const Intrinsics in = intrinsics_from_cam_K(K, 640, 480);
    CHECK(in.fx == 1066.778);
    CHECK(in.fy == 1067.487);
    CHECK(in.cx == 312.9869);
    CHECK(in.cy == 241.3109);
    CHECK(in.width == 640);
    CHECK(in.height == 480);
    const double skew[9] = {500, 3, 320, 0, 500, 240, 0, 0, 1};
    REQUIRE_THROWS_WITH(intrinsics_from_cam_K(skew, 640, 480), Contains("cam_K[1]=3"));
    const double neg[9] = {-500, 0, 320, 0, 500, 240, 0, 0, 1};
    REQUIRE_THROWS_WITH(intrinsics_from_cam_K(neg, 640, 480), Contains("fx=-500"));
    const double row[9] = {500, 0, 320, 0, 500, 240, 0, 0, 2};
    REQUIRE_THROWS_WITH(intrinsics_from_cam_K(row, 640, 480), Contains("(0, 0, 2)"));
    REQUIRE_THROWS_WITH(intrinsics_from_cam_K(K, 0, 480), Contains("0 x 480"));
}

TEST_CASE("implausible_camera: field of view, aspect and principal point for the image",
          "[geometry]") {
    Intrinsics ycbv;  // YCB-Video's Xtion at 640 x 480
    ycbv.fx = 1066.778, ycbv.fy = 1067.487, ycbv.cx = 312.9869, ycbv.cy = 241.3109;
    REQUIRE(implausible_camera(ycbv, 640, 480).empty());
    Intrinsics lm = ycbv;  // LINEMOD's Kinect
    lm.fx = 572.4114, lm.fy = 573.57043, lm.cx = 325.2611, lm.cy = 242.04899;
    REQUIRE(implausible_camera(lm, 640, 480).empty());
    // YCB-V's intrinsics on a 320 x 240 image: a 17 degree view.
    REQUIRE_THAT(implausible_camera(ycbv, 320, 240), Catch::Contains("17 degree field of view"));
    // A principal point near the corner: intrinsics of another resolution or crop.
    Intrinsics corner = ycbv;
    corner.cx = 600;
    REQUIRE_THAT(implausible_camera(corner, 640, 480), Catch::Contains("another resolution"));
    // Intrinsics of a 2x calibration: a 17 degree field of view.
    Intrinsics big = ycbv;
    big.fx *= 2, big.fy *= 2, big.cx *= 2, big.cy *= 2;
    REQUIRE_THAT(implausible_camera(big, 640, 480), Catch::Contains("17 degree field of view"));
    Intrinsics skew = ycbv;
    skew.fy = 800;
    REQUIRE_THAT(implausible_camera(skew, 640, 480), Catch::Contains("differ by more than 10 %"));
    REQUIRE_THAT(implausible_camera(ycbv, 0, 480), Catch::Contains("0 x 480"));
}
