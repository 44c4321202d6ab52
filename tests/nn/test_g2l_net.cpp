// SPDX-License-Identifier: MIT
#include <functional>
#include <algorithm>
#include <chrono>
#include <iostream>

#include <catch2/catch.hpp>

#include "core/autograd.h"
#include "core/rng.h"
#include "gradcheck.h"
#include "nn/models/g2l_net.h"
#include "nn/models/g2l_pose.h"
#include "nn/ops/concat_conv.h"
#include "nn/ops/elementwise.h"
#include "nn/ops/linear.h"
#include "nn/ops/loss.h"
#include "nn/ops/reduce.h"
#include "nn/ops/shape.h"

using namespace g2l;

namespace {

Tensor onehot_of(const std::vector<int>& cls, int C) {
    Tensor t = Tensor::zeros({int64_t(cls.size()), C});
    for (size_t b = 0; b < cls.size(); ++b) t.data<float>()[b * size_t(C) + size_t(cls[b])] = 1.f;
    return t;
}

Tensor points(int64_t B, int64_t N, uint64_t seed) {
    Rng rng(seed);
    return Tensor::randn({B, 3, N}, rng);
}

int64_t count(const nn::Module& m) { return m.num_parameters(); }

bool has_grad(const nn::Module& m) {
    for (const auto& [n, t] : m.named_parameters())
        if (t.grad().defined()) return true;
    return false;
}

bool all_have_grad(const nn::Module& m) {
    for (const auto& [n, t] : m.named_parameters())
        if (!t.grad().defined()) return false;
    return true;
}

Tensor param_named(const nn::Module& m, const std::string& name) {
    for (const auto& [n, t] : m.named_parameters())
        if (n == name) return t;
    FAIL("no parameter " << name);
    return Tensor();
}

}  // namespace

TEST_CASE("G2LNet: parameter counts equal the official networks (spec 4.7)", "[models]") {
    nn::G2LConfig cfg;  // width 1, 16 classes, K = 8, evf and rre on
    const nn::G2LNet net(cfg);
    CHECK(count(*net.seg()) == 1490306);
    CHECK(count(*net.evf()) == 1493144);
    CHECK(count(*net.tnet()) == 861699 - 525312);  // the unused official conv4 is not built
    CHECK(count(*net.rot()) == 3114776);
    CHECK(count(*net.rre()) == 614552);
    CHECK(net.num_parameters() == 1490306 + 1493144 + 336387 + 3114776 + 614552);

    const auto sd = net.state_dict();
    REQUIRE(sd.count("seg.backbone.conv1.weight") == 1);
    CHECK(sd.at("seg.backbone.conv5.weight").shape() == Shape{1024, 128});
    CHECK(sd.at("seg.head.conv1.weight").shape() == Shape{512, 2256});
    CHECK(sd.at("evf.out.weight").shape() == Shape{24, 128});
    CHECK(sd.at("rot.mlp.conv1.weight").shape() == Shape{1024, 2280});
    CHECK(sd.at("rot.out.weight").shape() == Shape{24, 128});
    CHECK(sd.at("rre.mlp.conv1.weight").shape() == Shape{256, 2256});
    CHECK(sd.at("tnet.fc.fc1.weight").shape() == Shape{256, 528});
    CHECK(sd.count("seg.backbone.bn5.running_var") == 1);

    // The baseline: no block A; B owns a backbone and sees 2256 channels.
    cfg.evf = false;
    cfg.rre = false;
    cfg.num_keypoints = 4;
    const nn::G2LNet base(cfg);
    REQUIRE(base.evf() == nullptr);
    REQUIRE(base.rre() == nullptr);
    const auto sdb = base.state_dict();
    CHECK(sdb.at("rot.mlp.conv1.weight").shape() == Shape{1024, 2256});
    CHECK(sdb.count("rot.backbone.conv1.weight") == 1);
    for (const auto& [n, t] : sdb) CHECK((n.rfind("evf.", 0) != 0 && n.rfind("rre.", 0) != 0));
}

