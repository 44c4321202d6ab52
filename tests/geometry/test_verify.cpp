// SPDX-License-Identifier: MIT
// Verification against depth (geometry/verify.h): a right pose is explained by the depth, a pose
// in front of the measured surface violates free space, one behind it is occluded, one beside it
// explains nothing; an occluder lowers the explained share but not the support much; no depth
// gives no verdict; footprints overlap as sets; bad input throws naming the value.
#include <catch2/catch.hpp>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "geometry/labels.h"
#include "geometry/model_info.h"
#include "geometry/verify.h"
#include "geom_test_util.h"

using namespace g2l;
using namespace g2l::geom;
using Catch::Matchers::Contains;

namespace {

constexpr float kSx = 120, kSy = 80, kSz = 60;  // the box (mm), centred on its origin
constexpr double kZ = 800;                        // its centre's depth at the true pose

Intrinsics camera() {
    Intrinsics K;
    K.fx = K.fy = 600;
    K.cx = 160;
    K.cy = 120;
    K.width = 320;
    K.height = 240;
    return K;
}

// The depth a camera sees of the box at (0, 0, kZ) facing it, in front of a wall at 1200 mm;
// pixels left of column `cover_until` see an occluder at 500 mm instead.
std::vector<float> scene_depth(int cover_until = -1) {
    const Intrinsics K = camera();
    std::vector<float> d(size_t(K.width * K.height));
    for (int v = 0; v < K.height; ++v)
        for (int u = 0; u < K.width; ++u) {
            const double front = kZ - kSz / 2;
            const double x = (u + 0.5 - K.cx) * front / K.fx, y = (v + 0.5 - K.cy) * front / K.fy;
            float z = std::abs(x) <= kSx / 2 && std::abs(y) <= kSy / 2 ? float(front) : 1200.f;
            if (u < cover_until) z = 500.f;
            d[size_t(v * K.width + u)] = z;
        }
    return d;
}

Pose at(double dx, double dy, double dz) {
    Pose p;
    p.t = Eigen::Vector3d(dx, dy, kZ + dz);
    return p;
}

}  // namespace

