// SPDX-License-Identifier: MIT
// Geometric symmetries found from the model surface: boxes, cubes, cylinders, and a box whose
// bump breaks every symmetry; bad options throw naming the value.
#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <catch2/catch.hpp>
#include <array>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "geometry/labels.h"
#include "geometry/metrics.h"
#include "geometry/symmetry.h"
#include "geom_test_util.h"

using namespace g2l;
using namespace g2l::geom;

namespace {

const Eigen::Vector3f kCentre(10.f, -5.f, 3.f);  // off the origin: rotations are about the box centre

// The box of geom_test_util.h centred at kCentre, with a 24 mm bump if `bump`.
Points box_surface(float sx, float sy, float sz, float step, bool bump = false) {
    return test::box_surface(sx, sy, sz, step, kCentre, bump ? 24.f : 0.f);
}

// A closed cylinder around z through kCentre: radius r, height hgt, 72 points per ring.
Points cylinder_surface(float r, float hgt, float step) {
    std::vector<Eigen::Vector3f> pts;
    const double pi = std::acos(-1.0);
    for (float z = -hgt / 2; z <= hgt / 2 + 1e-3f; z += step)
        for (int k = 0; k < 72; ++k) {
            const double a = 2 * pi * k / 72;
            pts.push_back(kCentre + Eigen::Vector3f(float(r * std::cos(a)), float(r * std::sin(a)), z));
        }
    for (float rr = step; rr < r; rr += step)
        for (int k = 0; k < 72; ++k) {
            const double a = 2 * pi * k / 72;
            for (float z : {-hgt / 2, hgt / 2})
                pts.push_back(kCentre + Eigen::Vector3f(float(rr * std::cos(a)), float(rr * std::sin(a)), z));
        }
    Points out(Eigen::Index(pts.size()), 3);
    for (size_t i = 0; i < pts.size(); ++i) out.row(Eigen::Index(i)) = pts[i].transpose();
    return out;
}

ModelInfo info_of(const Points& p) {
    ModelInfo info;
    const Eigen::Vector3f lo = p.colwise().minCoeff(), hi = p.colwise().maxCoeff();
    info.min = lo.cast<double>();
    info.size = (hi - lo).cast<double>();
    info.diameter = double((hi - lo).norm());  // the bbox diagonal bounds the diameter
    return info;
}

// Every accepted transform maps the point set onto itself and fixes the box centre.
void check_valid(const ModelKdTree& tree, const std::vector<SymmetryTransform>& syms) {
    for (const auto& s : syms) {
        CHECK((s.R * s.R.transpose() - Eigen::Matrix3f::Identity()).norm() < 1e-5f);
        CHECK(s.R.determinant() == Approx(1.0).margin(1e-5));
        CHECK((s.R * kCentre + s.t - kCentre).norm() < 1e-3f);
        CHECK(symmetry_score(tree, s).error_mm < 1.0);
    }
}

}  // namespace

TEST_CASE("symmetries: a box with three different sides has exactly its three 180-degree flips",
          "[geometry][symmetry]") {
    const Points pts = box_surface(40, 60, 100, 2);
    const ModelKdTree tree(pts);
    const auto syms = geometric_symmetries(tree, info_of(pts));
    REQUIRE(syms.size() == 4);
    CHECK(syms[0].R.isIdentity(1e-6f));
    CHECK(syms[0].t.norm() < 1e-6f);
    for (size_t i = 1; i < syms.size(); ++i) {
        // A flip about a coordinate axis: diagonal with one +1 and two -1.
        CHECK(syms[i].R.isDiagonal(1e-5f));
        CHECK(syms[i].R.trace() == Approx(-1.0).margin(1e-5));
    }
    check_valid(tree, syms);
}

TEST_CASE("symmetries: a cube has the 24 rotations of the cube group", "[geometry][symmetry]") {
    const Points pts = box_surface(50, 50, 50, 2);
    const ModelKdTree tree(pts);
    const auto syms = geometric_symmetries(tree, info_of(pts));
    CHECK(syms.size() == 24);
    check_valid(tree, syms);
}

