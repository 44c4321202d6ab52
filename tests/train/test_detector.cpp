// SPDX-License-Identifier: MIT
// The 2D detector (nn/models/detector.h, train/detector_train.h): peak extraction and box
// decoding on synthetic heat-maps, targets that decode back to their boxes, the focal loss at
// known values, bad configs and exports, and a tiny detector that learns to find coloured squares.
#include <catch2/catch.hpp>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>

#include "core/autograd.h"
#include "core/checkpoint.h"
#include "core/rng.h"
#include "data/bop.h"
#include "eval/detector_eval.h"
#include "geometry/mesh_io.h"
#include <nlohmann/json.hpp>
#include "nn/models/detector.h"
#include "nn/ops/elementwise.h"
#include "nn/optim.h"
#include "testing.h"
#include "train/detector_train.h"

using namespace g2l;
using Catch::Contains;
namespace fs = std::filesystem;

namespace {

// Decodes targets as if they were network outputs (heat as probabilities).
std::vector<nn::Detection> decode_targets(const train::DetTargets& t, int K, int w, int h,
                                          float min_score = 0.5f) {
    return nn::decode_detections(t.heat.data(), t.size.data(), t.offset.data(), K, w, h,
                                 min_score, 5, 4);
}

}  // namespace

TEST_CASE("detector: peaks are local maxima per class, best first, plateaus give one peak",
          "[detector]") {
    const int K = 2, w = 8, h = 6;
    std::vector<float> prob(size_t(K * w * h), 0.f), size(size_t(2 * w * h), 0.f),
        off(size_t(2 * w * h), 0.5f);
    auto at = [&](int k, int x, int y) -> float& { return prob[size_t((k * h + y) * w + x)]; };
    at(0, 2, 1) = 0.9f;
    at(0, 3, 1) = 0.6f;  // neighbour of a higher cell: not a peak
    at(0, 6, 4) = 0.4f;  // a second, weaker peak of class 0
    at(1, 5, 2) = 0.7f;  // a plateau of two equal cells: one peak (the first in row order)
    at(1, 6, 2) = 0.7f;
    at(1, 0, 5) = 0.2f;  // below the threshold
    size[size_t(1 * w + 2)] = std::log(10.f);  // class-agnostic size at (2, 1): 40 x 8 px
    size[size_t(w * h + 1 * w + 2)] = std::log(2.f);
    const auto d = nn::decode_detections(prob.data(), size.data(), off.data(), K, w, h, 0.3f, 5, 4);
    REQUIRE(d.size() == 3);
    REQUIRE(d[0].cls == 0);
    REQUIRE(d[0].score == Approx(0.9f));
    REQUIRE(d[0].peak_x == Approx((2 + 0.5f) * 4));
    REQUIRE(d[0].peak_y == Approx((1 + 0.5f) * 4));
    REQUIRE(d[0].w == Approx(40.f).epsilon(1e-5));
    REQUIRE(d[0].h == Approx(8.f).epsilon(1e-5));
    REQUIRE(d[0].x == Approx(10.f - 20.f));
    REQUIRE(d[1].cls == 1);
    REQUIRE(d[1].peak_x == Approx((5 + 0.5f) * 4));
    REQUIRE(d[2].cls == 0);
    REQUIRE(d[2].score == Approx(0.4f));
    // max_per_class keeps the best of each class.
    REQUIRE(nn::decode_detections(prob.data(), size.data(), off.data(), K, w, h, 0.3f, 1, 4).size() == 2);
    REQUIRE_THROWS_WITH(nn::decode_detections(prob.data(), size.data(), off.data(), 0, w, h, 0.3f, 5),
                        Contains("sizes must be > 0"));
    REQUIRE_THROWS_WITH(nn::decode_detections(nullptr, size.data(), off.data(), K, w, h, 0.3f, 5),
                        Contains("null buffer"));
}

TEST_CASE("detector: targets decode back to their boxes", "[detector]") {
    const int K = 3, w = 40, h = 30;
    const std::vector<train::DetBox> boxes{{0, 10.f, 12.f, 40.f, 30.f},
                                           {2, 100.f, 50.f, 21.f, 55.f},
                                           {2, 400.f, 10.f, 10.f, 10.f},   // centre off the grid
                                           {1, 5.f, 5.f, 0.f, 10.f}};      // empty: skipped
    const train::DetTargets t = train::make_detector_targets(boxes, K, w, h);
    int centres = 0;
    for (float m : t.mask) centres += m > 0;
    REQUIRE(centres == 2);
    const auto d = decode_targets(t, K, w, h);
    REQUIRE(d.size() == 2);
    for (const auto& det : d) {
        const train::DetBox& b = det.cls == 0 ? boxes[0] : boxes[1];
        REQUIRE(det.x == Approx(b.x).margin(1e-3));
        REQUIRE(det.y == Approx(b.y).margin(1e-3));
        REQUIRE(det.w == Approx(b.w).margin(1e-3));
        REQUIRE(det.h == Approx(b.h).margin(1e-3));
    }
    REQUIRE_THROWS_WITH(train::make_detector_targets({{3, 1, 1, 5, 5}}, K, w, h),
                        Contains("class 3 outside [0, 3)"));
}

TEST_CASE("detector: the focal loss at known values", "[detector]") {
    // One class, a 1 x 1 grid... a 4 x 4 output with one centre; logits 0 (p = 0.5) everywhere.
    nn::DetOut o;
    o.heat = Tensor::zeros({1, 1, 4, 4});
    o.size = Tensor::zeros({1, 2, 4, 4});
    o.offset = Tensor::zeros({1, 2, 4, 4});
    train::DetTargets t;
    t.heat.assign(16, 0.f);
    t.heat[5] = 1.f;
    t.mask.assign(16, 0.f);
    t.mask[5] = 1.f;
    t.size.assign(32, 0.f);
    t.size[5] = 1.f;  // |0 - 1| + |0 - 0|
    t.offset.assign(32, 0.f);
    t.offset[16 + 5] = 0.25f;
    double lh = 0, ls = 0, lo = 0;
    const Tensor L = train::detector_loss(o, {t}, 1, 0.1, 1, &lh, &ls, &lo);
    // centre: -(1 - .5)^2 log .5; 15 empty cells: -(1)^4 .5^2 log .5 each; one centre.
    const double expect = -(0.25 * std::log(0.5)) - 15 * (0.25 * std::log(0.5));
    REQUIRE(lh == Approx(expect).epsilon(1e-5));
    REQUIRE(ls == Approx(1.0).epsilon(1e-6));
    REQUIRE(lo == Approx(0.25).epsilon(1e-6));
    REQUIRE(L.item<double>() == Approx(expect + 0.1 + 0.25).epsilon(1e-5));
    REQUIRE_THROWS_WITH(train::detector_loss(o, {t, t}, 1, 1, 1), Contains("2 targets for a batch of 1"));

    // Per-cell weights of the negatives (cells showing a block): weight 0 on 3 empty cells and
    // 0.5 on a fourth removes 3.5 of the 15 negative terms; the centre's term is untouched.
    t.neg_weight.assign(16, 1.f);
    t.neg_weight[0] = t.neg_weight[1] = t.neg_weight[2] = 0.f;
    t.neg_weight[3] = 0.5f;
    t.neg_weight[5] = 0.f;  // the centre: a positive, never weighted
    train::detector_loss(o, {t}, 1, 0.1, 1, &lh);
    REQUIRE(lh == Approx(-(0.25 * std::log(0.5)) - 11.5 * (0.25 * std::log(0.5))).epsilon(1e-5));
    t.neg_weight.assign(15, 1.f);
    REQUIRE_THROWS_WITH(train::detector_loss(o, {t}, 1, 1, 1), Contains("targets of sample 0 do not match"));
}

