// SPDX-License-Identifier: MIT
// g2l — G2L-Net 6D object pose estimation from RGB-D frames, as a library.
//
// The whole public API: load a trained model (an inference export written by
// `g2l_train --export`, or a training checkpoint), then ask for the poses of the objects in
// 2D boxes of an RGB-D frame. Plain buffers and standard types only: no Eigen, OpenCV or
// g2l-internal headers are needed to use it.
//
//   #include <g2l/pose_estimator.h>
//   g2l::PoseEstimator est("models/ycbv_sim2real.g2l");
//   g2l::FrameView f;                      // borrowed buffers
//   f.width = 640; f.height = 480;
//   f.depth_u16 = depth.data(); f.depth_scale = 0.1;   // BOP YCB-V: 0.1 mm per unit
//   f.K = {1066.778, 1067.487, 312.9869, 241.3109};
//   for (const g2l::ObjectPose& p : est.estimate(f, {{5, 300, 200, 80, 160}}))
//       if (p.ok()) use(p.R, p.t);         // model -> camera, row-major R, t in mm
//
// Errors: invalid arguments and unreadable/corrupt model files throw std::runtime_error with a
// message that names the file, field or value. A box that cannot give a pose (object unknown
// to the model, box outside the image, no depth, too few points) does not throw: its
// ObjectPose carries the reason in `status` and the other boxes of the frame go on.
//
// Thread safety: a PoseEstimator may be shared between threads; calls to estimate() on one
// object are serialised (an internal mutex), so use one PoseEstimator per thread to run
// frames in parallel. The networks use the OpenMP threads set by EstimatorOptions::threads.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#if defined(__GNUC__)
#define G2L_API __attribute__((visibility("default")))
#else
#define G2L_API
#endif

