// SPDX-License-Identifier: MIT
// g2l_infer: 6D poses for RGB-D frames without ground truth, through the embeddable library
// (g2l::PoseEstimator, g2l::PoseTracker). One frame (--depth) prints one JSON object; a video
// (--scene, a BOP scene folder, or --frames, a list) runs in one process, frame after frame,
// with --track following the poses from frame to frame. --vis draws the poses.
#include <CLI/CLI.hpp>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "pipeline_cli.h"
#include "core/cli.h"
#include "core/error.h"
#include "geometry/camera.h"
#include "core/json.h"
#include "data/bop.h"
#include "data/dataset.h"
#include "data/detections.h"
#include "data/draw.h"
#include "data/sequence.h"
#include "g2l/pose_estimator.h"

namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

/// Everything the command line asks for.
struct Job {
    std::string model = "models/ycbv_sim2real.g2l";
    bool model_given = false;
    std::string depth, rgb, camera, boxes;
    g2l::EstimatorOptions est;  // the library's options, filled by the flags directly
    std::string scene, frames;  // a sequence: a BOP scene folder or a list file
    std::string json_out, vis, bop_csv;
    std::vector<std::string> box_args;
    std::vector<g2l::ObjectBox> hand_boxes;  // --box, parsed
    std::map<int, std::string> names;        // obj_names.json beside --meshes, for --vis
    int scene_id = -1, image_id = -1, redetect_every = 10,
        redetect_weak_every = 3;
    double min_score = 0;
    bool min_score_given = false, keep_rejected = false, track = false,
         quiet = false, verbose = false;
    bool sequence() const { return !scene.empty() || !frames.empty(); }
};