TEST_CASE("detector: block_cell_weights weights the cells whose centre pixel shows a block", "[detector]") {
    // 16 x 8 pixels, stride 4: 4 x 2 cells, centre pixels (2 + 4x, 2 + 4y).
    const int W = 16, H = 8;
    std::vector<uint8_t> blocks(size_t(W * H), 0);
    auto at = [&](int x, int y) -> uint8_t& { return blocks[size_t(y * W + x)]; };
    at(6, 2) = 255;   // cell (1, 0)'s centre
    at(3, 6) = 255;   // in cell (0, 1), off its centre (2, 6): not weighted
    at(14, 6) = 255;  // cell (3, 1)'s centre
    const std::vector<float> nw = train::block_cell_weights(blocks, W, H, 4, 0.25f);
    REQUIRE(nw == std::vector<float>{1, 0.25f, 1, 1, 1, 1, 1, 0.25f});
    REQUIRE(train::block_cell_weights(std::vector<uint8_t>(size_t(W * H), 0), W, H, 4, 0.f) ==
            std::vector<float>(8, 1.f));
    REQUIRE_THROWS_WITH(train::block_cell_weights(blocks, W, H + 1, 4, 0.f),
                        Contains("a mask of 128 pixels for 16 x 9"));
    REQUIRE_THROWS_WITH(train::block_cell_weights(blocks, W, H, 4, -1.f), Contains("weight -1"));
}

TEST_CASE("detector: a tiny detector learns to find coloured squares", "[detector][learn][slow]") {
    // 48 x 48 images of noise with a red and/or a green square (8-20 px); class 0 = red.
    const int S = 48, K = 2;
    auto make = [&](Rng& rng, Tensor* x, std::vector<train::DetBox>* boxes) {
        std::vector<uint8_t> rgb(size_t(S * S * 3));
        for (auto& v : rgb) v = uint8_t(rng.below(120));
        for (int k = 0; k < K; ++k) {
            if (rng.uniform() < 0.25) continue;
            const int sz = int(rng.randint(8, 21));
            const int x0 = int(rng.randint(0, S - sz)), y0 = int(rng.randint(0, S - sz));
            for (int y = y0; y < y0 + sz; ++y)
                for (int xx = x0; xx < x0 + sz; ++xx) {
                    uint8_t* p = &rgb[size_t((y * S + xx) * 3)];
                    p[0] = k == 0 ? 230 : 20, p[1] = k == 1 ? 230 : 20, p[2] = 20;
                }
            boxes->push_back({k, float(x0), float(y0), float(sz), float(sz)});
        }
        *x = nn::detector_input(rgb.data(), S, S, 1, nullptr, nullptr);
    };
    nn::DetectorConfig dc;
    dc.num_classes = K;
    dc.width = 8;
    dc.seed = 3;
    nn::Detector net(dc);
    nn::AdamOptions ao;
    ao.lr = 5e-3;
    nn::ParamGroup g;
    g.name = "detector";
    g.params = net.named_parameters();
    nn::Adam adam({g}, ao);
    Rng rng(11);
    const int B = 8;
    for (int step = 0; step < 250; ++step) {
        std::vector<Tensor> xs;
        std::vector<train::DetTargets> ts;
        Tensor batch = Tensor::empty({B, 3, S, S});
        for (int b = 0; b < B; ++b) {
            Tensor x;
            std::vector<train::DetBox> boxes;
            make(rng, &x, &boxes);
            std::copy(x.data<float>(), x.data<float>() + x.numel(),
                      batch.data<float>() + size_t(b) * size_t(x.numel()));
            ts.push_back(train::make_detector_targets(boxes, K, S / 4, S / 4));
        }
        net.train();
        adam.zero_grad();
        Tensor loss = train::detector_loss(net.forward(batch), ts, 1, 0.1, 1);
        loss.backward();
        adam.step();
    }
    // Held-out images: the best detection of each present class overlaps its square.
    Rng test_rng(999);
    int present = 0, found = 0;
    for (int i = 0; i < 30; ++i) {
        Tensor x;
        std::vector<train::DetBox> boxes;
        make(test_rng, &x, &boxes);
        autograd::NoGradGuard ng;
        net.eval();
        const nn::DetOut o = net.forward(x);
        const Tensor p = nn::sigmoid(o.heat);
        const auto dets = nn::decode_detections(p.data<float>(), o.size.data<float>(),
                                                o.offset.data<float>(), K, S / 4, S / 4, 0.05f, 1);
        for (const auto& b : boxes) {
            ++present;
            for (const auto& d : dets) {
                if (d.cls != b.cls) continue;
                const float ix = std::max(0.f, std::min(d.x + d.w, b.x + b.w) - std::max(d.x, b.x));
                const float iy = std::max(0.f, std::min(d.y + d.h, b.y + b.h) - std::max(d.y, b.y));
                const float inter = ix * iy, uni = d.w * d.h + b.w * b.h - inter;
                found += inter / uni >= 0.5f;
            }
        }
    }
    INFO(found << " of " << present << " squares found with IoU >= 0.5");
    REQUIRE(present > 30);
    REQUIRE(found >= int(0.8 * present));
}

