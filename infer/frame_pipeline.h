// SPDX-License-Identifier: MIT
// The one road from a depth frame and 2D boxes to poses (spec §2-§4 + the depth refinement):
// clip the box → sphere centre (the class-probability peak, else the box's depth centre) →
// crop (geometry/crop.h) → the compiled networks (nn::PoseEngine), one box at a time →
// refinement against the object's mesh (geometry/refine.h). g2l::PoseEstimator (the library a
// user links), g2l_eval and g2l_bench all run this code; evaluation adds only the ground truth
// it compares with, and optional oracle inputs between the crop and the networks.
//
// Internal (not installed): the public face is include/g2l/pose_estimator.h.
#pragma once

#include <Eigen/Core>
#include <array>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "g2l/pose_estimator.h"
#include "geometry/crop.h"
#include "geometry/model_info.h"
#include "geometry/refine.h"
#include "geometry/symmetry.h"
#include "geometry/types.h"
#include "geometry/verify.h"
#include "nn/models/g2l_engine.h"
#include "nn/models/g2l_io.h"

namespace g2l::infer {

/// What the refinement (and evaluation's object-point rule) needs of one object's mesh,
/// prepared once per object: the surface k-d tree (vertices + surface samples), and for the
/// refinement the tree points' normals and the closest-point grid.
struct PreparedMesh {
    std::unique_ptr<geom::ModelKdTree> tree;
    geom::Points normals;
    geom::ClosestPointGrid grid;
    geom::ModelInfo info;  ///< the box and diameter the refinement uses
    /// The model's geometric symmetries (geometry/symmetry.h; with for_refine): which of the
    /// refinement's finalists are distinct poses (PoseOutcome::alt_fit_mm).
    std::vector<geom::SymmetryTransform> syms;
    /// Throws g2l::Error for a mesh without vertices or an info with diameter <= 0.
    static PreparedMesh from_mesh(const geom::Mesh& mesh, const geom::ModelInfo& info,
                                  bool for_refine);
};

/// One box to pose.
struct PoseRequest {
    int obj_id = 0;
    geom::Box2i box;                 ///< pixels; clipped to the image here
    double peak_x = -1, peak_y = -1; ///< the class-probability peak (px); < 0: none
    /// The sphere centre (mm, camera frame) when the caller knows it (evaluation's
    /// ground-truth-mask protocol); otherwise the peak's depth, else the box's depth centre.
    std::optional<Eigen::Vector3d> centre;
};

enum class PoseStatus {
    ok,
    unknown_object,         ///< not an object of the model
    box_outside_image,      ///< the box does not overlap the image
    no_depth,               ///< no valid depth at the sphere centre
    too_few_points,         ///< fewer than 10 crop points
    too_few_object_points,  ///< the segmentation kept fewer than 10 points
};
const char* to_string(PoseStatus s);

/// What happened to one request. `crop` and `object_rows` stay valid until the next call.
struct PoseOutcome {
    int obj_id = 0;
    PoseStatus status = PoseStatus::ok;
    geom::Box2i box;                  ///< the box used (clipped)
    geom::Points crop;                ///< the crop points the networks got (camera frame, mm)
    std::vector<int> object_rows;     ///< crop rows taken as object (segmentation or oracle)
    geom::Pose pose;                  ///< valid when status == ok
    int num_crop_points = 0, num_object_points = 0;
    double ms_crop = 0, ms_seg = 0, ms_t = 0, ms_rot = 0;
    /// The frame's refinement (and verification) wall time shared equally among its refined
    /// boxes: a frame's boxes are refined together (FramePipeline::estimate), so one box's own
    /// span overlaps the others' and would count the same milliseconds twice.
    double ms_refine = 0;
    bool refined = false;             ///< a mesh refined the pose
    /// With estimate's `verify`: the pose checked against the depth (status ok, a mesh).
    std::optional<geom::Verification> check;
    double fit_mm = -1;               ///< the refinement's final fit (geometry/refine.h)
    /// the best fit of a distinct pose (RefineResult::alt_fit_mm): near fit_mm, the depth
    /// cannot tell the pose from it; -1 when there was none
    double alt_fit_mm = -1;
    int refine_hypothesis = -1, refine_cluster = -1;
    bool ok() const { return status == PoseStatus::ok; }
};

/// Oracle inputs for one request (evaluation only): the ground-truth object points replace the
/// segmentation, the ground-truth translation replaces the T-net's. Null = the network's.
struct Oracle {
    const std::vector<uint8_t>* object_mask = nullptr;  ///< one flag per crop row
    const Eigen::Vector3f* translation = nullptr;
};

/// What the pipeline needs of a pose model. The network is borrowed (in eval mode, must
/// outlive the pipeline; the compiled engine copies its weights at construction).
struct PipelineModel {
    nn::G2LNet* net = nullptr;
    std::map<int, int> class_of;  ///< obj_id -> class index
    std::vector<std::vector<Eigen::Vector3f>> keypoints;  ///< class index -> model keypoints
    std::map<int, double> diameter;  ///< obj_id -> mm; the sphere radius is radius_scale x it
    geom::CropKind crop = geom::CropKind::sphere;  ///< the crop the network was trained with
    double radius_scale = 1.0;
    int points = 0;                  ///< seg-net input points per crop (0 = the whole crop)
    int seg_points = 2000;           ///< object points fed to the T-net and the rotation blocks
    /// A loaded model file's (its diameters: the stored ones).
    static PipelineModel of(const nn::LoadedModel& m);
};

/// A detection to pose: the detector's box and class-probability peak of one object.
struct Candidate {
    int obj_id = 0;
    geom::Box2i box;
    double peak_x = -1, peak_y = -1;  ///< the class-probability peak (px); < 0: none
    double det_score = 0;             ///< the detector's heat at the peak
    /// The object the detector's peak was for: obj_id itself, or an object of a like shape
    /// whose peak this candidate re-uses (PipelineOptions::alike_frac).
    int det_obj_id = 0;
};

/// The score of a verified pose as the probability that it is right (ADD-S < 0.1 d): a logistic
/// model over the verification's parts and the detector's score. Depth alone cannot tell two
/// objects of a like shape apart (a gelatin box fits the face of a pudding box), the detector's
/// class map can; and a pose the depth explains is right more often than its detection score
/// says. Fitted on renders, never on real frames (`g2l_eval --fit-score`, docs/results.md).
struct ScoreModel {
    static constexpr int kFeatures = 8;
    using Features = std::array<double, kFeatures>;
    /// 1, explained, violation, occlusion, seg_agree, support x seg_agree, ln(det_score), and 1
    /// when the peak was borrowed from an object of a like shape.
    static Features features(const geom::Verification& v, double det_score, bool borrowed);
    /// w . x: the logit of the score model and of the arbiter (ArbiterModel).
    static double dot(const Features& w, const Features& x);
    /// 1 / (1 + e^-z), z clamped to +-40: the link of both models and of their fits.
    static double sigmoid(double z);
    /// Fitted on the verified hypotheses of 60 renders (configs/scenes/ycbv_table_blocks.json,
    /// seed 31; the shipped detector and pose model; docs/results.md has the command and the
    /// curves); first 2026-12-05, refitted 2026-12-07 with the same command on the pipeline of
    /// that day, which gives exactly these weights.
    Features w{{-0.2752, 0.6647, -0.7054, 0.0476, 0.7892, 1.6196, 1.8956, -0.1533}};
    /// sigmoid(w . features), in (0, 1).
    double probability(const geom::Verification& v, double det_score, bool borrowed) const;
};

/// Which of two poses that claim the same depth (an overlap, or a duplicate of one object) is
/// the right one, when one of them is: P(a right | exactly one of a, b right) =
/// sigmoid(w . (features(a) - features(b)) + footprint x ln(cells(a) / cells(b))), the score
/// model's features (ScoreModel::features; the bias cancels, w[0] = 0) and the cells of depth
/// each claims. The score model answers "is this pose right?" over every
/// hypothesis, most of them phantoms a weak peak makes, so the detector's heat weighs most
/// there; between two poses of the same depth the depth's own evidence (the explained share,
/// the violations, the segmentation's agreement) weighs more. Fitted on renders only, on the
/// overlaps and duplicates where exactly one pose was right (`g2l_eval --fit-score`,
/// docs/results.md).
struct ArbiterModel {
    /// Fitted 2026-12-08 on the conflicts of 60 renders (configs/scenes/
    /// ycbv_table_blocks.json, seed 31; the shipped width-32 detector and pose model), the
    /// score order's conflicts (the fit's run does not arbitrate: EvalOptions::arbitrate),
    /// with the footprint term (docs/experiments.md, "How much depth a pose claims").
    ScoreModel::Features w{{0, 1.0589, -0.8717, -0.1872, 1.1680, 2.3982, 1.3249, -0.2940}};
    /// The weight of ln(footprint cells), the depth a pose claims in absolute terms (the
    /// features say how much of its *model* the depth explains, not how much of the *depth* it
    /// explains): of two poses claiming the same depth, the one that claims more explains what
    /// the other does and more — a box posed on one face of a larger object claims a part of
    /// that object's depth, the object all of the box's.
    double footprint = 1.3994;
    /// ln(cells) of a footprint (geom::Verification::footprint), ln 1 = 0 for an empty one.
    static double ln_cells(size_t cells);
    /// P(a right | exactly one right) for two verified poses' features and footprints' ln_cells.
    /// A difference of per-pose strengths (w . features + footprint x ln_cells), so the
    /// preference is an order: the selection's re-tries end.
    double prefer(const ScoreModel::Features& a, const ScoreModel::Features& b,
                  double ln_cells_a = 0, double ln_cells_b = 0) const;
};

/// The fixed settings of the hypotheses road (spec §16; what a user may change is in
/// g2l::PipelineOptions): every candidate is posed by the networks and refined, verified
/// against the depth (geometry/verify.h), and the best explained kept, suppressing duplicates
/// and overlaps.
struct HypothesisTuning {
    /// A peak borrowed from an object of a like shape (PipelineOptions::alike_frac) enters with
    /// this share of its detection score.
    double alike_discount = 0.8;
    /// Two poses of one object whose centres lie closer than this fraction of its diameter are
    /// one instance — the lower score is a duplicate — when they also claim some of the same
    /// depth: more than duplicate_overlap of the lower one's footprint
    /// (geom::footprint_overlap; unverified poses: the centres alone). Copies of one part
    /// touching in a bin lie closer than half a diameter yet claim different pixels.
    double duplicate_frac = 0.5;
    double duplicate_overlap = 0.1;
    /// A pose more than this share of whose depth a higher-scored kept pose claims too
    /// (geom::footprint_overlap) is rejected ("overlap"): two objects cannot fill the same
    /// space.
    double overlap_frac = 0.3;
    geom::VerifyOptions verify;
    ScoreModel score_model;
    /// A later (lower-scored) pose that conflicts with kept ones replaces them when the arbiter
    /// prefers it to each of them (both verified, neither a fill-in); false: the higher score
    /// always wins.
    bool arbitrate = true;
    ArbiterModel arbiter;
};

/// What became of a hypothesis.
enum class Verdict {
    accepted,
    no_pose,     ///< the pipeline gave no pose (PoseOutcome::status says why)
    low_score,   ///< verified score below PipelineOptions::min_pose_score
    duplicate,   ///< another pose of the same object at the same place scored higher
    overlap,     ///< a higher-scored pose claims the same depth
    covered,     ///< not posed: its peak lies on depth a verified pose already explains
    implausible, ///< its distance disagrees with its box (implausible_distance)
};
const char* to_string(Verdict v);

/// Whether a pose's distance agrees with the box it came from; "" when it does, else why.
/// The object (diameter d) at depth z projects to at most f d / (z - d/2) pixels (f: the mean
/// focal length), so a box more than twice that is impossible — the depth reads too far (a
/// depth scale or a camera too large); a box under 1/8 of f d / z that does not touch the image
/// border shows the object far smaller than its depth allows, even 90 % hidden — the depth reads
/// too near. A pose nearer than 50 mm or beyond 20 m is no sensor's either. Catches a depth
/// scale 10x off, which otherwise gives confident poses at 6 m.
std::string implausible_distance(const geom::Pose& pose, const geom::Box2i& box,
                                 const geom::Intrinsics& K, double diameter);

struct Hypothesis {
    Candidate cand;
    PoseOutcome outcome;
    bool verified = false;        ///< a mesh verified it (else score = det_score)
    geom::Verification check;     ///< when verified
    /// The probability that the pose is right (HypothesisTuning::score_model over the check
    /// and the detection), or det_score when not verified.
    double score = 0;
    Verdict verdict = Verdict::no_pose;
    int rival = -1;               ///< duplicate / overlap: the index of the pose that won
    /// Posed by following the previous frame's pose (FramePipeline::follow), not from a
    /// detection of this frame.
    bool tracked = false;
    int track_id = -1;            ///< the instance's id across frames (infer::Tracker); -1: none
    /// A seed decided after every other hypothesis of the frame (a followed pose on a frame the
    /// detector saw: it only fills in an instance the fresh poses left out) and never covering.
    bool fill_in = false;
    bool accepted() const { return verdict == Verdict::accepted; }
    /// The box the pose is reported with: the box of its surface the depth explains
    /// (geom::Verification::box) when verified with enough inliers, else the detection's box.
    geom::Box2i reported_box() const {
        return verified && !check.box.empty() ? check.box : outcome.box;
    }
};

/// Whether two poses are one instance (HypothesisTuning::duplicate_frac / duplicate_overlap):
/// one object, centres closer than duplicate_frac x its `diameter`, and — both verified — their
/// footprints sharing more than duplicate_overlap of the lower one's (`shared`: their
/// geom::footprint_overlap, read only when both are verified; the other form computes it).
/// The selection's duplicate test and infer::Tracker's id hand-over.
bool same_instance(const Hypothesis& a, const Hypothesis& b, const HypothesisTuning& tune,
                   double diameter, double shared);
bool same_instance(const Hypothesis& a, const Hypothesis& b, const HypothesisTuning& tune,
                   double diameter);

/// FramePipeline::hypotheses' selection, on posed (and verified) hypotheses: best score first
/// (fill-ins last), each kept unless its pose is missing (no_pose), its distance disagrees with
/// its box (implausible_distance: implausible), its score is below `min_pose_score`
/// (low_score), or a kept pose is the same instance (same object, centres closer than
/// tune.duplicate_frac x its `diameter` and footprints overlapping by more than
/// tune.duplicate_overlap: duplicate) or claims the same depth (footprints
/// overlapping by more than tune.overlap_frac: overlap) and the arbiter (tune.arbiter, with
/// tune.arbitrate) does not prefer it to each such kept pose; the kept poses it is preferred to
/// are dropped then, naming it as their rival; a pose that had lost to a dropped one is tried
/// again, so every rival named is a kept pose. Covered hypotheses keep their verdict. Returns
/// them accepted first, then the rejected, each by score; rivals index the returned order.
std::vector<Hypothesis> select_hypotheses(std::vector<Hypothesis> hs,
                                          const HypothesisTuning& tune,
                                          const std::map<int, double>& diameter,
                                          const geom::Intrinsics& K, double min_pose_score);

/// How a pose of the previous frame is followed into the next one (tracking, spec §17): at
/// video rate an object moves a few millimetres or degrees between frames, so a short ICP from
/// the last pose on the depth points near the posed surface replaces the detector, the crop and
/// the networks (~1 ms instead of ~25 per object).
struct TrackOptions {
    /// Depth points are searched in the sphere around the last pose's model-box centre of radius
    /// (0.5 + search_frac) x diameter: the object's motion between frames.
    double search_frac = 0.25;
    /// Of those, the points within max(gate_min_mm, gate_frac x diameter) of the surface posed
    /// at the last pose are taken as the object's: the segmentation network's job, done by the
    /// last pose (a wider gate takes in the table and the neighbours).
    double gate_frac = 0.06;
    double gate_min_mm = 10.0;
    int iterations = 10;   ///< ICP steps from the last pose (no turned starts)
    int max_points = 500;  ///< object points the ICP uses (evenly strided)
};

class FramePipeline {
public:
    /// Throws g2l::Error for a null network or options out of range (PipelineOptions::check).
    /// (An object without a diameter is refused when a box of it is cropped, naming it.)
    /// `automatic` refinement refines the objects given a mesh (add_mesh) with `turns`.
    FramePipeline(PipelineModel model, const PipelineOptions& opt);
    ~FramePipeline();
    FramePipeline(FramePipeline&&) noexcept;
    FramePipeline& operator=(FramePipeline&&) noexcept;