/// The default model, `rel` (models/ycbv_sim2real.g2l), looked up where a user's g2l_infer can
/// find it: the working folder, then beside the program — the source tree of a build
/// (build/apps/g2l_infer → models/) and an installed prefix (bin/ → share/g2l/models/).
/// Returns `rel` unchanged when none has it (the estimator then names the missing file).
std::string default_model(const std::string& rel) {
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

void add_options(CLI::App& app, Job& j) {
    app.add_option("--model,--checkpoint", j.model,
                   "inference export or training checkpoint (default: the shipped YCB-Video "
                   "model, found next to this program whatever the working folder)")
        ->capture_default_str();
    app.add_option("--depth", j.depth, "one frame: its 16-bit depth PNG (BOP: depth/<id>.png)");
    app.add_option("--rgb", j.rgb, "one frame: its RGB image (the detector's input with "
                                   "--detector; drawn on with --vis)");
    app.add_option("--scene", j.scene,
                   "a video: a BOP scene folder (depth/, rgb/, scene_camera.json), its frames in "
                   "the order of their ids, in one process (instead of --depth)");
    app.add_option("--frames", j.frames,
                   "a video: a list file, one frame per line 'DEPTH_PNG [RGB_IMAGE]', all with "
                   "--camera (instead of --depth)");
    app.add_flag("--track", j.track,
                 "a video: follow each pose into the next frame (a short ICP from it, verified "
                 "against the depth) and run the detector only on the first frame, when a "
                 "confident pose is lost and every --redetect-every frames; needs --detector "
                 "and --meshes");
    app.add_option("--redetect-every", j.redetect_every,
                   "--track: the detector also runs every N frames, to find objects entering the "
                   "view (0 = only when a pose is lost)")
        ->check(CLI::Range(0, 1000000))
        ->capture_default_str();
    app.add_option("--redetect-weak-every", j.redetect_weak_every,
                   "--track: while a followed pose scores below 0.5 (a weak one), the detector "
                   "runs every N frames and decides it again (0 = --redetect-every)")
        ->check(CLI::Range(0, 1000000))
        ->capture_default_str();
    app.add_option("--detector", j.est.detector,
                   "a 2D detector export (<run_dir>/detector.g2l of a \"task\": \"detector\" "
                   "training): finds the boxes on the frame instead of --boxes / --box; it sees "
                   "what its export says: the --rgb image, the depth, or both");
    app.add_flag("--det-mirror", j.est.detector_mirror,
                 "the detector also sees the image mirrored left-right and averages the two "
                 "class-probability maps (two network passes)");
    app.add_option("--camera", j.camera,
                   "camera JSON: BOP camera.json, a scene_camera.json entry, or a whole "
                   "scene_camera.json with --image-id (--scene reads the scene's own)");
    app.add_option("--boxes", j.boxes, "BOP detection file (JSON array of {scene_id, image_id, "
                                       "category_id, bbox, score})");
    app.add_option("--box", j.box_args, "a box OBJ_ID,X,Y,W,H (repeatable; instead of --boxes)");
    app.add_option("--scene-id", j.scene_id,
                   "keep detections of this scene (entries with one); the scene_id of --bop-csv "
                   "(default: the --scene folder's number, else 0)");
    app.add_option("--image-id", j.image_id, "keep detections of this image; picks the camera "
                                             "entry of a scene_camera.json");
    app.add_option("--min-score", j.min_score, "skip detections scoring below this");
    app.add_option("--json", j.json_out,
                   "one frame: write the JSON here instead of stdout; a video: a folder, one "
                   "<image id>.json per frame (without it: one JSON object per line on stdout)");
    app.add_option("--bop-csv", j.bop_csv,
                   "also write the poses as a BOP Challenge results CSV (scene_id, im_id, "
                   "obj_id, score, R, t, time); g2l_eval --poses scores it");
    app.add_option("--vis", j.vis,
                   "one frame: a PNG; a video: a folder of numbered PNGs (<image id>.png): the "
                   "poses' 3D boxes (blue, with id and score; rejected hypotheses red) on the RGB "
                   "image (or the depth)");
    app.add_option("--models-info", j.est.models_info,
                   "BOP models_info.json, for model files that do not store the diameters");
    app.add_option("--threads", j.est.threads, "CPU threads (0 = all)")->check(CLI::Range(0, 1024));
    app.add_option("--meshes", j.est.meshes, "folder of the objects' meshes (obj_000005.ply ...; BOP "
                                         "models/): the poses are refined against them (--refine)");
    g2l::cli::add_pipeline_options(app, j.est, "--max-instances");
    app.add_flag("--keep-rejected", j.keep_rejected,
                 "--detector: also list the rejected hypotheses (status low score, duplicate or "
                 "overlap, with the winning pose's index in \"rival\")");
    app.add_flag("--quiet", j.quiet, "a video: no progress lines on stderr (errors still)");
    app.add_flag("--verbose", j.verbose,
                 "error messages with their source location (also G2L_VERBOSE=1)");
}

/// --box OBJ_ID,X,Y,W,H: five integers that fit the pixel range, W and H > 0.
bool parse_box(const std::string& a, g2l::ObjectBox* out) {
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
    if (!good || v[3] <= 0 || v[4] <= 0) return false;
    *out = {int(v[0]), int(v[1]), int(v[2]), int(v[3]), int(v[4]), 1.0};
    return true;
}

/// The usage rules; an empty string when the command line holds together.
std::string usage_error(Job& j) {
    const int sources = int(!j.boxes.empty()) + int(!j.box_args.empty()) + int(!j.est.detector.empty());
    if (sources != 1) return "give exactly one of --boxes, --box and --detector";
    if (int(!j.depth.empty()) + int(!j.scene.empty()) + int(!j.frames.empty()) != 1)
        return "give exactly one of --depth (one frame), --scene (a BOP scene folder) and "
               "--frames (a list file)";
    if (j.camera.empty() && j.scene.empty())
        return "--camera is required (except with --scene, which reads its scene_camera.json)";
    if (j.est.refine != g2l::Refinement::none && j.est.refine != g2l::Refinement::automatic &&
        j.est.meshes.empty())
        return std::string("--refine ") + g2l::to_string(j.est.refine) +
               " needs --meshes FOLDER (the objects' obj_NNNNNN.ply meshes)";
    if (j.est.detector_mirror && j.est.detector.empty()) return "--det-mirror needs --detector FILE";
    if (j.sequence() && !j.box_args.empty())
        return "--box is for one frame; a video takes --detector or --boxes (a BOP detection file "
               "with image ids)";
    if (j.sequence() && !j.rgb.empty()) return "--rgb is for one frame (--scene and --frames name their own)";
    if (j.track && !j.sequence()) return "--track follows poses across the frames of --scene or --frames";
    if (j.track && (j.est.detector.empty() || j.est.meshes.empty() ||
                    j.est.refine == g2l::Refinement::none))
        return "--track needs --detector and --meshes (it follows the poses against the meshes)";
    for (const std::string& a : j.box_args) {
        g2l::ObjectBox b;
        if (!parse_box(a, &b))
            return "--box '" + a + "': expected OBJ_ID,X,Y,W,H (integers within +-1000000, W and "
                   "H > 0)";
        j.hand_boxes.push_back(b);
    }
    return g2l::cli::pipeline_usage_error(j.est);
}

g2l::EstimatorOptions estimator_options(const Job& j) {
    g2l::EstimatorOptions opt = j.est;
    opt.keep_rejected = true;  // drawn by --vis; left out of the JSON unless asked
    // --min-score: the BOP detection file's threshold (default 0) and, given, the detector's.
    if (!j.est.detector.empty() && j.min_score_given) opt.min_detection_score = j.min_score;
    return opt;
}

bool rejected(const g2l::ObjectPose& p) {
    return p.status == g2l::PoseStatus::rejected_duplicate ||
           p.status == g2l::PoseStatus::rejected_overlap ||
           p.status == g2l::PoseStatus::rejected_low_score ||
           p.status == g2l::PoseStatus::rejected_implausible_distance;
}

/// A pose whose distance contradicts its box says the depth scale or the camera is likely
/// wrong: said on stderr (the first three, then a count at the end), never silently.
void warn_implausible(const std::vector<g2l::ObjectPose>& poses, const char* image, int* count) {
    for (const g2l::ObjectPose& p : poses) {
        if (p.status != g2l::PoseStatus::rejected_implausible_distance) continue;
        if ((*count)++ < 3)
            std::fprintf(stderr, "g2l_infer: warning: image %s: object %d's pose at z = %.0f mm "
                                 "disagrees with its %d x %d px box (status \"implausible "
                                 "distance\"): check the camera's depth_scale and intrinsics\n",
                         image, p.obj_id, p.t[2], p.bbox[2], p.bbox[3]);
    }
}

/// One frame's images and camera, loaded.
struct LoadedFrame {
    int image_id = 0;
    std::string depth_path;
    std::vector<uint16_t> depth;
    g2l::data::Image rgb;
    g2l::data::CameraFile cam;
    int w = 0, h = 0;
    g2l::FrameView view() const {
        g2l::FrameView f;
        f.width = w, f.height = h;
        f.depth_u16 = depth.data();
        f.depth_scale = cam.depth_scale;
        f.K = {cam.fx, cam.fy, cam.cx, cam.cy};
        if (!rgb.data.empty()) f.rgb = rgb.data.data();
        return f;
    }
};

/// Loads a frame; throws naming the file (a corrupt image, a camera of another size).
LoadedFrame load_frame(const g2l::data::SequenceFrame& sf, const std::string& camera_source) {
    G2L_CHECK(sf.camera_error.empty(), sf.camera_error);
    LoadedFrame f;
    f.image_id = sf.image_id;
    f.depth_path = sf.depth;
    f.cam = sf.camera;
    f.depth = g2l::data::load_depth_png(sf.depth, &f.w, &f.h);
    G2L_CHECK((f.cam.width == 0 || f.cam.width == f.w) && (f.cam.height == 0 || f.cam.height == f.h),
              "depth '", sf.depth, "' is ", f.w, " x ", f.h, " pixels but the camera '",
              camera_source, "' is ", f.cam.width, " x ", f.cam.height,
              " (its intrinsics do not hold for this image)");
    g2l::geom::Intrinsics K;
    K.fx = f.cam.fx, K.fy = f.cam.fy, K.cx = f.cam.cx, K.cy = f.cam.cy;
    static bool warned = false;  // once per run: a video has one camera
    if (const std::string why = g2l::geom::implausible_camera(K, f.w, f.h); !why.empty() && !warned) {
        warned = true;
        std::fprintf(stderr, "g2l_infer: warning: the camera '%s' looks wrong for '%s': %s\n",
                     camera_source.c_str(), sf.depth.c_str(), why.c_str());
    }
    if (!sf.rgb.empty()) {
        f.rgb = g2l::data::load_rgb_image(sf.rgb);
        G2L_CHECK(f.rgb.w == f.w && f.rgb.h == f.h, "rgb '", sf.rgb, "' is ", f.rgb.w, " x ",
                  f.rgb.h, " but the depth '", sf.depth, "' is ", f.w, " x ", f.h);
    }
    return f;
}

/// The BOP detections of one image (--boxes), filtered as the options say.
std::vector<g2l::ObjectBox> boxes_of(const std::vector<g2l::data::Detection>& dets, const Job& j,
                                     int scene_id, int image_id) {
    std::vector<g2l::ObjectBox> boxes;
    for (const auto& d : dets) {
        if (scene_id >= 0 && d.scene_id >= 0 && d.scene_id != scene_id) continue;
        if (image_id >= 0 && d.image_id >= 0 && d.image_id != image_id) continue;
        if (d.score < j.min_score) continue;
        boxes.push_back({d.obj_id, int(std::lround(d.x)), int(std::lround(d.y)),
                         int(std::lround(d.w)), int(std::lround(d.h)), d.score});
    }
    return boxes;
}

/// One frame's poses as the JSON object g2l_infer prints.
json frame_json(const Job& j, const LoadedFrame& f, const std::vector<g2l::ObjectPose>& poses,
                const std::vector<g2l::ObjectBox>& boxes, bool refining) {
    json out;
    out["model"] = j.model;
    out["depth"] = f.depth_path;
    out["width"] = f.w;
    out["height"] = f.h;
    out["objects"] = json::array();
    for (size_t i = 0; i < poses.size(); ++i) {
        const g2l::ObjectPose& p = poses[i];
        // Rejected hypotheses of the detector road only with --keep-rejected (a rejected
        // given box keeps its place: one entry per box).
        if (!j.est.detector.empty() && rejected(p) && !j.keep_rejected) continue;
        const std::array<int, 4> bb =
            j.est.detector.empty() ? std::array<int, 4>{{boxes[i].x, boxes[i].y, boxes[i].w, boxes[i].h}}
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
        if (p.verified)
            o["check"] = {{"explained", p.check.explained}, {"violation", p.check.violation},
                          {"occlusion", p.check.occlusion}, {"seg_agree", p.check.seg_agree},
                          {"bbox", p.check.bbox}};
        if (p.rival >= 0) o["rival"] = p.rival;
        if (j.track) o["track_id"] = p.track_id, o["tracked"] = p.tracked;
        // Always say whether the pose went through the refinement, and why not when it was
        // asked for and did not (no mesh of this object in --meshes).
        o["refined"] = p.refined;
        if (p.refined) o["fit_mm"] = p.fit_mm;
        if (p.refined) o["alt_fit_mm"] = p.alt_fit_mm;
        if (p.ok() && !p.refined && refining) {
            char mesh_name[32];
            std::snprintf(mesh_name, sizeof mesh_name, "obj_%06d.ply", p.obj_id);
            o["note"] = g2l::cat("not refined: no ", mesh_name, " in --meshes '", j.est.meshes, "'");
        }
        if (p.ok() || rejected(p)) {
            o["R"] = p.R;
            o["t"] = p.t;
        }
        out["objects"].push_back(o);
    }
    return out;
}

/// The objects' names for the pictures: the BOP obj_names.json ({"5": "006_mustard_bottle"})
/// in the --meshes folder or its parent; none when neither has one (ids only).
std::map<int, std::string> object_names(const std::string& meshes) {
    std::map<int, std::string> out;
    if (meshes.empty()) return out;
    for (const fs::path& p : {fs::path(meshes) / "obj_names.json",
                              fs::path(meshes).parent_path() / "obj_names.json"}) {
        std::error_code ec;
        if (!fs::is_regular_file(p, ec)) continue;
        const json j = g2l::parse_json_file(p.string());
        G2L_CHECK(j.is_object(), "'", p.string(), "': expected an object of id -> name");
        for (auto it = j.begin(); it != j.end(); ++it) {
            char* end = nullptr;
            const long id = std::strtol(it.key().c_str(), &end, 10);
            if (*end == '\0' && it.value().is_string()) out[int(id)] = it.value().get<std::string>();
        }
        break;
    }
    return out;
}

/// The frame (its RGB image, else its depth in colour) with the poses' 3D boxes: reported
/// poses blue with their id, name, track id and score, rejected hypotheses red (underneath)
/// with the reason.
void draw_poses(const std::string& path, const LoadedFrame& f,
                const std::vector<g2l::ObjectPose>& poses, const g2l::PoseEstimator& est,
                const std::map<int, std::string>& names) {
    g2l::data::Image im;
    if (!f.rgb.data.empty()) {
        im = f.rgb;
    } else {
        std::vector<float> mm(f.depth.size());
        for (size_t i = 0; i < f.depth.size(); ++i) mm[i] = float(f.depth[i] * f.cam.depth_scale);
        im = g2l::data::depth_to_rgb(mm, f.w, f.h);
    }
    g2l::geom::Intrinsics gk;
    gk.fx = f.cam.fx, gk.fy = f.cam.fy, gk.cx = f.cam.cx, gk.cy = f.cam.cy;
    gk.width = f.w, gk.height = f.h;
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
        const auto nm = names.find(p.obj_id);
        const std::string id = std::to_string(p.obj_id) +
                               (nm != names.end() ? " " + nm->second.substr(0, 24) : std::string());
        char label[128];
        if (ok && p.track_id >= 0)
            std::snprintf(label, sizeof label, "%s #%d %.2f", id.c_str(), p.track_id, p.score);
        else if (ok)
            std::snprintf(label, sizeof label, "%s %.2f", id.c_str(), p.score);
        else
            std::snprintf(label, sizeof label, "%s %s %.2f", id.c_str(), g2l::to_string(p.status),
                          p.score);
        const std::array<int, 4>& b = p.bbox;
        g2l::data::draw_text(&im, b[0], ok ? std::max(10, b[1] - 3) : b[1] + b[3] - 2, label,
                             ok ? g2l::data::Rgb{120, 170, 255} : g2l::data::Rgb{255, 120, 120});
    }
    g2l::data::save_png(path, im);
}

