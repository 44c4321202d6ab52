// SPDX-License-Identifier: MIT
// nn::PoseEngine (the fast inference path) against nn::estimate_pose (the eval-mode autograd
// graph): the same object points, translation and rotation up to float rounding, for every
// network variant; several objects batched = one by one; no heap allocation after warm-up.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>

#include <catch2/catch.hpp>

#include "core/rng.h"
#include "nn/models/g2l_engine.h"
#include "nn/models/g2l_pose.h"

using namespace g2l;

namespace {

std::atomic<long> g_allocs{0};
std::atomic<bool> g_count{false};

// A crop: an ellipsoid-ish object blob in front of a background plane.
geom::Points make_crop(int n, uint64_t seed) {
    Rng rng(seed);
    geom::Points p(n, 3);
    for (int i = 0; i < n; ++i) {
        if (i % 3 == 0) {
            p.row(i) << float(rng.uniform(-150, 150)), float(rng.uniform(-150, 150)),
                float(900 + rng.uniform(-3, 3));
        } else {
            p.row(i) << float(rng.normal(0, 30)), float(rng.normal(10, 40)), float(760 + rng.normal(0, 25));
        }
    }
    return p;
}

std::vector<Eigen::Vector3f> box_keypoints(float sx, float sy, float sz) {
    std::vector<Eigen::Vector3f> k;
    for (int i = 0; i < 8; ++i)
        k.emplace_back((i & 1) ? sx : -sx, (i & 2) ? sy : -sy, (i & 4) ? sz : -sz);
    return k;
}

// A random network whose BatchNorm statistics are not the identity, and whose segmentation
// keeps a good share of the points (output bias).
nn::G2LNet make_net(const nn::G2LConfig& c, uint64_t seed) {
    nn::G2LNet net(c);
    Rng rng(seed);
    for (auto& [name, t] : net.named_buffers()) {
        if (t.dtype() != DType::F32) continue;
        float* v = t.data<float>();
        const bool var = name.find("running_var") != std::string::npos;
        const bool mean = name.find("running_mean") != std::string::npos;
        for (int64_t i = 0; i < t.numel(); ++i)
            if (var) v[i] = float(0.5 + rng.uniform());
            else if (mean) v[i] = float(rng.uniform(-0.2, 0.2));
    }
    for (auto& [name, t] : net.named_parameters()) {
        if (name.find(".bn") != std::string::npos && name.find(".weight") != std::string::npos)
            for (int64_t i = 0; i < t.numel(); ++i) t.data<float>()[i] = float(0.5 + rng.uniform());
        if (name == "seg.out.bias") t.data<float>()[1] = 0.3f;
    }
    net.eval();
    return net;
}

// A width-0.25 network with per-class heads and the kp_rms rotation unit.
nn::G2LConfig class_heads_config(int num_classes) {
    nn::G2LConfig c;
    c.num_classes = num_classes;
    c.width = 0.25;
    c.class_heads = true;
    c.rot_unit = "kp_rms";
    return c;
}

void check_same(const nn::PoseEstimate& a, const nn::PoseEstimate& b) {
    REQUIRE(a.ok == b.ok);
    CHECK(a.status == b.status);
    CHECK(a.num_object_points == b.num_object_points);
    if (!a.ok) return;
    for (int r = 0; r < 3; ++r) {
        CHECK(a.pose.t[r] == Approx(b.pose.t[r]).epsilon(1e-4).margin(1e-3));
        for (int c = 0; c < 3; ++c) CHECK(a.pose.R(r, c) == Approx(b.pose.R(r, c)).margin(2e-4));
    }
}

}  // namespace