    /// The mesh of object `obj_id` (mm, model frame) with its box and diameter `info`: what the
    /// refinement needs is built once, here. An object without a mesh keeps the networks' pose.
    void add_mesh(int obj_id, const geom::Mesh& mesh, const geom::ModelInfo& info);
    /// The prepared mesh of an object, or null.
    const PreparedMesh* mesh(int obj_id) const;

    const PipelineModel& model() const { return model_; }
    /// The options, -1 point counts resolved to the model's and `automatic` to `turns`.
    const PipelineOptions& options() const { return opt_; }
    /// New options for the next frames (checked and resolved as the constructor's); the
    /// refinement cannot change (add_mesh prepared the meshes for it): throws g2l::Error.
    void set_options(const PipelineOptions& opt);
    Refinement refine() const { return opt_.refine; }
    const HypothesisTuning& tuning() const { return tuning_; }
    /// Other fixed settings for the hypotheses road (studies and fits: g2l_eval --fit-score
    /// selects in score order, HypothesisTuning::arbitrate false).
    void set_tuning(const HypothesisTuning& t) { tuning_ = t; }

    /// Step 1: the crop of every request (`depth_mm` is K.height x K.width, 0 = no depth).
    void crop(const float* depth_mm, const geom::Intrinsics& K,
              const std::vector<PoseRequest>& requests, std::vector<PoseOutcome>* out);
    /// Step 2: the networks for every cropped request (one engine call each), then the
    /// refinement (when the options ask for it and the object has a mesh) and, with `verify`,
    /// the verification of each refined pose against the depth (PoseOutcome::check). The
    /// boxes' refinements run together on OpenMP's threads, overlapping the next boxes'
    /// networks; each box's result depends only on that box. `oracles` (optional): one per
    /// outcome.
    void estimate(const float* depth_mm, const geom::Intrinsics& K,
                  std::vector<PoseOutcome>* outcomes, const std::vector<Oracle>* oracles = nullptr,
                  const geom::VerifyOptions* verify_opt = nullptr);
    /// crop + estimate.
    void run(const float* depth_mm, const geom::Intrinsics& K,
             const std::vector<PoseRequest>& requests, std::vector<PoseOutcome>* out,
             const geom::VerifyOptions* verify_opt = nullptr);

