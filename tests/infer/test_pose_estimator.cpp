// SPDX-License-Identifier: MIT
// The embeddable library (infer/include/g2l/pose_estimator.h) on the shipped model and the
// two real YCB-Video frames of tests/data/ycbv_mini: the same poses as the pipeline's own
// functions, per-box statuses for boxes that cannot give a pose, clear errors for bad frames
// and bad model files, and thread safety.
#include <catch2/catch.hpp>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <thread>

#include "core/checkpoint.h"
#include "data/bop.h"
#include "g2l/pose_estimator.h"
#include "infer/frame_pipeline.h"
#include "geometry/camera.h"
#include "geometry/crop.h"
#include "geometry/mesh_io.h"
#include "nn/models/detector.h"
#include "nn/models/g2l_io.h"
#include "nn/models/g2l_pose.h"
#include "testing.h"

using Catch::Matchers::Contains;

namespace {

const std::string kModel = std::string(G2L_SOURCE_DIR) + "/models/ycbv_sim2real.g2l";

struct Fixture {
    g2l::data::Dataset ds;
    std::vector<uint16_t> depth;
    int w = 0, h = 0;
    const g2l::data::Frame* frame = nullptr;
};

Fixture load_frame(size_t index) {
    Fixture f;
    f.ds = g2l::data::open_bop(g2l::testing::fixture_dir() + "/ycbv_mini", "train_real", {});
    REQUIRE(f.ds.frames().size() > index);
    f.frame = &f.ds.frames()[index];
    f.depth = g2l::data::load_depth_png(f.frame->depth_path, &f.w, &f.h);
    return f;
}

g2l::FrameView view_of(const Fixture& f) {
    g2l::FrameView v;
    v.width = f.w;
    v.height = f.h;
    v.depth_u16 = f.depth.data();
    v.depth_scale = f.frame->depth_scale;
    v.K = {f.frame->K.fx, f.frame->K.fy, f.frame->K.cx, f.frame->K.cy};
    return v;
}

g2l::ObjectBox box_of(const g2l::data::Instance& inst) {
    return {inst.obj_id, inst.bbox_visib.x, inst.bbox_visib.y, inst.bbox_visib.w,
            inst.bbox_visib.h, 0.9};
}

}  // namespace

TEST_CASE("PoseEstimator: the poses of the pipeline's own crop and estimate_pose (eval graph)",
          "[infer]") {
    const Fixture f = load_frame(0);
    g2l::PoseEstimator est(kModel);
    std::vector<g2l::ObjectBox> boxes;
    for (const auto& inst : f.frame->instances) boxes.push_back(box_of(inst));
    REQUIRE(boxes.size() == 2);
    const auto poses = est.estimate(view_of(f), boxes);
    REQUIRE(poses.size() == 2);

    // The same steps by hand: box centre from depth, sphere crop, estimate_pose.
    g2l::nn::LoadedModel m = g2l::nn::load_model(kModel);
    std::vector<float> mm(f.depth.size());
    for (size_t i = 0; i < mm.size(); ++i) mm[i] = float(f.depth[i] * f.frame->depth_scale);
    for (size_t b = 0; b < boxes.size(); ++b) {
        const auto& inst = f.frame->instances[b];
        INFO("object " << inst.obj_id);
        REQUIRE(poses[b].ok());
        CHECK(poses[b].obj_id == inst.obj_id);
        CHECK(poses[b].score == 0.9);
        Eigen::Vector3d c;
        REQUIRE(g2l::geom::box_centre(mm.data(), f.w, f.h, f.frame->K, inst.bbox_visib, &c));
        const auto pts = g2l::geom::depth_to_points(mm.data(), f.w, f.h, f.frame->K, inst.bbox_visib);
        const auto keep = g2l::geom::crop_indices(m.crop, pts, c, m.radius_scale * m.objects.at(inst.obj_id).diameter);
        g2l::geom::Points crop(int64_t(keep.size()), 3);
        for (size_t i = 0; i < keep.size(); ++i) crop.row(int64_t(i)) = pts.row(keep[i]);
        CHECK(poses[b].num_crop_points == int(keep.size()));
        const int cls = m.class_of.at(inst.obj_id);
        const auto ref = g2l::nn::estimate_pose(*m.net, crop, cls, m.keypoints[size_t(cls)],
                                                m.seg_points, m.points);
        REQUIRE(ref.ok);
        CHECK(poses[b].num_object_points == ref.num_object_points);
        for (int r = 0; r < 3; ++r) {
            // The library runs the compiled networks (nn::PoseEngine): float rounding apart,
            // the graph's pose.
            CHECK(poses[b].t[size_t(r)] == Approx(ref.pose.t[r]).epsilon(1e-4).margin(1e-3));
            for (int k = 0; k < 3; ++k)
                CHECK(poses[b].R[size_t(r * 3 + k)] == Approx(ref.pose.R(r, k)).margin(2e-4));
        }
        // A rotation, and a translation near the truth (the model learned where objects are).
        Eigen::Matrix3d R;
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k) R(r, k) = poses[b].R[size_t(r * 3 + k)];
        CHECK((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-6);
        CHECK(R.determinant() == Approx(1.0).margin(1e-6));
        const Eigen::Vector3d t(poses[b].t[0], poses[b].t[1], poses[b].t[2]);
        CHECK((t - inst.pose.t).norm() < 40.0);
        CHECK(poses[b].timings.total_ms >= poses[b].timings.segmentation_ms);
    }
    CHECK(est.diameter(8) == Approx(m.objects.at(8).diameter));
    CHECK(est.object_ids().size() == m.class_of.size());
    CHECK(est.keypoints(8).size() == 3 * m.keypoints[0].size());
    CHECK(std::string(g2l::version()).find('.') != std::string::npos);
}

