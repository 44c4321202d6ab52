// SPDX-License-Identifier: MIT
// One road from a frame to a pose: g2l_eval's evaluation (train/evaluate.h) and the library a
// user links (g2l::PoseEstimator) both run infer/frame_pipeline.h, so on the same frames and
// boxes they give bitwise the same poses — every published figure measures the shipped code.
#include <catch2/catch.hpp>

#include "core/threads.h"
#include "data/bop.h"
#include "g2l/pose_estimator.h"
#include "infer/frame_pipeline.h"
#include "nn/models/g2l_io.h"
#include "testing.h"
#include "eval/evaluate.h"

namespace {

const std::string kModel = std::string(G2L_SOURCE_DIR) + "/models/ycbv_sim2real.g2l";

// A fixture frame as the library sees it (the depth stays alive with the view), and its
// ground-truth boxes.
struct FixtureFrame {
    FixtureFrame() = default;
    FixtureFrame(FixtureFrame&&) = default;  // the view keeps pointing at the moved buffer
    FixtureFrame(const FixtureFrame&) = delete;
    std::vector<uint16_t> depth;
    g2l::FrameView view;
    std::vector<g2l::ObjectBox> boxes;
};

FixtureFrame fixture_frame(const g2l::data::Dataset& ds, const g2l::data::Frame& f) {
    FixtureFrame out;
    int w = 0, h = 0;
    out.depth = ds.load_depth(f, &w, &h);
    out.view.width = w, out.view.height = h;
    out.view.depth_u16 = out.depth.data();
    out.view.depth_scale = f.depth_scale;
    out.view.K = {f.K.fx, f.K.fy, f.K.cx, f.K.cy};
    for (const auto& gi : f.instances)
        out.boxes.push_back({gi.obj_id, gi.box().x, gi.box().y, gi.box().w, gi.box().h, 1.0});
    return out;
}

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
        g2l::eval::EvalOptions eo;  // the pipeline's options: the library's own type
        eo.pipeline.refine = g2l::parse_refinement(refine, "refine");
        std::vector<g2l::eval::InstanceResult> inst;
        g2l::eval::evaluate_instances(g2l::infer::PipelineModel::of(m), ds, eo, &inst);
        REQUIRE(inst.size() == 4);