namespace g2l {

/// Pinhole intrinsics in pixels: u = fx X / Z + cx, v = fy Y / Z + cy.
struct CameraIntrinsics {
    double fx = 0, fy = 0, cx = 0, cy = 0;
};

/// One RGB-D frame as borrowed, row-major, unpadded buffers of width x height pixels.
/// Exactly one of depth_u16 / depth_mm is set. Depth 0, NaN or inf means "no measurement".
struct FrameView {
    int width = 0, height = 0;
    const uint8_t* rgb = nullptr;         ///< optional RGB (3 bytes per pixel); the pose
                                          ///< networks use depth only
    const uint16_t* depth_u16 = nullptr;  ///< raw depth; z = value * depth_scale (mm)
    double depth_scale = 1.0;             ///< mm per unit of depth_u16 (BOP: scene_camera.json)
    const float* depth_mm = nullptr;      ///< depth already in mm
    CameraIntrinsics K;
};

/// A 2D box around one object, in pixels (BOP bbox convention: x, y, width, height).
struct ObjectBox {
    int obj_id = 0;      ///< the object's id in the model (BOP obj_id)
    int x = 0, y = 0, w = 0, h = 0;
    double score = 1.0;  ///< the detector's confidence; copied to ObjectPose::score
    /// The detector's class-probability peak (pixels); when >= 0 the sphere centre is this
    /// pixel lifted with the nearest valid depth in the box (spec §2), else it comes from the
    /// box and the depth alone. PoseEstimator::detect fills it.
    double peak_x = -1, peak_y = -1;
};

/// Why a box got no pose.
enum class PoseStatus {
    ok,                    ///< R and t are set
    unknown_object,        ///< the model was not trained on this obj_id
    box_outside_image,     ///< the box has no pixel inside the image
    no_depth,              ///< no valid depth in the box
    too_few_points,        ///< fewer than 10 depth points in the 3D crop
    too_few_object_points, ///< the segmentation kept fewer than 10 points
    // A pose was found but not reported (R, t and score are set; EstimatorOptions::keep_rejected
    // returns these from estimate(frame)):
    rejected_low_score,    ///< its verified score is below EstimatorOptions::min_pose_score
    rejected_duplicate,    ///< a higher-scored pose of the same object lies at the same place
    rejected_overlap,      ///< a higher-scored pose claims the same depth (ObjectPose::rival)
    /// Its distance disagrees with its box: the box is larger than the object can look at that
    /// depth, or far smaller than it must (a depth scale or camera off by a factor), or the
    /// pose lies nearer than 50 mm or beyond 20 m.
    rejected_implausible_distance
};

/// "ok", "unknown object", "box outside image", "no depth", "too few points",
/// "too few object points", "low score", "duplicate", "overlap", "implausible distance".
G2L_API const char* to_string(PoseStatus status);

/// Wall time of the stages of one box, in milliseconds. The boxes of one frame go through the
/// networks one at a time; their refinements run together (alongside the next boxes'
/// networks), so refine_ms is the frame's refinement time shared equally among its refined
/// boxes: the boxes' total_ms add up to the frame's time, not more.
struct PoseTimings {
    double crop_ms = 0;         ///< box centre, back-projection and 3D crop
    double segmentation_ms = 0;
    double translation_ms = 0;
    double rotation_ms = 0;     ///< blocks A, B, C and the two Kabsch fits
    /// depth refinement (EstimatorOptions::refine) and verification: this box's share of the
    /// frame's (see above)
    double refine_ms = 0;
    double total_ms = 0;
};

/// The result for one box.
struct ObjectPose {
    int obj_id = 0;
    PoseStatus status = PoseStatus::ok;
    std::array<double, 9> R{{1, 0, 0, 0, 1, 0, 0, 0, 1}};  ///< model -> camera, row-major
    std::array<double, 3> t{{0, 0, 0}};                    ///< model origin in the camera, mm
    /// How far the depth bears the pose out, in [0, 1], when the object's mesh is known
    /// (EstimatorOptions::meshes): the share of the model's visible surface the measured depth
    /// explains, discounted for free-space violations (the sensor saw through where the model
    /// would be) and occlusion, times the share of the segmented points the posed model
    /// explains (see `check`). Without the mesh: the box's (detection's) score. Threshold it
    /// with EstimatorOptions::min_pose_score; docs/results.md shows its precision-recall curve.
    double score = 0;
    double detection_score = 0;    ///< the box's (detector's) score
    std::array<int, 4> bbox{{0, 0, 0, 0}};  ///< the box it came from, clipped: x, y, w, h (px)
    /// The parts of `score` (all -1 when not verified).
    struct Check {
        double explained = -1;   ///< share of the visible model surface the depth explains
        double violation = -1;   ///< share seen through (free-space violations)
        double occlusion = -1;   ///< share hidden behind something nearer
        double seg_agree = -1;   ///< share of the object points on the posed surface
        /// The box of the posed surface the depth explains (x, y, w, h px): the pixels of the
        /// inlier points, a box drawn by the pose where `bbox` is the detector's; all 0 with
        /// too few inliers to place one (or not verified).
        std::array<int, 4> bbox{{0, 0, 0, 0}};
    } check;
    bool verified = false;         ///< `score` is the depth verification's
    /// rejected_duplicate / rejected_overlap: the index (in the returned list) of the pose that
    /// won; -1 otherwise.
    int rival = -1;
    int num_crop_points = 0;       ///< depth points in the 3D crop
    int num_object_points = 0;     ///< of those, segmented as the object
    /// With EstimatorOptions::refine: the mean distance (mm) from the object points to the
    /// posed mesh (each capped at 10% of the diameter) plus the free-space penalty; smaller is a
    /// better fit to the depth. -1 without refinement.
    double fit_mm = -1;
    /// With EstimatorOptions::refine: the fit (as fit_mm) of the best *distinct* pose the
    /// refinement found — a rotation more than 30 degrees from this one that the model's
    /// symmetries do not explain (a mug's handle on the other side, a clamp's jaws the other
    /// way). Near fit_mm, the depth cannot tell the two apart and the rotation is a guess; on
    /// renders, poses of objects without symmetries with alt_fit_mm < 1.2 fit_mm were right
    /// (ADD) in about one case in five (docs/results.md). -1 when there was none.
    double alt_fit_mm = -1;
    bool refined = false;  ///< the pose was refined (refine set and the object's mesh found)
    /// PoseTracker: the pose followed the previous frame's (false: a fresh detection's).
    bool tracked = false;
    /// PoseTracker: the instance's id, the same across the frames it is followed in; -1 outside
    /// a tracker.
    int track_id = -1;
    PoseTimings timings;
    bool ok() const { return status == PoseStatus::ok; }
};

/// Depth refinement of the networks' poses against the objects' meshes.
enum class Refinement {
    none,   ///< the networks' poses as they are (G2L-Net as published)
    icp,    ///< ICP of the segmented object points onto the mesh, from the networks' pose
    /// ICP also from that pose turned by the mesh box's near-symmetric turns (90/180-degree
    /// axis permutations, 45-degree axis turns); the start that fits the depth best (object
    /// points close to the mesh, no mesh point in front of the measured surface) wins when it
    /// fits clearly better than the networks' own. Fixes most of the flips a depth-only network
    /// makes (a box turned over, a mug's handle side); ~20-30 ms per box on 2 cores.
    turns,
    /// The default: `turns` when EstimatorOptions::meshes is given, `none` without.
    automatic
};

/// "none", "icp", "turns", "automatic".
G2L_API const char* to_string(Refinement refine);

/// "none", "icp", "turns" or "automatic" as a Refinement; anything else throws
/// std::runtime_error naming `what` (a flag or key) and the value.
G2L_API Refinement parse_refinement(const std::string& text, const std::string& what);

/// How a frame's boxes become poses: the one options type of the pipeline, whichever road runs
/// it (the library's PoseEstimator, g2l_infer, g2l_eval and training's validation all embed
/// it; nothing is translated). The defaults reproduce the settings the model was trained with.
struct G2L_API PipelineOptions {
    int crop_points = -1;     ///< points of the crop the segmentation sees (-1: the model's
                              ///< `sampling.points`; 0: the whole crop)
    int object_points = -1;   ///< object points fed to the translation and rotation networks
                              ///< (-1: the model's `sampling.seg_points`)
    /// Depth refinement: by default (`automatic`) every pose whose object has a mesh is refined
    /// (`turns`); `none` keeps the networks' poses even then.
    Refinement refine = Refinement::automatic;
    /// Detections scoring less are dropped. Low, because every hypothesis is verified against
    /// the depth: a weak peak of a partly hidden object is worth trying.
    double min_detection_score = 0.1;
    /// The best peaks kept per object, so several instances of one object each get a pose (bin
    /// picking).
    int max_instances = 3;
    /// The detections tried per frame (each posed, refined and verified), best detection
    /// scores first; bounds the frame's time.
    int max_hypotheses = 12;
    /// A peak of one object is also tried as each object whose mesh box's sorted sides all lie
    /// within this fraction of its own (a depth-only detector confuses such objects; needs the
    /// meshes); 0 = off.
    double alike_frac = 0.15;
    /// Poses whose verified score (ObjectPose::score) is below this are rejected ("low score").
    double min_pose_score = 0.0;
    /// Candidates are posed in order; one whose peak (else its box centre) lies on depth that an
    /// earlier verified pose scoring at least this explains is not posed at all ("covered"):
    /// second looks at a found object are rarely right and cost a full pose. Chosen on held-out
    /// renders (docs/results.md): 0.7 keeps every figure of posing all and saves ~30 % of the
    /// time; 0.5 saved ~40 % and lost 1.4 points. Above 1 = off.
    double cover_score = 0.7;
    /// Throws std::runtime_error naming the first option out of its range and its value.
    void check() const;
};

/// Options of a PoseEstimator: the pipeline's, plus where its files are.
struct G2L_API EstimatorOptions : PipelineOptions {
    int threads = 0;          ///< OpenMP threads for the networks (0 = leave as they are)
    /// A BOP models_info.json: the object diameters for model files that do not store them
    /// (older checkpoints), and the boxes and diameters the refinement uses for the meshes it
    /// lists (without it they are measured on the mesh) — give the dataset's file to get
    /// exactly g2l_eval's poses.
    std::string models_info;
    /// A 2D detector export (g2l_train with a "task": "detector" config writes
    /// <run_dir>/detector.g2l): enables detect() and estimate(frame) without boxes.
    std::string detector;
    /// estimate(frame) also returns the rejected hypotheses (after the accepted poses, with the
    /// reason in ObjectPose::status), e.g. to draw them.
    bool keep_rejected = false;
    /// detect(): the detector also sees the frame mirrored left-right and the two
    /// class-probability maps are averaged (two network passes; on the real LM-O images mean
    /// recall 45.9 -> 47.7, docs/results.md)
    bool detector_mirror = false;
    /// The folder of the objects' meshes, named as BOP names them (obj_000005.ply; mm): needed
    /// by `refine` and the verification. The constructor loads the mesh of every object of the
    /// model found there (at least one); an object without a mesh keeps the networks' pose
    /// (ObjectPose::refined). Without it, `automatic` refinement is `none`.
    std::string meshes;
    /// PipelineOptions::check(), and threads >= 0.
    void check() const;
};

/// G2L-Net's pose pipeline for the objects of one trained model.
/// The constructor throws std::runtime_error also when `refine` is icp or turns without `meshes`, when
/// that folder has no mesh of the model's objects, or a mesh is unreadable (naming the file).
class G2L_API PoseEstimator {
public:
    /// Loads `model_path` (an export or a training checkpoint). Throws std::runtime_error
    /// naming the file for a missing, truncated or corrupt file, and for objects whose
    /// diameter is unknown (see EstimatorOptions::models_info).
    explicit PoseEstimator(const std::string& model_path, const EstimatorOptions& options = {});
    ~PoseEstimator();
    PoseEstimator(PoseEstimator&&) noexcept;
    PoseEstimator& operator=(PoseEstimator&&) noexcept;
    PoseEstimator(const PoseEstimator&) = delete;
    PoseEstimator& operator=(const PoseEstimator&) = delete;