TEST_CASE("G2LNet: width multiplier scales hidden widths with a minimum of 8", "[models]") {
    CHECK(nn::scaled_width(1024, 1.0) == 1024);
    CHECK(nn::scaled_width(64, 0.25) == 16);
    CHECK(nn::scaled_width(64, 0.1) == 8);   // round(6.4) = 6 -> min 8
    CHECK(nn::scaled_width(128, 0.3) == 38);  // round(38.4)
    nn::G2LConfig cfg;
    cfg.width = 0.25;
    const nn::G2LNet net(cfg);
    const auto sd = net.state_dict();
    CHECK(sd.at("seg.backbone.conv5.weight").shape() == Shape{256, 32});
    CHECK(sd.at("seg.head.conv1.weight").shape() == Shape{128, 16 + 32 + 256 + 256 + 16});
    CHECK(sd.at("seg.out.weight").shape() == Shape{2, 32});
    CHECK(sd.at("rot.mlp.conv1.weight").shape() == Shape{256, 24 + 16 + 32 + 256 + 256 + 16});
}

TEST_CASE("G2LNet: output shapes for B = 2, N = 50", "[models]") {
    nn::G2LNet net(nn::G2LConfig{});
    const Tensor oh = onehot_of({3, 7}, 16);
    const Tensor logp = net.seg_forward(points(2, 50, 1), oh);
    REQUIRE(logp.shape() == Shape{2, 2, 50});
    // log-probabilities: exp sums to 1 over the 2 channels at every point
    const auto lp = logp.to_vector<float>();
    for (int b = 0; b < 2; ++b)
        for (int n = 0; n < 50; ++n)
            REQUIRE(std::exp(lp[size_t(b * 100 + n)]) + std::exp(lp[size_t(b * 100 + 50 + n)]) ==
                    Approx(1.0).epsilon(1e-5));
    REQUIRE(net.t_forward(points(2, 40, 2), oh).shape() == Shape{2, 3});
    const nn::RotOut r = net.rot_forward(points(2, 50, 3), oh);
    REQUIRE(r.vectors.shape() == Shape{2, 24, 50});
    REQUIRE(r.keypoints.shape() == Shape{2, 8, 3});
    REQUIRE(r.residual.shape() == Shape{2, 8, 3});

    nn::G2LConfig cfg;
    cfg.evf = false;
    cfg.rre = false;
    cfg.num_keypoints = 12;
    cfg.width = 0.25;
    nn::G2LNet base(cfg);
    const nn::RotOut rb = base.rot_forward(points(2, 50, 4), oh);
    REQUIRE_FALSE(rb.vectors.defined());
    REQUIRE_FALSE(rb.residual.defined());
    REQUIRE(rb.keypoints.shape() == Shape{2, 12, 3});
}

TEST_CASE("G2LNet: gradient flow between blocks A, B and C", "[models][grad]") {
    nn::G2LConfig cfg;
    cfg.width = 0.125;
    nn::G2LNet net(cfg);
    const Tensor x = points(2, 30, 5), oh = onehot_of({0, 1}, 16);
    Rng rng(6);
    const Tensor rk = Tensor::randn({2, 8, 3}, rng);

    // B's loss reaches A's head (through A's vectors, which are not detached) ...
    nn::RotOut r = net.rot_forward(x, oh);
    nn::sum(nn::mul(r.keypoints, rk)).backward();
    CHECK(all_have_grad(*net.rot()));
    CHECK(param_named(*net.evf(), "head.conv1.weight").grad().defined());
    CHECK(param_named(*net.evf(), "out.weight").grad().defined());
    // As in the official code, A's head sees A's live backbone output, so B's loss also reaches
    // A's backbone THROUGH the vectors; the feature path into B is detached (checked below).
    CHECK(param_named(*net.evf(), "backbone.conv1.weight").grad().defined());
    CHECK_FALSE(has_grad(*net.rre()));
    CHECK_FALSE(has_grad(*net.seg()));
    CHECK_FALSE(has_grad(*net.tnet()));

    // ... but not through the features: with A's vectors cut, nothing of A gets a gradient.
    net.zero_grad();
    const nn::EvfOut a = net.evf()->forward(x, oh);
    for (const Tensor& t : {a.feat.x1, a.feat.x2, a.feat.pf, a.feat.g}) {
        CHECK_FALSE(t.requires_grad());
        CHECK(t.grad_fn() == nullptr);
    }
    nn::sum(nn::mul(net.rot()->forward(a.vectors.detach(), a.feat), rk)).backward();
    CHECK(all_have_grad(*net.rot()));
    CHECK_FALSE(has_grad(*net.evf()));

    // C's loss does not reach A (nor B) at all.
    net.zero_grad();
    r = net.rot_forward(x, oh);
    nn::sum(nn::mul(r.residual, rk)).backward();
    CHECK(all_have_grad(*net.rre()));
    CHECK_FALSE(has_grad(*net.evf()));
    CHECK_FALSE(has_grad(*net.rot()));

    // A's own loss trains its backbone and head.
    net.zero_grad();
    r = net.rot_forward(x, oh);
    nn::sum(nn::square(r.vectors)).backward();
    CHECK(all_have_grad(*net.evf()));
    CHECK_FALSE(has_grad(*net.rot()));
}