TEST_CASE("verify_pose: right, in front, behind, beside, occluded, no depth", "[geometry]") {
    const Points pts = test::box_surface(kSx, kSy, kSz, 2, Eigen::Vector3f::Zero());
    const ModelKdTree tree(pts);
    const ModelInfo info = compute_model_info(pts);
    const Intrinsics K = camera();
    const std::vector<float> depth = scene_depth();
    const DepthImage di{depth.data(), K};
    // The object points the segmentation would give: the measured front face.
    Points obs(0, 3);
    {
        std::vector<Eigen::Vector3f> o;
        for (float x = -kSx / 2; x <= kSx / 2; x += 4)
            for (float y = -kSy / 2; y <= kSy / 2; y += 4)
                o.emplace_back(x, y, float(kZ - kSz / 2));
        obs.resize(Eigen::Index(o.size()), 3);
        for (size_t i = 0; i < o.size(); ++i) obs.row(Eigen::Index(i)) = o[i].transpose();
    }
    const VerifyOptions opt;
    const Verification right = verify_pose(tree, info, at(0, 0, 0), di, obs, opt);
    INFO("right: visible " << right.visible << " inliers " << right.inliers << " violations "
                           << right.violations << " occluded " << right.occluded);
    CHECK(right.tol_mm == Approx(std::max(6.0, 0.04 * info.diameter)));
    CHECK(right.visible > 200);
    CHECK(right.explained > 0.95);
    CHECK(right.violation < 0.03);
    CHECK(right.seg_agree == Approx(1.0));
    CHECK(right.score > 0.9);
    CHECK(!right.footprint.empty());
    CHECK(std::is_sorted(right.footprint.begin(), right.footprint.end()));
    // The box of the explained surface: the front face's projection (120 x 80 mm at 770 mm:
    // x 113.2-206.8, y 88.8-151.2 px), to the model points' spacing.
    INFO("right box " << right.box.x << " " << right.box.y << " " << right.box.w << " "
                      << right.box.h);
    const double fz = kZ - kSz / 2;
    CHECK(std::abs(right.box.x - (K.cx - K.fx * kSx / 2 / fz)) <= 3);
    CHECK(std::abs(right.box.y - (K.cy - K.fy * kSy / 2 / fz)) <= 3);
    CHECK(std::abs(right.box.w - K.fx * kSx / fz) <= 4);
    CHECK(std::abs(right.box.h - K.fy * kSy / fz) <= 4);

    // 40 mm nearer the camera: the sensor sees the face 40 mm behind the model's: violations.
    const Verification front = verify_pose(tree, info, at(0, 0, -40), di, obs, opt);
    CHECK(front.violation > 0.9);
    CHECK(front.score < 0.1);
    // 40 mm farther: hidden behind the measured face: occluded, nothing explained.
    const Verification behind = verify_pose(tree, info, at(0, 0, 40), di, obs, opt);
    CHECK(behind.occlusion > 0.9);
    CHECK(behind.score < 0.1);
    // 150 mm to the side: the wall behind it, seen through the model.
    const Verification beside = verify_pose(tree, info, at(150, 0, 0), di, obs, opt);
    CHECK(beside.violation > 0.9);
    CHECK(beside.seg_agree < 0.05);
    CHECK(beside.score < 0.05);
    // The right pose with its left third covered: fewer explained, the support stays high.
    const std::vector<float> covered = scene_depth(int(K.cx - 0.2 * K.fx * kSx / (kZ - kSz / 2)));
    const Verification occl = verify_pose(tree, info, at(0, 0, 0), DepthImage{covered.data(), K},
                                          obs, opt);
    CHECK(occl.explained < 0.85);
    CHECK(occl.occlusion > 0.15);
    CHECK(occl.violation < 0.03);
    CHECK(occl.support > 0.75);
    CHECK(occl.score > occl.explained);
    // Its box starts where the occluder ends: what the depth confirms, not the model's outline.
    const int cover_col = int(K.cx - 0.2 * K.fx * kSx / (kZ - kSz / 2));
    CHECK(occl.box.x >= cover_col - 2);
    CHECK(occl.box.x + occl.box.w == right.box.x + right.box.w);
    CHECK(occl.box.h == right.box.h);
    // No depth at all: nothing to verify.
    const std::vector<float> none(depth.size(), 0.f);
    const Verification nodepth = verify_pose(tree, info, at(0, 0, 0), DepthImage{none.data(), K},
                                             obs, opt);
    CHECK(nodepth.visible == 0);
    CHECK(nodepth.unmeasured > 200);
    CHECK(nodepth.score == 0.0);
    CHECK(nodepth.box.empty());
    CHECK(behind.box.empty());  // fewer inliers than min_visible: no box to place
    // No object points: seg_agree 0, so no score either.
    CHECK(verify_pose(tree, info, at(0, 0, 0), di, Points(0, 3), opt).score == 0.0);
    // Behind the camera: nothing visible.
    CHECK(verify_pose(tree, info, at(0, 0, -kZ - 100), di, obs, opt).visible == 0);

    // With the model's closest-point grid the object points' nearest model points come from
    // its buckets: the same agreement, to the point, for poses on, near and off the surface
    // (seg_agree strictly between 0 and 1 in some, so the tolerance's edge is crossed).
    {
        const ClosestPointGrid grid(tree, 2.0, 0.1 * info.diameter);
        int partial = 0;
        for (const Pose& p : {at(0, 0, 0), at(0, 0, -40), at(3, -2, 5), at(0, 0, 6), at(7, 0, 0),
                              at(20, 10, -5), at(150, 0, 0), at(0, 0, -kZ - 100)}) {
            const Verification a = verify_pose(tree, info, p, di, obs, opt);
            const Verification b = verify_pose(tree, info, p, di, obs, opt, &grid);
            CHECK(a.seg_agree == b.seg_agree);
            CHECK(a.score == b.score);
            CHECK(a.footprint == b.footprint);
            partial += a.seg_agree > 0 && a.seg_agree < 1;
        }
        CHECK(partial >= 2);
    }

    // Two poses of the same place claim the same footprint; a box beside claims another one.
    CHECK(footprint_overlap(right.footprint, right.footprint) == Approx(1.0));
    const Verification shifted = verify_pose(tree, info, at(5, 0, 0), di, obs, opt);
    CHECK(footprint_overlap(right.footprint, shifted.footprint) > 0.8);
    CHECK(footprint_overlap(right.footprint, {}) == 0.0);
    CHECK(footprint_overlap({1, 2, 3, 4}, {3, 4, 5}) == Approx(2.0 / 3.0));  // of the second
    CHECK(footprint_overlap({3, 4, 5}, {1, 2, 3, 4}) == Approx(0.5));
    CHECK(footprint_overlap({1, 2}, {3, 4}) == 0.0);

    // Bad input.
    CHECK_THROWS_WITH(verify_pose(tree, info, at(0, 0, 0), DepthImage{}, obs, opt),
                      Contains("need a depth image"));
    ModelInfo flat = info;
    flat.diameter = 0;
    CHECK_THROWS_WITH(verify_pose(tree, flat, at(0, 0, 0), di, obs, opt),
                      Contains("diameter must be > 0"));
    Pose nan = at(0, 0, 0);
    nan.t.x() = std::nan("");
    CHECK_THROWS_WITH(verify_pose(tree, info, nan, di, obs, opt), Contains("not finite"));
    VerifyOptions bad;
    bad.tol_min_mm = 0;
    CHECK_THROWS_WITH(verify_pose(tree, info, at(0, 0, 0), di, obs, bad),
                      Contains("options out of range"));
}