TEST_CASE("PoseEstimator: boxes without a pose get a status, the rest of the frame goes on",
          "[infer]") {
    const Fixture f = load_frame(0);
    g2l::PoseEstimator est(kModel);
    const auto& inst = f.frame->instances[0];
    const g2l::ObjectBox good = box_of(inst);
    std::vector<g2l::ObjectBox> boxes = {
        {999, 10, 10, 50, 50, 1},               // unknown object
        {inst.obj_id, 5000, 10, 50, 50, 1},     // wholly outside
        {inst.obj_id, -200, -200, 100, 100, 1}, // outside (negative)
        {inst.obj_id, 10, 10, 0, 30, 1},        // empty
        good,
        // partly outside: clipped to the image, same pose as the box cut at the border
        {inst.obj_id, good.x - 10000, good.y, good.w + 10000, good.h, 1},
    };
    const auto p = est.estimate(view_of(f), boxes);
    REQUIRE(p.size() == boxes.size());
    CHECK(p[0].status == g2l::PoseStatus::unknown_object);
    CHECK(std::string(g2l::to_string(p[0].status)) == "unknown object");
    CHECK(p[1].status == g2l::PoseStatus::box_outside_image);
    CHECK(p[2].status == g2l::PoseStatus::box_outside_image);
    CHECK(p[3].status == g2l::PoseStatus::box_outside_image);
    CHECK(p[4].ok());
    CHECK(p[5].ok());
    CHECK_FALSE(p[1].ok());

    // Depth with NaN / inf / 0 only: "no depth"; half of the box invalid: still a pose, the
    // same as with those pixels at 0.
    std::vector<float> mm(f.depth.size());
    for (size_t i = 0; i < mm.size(); ++i) mm[i] = float(f.depth[i] * f.frame->depth_scale);
    std::vector<float> bad(mm.size(), std::numeric_limits<float>::quiet_NaN());
    for (size_t i = 0; i < bad.size(); i += 3) bad[i] = std::numeric_limits<float>::infinity();
    for (size_t i = 1; i < bad.size(); i += 5) bad[i] = 0.f;
    g2l::FrameView v = view_of(f);
    v.depth_u16 = nullptr;
    v.depth_mm = bad.data();
    const auto none = est.estimate(v, {good});
    CHECK(none[0].status == g2l::PoseStatus::no_depth);
    std::vector<float> holes = mm, zeros = mm;
    for (int y = good.y; y < good.y + good.h; ++y)
        for (int x = good.x; x < good.x + good.w; x += 2) {
            holes[size_t(y) * size_t(f.w) + size_t(x)] = (x / 2) % 2 ? NAN : -INFINITY;
            zeros[size_t(y) * size_t(f.w) + size_t(x)] = 0.f;
        }
    v.depth_mm = holes.data();
    const auto a = est.estimate(v, {good});
    v.depth_mm = zeros.data();
    const auto b = est.estimate(v, {good});
    REQUIRE(a[0].ok());
    CHECK(a[0].t == b[0].t);
    CHECK(a[0].R == b[0].R);
    // Only a few points: too few points, not a crash.
    std::vector<float> sparse(mm.size(), 0.f);
    for (int k = 0; k < 5; ++k) {
        const size_t i = size_t(good.y + good.h / 2) * size_t(f.w) + size_t(good.x + good.w / 2 + k);
        sparse[i] = mm[i];
    }
    v.depth_mm = sparse.data();
    CHECK(est.estimate(v, {good})[0].status == g2l::PoseStatus::too_few_points);
    CHECK(est.estimate(v, {}).empty());
}

TEST_CASE("PoseEstimator: invalid frames throw naming the field", "[infer]") {
    const Fixture f = load_frame(0);
    g2l::PoseEstimator est(kModel);
    const g2l::ObjectBox box = box_of(f.frame->instances[0]);
    auto expect = [&](g2l::FrameView v, const std::string& what) {
        INFO(what);
        REQUIRE_THROWS_WITH(est.estimate(v, {box}), Contains(what));
    };
    g2l::FrameView v = view_of(f);
    v.K.fx = 0;
    expect(v, "focal lengths must be finite and > 0");
    v = view_of(f);
    v.K.fy = std::nan("");
    expect(v, "fy=nan");
    v = view_of(f);
    v.K.cx = INFINITY;
    expect(v, "principal point");
    v = view_of(f);
    v.width = 0;
    expect(v, "frame size must be positive");
    v = view_of(f);
    v.depth_u16 = nullptr;
    expect(v, "neither given");
    v = view_of(f);
    std::vector<float> mm(f.depth.size(), 500.f);
    v.depth_mm = mm.data();
    expect(v, "both given");
    v = view_of(f);
    v.depth_scale = 0;
    expect(v, "depth_scale must be finite and > 0");
    // After the errors the estimator still works.
    CHECK(est.estimate(view_of(f), {box})[0].ok());
}