TEST_CASE("G2LNet: the evf-off baseline trains B's own backbone, C sees it detached",
          "[models][grad]") {
    nn::G2LConfig cfg;
    cfg.width = 0.125;
    cfg.evf = false;
    nn::G2LNet net(cfg);
    const Tensor x = points(2, 30, 7), oh = onehot_of({2, 3}, 16);
    nn::RotOut r = net.rot_forward(x, oh);
    nn::sum(r.keypoints).backward();
    CHECK(param_named(*net.rot(), "backbone.conv1.weight").grad().defined());
    CHECK_FALSE(has_grad(*net.rre()));
    net.zero_grad();
    r = net.rot_forward(x, oh);
    nn::sum(r.residual).backward();
    CHECK(all_have_grad(*net.rre()));
    CHECK_FALSE(has_grad(*net.rot()));
}

TEST_CASE("G2LNet: train and eval modes differ (batch norm, dropout)", "[models]") {
    nn::G2LConfig cfg;
    cfg.width = 0.125;
    nn::G2LNet net(cfg);
    const Tensor x = points(2, 40, 8), oh = onehot_of({0, 5}, 16);
    const auto running0 = net.state_dict().at("seg.backbone.bn1.running_mean").to_vector<float>();
    const auto t1 = net.seg_forward(x, oh).to_vector<float>();
    const auto t2 = net.seg_forward(x, oh).to_vector<float>();
    CHECK(t1 != t2);  // fresh dropout masks
    const auto running1 = net.state_dict().at("seg.backbone.bn1.running_mean").to_vector<float>();
    CHECK(running0 != running1);  // training updates the running statistics
    net.eval();
    REQUIRE_FALSE(net.seg()->is_training());
    autograd::NoGradGuard no_grad;
    const Tensor e1 = net.seg_forward(x, oh);
    CHECK(e1.grad_fn() == nullptr);  // no graph is recorded under NoGradGuard
    const auto e2 = net.seg_forward(x, oh).to_vector<float>();
    CHECK(e1.to_vector<float>() == e2);  // deterministic
    CHECK(e1.to_vector<float>() != t1);
    CHECK(net.state_dict().at("seg.backbone.bn1.running_mean").to_vector<float>() == running1);
    const auto k1 = net.rot_forward(x, oh).keypoints.to_vector<float>();
    CHECK(net.rot_forward(x, oh).keypoints.to_vector<float>() == k1);
}

TEST_CASE("G2LNet: official head column order maps onto ours", "[models]") {
    // Tiny example: c1 = c2 = 1, c5 = 2, 1 class: official [x1 x2 g0 g1 pf0 pf1 oh].
    CHECK(nn::official_head_columns(0, 1, 1, 2, 1) == std::vector<int64_t>{0, 1, 4, 5, 2, 3, 6});
    CHECK(nn::official_head_columns(2, 1, 1, 1, 1) == std::vector<int64_t>{0, 1, 2, 3, 5, 4, 6});
    // A permuted official weight applied to the official materialised input gives our output.
    Rng rng(9);
    const int64_t B = 2, N = 6, c1 = 3, c2 = 4, c5 = 5, C = 2, Ctot = c1 + c2 + 2 * c5 + C;
    const Tensor x1 = Tensor::randn({B, c1, N}, rng), x2 = Tensor::randn({B, c2, N}, rng);
    const Tensor pf = Tensor::randn({B, c5, N}, rng), g = Tensor::randn({B, c5}, rng);
    const Tensor oh = onehot_of({1, 0}, int(C));
    const Tensor w = Tensor::randn({7, Ctot}, rng);
    const auto cols = nn::official_head_columns(0, c1, c2, c5, C);
    Tensor w_off = Tensor::zeros({7, Ctot});
    for (int64_t o = 0; o < 7; ++o)
        for (int64_t i = 0; i < Ctot; ++i)
            w_off.data<float>()[o * Ctot + cols[size_t(i)]] = w.data<float>()[o * Ctot + i];
    auto tile = [N](const Tensor& v) { return nn::repeat(nn::unsqueeze(v, 2), 2, N); };
    const Tensor official = nn::conv1x1(nn::concat({x1, x2, tile(g), pf, tile(oh)}, 1), w_off);
    const Tensor ours = nn::concat_conv1x1({x1, x2, pf}, {g, oh}, w);
    CHECK(testing::max_abs_diff(official, ours) < 1e-5);
}