/// Writes `text` to `path` (empty: stdout); throws naming the file on a write error.
void write_text(const std::string& path, const std::string& text) {
    if (path.empty()) {
        errno = 0;
        const bool ok = std::fputs(text.c_str(), stdout) >= 0 && std::fflush(stdout) == 0;
        if (!ok) g2l::cli::stdout_failure_reported();
        G2L_CHECK(ok, "cannot write the JSON to the standard output: ",
                  errno ? std::strerror(errno) : "write error");
        return;
    }
    std::ofstream o(path);
    o << text;
    o.close();
    G2L_CHECK(o.good(), "'", path, "': cannot write the file: ",
              errno ? std::strerror(errno) : "write error");
}

/// The reported poses of one frame as BOP CSV rows.
void csv_rows(std::ofstream& csv, int scene_id, int image_id,
              const std::vector<g2l::ObjectPose>& poses, double seconds) {
    for (const g2l::ObjectPose& p : poses) {
        if (!p.ok()) continue;
        char buf[512];
        std::snprintf(buf, sizeof buf,
                      "%d,%d,%d,%.6f,%.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f,%.6f %.6f "
                      "%.6f,%.6f\n",
                      scene_id, image_id, p.obj_id, p.score, p.R[0], p.R[1], p.R[2], p.R[3],
                      p.R[4], p.R[5], p.R[6], p.R[7], p.R[8], p.t[0], p.t[1], p.t[2], seconds);
        csv << buf;
    }
}

