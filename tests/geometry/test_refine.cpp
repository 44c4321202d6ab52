// SPDX-License-Identifier: MIT
// Depth refinement (geometry/refine.h): ICP recovers a perturbed pose, the turned starts
// recover a flipped one that ICP alone cannot, the free-space test counts model points in
// front of the measured surface, and bad input throws naming the value.
#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "geometry/labels.h"
#include "geometry/metrics.h"
#include "geometry/model_info.h"
#include "geometry/refine.h"
#include "geometry/symmetry.h"
#include "geom_test_util.h"

using namespace g2l;
using namespace g2l::geom;
using Catch::Matchers::Contains;

namespace {

// A 120 x 60 x 40 mm box (grid 4 mm) with a 30 mm cube on one corner of its +z face: no
// rotation maps it onto itself.
Points bumped_box() { return test::box_surface(120, 60, 40, 4, Eigen::Vector3f::Zero(), 30); }

Points transform(const Points& p, const Pose& pose) {
    Points out(p.rows(), 3);
    for (Eigen::Index i = 0; i < p.rows(); ++i)
        out.row(i) = (pose.R * p.row(i).transpose().cast<double>() + pose.t).cast<float>().transpose();
    return out;
}

Pose gt_pose() {
    Pose g;
    g.R = (Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()) *
           Eigen::AngleAxisd(-0.7, Eigen::Vector3d::UnitY()))
              .toRotationMatrix();
    g.t = Eigen::Vector3d(20, -10, 800);
    return g;
}

}  // namespace

TEST_CASE("refine_pose: ICP recovers a pose perturbed by 12 degrees and 15 mm", "[geometry][refine]") {
    const Points model = bumped_box();
    const ModelKdTree tree(model);
    const ModelInfo info = compute_model_info(model);
    const Pose gt = gt_pose();
    const Points obs = transform(model, gt);
    Pose start = gt;
    start.R = Eigen::AngleAxisd(12 * M_PI / 180, Eigen::Vector3d(1, 2, 3).normalized()) * gt.R;
    start.t += Eigen::Vector3d(10, -8, 8);
    REQUIRE(rotation_error_deg(start.R, gt.R) > 11.9);
    RefineOptions opt;
    opt.hypotheses = false;
    const Points normals = tree.normals();
    const RefineResult r = refine_pose(tree, info, obs, start, opt, nullptr, &normals);
    // Point-to-point ICP gets the rotation but slides slowly along the flat faces.
    const RefineResult p2p = refine_pose(tree, info, obs, start, opt);
    CHECK(rotation_error_deg(p2p.pose.R, gt.R) < 1);
    CHECK((p2p.pose.t - gt.t).norm() > 1);
    CHECK(rotation_error_deg(r.pose.R, gt.R) < 0.5);
    CHECK((r.pose.t - gt.t).norm() < 0.5);
    CHECK(r.hypothesis == 0);
    CHECK(r.hypotheses == 1);
    CHECK(r.fit_mm < 0.5);
    CHECK(r.fit_mm >= 0);
}

TEST_CASE("refine_pose: the turned starts recover a box turned over, ICP alone does not",
          "[geometry][refine]") {
    const Points model = bumped_box();
    const ModelKdTree tree(model);
    const ModelInfo info = compute_model_info(model);
    const Pose gt = gt_pose();
    const Points obs = transform(model, gt);
    // The pose turned 180 degrees about the box's long axis, through its centre.
    const Eigen::Vector3d c = info.min + 0.5 * info.size;
    const Eigen::Matrix3d T = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
    Pose flipped;
    flipped.R = gt.R * T;
    flipped.t = gt.R * (c - T * c) + gt.t;
    RefineOptions opt;
    opt.hypotheses = false;
    const RefineResult alone = refine_pose(tree, info, obs, flipped, opt);
    CHECK(rotation_error_deg(alone.pose.R, gt.R) > 90);
    opt.hypotheses = true;
    const RefineResult turned = refine_pose(tree, info, obs, flipped, opt);
    CHECK(rotation_error_deg(turned.pose.R, gt.R) < 1);
    CHECK((turned.pose.t - gt.t).norm() < 1);
    CHECK(turned.hypothesis > 0);
    CHECK(turned.hypotheses > 24);
    CHECK(turned.fit_mm < 0.5 * turned.start_fit_mm);
    // From the right pose, the network's start is kept.
    const RefineResult kept = refine_pose(tree, info, obs, gt, opt);
    CHECK(kept.hypothesis == 0);
    CHECK(rotation_error_deg(kept.pose.R, gt.R) < 0.5);
}

