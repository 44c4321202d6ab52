// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>
#include <random>

#include "core/error.h"
#include "geom_test_util.h"
#include "geometry/labels.h"
#include "geometry/mesh_io.h"
#include "mesh_distance.h"
#include "testing.h"

using namespace g2l::geom;
using Catch::Contains;

using g2l::testing::point_triangle_distance;

namespace {

/// A 40 x 40 mm square in the z = 0 plane made of 2 triangles: the vertices alone are 40 mm
/// apart, so only surface samples can label points above the middle of the square.
Mesh square_mesh() {
    Mesh m;
    m.vertices.resize(4, 3);
    m.vertices << 0, 0, 0, 40, 0, 0, 40, 40, 0, 0, 40, 0;
    m.faces.resize(2, 3);
    m.faces << 0, 1, 2, 0, 2, 3;
    return m;
}

}  // namespace

TEST_CASE("sample_surface covers every triangle within the spacing", "[geometry]") {
    const Mesh m = square_mesh();
    const Points s = sample_surface(m, 2.0);
    // m = ceil(56.57 / 2) = 29 divisions per triangle: (30 * 31 / 2 - 3) = 462 per triangle.
    REQUIRE(s.rows() == 2 * 462);
    CHECK(s.col(2).cwiseAbs().maxCoeff() == 0.f);
    CHECK(s.col(0).minCoeff() >= -1e-4f);  // barycentric rounding only
    CHECK(s.col(0).maxCoeff() <= 40.0001f);
    CHECK(sample_surface(m, 2.0) == s);  // deterministic
    // Every point of the square is within 2 mm of a sample or vertex (dense probe grid).
    const ModelKdTree tree = ModelKdTree::from_mesh(m, 2.0);
    CHECK(tree.size() == 4 + s.rows());
    double worst = 0;
    for (int i = 0; i <= 80; ++i) {
        for (int j = 0; j <= 80; ++j) {
            worst = std::max(worst, double(tree.nearest(Eigen::Vector3f(i * 0.5f, j * 0.5f, 0))));
        }
    }
    CHECK(worst <= 2.0);
    REQUIRE_THROWS_WITH(sample_surface(m, 0.0), Contains("spacing_mm") && Contains("got 0"));
    Mesh bad = m;
    bad.faces(1, 1) = 4;
    REQUIRE_THROWS_WITH(sample_surface(bad, 2.0), Contains("face 1 index 4"));
}

TEST_CASE("ModelKdTree nearest matches brute force", "[geometry]") {
    std::mt19937 rng(17);
    const Points model = test::random_points(2000, 50.0, rng);
    ModelKdTree tree(model);
    const Points q = test::random_points(300, 80.0, rng);
    for (int i = 0; i < q.rows(); ++i) {
        Eigen::Index best = 0;
        const double d =
            std::sqrt((model.rowwise() - q.row(i)).rowwise().squaredNorm().minCoeff(&best));
        int idx = -1;
        const float got = tree.nearest(q.row(i).transpose(), &idx);
        CHECK(got == Approx(d).epsilon(1e-5));
        CHECK((model.row(idx) - q.row(i)).norm() == Approx(d).epsilon(1e-5));
    }
    REQUIRE_THROWS_WITH(ModelKdTree(Points(0, 3)), Contains("empty"));
    Points bad = model.topRows(4);
    bad(2, 2) = std::numeric_limits<float>::quiet_NaN();
    REQUIRE_THROWS_WITH(ModelKdTree(bad), Contains("point 2"));
    const ModelKdTree moved = std::move(tree);
    CHECK(moved.size() == 2000);
    CHECK(moved.nearest(model.row(17).transpose()) == 0.f);
}

TEST_CASE("ModelKdTree nearest_below: the exact nearest point within a bound, else none", "[geometry]") {
    std::mt19937 rng(23);
    const Points model = test::random_points(3000, 50.0, rng);
    const ModelKdTree tree(model);
    const Points q = test::random_points(300, 80.0, rng);
    std::uniform_real_distribution<float> slack(1.0f, 3.0f);
    int found = 0;
    for (int i = 0; i < q.rows(); ++i) {
        const Eigen::Vector3f x = q.row(i).transpose();
        int want = -1;
        const float d = tree.nearest(x, &want);
        // A bound above the nearest distance (as a grid cell's point gives): the same point.
        int got = -7;
        CHECK(tree.nearest_below(x, d * slack(rng) + 1e-3f, &got) == d);
        CHECK(got == want);
        // A bound at or below it: nothing, and the index is left alone.
        got = -7;
        CHECK(std::isinf(tree.nearest_below(x, d * 0.999f, &got)));
        CHECK(got == -7);
        found += want >= 0;
    }
    CHECK(found == 300);
    int idx = -7;
    CHECK(std::isinf(tree.nearest_below(Eigen::Vector3f(1e4f, 0.f, 0.f), 10.f, &idx)));
    CHECK(idx == -7);
}