TEST_CASE("detector: bad configs, shapes and exports are named errors", "[detector]") {
    const std::string dir = testing::temp_dir("detector_cfg");
    auto parse = [&](const std::string& text) {
        return train::parse_detector_config(text, "det.json", dir);
    };
    const std::string ok = R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1, 2]}})";
    const train::DetectorTrainConfig c = parse(ok);
    REQUIRE(c.object_ids == std::vector<int>{1, 2});
    REQUIRE(c.models_root == "/m");
    // Round trip through the written config.
    const train::DetectorTrainConfig c2 = parse(train::detector_config_to_json(c));
    REQUIRE(train::detector_config_to_json(c2) == train::detector_config_to_json(c));
    REQUIRE_THROWS_WITH(parse(R"({"task": "pose"})"), Contains("'task' must be \"detector\""));
    REQUIRE_THROWS_WITH(parse(R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1], "colour": 1}})"),
                        Contains("unknown key 'data.colour'"));
    REQUIRE_THROWS_WITH(parse(R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1, 1]}})"),
                        Contains("repeats an id"));
    REQUIRE_THROWS_WITH(parse(R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1], "downscale": 3}})"),
                        Contains("'data.downscale' must be 1, 2 or 4, got 3"));
    REQUIRE_THROWS_WITH(parse(R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1]}, "train": {"batch": "8"}})"),
                        Contains("'train.batch' must be an integer in the range of 32 bits, got \"8\""));
    REQUIRE_THROWS_WITH(parse(R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1]}, "optim": {"lr": -1}})"),
                        Contains("'optim.lr' must be > 0"));
    REQUIRE_THROWS_WITH(parse(R"({"task": "detector", "task": "detector"})"), Contains("duplicate"));
    REQUIRE_THROWS_WITH(parse(R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1]}, "augment": {"object_tone_prob": 1.5}})"),
                        Contains("'augment.object_tone_prob' must be in [0, 1], got 1.5"));
    REQUIRE_THROWS_WITH(parse(R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1]}, "augment": {"photo_prob": 0.5}})"),
                        Contains("'augment.photo_prob' is 0.5 but 'augment.backgrounds' lists no"));
    REQUIRE_THROWS_WITH(parse(R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1]}, "augment": {"backgrounds": "/bg"}})"),
                        Contains("'augment.backgrounds' must be an array of strings, got \"/bg\""));
    REQUIRE_THROWS_WITH(parse(R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1], "distractor_ids": [3]}})"),
                        Contains("'data.distractor_ids' is set but 'data.distractors_root' is empty"));
    REQUIRE_THROWS_WITH(parse(R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1], "distractors_root": "/d", "distractor_colors": 0}})"),
                        Contains("'data.distractor_colors' must be in [1, 16], got 0"));
    REQUIRE(parse(R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1]}})")
                .w_block_negatives == 1.0);  // blocks are background unless asked
    REQUIRE(parse(R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1]}, "loss": {"block_negatives": 0}})")
                .w_block_negatives == 0.0);
    REQUIRE_THROWS_WITH(parse(R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1]}, "loss": {"block_negatives": 1.5}})"),
                        Contains("'loss.block_negatives' must be in [0, 1], got 1.5"));
    // data.mix: probabilities in (0, 1] summing to at most 1, the main scene's camera, both
    // keys given.
    const std::string mix_head = R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1], "mix": )";
    REQUIRE(parse(mix_head + R"([{"prob": 0.4, "scene": {"seed": 5}}]}})").mix.at(0).scene.seed == 5);
    REQUIRE_THROWS_WITH(parse(mix_head + R"([{"prob": 0, "scene": {}}]}})"),
                        Contains("'data.mix[0].prob' must be in (0, 1], got 0"));
    REQUIRE_THROWS_WITH(parse(mix_head + R"([{"prob": 0.6, "scene": {}}, {"prob": 0.6, "scene": {}}]}})"),
                        Contains("the 'data.mix' probabilities sum to 1.2, more than 1"));
    REQUIRE_THROWS_WITH(parse(mix_head + R"([{"prob": 0.5, "scene": {"camera": {"fx": 500, "fy": 500, "cx": 320, "cy": 240, "width": 640, "height": 480}}}]}})"),
                        Contains("'data.mix[0].scene.camera' (640 x 480, f 500) must be data.scene's camera"));
    REQUIRE_THROWS_WITH(parse(mix_head + R"([{"prob": 0.5}]}})"), Contains("'data.mix[0].scene' is required"));
    REQUIRE_THROWS_WITH(parse(mix_head + R"([{"prob": 0.5, "scene": {}, "weight": 1}]}})"),
                        Contains("unknown key 'data.mix[0].weight'"));

    nn::DetectorConfig dc;
    dc.num_classes = 2;
    dc.width = 4;
    nn::Detector net(dc);
    REQUIRE_THROWS_WITH(net.forward(Tensor::zeros({1, 3, 20, 32})), Contains("multiples of 16"));
    REQUIRE_THROWS_WITH(nn::Detector(nn::DetectorConfig{0, 16, 1}), Contains("num_classes"));
    // Export round trip, a truncated export, a pose checkpoint given as a detector.
    const std::string path = (fs::path(dir) / "det.g2l").string();
    nn::save_detector(path, net, {7, 9}, 2);
    const nn::LoadedDetector ld = nn::load_detector(path);
    REQUIRE(ld.object_ids == std::vector<int>{7, 9});
    REQUIRE(ld.downscale == 2);
    REQUIRE(ld.net->state_dict().at("heat.bias").to_vector<float>() ==
            net.state_dict().at("heat.bias").to_vector<float>());
    {
        const std::string bytes = testing::read_file(path);
        std::ofstream out(path + ".cut", std::ios::binary);
        out.write(bytes.data(), std::streamsize(bytes.size() / 2));
    }
    REQUIRE_THROWS_WITH(nn::load_detector(path + ".cut"), Contains("truncated"));
    save_checkpoint(path + ".other", {{"x", Tensor::zeros({1})}}, R"({"format": "g2l-model"})");
    REQUIRE_THROWS_WITH(nn::load_detector(path + ".other"), Contains("is not a detector export"));
    // The mean of detector exports (g2l_train --average with detector.g2l files).
    REQUIRE(nn::is_detector_export(path));
    REQUIRE_FALSE(nn::is_detector_export(path + ".other"));
    dc.seed = 99;
    nn::Detector net2(dc);
    const std::string path2 = (fs::path(dir) / "det2.g2l").string();
    nn::save_detector(path2, net2, {7, 9}, 2);
    const std::string avg = (fs::path(dir) / "avg.g2l").string();
    REQUIRE(train::export_detector_average({path, path2}, avg) > 0);
    const nn::LoadedDetector la = nn::load_detector(avg);
    REQUIRE(la.object_ids == std::vector<int>{7, 9});
    {
        const auto a = net.state_dict().at("heat.bias").to_vector<float>();
        const auto b = net2.state_dict().at("heat.bias").to_vector<float>();
        const auto m = la.net->state_dict().at("heat.bias").to_vector<float>();
        REQUIRE(m.size() == a.size());
        for (size_t i = 0; i < m.size(); ++i) CHECK(m[i] == Approx(0.5 * (a[i] + b[i])).margin(1e-7));
        // Conv weights differ between the seeds: the mean is not just one of them.
        const auto wa = net.state_dict().at("stem.conv.weight").to_vector<float>();
        const auto wb = net2.state_dict().at("stem.conv.weight").to_vector<float>();
        const auto wm = la.net->state_dict().at("stem.conv.weight").to_vector<float>();
        int between = 0;
        for (size_t i = 0; i < wm.size(); ++i) between += wa[i] != wb[i] && wm[i] == Approx(0.5 * (wa[i] + wb[i]));
        CHECK(between > 0);
    }
    nn::save_detector(path2 + ".objs", net2, {7, 8}, 2);
    REQUIRE_THROWS_WITH(train::export_detector_average({path, path2 + ".objs"}, avg),
                        Contains("'" + path2 + ".objs' has other objects, width or downscale than '" + path + "'"));
    REQUIRE_THROWS_WITH(train::export_detector_average({path, path + ".other"}, avg),
                        Contains("is not a detector export"));
    REQUIRE_THROWS_WITH(train::export_detector_average({path}, avg), Contains("at least two"));
    std::vector<uint8_t> rgb(12, 0);
    REQUIRE_THROWS_WITH(nn::detector_input(rgb.data(), 2, 2, 3, nullptr, nullptr),
                        Contains("downscale must be 1, 2 or 4"));
    REQUIRE_THROWS_WITH(nn::detector_input(rgb.data(), 0, 2, 1, nullptr, nullptr),
                        Contains("empty image"));
}