TEST_CASE("refine_pose: alt_fit_mm, the best distinct pose: a plain box's flips fit as well "
          "unless its symmetries are given, the bumped box's do not", "[geometry][refine]") {
    const Pose gt = gt_pose();
    RefineOptions opt;
    // A plain 120 x 60 x 40 box seen from all sides: turned over onto itself it fits as well.
    const Points plain = test::box_surface(120, 60, 40, 4, Eigen::Vector3f::Zero());
    const ModelKdTree plain_tree(plain);
    const ModelInfo plain_info = compute_model_info(plain);
    const Points plain_obs = transform(plain, gt);
    const RefineResult r = refine_pose(plain_tree, plain_info, plain_obs, gt, opt);
    CHECK(r.fit_mm < 0.1);
    REQUIRE(r.alt_fit_mm >= 0);
    CHECK(r.alt_fit_mm < r.fit_mm + 0.1);  // the flips: as good a fit, 180 degrees away
    // With the box's symmetries those flips are the same pose: none left, or clearly worse.
    const std::vector<SymmetryTransform> syms = geometric_symmetries(plain_tree, plain_info);
    REQUIRE(syms.size() == 4);  // the identity and the three half-turns
    const RefineResult s =
        refine_pose(plain_tree, plain_info, plain_obs, gt, opt, nullptr, nullptr, nullptr, &syms);
    // The pose itself does not change (the same computation: the same numbers).
    CHECK((s.pose.R - r.pose.R).cwiseAbs().maxCoeff() < 1e-12);
    CHECK((s.pose.t - r.pose.t).cwiseAbs().maxCoeff() < 1e-9);
    CHECK(s.fit_mm == r.fit_mm);
    CHECK((s.alt_fit_mm < 0 || s.alt_fit_mm > r.fit_mm + 2.0));
    // The bumped box (no symmetry): every turn leaves the bump unexplained.
    const Points bumped = bumped_box();
    const ModelKdTree tree(bumped);
    const ModelInfo info = compute_model_info(bumped);
    const RefineResult b = refine_pose(tree, info, transform(bumped, gt), gt, opt);
    CHECK(b.fit_mm < 0.1);
    CHECK(b.alt_fit_mm > b.fit_mm + 2.0);
    // Without the turned starts there is no finalist to compare.
    opt.hypotheses = false;
    CHECK(refine_pose(tree, info, transform(bumped, gt), gt, opt).alt_fit_mm == -1);
    opt = {};
    opt.alt_min_deg = -1;
    CHECK_THROWS_WITH(refine_pose(tree, info, transform(bumped, gt), gt, opt), Contains("alt_min_deg"));
}

TEST_CASE("free_space_violation: model points in front of the measured surface", "[geometry][refine]") {
    // A flat wall at 1000 mm over a 64 x 64 image, one pixel with no measurement.
    Intrinsics K;
    K.fx = K.fy = 100;
    K.cx = K.cy = 32;
    K.width = K.height = 64;
    std::vector<float> depth(64 * 64, 1000.f);
    const DepthImage di{depth.data(), K};
    Points pts(3, 3);
    pts << 0, 0, 0, 10, 0, 0, 0, 10, 0;
    Pose p;
    p.t = Eigen::Vector3d(0, 0, 900);   // 100 mm in front of the wall: all violate
    CHECK(free_space_violation(pts, p, di, 10) == Approx(1.0));
    p.t.z() = 1005;                     // on the wall (within 10 mm): none
    CHECK(free_space_violation(pts, p, di, 10) == Approx(0.0));
    p.t.z() = 1200;                     // behind the wall (hidden): none seen, 0
    CHECK(free_space_violation(pts, p, di, 10) == Approx(0.0));
    depth[32 * 64 + 32] = 0.f;          // the first point's pixel has no depth: not counted
    p.t.z() = 900;
    CHECK(free_space_violation(pts, p, di, 10) == Approx(1.0));
    p.t = Eigen::Vector3d(0, 0, -500);  // behind the camera: nothing seen
    CHECK(free_space_violation(pts, p, di, 10) == Approx(0.0));

    // In refine_pose, the penalty raises the cost of a pose floating in front of the wall.
    const Points model = bumped_box();
    const ModelKdTree tree(model);
    const ModelInfo info = compute_model_info(model);
    std::vector<float> far(64 * 64, 5000.f);
    const DepthImage wall{far.data(), K};
    Pose gt;
    gt.t = Eigen::Vector3d(0, 0, 800);
    const Points obs = transform(model, gt);
    RefineOptions opt;
    opt.hypotheses = false;
    const RefineResult plain = refine_pose(tree, info, obs, gt, opt);
    const RefineResult walled = refine_pose(tree, info, obs, gt, opt, &wall);
    CHECK(plain.violation == 0);
    CHECK(walled.violation > 0.5);
    CHECK(walled.fit_mm > plain.fit_mm + 0.5 * opt.inlier_frac * info.diameter);
}