TEST_CASE("PoseEstimator: missing, truncated and incomplete model files", "[infer]") {
    const std::string dir = g2l::testing::temp_dir("infer_models");
    REQUIRE_THROWS_WITH(g2l::PoseEstimator(dir + "/nope.g2l"), Contains(dir + "/nope.g2l"));
    {
        std::ifstream in(kModel, std::ios::binary);
        std::vector<char> bytes(4096);
        in.read(bytes.data(), long(bytes.size()));
        std::ofstream out(dir + "/cut.g2l", std::ios::binary);
        out.write(bytes.data(), long(bytes.size()));
    }
    REQUIRE_THROWS_WITH(g2l::PoseEstimator(dir + "/cut.g2l"), Contains("cut.g2l"));
    g2l::EstimatorOptions bad;
    bad.object_points = 0;
    REQUIRE_THROWS_WITH(g2l::PoseEstimator(kModel, bad), Contains("object_points"));

    // A file without the diameters (written before they were stored): a clear error, and
    // EstimatorOptions::models_info supplies them.
    g2l::Checkpoint ck = g2l::load_checkpoint(kModel);
    nlohmann::json meta = nlohmann::json::parse(ck.meta_json);
    REQUIRE(meta.contains("objects"));
    nlohmann::json info = nlohmann::json::object();
    for (const auto& o : meta.at("objects"))
        info[std::to_string(o.at("obj_id").get<int>())] = {
            {"diameter", o.at("diameter")}, {"min_x", -1}, {"min_y", -1}, {"min_z", -1},
            {"size_x", 2}, {"size_y", 2}, {"size_z", 2}};
    meta.erase("objects");
    std::vector<std::pair<std::string, g2l::Tensor>> tensors(ck.tensors.begin(), ck.tensors.end());
    g2l::save_checkpoint(dir + "/old.g2l", tensors, meta.dump());
    REQUIRE_THROWS_WITH(g2l::PoseEstimator(dir + "/old.g2l"), Contains("models_info"));
    std::ofstream(dir + "/models_info.json") << info.dump();
    g2l::EstimatorOptions o;
    o.models_info = dir + "/models_info.json";
    g2l::PoseEstimator old(dir + "/old.g2l", o);
    const Fixture f = load_frame(0);
    g2l::PoseEstimator cur(kModel);
    const g2l::ObjectBox box = box_of(f.frame->instances[0]);
    CHECK(old.estimate(view_of(f), {box})[0].t == cur.estimate(view_of(f), {box})[0].t);
}

TEST_CASE("PoseEstimator: one estimator shared by two threads gives the sequential results",
          "[infer]") {
    const Fixture f0 = load_frame(0), f1 = load_frame(1);
    g2l::PoseEstimator est(kModel);
    auto boxes_of = [](const Fixture& f) {
        std::vector<g2l::ObjectBox> b;
        for (const auto& inst : f.frame->instances) b.push_back(box_of(inst));
        return b;
    };
    const auto s0 = est.estimate(view_of(f0), boxes_of(f0));
    const auto s1 = est.estimate(view_of(f1), boxes_of(f1));
    std::vector<g2l::ObjectPose> p0, p1;
    std::thread a([&] { for (int i = 0; i < 3; ++i) p0 = est.estimate(view_of(f0), boxes_of(f0)); });
    std::thread b([&] { for (int i = 0; i < 3; ++i) p1 = est.estimate(view_of(f1), boxes_of(f1)); });
    a.join();
    b.join();
    REQUIRE(p0.size() == s0.size());
    REQUIRE(p1.size() == s1.size());
    for (size_t i = 0; i < s0.size(); ++i) CHECK(p0[i].R == s0[i].R);
    for (size_t i = 0; i < s1.size(); ++i) CHECK(p1[i].t == s1[i].t);
}