TEST_CASE("symmetries: a cylinder has its axis turns and the flips about horizontal axes",
          "[geometry][symmetry]") {
    const Points pts = cylinder_surface(30, 100, 2);
    const ModelKdTree tree(pts);
    SymmetryOptions o;
    o.axis_steps = 24;
    const auto syms = geometric_symmetries(tree, info_of(pts), o);
    // 24 turns about z (identity included) + 180 degrees about x, y and the two diagonals.
    CHECK(syms.size() == 28);
    int z_turns = 0;
    for (const auto& s : syms) z_turns += (s.R.col(2) - Eigen::Vector3f::UnitZ()).norm() < 1e-5f;
    CHECK(z_turns == 24);
    check_valid(tree, syms);
}

TEST_CASE("symmetries: a bump on one face breaks every symmetry of the box",
          "[geometry][symmetry]") {
    const Points pts = box_surface(40, 60, 100, 2, /*bump=*/true);
    const ModelKdTree tree(pts);
    const auto syms = geometric_symmetries(tree, info_of(box_surface(40, 60, 100, 2)));
    REQUIRE(syms.size() == 1);
    CHECK(syms[0].R.isIdentity(1e-6f));
}

TEST_CASE("model_frame: a box modelled turned about z gets its own axes and its three flips",
          "[geometry][symmetry]") {
    // The YCB-Video pudding box, gelatin box and wood block are modelled turned ~15-30 degrees
    // about z: the axis-aligned box is not theirs, and its x / y flips are not their symmetries.
    const Points straight = box_surface(40, 60, 100, 2);
    const Eigen::Matrix3f Rm = Eigen::AngleAxisf(0.44f, Eigen::Vector3f::UnitZ()).toRotationMatrix();
    const Points turned = (straight * Rm.transpose()).eval();  // each row p -> Rm p
    const ModelFrame f = model_frame(turned);
    CHECK_FALSE(f.aligned);
    CHECK((f.centre - Rm * kCentre).norm() < 1.f);
    CHECK(f.axes.determinant() == Approx(1.0).margin(1e-4));
    for (int j = 0; j < 3; ++j) {
        // Each frame axis is one of the box's own axes (the columns of Rm), its extent that side.
        int k = 0;
        const float dot = (Rm.transpose() * f.axes.col(j)).cwiseAbs().maxCoeff(&k);
        CHECK(dot > 0.9995f);
        CHECK(f.size[j] == Approx(std::array<float, 3>{40, 60, 100}[size_t(k)]).margin(1.0));
    }
    // The axis-aligned box stays as modelled.
    const ModelFrame a = model_frame(straight);
    CHECK(a.aligned);
    CHECK(a.axes.isIdentity(1e-6f));
    CHECK((a.centre - kCentre).norm() < 1e-3f);
    CHECK((a.size - Eigen::Vector3f(40, 60, 100)).norm() < 1e-3f);

    // The turned box has its three flips about its own axes (only the z flip before).
    const ModelKdTree tree(turned);
    const auto syms = geometric_symmetries(tree, info_of(turned));
    REQUIRE(syms.size() == 4);
    for (size_t i = 1; i < syms.size(); ++i) {
        const Eigen::AngleAxisf aa(syms[i].R);
        CHECK(aa.angle() == Approx(M_PI).margin(1e-3));
        CHECK((Rm.transpose() * aa.axis()).cwiseAbs().maxCoeff() > 0.9995f);
        CHECK((syms[i].R * (Rm * kCentre) + syms[i].t - Rm * kCentre).norm() < 1.f);
        CHECK(symmetry_score(tree, syms[i]).error_mm < 1.0);
    }

    CHECK_THROWS_WITH(model_frame(turned.topRows(3)), Catch::Contains("at least 4 points, got 3"));
    Points bad = turned;
    bad(5, 1) = std::nanf("");
    CHECK_THROWS_WITH(model_frame(bad), Catch::Contains("not finite"));
    CHECK_THROWS_WITH(model_frame(turned, 1.0), Catch::Contains("min_gain") && Catch::Contains("1"));
}