    /// The candidates of a frame's detections: per object its best `max_instances` scoring at
    /// least `min_detection_score`, plus each detection tried as the objects of a like shape
    /// (PipelineOptions::alike_frac; needs their meshes' boxes), at most `max_hypotheses`, best
    /// score first. Detections of objects the model does not know (or knows no diameter of) are
    /// dropped.
    std::vector<Candidate> candidates(const std::vector<Candidate>& detections) const;
    /// The hypotheses road: every candidate, in order, through crop, networks and refinement
    /// (unless an earlier verified pose already explains the depth at its peak:
    /// PipelineOptions::cover_score), verified against the depth (objects with a mesh), then
    /// ranked by score with duplicates and overlaps suppressed. *out: one Hypothesis per
    /// candidate, accepted ones first by score, then the rejected ones by score. Deterministic.
    /// `seeds` (optional): hypotheses posed already (tracked poses, FramePipeline::follow) that
    /// enter ahead of the candidates: they take part in the covered test and the selection like
    /// the candidates' poses.
    void hypotheses(const float* depth_mm, const geom::Intrinsics& K,
                    const std::vector<Candidate>& candidates, std::vector<Hypothesis>* out,
                    const std::vector<Hypothesis>* seeds = nullptr);
    /// Follows `last` (an accepted pose of the previous frame, of an object with a mesh) into
    /// this frame: the depth points near its posed surface, ICP from its pose, verified and
    /// scored as a hypothesis (tracked = true, its candidate and track id kept). Its box is the
    /// image box of the searched sphere; status box_outside_image when that leaves the image,
    /// too_few_object_points when fewer than 10 points lie near the surface (the object left or
    /// moved too far). Throws g2l::Error when the object has no mesh or the pipeline does not
    /// refine (Refinement::none).
    Hypothesis follow(const float* depth_mm, const geom::Intrinsics& K, const Hypothesis& last,
                      const TrackOptions& topt) const;
    /// Verifies one posed outcome (status ok, object with a mesh) against the depth.
    geom::Verification verify(const float* depth_mm, const geom::Intrinsics& K,
                              const PoseOutcome& o, const geom::VerifyOptions& opt) const;

private:
    PipelineOptions resolved(const PipelineOptions& opt) const;
    // crop() for one request (writes only *out).
    void crop_one(const float* depth_mm, const geom::Intrinsics& K, const PoseRequest& r,
                  PoseOutcome* out) const;
    PipelineModel model_;
    PipelineOptions opt_;
    HypothesisTuning tuning_;
    std::unique_ptr<nn::PoseEngine> engine_;
    std::map<int, PreparedMesh> meshes_;
    // Reused between frames.
    std::vector<nn::PoseQuery> single_;  // the engine's batch of one (reused)
    std::vector<nn::PoseEstimate> single_out_;
};

}  // namespace g2l::infer