TEST_CASE("label_points matches brute-force distance to the posed mesh surface", "[geometry]") {
    std::mt19937 rng(23);
    const Mesh m = square_mesh();
    Pose pose;
    pose.R = test::random_rotation(rng);
    pose.t = Eigen::Vector3d(30, -20, 700);
    // Scene points near the posed square: model-frame points in a slab around it, mapped out.
    std::uniform_real_distribution<double> u(-10.0, 50.0), h(-20.0, 20.0);
    const int n = 3000;
    Points model_frame(n, 3);
    for (int i = 0; i < n; ++i) model_frame.row(i) << float(u(rng)), float(u(rng)), float(h(rng));
    const Points cam = ((model_frame.cast<double>() * pose.R.transpose()).rowwise() +
                        pose.t.transpose()).cast<float>();
    const ModelKdTree tree = ModelKdTree::from_mesh(m, 1.0);
    const std::vector<uint8_t> lab = tree.label_points(cam, pose, 8.f);
    REQUIRE(lab.size() == size_t(n));
    int agree = 0, positives = 0, undecided = 0;
    for (int i = 0; i < n; ++i) {
        const Eigen::Vector3d p = model_frame.row(i).cast<double>();
        const Eigen::Vector3d v[4] = {m.vertices.row(0).cast<double>(),
                                      m.vertices.row(1).cast<double>(),
                                      m.vertices.row(2).cast<double>(),
                                      m.vertices.row(3).cast<double>()};
        const double d = std::min(point_triangle_distance(p, v[0], v[1], v[2]),
                                  point_triangle_distance(p, v[0], v[2], v[3]));
        // Sampling at 1 mm can only over-estimate the true distance by < 1 mm: points with
        // d < 7 must be object, d >= 8 background; 7 <= d < 8 may go either way.
        if (d < 7.0) {
            CHECK(lab[i] == 1);
            agree += lab[i] == 1;
        } else if (d >= 8.0) {
            CHECK(lab[i] == 0);
            agree += lab[i] == 0;
        } else {
            ++undecided;
        }
        positives += lab[i];
    }
    CHECK(agree + undecided == n);
    CHECK(positives > n / 10);
    CHECK(positives < n);
    // Vertices only (no surface samples) would miss points above the middle of the square.
    const ModelKdTree vertices_only(m.vertices);
    Points mid(1, 3);
    mid << 20, 20, 3;
    Pose id;
    CHECK(tree.label_points(mid, id)[0] == 1);
    CHECK(vertices_only.label_points(mid, id)[0] == 0);
    Points nan_pt = mid;
    nan_pt(0, 0) = std::numeric_limits<float>::quiet_NaN();
    CHECK(tree.label_points(nan_pt, id)[0] == 0);
    REQUIRE_THROWS_WITH(tree.label_points(mid, id, -1.f), Contains("threshold_mm"));
}

TEST_CASE("surface tree of a real YCB-V model labels its own posed samples", "[geometry]") {
    const auto shared = g2l::testing::shared_data_dir();
    if (!shared) {
        g2l::testing::skip_without_shared_data("KD-tree over a real model");
        return;
    }
    const Mesh m = load_mesh(*shared + "/ycbv/models/obj_000001.ply");
    auto t0 = std::chrono::steady_clock::now();
    const ModelKdTree tree = ModelKdTree::from_mesh(m, 2.0);
    const double build_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    std::mt19937 rng(1);
    Pose pose;
    pose.R = test::random_rotation(rng);
    pose.t = Eigen::Vector3d(50, 20, 900);
    // Vertices offset by 4 mm along random directions are object; offset by 30 mm along the
    // outward direction from the centroid mostly are not.
    const Eigen::RowVector3f centroid = m.vertices.colwise().mean();
    Points near(m.vertices.rows(), 3), far(m.vertices.rows(), 3);
    std::normal_distribution<float> g(0.f, 1.f);
    for (Eigen::Index i = 0; i < m.vertices.rows(); ++i) {
        Eigen::RowVector3f dir(g(rng), g(rng), g(rng));
        near.row(i) = m.vertices.row(i) + 4.f * dir.normalized();
        far.row(i) = m.vertices.row(i) + 30.f * (m.vertices.row(i) - centroid).normalized();
    }
    auto to_cam = [&](const Points& p) {
        return Points(((p.cast<double>() * pose.R.transpose()).rowwise() + pose.t.transpose())
                          .cast<float>());
    };
    t0 = std::chrono::steady_clock::now();
    const auto ln = tree.label_points(to_cam(near), pose);
    const double label_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const auto lf = tree.label_points(to_cam(far), pose);
    int n_near = 0, n_far = 0;
    for (size_t i = 0; i < ln.size(); ++i) {
        n_near += ln[i];
        n_far += lf[i];
    }
    std::cerr << "ModelKdTree::from_mesh(ycbv obj 1): " << tree.size() << " points in " << build_ms
              << " ms; label_points(" << ln.size() << ") in " << label_ms << " ms\n";
    CHECK(n_near == int(ln.size()));
    CHECK(n_far < int(lf.size()) / 20);
}