TEST_CASE("symmetries: score of a flip, bad diameters and options throw naming the value",
          "[geometry][symmetry]") {
    const Points pts = box_surface(40, 60, 100, 2);
    const ModelKdTree tree(pts);
    SymmetryTransform flip;
    flip.R = Eigen::Vector3f(1, -1, -1).asDiagonal();
    flip.t = kCentre - flip.R * kCentre;
    const SymmetryScore sc = symmetry_score(tree, flip);
    CHECK(sc.error_mm < 1e-3);
    CHECK(sc.displacement_mm > 40);  // y and z flip: points move by 2 * sqrt(y^2 + z^2) on average
    SymmetryTransform quarter;  // 90 degrees about z: a 40 x 60 face does not map onto itself
    quarter.R << 0, -1, 0, 1, 0, 0, 0, 0, 1;
    quarter.t = kCentre - quarter.R * kCentre;
    CHECK(symmetry_score(tree, quarter).error_mm > 3);

    ModelInfo info = info_of(pts);
    ModelInfo bad = info;
    bad.diameter = 0;
    CHECK_THROWS_WITH(geometric_symmetries(tree, bad), Catch::Contains("diameter") && Catch::Contains("0"));
    SymmetryOptions o;
    o.tolerance_frac = 1.5;
    CHECK_THROWS_WITH(geometric_symmetries(tree, info, o), Catch::Contains("tolerance_frac") && Catch::Contains("1.5"));
    o = {};
    o.axis_steps = 0;
    CHECK_THROWS_WITH(geometric_symmetries(tree, info, o), Catch::Contains("axis_steps"));
    o = {};
    o.displacement_frac = std::nan("");
    CHECK_THROWS_WITH(geometric_symmetries(tree, info, o), Catch::Contains("displacement_frac"));
    CHECK_THROWS_WITH(symmetry_score(tree, flip, 0), Catch::Contains("max_points"));
}

TEST_CASE("add_sym / rotation_error_sym_deg: a pose off by a symmetry scores as right",
          "[geometry][symmetry]") {
    // A 40 x 60 x 100 box centred at the origin: the 180-degree turn about z maps it onto itself.
    Points pts(8, 3);
    for (int i = 0; i < 8; ++i)
        pts.row(i) << (i & 1 ? 20.f : -20.f), (i & 2 ? 30.f : -30.f), (i & 4 ? 50.f : -50.f);
    SymmetryTransform flip;
    flip.R = Eigen::AngleAxisf(float(M_PI), Eigen::Vector3f::UnitZ()).toRotationMatrix();
    const std::vector<SymmetryTransform> syms{SymmetryTransform{}, flip};
    Pose gt;
    gt.R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    gt.t = Eigen::Vector3d(10, -20, 800);
    const Pose est = compose(gt, flip);  // the estimate is the flipped pose
    // Plain ADD sees a 180-degree error: corners move by up to 2 x 36 mm.
    CHECK(add(est, gt, pts) > 30.0);
    CHECK(rotation_error_deg(est.R, gt.R) == Approx(180.0).margin(1e-3));
    // Modulo the symmetry it is exact.
    CHECK(add_sym(est, gt, pts, syms) == Approx(0.0).margin(1e-4));
    CHECK(rotation_error_sym_deg(est.R, gt.R, syms) == Approx(0.0).margin(1e-3));
    // Without symmetries the functions are the plain metrics.
    CHECK(add_sym(est, gt, pts, {}) == Approx(add(est, gt, pts)));
    CHECK(rotation_error_sym_deg(est.R, gt.R, {}) == Approx(180.0).margin(1e-3));
    // A pose 10 degrees off the flipped one: 10 degrees modulo symmetries, not 170.
    Pose off = est;
    off.R = est.R * Eigen::AngleAxisd(10 * M_PI / 180, Eigen::Vector3d::UnitX()).toRotationMatrix();
    CHECK(rotation_error_sym_deg(off.R, gt.R, syms) == Approx(10.0).margin(1e-3));
    CHECK(add_sym(off, gt, pts, syms) > 1.0);
}
