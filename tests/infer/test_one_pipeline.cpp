// SPDX-License-Identifier: MIT
// One road from a frame to a pose: g2l_eval's evaluation (train/evaluate.h) and the library a
// user links (g2l::PoseEstimator) both run infer/frame_pipeline.h, so on the same frames and
// boxes they give bitwise the same poses — every published figure measures the shipped code.
#include <catch2/catch.hpp>

#include "data/bop.h"
#include "g2l/pose_estimator.h"
#include "infer/frame_pipeline.h"
#include "nn/models/g2l_io.h"
#include "testing.h"
#include "eval/evaluate.h"

namespace {

const std::string kModel = std::string(G2L_SOURCE_DIR) + "/models/ycbv_sim2real.g2l";

}  // namespace

TEST_CASE("g2l_eval's evaluation and PoseEstimator give bitwise the same poses on the same frames",
          "[infer][eval]") {
    const std::string root = g2l::testing::fixture_dir() + "/ycbv_mini";
    const g2l::data::Dataset ds = g2l::data::open_bop(root, "train_real", {});
    REQUIRE(ds.frames().size() == 2);
    g2l::nn::LoadedModel m = g2l::nn::load_model(kModel);
    for (const auto& [refine, lib_refine] :
         {std::pair<const char*, g2l::Refinement>{"none", g2l::Refinement::none},
          {"turns", g2l::Refinement::turns}}) {
        INFO("refinement " << refine);
        g2l::eval::EvalOptions eo;
        eo.crop = g2l::infer::parse_crop(m.crop, "crop");
        eo.radius_scale = m.radius_scale;
        eo.crop_points = m.points;
        eo.max_object_points = m.seg_points;
        eo.refine = g2l::infer::parse_refine(refine, "refine");
        std::vector<g2l::eval::InstanceResult> inst;
        g2l::eval::evaluate_instances(*m.net, ds, m.class_of, m.keypoints, eo, &inst);
        REQUIRE(inst.size() == 4);

        g2l::EstimatorOptions o;
        o.refine = lib_refine;
        o.meshes = root + "/models";
        o.models_info = root + "/models/models_info.json";  // the boxes evaluation refines with
        g2l::PoseEstimator est(kModel, o);
        size_t k = 0, compared = 0;
        for (const auto& f : ds.frames()) {
            int w = 0, h = 0;
            const std::vector<uint16_t> depth = ds.load_depth(f, &w, &h);
            g2l::FrameView v;
            v.width = w, v.height = h;
            v.depth_u16 = depth.data();
            v.depth_scale = f.depth_scale;
            v.K = {f.K.fx, f.K.fy, f.K.cx, f.K.cy};
            std::vector<g2l::ObjectBox> boxes;
            for (const auto& gi : f.instances)
                boxes.push_back({gi.obj_id, gi.box().x, gi.box().y, gi.box().w, gi.box().h, 1.0});
            const auto poses = est.estimate(v, boxes);
            for (size_t i = 0; i < poses.size(); ++i, ++k) {
                const auto& r = inst[k];
                INFO("frame " << f.image_id << " object " << r.obj_id);
                REQUIRE(r.obj_id == poses[i].obj_id);
                REQUIRE(r.found);
                REQUIRE(poses[i].ok());
                CHECK(poses[i].refined == (lib_refine != g2l::Refinement::none));
                for (int a = 0; a < 3; ++a) {
                    CHECK(poses[i].t[size_t(a)] == r.est.t[a]);  // bitwise, no tolerance
                    for (int b = 0; b < 3; ++b) CHECK(poses[i].R[size_t(a * 3 + b)] == r.est.R(a, b));
                }
                ++compared;
            }
        }
        CHECK(compared == 4);
    }
}

TEST_CASE("FramePipeline: refinement and crop names are parsed once, bad ones named", "[infer]") {
    using namespace g2l::infer;
    CHECK(parse_refine("turns", "x") == Refine::turns);
    CHECK(parse_refine("icp", "x") == Refine::icp);
    CHECK(parse_refine("none", "x") == Refine::none);
    CHECK_THROWS_WITH(parse_refine("Turns", "--refine"),
                      Catch::Matchers::Contains("--refine must be none, icp or turns, got 'Turns'"));
    CHECK(parse_crop("frustum", "x") == CropKind::frustum);
    CHECK_THROWS_WITH(parse_crop("cube", "crop"),
                      Catch::Matchers::Contains("crop must be sphere, frustum or slab, got 'cube'"));
    for (Refine r : {Refine::none, Refine::icp, Refine::turns}) CHECK(parse_refine(to_string(r), "x") == r);
}

TEST_CASE("PoseEstimator: a box's pose does not depend on the other boxes of the frame",
          "[infer]") {
    const std::string root = g2l::testing::fixture_dir() + "/ycbv_mini";
    const g2l::data::Dataset ds = g2l::data::open_bop(root, "train_real", {});
    const auto& f = ds.frames().front();
    REQUIRE(f.instances.size() >= 2);
    int w = 0, h = 0;
    const std::vector<uint16_t> depth = ds.load_depth(f, &w, &h);
    g2l::FrameView v;
    v.width = w, v.height = h;
    v.depth_u16 = depth.data();
    v.depth_scale = f.depth_scale;
    v.K = {f.K.fx, f.K.fy, f.K.cx, f.K.cy};
    std::vector<g2l::ObjectBox> boxes;
    for (const auto& gi : f.instances)
        boxes.push_back({gi.obj_id, gi.box().x, gi.box().y, gi.box().w, gi.box().h, 1.0});
    g2l::EstimatorOptions o;
    o.refine = g2l::Refinement::none;  // the networks alone: where batching would show
    g2l::PoseEstimator est(kModel, o);
    const auto all = est.estimate(v, boxes);
    for (size_t i = 0; i < boxes.size(); ++i) {
        INFO("box " << i);
        const auto one = est.estimate(v, {boxes[i]});
        REQUIRE(all[i].ok());
        REQUIRE(one[0].ok());
        for (size_t k = 0; k < 9; ++k) CHECK(one[0].R[k] == all[i].R[k]);
        for (size_t k = 0; k < 3; ++k) CHECK(one[0].t[k] == all[i].t[k]);
    }
}