TEST_CASE("refine_pose: bad input throws naming the value", "[geometry][refine]") {
    const Points model = bumped_box();
    const ModelKdTree tree(model);
    const ModelInfo info = compute_model_info(model);
    const Pose gt = gt_pose();
    Points obs = transform(model, gt);
    CHECK_THROWS_WITH(refine_pose(tree, info, obs.topRows(2), gt), Contains("at least 3 observed points, got 2"));
    Points bad = obs;
    bad(5, 1) = std::nanf("");
    CHECK_THROWS_WITH(refine_pose(tree, info, bad, gt), Contains("is not finite"));
    Pose nan_pose = gt;
    nan_pose.t.x() = std::nan("");
    CHECK_THROWS_WITH(refine_pose(tree, info, obs, nan_pose), Contains("initial pose is not finite"));
    ModelInfo no_diam = info;
    no_diam.diameter = 0;
    CHECK_THROWS_WITH(refine_pose(tree, no_diam, obs, gt), Contains("diameter must be > 0, got 0"));
    RefineOptions opt;
    opt.max_points = 2;
    CHECK_THROWS_WITH(refine_pose(tree, info, obs, gt, opt), Contains("max_points 2"));
    opt = {};
    opt.switch_ratio = 0;
    CHECK_THROWS_WITH(refine_pose(tree, info, obs, gt, opt), Contains("switch_ratio 0"));
    const DepthImage empty{};
    CHECK_THROWS_WITH(refine_pose(tree, info, obs, gt, {}, &empty), Contains("depth image"));
}

TEST_CASE("ModelKdTree: knn nearest first, normals of a box's faces", "[geometry][refine]") {
    const Points model = bumped_box();
    const ModelKdTree tree(model);
    int idx[5];
    float d2[5];
    const Eigen::Vector3f q(0.5f, 0.3f, 20.f);  // near the middle of the +z face
    REQUIRE(tree.knn(q, 5, idx, d2) == 5);
    for (int j = 1; j < 5; ++j) CHECK(d2[j] >= d2[j - 1]);
    int nearest = -1;
    CHECK(std::sqrt(d2[0]) == Approx(tree.nearest(q, &nearest)));
    CHECK(idx[0] == nearest);
    const Points n = tree.normals();
    REQUIRE(n.rows() == model.rows());
    // A point in the middle of the +z face: normal along z; of the +x face: along x.
    CHECK(std::abs(n(nearest, 2)) == Approx(1.0).margin(1e-3));
    tree.nearest(Eigen::Vector3f(60.f, 1.f, 2.f), &nearest);
    CHECK(std::abs(n(nearest, 0)) == Approx(1.0).margin(1e-3));
    for (Eigen::Index i = 0; i < n.rows(); i += 97) CHECK(n.row(i).norm() == Approx(1.0).margin(1e-4));
    CHECK_THROWS_WITH(tree.knn(q, 0, idx, d2), Contains("k must be >= 1, got 0"));
    CHECK_THROWS_WITH(tree.normals(2), Contains("k must be >= 3, got 2"));
    // Normals that do not match the tree are refused.
    RefineOptions opt;
    const Points short_n = n.topRows(10);
    CHECK_THROWS_WITH(refine_pose(tree, compute_model_info(model), transform(model, gt_pose()),
                                  gt_pose(), opt, nullptr, &short_n),
                      Contains("10 normals for"));
}