TEST_CASE("PoseEstimator: the detector gives boxes with peaks, and the whole pipeline runs",
          "[infer][detector]") {
    Fixture f = load_frame(0);
    const g2l::data::Image rgb = f.ds.load_rgb(*f.frame);
    REQUIRE(rgb.channels == 3);
    // An untrained detector for the fixture's objects 8 and 14 (the plumbing, not accuracy).
    const std::string dir = g2l::testing::temp_dir("infer_detector");
    g2l::nn::DetectorConfig dc;
    dc.num_classes = 2;
    dc.width = 4;
    g2l::nn::Detector net(dc);
    g2l::nn::save_detector(dir + "/det.g2l", net, {8, 14}, 4);
    g2l::EstimatorOptions o;
    o.detector = dir + "/det.g2l";
    o.min_detection_score = 0.0;  // every class peak, whatever an untrained net scores
    o.max_instances = 1;          // the best peak of each class
    o.keep_rejected = true;       // estimate(frame) returns every hypothesis, posed or not
    g2l::PoseEstimator est(kModel, o);
    g2l::FrameView v = view_of(f);
    REQUIRE_THROWS_WITH(est.detect(v), Contains("the rgb detector '" + o.detector +
                                                "' needs the frame's RGB image"));
    REQUIRE(est.detector_input() == "rgb");
    v.rgb = rgb.data.data();
    const auto boxes = est.detect(v);
    REQUIRE(boxes.size() == 2);  // one per class
    for (const auto& b : boxes) {
        REQUIRE((b.obj_id == 8 || b.obj_id == 14));
        REQUIRE(b.peak_x >= 0);
        REQUIRE(b.peak_x < v.width);
        REQUIRE(b.peak_y < v.height);
        REQUIRE(b.score >= 0);
    }
    REQUIRE(boxes[0].score >= boxes[1].score);
    // With the mirrored pass: nn::detect's averaged maps, through the library.
    g2l::EstimatorOptions om = o;
    om.detector_mirror = true;
    g2l::PoseEstimator est_m(kModel, om);
    const auto boxes_m = est_m.detect(v);
    const auto direct = g2l::nn::detect(net, 4, v.rgb, v.width, v.height, 0.0f, 1, true);
    REQUIRE(boxes_m.size() == direct.size());
    for (size_t i = 0; i < direct.size(); ++i) CHECK(boxes_m[i].score == Approx(direct[i].score));
    const auto plain_direct = g2l::nn::detect(net, 4, v.rgb, v.width, v.height, 0.0f, 1);
    CHECK(std::abs(plain_direct[0].score - direct[0].score) > 1e-6f);
    const auto poses = est.estimate(v);  // no meshes: nothing verified, nothing suppressed
    REQUIRE(poses.size() == boxes.size());
    for (const auto& b : boxes) {
        int n = 0;
        for (const auto& p : poses) n += p.obj_id == b.obj_id && !p.verified;
        CHECK(n == 1);
    }
    // Several peaks per class when asked: at least as many boxes, best first.
    g2l::EstimatorOptions o3 = o;
    o3.max_instances = 3;
    const auto boxes3 = g2l::PoseEstimator(kModel, o3).detect(v);
    CHECK(boxes3.size() >= boxes.size());
    CHECK(boxes3.size() <= 6);
    for (size_t i = 1; i < boxes3.size(); ++i) CHECK(boxes3[i - 1].score >= boxes3[i].score);
    // A peak with a valid depth pixel lifts to the centre at the peak pixel's ray.
    g2l::ObjectBox gt = box_of(f.frame->instances[0]);
    gt.peak_x = gt.x + gt.w / 2.0;
    gt.peak_y = gt.y + gt.h / 2.0;
    const auto p = est.estimate(v, {gt});
    REQUIRE(p.size() == 1);
    REQUIRE(p[0].num_crop_points > 0);
    // A depth detector: detect() feeds it the depth and the intrinsics (no RGB needed), the
    // same detections as nn::detect on the frame's depth in mm; without depth, a clear error.
    {
        g2l::nn::DetectorConfig dd = dc;
        dd.input = g2l::nn::DetectorInput::depth;
        g2l::nn::Detector dnet(dd);
        g2l::nn::save_detector(dir + "/det_depth.g2l", dnet, {8, 14}, 4);
        g2l::EstimatorOptions od = o;
        od.detector = dir + "/det_depth.g2l";
        g2l::PoseEstimator est_d(kModel, od);
        REQUIRE(est_d.detector_input() == "depth");
        g2l::FrameView vd = view_of(f);  // depth_u16, no RGB
        const auto bd = est_d.detect(vd);
        REQUIRE(bd.size() == 2);
        std::vector<float> mm(f.depth.size());
        for (size_t i = 0; i < mm.size(); ++i) mm[i] = float(double(f.depth[i]) * vd.depth_scale);
        g2l::nn::DetectorFrame df;
        df.width = vd.width, df.height = vd.height, df.depth_mm = mm.data();
        df.fx = vd.K.fx, df.fy = vd.K.fy, df.cx = vd.K.cx, df.cy = vd.K.cy;
        const auto dd_direct = g2l::nn::detect(dnet, 4, df, 0.0f, 1);
        REQUIRE(dd_direct.size() == bd.size());
        for (size_t i = 0; i < bd.size(); ++i) {
            CHECK(bd[i].obj_id == (dd_direct[i].cls == 0 ? 8 : 14));
            CHECK(bd[i].score == Approx(dd_direct[i].score).epsilon(0).margin(1e-6));
        }
        REQUIRE(est_d.estimate(vd).size() == 2);  // the whole pipeline without RGB
        g2l::FrameView none = vd;
        none.depth_u16 = nullptr;
        REQUIRE_THROWS_WITH(est_d.detect(none), Contains("the depth detector '" + od.detector +
                                                         "' needs the frame's depth"));
    }
    // Without a detector: a clear error; a bad score threshold: a clear error.
    g2l::PoseEstimator plain(kModel);
    REQUIRE(plain.detector_input().empty());
    REQUIRE_THROWS_WITH(plain.detect(v), Contains("no detector"));
    g2l::EstimatorOptions bad;
    bad.min_detection_score = 2;
    REQUIRE_THROWS_WITH(g2l::PoseEstimator(kModel, bad), Contains("min_detection_score"));
    g2l::EstimatorOptions missing;
    missing.detector = dir + "/none.g2l";
    REQUIRE_THROWS_WITH(g2l::PoseEstimator(kModel, missing), Contains("none.g2l"));
}