        g2l::EstimatorOptions o;
        o.refine = lib_refine;
        o.meshes = root + "/models";
        o.models_info = root + "/models/models_info.json";  // the boxes evaluation refines with
        g2l::PoseEstimator est(kModel, o);
        size_t k = 0, compared = 0;
        for (const auto& f : ds.frames()) {
            const FixtureFrame ff = fixture_frame(ds, f);
            const auto poses = est.estimate(ff.view, ff.boxes);
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
    using g2l::Refinement;
    using g2l::geom::CropKind;
    CHECK(g2l::parse_refinement("turns", "x") == Refinement::turns);
    CHECK(g2l::parse_refinement("icp", "x") == Refinement::icp);
    CHECK(g2l::parse_refinement("none", "x") == Refinement::none);
    CHECK(g2l::parse_refinement("automatic", "x") == Refinement::automatic);
    CHECK_THROWS_WITH(g2l::parse_refinement("Turns", "--refine"),
                      Catch::Matchers::Contains("--refine must be none, icp, turns or automatic, got 'Turns'"));
    CHECK(g2l::geom::parse_crop("frustum", "x") == CropKind::frustum);
    CHECK_THROWS_WITH(g2l::geom::parse_crop("cube", "crop"),
                      Catch::Matchers::Contains("crop must be sphere, frustum or slab, got 'cube'"));
    for (Refinement r : {Refinement::none, Refinement::icp, Refinement::turns, Refinement::automatic})
        CHECK(g2l::parse_refinement(g2l::to_string(r), "x") == r);
}

TEST_CASE("PipelineOptions: one type for every road, checked where it is defined", "[infer]") {
    g2l::PipelineOptions o;
    CHECK_NOTHROW(o.check());
    auto bad = [](auto edit, const char* what) {
        g2l::PipelineOptions x;
        edit(x);
        CHECK_THROWS_WITH(x.check(), Catch::Matchers::Contains(what));
    };
    bad([](g2l::PipelineOptions& x) { x.crop_points = -2; }, "crop_points must be >= -1");
    bad([](g2l::PipelineOptions& x) { x.object_points = 0; }, "object_points must be -1");
    bad([](g2l::PipelineOptions& x) { x.min_detection_score = 1.5; }, "min_detection_score must be in [0, 1], got 1.5");
    bad([](g2l::PipelineOptions& x) { x.max_instances = 0; }, "max_instances must be >= 1, got 0");
    bad([](g2l::PipelineOptions& x) { x.max_hypotheses = 0; }, "max_hypotheses must be >= 1");
    bad([](g2l::PipelineOptions& x) { x.alike_frac = std::nan(""); }, "alike_frac must be in [0, 1)");
    bad([](g2l::PipelineOptions& x) { x.min_pose_score = -0.1; }, "min_pose_score must be in [0, 1]");
    bad([](g2l::PipelineOptions& x) { x.cover_score = -1; }, "cover_score must be >= 0");
    bad([](g2l::PipelineOptions& x) { x.refine = g2l::Refinement(17); }, "refine must be none, icp, turns or automatic, got 17");
    // The pipeline resolves the defaults to the model's (and `automatic` to `turns`), and
    // refuses a change of refinement once its meshes are prepared.
    g2l::nn::LoadedModel m = g2l::nn::load_model(kModel);
    g2l::infer::FramePipeline pipe(g2l::infer::PipelineModel::of(m), o);
    CHECK(pipe.options().crop_points == m.points);
    CHECK(pipe.options().object_points == m.seg_points);
    CHECK(pipe.refine() == g2l::Refinement::turns);
    g2l::PipelineOptions none = o;
    none.refine = g2l::Refinement::none;
    CHECK_THROWS_WITH(pipe.set_options(none), Catch::Matchers::Contains("cannot change from turns to none"));
    g2l::PipelineOptions fewer = o;
    fewer.max_hypotheses = 2;
    pipe.set_options(fewer);
    CHECK(pipe.options().max_hypotheses == 2);
    CHECK(pipe.options().crop_points == m.points);
    fewer.max_instances = 0;
    CHECK_THROWS_WITH(pipe.set_options(fewer), Catch::Matchers::Contains("max_instances"));
    CHECK_THROWS_WITH(g2l::infer::FramePipeline(g2l::infer::PipelineModel::of(m), fewer),
                      Catch::Matchers::Contains("max_instances must be >= 1"));
}

TEST_CASE("PoseEstimator: a box's pose does not depend on the other boxes of the frame",
          "[infer]") {
    const std::string root = g2l::testing::fixture_dir() + "/ycbv_mini";
    const g2l::data::Dataset ds = g2l::data::open_bop(root, "train_real", {});
    const auto& f = ds.frames().front();
    REQUIRE(f.instances.size() >= 2);
    const FixtureFrame ff = fixture_frame(ds, f);
    const g2l::FrameView& v = ff.view;
    const std::vector<g2l::ObjectBox>& boxes = ff.boxes;
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

TEST_CASE("PoseEstimator: a frame's boxes refined together get the poses each gets alone, "
          "whatever the thread count, and share the refinement time",
          "[infer]") {
    const std::string root = g2l::testing::fixture_dir() + "/ycbv_mini";
    const g2l::data::Dataset ds = g2l::data::open_bop(root, "train_real", {});
    const FixtureFrame ff = fixture_frame(ds, ds.frames().front());
    const g2l::FrameView& v = ff.view;
    // Both objects have meshes (8 and 14), each box twice: four refinements at once.
    std::vector<g2l::ObjectBox> boxes = ff.boxes;
    boxes.insert(boxes.end(), ff.boxes.begin(), ff.boxes.end());
    REQUIRE(boxes.size() == 4);
    g2l::EstimatorOptions o;
    o.meshes = root + "/models";  // automatic: turns for every object with a mesh
    g2l::PoseEstimator est(kModel, o);
    const int threads = g2l::num_threads();
    std::vector<std::vector<g2l::ObjectPose>> runs;
    for (const int t : {2, 1}) {
        g2l::set_num_threads(t);
        runs.push_back(est.estimate(v, boxes));
    }
    g2l::set_num_threads(threads);
    const auto& all = runs[0];
    for (size_t i = 0; i < boxes.size(); ++i) {
        INFO("box " << i);
        REQUIRE(all[i].ok());
        CHECK(all[i].refined);
        const auto one = est.estimate(v, {boxes[i]});
        REQUIRE(one[0].ok());
        for (const g2l::ObjectPose* other :
             std::vector<const g2l::ObjectPose*>{&one[0], &runs[1][i], &all[i % 2]}) {
            for (size_t k = 0; k < 9; ++k) CHECK(other->R[k] == all[i].R[k]);
            for (size_t k = 0; k < 3; ++k) CHECK(other->t[k] == all[i].t[k]);
            CHECK(other->score == all[i].score);
        }
        // The frame's refinement time, shared equally: every refined box reports the same.
        CHECK(all[i].timings.refine_ms > 0);
        CHECK(all[i].timings.refine_ms == all[0].timings.refine_ms);
        CHECK(all[i].timings.total_ms >= all[i].timings.refine_ms);
    }
}

TEST_CASE("FramePipeline: candidates spend the budget on each object's best peak first, then "
          "its other peaks, then like-shaped objects, hypotheses suppress duplicates",
          "[infer]") {
    using namespace g2l::infer;
    g2l::nn::LoadedModel m = g2l::nn::load_model(kModel);
    g2l::PipelineOptions po;  // the defaults: turns (the library's with meshes), 3 per object,
                              // 12 in all, detections >= 0.1, like within 15 %
    FramePipeline pipe(PipelineModel::of(m), po);
    const std::string root = g2l::testing::fixture_dir() + "/ycbv_mini";
    const g2l::data::Dataset ds = g2l::data::open_bop(root, "train_real", {});
    const g2l::geom::Mesh& gelatin = ds.load_model_mesh(8);
    pipe.add_mesh(8, gelatin, ds.model(8).info);
    pipe.add_mesh(14, ds.load_model_mesh(14), ds.model(14).info);
    // Object 9 gets the gelatin box's mesh 5 % larger: a like shape (object 14, the mug, is not).
    g2l::geom::Mesh bigger = gelatin;
    bigger.vertices *= 1.05f;
    g2l::geom::ModelInfo bigger_info = ds.model(8).info;
    bigger_info.diameter *= 1.05;
    bigger_info.min *= 1.05;
    bigger_info.size *= 1.05;
    pipe.add_mesh(9, bigger, bigger_info);
    auto det = [](int id, double score, int x) {
        Candidate c;
        c.obj_id = c.det_obj_id = id;
        c.box = {x, 100, 50, 50};
        c.det_score = score;
        return c;
    };
    const std::vector<Candidate> dets = {det(8, 0.9, 0),  det(8, 0.5, 60), det(8, 0.4, 120),
                                         det(8, 0.3, 180), det(14, 0.2, 240), det(999, 0.95, 0),
                                         det(14, 0.05, 300)};
    g2l::PipelineOptions ho = po;
    const auto c = pipe.candidates(dets);
    // Best own peaks (8 @ 0.9, 14 @ 0.2), the other own peaks (8 @ 0.5, 0.4; 0.3 is over the
    // cap of 3), then object 9 borrowing object 8's peaks (0.8 x their score; 3 at most).
    std::vector<std::pair<int, double>> got;
    for (const auto& x : c) got.emplace_back(x.obj_id, x.det_score);
    const std::vector<std::pair<int, double>> want = {{8, 0.9}, {14, 0.2}, {8, 0.5}, {8, 0.4},
                                                      {9, 0.72}, {9, 0.4}, {9, 0.32}};
    REQUIRE(got.size() == want.size());
    for (size_t i = 0; i < want.size(); ++i) {
        INFO("candidate " << i);
        CHECK(got[i].first == want[i].first);
        CHECK(got[i].second == Approx(want[i].second));
    }
    CHECK(c[4].det_obj_id == 8);  // borrowed
    ho.alike_frac = 0;             // off: no borrowed peak
    pipe.set_options(ho);
    CHECK(pipe.candidates(dets).size() == 4);
    ho.max_hypotheses = 2;         // the budget: the best own peaks only
    pipe.set_options(ho);
    const auto two = pipe.candidates(dets);
    REQUIRE(two.size() == 2);
    CHECK(two[0].obj_id == 8);
    CHECK(two[1].obj_id == 14);
    ho.max_instances = 0;
    CHECK_THROWS_WITH(pipe.set_options(ho), Catch::Matchers::Contains("max_instances"));

    // Two detections of one instance (the same GT box, one shifted by 4 px): two poses at the
    // same place, the lower-scored one a duplicate (or an overlap) of the other, naming it.
    const auto& f = ds.frames().front();
    int w = 0, h = 0;
    const std::vector<float> depth = ds.load_depth_mm(f, &w, &h);
    g2l::geom::Intrinsics K = f.K;
    K.width = w, K.height = h;
    const auto& inst = f.instances.front();
    Candidate a;
    a.obj_id = a.det_obj_id = inst.obj_id;
    a.box = inst.box();
    a.det_score = 0.8;
    Candidate b = a;
    b.box.x += 4;
    b.det_score = 0.6;
    std::vector<Hypothesis> hs;
    g2l::PipelineOptions all_posed = po;
    all_posed.cover_score = 2.0;  // off: both are posed, the lower score loses
    pipe.set_options(all_posed);
    pipe.hypotheses(depth.data(), K, {b, a}, &hs);
    REQUIRE(hs.size() == 2);
    CHECK(hs[0].accepted());
    CHECK(hs[0].verified);
    CHECK(hs[0].score > 0.5);
    CHECK((hs[1].verdict == Verdict::duplicate || hs[1].verdict == Verdict::overlap));
    CHECK(hs[1].rival == 0);
    CHECK(hs[1].score <= hs[0].score);
    CHECK(hs[1].outcome.ok());
    const double det_a = hs[0].cand.det_score;
    // Other fixed settings reach the selection: an arbiter that prefers the weaker detection
    // keeps b (a is its duplicate); with arbitrate off (g2l_eval --fit-score's run) the score
    // order decides again.
    const HypothesisTuning shipped = pipe.tuning();
    HypothesisTuning odd = shipped;
    odd.arbiter.w = {};
    odd.arbiter.w[6] = -10.0;  // ln det_score
    odd.arbiter.footprint = 0;
    pipe.set_tuning(odd);
    pipe.hypotheses(depth.data(), K, {b, a}, &hs);
    REQUIRE(hs.size() == 2);
    CHECK(hs[0].accepted());
    CHECK(hs[0].cand.det_score < det_a);
    CHECK(hs[1].rival == 0);
    odd.arbitrate = false;
    pipe.set_tuning(odd);
    pipe.hypotheses(depth.data(), K, {b, a}, &hs);
    REQUIRE(hs.size() == 2);
    CHECK(hs[0].accepted());
    CHECK(hs[0].cand.det_score == det_a);
    pipe.set_tuning(shipped);
    // With the default cover: the second look at the same object (its box centre on depth the
    // first, confident pose explains) is not posed at all.
    pipe.set_options(po);
    pipe.hypotheses(depth.data(), K, {a, b}, &hs);
    REQUIRE(hs.size() == 2);
    CHECK(hs[0].accepted());
    CHECK(hs[1].verdict == Verdict::covered);
    CHECK(hs[1].rival == 0);
    CHECK_FALSE(hs[1].outcome.ok());
    CHECK(std::string(to_string(Verdict::covered)) == "covered");
    // A threshold above every score rejects both as low-scored; nothing is accepted.
    g2l::PipelineOptions strict = po;
    strict.min_pose_score = 1.0;
    pipe.set_options(strict);
    pipe.hypotheses(depth.data(), K, {a, b}, &hs);
    for (const auto& x : hs) CHECK(x.verdict == Verdict::low_score);
    CHECK(std::string(to_string(Verdict::overlap)) == "overlap");
}

TEST_CASE("PoseEstimator: with the meshes but no refinement, every pose is still verified",
          "[infer]") {
    // The road verifies a pose where it refines it; without refinement it verifies the
    // networks' pose as it is.
    const std::string root = g2l::testing::fixture_dir() + "/ycbv_mini";
    const g2l::data::Dataset ds = g2l::data::open_bop(root, "train_real", {});
    const FixtureFrame ff = fixture_frame(ds, ds.frames().front());
    g2l::EstimatorOptions o;
    o.meshes = root + "/models";
    o.refine = g2l::Refinement::none;
    o.min_pose_score = 0;  // report every verified pose, whatever its score
    g2l::PoseEstimator est(kModel, o);
    const auto poses = est.estimate(ff.view, ff.boxes);
    REQUIRE(poses.size() == ff.boxes.size());
    for (const auto& p : poses) {
        INFO("object " << p.obj_id);
        REQUIRE(p.ok());
        CHECK_FALSE(p.refined);
        CHECK(p.verified);
        CHECK(p.check.explained >= 0);
        CHECK(p.check.seg_agree >= 0);
        CHECK(p.score >= 0);
        CHECK(p.score <= 1);
    }
}