TEST_CASE("detector training: object_tone changes each object on its own, never the background",
          "[detector]") {
    // 8 x 2 image: group 1 = a grey object of two shades (100 and 200), group 2 = a flat red
    // one, group 0 = background (a ramp that must come out unchanged).
    const int w = 8, h = 2;
    std::vector<uint16_t> groups = {1, 1, 1, 1, 2, 2, 0, 0, 1, 1, 1, 1, 2, 2, 0, 0};
    std::vector<uint8_t> rgb(size_t(w * h * 3));
    for (int i = 0; i < w * h; ++i)
        for (int k = 0; k < 3; ++k) {
            uint8_t v = uint8_t(10 * i + k);
            if (groups[size_t(i)] == 1) v = (i % 2) ? 200 : 100;
            if (groups[size_t(i)] == 2) v = k == 0 ? 180 : 40;
            rgb[size_t(i * 3 + k)] = v;
        }
    Rng rng0(5);
    std::vector<uint8_t> same = rgb;
    train::object_tone(same, groups, w, h, 0.0, rng0);
    REQUIRE(same == rgb);  // prob 0: nothing

    int changed1 = 0, changed2 = 0;
    for (uint64_t seed = 1; seed <= 200; ++seed) {
        std::vector<uint8_t> out = rgb, again = rgb;
        Rng r1(seed), r2(seed);
        train::object_tone(out, groups, w, h, 1.0, r1);
        train::object_tone(again, groups, w, h, 1.0, r2);
        REQUIRE(out == again);  // the seed decides
        double lum_lo = 0, lum_hi = 0;
        for (int i = 0; i < w * h; ++i) {
            const uint8_t* o = &out[size_t(i * 3)];
            const uint8_t* in = &rgb[size_t(i * 3)];
            if (groups[size_t(i)] == 0) {
                REQUIRE((o[0] == in[0] && o[1] == in[1] && o[2] == in[2]));
                continue;
            }
            if (groups[size_t(i)] == 1) ((i % 2) ? lum_hi : lum_lo) += (o[0] + o[1] + o[2]) / 3.0 / 4;
            changed1 += groups[size_t(i)] == 1 && o[0] != in[0];
            changed2 += groups[size_t(i)] == 2 && o[0] != in[0];
        }
        // The two shades keep their order; their gap shrinks to contrast (0.4-1) x brightness
        // (0.5-1.2) x tint (0.85-1.15) of the 100 it was (+1 for rounding).
        INFO("seed " << seed << ": shades " << lum_lo << " / " << lum_hi);
        REQUIRE(lum_hi - lum_lo >= 0.4 * 0.5 * 0.85 * 100 - 1);
        REQUIRE(lum_hi - lum_lo <= 1.0 * 1.2 * 1.15 * 100 + 1);
        // The mean brightness of the grey object: 150 x 0.5-1.2 x 0.85-1.15.
        const double mean = (lum_lo + lum_hi) / 2;
        REQUIRE(mean >= 150 * 0.5 * 0.85 - 1);
        REQUIRE(mean <= 150 * 1.2 * 1.15 + 1);
    }
    REQUIRE(changed1 > 0);
    REQUIRE(changed2 > 0);

    // Bad input is named.
    Rng r(1);
    std::vector<uint8_t> short_rgb(10);
    REQUIRE_THROWS_WITH(train::object_tone(short_rgb, groups, w, h, 1.0, r),
                        Contains("object_tone: 10 colour values and 16 group ids for a 8 x 2 image"));
    REQUIRE_THROWS_WITH(train::object_tone(rgb, groups, w, h, 2.0, r),
                        Contains("object_tone: prob must be in [0, 1], got 2"));
    REQUIRE_THROWS_WITH(train::object_tone(rgb, groups, 0, h, 1.0, r), Contains("bad image size 0 x 2"));
}

TEST_CASE("detector: evaluation and g2l_eval's detector boxes run on real frames", "[detector]") {
    // An untrained detector for the fixture's two objects: the plumbing, not the accuracy.
    const data::BopDataset ds = data::open_bop(testing::fixture_dir() + "/ycbv_mini", "train_real");
    nn::DetectorConfig dc;
    dc.num_classes = 2;
    dc.width = 4;
    nn::LoadedDetector det;
    det.net = std::make_unique<nn::Detector>(dc);
    det.net->eval();
    det.object_ids = {8, 14};
    det.downscale = 4;
    const auto r = eval::evaluate_detector(det, ds, 0.0, 0.3f, 2);
    REQUIRE(r.frames == 2);
    REQUIRE(r.rows.size() == 2);
    REQUIRE(r.total.instances > 0);
    REQUIRE(r.ms_per_frame > 0);
    const std::string table = eval::detector_eval_table(r);
    REQUIRE_THAT(table, Contains("recall@.5") && Contains("recall_top3") && Contains("2 frames"));
    for (const auto& row : r.rows) {  // the best detection is one of the three best
        REQUIRE(row.found_top3 >= row.found);
        REQUIRE(row.found_top3 <= row.instances);
    }
    // nn::detect gives its detections best first (evaluate_detector's top-3 relies on it).
    const data::Image img = ds.load_rgb(ds.frames()[0]);
    const auto raw = nn::detect(*det.net, det.downscale, img.data.data(), img.w, img.h, 0.0f, 10);
    REQUIRE(raw.size() > 2);
    for (size_t i = 1; i < raw.size(); ++i) CHECK(raw[i - 1].score >= raw[i].score);
    const auto dets = eval::run_detector_on(det, ds, 0.0f);
    REQUIRE(!dets.empty());
    for (const auto& d : dets) {
        REQUIRE(d.scene_id >= 0);
        REQUIRE((d.obj_id == 8 || d.obj_id == 14));
        REQUIRE(d.peak_x >= 0);
        REQUIRE(d.peak_x < 640);
        REQUIRE(d.peak_y < 480);
        REQUIRE(d.time > 0);
    }
}

TEST_CASE("detector: the mirrored pass averages the two class-probability maps", "[detector]") {
    // An untrained detector on a random 128 x 96 image (downscale 2: 64 x 48 input, 16 x 12
    // cells, no padding): the best score of each class with `mirror` is the maximum of the
    // average of the plain map and the mirrored image's map mirrored back.
    nn::DetectorConfig dc;
    dc.num_classes = 3;
    dc.width = 4;
    nn::Detector net(dc);
    net.eval();
    Rng rng(11);
    const int W = 128, H = 96;
    std::vector<uint8_t> img(size_t(W) * H * 3), mir(img.size());
    for (auto& v : img) v = uint8_t(rng.below(256));
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            for (int c = 0; c < 3; ++c)
                mir[(size_t(y) * W + x) * 3 + c] = img[(size_t(y) * W + (W - 1 - x)) * 3 + c];
    int iw = 0, ih = 0;
    autograd::NoGradGuard ng;
    const Tensor pa = nn::sigmoid(net.forward(nn::detector_input(img.data(), W, H, 2, &iw, &ih)).heat);
    const Tensor pb = nn::sigmoid(net.forward(nn::detector_input(mir.data(), W, H, 2, &iw, &ih)).heat);
    REQUIRE(pa.size(3) == 16);
    REQUIRE(pa.size(2) == 12);
    const auto dets = nn::detect(net, 2, img.data(), W, H, 0.0f, 1, /*mirror=*/true);
    const auto plain = nn::detect(net, 2, img.data(), W, H, 0.0f, 1);
    REQUIRE(dets.size() == 3);
    bool differs = false;
    for (const auto& d : dets) {
        float best = 0.f, best_plain = 0.f;
        for (int y = 0; y < 12; ++y)
            for (int x = 0; x < 16; ++x) {
                const float a = pa.data<float>()[(d.cls * 12 + y) * 16 + x];
                const float b = pb.data<float>()[(d.cls * 12 + y) * 16 + (15 - x)];
                best = std::max(best, 0.5f * (a + b));
                best_plain = std::max(best_plain, a);
            }
        CHECK(d.score == Approx(best).epsilon(1e-5));
        for (const auto& p : plain)
            if (p.cls == d.cls) {
                CHECK(p.score == Approx(best_plain).epsilon(1e-5));
                differs = differs || std::abs(p.score - d.score) > 1e-4f;
            }
    }
    CHECK(differs);  // the second pass changed something
}