std::ofstream open_csv(const std::string& path) {
    std::ofstream csv;
    if (path.empty()) return csv;
    csv.open(path);
    G2L_CHECK(csv.good(), "--bop-csv '", path, "': cannot write the file");
    csv << "scene_id,im_id,obj_id,score,R,t,time\n";
    return csv;
}

void close_csv(std::ofstream& csv, const std::string& path) {
    if (!csv.is_open()) return;
    csv.close();
    G2L_CHECK(csv.good(), "--bop-csv '", path, "': write error");
}

int run_frame(Job& j, const std::vector<g2l::data::Detection>& dets) {
    g2l::data::SequenceFrame sf;
    sf.image_id = j.image_id;
    sf.depth = j.depth;
    sf.rgb = j.rgb;
    sf.camera = g2l::data::load_camera_file(j.camera, j.image_id);
    const LoadedFrame f = load_frame(sf, j.camera);
    std::vector<g2l::ObjectBox> boxes = boxes_of(dets, j, j.scene_id, j.image_id);
    for (const g2l::ObjectBox& b : j.hand_boxes) boxes.push_back(b);
    const g2l::EstimatorOptions opt = estimator_options(j);
    g2l::PoseEstimator est(j.model, opt);
    if (!j.est.detector.empty() && j.rgb.empty() && est.detector_input() != "depth") {
        std::fprintf(stderr, "g2l_infer: --detector '%s' is an %s detector: it needs the --rgb "
                             "image\n", j.est.detector.c_str(), est.detector_input().c_str());
        return g2l::cli::kUsageError;
    }
    // With the detector: the hypotheses road (several instances per object, each pose
    // verified, duplicates and overlaps rejected); with boxes: one pose per box.
    const auto t0 = std::chrono::steady_clock::now();
    const std::vector<g2l::ObjectPose> poses =
        j.est.detector.empty() ? est.estimate(f.view(), boxes) : est.estimate(f.view());
    const double sec =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    int implausible = 0;
    warn_implausible(poses, std::to_string(std::max(0, j.image_id)).c_str(), &implausible);
    const bool refining = !opt.meshes.empty() && opt.refine != g2l::Refinement::none;
    if (!j.vis.empty()) draw_poses(j.vis, f, poses, est, object_names(j.est.meshes));
    std::ofstream csv = open_csv(j.bop_csv);
    if (csv.is_open()) csv_rows(csv, std::max(0, j.scene_id), std::max(0, j.image_id), poses, sec);
    close_csv(csv, j.bop_csv);
    write_text(j.json_out, frame_json(j, f, poses, boxes, refining).dump(2) + "\n");
    return 0;
}