TEST_CASE("PoseEstimator: depth refinement against the meshes, and its option errors", "[infer]") {
    const Fixture f = load_frame(0);
    std::vector<g2l::ObjectBox> boxes;
    for (const auto& inst : f.frame->instances) boxes.push_back(box_of(inst));
    g2l::PoseEstimator plain(kModel);
    const auto before = plain.estimate(view_of(f), boxes);
    g2l::EstimatorOptions opt;
    opt.refine = g2l::Refinement::turns;
    opt.meshes = g2l::testing::fixture_dir() + "/ycbv_mini/models";  // objects 8 and 14 only
    g2l::PoseEstimator est(kModel, opt);
    const auto after = est.estimate(view_of(f), boxes);
    REQUIRE(after.size() == boxes.size());
    double err_before = 0, err_after = 0;
    for (size_t b = 0; b < boxes.size(); ++b) {
        const auto& inst = f.frame->instances[b];
        INFO("object " << inst.obj_id);
        REQUIRE(after[b].ok());
        CHECK(after[b].refined);
        CHECK(!before[b].refined);
        CHECK(before[b].fit_mm == -1);
        // The refined pose fits the depth: object points within a few mm of the mesh.
        CHECK(after[b].fit_mm >= 0);
        CHECK(after[b].fit_mm < 5.0);
        CHECK(after[b].timings.refine_ms > 0);
        CHECK(after[b].timings.total_ms >= after[b].timings.refine_ms);
        Eigen::Matrix3d R;
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k) R(r, k) = after[b].R[size_t(r * 3 + k)];
        CHECK((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-6);
        CHECK(R.determinant() == Approx(1.0).margin(1e-6));
        // ICP on real depth: the translation lands near the truth. Measured 2026-12-04 (printed
        // below): the networks 6.6 and 9.3 mm off on these two, refined 8.5 and 5.3 mm; pinned
        // at the measured value + 2 mm, the fit at its measured 1.25 / 0.97 mm + 0.5.
        const Eigen::Vector3d t0(before[b].t[0], before[b].t[1], before[b].t[2]);
        const Eigen::Vector3d t1(after[b].t[0], after[b].t[1], after[b].t[2]);
        std::printf("refine: object %d translation error %.1f -> %.1f mm, fit %.2f mm\n",
                    inst.obj_id, (t0 - inst.pose.t).norm(), (t1 - inst.pose.t).norm(), after[b].fit_mm);
        CHECK((t1 - inst.pose.t).norm() < (inst.obj_id == 8 ? 8.5 : 5.3) + 2.0);
        CHECK(after[b].fit_mm < (inst.obj_id == 8 ? 1.25 : 0.97) + 0.5);
        // The best distinct pose's fit (the gelatin box's flips are its symmetries, not
        // distinct poses): -1 without refinement, else -1 or a fit of its own.
        std::printf("refine: object %d alt_fit %.2f mm\n", inst.obj_id, after[b].alt_fit_mm);
        CHECK(before[b].alt_fit_mm == -1);
        CHECK((after[b].alt_fit_mm == -1 || after[b].alt_fit_mm > 0));
        err_before += (t0 - inst.pose.t).norm();
        err_after += (t1 - inst.pose.t).norm();
    }
    CHECK(err_after < err_before);
    // The default (automatic) refines with meshes — the same poses as turns — and `plain`
    // above (no meshes) did not; `none` with meshes keeps the networks' poses.
    g2l::EstimatorOptions auto_opt;
    CHECK(auto_opt.refine == g2l::Refinement::automatic);
    auto_opt.meshes = opt.meshes;
    const auto autod = g2l::PoseEstimator(kModel, auto_opt).estimate(view_of(f), boxes);
    g2l::EstimatorOptions none_opt;
    none_opt.meshes = opt.meshes;
    none_opt.refine = g2l::Refinement::none;
    const auto kept = g2l::PoseEstimator(kModel, none_opt).estimate(view_of(f), boxes);
    for (size_t b = 0; b < boxes.size(); ++b) {
        CHECK(autod[b].refined);
        CHECK(autod[b].R == after[b].R);
        CHECK(autod[b].t == after[b].t);
        CHECK(!kept[b].refined);
        CHECK(kept[b].R == before[b].R);
        CHECK(kept[b].t == before[b].t);
    }
    // An object of the model without a mesh in the folder keeps the networks' pose.
    g2l::ObjectBox other = boxes[0];
    other.obj_id = 5;
    const auto unrefined = est.estimate(view_of(f), {other});
    CHECK(!unrefined[0].refined);
    CHECK(unrefined[0].fit_mm == -1);

    g2l::EstimatorOptions bad;
    bad.refine = g2l::Refinement::icp;
    CHECK_THROWS_WITH(g2l::PoseEstimator(kModel, bad), Contains("needs EstimatorOptions::meshes"));
    bad.meshes = g2l::testing::fixture_dir() + "/no_such_folder";
    CHECK_THROWS_WITH(g2l::PoseEstimator(kModel, bad), Contains("no_such_folder' is not a folder"));
    bad.meshes = g2l::testing::fixture_dir();
    CHECK_THROWS_WITH(g2l::PoseEstimator(kModel, bad), Contains("has no obj_NNNNNN.ply mesh"));
    CHECK(std::string(g2l::to_string(g2l::Refinement::turns)) == "turns");
    CHECK(std::string(g2l::to_string(g2l::Refinement::automatic)) == "automatic");
    bad.refine = static_cast<g2l::Refinement>(7);
    CHECK_THROWS_WITH(g2l::PoseEstimator(kModel, bad), Contains("refine must be none, icp, turns or automatic, got 7"));
}