TEST_CASE("G2LNet: param_groups cover every parameter once with the given multipliers",
          "[models]") {
    nn::G2LConfig cfg;
    cfg.width = 0.125;
    const nn::G2LNet net(cfg);
    const auto groups = net.param_groups();
    REQUIRE(groups.size() == 5);
    const std::vector<std::pair<std::string, double>> want = {
        {"seg", 1}, {"tnet", 10}, {"evf", 1}, {"rot", 30}, {"rre", 20}};
    int64_t total = 0;
    for (size_t i = 0; i < groups.size(); ++i) {
        CHECK(groups[i].name == want[i].first);
        CHECK(groups[i].lr_mult == want[i].second);
        for (const auto& [n, t] : groups[i].params) {
            CHECK(n.rfind(want[i].first + ".", 0) == 0);
            total += t.numel();
        }
    }
    CHECK(total == net.num_parameters());
    CHECK(groups[0].params[0].first == "seg.backbone.conv1.weight");
    nn::G2LLrMults m;
    m.rot = 2;
    cfg.rre = false;
    const auto g2 = nn::G2LNet(cfg).param_groups(m, 1e-4);
    REQUIRE(g2.size() == 4);
    CHECK(g2[3].name == "rot");
    CHECK(g2[3].lr_mult == 2);
    CHECK(g2[3].weight_decay == 1e-4);
}

TEST_CASE("G2LNet: a tiny network overfits one batch with Adam", "[models][train]") {
    nn::G2LConfig cfg;
    cfg.width = 0.0625;
    cfg.num_classes = 4;
    cfg.num_keypoints = 4;
    nn::G2LNet net(cfg);
    const int64_t B = 4, N = 64, K = 4;
    const Tensor x = points(B, N, 10), oh = onehot_of({0, 1, 2, 3}, 4);
    // Toy targets: object = points with x > 0; fixed random translation / keypoints / vectors.
    Tensor labels = Tensor::empty({B, N}, DType::I32);
    for (int64_t i = 0; i < B * N; ++i)
        labels.data<int32_t>()[i] = x.data<float>()[(i / N) * 3 * N + i % N] > 0 ? 1 : 0;
    Rng rng(11);
    const Tensor t_gt = Tensor::randn({B, 3}, rng), kp_gt = Tensor::randn({B, K, 3}, rng);
    const Tensor vec_gt = Tensor::randn({B, 3 * K, N}, rng), res_gt = Tensor::randn({B, K, 3}, rng);
    nn::AdamOptions opt;
    opt.lr = 1e-2;
    opt.beta2 = 0.99;
    nn::Adam adam(net.param_groups(nn::G2LLrMults{1, 1, 1, 1, 1}), opt);
    auto loss_fn = [&]() {
        const Tensor l_seg = nn::nll_loss(net.seg_forward(x, oh), labels);
        const Tensor l_t = nn::mse_loss(net.t_forward(x, oh), t_gt);
        const nn::RotOut r = net.rot_forward(x, oh);
        return l_seg + l_t + nn::mse_loss(r.vectors, vec_gt) + nn::mse_loss(r.keypoints, kp_gt) +
               nn::mse_loss(r.residual, res_gt);
    };
    double first = 0, last = 0;
    for (int step = 0; step < 30; ++step) {
        adam.zero_grad();
        const Tensor loss = loss_fn();
        const double v = loss.item<double>();
        REQUIRE(std::isfinite(v));
        if (step == 0) first = v;
        last = v;
        loss.backward();
        adam.step();
    }
    INFO("loss " << first << " -> " << last);
    CHECK(last < 0.45 * first);  // measured (2026-12-01): 7.79 -> 2.64 (x0.34)
}

