// SPDX-License-Identifier: MIT
#include <catch2/catch.hpp>

#include "testing.h"

#include <random>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "geom_test_util.h"
#include "geometry/crop.h"
#include "geometry/kabsch.h"
#include "geometry/labels.h"
#include "geometry/metrics.h"
#include "geometry/model_info.h"

using namespace g2l::geom;

namespace {

struct Outputs {
    Points samples;
    std::vector<uint8_t> labels;
    double adds_value = 0;
    double diameter = 0;
    std::vector<float> rotations;
    std::vector<int> crop;
};

Outputs run_all() {
    std::mt19937 rng(99);
    Mesh m;
    m.vertices = test::random_points(300, 40.0, rng);
    m.faces.resize(400, 3);
    std::uniform_int_distribution<int> vi(0, 299);
    for (int f = 0; f < 400; ++f) m.faces.row(f) << vi(rng), vi(rng), vi(rng);
    Outputs o;
    o.samples = sample_surface(m, 3.0);
    const ModelKdTree tree = ModelKdTree::from_mesh(m, 3.0);
    Pose pose;
    pose.R = test::random_rotation(rng);
    pose.t = Eigen::Vector3d(0, 0, 500);
    Points cam = test::random_points(30000, 60.0, rng);
    cam.col(2).array() += 500.f;
    o.labels = tree.label_points(cam.topRows(8000), pose, 8.f);
    Pose est = pose;
    est.R = test::random_rotation(rng);
    o.adds_value = adds(est, pose, o.samples);
    o.diameter = compute_model_info(cam.topRows(5000)).diameter;
    const int B = 40, K = 8;
    std::vector<float> P(B * K * 3), Q(B * K * 3);
    std::normal_distribution<float> g(0.f, 50.f);
    for (auto& x : P) x = g(rng);
    for (auto& x : Q) x = g(rng);
    o.rotations.resize(B * 9);
    kabsch_batched(P.data(), Q.data(), B, K, o.rotations.data());
    o.crop = crop_indices(CropKind::sphere, cam, Eigen::Vector3d(0, 0, 500), 40.0);
    return o;
}

}  // namespace

TEST_CASE("geometry results do not depend on the OpenMP thread count", "[geometry]") {
#ifndef _OPENMP
    testing::mark_skipped("built without OpenMP: nothing to compare");
    return;
#else
    const int saved = omp_get_max_threads();
    omp_set_num_threads(1);
    const Outputs a = run_all();
    omp_set_num_threads(4);
    const Outputs b = run_all();
    omp_set_num_threads(saved);
    CHECK(a.samples == b.samples);
    CHECK(a.labels == b.labels);
    CHECK(a.adds_value == b.adds_value);  // bitwise: fixed-order sum
    CHECK(a.diameter == b.diameter);
    CHECK(a.rotations == b.rotations);
    CHECK(a.crop == b.crop);
    CHECK(a.samples.rows() > 1000);
#endif
}