TEST_CASE("PoseEstimator: the shipped depth detector and pose model on the real fixture frames, no GT box",
          "[infer][detector]") {
    // What ./g2l.sh demo runs, pinned per instance near the values measured 2026-12-07 with
    // the width-32 detector (this test prints them): box IoU, translation and rotation error
    // of the refined pose against the fixture's ground truth. Margins: IoU -0.05, translation
    // +2 mm, rotation +2 deg (the mug: +8 deg, below).
    struct Pin {
        size_t frame;
        int obj_id;
        double iou, t_mm, rot_deg, rot_margin;
    };
    // The mug's 16 and 114 deg are its near-symmetry: the handle is not in view, so a turn
    // about the mug's axis fits the depth as well, and the refinement keeps the one the crop's
    // networks start from (ADD-S is what the mug is judged by). That turn is not observed, so
    // rounding moves it: 15.7 deg in the optimised build, 17.8 under the sanitizers' flags.
    const Pin pins[] = {{0, 8, 0.831, 0.47, 0.55, 2.0}, {0, 14, 0.936, 4.21, 15.71, 8.0},
                        {1, 8, 0.888, 0.61, 0.66, 2.0}, {1, 14, 0.749, 6.09, 113.78, 8.0}};
    g2l::EstimatorOptions o;
    o.detector = std::string(G2L_SOURCE_DIR) + "/models/ycbv_detector.g2l";
    o.meshes = g2l::testing::fixture_dir() + "/ycbv_mini/models";
    g2l::PoseEstimator est(kModel, o);
    REQUIRE(est.detector_input() == "depth");
    int checked = 0;
    for (size_t index : {size_t(0), size_t(1)}) {
        const Fixture f = load_frame(index);
        const g2l::FrameView v = view_of(f);  // depth only: the detector needs no RGB
        const auto boxes = est.detect(v);
        const auto poses = est.estimate(v, boxes);
        for (const auto& inst : f.frame->instances) {
            INFO("frame " << index << " object " << inst.obj_id);
            size_t k = boxes.size();
            for (size_t b = 0; b < boxes.size(); ++b)  // the object's best peak (best first)
                if (boxes[b].obj_id == inst.obj_id && k == boxes.size()) k = b;
            REQUIRE(k < boxes.size());
            const auto& gt = inst.bbox_visib;
            const double iou = g2l::geom::box_iou(boxes[k].x, boxes[k].y, boxes[k].w, boxes[k].h,
                                                  gt.x, gt.y, gt.w, gt.h);
            REQUIRE(poses[k].ok());
            CHECK(poses[k].refined);
            const Eigen::Vector3d t(poses[k].t[0], poses[k].t[1], poses[k].t[2]);
            Eigen::Matrix3d R;
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 3; ++c) R(r, c) = poses[k].R[size_t(r * 3 + c)];
            const double cosang =
                std::clamp(((R.transpose() * inst.pose.R).trace() - 1) / 2, -1.0, 1.0);
            const double t_err = (t - inst.pose.t).norm(), rot = std::acos(cosang) * 180 / M_PI;
            std::printf("shipped pipeline: frame %zu object %d: IoU %.3f, t error %.2f mm, "
                        "rotation error %.2f deg\n",
                        index, inst.obj_id, iou, t_err, rot);
            for (const Pin& p : pins) {
                if (p.frame != index || p.obj_id != inst.obj_id) continue;
                CHECK(iou >= p.iou - 0.05);
                CHECK(t_err <= p.t_mm + 2.0);
                CHECK(rot <= p.rot_deg + p.rot_margin);
                ++checked;
            }
        }
    }
    CHECK(checked == 4);  // every pinned instance was found and checked
}

