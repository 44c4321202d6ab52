// SPDX-License-Identifier: MIT
// g2l_infer: 6D poses for RGB-D frames without ground truth, through the embeddable library
// (g2l::PoseEstimator). Prints JSON; --vis writes the frame with the projected 3D boxes.
#include <CLI/CLI.hpp>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/cli.h"
#include "core/error.h"
#include "core/json.h"
#include "data/bop.h"
#include "data/dataset.h"
#include "data/detections.h"
#include "data/draw.h"
#include "g2l/pose_estimator.h"

namespace {

using json = nlohmann::json;

/// The default model, `rel` (models/ycbv_sim2real.g2l), looked up where a user's g2l_infer can
/// find it: the working folder, then beside the program — the source tree of a build
/// (build/apps/g2l_infer → models/) and an installed prefix (bin/ → share/g2l/models/).
/// Returns `rel` unchanged when none has it (the estimator then names the missing file).
std::string default_model(const std::string& rel) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::is_regular_file(rel, ec)) return rel;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (ec) return rel;
    const fs::path name = fs::path(rel).filename();
    for (const fs::path& c : {exe.parent_path().parent_path().parent_path() / rel,
                              exe.parent_path().parent_path() / "share/g2l/models" / name}) {
        if (fs::is_regular_file(c, ec)) return c.string();
    }
    return rel;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"g2l_infer: 6D object poses for an RGB-D frame from a trained G2L-Net model and "
                 "2D boxes (a BOP detection file or --box). Prints one JSON object per run: per "
                 "box the status, R (row-major, model -> camera), t (mm), score and timings."};
    std::string model = "models/ycbv_sim2real.g2l", depth_path, rgb_path, camera_path, boxes_path,
                out_json, vis_path, models_info;
    std::vector<std::string> box_args;
    int scene_id = -1, image_id = -1, threads = 0;
    double min_score = 0;
    app.add_option("--model,--checkpoint", model,
                   "inference export or training checkpoint (default: the shipped YCB-Video "
                   "model, found next to this program whatever the working folder)")
        ->capture_default_str();
    app.add_option("--depth", depth_path, "16-bit depth PNG (BOP: depth/<id>.png)")->required();
    app.add_option("--rgb", rgb_path, "RGB image (the detector's input with --detector; drawn on "
                                      "with --vis)");
    std::string detector_path;
    app.add_option("--detector", detector_path,
                   "a 2D detector export (<run_dir>/detector.g2l of a \"task\": \"detector\" "
                   "training): finds the boxes on the frame instead of --boxes / --box; it sees "
                   "what its export says: the --rgb image, the depth, or both");
    bool det_mirror = false;
    app.add_flag("--det-mirror", det_mirror,
                 "the detector also sees the image mirrored left-right and averages the two "
                 "class-probability maps (two network passes)");
    app.add_option("--camera", camera_path,
                   "camera JSON: BOP camera.json, a scene_camera.json entry, or a whole "
                   "scene_camera.json with --image-id")
        ->required();
    app.add_option("--boxes", boxes_path, "BOP detection file (JSON array of {scene_id, image_id, "
                                          "category_id, bbox, score})");
    app.add_option("--box", box_args, "a box OBJ_ID,X,Y,W,H (repeatable; instead of --boxes)");
    app.add_option("--scene-id", scene_id, "keep detections of this scene (entries with one)");
    app.add_option("--image-id", image_id, "keep detections of this image; picks the camera "
                                           "entry of a scene_camera.json");
    app.add_option("--min-score", min_score, "skip detections scoring below this");
    app.add_option("--json", out_json, "write the JSON here instead of stdout");
    app.add_option("--vis", vis_path, "write a PNG with the estimated 3D boxes (blue) projected "
                                      "on the RGB image (or the depth)");
    app.add_option("--models-info", models_info,
                   "BOP models_info.json, for model files that do not store the diameters");
    app.add_option("--threads", threads, "CPU threads (0 = all)")->check(CLI::Range(0, 1024));
    std::string refine, meshes;
    app.add_option("--refine", refine,
                   "depth refinement against the objects' meshes (needs --meshes): turns (ICP "
                   "from the networks' pose and from its near-symmetric turns, the best depth fit "
                   "wins; ~40 ms per object), icp (from the networks' pose only) or none; default "
                   "turns with --meshes, none without")
        ->check(CLI::IsMember({"none", "icp", "turns"}));
    app.add_option("--meshes", meshes, "folder of the objects' meshes (obj_000005.ply ...; BOP "
                                       "models/): the poses are refined against them (--refine)");
    double min_pose_score = 0;
    app.add_option("--min-pose-score", min_pose_score,
                   "poses whose depth-verified score (the probability that the pose is right, "
                   "with --meshes) is below this are rejected: left out with --detector, marked "
                   "\"low score\" with given boxes")
        ->check(CLI::Range(0.0, 1.0));
    int max_instances = 3;
    app.add_option("--max-instances", max_instances,
                   "--detector: peaks (instances) of one object tried per frame")
        ->check(CLI::Range(1, 1000));
    bool keep_rejected = false;
    app.add_flag("--keep-rejected", keep_rejected,
                 "--detector: also list the rejected hypotheses (status low score, duplicate or "
                 "overlap, with the winning pose's index in \"rival\")");
    bool verbose = false;
    app.add_flag("--verbose", verbose, "error messages with their source location (also G2L_VERBOSE=1)");
    if (const int rc = g2l::cli::parse(app, argc, argv, "g2l_infer"); rc >= 0) return rc;
    if (int(!boxes_path.empty()) + int(!box_args.empty()) + int(!detector_path.empty()) != 1) {
        std::fprintf(stderr, "g2l_infer: give exactly one of --boxes, --box and --detector (see "
                             "g2l_infer --help)\n");
        return g2l::cli::kUsageError;
    }
    if (!refine.empty() && refine != "none" && meshes.empty()) {
        std::fprintf(stderr, "g2l_infer: --refine %s needs --meshes FOLDER (the objects' "
                             "obj_NNNNNN.ply meshes)\n", refine.c_str());
        return g2l::cli::kUsageError;
    }
    if (det_mirror && detector_path.empty()) {
        std::fprintf(stderr, "g2l_infer: --det-mirror needs --detector FILE\n");
        return g2l::cli::kUsageError;
    }
    // --box OBJ_ID,X,Y,W,H: five integers that fit the pixel range, W and H > 0 (a bad one is a
    // bad command line).
    std::vector<g2l::ObjectBox> hand_boxes;
    for (const std::string& a : box_args) {
        long v[5];
        const char* p = a.c_str();
        bool good = true;
        for (int k = 0; k < 5 && good; ++k) {
            char* end = nullptr;
            errno = 0;
            v[k] = std::strtol(p, &end, 10);
            good = end != p && errno == 0 && v[k] >= -1000000 && v[k] <= 1000000 &&
                   (k == 4 ? *end == '\0' : *end == ',');
            p = end + (k < 4 ? 1 : 0);
        }
        if (!good || v[3] <= 0 || v[4] <= 0) {
            std::fprintf(stderr, "g2l_infer: --box '%s': expected OBJ_ID,X,Y,W,H (integers within "
                                 "+-1000000, W and H > 0)\n", a.c_str());
            return g2l::cli::kUsageError;
        }
        hand_boxes.push_back({int(v[0]), int(v[1]), int(v[2]), int(v[3]), int(v[4]), 1.0});
    }
    try {
        // Boxes first: a typo there should not wait for the model to load.
        std::vector<g2l::ObjectBox> boxes;
        if (!boxes_path.empty()) {
            for (const auto& d : g2l::data::load_bop_detections(boxes_path)) {
                if (scene_id >= 0 && d.scene_id >= 0 && d.scene_id != scene_id) continue;
                if (image_id >= 0 && d.image_id >= 0 && d.image_id != image_id) continue;
                if (d.score < min_score) continue;
                boxes.push_back({d.obj_id, int(std::lround(d.x)), int(std::lround(d.y)),
                                 int(std::lround(d.w)), int(std::lround(d.h)), d.score});
            }
        }
        for (const g2l::ObjectBox& b : hand_boxes) boxes.push_back(b);
        const g2l::data::CameraFile cam = g2l::data::load_camera_file(camera_path, image_id);
        const g2l::CameraIntrinsics K{cam.fx, cam.fy, cam.cx, cam.cy};
        const double depth_scale = cam.depth_scale;
        const int cam_w = cam.width, cam_h = cam.height;
        int w = 0, h = 0;
        const std::vector<uint16_t> depth = g2l::data::load_depth_png(depth_path, &w, &h);
        G2L_CHECK((cam_w == 0 || cam_w == w) && (cam_h == 0 || cam_h == h), "--depth '",
                  depth_path, "' is ", w, " x ", h, " pixels but the camera '", camera_path,
                  "' is ", cam_w, " x ", cam_h, " (its intrinsics do not hold for this image)");
        g2l::data::Image rgb;
        if (!rgb_path.empty()) {
            rgb = g2l::data::load_rgb_image(rgb_path);
            G2L_CHECK(rgb.w == w && rgb.h == h, "--rgb '", rgb_path, "' is ", rgb.w, " x ", rgb.h,
                      " but the depth '", depth_path, "' is ", w, " x ", h);
        }
        g2l::EstimatorOptions opt;
        opt.threads = threads;
        opt.models_info = models_info;
        opt.detector = detector_path;
        opt.detector_mirror = det_mirror;
        opt.refine = refine.empty()      ? g2l::Refinement::automatic  // turns with --meshes
                     : refine == "icp"   ? g2l::Refinement::icp
                     : refine == "turns" ? g2l::Refinement::turns
                                         : g2l::Refinement::none;
        opt.meshes = meshes;
        opt.min_pose_score = min_pose_score;
        opt.max_instances = max_instances;
        opt.keep_rejected = true;  // drawn by --vis; left out of the JSON unless asked
        if (!detector_path.empty() && app.count("--min-score")) opt.min_detection_score = min_score;
        if (app.count("--model") == 0) model = default_model(model);
        g2l::PoseEstimator est(model, opt);
        const bool refining = !opt.meshes.empty() && opt.refine != g2l::Refinement::none;
        if (!detector_path.empty() && rgb_path.empty() && est.detector_input() != "depth") {
            std::fprintf(stderr, "g2l_infer: --detector '%s' is an %s detector: it needs the "
                                 "--rgb image\n", detector_path.c_str(), est.detector_input().c_str());
            return g2l::cli::kUsageError;
        }
        g2l::FrameView f;
        f.width = w;
        f.height = h;
        f.depth_u16 = depth.data();
        f.depth_scale = depth_scale;
        f.K = K;
        if (!rgb.data.empty()) f.rgb = rgb.data.data();
        // With the detector: the hypotheses road (several instances per object, each pose
        // verified, duplicates and overlaps rejected); with boxes: one pose per box.
        const std::vector<g2l::ObjectPose> poses =
            detector_path.empty() ? est.estimate(f, boxes) : est.estimate(f);
        auto rejected = [](const g2l::ObjectPose& p) {
            return p.status == g2l::PoseStatus::rejected_duplicate ||
                   p.status == g2l::PoseStatus::rejected_overlap ||
                   (p.status == g2l::PoseStatus::rejected_low_score);
        };

        json out;
        out["model"] = model;
        out["depth"] = depth_path;
        out["width"] = w;
        out["height"] = h;
        out["objects"] = json::array();
        for (size_t i = 0; i < poses.size(); ++i) {
            const g2l::ObjectPose& p = poses[i];
            // Rejected hypotheses of the detector road only with --keep-rejected (a rejected
            // given box keeps its place: one entry per box).
            if (!detector_path.empty() && rejected(p) && !keep_rejected) continue;
            const std::array<int, 4> bb = detector_path.empty()
                                              ? std::array<int, 4>{{boxes[i].x, boxes[i].y,
                                                                    boxes[i].w, boxes[i].h}}
                                              : p.bbox;
            json o = {{"obj_id", p.obj_id}, {"status", g2l::to_string(p.status)}, {"ok", p.ok()},
                      {"score", p.score}, {"detection_score", p.detection_score},
                      {"verified", p.verified}, {"bbox", bb},
                      {"num_crop_points", p.num_crop_points},
                      {"num_object_points", p.num_object_points},
                      {"timings_ms", {{"crop", p.timings.crop_ms},
                                      {"segmentation", p.timings.segmentation_ms},
                                      {"translation", p.timings.translation_ms},
                                      {"rotation", p.timings.rotation_ms},
                                      {"refine", p.timings.refine_ms},
                                      {"total", p.timings.total_ms}}}};
            // Always say whether the pose went through the refinement, and why not when it was
            // asked for and did not (no mesh of this object in --meshes).
            if (p.verified)
                o["check"] = {{"explained", p.check.explained}, {"violation", p.check.violation},
                              {"occlusion", p.check.occlusion}, {"seg_agree", p.check.seg_agree}};
            if (p.rival >= 0) o["rival"] = p.rival;
            o["refined"] = p.refined;
            if (p.refined) o["fit_mm"] = p.fit_mm;
            if (p.ok() && !p.refined && refining) {
                char mesh_name[32];
                std::snprintf(mesh_name, sizeof mesh_name, "obj_%06d.ply", p.obj_id);
                o["note"] = g2l::cat("not refined: no ", mesh_name, " in --meshes '",
                                     opt.meshes, "'");
            }
            if (p.ok() || rejected(p)) {
                o["R"] = p.R;
                o["t"] = p.t;
            }
            out["objects"].push_back(o);
        }
        if (!vis_path.empty()) {
            g2l::data::Image im;
            if (!rgb.data.empty()) {
                im = rgb;
            } else {
                std::vector<float> mm(depth.size());
                for (size_t i = 0; i < depth.size(); ++i) mm[i] = float(depth[i] * depth_scale);
                im = g2l::data::depth_to_rgb(mm, w, h);
            }
            g2l::geom::Intrinsics gk;
            gk.fx = K.fx, gk.fy = K.fy, gk.cx = K.cx, gk.cy = K.cy, gk.width = w, gk.height = h;
            // Reported poses blue with their id and score; rejected hypotheses red (drawn
            // first, underneath) with the reason.
            std::vector<const g2l::ObjectPose*> order;
            for (const g2l::ObjectPose& p : poses)
                if (rejected(p)) order.push_back(&p);
            for (const g2l::ObjectPose& p : poses)
                if (p.ok()) order.push_back(&p);
            for (const g2l::ObjectPose* pp : order) {
                const g2l::ObjectPose& p = *pp;
                const std::vector<double> kp = est.keypoints(p.obj_id);
                Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e30), hi = -lo;
                for (size_t k = 0; k + 2 < kp.size(); k += 3)
                    for (int c = 0; c < 3; ++c)
                        lo[c] = std::min(lo[c], kp[k + size_t(c)]), hi[c] = std::max(hi[c], kp[k + size_t(c)]);
                g2l::geom::Pose pose;
                for (int r = 0; r < 3; ++r) {
                    for (int c = 0; c < 3; ++c) pose.R(r, c) = p.R[size_t(r * 3 + c)];
                    pose.t[r] = p.t[size_t(r)];
                }
                const bool ok = p.ok();
                g2l::data::draw_box3d(&im, lo, hi, pose, gk,
                                      ok ? g2l::data::Rgb{40, 90, 255} : g2l::data::Rgb{230, 40, 40},
                                      ok ? 2 : 1);
                char label[96];
                if (ok)
                    std::snprintf(label, sizeof label, "%d %.2f", p.obj_id, p.score);
                else
                    std::snprintf(label, sizeof label, "%d %s %.2f", p.obj_id,
                                  g2l::to_string(p.status), p.score);
                const std::array<int, 4>& b = p.bbox;
                g2l::data::draw_text(&im, b[0], ok ? std::max(10, b[1] - 3) : b[1] + b[3] - 2,
                                     label, ok ? g2l::data::Rgb{120, 170, 255}
                                               : g2l::data::Rgb{255, 120, 120});
            }
            g2l::data::save_png(vis_path, im);
        }
        const std::string text = out.dump(2) + "\n";
        if (out_json.empty()) {
            errno = 0;
            const bool ok = std::fputs(text.c_str(), stdout) >= 0 && std::fflush(stdout) == 0;
            if (!ok) g2l::cli::stdout_failure_reported();
            G2L_CHECK(ok, "cannot write the JSON to the standard output: ",
                      errno ? std::strerror(errno) : "write error");
        } else {
            std::ofstream o(out_json);
            o << text;
            o.close();
            G2L_CHECK(o.good(), "--json '", out_json, "': cannot write the file: ",
                      errno ? std::strerror(errno) : "write error");
        }
        return 0;
    } catch (const std::exception& e) {
        return g2l::cli::report("g2l_infer", e, verbose);
    }
}
