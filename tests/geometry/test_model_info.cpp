// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include <chrono>
#include <cmath>
#include <iostream>
#include <random>
#include <vector>

#include "core/error.h"
#include "geom_test_util.h"
#include "geometry/mesh_io.h"
#include "geometry/model_info.h"
#include "testing.h"

using namespace g2l::geom;
using g2l::geom::test::random_points;
using g2l::geom::test::write_file;
using Catch::Contains;

namespace {

/// O(N^2) reference on raw doubles (fast enough in Debug builds too).
double brute_force_diameter(const Points& p) {
    const Eigen::Index n = p.rows();
    std::vector<double> x(p.data(), p.data() + n * 3);
    double best = 0;
    for (Eigen::Index i = 0; i < n; ++i) {
        const double* a = &x[3 * i];
        for (Eigen::Index j = i + 1; j < n; ++j) {
            const double* b = &x[3 * j];
            const double d = (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                             (a[2] - b[2]) * (a[2] - b[2]);
            best = std::max(best, d);
        }
    }
    return std::sqrt(best);
}

}  // namespace

TEST_CASE("compute_model_info gives the exact diameter and extent", "[geometry]") {
    // A 2 x 4 x 6 box's corners plus its centre: diameter = sqrt(4 + 16 + 36).
    Points box(9, 3);
    box << 0, 0, 0, 2, 0, 0, 0, 4, 0, 0, 0, 6, 2, 4, 0, 2, 0, 6, 0, 4, 6, 2, 4, 6, 1, 2, 3;
    const ModelInfo b = compute_model_info(box);
    CHECK(b.diameter == Approx(std::sqrt(56.0)).epsilon(1e-12));
    CHECK(b.min == Eigen::Vector3d(0, 0, 0));
    CHECK(b.size == Eigen::Vector3d(2, 4, 6));
    CHECK_FALSE(b.symmetric);

    // Random clouds (incl. an elongated one whose diameter is not between axis extremes)
    // against brute force.
    std::mt19937 rng(7);
    for (int trial = 0; trial < 8; ++trial) {
        Points p = random_points(1500, 50.0, rng);
        if (trial % 2) p.col(1) *= 0.2f;
        if (trial == 4) {  // rotate so the long axis is diagonal
            const Eigen::Matrix3f R = test::random_rotation(rng).cast<float>();
            p = (p * R.transpose()).eval();
        }
        if (trial == 5) p.rowwise().normalize();  // on a sphere: weakest pruning bounds
        if (trial == 6) p = p.array().round().matrix() * 0.f;  // all points equal
        if (trial == 7) p = (p / 10.f).array().round().matrix();  // many tied pairs
        const ModelInfo info = compute_model_info(p);
        CHECK(info.diameter == Approx(brute_force_diameter(p)).epsilon(1e-12));
        CHECK(info.min.x() == Approx(p.col(0).minCoeff()));
        CHECK(info.size.z() == Approx(p.col(2).maxCoeff() - p.col(2).minCoeff()));
    }
    const ModelInfo one = compute_model_info(Points::Constant(1, 3, 4.f));
    CHECK(one.diameter == 0);

    REQUIRE_THROWS_WITH(compute_model_info(Points(0, 3)), Contains("no vertices"));
    Points bad = Points::Zero(3, 3);
    bad(2, 1) = std::nanf("");
    REQUIRE_THROWS_WITH(compute_model_info(bad), Contains("vertex 2"));
}

TEST_CASE("load_models_info_json reads BOP entries and symmetry flags", "[geometry]") {
    const std::string dir = g2l::testing::temp_dir("minfo_json");
    write_file(dir + "/mi.json", R"({
      "1": {"diameter": 102.5, "min_x": -1, "min_y": -2, "min_z": -3,
            "size_x": 2, "size_y": 4, "size_z": 6},
      "10": {"diameter": 164.6, "min_x": 0, "min_y": 0, "min_z": 0, "size_x": 1, "size_y": 1,
             "size_z": 1, "symmetries_discrete": [[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]]},
      "11": {"diameter": 175.9, "min_x": 0, "min_y": 0, "min_z": 0, "size_x": 1, "size_y": 1,
             "size_z": 1, "symmetries_continuous": [{"axis": [0, 0, 1], "offset": [0, 0, 0]}]}
    })");
    const auto m = load_models_info_json(dir + "/mi.json");
    REQUIRE(m.size() == 3);
    CHECK(m.at(1).diameter == 102.5);
    CHECK(m.at(1).min == Eigen::Vector3d(-1, -2, -3));
    CHECK(m.at(1).size == Eigen::Vector3d(2, 4, 6));
    CHECK_FALSE(m.at(1).symmetric);
    CHECK(m.at(10).symmetric);
    CHECK(m.at(11).symmetric);