TEST_CASE("same_architecture: every shaping field counts, dropout and seed do not", "[models]") {
    const nn::G2LConfig a;
    nn::G2LConfig b = a;
    b.dropout = 0.5, b.rre_dropout = 0.1, b.seed = 99;  // training only
    CHECK(nn::same_architecture(a, b));
    const std::vector<std::function<void(nn::G2LConfig&)>> changes = {
        [](nn::G2LConfig& c) { c.num_classes = 21; },
        [](nn::G2LConfig& c) { c.num_keypoints = 12; },
        [](nn::G2LConfig& c) { c.evf = false; },
        [](nn::G2LConfig& c) { c.rre = false; },
        [](nn::G2LConfig& c) { c.width = 0.5; },
        [](nn::G2LConfig& c) { c.out_scale_mm = 100; },
        [](nn::G2LConfig& c) { c.rot_unit = "kp_rms"; },
        [](nn::G2LConfig& c) { c.class_heads = true; },
    };
    for (size_t i = 0; i < changes.size(); ++i) {
        nn::G2LConfig c = a;
        changes[i](c);
        INFO("change " << i);
        CHECK_FALSE(nn::same_architecture(a, c));
        CHECK_FALSE(nn::same_architecture(c, a));
    }
}

TEST_CASE("G2LNet: wrong input shapes and configs throw naming the value", "[models][errors]") {
    nn::G2LConfig cfg;
    cfg.width = 0.125;
    nn::G2LNet net(cfg);
    const Tensor oh = onehot_of({0, 1}, 16);
    Rng rng(12);
    const Tensor bnx3 = Tensor::randn({2, 50, 3}, rng);  // points-last: wrong layout
    REQUIRE_THROWS_WITH(net.seg_forward(bnx3, oh),
                        Catch::Contains("SegNet") && Catch::Contains("[B, 3, N]") &&
                            Catch::Contains("[2, 50, 3]"));
    REQUIRE_THROWS_WITH(net.t_forward(bnx3, oh), Catch::Contains("TNet") &&
                                                     Catch::Contains("[2, 50, 3]"));
    REQUIRE_THROWS_WITH(net.rot_forward(bnx3, oh), Catch::Contains("EvfNet") &&
                                                       Catch::Contains("[2, 50, 3]"));
    REQUIRE_THROWS_WITH(net.seg_forward(points(2, 0, 1), oh), Catch::Contains("[2, 3, 0]"));
    REQUIRE_THROWS_WITH(net.seg_forward(points(2, 10, 1), onehot_of({0, 1}, 5)),
                        Catch::Contains("[2, 16]") && Catch::Contains("[2, 5]"));
    REQUIRE_THROWS_WITH(net.seg_forward(points(3, 10, 1), oh),
                        Catch::Contains("[3, 16]") && Catch::Contains("[2, 16]"));
    REQUIRE_THROWS_WITH(net.seg_forward(points(2, 10, 1).to(DType::F64), oh),
                        Catch::Contains("dtype"));
    REQUIRE_THROWS_WITH(net.rot()->forward(Tensor::zeros({2, 5, 10}), nn::PointFeatures{}),
                        Catch::Contains("[B, 24, N]") && Catch::Contains("[2, 5, 10]"));
    nn::G2LConfig bad = cfg;
    bad.num_keypoints = 2;
    REQUIRE_THROWS_WITH(nn::G2LNet(bad), Catch::Contains("num_keypoints") && Catch::Contains("2"));
    bad = cfg;
    bad.width = 0;
    REQUIRE_THROWS_WITH(nn::G2LNet(bad), Catch::Contains("width"));
    bad = cfg;
    bad.dropout = 1.0;
    REQUIRE_THROWS_WITH(nn::G2LNet(bad), Catch::Contains("dropout") && Catch::Contains("1"));
    bad = cfg;
    bad.num_classes = 0;
    REQUIRE_THROWS_WITH(nn::G2LNet(bad), Catch::Contains("num_classes"));
}