namespace {

// A 200 x 200 image (f = 200) of a table at 1000 mm facing the camera, with the model posed at
// `pose` z-buffered over it (4 mm model grid: no gaps at this distance).
std::vector<float> table_with(const Points& posed, const Intrinsics& K) {
    std::vector<float> depth(size_t(K.width * K.height), 1000.f);
    for (Eigen::Index i = 0; i < posed.rows(); ++i) {
        const float z = posed(i, 2);
        const int u = int(std::lround(K.fx * posed(i, 0) / z + K.cx));
        const int v = int(std::lround(K.fy * posed(i, 1) / z + K.cy));
        if (u < 0 || v < 0 || u >= K.width || v >= K.height) continue;
        float& d = depth[size_t(v * K.width + u)];
        d = std::min(d, z);
    }
    return depth;
}

Intrinsics table_camera() {
    Intrinsics K;
    K.fx = K.fy = 200;
    K.cx = K.cy = 100;
    K.width = K.height = 200;
    return K;
}

// The bumped box with its bump towards the camera, resting on the table at 1000 mm (it spans
// 960-1000 mm), its surface points as observed and the depth image.
struct BoxOnTable {
    Points model = bumped_box();
    ModelKdTree tree{model};
    ModelInfo info = compute_model_info(model);
    Pose gt = [] {
        Pose p;
        p.R = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
        p.t = Eigen::Vector3d(0, 0, 980);
        return p;
    }();
    Intrinsics K = table_camera();
    Points obs = transform(model, gt);
    std::vector<float> depth = table_with(obs, K);
    DepthImage di{depth.data(), K};
};

}  // namespace