    write_file(dir + "/bad1.json", R"({"3": {"diameter": 1, "min_x": 0}})");
    REQUIRE_THROWS_WITH(load_models_info_json(dir + "/bad1.json"),
                        Contains("bad1.json") && Contains("'3.min_y'"));
    write_file(dir + "/bad2.json", R"({"x": {}})");
    REQUIRE_THROWS_WITH(load_models_info_json(dir + "/bad2.json"), Contains("'x'"));
    write_file(dir + "/bad3.json", R"({"3": {"diameter": 1, )");
    REQUIRE_THROWS_WITH(load_models_info_json(dir + "/bad3.json"),
                        Contains("bad3.json") && Contains("invalid JSON"));
    write_file(dir + "/bad4.json", R"({"2": {"diameter": -4, "min_x": 0, "min_y": 0, "min_z": 0,
                                     "size_x": 1, "size_y": 1, "size_z": 1}})");
    REQUIRE_THROWS_WITH(load_models_info_json(dir + "/bad4.json"),
                        Contains("'2.diameter' must be > 0, got -4"));
    REQUIRE_THROWS_WITH(load_models_info_json(dir + "/none.json"), Contains("none.json"));
}

TEST_CASE("load_models_info_yml parses the Linemod_preprocessed line format", "[geometry]") {
    const std::string dir = g2l::testing::temp_dir("minfo_yml");
    write_file(dir + "/mi.yml",
               "# LINEMOD\n"
               "1: {diameter: 102.09865663, min_x: -37.93430000, min_y: -38.79960000, min_z: "
               "-45.88450000, size_x: 75.86860000, size_y: 77.59920000, size_z: 91.76900000}\r\n"
               "\n"
               "12: {size_z: 90.8, diameter: 145.54287471, min_x: -50.4439, min_y: -54.2485, "
               "min_z: -45.4, size_x: 100.8878, size_y: 108.497}\n");
    const auto m = load_models_info_yml(dir + "/mi.yml");
    REQUIRE(m.size() == 2);
    CHECK(m.at(1).diameter == 102.09865663);
    CHECK(m.at(1).min.z() == -45.8845);
    CHECK(m.at(1).size.y() == 77.5992);
    CHECK(m.at(12).size.z() == 90.8);
    CHECK(m.at(12).min.x() == -50.4439);

    write_file(dir + "/b1.yml", "1: {diameter: 10, min_x: 0, min_y: 0, min_z: 0, size_x: 1, "
                                "size_y: 1}\n");
    REQUIRE_THROWS_WITH(load_models_info_yml(dir + "/b1.yml"),
                        Contains("b1.yml' line 1") && Contains("no 'size_z'"));
    write_file(dir + "/b2.yml", "\n1 {diameter: 10}\n");
    REQUIRE_THROWS_WITH(load_models_info_yml(dir + "/b2.yml"), Contains("line 2"));
    write_file(dir + "/b3.yml", "1: {diameter: 1O.5, min_x: 0, min_y: 0, min_z: 0, size_x: 1, "
                                "size_y: 1, size_z: 1}\n");
    REQUIRE_THROWS_WITH(load_models_info_yml(dir + "/b3.yml"),
                        Contains("bad number '1O.5'") && Contains("'diameter'"));
    const std::string ok = "1: {diameter: 1, min_x: 0, min_y: 0, min_z: 0, size_x: 1, "
                           "size_y: 1, size_z: 1}\n";
    write_file(dir + "/b4.yml", ok + ok);
    REQUIRE_THROWS_WITH(load_models_info_yml(dir + "/b4.yml"), Contains("id 1 appears twice"));
}