    /// One ObjectPose per box, in the order of `boxes`, each verified against the depth when
    /// its mesh is known (no box suppresses another). Throws std::runtime_error for an
    /// invalid frame: size <= 0, no depth or both depth buffers, depth_scale not finite and
    /// > 0, focal lengths not finite and > 0, principal point not finite.
    std::vector<ObjectPose> estimate(const FrameView& frame, const std::vector<ObjectBox>& boxes);

    /// G2L-Net's global localization: the detector (EstimatorOptions::detector) on what its
    /// export asks for (detector_input(): the RGB image, the depth with the intrinsics, or
    /// both); the best EstimatorOptions::max_instances peaks of each object it was trained on
    /// that score at least EstimatorOptions::min_detection_score, best first, each with its
    /// box. Throws std::runtime_error when no detector was given or the frame lacks what it
    /// needs.
    std::vector<ObjectBox> detect(const FrameView& frame);
    /// What the detector sees: "rgb", "depth" or "rgbd"; "" without a detector.
    std::string detector_input() const;
    /// The whole pipeline with hypotheses: detect(frame); each detection (and, with meshes,
    /// the same peak as each object of a like shape) posed, refined and verified against the
    /// depth; the best explained kept, a second pose of the same instance or one claiming the
    /// depth of a better pose rejected (a detection whose peak lies on depth a confident pose
    /// already explains is not even posed), poses below min_pose_score dropped. Several instances
    /// of one object each get a pose. Accepted poses first, best score first (then, with
    /// keep_rejected, the rejected ones).
    std::vector<ObjectPose> estimate(const FrameView& frame);