TEST_CASE("fit_plane: the table around an object, deterministic, no depth, bad options",
          "[geometry][refine]") {
    // A tilted table: n . p + d = 0 with n = (0, -0.6, -0.8), d = 900 (camera on the + side),
    // a 40 x 40 px block 60 mm nearer in the middle and a band of missing pixels.
    const Intrinsics K = table_camera();
    const Eigen::Vector3d n(0, -0.6, -0.8);
    std::vector<float> depth(size_t(K.width * K.height));
    for (int v = 0; v < K.height; ++v)
        for (int u = 0; u < K.width; ++u) {
            const Eigen::Vector3d ray((u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0);
            float z = float(-900.0 / n.dot(ray));
            if (std::abs(u - 100) < 20 && std::abs(v - 100) < 20) z -= 60.f;
            if (v >= 10 && v < 20) z = 0.f;
            depth[size_t(v * K.width + u)] = z;
        }
    const DepthImage di{depth.data(), K};
    Plane p;
    REQUIRE(fit_plane(di, 0, 0, K.width, K.height, 4.0, &p));
    CHECK(p.n.dot(n) > 0.9999);
    CHECK(p.d == Approx(900).margin(1.0));
    CHECK(p.inlier_frac == Approx(1.0 - 1600.0 / 38000.0).margin(0.02));  // all but the block
    Plane q;
    REQUIRE(fit_plane(di, 0, 0, K.width, K.height, 4.0, &q));
    CHECK(q.n == p.n);  // deterministic
    CHECK(q.d == p.d);
    // Only the block (a region inside it): the block's face is the plane, all inliers.
    REQUIRE(fit_plane(di, 85, 85, 115, 115, 4.0, &q));
    CHECK(q.inlier_frac == Approx(1.0));
    CHECK(q.d < 900 - 30);  // the block's face: nearer the camera than the table
    // No measured pixel / a region outside the image: no plane.
    std::vector<float> none(size_t(K.width * K.height), 0.f);
    CHECK_FALSE(fit_plane(DepthImage{none.data(), K}, 0, 0, K.width, K.height, 4.0, &q));
    CHECK_FALSE(fit_plane(di, 300, 300, 400, 400, 4.0, &q));
    CHECK_THROWS_WITH(fit_plane(di, 0, 0, 10, 10, 0.0, &q), Contains("tol_mm 0"));
    CHECK_THROWS_WITH(fit_plane(DepthImage{}, 0, 0, 10, 10, 4.0, &q), Contains("depth image"));
}

TEST_CASE("refine_pose: a pose sunk into the support plane pays for it, without the plane it "
          "does not", "[geometry][refine]") {
    const BoxOnTable scene;
    const ModelKdTree& tree = scene.tree;
    const ModelInfo& info = scene.info;
    const Pose& gt = scene.gt;
    const Points& obs = scene.obs;
    const DepthImage& di = scene.di;
    RefineOptions opt;
    opt.hypotheses = false;
    opt.iterations = opt.coarse_iterations = 0;  // score the starts as they are
    const RefineResult on = refine_pose(tree, info, obs, gt, opt, &di);
    CHECK(on.plane);
    CHECK(on.violation < 0.02);
    Pose sunk = gt;
    sunk.t.z() += 30;  // 30 mm into the table: the far 22 mm of the box's 40 are beneath it
    const RefineResult in = refine_pose(tree, info, obs, sunk, opt, &di);
    CHECK(in.plane);
    CHECK(in.violation > 0.25);
    CHECK(in.fit_mm > on.fit_mm + 0.25 * opt.inlier_frac * info.diameter);
    opt.support_plane = false;  // hidden behind the table, the sunk points break no free space
    const RefineResult off = refine_pose(tree, info, obs, sunk, opt, &di);
    CHECK_FALSE(off.plane);
    CHECK(off.violation < 0.02);
    // A plane holding too few of the pixels is not taken as the support.
    opt = {};
    opt.hypotheses = false;
    opt.plane_min_inliers = 1.0;
    CHECK_FALSE(refine_pose(tree, info, obs, gt, opt, &di).plane);
    opt.plane_tol_mm = 0;
    CHECK_THROWS_WITH(refine_pose(tree, info, obs, gt, opt, &di), Contains("plane_tol_mm 0"));
}

TEST_CASE("pose_cost: refine_pose's cost of a pose as it is, the sunk pose costs more, bad input",
          "[geometry][refine]") {
    const BoxOnTable b;
    RefineOptions opt;
    opt.hypotheses = false;
    opt.iterations = opt.coarse_iterations = 0;  // refine_pose scores its start as it is
    Pose sunk = b.gt;
    sunk.t.z() += 30;
    for (const Pose& p : {b.gt, sunk}) {
        const RefineResult r = refine_pose(b.tree, b.info, b.obs, p, opt, &b.di);
        CHECK(pose_cost(b.tree, b.info, b.obs, p, opt, &b.di) == Approx(r.fit_mm).margin(1e-9));
        // Without the depth image (and every observed point): the capped fit alone.
        RefineOptions all = opt;
        all.max_points = int(b.obs.rows());
        CHECK(pose_cost(b.tree, b.info, b.obs, p, all) ==
              Approx(fit_error(b.tree, b.obs, p, opt.inlier_frac * b.info.diameter)).margin(1e-9));
    }
    CHECK(pose_cost(b.tree, b.info, b.obs, b.gt, opt, &b.di) < 0.05);
    // 30 mm into the table: the support plane adds its penalty to the fit.
    CHECK(pose_cost(b.tree, b.info, b.obs, sunk, opt, &b.di) >
          pose_cost(b.tree, b.info, b.obs, sunk, opt) + 0.25 * opt.inlier_frac * b.info.diameter);
    CHECK_THROWS_WITH(pose_cost(b.tree, b.info, b.obs.topRows(2), b.gt),
                      Contains("pose_cost: need at least 3 observed points, got 2"));
    Pose nan_pose = b.gt;
    nan_pose.R(0, 0) = std::nan("");
    CHECK_THROWS_WITH(pose_cost(b.tree, b.info, b.obs, nan_pose), Contains("pose_cost: the pose is not finite"));
    const DepthImage empty{};
    CHECK_THROWS_WITH(pose_cost(b.tree, b.info, b.obs, b.gt, {}, &empty), Contains("depth image"));
}

TEST_CASE("refine_pose: a neighbouring object's points form their own cluster and are left out",
          "[geometry][refine]") {
    // The bumped box at its pose plus a flat 80 x 80 mm patch 40 mm beside it (a neighbour the
    // segmentation took along): two clusters at 10% of the diameter (~14 mm).
    const Points model = bumped_box();
    const ModelKdTree tree(model);
    const ModelInfo info = compute_model_info(model);
    const Pose gt = gt_pose();
    const Points obj = transform(model, gt);
    std::vector<Eigen::Vector3f> patch;
    for (float a = 0; a <= 80; a += 4)
        for (float b = 0; b <= 80; b += 4)
            patch.push_back(obj.colwise().maxCoeff().transpose() + Eigen::Vector3f(40.f + a, b - 40.f, 0.f));
    Points obs(obj.rows() + Eigen::Index(patch.size()), 3);
    obs.topRows(obj.rows()) = obj;
    for (size_t i = 0; i < patch.size(); ++i) obs.row(obj.rows() + Eigen::Index(i)) = patch[i].transpose();
    RefineOptions opt;
    opt.hypotheses = false;
    opt.max_points = int(obs.rows());  // every point: the fits compare exactly
    const RefineResult split = refine_pose(tree, info, obs, gt, opt);
    CHECK(split.cluster == 0);  // the largest cluster: the box
    CHECK(split.observed == int(obj.rows()));
    CHECK(split.fit_mm < 0.5);
    CHECK(rotation_error_deg(split.pose.R, gt.R) < 0.5);
    CHECK((split.pose.t - gt.t).norm() < 1.0);
    opt.cluster_frac = 0;  // off: all points, the patch's capped distances in the fit
    const RefineResult all = refine_pose(tree, info, obs, gt, opt);
    CHECK(all.cluster == -1);
    CHECK(all.observed == int(obs.rows()));
    CHECK(all.fit_mm > split.fit_mm + 0.5 * opt.inlier_frac * info.diameter * double(patch.size()) /
                                          double(obs.rows()));
    opt.cluster_frac = 0.1;
    opt.cluster_min_share = 0.99;  // no cluster holds 99% of the points: only the whole set
    CHECK(refine_pose(tree, info, obs, gt, opt).cluster == -1);
    opt.cluster_min_share = 1.5;
    CHECK_THROWS_WITH(refine_pose(tree, info, obs, gt, opt), Contains("cluster_min_share 1.5"));
    opt.cluster_min_share = 0.25;
    opt.cluster_frac = -1;
    CHECK_THROWS_WITH(refine_pose(tree, info, obs, gt, opt), Contains("cluster_frac -1"));
}

TEST_CASE("ClosestPointGrid: near the true nearest point, outside is beyond the margin, bad input",
          "[geometry][refine]") {
    const Points model = bumped_box();
    const ModelKdTree tree(model);
    const ModelInfo info = compute_model_info(model);
    const ClosestPointGrid grid = ClosestPointGrid::for_refine(tree, info);
    // diameter / 80 (1 to 4 mm), margin = the default inlier cap (0.1 of the diameter).
    CHECK(grid.cell_mm() == Approx(std::clamp(info.diameter / 80, 1.0, 4.0)));
    CHECK(grid.margin_mm() == Approx(0.1 * info.diameter));
    CHECK(grid.tree_points() == tree.size());
    const double lim = std::sqrt(3.0) * grid.cell_mm();
    // Points around the box (a deterministic lattice, some beyond the grid): each lookup's model
    // point is within sqrt(3) cells of the exact nearest distance; -1 only beyond the margin.
    int inside = 0, outside = 0;
    double worst = 0;
    for (float x = -100; x <= 220; x += 7.3f)
        for (float y = -60; y <= 120; y += 6.1f)
            for (float z = -60; z <= 110; z += 5.7f) {
                const Eigen::Vector3f q(x, y, z);
                const float exact = tree.nearest(q);
                const int k = grid.lookup(q);
                if (k < 0) {
                    ++outside;
                    CHECK(exact > grid.margin_mm() - 1e-3);
                    continue;
                }
                ++inside;
                REQUIRE(k < tree.size());
                const double got = (q - tree.points().row(k).transpose()).norm();
                CHECK(got >= exact - 1e-3);
                worst = std::max(worst, got - exact);
            }
    CHECK(inside > 1000);
    CHECK(outside > 1000);
    CHECK(worst <= lim);
    CHECK(worst > 0);  // the grid is an approximation, and the test can tell
    CHECK(grid.lookup(Eigen::Vector3f(std::nanf(""), 0, 0)) == -1);
    // The raw layout (the refinement's vectorised lookups) indexes the same cells as lookup.
    const ClosestPointGrid::Layout g = grid.layout();
    REQUIRE(int64_t(g.nx) * g.ny * g.nz == grid.size());
    int same = 0;
    for (float x = -100; x <= 220; x += 9.1f)
        for (float y = -60; y <= 120; y += 8.3f)
            for (float z = -60; z <= 110; z += 7.7f) {
                const float fx = (x - g.lo[0]) * g.inv_cell, fy = (y - g.lo[1]) * g.inv_cell,
                            fz = (z - g.lo[2]) * g.inv_cell;
                const bool in = fx >= 0 && fy >= 0 && fz >= 0 && fx < float(g.nx) &&
                                fy < float(g.ny) && fz < float(g.nz);
                const int k = in ? g.cells[g.offset(int(fx), int(fy), int(fz))] : -1;
                same += k == grid.lookup(Eigen::Vector3f(x, y, z));
            }
    CHECK(same == 36 * 22 * 23);
    // Bad input names the value.
    CHECK_THROWS_WITH(ClosestPointGrid(tree, 0, 5), Contains("cell_mm must be > 0, got 0"));
    CHECK_THROWS_WITH(ClosestPointGrid(tree, 2, -1), Contains("margin_mm must be >= 0, got -1"));
    CHECK_THROWS_WITH(ClosestPointGrid(tree, 0.01, 5), Contains("exceed the limit"));
    ModelInfo no_diam = info;
    no_diam.diameter = 0;
    CHECK_THROWS_WITH(ClosestPointGrid::for_refine(tree, no_diam), Contains("diameter must be > 0"));
}

TEST_CASE("ClosestPointGrid::nearest_below: the k-d tree's exact nearest point, bad input",
          "[geometry][refine]") {
    const Points model = bumped_box();
    const ModelKdTree tree(model);
    const ClosestPointGrid grid = ClosestPointGrid::for_refine(tree, compute_model_info(model));
    CHECK(grid.bucket_mm() >= 4.0);
    // A lattice around and through the box: with a bound above the true distance (tight, as
    // the refinement's, or loose), the same distance as the k-d tree to the bit, and a point at
    // that distance; with a bound below it, nothing.
    int checked = 0, none = 0;
    for (float x = -40; x <= 170; x += 3.7f)
        for (float y = -30; y <= 100; y += 4.1f)
            for (float z = -30; z <= 90; z += 3.3f) {
                const Eigen::Vector3f q(x, y, z);
                int kd = -1;
                const float want = tree.nearest(q, &kd);
                for (const float bound : {want * 1.001f + 1e-3f, want + 9.f}) {
                    int got = -1;
                    const float d = grid.nearest_below(q, bound, &got);
                    REQUIRE(got >= 0);
                    REQUIRE(got < tree.size());
                    CHECK(d == want);
                    CHECK((q - tree.points().row(got).transpose()).squaredNorm() ==
                          Approx((q - tree.points().row(kd).transpose()).squaredNorm()).epsilon(1e-6));
                    ++checked;
                }
                if (want > 0.5f) {
                    int untouched = 12345;
                    CHECK(std::isinf(grid.nearest_below(q, want * 0.99f, &untouched)));
                    CHECK(untouched == 12345);
                    ++none;
                }
            }
    CHECK(checked > 20000);
    CHECK(none > 5000);
    // Far outside the points' box, a NaN point, a bound that is not > 0: nothing.
    int i = -1;
    CHECK(std::isinf(grid.nearest_below(Eigen::Vector3f(1000, 0, 0), 50, &i)));
    CHECK(std::isinf(grid.nearest_below(Eigen::Vector3f(std::nanf(""), 0, 0), 50, &i)));
    CHECK(std::isinf(grid.nearest_below(Eigen::Vector3f(0, 0, 0), 0, &i)));
    CHECK(std::isinf(grid.nearest_below(Eigen::Vector3f(0, 0, 0), std::nanf(""), &i)));
    CHECK(i == -1);
    // An empty grid holds no points.
    CHECK(std::isinf(ClosestPointGrid().nearest_below(Eigen::Vector3f(0, 0, 0), 50, &i)));
}

TEST_CASE("refine_pose: with the grid, the same poses as with the k-d tree alone",
          "[geometry][refine]") {
    const Points model = bumped_box();
    const ModelKdTree tree(model);
    const ModelInfo info = compute_model_info(model);
    const Points normals = tree.normals();
    const ClosestPointGrid grid = ClosestPointGrid::for_refine(tree, info);
    const Pose gt = gt_pose();
    const Points obs = transform(model, gt);
    // Perturbed (ICP from the start) and turned over (the turned starts must win).
    Pose start = gt;
    start.R = Eigen::AngleAxisd(12 * M_PI / 180, Eigen::Vector3d(1, 2, 3).normalized()) * gt.R;
    start.t += Eigen::Vector3d(10, -8, 8);
    const Eigen::Vector3d c = info.min + 0.5 * info.size;
    const Eigen::Matrix3d T = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
    Pose flipped;
    flipped.R = gt.R * T;
    flipped.t = gt.R * (c - T * c) + gt.t;
    for (const Pose& init : {start, flipped}) {
        const RefineResult exact = refine_pose(tree, info, obs, init, {}, nullptr, &normals);
        const RefineResult fast = refine_pose(tree, info, obs, init, {}, nullptr, &normals, &grid);
        CHECK(rotation_error_deg(fast.pose.R, gt.R) < 0.5);
        CHECK((fast.pose.t - gt.t).norm() < 0.5);
        CHECK(rotation_error_deg(fast.pose.R, exact.pose.R) < 0.5);
        CHECK(fast.hypothesis == exact.hypothesis);
        // The exact fit is reported (of the observed points refine_pose strides to max_points).
        CHECK(fast.fit_mm == Approx(fit_error(tree, obs, fast.pose, 0.1 * info.diameter)).margin(1e-3));
        CHECK(fast.fit_mm < 0.5);
    }
    CHECK(refine_pose(tree, info, obs, flipped, {}, nullptr, &normals, &grid).hypothesis > 0);
    // An empty grid is no grid; one with a margin below the inlier cap is refused.
    const ClosestPointGrid none;
    CHECK(rotation_error_deg(refine_pose(tree, info, obs, start, {}, nullptr, &normals, &none).pose.R,
                             gt.R) < 0.5);
    const ClosestPointGrid thin(tree, 2.0, 1.0);
    CHECK_THROWS_WITH(refine_pose(tree, info, obs, start, {}, nullptr, &normals, &thin),
                      Contains("below the inlier cap"));
    const ModelKdTree other(bumped_box().topRows(500));
    const ClosestPointGrid foreign = ClosestPointGrid::for_refine(other, info);
    CHECK_THROWS_WITH(refine_pose(tree, info, obs, start, {}, nullptr, &normals, &foreign),
                      Contains("built over a tree of 500 points"));
    RefineOptions opt;
    opt.polish_iterations = -1;
    CHECK_THROWS_WITH(refine_pose(tree, info, obs, start, opt, nullptr, &normals, &grid),
                      Contains("polish_iterations must be >= 0, got -1"));
}

TEST_CASE("euclidean_clusters: the components a brute-force search finds, in its order, bad input",
          "[geometry][refine]") {
    // Two boxes 30 mm apart, a line of points 6 mm apart leading away from one, a far pair, a
    // single stray point and duplicated points: components joined by "closer than radius".
    Points a = test::box_surface(60, 40, 30, 4, Eigen::Vector3f::Zero(), 0);
    Points b = test::box_surface(50, 30, 30, 4, Eigen::Vector3f(90, 0, 0), 0);
    std::vector<Eigen::Vector3f> extra;
    for (int i = 1; i <= 12; ++i) extra.emplace_back(-6.f * float(i), 10.f, 10.f);
    extra.emplace_back(500.f, 500.f, 500.f);
    extra.emplace_back(503.f, 500.f, 500.f);
    extra.emplace_back(-300.f, 0.f, 0.f);
    Points pts(a.rows() + b.rows() + int64_t(extra.size()) + 2, 3);
    // Interleave the sets so that component ids and row order differ.
    int64_t r = 0, ia = 0, ib = 0;
    while (ia < a.rows() || ib < b.rows()) {
        if (ib < b.rows()) pts.row(r++) = b.row(ib++);
        if (ia < a.rows()) pts.row(r++) = a.row(ia++);
    }
    for (const auto& e : extra) pts.row(r++) = e.transpose();
    pts.row(r++) = a.row(3);
    pts.row(r++) = b.row(5);
    REQUIRE(r == pts.rows());
    auto brute = [&](double radius) {
        const int64_t n = pts.rows();
        std::vector<int64_t> comp(size_t(n), -1);
        std::vector<std::vector<int64_t>> out;
        for (int64_t s0 = 0; s0 < n; ++s0) {
            if (comp[size_t(s0)] >= 0) continue;
            out.emplace_back();
            std::vector<int64_t> stack{s0};
            comp[size_t(s0)] = int64_t(out.size()) - 1;
            while (!stack.empty()) {
                const int64_t x = stack.back();
                stack.pop_back();
                out.back().push_back(x);
                for (int64_t y = 0; y < n; ++y)
                    if (comp[size_t(y)] < 0 &&
                        (pts.row(x) - pts.row(y)).squaredNorm() < float(radius * radius)) {
                        comp[size_t(y)] = comp[size_t(s0)];
                        stack.push_back(y);
                    }
            }
        }
        for (auto& c : out) std::sort(c.begin(), c.end());
        std::stable_sort(out.begin(), out.end(),
                         [](const auto& x, const auto& y) { return x.size() > y.size(); });
        return out;
    };
    for (const double radius : {2.0, 5.0, 6.5, 31.0, 2000.0}) {
        INFO("radius " << radius);
        const auto got = euclidean_clusters(pts, radius);
        CHECK(got == brute(radius));
    }
    // 6.5 mm: the two boxes, the line joined to box a, the far pair, the stray point.
    const auto c = euclidean_clusters(pts, 6.5);
    REQUIRE(c.size() == 4);
    CHECK(c[0].size() == size_t(a.rows() + 12 + 1));
    CHECK(c[1].size() == size_t(b.rows() + 1));
    CHECK(c[2].size() == 2);
    CHECK(c[3].size() == 1);
    CHECK(euclidean_clusters(Points(0, 3), 5.0).empty());
    CHECK_THROWS_WITH(euclidean_clusters(pts, 0), Contains("radius must be > 0, got 0"));
    Points bad = pts;
    bad(7, 1) = std::nanf("");
    CHECK_THROWS_WITH(euclidean_clusters(bad, 5), Contains("point 7 is not finite"));
}