// Timing of one training batch at width 1 (B = 8, N = 1500 seg, M = 1000 rot): hidden and
// [slow] (a sanitizer run with "~[slow]" would otherwise include it), run with
// `test_nn "[perf]"`. It prints times and checks the backward pass only: speed targets live in
// g2l_bench, never in timed unit tests.
TEST_CASE("G2LNet: forward + backward time of one batch at width 1", "[.][perf][slow][models]") {
    nn::G2LNet net(nn::G2LConfig{});
    const Tensor oh = onehot_of({0, 1, 2, 3, 4, 5, 6, 7}, 16);
    const Tensor xs = points(8, 1500, 13), xr = points(8, 1000, 14), xt = points(8, 1000, 15);
    Tensor labels = Tensor::zeros({8, 1500}, DType::I32);
    double best = 1e30;
    for (int rep = 0; rep < 4; ++rep) {
        using Clock = std::chrono::steady_clock;
        const auto t0 = Clock::now();
        const Tensor l_seg = nn::nll_loss(net.seg_forward(xs, oh), labels);
        const auto t1 = Clock::now();
        const Tensor l_t = nn::sum(net.t_forward(xt, oh));
        const nn::RotOut r = net.rot_forward(xr, oh);
        const Tensor loss = l_seg + l_t + nn::mean(nn::square(r.vectors)) +
                            nn::mean(r.keypoints) + nn::mean(r.residual);
        const auto t2 = Clock::now();
        loss.backward();
        const auto t3 = Clock::now();
        auto ms = [](auto a, auto b) {
            return std::chrono::duration<double, std::milli>(b - a).count();
        };
        std::cout << "seg fwd " << ms(t0, t1) << " ms, t+rot fwd " << ms(t1, t2)
                  << " ms, backward " << ms(t2, t3) << " ms, total " << ms(t0, t3) << " ms\n";
        best = std::min(best, ms(t0, t3));
        if (rep == 0)
            for (const auto& [name, p] : net.named_parameters()) {
                INFO(name);
                CHECK(p.grad().defined());
            }
        net.zero_grad();
    }
    std::cout << "best forward + backward: " << best << " ms per batch of 8\n";
}

TEST_CASE("even_sample: a deterministic stride, or every point once plus spread repeats",
          "[nn][pose]") {
    CHECK(nn::even_sample(10, 5) == std::vector<int>{0, 2, 4, 6, 8});
    CHECK(nn::even_sample(4, 4) == std::vector<int>{0, 1, 2, 3});
    CHECK(nn::even_sample(3, 7) == std::vector<int>{0, 1, 2, 0, 0, 1, 2});
    CHECK(nn::even_sample(0, 5).empty());
    CHECK(nn::even_sample(5, 0).empty());
    const auto big = nn::even_sample(100000, 1500);
    REQUIRE(big.size() == 1500);
    CHECK(std::is_sorted(big.begin(), big.end()));
    CHECK(big.back() < 100000);
}

TEST_CASE("rot_forward: a per-sample scale divides the input and scales the outputs",
          "[nn][g2l]") {
    nn::G2LConfig c;
    c.num_classes = 1;
    c.width = 0.125;
    c.rot_unit = "kp_rms";
    nn::G2LNet net(c);
    net.eval();
    autograd::NoGradGuard ng;
    Rng rng(3);
    Tensor x = Tensor::empty({1, 3, 40});
    for (int i = 0; i < 120; ++i) x.data<float>()[i] = float(rng.uniform(-60, 60));
    const Tensor oh = Tensor::ones({1, 1});
    Tensor s1 = Tensor::ones({1, 1, 1});
    Tensor s2 = Tensor::empty({1, 1, 1});
    s2.data<float>()[0] = 2.f;
    Tensor x2 = Tensor::empty({1, 3, 40});
    for (int i = 0; i < 120; ++i) x2.data<float>()[i] = 2.f * x.data<float>()[i];
    // Doubling the points and the scale doubles the keypoints (the network sees the same input).
    const auto k1 = net.rot_forward(x, oh, s1).keypoints.to_vector<float>();
    const auto k2 = net.rot_forward(x2, oh, s2).keypoints.to_vector<float>();
    for (size_t i = 0; i < k1.size(); ++i) CHECK(k2[i] == Approx(2 * k1[i]).margin(1e-4));
    CHECK_THROWS_WITH(net.rot_forward(x, oh, Tensor::ones({1, 3})), Catch::Contains("[B, 1, 1]"));
}