    /// The obj_ids the model knows, ascending.
    std::vector<int> object_ids() const;
    /// The diameter (mm) of a known object; throws std::runtime_error for another id.
    double diameter(int obj_id) const;
    /// The model's K keypoints of an object in its frame (mm), as x0 y0 z0 x1 ...; throws for
    /// an unknown id.
    std::vector<double> keypoints(int obj_id) const;

private:
    friend class PoseTracker;
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// Options of a PoseTracker.
struct TrackerOptions {
    /// The detector runs on every redetect_every-th frame even when every pose was followed, to
    /// find objects that entered the view (1 = every frame; 0 = only when needed).
    int redetect_every = 10;
    /// While a followed pose scores below min_track_score (a weak one: the wrong one of two like
    /// objects, a half-hidden one), the detector runs every redetect_weak_every frames and the
    /// weak poses are decided again from its fresh hypotheses (0 = redetect_every).
    int redetect_weak_every = 3;
    /// A pose scoring at least this is confident (on the real YCB-Video frames 99.5% of the poses
    /// scoring >= 0.5 are right); below it, weak.
    double min_track_score = 0.5;
    /// A confident pose whose followed pose scores below this has lost its object: the detector
    /// runs on that frame (between lost_score and min_track_score it turns weak).
    double lost_score = 0.3;
};

/// Poses across the frames of a video (a robot's camera, a recorded sequence). Each pose of
/// frame t is followed into frame t+1 (the depth near its posed surface, a short ICP from it,
/// verified against the depth again: ~1-3 ms per object instead of a detection and the
/// networks), and the whole pipeline of PoseEstimator::estimate(frame) runs only when needed:
/// on the first frame, when a confident pose loses its object, and every
/// TrackerOptions::redetect_every frames (objects entering the view). Each pose carries a
/// track_id, the same while the instance is followed. Frames may be skipped (a dropped frame is
/// a larger motion; a pose that cannot follow it is lost and found again by the detector).
///
///   g2l::PoseTracker tracker(est);           // est: a PoseEstimator with detector and meshes
///   for (each frame f) for (const g2l::ObjectPose& p : tracker.track(f)) use(p);
///
/// The estimator must outlive the tracker; the tracker uses the estimator's options
/// (min_pose_score, max_instances, ...) and is not thread-safe (one sequence, one thread).
class G2L_API PoseTracker {
public:
    /// Throws std::runtime_error when `estimator` has no detector or no meshes (refinement
    /// none), or the options are out of range.
    explicit PoseTracker(PoseEstimator& estimator, const TrackerOptions& options = {});
    ~PoseTracker();
    PoseTracker(PoseTracker&&) noexcept;
    PoseTracker& operator=(PoseTracker&&) noexcept;
    PoseTracker(const PoseTracker&) = delete;
    PoseTracker& operator=(const PoseTracker&) = delete;

    /// The poses of the next frame of the sequence, as PoseEstimator::estimate(frame) returns
    /// them (accepted first, best score first; with keep_rejected the rejected after them).
    /// Throws std::runtime_error for an invalid frame (the tracks are kept: the next frame
    /// goes on from the last good one).
    std::vector<ObjectPose> track(const FrameView& frame);
    /// Forgets every track (a new sequence, a cut): the next frame runs the detector.
    void reset();
    /// Whether the last track() ran the detector.
    bool detected() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// The library's version, "MAJOR.MINOR.PATCH".
G2L_API const char* version();

}  // namespace g2l