TEST_CASE("detector: widening keeps the outputs and splits the copies", "[detector]") {
    // A width-4 depth detector with random weights and BatchNorm statistics, widened to 8 and
    // 12: the same heat, size and offset in eval and in training mode (batch statistics), the
    // two copies of a channel read their inputs with different shares (they learn apart), and
    // widths that are not a whole multiple, or other classes, are named errors.
    nn::DetectorConfig a;
    a.num_classes = 3;
    a.width = 4;
    a.input = nn::DetectorInput::depth;
    nn::Detector narrow(a);
    Rng rng(5);
    {
        autograd::NoGradGuard ng;
        for (auto& [name, t] : narrow.state_dict()) {
            if (t.dtype() != DType::F32) continue;  // BatchNorm's step counter
            Tensor r = Tensor::randn(t.shape(), rng);
            if (name.find("running_var") != std::string::npos || name.find("bn.weight") != std::string::npos)
                for (int64_t i = 0; i < r.numel(); ++i)
                    r.data<float>()[i] = 0.5f + std::abs(r.data<float>()[i]);
            else
                for (int64_t i = 0; i < r.numel(); ++i) r.data<float>()[i] *= 0.3f;
            t.copy_(r);
        }
    }
    const Tensor x = Tensor::randn({2, nn::kDepthChannels, 32, 48}, rng);
    for (int k : {2, 3}) {
        INFO("width x" << k);
        nn::DetectorConfig b = a;
        b.width = 4 * k;
        b.seed = 77;
        nn::Detector wide(b);
        nn::widen_detector(narrow, wide, 9);
        autograd::NoGradGuard ng;
        for (bool train : {false, true}) {
            INFO((train ? "training mode" : "eval mode"));
            narrow.train(train);
            wide.train(train);
            const nn::DetOut p = narrow.forward(x), q = wide.forward(x);
            for (const auto& [u, v] : {std::pair{p.heat, q.heat}, std::pair{p.size, q.size},
                                       std::pair{p.offset, q.offset}}) {
                REQUIRE(u.shape() == v.shape());
                double worst = 0, scale = 0;
                for (int64_t i = 0; i < u.numel(); ++i) {
                    worst = std::max(worst, double(std::abs(u.data<float>()[i] - v.data<float>()[i])));
                    scale = std::max(scale, double(std::abs(u.data<float>()[i])));
                }
                CHECK(scale > 0.1);
                CHECK(worst < 1e-4 * std::max(1.0, scale));
            }
        }
        // d4b reads d4a's 8 (narrow) -> 8k channels: copies 0 and 8 of input channel 0 sum to
        // the narrow weight and differ.
        const auto sd = wide.state_dict();
        const Tensor w = sd.at("d4b.conv.weight"), w0 = narrow.state_dict().at("d4b.conv.weight");
        REQUIRE(w.size(1) == 8 * k);
        const int64_t kk = 9, in = w.size(1);
        const float* wp = w.data<float>();
        double sum = 0;
        for (int c = 0; c < k; ++c) sum += wp[(0 * in + c * 8 + 0) * kk + 4];
        CHECK(sum == Approx(w0.data<float>()[(0 * 8 + 0) * kk + 4]).margin(1e-6));
        CHECK(std::abs(wp[(0 * in + 0) * kk + 4] - wp[(0 * in + 8) * kk + 4]) > 1e-6);
        // BatchNorm statistics are copied per channel
        CHECK(sd.at("d8a.bn.running_var").data<float>()[16 + 3] ==
              narrow.state_dict().at("d8a.bn.running_var").data<float>()[3]);
    }
    nn::DetectorConfig bad = a;
    bad.width = 6;
    nn::Detector b6(bad);
    REQUIRE_THROWS_WITH(nn::widen_detector(narrow, b6, 1), Contains("width 6 is not a whole multiple of width 4"));
    bad.width = 8;
    bad.num_classes = 4;
    nn::Detector b4(bad);
    REQUIRE_THROWS_WITH(nn::widen_detector(narrow, b4, 1), Contains("differ in classes (3 vs 4)"));
}