TEST_CASE("PoseEstimator: hypotheses verified against the depth on the real fixture frames",
          "[infer][detector]") {
    // The whole road of estimate(frame): several peaks per object, each posed, refined and
    // verified; the right poses of the fixture's two objects are reported with a score that
    // says so, the rest rank below them or are rejected with a reason.
    g2l::EstimatorOptions o;
    o.detector = std::string(G2L_SOURCE_DIR) + "/models/ycbv_detector.g2l";
    o.meshes = g2l::testing::fixture_dir() + "/ycbv_mini/models";
    o.keep_rejected = true;
    g2l::PoseEstimator est(kModel, o);
    g2l::EstimatorOptions strict = o;
    strict.keep_rejected = false;
    strict.min_pose_score = 0.5;
    g2l::PoseEstimator est_strict(kModel, strict);
    for (size_t index : {size_t(0), size_t(1)}) {
        const Fixture f = load_frame(index);
        const g2l::FrameView v = view_of(f);
        const auto poses = est.estimate(v);
        REQUIRE(!poses.empty());
        // Accepted first, best first; rejected ones name their reason and their rival.
        bool in_rejected = false;
        double last = 2.0;
        for (size_t i = 0; i < poses.size(); ++i) {
            const auto& p = poses[i];
            INFO("frame " << index << " pose " << i << " object " << p.obj_id << " status "
                          << g2l::to_string(p.status) << " score " << p.score);
            // The fixture has the meshes of objects 8 and 14 only: the others stay unverified.
            CHECK(p.verified == (p.obj_id == 8 || p.obj_id == 14));
            CHECK(p.score >= 0.0);
            CHECK(p.score <= 1.0);
            if (p.verified) {
                CHECK(p.check.explained >= 0.0);
                CHECK(p.check.seg_agree >= 0.0);
            }
            if (p.ok()) {
                CHECK_FALSE(in_rejected);
                CHECK(p.score <= last + 1e-12);
                last = p.score;
            } else {
                in_rejected = true;
                if (p.status == g2l::PoseStatus::rejected_duplicate ||
                    p.status == g2l::PoseStatus::rejected_overlap) {
                    REQUIRE(p.rival >= 0);
                    REQUIRE(size_t(p.rival) < poses.size());
                    CHECK(poses[size_t(p.rival)].ok());
                    // (a lower-scored rival only where the arbiter preferred its depth
                    // evidence: tests/infer/test_select.cpp)
                }
            }
        }
        // Each ground-truth object: a reported pose within 10% of its diameter (ADD-S-like:
        // the centre) that scores above 0.5, and above every wrong reported pose of the frame.
        double worst_right = 1.0, best_wrong = 0.0;
        for (const auto& inst : f.frame->instances) {
            INFO("frame " << index << " object " << inst.obj_id);
            bool found = false;
            for (const auto& p : poses) {
                if (!p.ok() || p.obj_id != inst.obj_id) continue;
                const Eigen::Vector3d t(p.t[0], p.t[1], p.t[2]);
                if ((t - inst.pose.t).norm() < 0.1 * est.diameter(inst.obj_id)) {
                    found = true;
                    worst_right = std::min(worst_right, p.score);
                    CHECK(p.score > 0.5);
                    // The box of the surface the depth explains: the visible object's.
                    const auto& b = p.check.bbox;
                    const g2l::geom::Box2i gb = inst.box();
                    CHECK(g2l::geom::box_iou(b[0], b[1], b[2], b[3], gb.x, gb.y, gb.w, gb.h) > 0.7);
                }
            }
            CHECK(found);
        }
        for (const auto& p : poses) {
            if (!p.ok()) continue;
            bool right = false;
            for (const auto& inst : f.frame->instances) {
                const Eigen::Vector3d t(p.t[0], p.t[1], p.t[2]);
                right = right || (p.obj_id == inst.obj_id &&
                                  (t - inst.pose.t).norm() < 0.1 * est.diameter(inst.obj_id));
            }
            if (!right && p.verified) best_wrong = std::max(best_wrong, p.score);
        }
        std::printf("hypotheses on fixture frame %zu: %zu poses, worst right score %.3f, best "
                    "wrong score %.3f\n", index, poses.size(), worst_right, best_wrong);
        CHECK(worst_right > best_wrong);
        // A threshold drops what scores below it and keeps no rejected hypothesis.
        for (const auto& p : est_strict.estimate(v)) {
            CHECK(p.ok());
            if (p.verified) CHECK(p.score >= 0.5);
        }
        // Given boxes: one verified pose per box, in order, none suppressed.
        std::vector<g2l::ObjectBox> boxes;
        for (const auto& inst : f.frame->instances)
            boxes.push_back({inst.obj_id, inst.bbox_visib.x, inst.bbox_visib.y, inst.bbox_visib.w,
                             inst.bbox_visib.h, 1.0});
        const auto given = est.estimate(v, boxes);
        REQUIRE(given.size() == boxes.size());
        for (size_t b = 0; b < boxes.size(); ++b) {
            CHECK(given[b].obj_id == boxes[b].obj_id);
            CHECK(given[b].verified);
            CHECK(given[b].detection_score == 1.0);
            CHECK(given[b].score > 0.5);
        }
    }
    g2l::EstimatorOptions bad = o;
    bad.max_instances = 0;
    CHECK_THROWS_WITH(g2l::PoseEstimator(kModel, bad), Contains("max_instances must be >= 1"));
    bad = o;
    bad.max_hypotheses = 0;
    CHECK_THROWS_WITH(g2l::PoseEstimator(kModel, bad), Contains("max_hypotheses must be >= 1"));
    bad = o;
    bad.min_pose_score = 1.5;
    CHECK_THROWS_WITH(g2l::PoseEstimator(kModel, bad), Contains("min_pose_score must be in [0, 1]"));
}

