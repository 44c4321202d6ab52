// SPDX-License-Identifier: MIT
// Stable resting poses and centres of mass: a cube rests on its 6 faces with equal odds, a flat
// box mostly on its large faces, an off-centre mass changes the odds, the resting rotation maps
// "down" onto -z; degenerate meshes and options throw.
#include <Eigen/Geometry>
#include <catch2/catch.hpp>
#include <cmath>

#include "core/error.h"
#include "geometry/stable_poses.h"

using namespace g2l;
using namespace g2l::geom;

namespace {

// Closed box [-sx/2, sx/2] x ... shifted by c, 12 outward-facing triangles.
Mesh box(double sx, double sy, double sz, Eigen::Vector3f c = Eigen::Vector3f::Zero()) {
    Mesh m;
    m.vertices.resize(8, 3);
    for (int i = 0; i < 8; ++i)
        m.vertices.row(i) << float((i & 1 ? 0.5 : -0.5) * sx) + c.x(),
            float((i & 2 ? 0.5 : -0.5) * sy) + c.y(), float((i & 4 ? 0.5 : -0.5) * sz) + c.z();
    const int f[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                          {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
    m.faces.resize(12, 3);
    for (int i = 0; i < 12; ++i) m.faces.row(i) << f[i][0], f[i][1], f[i][2];
    m.path = "<box>";
    return m;
}

}  // namespace

TEST_CASE("centre_of_mass: a closed box is its centre, a surface-only mesh its area centroid",
          "[geometry][stable]") {
    const Eigen::Vector3f c(12.f, -7.f, 30.f);
    const Eigen::Vector3d com = centre_of_mass(box(40, 60, 100, c));
    CHECK(com.x() == Approx(12.0).margin(1e-6));
    CHECK(com.y() == Approx(-7.0).margin(1e-6));
    CHECK(com.z() == Approx(30.0).margin(1e-6));
    // Winding flipped everywhere (inward normals): the signed volume changes sign, not the com.
    Mesh inv = box(40, 60, 100, c);
    for (int64_t i = 0; i < inv.faces.rows(); ++i) std::swap(inv.faces(i, 1), inv.faces(i, 2));
    CHECK((centre_of_mass(inv) - com).norm() < 1e-6);
    // A single triangle encloses nothing: its area centroid.
    Mesh tri;
    tri.vertices.resize(3, 3);
    tri.vertices << 0, 0, 0, 30, 0, 0, 0, 30, 0;
    tri.faces.resize(1, 3);
    tri.faces << 0, 1, 2;
    const Eigen::Vector3d t = centre_of_mass(tri);
    CHECK(t.x() == Approx(10.0));
    CHECK(t.y() == Approx(10.0));
}

TEST_CASE("stable_poses: a cube rests on 6 faces with equal odds", "[geometry][stable]") {
    const Mesh m = box(50, 50, 50);
    const auto poses = stable_poses(m, centre_of_mass(m));
    REQUIRE(poses.size() == 6);
    double total = 0;
    for (const auto& p : poses) {
        total += p.probability;
        CHECK(p.probability == Approx(1.0 / 6).margin(0.02));
        CHECK(p.height == Approx(25.0).margin(0.05));
        // down is a face normal: one coordinate +-1
        CHECK(p.down.cwiseAbs().maxCoeff() == Approx(1.0).margin(1e-4));
    }
    CHECK(total == Approx(1.0));
}

TEST_CASE("stable_poses: a flat box lies mostly on its large faces", "[geometry][stable]") {
    const Mesh m = box(100, 80, 20);
    const auto poses = stable_poses(m, centre_of_mass(m));
    REQUIRE(poses.size() >= 2);
    // The two large faces (normal +-z, height 10) come first and take most of the drops.
    CHECK(std::fabs(poses[0].down.z()) == Approx(1.0).margin(1e-4));
    CHECK(std::fabs(poses[1].down.z()) == Approx(1.0).margin(1e-4));
    CHECK(poses[0].height == Approx(10.0).margin(0.05));
    CHECK(poses[0].probability + poses[1].probability > 0.6);
    CHECK(poses[0].probability == Approx(poses[1].probability).margin(0.03));
}

TEST_CASE("stable_poses: a mass near one face makes that face the likely one",
          "[geometry][stable]") {
    const Mesh m = box(50, 50, 50);
    // Centre of mass 15 mm below the centre (a weighted base): the -z face wins clearly and the
    // +z face (com 40 mm above it) becomes the least likely of the six.
    const auto poses = stable_poses(m, Eigen::Vector3d(0, 0, -15));
    REQUIRE(poses.size() == 6);
    CHECK(poses[0].down.z() == Approx(-1.0).margin(1e-4));
    CHECK(poses[0].height == Approx(10.0).margin(0.05));
    CHECK(poses[0].probability > 0.3);
    CHECK(poses.back().down.z() == Approx(1.0).margin(1e-4));
    CHECK(poses.back().height == Approx(40.0).margin(0.05));
    CHECK(poses.back().probability < 0.1);
}

TEST_CASE("resting_rotation maps the pose's down direction onto -z", "[geometry][stable]") {
    StablePose p;
    p.down = Eigen::Vector3f(1, 2, -0.5).normalized();
    const Eigen::Matrix3d R = resting_rotation(p);
    CHECK((R * p.down.cast<double>().normalized() - Eigen::Vector3d(0, 0, -1)).norm() < 1e-9);
    CHECK(R.determinant() == Approx(1.0));
    p.down = Eigen::Vector3f(0, 0, 1);  // the antiparallel case
    CHECK((resting_rotation(p) * Eigen::Vector3d(0, 0, 1) - Eigen::Vector3d(0, 0, -1)).norm() < 1e-9);
}

TEST_CASE("stable_poses: bad input throws naming the field", "[geometry][stable]") {
    const Mesh m = box(50, 50, 50);
    CHECK_THROWS_WITH(stable_poses(Mesh{}, Eigen::Vector3d::Zero()), Catch::Contains("no vertices"));
    CHECK_THROWS_WITH(centre_of_mass(Mesh{}), Catch::Contains("no vertices"));
    StablePoseOptions o;
    o.directions = 10;
    CHECK_THROWS_WITH(stable_poses(m, Eigen::Vector3d::Zero(), o), Catch::Contains("directions"));
    o = {};
    o.min_probability = 1.5;
    CHECK_THROWS_WITH(stable_poses(m, Eigen::Vector3d::Zero(), o), Catch::Contains("min_probability"));
    o = {};
    o.merge_deg = 0;
    CHECK_THROWS_WITH(stable_poses(m, Eigen::Vector3d::Zero(), o), Catch::Contains("merge_deg"));
}