TEST_CASE("detector training: run directory, checkpoints and --resume continue the same run",
          "[detector][train]") {
    // A coloured copy of the fixture's object 8 (YCB-V models carry no colour).
    const std::string dir = testing::temp_dir("detector_train");
    fs::create_directories(dir + "/models/models");
    geom::Mesh mesh = geom::load_mesh(testing::fixture_dir() + "/ycbv_mini/models/obj_000008.ply");
    mesh.colors.resize(mesh.vertices.rows(), 3);
    for (int64_t i = 0; i < mesh.vertices.rows(); ++i)
        mesh.colors.row(i) << uint8_t(200), uint8_t(40 + i % 50), uint8_t(30);
    geom::save_ply(dir + "/models/models/obj_000008.ply", mesh);
    std::ofstream(dir + "/models/models/models_info.json")
        << R"({"8": {"diameter": 114.05, "min_x": -46.13, "min_y": -50.06, "min_z": -18.62,
                     "size_x": 89.36, "size_y": 101.11, "size_z": 30.12}})";
    auto config = [&](const std::string& run) {
        const std::string text = R"({"task": "detector", "run_dir": ")" + run + R"(",
            "data": {"models_root": ")" + dir + R"(/models", "object_ids": [8], "downscale": 2,
                     "scene": {"camera": {"fx": 150, "fy": 150, "cx": 64, "cy": 48,
                                          "width": 128, "height": 96},
                               "z_min": 400, "z_max": 600, "targets_min": 1, "targets_max": 1,
                               "distractors_max": 0, "seed": 3}},
            "model": {"width": 4},
            "train": {"steps": 4, "batch": 2, "checkpoint_every": 1, "log_every": 1}})";
        return train::parse_detector_config(text, "det.json", dir);
    };
    auto losses = [](const std::string& run) {
        std::vector<std::string> out;
        std::ifstream f(run + "/steps.jsonl");
        for (std::string line; std::getline(f, line);) {
            const auto j = nlohmann::json::parse(line);
            if (j.contains("loss")) out.push_back(std::to_string(j["step"].get<int>()) + ":" +
                                                  nlohmann::json(j["loss"]).dump());
        }
        return out;
    };
    train::TrainOptions quiet;
    quiet.progress = false;
    const std::string a = dir + "/run_a", b = dir + "/run_b";
    const auto sa = train::run_detector_training(config(a), quiet);
    REQUIRE(sa.steps == 4);
    REQUIRE(losses(a).size() == 4);
    for (const char* f : {"config.json", "last.g2l", "detector.g2l", "preview_0.png"})
        REQUIRE(fs::exists(fs::path(a) / f));
    const nn::LoadedDetector ld = nn::load_detector(a + "/detector.g2l");
    REQUIRE(ld.object_ids == std::vector<int>{8});
    // A fresh run into a run directory is refused; --force starts over.
    REQUIRE_THROWS_WITH(train::run_detector_training(config(a), quiet),
                        Contains("already holds a run"));
    // Stop after 2 steps, resume: the same losses as the uninterrupted run, to the bit.
    train::TrainOptions two = quiet;
    two.max_steps = 2;
    const auto sb = train::run_detector_training(config(b), two);
    REQUIRE(sb.stopped_early);
    REQUIRE(sb.steps == 2);
    train::TrainOptions resume = quiet;
    resume.resume_dir = b;
    const auto sc = train::run_detector_training(config(b), resume);
    REQUIRE(sc.steps == 4);
    REQUIRE(losses(b) == losses(a));
    // Resuming a finished run says so.
    REQUIRE_THROWS_WITH(train::run_detector_training(config(b), resume),
                        Contains("already finished its 4 steps"));
    // train.time_schedule: a 1000-step run that a 1.8 s limit ends after a few dozen steps
    // still decays by the clock.
    {
        train::DetectorTrainConfig t = config(dir + "/run_t");
        t.steps = 1000;
        t.time_limit_min = 0.03;
        t.time_schedule = true;
        const auto st = train::run_detector_training(t, quiet);
        REQUIRE(st.stopped_early);
        REQUIRE(st.steps < 700);  // by steps, not even the first decay
        std::vector<double> lr;
        std::ifstream f(dir + "/run_t/steps.jsonl");
        for (std::string line; std::getline(f, line);) {
            const auto j = nlohmann::json::parse(line);
            if (j.contains("lr")) lr.push_back(j["lr"].get<double>());
        }
        std::ifstream g(dir + "/run_t/steps.jsonl");
        double last_step_s = 0;
        for (std::string line; std::getline(g, line);) {
            const auto j = nlohmann::json::parse(line);
            if (j.contains("step_s")) last_step_s = j["step_s"].get<double>();
        }
        INFO(st.steps << " steps, the last " << last_step_s << " s");
        REQUIRE(lr.front() == Approx(t.lr));
        for (double v : lr)
            REQUIRE((v == Approx(t.lr) || v == Approx(0.1 * t.lr) || v == Approx(0.01 * t.lr)));
        // The last step started at least (limit - its duration) into the run: past 70 % of
        // the limit when steps are short (an instrumented build's may not be), so decayed.
        if (last_step_s < 0.25 * 60 * t.time_limit_min) REQUIRE(lr.back() < 0.5 * t.lr);
    }
    // A signal while the first batch renders: no step, last.g2l at step 0, resumable to the
    // same losses.
    const std::string c = dir + "/run_c";
    std::atomic<bool> stop{true};
    train::TrainOptions sig = quiet;
    sig.stop_flag = &stop;
    const auto sd = train::run_detector_training(config(c), sig);
    REQUIRE(sd.interrupted);
    REQUIRE(sd.steps == 0);
    train::TrainOptions resume_c = quiet;
    resume_c.resume_dir = c;
    REQUIRE(train::run_detector_training(config(c), resume_c).steps == 4);
    REQUIRE(losses(c) == losses(a));
    // model.init: fine-tuning run a's export at its width and widened to 8 sees the same first
    // batch with the same loss (widening keeps the function); width 6 is a named error.
    auto first_loss = [](const std::string& run) {
        std::ifstream f(run + "/steps.jsonl");
        for (std::string line; std::getline(f, line);) {
            const auto j = nlohmann::json::parse(line);
            if (j.contains("loss")) return j["loss"].get<double>();
        }
        return -1.0;
    };
    train::DetectorTrainConfig same = config(dir + "/run_init4"), wide = config(dir + "/run_init8");
    same.init = wide.init = a + "/detector.g2l";
    same.steps = wide.steps = 1;
    wide.width = 8;
    train::run_detector_training(same, quiet);
    train::run_detector_training(wide, quiet);
    REQUIRE(first_loss(dir + "/run_init4") > 0);
    CHECK(first_loss(dir + "/run_init8") == Approx(first_loss(dir + "/run_init4")).epsilon(1e-4));
    CHECK(nn::load_detector(dir + "/run_init8/detector.g2l").net->config().width == 8);
    // data.mix: every image from a mixed-in scene (prob 1) is the run of that scene alone, to
    // the bit; not the run of data.scene.
    {
        train::DetectorTrainConfig seven = config(dir + "/run_seven"), mixed = config(dir + "/run_mix");
        seven.scene.seed = 7;
        seven.steps = mixed.steps = 2;
        mixed.mix.push_back({1.0, seven.scene});
        train::run_detector_training(seven, quiet);
        train::run_detector_training(mixed, quiet);
        REQUIRE(losses(dir + "/run_mix").size() == 2);
        CHECK(losses(dir + "/run_mix") == losses(dir + "/run_seven"));
        const std::vector<std::string> all_a = losses(a);
        const std::vector<std::string> first2(all_a.begin(), all_a.begin() + 2);
        CHECK(losses(dir + "/run_mix") != first2);
        // Written to config.json and read back: the same mix.
        const train::DetectorTrainConfig back =
            train::load_detector_config(dir + "/run_mix/config.json");
        REQUIRE(back.mix.size() == 1);
        CHECK(back.mix[0].prob == 1.0);
        CHECK(back.mix[0].scene.seed == 7);
    }
    train::DetectorTrainConfig odd = config(dir + "/run_init6");
    odd.init = a + "/detector.g2l";
    odd.width = 6;
    REQUIRE_THROWS_WITH(train::run_detector_training(odd, quiet),
                        Contains("its width 4 is neither model.width 6 nor a whole divisor"));
}