/// A video, frame after frame in one process: a bad frame is reported and skipped (the
/// tracker goes on from the last good one); the exit code says whether any failed.
/// The frames of --scene or --frames, and the scene id their CSV rows carry (--scene-id, else
/// a BOP scene folder's name, else 0).
std::vector<g2l::data::SequenceFrame> sequence_frames(const Job& j, int* scene_id) {
    *scene_id = j.scene_id;
    if (j.scene.empty()) {
        *scene_id = std::max(0, *scene_id);
        return g2l::data::list_frames_file(j.frames, g2l::data::load_camera_file(j.camera, j.image_id));
    }
    if (*scene_id < 0) {  // BOP: the folder's name is the scene id
        const std::string name = fs::path(j.scene).lexically_normal().filename().string();
        const std::string stem = name.empty() ? fs::path(j.scene).parent_path().filename().string() : name;
        char* end = nullptr;
        const long v = std::strtol(stem.c_str(), &end, 10);
        *scene_id = !stem.empty() && *end == '\0' && v >= 0 && v < 1000000000 ? int(v) : 0;
    }
    return g2l::data::list_bop_scene(j.scene);
}

int run_sequence(Job& j, const std::vector<g2l::data::Detection>& dets) {
    int scene_id = 0;
    const std::vector<g2l::data::SequenceFrame> frames = sequence_frames(j, &scene_id);
    const g2l::EstimatorOptions opt = estimator_options(j);
    g2l::PoseEstimator est(j.model, opt);
    std::unique_ptr<g2l::PoseTracker> tracker;
    if (j.track) {
        g2l::TrackerOptions to;
        to.redetect_every = j.redetect_every;
        to.redetect_weak_every = j.redetect_weak_every;
        tracker = std::make_unique<g2l::PoseTracker>(est, to);
    }
    const bool refining = !opt.meshes.empty() && opt.refine != g2l::Refinement::none;
    std::error_code ec;
    for (const std::string* dir : {&j.json_out, &j.vis})
        if (!dir->empty()) {
            fs::create_directories(*dir, ec);
            G2L_CHECK(fs::is_directory(*dir, ec), "'", *dir, "' is not a folder and cannot be made");
        }
    std::ofstream csv = open_csv(j.bop_csv);
    if (!j.vis.empty()) j.names = object_names(j.est.meshes);
    const std::string camera_source = j.scene.empty() ? j.camera : j.scene + "/scene_camera.json";
    int failed = 0, detected = 0, implausible = 0;
    double total_ms = 0;
    const auto start = std::chrono::steady_clock::now();
    const size_t progress_every = std::max<size_t>(1, frames.size() / 50);
    for (size_t n = 0; n < frames.size(); ++n) {
        const g2l::data::SequenceFrame& sf = frames[n];
        char id[16];
        std::snprintf(id, sizeof id, "%06d", sf.image_id);
        try {
            const LoadedFrame f = load_frame(sf, camera_source);
            G2L_CHECK(j.est.detector.empty() || !f.rgb.data.empty() || est.detector_input() == "depth",
                      "frame ", id, " has no RGB image and the --detector is an ",
                      est.detector_input(), " detector");
            const std::vector<g2l::ObjectBox> boxes = boxes_of(dets, j, scene_id, sf.image_id);
            const auto t0 = std::chrono::steady_clock::now();
            const std::vector<g2l::ObjectPose> poses =
                tracker ? tracker->track(f.view())
                : j.est.detector.empty() ? est.estimate(f.view(), boxes) : est.estimate(f.view());
            const double ms = std::chrono::duration<double, std::milli>(
                                  std::chrono::steady_clock::now() - t0).count();
            total_ms += ms;
            warn_implausible(poses, id, &implausible);
            const bool det = tracker ? tracker->detected() : true;
            detected += det;
            json out = frame_json(j, f, poses, boxes, refining);
            out["image_id"] = sf.image_id;
            out["ms"] = ms;
            if (tracker) out["detected"] = det;
            if (j.json_out.empty())
                write_text("", out.dump() + "\n");
            else
                write_text((fs::path(j.json_out) / (std::string(id) + ".json")).string(),
                           out.dump(2) + "\n");
            if (csv.is_open()) csv_rows(csv, scene_id, sf.image_id, poses, ms / 1000.0);
            if (!j.vis.empty())
                draw_poses((fs::path(j.vis) / (std::string(id) + ".png")).string(), f, poses, est,
                           j.names);
            if (!j.quiet && ((n + 1) % progress_every == 0 || n + 1 == frames.size())) {
                int reported = 0;
                for (const auto& p : poses) reported += p.ok();
                const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
                std::fprintf(stderr, "g2l_infer: frame %zu/%zu (image %s): %d poses, %.1f ms%s, "
                                     "ETA %.0f s\n", n + 1, frames.size(), id, reported, ms,
                             tracker ? (det ? ", detector" : ", tracked") : "",
                             el / double(n + 1) * double(frames.size() - n - 1));
            }
        } catch (const std::exception& e) {
            ++failed;
            std::fprintf(stderr, "g2l_infer: frame %zu/%zu (image %s) failed, the others go on: %s\n",
                         n + 1, frames.size(), id, e.what());
        }
    }
    close_csv(csv, j.bop_csv);
    if (implausible > 3)
        std::fprintf(stderr, "g2l_infer: warning: %d poses in all had an implausible distance "
                             "(depth scale or camera)\n", implausible);
    const int good = int(frames.size()) - failed;
    if (!j.quiet)
        std::fprintf(stderr, "g2l_infer: %d frames, mean %.1f ms per frame (poses only)%s\n", good,
                     good ? total_ms / good : 0.0,
                     tracker ? g2l::cat(", the detector ran on ", detected).c_str() : "");
    if (failed) {
        std::fprintf(stderr, "g2l_infer: %d of %zu frames failed (above); the others are written\n",
                     failed, frames.size());
        return g2l::cli::kRunError;
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"g2l_infer: 6D object poses for RGB-D frames from a trained G2L-Net model and "
                 "2D boxes (a detector, a BOP detection file or --box). One frame (--depth) prints "
                 "one JSON object: per pose the status, R (row-major, model -> camera), t (mm), "
                 "score and timings. A video (--scene or --frames) runs in one process, one JSON "
                 "per frame, --track following the poses from frame to frame."};
    Job j;
    add_options(app, j);
    if (const int rc = g2l::cli::parse(app, argc, argv, "g2l_infer"); rc >= 0) return rc;
    j.model_given = app.count("--model") > 0;
    j.min_score_given = app.count("--min-score") > 0;
    if (const std::string err = usage_error(j); !err.empty()) {
        std::fprintf(stderr, "g2l_infer: %s (see g2l_infer --help)\n", err.c_str());
        return g2l::cli::kUsageError;
    }
    try {
        // Boxes first: a typo there should not wait for the model to load.
        const std::vector<g2l::data::Detection> dets =
            j.boxes.empty() ? std::vector<g2l::data::Detection>{}
                            : g2l::data::load_bop_detections(j.boxes);
        if (!j.model_given) j.model = default_model(j.model);
        return j.sequence() ? run_sequence(j, dets) : run_frame(j, dets);
    } catch (const std::exception& e) {
        return g2l::cli::report("g2l_infer", e, j.verbose);
    }
}