TEST_CASE("PoseEstimator: meshes in metres, or of another object, are refused with the fix",
          "[infer]") {
    const std::string dir = g2l::testing::temp_dir("estimator_units");
    const std::string mini = g2l::testing::fixture_dir() + "/ycbv_mini/models";
    g2l::geom::Mesh m = g2l::geom::load_mesh(mini + "/obj_000008.ply");
    g2l::EstimatorOptions opt;
    opt.refine = g2l::Refinement::turns;
    opt.meshes = dir;
    // Object 8's mesh in metres.
    m.vertices /= 1000.f;
    g2l::geom::save_ply(dir + "/obj_000008.ply", m);
    REQUIRE_THROWS_WITH(g2l::PoseEstimator(kModel, opt),
                        Contains("obj_000008.ply' is only 0.114") && Contains("looks like metres"));
    // The same with the dataset's models_info.json: measured against its diameter.
    opt.models_info = mini + "/models_info.json";
    REQUIRE_THROWS_WITH(g2l::PoseEstimator(kModel, opt),
                        Contains("declares diameter 114.05") && Contains("looks like metres"));
    // Millimetres, but object 14's mesh under object 8's name: the model was trained on 8.
    opt.models_info.clear();
    std::filesystem::copy_file(mini + "/obj_000014.ply", dir + "/obj_000008.ply",
                               std::filesystem::copy_options::overwrite_existing);
    REQUIRE_THROWS_WITH(g2l::PoseEstimator(kModel, opt),
                        Contains("measures 124.9") && Contains("trained on object 8 with diameter 114.05"));
}

TEST_CASE("PoseEstimator: a depth scale 10x off gives no 'ok' pose: implausible distance",
          "[infer]") {
    const Fixture f = load_frame(0);
    std::vector<g2l::ObjectBox> boxes;
    for (const auto& inst : f.frame->instances) boxes.push_back(box_of(inst));
    g2l::PoseEstimator est(kModel);
    g2l::FrameView v = view_of(f);
    for (const auto& p : est.estimate(v, boxes)) REQUIRE(p.ok());  // the right scale: plausible
    for (const double k : {10.0, 0.1}) {
        INFO("depth scale x" << k);
        v.depth_scale = f.frame->depth_scale * k;
        const auto poses = est.estimate(v, boxes);
        REQUIRE(poses.size() == boxes.size());
        for (const auto& p : poses) {
            // The pose exists (R, t set) but is not reported as ok: its distance contradicts
            // the box the object fills.
            CHECK(p.status == g2l::PoseStatus::rejected_implausible_distance);
            CHECK(std::string(g2l::to_string(p.status)) == "implausible distance");
            CHECK(p.t[2] != 0);
        }
    }
}

TEST_CASE("implausible_distance: box against the object's size at the pose's depth", "[infer]") {
    g2l::geom::Intrinsics K;
    K.fx = K.fy = 1000, K.cx = 320, K.cy = 240, K.width = 640, K.height = 480;
    g2l::geom::Pose p;
    p.t = {0, 0, 1000};  // a 100 mm object 1 m away covers ~100 px
    const g2l::geom::Box2i seen{270, 190, 90, 80};
    REQUIRE(g2l::infer::implausible_distance(p, seen, K, 100).empty());
    REQUIRE(g2l::infer::implausible_distance(p, {300, 230, 15, 12}, K, 100).empty());  // 85 % hidden
    p.t.z() = 10000;  // depth 10x too far: the object would cover ~10 px, the box is 90
    REQUIRE_THAT(g2l::infer::implausible_distance(p, seen, K, 100),
                 Contains("90 px box is more than twice") && Contains("reads too far"));
    p.t.z() = 100;  // 10x too near: ~1000 px, the box is 90
    REQUIRE_THAT(g2l::infer::implausible_distance(p, seen, K, 100), Contains("reads too near"));
    // ... unless the box is cut by the image border (the object may extend beyond it).
    p.t.z() = 150;
    REQUIRE(g2l::infer::implausible_distance(p, {0, 190, 60, 80}, K, 100).empty());
    p.t.z() = 30;
    REQUIRE_THAT(g2l::infer::implausible_distance(p, seen, K, 100), Contains("outside any RGB-D"));
    p.t.z() = std::nan("");
    REQUIRE_THAT(g2l::infer::implausible_distance(p, seen, K, 100), Contains("outside any RGB-D"));
}