TEST_CASE("detector training: distractor meshes and photo backgrounds", "[detector][train]") {
    // Target: a coloured copy of the fixture's object 8; distractors: the fixture's uncoloured
    // models (painted); backgrounds: the fixture's real RGB frames.
    const std::string dir = testing::temp_dir("detector_photo");
    fs::create_directories(dir + "/models/models");
    geom::Mesh mesh = geom::load_mesh(testing::fixture_dir() + "/ycbv_mini/models/obj_000008.ply");
    mesh.colors.resize(mesh.vertices.rows(), 3);
    for (int64_t i = 0; i < mesh.vertices.rows(); ++i) mesh.colors.row(i) << 200, 40, 30;
    geom::save_ply(dir + "/models/models/obj_000008.ply", mesh);
    std::ofstream(dir + "/models/models/models_info.json")
        << R"({"8": {"diameter": 114.05, "min_x": -46.13, "min_y": -50.06, "min_z": -18.62,
                     "size_x": 89.36, "size_y": 101.11, "size_z": 30.12}})";
    const std::string mini = testing::fixture_dir() + "/ycbv_mini";
    auto config = [&](const std::string& run, const std::string& backgrounds) {
        const std::string text = R"({"task": "detector", "run_dir": ")" + run + R"(",
            "data": {"models_root": ")" + dir + R"(/models", "object_ids": [8], "downscale": 2,
                     "distractors_root": ")" + mini + R"(", "distractor_colors": 2,
                     "scene": {"camera": {"fx": 150, "fy": 150, "cx": 64, "cy": 48,
                                          "width": 128, "height": 96},
                               "z_min": 400, "z_max": 600, "targets_min": 1, "targets_max": 1,
                               "distractors_min": 2, "distractors_max": 2, "seed": 3,
                               "random_background": false, "support_plane_prob": 0}},
            "augment": {"backgrounds": [")" + backgrounds + R"("], "photo_prob": 1,
                        "clutter_prob": 0, "noise_std": 0, "color_jitter": 0},
            "model": {"width": 4},
            "train": {"steps": 2, "batch": 2, "checkpoint_every": 1, "log_every": 1}})";
        return train::parse_detector_config(text, "det.json", dir);
    };
    train::TrainOptions quiet;
    quiet.progress = false;
    const auto s = train::run_detector_training(config(dir + "/run", mini + "/train_real/000000/rgb"), quiet);
    REQUIRE(s.steps == 2);
    REQUIRE(fs::exists(dir + "/run/preview_0.png"));
    // The preview (the first training image at the detector's 64 x 48 input): the photo covers
    // the background, which is black in this scene without it (88% of the pixels).
    const data::Image p = data::load_rgb_image(dir + "/run/preview_0.png");
    REQUIRE(p.w == 64);
    REQUIRE(p.h == 48);
    int black = 0;
    for (size_t i = 0; i < p.data.size(); i += 3) black += p.data[i] + p.data[i + 1] + p.data[i + 2] == 0;
    INFO(black << " black pixels");
    REQUIRE(black < 64 * 48 / 20);
    // A background directory that does not exist, or holds no image, is named.
    REQUIRE_THROWS_WITH(train::run_detector_training(config(dir + "/run2", dir + "/nope"), quiet),
                        Contains("augment.backgrounds: '" + dir + "/nope' is not a directory"));
    REQUIRE_THROWS_WITH(train::run_detector_training(config(dir + "/run3", dir + "/models"), quiet),
                        Contains("holds no .png or .jpg image"));
}

TEST_CASE("detector: the depth input encodes planes, steps and holes as documented", "[detector]") {
    // A 40 x 30 depth image through a camera with fx = fy = 50, centre (19.5, 14.5).
    const int w = 40, h = 30;
    const double fx = 50, fy = 50, cx = 19.5, cy = 14.5;
    const size_t plane = size_t(w) * size_t(h);
    std::vector<float> feat(size_t(nn::kDepthChannels) * plane, -9.f);
    auto at = [&](int c, int x, int y) { return feat[size_t(c) * plane + size_t(y) * size_t(w) + size_t(x)]; };
    // 1. A fronto-parallel plane at 1500 mm: measured, depth (1500 - 1000) / 500 = 1, no
    //    relief, normal (0, 0, -1) (towards the camera).
    std::vector<float> z(plane, 1500.f);
    nn::depth_features(z.data(), w, h, fx, fy, cx, cy, feat.data(), w, int64_t(plane));
    for (int y = 0; y < h; y += 7)
        for (int x = 0; x < w; x += 9) {
            CHECK(at(0, x, y) == 1.f);
            CHECK(at(1, x, y) == Approx(1.0).epsilon(0).margin(1e-6));
            CHECK(at(2, x, y) == Approx(0.0).epsilon(0).margin(1e-5));
            CHECK(at(3, x, y) == Approx(0.0).epsilon(0).margin(1e-6));
            CHECK(at(4, x, y) == Approx(0.0).epsilon(0).margin(1e-6));
            CHECK(at(5, x, y) == Approx(-1.0).epsilon(0).margin(1e-6));
        }
    // 2. A plane tilted about the y axis, z = 1000 + 0.5 X: its normal is (0.5, 0, -1) / |.|.
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            z[size_t(y) * size_t(w) + size_t(x)] = float(1000.0 / (1.0 - 0.5 * (x - cx) / fx));
    nn::depth_features(z.data(), w, h, fx, fy, cx, cy, feat.data(), w, int64_t(plane));
    const double n = std::sqrt(1.25);
    for (int y = 5; y < h - 5; y += 5)
        for (int x = 5; x < w - 5; x += 5) {
            CHECK(at(3, x, y) == Approx(0.5 / n).epsilon(0).margin(0.01));
            CHECK(at(4, x, y) == Approx(0.0).epsilon(0).margin(0.01));
            CHECK(at(5, x, y) == Approx(-1.0 / n).epsilon(0).margin(0.01));
        }
    // 3. A box 60 mm in front of a plane at 1000 mm: negative relief on it, positive just
    //    around it on the plane; holes (0, NaN, inf) give 0 in every channel.
    std::fill(z.begin(), z.end(), 1000.f);
    for (int y = 10; y < 20; ++y)
        for (int x = 15; x < 25; ++x) z[size_t(y) * size_t(w) + size_t(x)] = 940.f;
    z[0] = 0.f;
    z[1] = std::numeric_limits<float>::quiet_NaN();
    z[2] = std::numeric_limits<float>::infinity();
    nn::depth_features(z.data(), w, h, fx, fy, cx, cy, feat.data(), w, int64_t(plane));
    CHECK(at(2, 20, 15) < -0.5f);
    CHECK(at(2, 20, 15) >= -3.f);
    CHECK(at(2, 20, 22) > 0.1f);
    for (int x = 0; x < 3; ++x)
        for (int c = 0; c < nn::kDepthChannels; ++c) CHECK(at(c, x, 0) == 0.f);
    CHECK(at(0, 3, 0) == 1.f);
    // Bad sizes and intrinsics are named.
    REQUIRE_THROWS_WITH(nn::depth_features(z.data(), w, h, 0, fy, cx, cy, feat.data(), w, int64_t(plane)),
                        Contains("fx, fy > 0"));
    REQUIRE_THROWS_WITH(nn::depth_features(z.data(), w, h, fx, fy, cx, cy, feat.data(), w - 1, int64_t(plane)),
                        Contains("bad sizes"));
}