TEST_CASE("select_class_block: picks each sample's block, gradients reach only that block",
          "[nn][g2l][grad]") {
    // x [B=3, C*F = 4*2] and [B, C*F, N=3]; classes 2, 0, 3.
    Rng rng(11);
    Tensor x = Tensor::randn({3, 8}, rng);
    const Tensor oh = onehot_of({2, 0, 3}, 4);
    const Tensor y = nn::select_class_block(x, oh);
    REQUIRE(y.shape() == Shape{3, 2});
    const float* xv = x.data<float>();
    CHECK(y.data<float>()[0] == xv[0 * 8 + 2 * 2]);
    CHECK(y.data<float>()[1] == xv[0 * 8 + 2 * 2 + 1]);
    CHECK(y.data<float>()[2] == xv[1 * 8 + 0]);
    CHECK(y.data<float>()[5] == xv[2 * 8 + 3 * 2 + 1]);
    Tensor x3 = Tensor::randn({3, 8, 3}, rng);
    const Tensor y3 = nn::select_class_block(x3, oh);
    REQUIRE(y3.shape() == Shape{3, 2, 3});
    // sample 1 (class 0), channel 1, point 2 = x3[1, 0*2 + 1, 2]
    CHECK(y3.data<float>()[(1 * 2 + 1) * 3 + 2] == x3.data<float>()[(1 * 8 + 1) * 3 + 2]);
    const Tensor oh64 = oh.to(DType::F64);
    Tensor xin = testing::distinct_values({3, 8, 3}, 5);
    xin.set_requires_grad(true);
    testing::gradcheck([&](const std::vector<Tensor>& in) { return nn::select_class_block(in[0], oh64); },
                       {xin});
    CHECK_THROWS_WITH(nn::select_class_block(Tensor::zeros({3, 7}), oh), Catch::Contains("[B, C*F]"));
    CHECK_THROWS_WITH(nn::select_class_block(x, Tensor::zeros({2, 4})), Catch::Contains("onehot"));
}

TEST_CASE("G2LNet class_heads: one output block per class in A, B and C, classes train apart",
          "[nn][g2l]") {
    nn::G2LConfig c;
    c.num_classes = 3;
    c.width = 0.125;
    c.rot_unit = "kp_rms";
    c.class_heads = true;
    nn::G2LNet net(c);
    const int K = c.num_keypoints;
    CHECK(param_named(net, "rot.out.weight").size(0) == 3 * 3 * K);
    CHECK(param_named(net, "evf.out.weight").size(0) == 3 * 3 * K);
    CHECK(param_named(net, "rre.out.weight").size(0) == 3 * 3 * K);
    nn::G2LConfig plain = c;
    plain.class_heads = false;
    CHECK(nn::G2LNet(plain).num_parameters() < net.num_parameters());
    // A loss on class 1's samples only: block B's output rows of classes 0 and 2 get no gradient.
    Rng rng(4);
    const Tensor x = Tensor::randn({2, 3, 30}, rng);
    const Tensor oh = onehot_of({1, 1}, 3);
    const nn::RotOut r = net.rot_forward(x, oh, Tensor::ones({2, 1, 1}));
    REQUIRE(r.keypoints.shape() == Shape{2, K, 3});
    REQUIRE(r.vectors.shape() == Shape{2, 3 * K, 30});
    nn::sum(nn::square(r.keypoints)).backward();
    const Tensor g = param_named(net, "rot.out.weight").grad();
    REQUIRE(g.defined());
    const int64_t in = g.size(1);
    double other = 0, own = 0;
    for (int64_t row = 0; row < 3 * 3 * K; ++row)
        for (int64_t j = 0; j < in; ++j) {
            const double v = std::abs(g.data<float>()[row * in + j]);
            (row / (3 * K) == 1 ? own : other) += v;
        }
    CHECK(other == 0.0);
    CHECK(own > 0.0);
}