// Every replaceable global allocation function, counted and on malloc/free (so that the
// sanitizers see matching pairs whichever form the code uses).
namespace {
void* counted_alloc(std::size_t n) {
    if (g_count.load(std::memory_order_relaxed)) g_allocs.fetch_add(1, std::memory_order_relaxed);
    return std::malloc(n ? n : 1);
}
}  // namespace
void* operator new(std::size_t n) {
    if (void* p = counted_alloc(n)) return p;
    throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
    if (void* p = counted_alloc(n)) return p;
    throw std::bad_alloc();
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return counted_alloc(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return counted_alloc(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }

TEST_CASE("PoseEngine: the poses of the eval-mode graph for every network variant", "[nn][engine]") {
    struct Variant {
        bool evf, rre, class_heads;
        std::string unit;
        double out_scale;
    };
    const std::vector<Variant> variants = {{true, true, false, "kp_rms", 1},
                                           {true, true, true, "kp_rms", 1},
                                           {false, true, false, "mm", 1},
                                           {true, false, true, "mm", 50},
                                           {false, false, false, "kp_rms", 1}};
    const auto kps = box_keypoints(40, 30, 55);
    for (size_t v = 0; v < variants.size(); ++v) {
        INFO("variant " << v);
        nn::G2LConfig c;
        c.num_classes = 4;
        c.width = 0.25;
        c.evf = variants[v].evf;
        c.rre = variants[v].rre;
        c.class_heads = variants[v].class_heads;
        c.rot_unit = variants[v].unit;
        c.out_scale_mm = variants[v].out_scale;
        c.seed = 3 + v;
        nn::G2LNet net = make_net(c, 10 + v);
        nn::PoseEngine eng(net);
        for (int trial = 0; trial < 3; ++trial) {
            const geom::Points crop = make_crop(trial == 2 ? 300 : 3000, 100 + trial);
            const int cls = trial % 4;
            const int cp = trial == 1 ? 0 : 512, op = trial == 1 ? 0 : 256;
            const nn::PoseEstimate ref = nn::estimate_pose(net, crop, cls, kps, op, cp);
            const nn::PoseEstimate got = eng.estimate(crop, cls, kps, op, cp);
            REQUIRE(ref.ok);
            check_same(got, ref);
        }
    }
}

TEST_CASE("PoseEngine: several objects batched give each object's own result, failures keep "
          "their status", "[nn][engine]") {
    nn::G2LNet net = make_net(class_heads_config(3), 7);
    nn::PoseEngine eng(net);
    const auto k0 = box_keypoints(40, 30, 55), k1 = box_keypoints(90, 20, 20);
    const geom::Points a = make_crop(2000, 1), b = make_crop(900, 2), tiny = make_crop(5, 3);
    const std::vector<nn::PoseQuery> q = {{&a, 0, &k0}, {&tiny, 1, &k1}, {&b, 2, &k1}, {&a, 1, &k1}};
    std::vector<nn::PoseEstimate> batch;
    eng.estimate(q, 300, 700, &batch);
    REQUIRE(batch.size() == 4);
    CHECK(batch[1].status == "too few crop points");
    CHECK_FALSE(batch[1].ok);
    for (size_t i : {size_t(0), size_t(2), size_t(3)}) {
        INFO("query " << i);
        const nn::PoseEstimate one = eng.estimate(*q[i].crop, q[i].class_index, *q[i].keypoints, 300, 700);
        check_same(batch[i], one);
        check_same(batch[i], nn::estimate_pose(net, *q[i].crop, q[i].class_index, *q[i].keypoints, 300, 700));
    }
    CHECK_THROWS_WITH(eng.estimate(a, 3, k0, 300, 700), Catch::Contains("class index 3"));
    const std::vector<Eigen::Vector3f> k5(k0.begin(), k0.begin() + 5);
    CHECK_THROWS_WITH(eng.estimate(a, 0, k5, 300, 700), Catch::Contains("5 model keypoints"));
    CHECK_THROWS_WITH(eng.estimate({{nullptr, 0, &k0}}, 300, 700, &batch), Catch::Contains("null crop"));
}

TEST_CASE("PoseEngine: given object points and translation replace the seg net's and the "
          "T-net's, the rows taken are reported", "[nn][engine]") {
    nn::G2LNet net = make_net(class_heads_config(2), 11);
    nn::PoseEngine eng(net);
    const auto kps = box_keypoints(40, 30, 55);
    const geom::Points crop = make_crop(1500, 5);
    const int cp = 600, op = 256;
    const std::vector<int> seen = nn::even_sample(int(crop.rows()), cp);
    std::vector<nn::PoseEstimate> out;

    // The rows the seg net took: a subset of the rows it saw, as many as it reports.
    std::vector<int> rows;
    nn::PoseQuery q{&crop, 1, &kps};
    q.object_rows = &rows;
    eng.estimate({q}, op, cp, &out);
    REQUIRE(out[0].ok);
    REQUIRE_FALSE(rows.empty());
    CHECK(int(rows.size()) == out[0].num_object_points);
    for (int r : rows) CHECK(std::find(seen.begin(), seen.end(), r) != seen.end());
    const nn::PoseEstimate plain = out[0];

    // A mask that flags exactly those rows gives the same estimate to the bit.
    std::vector<uint8_t> mask(size_t(crop.rows()), 0);
    for (int r : rows) mask[size_t(r)] = 1;
    nn::PoseQuery qm = q;
    qm.object_mask = &mask;
    std::vector<int> rows_m;
    qm.object_rows = &rows_m;
    eng.estimate({qm}, op, cp, &out);
    CHECK(rows_m == rows);
    CHECK(out[0].pose.R == plain.pose.R);
    CHECK(out[0].pose.t == plain.pose.t);

    // The blob (every row not on the background plane at z ~ 900) as the object: the rows taken
    // are the seen blob rows, and the estimate differs from the seg net's.
    std::vector<uint8_t> blob(size_t(crop.rows()), 0);
    for (int64_t r = 0; r < crop.rows(); ++r) blob[size_t(r)] = r % 3 != 0;
    qm.object_mask = &blob;
    eng.estimate({qm}, op, cp, &out);
    REQUIRE(out[0].ok);
    std::vector<int> want;
    for (int r : seen)
        if (r % 3 != 0) want.push_back(r);
    CHECK(rows_m == want);
    CHECK(out[0].num_object_points == int(want.size()));
    CHECK((out[0].pose.t - plain.pose.t).norm() > 1e-3);

    // The T-net's own translation given back: the same rotation to the bit; another one is
    // the estimate's translation and changes the rotation input (so the rotation).
    Eigen::Vector3f t = plain.pose.t.cast<float>();
    nn::PoseQuery qt = q;
    qt.translation = &t;
    eng.estimate({qt}, op, cp, &out);
    CHECK(out[0].pose.R == plain.pose.R);
    t += Eigen::Vector3f(30, -20, 15);
    eng.estimate({qt}, op, cp, &out);
    CHECK(out[0].pose.t == t.cast<double>());
    CHECK((out[0].pose.R - plain.pose.R).norm() > 1e-6);

    // No flagged point: too few object points, and the rows taken are empty.
    std::vector<uint8_t> none(size_t(crop.rows()), 0);
    qm.object_mask = &none;
    eng.estimate({qm}, op, cp, &out);
    CHECK_FALSE(out[0].ok);
    CHECK(out[0].status == "too few object points");
    CHECK(rows_m.empty());

    // Bad input is named.
    std::vector<uint8_t> short_mask(10, 1);
    qm.object_mask = &short_mask;
    CHECK_THROWS_WITH(eng.estimate({qm}, op, cp, &out),
                      Catch::Contains("object mask of 10 flags for 1500 crop points"));
    Eigen::Vector3f bad(0, std::nanf(""), 700);
    qt.translation = &bad;
    CHECK_THROWS_WITH(eng.estimate({qt}, op, cp, &out), Catch::Contains("non-finite translation"));
}

TEST_CASE("PoseEngine: no heap allocation per frame after warm-up", "[nn][engine]") {
    nn::G2LConfig c;
    c.num_classes = 2;
    c.width = 0.25;
    c.rot_unit = "kp_rms";
    nn::G2LNet net = make_net(c, 9);
    nn::PoseEngine eng(net);
    const auto kp = box_keypoints(40, 30, 55);
    const geom::Points a = make_crop(3000, 5), b = make_crop(2500, 6);
    const std::vector<nn::PoseQuery> q = {{&a, 0, &kp}, {&b, 1, &kp}};
    std::vector<nn::PoseEstimate> out;
    eng.estimate(q, 512, 1024, &out);  // warm-up: buffers grow
    eng.estimate(q, 512, 1024, &out);
    REQUIRE(out[0].ok);
    g_allocs = 0;
    g_count = true;
    for (int i = 0; i < 3; ++i) eng.estimate(q, 512, 1024, &out);
    g_count = false;
    CHECK(g_allocs.load() == 0);
    CHECK(out[1].ok);
    // The graph path allocates (a sanity check that the counter counts).
    g_allocs = 0;
    g_count = true;
    (void)nn::estimate_pose(net, a, 0, kp, 512, 1024);
    g_count = false;
    CHECK(g_allocs.load() > 100);
}