TEST_CASE("detector: depth and rgbd detectors take what their export says", "[detector]") {
    REQUIRE(nn::parse_detector_input("depth", "x") == nn::DetectorInput::depth);
    REQUIRE(nn::parse_detector_input("rgbd", "x") == nn::DetectorInput::rgbd);
    REQUIRE(std::string(nn::to_string(nn::DetectorInput::rgb)) == "rgb");
    REQUIRE(nn::detector_input_channels(nn::DetectorInput::rgbd) == 3 + nn::kDepthChannels);
    REQUIRE_THROWS_WITH(nn::parse_detector_input("thermal", "det.json: data.input"),
                        Contains("det.json: data.input: the detector input must be \"rgb\", \"depth\" or \"rgbd\", got \"thermal\""));
    // The config key, its round trip and a bad value.
    const std::string dir = testing::temp_dir("detector_depth");
    const train::DetectorTrainConfig c = train::parse_detector_config(
        R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1], "input": "depth"}})",
        "det.json", dir);
    REQUIRE(c.input == nn::DetectorInput::depth);
    REQUIRE(train::parse_detector_config(train::detector_config_to_json(c), "det.json", dir).input ==
            nn::DetectorInput::depth);
    REQUIRE_THROWS_WITH(train::parse_detector_config(
                            R"({"task": "detector", "data": {"models_root": "/m", "object_ids": [1], "input": "ir"}})",
                            "det.json", dir),
                        Contains("data.input: the detector input must be"));
    // Pooling: each 2 x 2 block's measured pixels are averaged (0 / NaN are not measured).
    const int W = 32, H = 32;
    std::vector<float> depth(size_t(W) * size_t(H), 800.f);
    depth[0] = 0.f;
    depth[1] = std::numeric_limits<float>::quiet_NaN();
    depth[size_t(W)] = 900.f;  // block (0, 0): 0, NaN, 900, 800 -> the mean of 900 and 800
    std::vector<uint8_t> rgb(size_t(W) * size_t(H) * 3, 128);
    nn::DetectorFrame fr;
    fr.width = W, fr.height = H, fr.depth_mm = depth.data();
    fr.fx = fr.fy = 40, fr.cx = 15.5, fr.cy = 15.5;
    int iw = 0, ih = 0;
    const Tensor x = nn::detector_input(fr, nn::DetectorInput::depth, 2, &iw, &ih);
    REQUIRE(x.size(1) == nn::kDepthChannels);
    REQUIRE(iw == 16);
    REQUIRE(ih == 16);
    const float* px = x.data<float>();
    CHECK(px[0] == 1.f);                                               // valid
    CHECK(px[size_t(iw) * size_t(ih)] == Approx((850.0 - 1000) / 500).epsilon(0).margin(1e-6));  // depth
    CHECK(px[size_t(iw) * size_t(ih) + 1] == Approx((800.0 - 1000) / 500).epsilon(0).margin(1e-6));
    // rgbd: the colour channels first, then the same depth channels.
    fr.rgb = rgb.data();
    const Tensor xd = nn::detector_input(fr, nn::DetectorInput::rgbd, 2, nullptr, nullptr);
    REQUIRE(xd.size(1) == 3 + nn::kDepthChannels);
    CHECK(xd.data<float>()[0] == Approx((128 / 255.0 - 0.5) / 0.25).epsilon(0).margin(1e-6));
    const size_t p = size_t(iw) * size_t(ih);
    for (size_t i = 0; i < size_t(nn::kDepthChannels) * p; ++i)
        if (xd.data<float>()[3 * p + i] != px[i]) FAIL("rgbd depth channel value " << i << " differs");
    // Missing buffers are named.
    nn::DetectorFrame no_depth = fr;
    no_depth.depth_mm = nullptr;
    REQUIRE_THROWS_WITH(nn::detector_input(no_depth, nn::DetectorInput::depth, 2, nullptr, nullptr),
                        Contains("the depth detector needs the frame's depth image"));
    nn::DetectorFrame no_rgb = fr;
    no_rgb.rgb = nullptr;
    REQUIRE_THROWS_WITH(nn::detector_input(no_rgb, nn::DetectorInput::rgbd, 2, nullptr, nullptr),
                        Contains("the rgbd detector needs the frame's RGB image"));
    nn::DetectorFrame no_k = fr;
    no_k.fx = 0;
    REQUIRE_THROWS_WITH(nn::detector_input(no_k, nn::DetectorInput::depth, 2, nullptr, nullptr),
                        Contains("fx, fy > 0"));
    // A depth detector: its stem takes the depth channels; the export keeps "input"; an RGB
    // tensor is refused naming the expected shape; detect() runs on the depth frame.
    nn::DetectorConfig dc;
    dc.num_classes = 2;
    dc.width = 4;
    dc.input = nn::DetectorInput::depth;
    nn::Detector net(dc);
    REQUIRE_THROWS_WITH(net.forward(Tensor::zeros({1, 3, 16, 16})),
                        Contains("expected the depth input as [B, 6, H, W]"));
    const std::string path = (fs::path(dir) / "det_depth.g2l").string();
    nn::save_detector(path, net, {3, 4}, 2);
    const nn::LoadedDetector ld = nn::load_detector(path);
    REQUIRE(ld.input() == nn::DetectorInput::depth);
    const auto dets = nn::detect(*ld.net, 2, fr, 0.0f, 1);
    REQUIRE(dets.size() == 2);
    const auto mirrored = nn::detect(*ld.net, 2, fr, 0.0f, 1, true);
    REQUIRE(mirrored.size() == 2);
    REQUIRE_THROWS_WITH(nn::detect(*ld.net, 2, no_depth, 0.0f, 1), Contains("needs the frame's depth"));
    // An export written before "input" existed is an RGB detector; a bad value is named.
    {
        const Checkpoint ck = load_checkpoint(path);
        nlohmann::json meta = nlohmann::json::parse(ck.meta_json);
        std::vector<std::pair<std::string, Tensor>> ts(ck.tensors.begin(), ck.tensors.end());
        meta.erase("input");
        nn::DetectorConfig rc = dc;
        rc.input = nn::DetectorInput::rgb;
        nn::Detector rnet(rc);
        std::vector<std::pair<std::string, Tensor>> rts;
        for (const auto& [name, t] : rnet.state_dict()) rts.emplace_back("model." + name, t);
        save_checkpoint(path + ".old", rts, meta.dump());
        REQUIRE(nn::load_detector(path + ".old").input() == nn::DetectorInput::rgb);
        meta["input"] = "sonar";
        save_checkpoint(path + ".bad", ts, meta.dump());
        REQUIRE_THROWS_WITH(nn::load_detector(path + ".bad"), Contains("got \"sonar\""));
    }
}

// [slow]: 5 s in Release, minutes under the sanitizers (whose run leaves [slow] out; the
// detector's code paths run there in the other detector cases).
TEST_CASE("the shipped LM-O colour detector on the 100 real LM-O photos: recall pinned",
          "[detector][shared][slow]") {
    // models/lmo_detector.g2l, plain pass (g2l_eval --detector models/lmo_detector.g2l --root
    // ../shared/data/lmo --split test): mean recall@0.5 measured 50.8 % over 761 instances
    // (docs/results.md), per object 71.3 / 66.7 / 64.6 / 33.0 / 82.8 / 13.8 / 11.6 / 63.0 %.
    // Pinned at the measured values minus 1 point (mean) and 3 points (each object).
    const auto shared = g2l::testing::shared_data_dir();
    if (!shared) return g2l::testing::skip_without_shared_data("the shipped LM-O detector's recall");
    const nn::LoadedDetector det =
        nn::load_detector(std::string(G2L_SOURCE_DIR) + "/models/lmo_detector.g2l");
    data::BopOptions o;
    o.obj_ids = det.object_ids;
    const data::BopDataset ds = data::open_bop(*shared + "/lmo", "test", o);
    const auto r = g2l::eval::evaluate_detector(det, ds, 0.1, 0.3f, 0, false, false);
    std::printf("shipped LM-O detector: mean recall %.2f %% over %d instances\n",
                100 * r.mean_recall, r.total.instances);
    CHECK(r.total.instances == 761);
    CHECK(100 * r.mean_recall >= 50.8 - 1.0);
    const std::map<int, double> measured = {{1, 71.3}, {5, 66.7}, {6, 64.6},  {8, 33.0},
                                            {9, 82.8}, {10, 13.8}, {11, 11.6}, {12, 63.0}};
    REQUIRE(r.rows.size() == measured.size());
    for (const auto& row : r.rows) {
        INFO("object " << row.obj_id);
        REQUIRE(measured.count(row.obj_id));
        CHECK(100 * row.recall() >= measured.at(row.obj_id) - 3.0);
    }
}