TEST_CASE("real models_info files load and the computed YCB-V diameter matches", "[geometry]") {
    const auto shared = g2l::testing::shared_data_dir();
    if (!shared) {
        g2l::testing::skip_without_shared_data("models_info and diameter check");
        return;
    }
    const auto ycb = load_models_info_json(*shared + "/ycbv/models/models_info.json");
    CHECK(ycb.size() == 21);
    CHECK(ycb.at(1).diameter == Approx(172.062635));
    const auto lmo = load_models_info_json(*shared + "/lmo/models/models_info.json");
    CHECK(lmo.size() == 8);
    CHECK(lmo.at(10).symmetric);
    CHECK(lmo.at(11).symmetric);
    CHECK_FALSE(lmo.at(1).symmetric);
    const auto yml = load_models_info_yml(*shared + "/lmo/linemod_models_info_all15.yml");
    REQUIRE(yml.size() == 15);
    CHECK(yml.at(1).diameter == 102.09865663);
    CHECK(yml.at(15).size.z() == 184.7474);

    const Mesh mesh = load_mesh(*shared + "/ycbv/models/obj_000001.ply");
    const auto t0 = std::chrono::steady_clock::now();
    const ModelInfo info = compute_model_info(mesh.vertices);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    std::cerr << "compute_model_info(ycbv obj 1, " << mesh.vertices.rows()
              << " vertices): diameter " << info.diameter << " mm in " << ms << " ms\n";
    CHECK(std::abs(info.diameter - ycb.at(1).diameter) < 0.01 * ycb.at(1).diameter);
    CHECK(info.diameter == Approx(brute_force_diameter(mesh.vertices)).epsilon(1e-12));
    CHECK((info.min - ycb.at(1).min).cwiseAbs().maxCoeff() < 0.01);
    CHECK((info.size - ycb.at(1).size).cwiseAbs().maxCoeff() < 0.01);
}

TEST_CASE("check_mesh_units: metres and wrong diameters are refused with the fix", "[geometry]") {
    const Mesh mm = load_mesh(g2l::testing::fixture_dir() + "/ycbv_mini/models/obj_000008.ply");
    ModelInfo declared;
    declared.diameter = 114.053345;  // the fixture's models_info.json
    // Millimetres and the right diameter: the measured info comes back.
    const ModelInfo ok = check_mesh_units(mm, &declared, "models_info.json");
    REQUIRE(ok.diameter == Approx(114.053345).epsilon(1e-6));
    REQUIRE(check_mesh_units(mm, nullptr).diameter == Approx(114.053345).epsilon(1e-6));
    declared.diameter = 114.053345 * 1.04;  // within 5 %
    REQUIRE_NOTHROW(check_mesh_units(mm, &declared, "models_info.json"));
    // The same mesh in metres: refused on its own, and against the models_info entry.
    Mesh m = mm;
    m.vertices /= 1000.f;
    REQUIRE_THROWS_WITH(check_mesh_units(m, nullptr),
                        Contains("obj_000008.ply' is only 0.114") && Contains("looks like metres") &&
                            Contains("scale its vertices by 1000"));
    declared.diameter = 114.053345;
    REQUIRE_THROWS_WITH(check_mesh_units(m, &declared, "'x/models_info.json'"),
                        Contains("measures 0.114") && Contains("'x/models_info.json' declares diameter 114.05") &&
                            Contains("looks like metres"));
    // A diameter 10x off (cm / mm) or 6 % off.
    declared.diameter = 11.4053345;
    REQUIRE_THROWS_WITH(check_mesh_units(mm, &declared, "models_info.json"),
                        Contains("centimetre / millimetre slip"));
    declared.diameter = 114.053345 * 1.06;
    REQUIRE_THROWS_WITH(check_mesh_units(mm, &declared, "models_info.json"),
                        Contains("fix the models_info entry"));
    REQUIRE_THROWS_WITH(check_mesh_units(Mesh{}, nullptr), Contains("has no vertices"));
}
